"""The output folder of a run: one run at a time, its settings recorded, a resume that matches them.

:class:`OutputFolder` is held for the length of a run (``with OutputFolder(...):``):

* **Locked**: a second run into the same folder fails at once with :class:`FolderBusyError` (an OS file lock on
  ``.stereo_classic.lock``, released by the OS when the holder exits, even when it is killed).
* **Settings recorded**: ``run.json`` holds the settings that decide what the files contain (input, outputs,
  detector, fusion, matcher, seed, scale; not threads, executor or progress).
* **Resume matches**: with ``resume=True`` a folder whose ``run.json`` differs fails with
  :class:`SettingsMismatchError`, naming every setting that differs and both values.
* **A fresh run owns the folder**: without ``resume`` the files an earlier run recorded in ``run.json`` wrote
  (its kinds of output files and ``objects.jsonl``) are removed first, so no older frame stays beside the new
  ones. Other files are left alone. Stale temporary files of an interrupted write (``.NAME.<hex>.tmp``) are
  removed in either case.
* **Nothing left from nothing**: a run that writes no frame (bad input, an error before the first frame) leaves
  neither ``run.json`` nor the lock file, and removes the folder when it made it.

Examples
--------
>>> import tempfile, pathlib
>>> with tempfile.TemporaryDirectory() as tmp:
...     with OutputFolder(tmp, {"seed": 0}, outputs=["{name}_disparity.pfm"]) as folder:
...         _ = (pathlib.Path(tmp) / "a_disparity.pfm").write_bytes(b"x")
...     try:
...         OutputFolder(tmp, {"seed": 1}, outputs=["{name}_disparity.pfm"], resume=True).__enter__()
...     except SettingsMismatchError as exc:
...         print(str(exc).split("What differs: ")[1].split(".")[0])
seed: the folder's run had 0, this run has 1
"""

from __future__ import annotations

import json
import logging
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Self

from stereo_classic import io

__all__ = ["LOCK_NAME", "RUN_NAME", "FolderBusyError", "OutputFolder", "SettingsMismatchError", "settings_diff"]

log = logging.getLogger("stereo_classic.outputs")

#: The settings of the run that wrote the folder.
RUN_NAME = "run.json"
#: The lock file (kept; the lock is on the open file, not on its existence).
LOCK_NAME = ".stereo_classic.lock"
_TMP = re.compile(r"^\..+\.[0-9a-f]{12}\.tmp$")  # stereo_classic.io.atomic_write's temporary files


class FolderBusyError(ValueError):
    """Another run holds the output folder."""


class SettingsMismatchError(ValueError):
    """``--resume`` into a folder written with other settings; the message lists every difference."""


def _short(value: Any) -> str:
    text = json.dumps(value) if not isinstance(value, str) else repr(value)
    return text if len(text) <= 90 else text[:60] + f"... ({len(text)} characters)"


def settings_diff(old: Mapping[str, Any], new: Mapping[str, Any], prefix: str = "") -> list[str]:
    """One line per setting that differs between ``old`` (the folder's) and ``new`` (this run's).

    >>> settings_diff({"seed": 0, "matcher": {"p1": 8}}, {"seed": 0, "matcher": {"p1": 10}})
    ["matcher.p1: the folder's run had 8, this run has 10"]
    """
    lines = []
    for key in sorted(set(old) | set(new)):
        a, b = old.get(key, "(not set)"), new.get(key, "(not set)")
        if isinstance(a, Mapping) and isinstance(b, Mapping):
            lines += settings_diff(a, b, f"{prefix}{key}.")
        elif a != b:
            lines.append(f"{prefix}{key}: the folder's run had {_short(a)}, this run has {_short(b)}")
    return lines


class _Lock:
    """An exclusive, non-blocking OS lock on a file (fcntl on POSIX, msvcrt on Windows)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.fd: int | None = None

    def acquire(self) -> bool:
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            if os.name == "nt":  # pragma: no cover - Windows
                import msvcrt

                msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
            else:
                import fcntl

                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            return False
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self.fd = fd
        return True

    def holder(self) -> str:
        try:
            pid = self.path.read_text(encoding="utf-8").strip()
        except OSError:
            pid = ""
        return f"process {pid}" if pid.isdigit() else "another process"

    def release(self) -> None:
        if self.fd is not None:
            os.close(self.fd)  # closing releases the lock
            self.fd = None


class OutputFolder:
    """Hold an output folder for one run; see the module docstring.

    Parameters
    ----------
    path : path
        The folder (created).
    settings : mapping
        JSON-ready settings that decide what the files hold; recorded in ``run.json``.
    outputs : sequence of str
        The file name patterns this run writes (``"{name}_disparity.pfm"``, ...), recorded so that a later fresh
        run knows what it may remove.
    resume : bool
        Continue the folder's run: its ``run.json`` must hold the same settings.

    Raises
    ------
    FolderBusyError
        Another run holds the folder.
    SettingsMismatchError
        ``resume`` and the folder's run had other settings.
    """

    def __init__(self, path: str | os.PathLike[str], settings: Mapping[str, Any], *, outputs: Sequence[str] = (),
                 resume: bool = False) -> None:
        self.path = Path(path)
        self.settings = json.loads(json.dumps(dict(settings)))  # JSON-ready, as it will read back
        self.outputs = list(outputs)
        self.resume = bool(resume)
        self.removed: list[Path] = []
        self._lock = _Lock(self.path / LOCK_NAME)

    def __enter__(self) -> Self:
        self._created = not self.path.exists()
        self.path.mkdir(parents=True, exist_ok=True)
        if not self._lock.acquire():
            raise FolderBusyError(f"output folder {self.path} is in use by another run ({self._lock.holder()}); "
                                  "wait for it to finish or choose another -o/--output")
        try:
            self._prepare()
        except BaseException:
            self._lock.release()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        try:
            if not any(p.name not in (RUN_NAME, LOCK_NAME) for p in self.path.iterdir()):
                # nothing was written (bad input, an error before the first frame): leave nothing behind
                (self.path / RUN_NAME).unlink(missing_ok=True)
                (self.path / LOCK_NAME).unlink(missing_ok=True)
                if self._created:
                    self.path.rmdir()
        except OSError:
            pass
        finally:
            self._lock.release()

    def _previous(self) -> dict[str, Any] | None:
        path = self.path / RUN_NAME
        if not path.is_file():
            return None
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
            return data if isinstance(data, dict) and isinstance(data.get("settings"), dict) else None
        except (OSError, ValueError):
            return None

    def _prepare(self) -> None:
        previous = self._previous()
        for tmp in self.path.iterdir():
            if _TMP.match(tmp.name) and tmp.is_file():
                tmp.unlink(missing_ok=True)
                self.removed.append(tmp)
        if self.resume:
            if previous is not None:
                diff = settings_diff(previous["settings"], self.settings)
                if diff:
                    raise SettingsMismatchError(
                        f"--resume: {self.path} was written with other settings; resuming would mix results. "
                        f"What differs: {'; '.join(diff)}. Resume with the folder's settings, or write to another "
                        "-o/--output (a fresh run without --resume replaces the folder's run)")
            elif any(p.name != LOCK_NAME for p in self.path.iterdir()):
                log.warning("--resume: %s has no %s (written by an older version?): its settings cannot be checked",
                            self.path, RUN_NAME)
        elif previous is not None:
            self._remove_owned(previous)
        with io.atomic_write(self.path / RUN_NAME, "w") as f:
            f.write(json.dumps({"settings": self.settings, "outputs": self.outputs}, indent=2) + "\n")

    def _remove_owned(self, previous: Mapping[str, Any]) -> None:
        patterns = [p for p in previous.get("outputs", []) if isinstance(p, str) and "{name}" in p]
        owned = [re.compile(re.escape(p).replace(re.escape("{name}"), ".+")) for p in patterns]
        owned.append(re.compile(re.escape("objects.jsonl")))
        for path in sorted(self.path.iterdir()):
            if path.is_file() and any(r.fullmatch(path.name) for r in owned):
                path.unlink(missing_ok=True)
                self.removed.append(path)
        if self.removed:
            log.warning("%s held an earlier run: removed its %d file(s) (--resume continues a run instead)",
                        self.path, len(self.removed))
