"""Error classes of the calib package."""

from __future__ import annotations

__all__ = ["CalibrationError"]


class CalibrationError(ValueError):
    """Bad or incomplete calibration data.

    The message names the file and the key (or the parameter), what was expected and what came.
    It subclasses :class:`ValueError`, so ``except ValueError`` catches it too.
    """
