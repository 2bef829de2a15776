"""The error every reader of :mod:`stereo_classic.io` raises for a file it cannot use.

A missing file (or a directory where a file was expected) is a ``FileNotFoundError``; a file that exists
but is empty, truncated, lying or of an unsupported kind is a :class:`FileFormatError`, a ``ValueError``,
so callers can catch either.

Example
-------
>>> from stereo_classic.io import FileFormatError
>>> issubclass(FileFormatError, ValueError)
True
"""

from __future__ import annotations

__all__ = ["FileFormatError"]


class FileFormatError(ValueError):
    """A file exists but its content is not what the reader expects (empty, truncated, wrong format)."""
