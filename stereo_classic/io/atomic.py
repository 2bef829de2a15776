"""Atomic file writes: a file appears complete or not at all.

Every writer of :mod:`stereo_classic.io` goes through :func:`atomic_write`: it writes a temporary file
in the target folder and renames it over the target with :func:`os.replace`, so a failed write never
leaves a half-written file behind.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from stereo_classic.io._common import PathLike, as_path

__all__ = ["atomic_write"]


@contextlib.contextmanager
def atomic_write(path: PathLike, mode: str = "wb") -> Iterator[IO[Any]]:
    """Open ``path`` for writing so that it appears complete or not at all.

    The body writes into a temporary file in the same folder; on success the file is flushed,
    synced and renamed over ``path`` (:func:`os.replace`, atomic on POSIX and Windows). If the body
    raises, the temporary file is removed and ``path`` is left as it was.

    Parameters
    ----------
    path : str or os.PathLike
        Target file. Its folder must exist.
    mode : {"wb", "w", "wt"}
        Binary (default) or text (UTF-8, ``\\n`` line ends).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> target = pathlib.Path(tempfile.mkdtemp()) / "a.txt"
    >>> with atomic_write(target, "w") as f:
    ...     _ = f.write("hello")
    >>> target.read_text()
    'hello'
    """
    if mode not in ("wb", "w", "wt"):
        raise ValueError(f"`mode` must be 'wb', 'w' or 'wt', got {mode!r}")
    target = as_path(path)
    parent = target.parent if str(target.parent) else Path(".")
    if not parent.is_dir():
        raise FileNotFoundError(f"cannot write {target}: folder {parent} does not exist")
    if target.is_dir():
        raise IsADirectoryError(f"cannot write {target}: it is a directory")
    tmp = parent / f".{target.name}.{secrets.token_hex(6)}.tmp"
    # os.open with 0o666 lets the process umask decide the final permissions, like open() would.
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
    try:
        if mode == "wb":
            handle: IO[Any] = os.fdopen(fd, "wb")
        else:
            handle = os.fdopen(fd, "w", encoding="utf-8", newline="\n")
    except BaseException:
        os.close(fd)
        tmp.unlink(missing_ok=True)
        raise
    try:
        with handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
