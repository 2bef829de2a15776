"""Output paths checked before any work: a command whose output cannot be written fails at once, not after
seconds or minutes of computing.

:func:`check_output_dir` (a folder that will be created if needed) and :func:`check_output_file` (a file whose
folder must exist) raise :class:`~stereo_classic.cli.errors.UsageError` (exit code 2) naming the option, the path
and what is wrong with it.

Examples
--------
>>> import tempfile, pathlib
>>> tmp = pathlib.Path(tempfile.mkdtemp())
>>> (tmp / "taken").write_text("x")
1
>>> check_output_dir(tmp / "new" / "out", "--out") == tmp / "new" / "out"
True
>>> try:
...     check_output_dir(tmp / "taken", "--out")
... except UsageError as exc:
...     print(str(exc).replace(str(tmp), "TMP"))
--out TMP/taken exists and is a file, not a folder; choose another folder or remove it
"""

from __future__ import annotations

import os
from pathlib import Path

from stereo_classic.cli.errors import UsageError

__all__ = ["check_output_dir", "check_output_file"]


def _existing_ancestor(path: Path) -> Path:
    """The nearest part of ``path`` (itself included) that exists."""
    for candidate in (path, *path.parents):
        if candidate.exists():
            return candidate
    return Path(".")


def check_output_dir(path: str | os.PathLike[str], option: str) -> Path:
    """``path`` as a Path when it is a folder that exists or can be made and written; else :class:`UsageError`.

    A path that is a file, a path below a file, and a folder without write permission are refused.
    """
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise UsageError(f"{option} {p} exists and is a file, not a folder; choose another folder or remove it")
    base = _existing_ancestor(p)
    if not base.is_dir():
        raise UsageError(f"{option} {p}: {base} is a file, so the folder cannot be made there")
    if not os.access(base, os.W_OK | os.X_OK):
        raise UsageError(f"{option} {p}: no permission to write in {base}")
    return p


def check_output_file(path: str | os.PathLike[str], option: str) -> Path:
    """``path`` as a Path when a file can be written there (its folder exists and is writable, and it is not a
    folder itself); else :class:`UsageError`."""
    p = Path(path)
    if p.is_dir():
        raise UsageError(f"{option} {p} is a folder, expected a file name")
    parent = p.parent
    if not parent.is_dir():
        what = "is a file" if parent.exists() else "does not exist"
        raise UsageError(f"{option} {p}: the folder {str(parent)!r} {what}")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise UsageError(f"{option} {p}: no permission to write in {parent}")
    return p
