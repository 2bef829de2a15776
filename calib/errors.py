"""Error classes of the calib package, and the helper that says which file an error comes from."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["CalibrationError", "prefix_errors"]


class CalibrationError(ValueError):
    """Bad or incomplete calibration data.

    The message names the file and the key (or the parameter), what was expected and what came.
    It subclasses :class:`ValueError`, so ``except ValueError`` catches it too.
    """


@contextmanager
def prefix_errors(where: object) -> Iterator[None]:
    """Re-raise a :class:`CalibrationError` from the block as ``CalibrationError(f"{where}: {message}")``.

    Used where a rig is built from the values of a file, so that the rig's own check names the file.

    Examples
    --------
    >>> try:
    ...     with prefix_errors("rig.yaml"):
    ...         raise CalibrationError("`focal_px` must be > 0, got -1.0")
    ... except CalibrationError as exc:
    ...     print(exc)
    rig.yaml: `focal_px` must be > 0, got -1.0
    """
    try:
        yield
    except CalibrationError as exc:
        raise CalibrationError(f"{where}: {exc}") from None
