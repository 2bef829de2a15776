"""The warning of a bare :func:`~stereo_classic.fusion.localize` call whose boxes' disparities pile up at the end
of the searched range: such an object may be nearer than the range reaches, and the distance it got is the best of
wrong candidates (too far). :class:`stereo_classic.Localizer` runs the frame checks of :mod:`stereo_classic.checks`,
which look again and mark such objects ``"beyond_range"``; ``localize`` alone has no images to look again at, so it
says so instead (a :class:`RangeWarning`, once per call), naming the objects.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np

from stereo_classic.fusion.boxes import shrunk_pixel_box

__all__ = ["PILE_SHARE", "RangeWarning", "piled_boxes", "range_saturation", "warn_if_piled"]

#: A box is suspect when this fraction of its known (measured) pixels lies within 1 px of the end of the range:
#: ``stereo_classic.checks.BOX_SATURATION`` is this share (the frame checks mark such objects beyond_range).
PILE_SHARE = 0.05


def range_saturation(disparity: np.ndarray, max_disparity: float, margin: float = 1.0) -> float:
    """Fraction (0..1) of the known pixels of ``disparity`` within ``margin`` px of ``max_disparity``.

    >>> range_saturation(np.array([[1.0, 63.0, 62.5, np.nan]]), 63)
    0.6666666666666666
    """
    known = np.isfinite(disparity)
    n = int(np.count_nonzero(known))
    if n == 0:
        return 0.0
    with np.errstate(invalid="ignore"):
        return int(np.count_nonzero(disparity >= max_disparity - margin)) / n


class RangeWarning(UserWarning):
    """Objects whose box's disparities pile up at the end of the searched range (possibly nearer than it reaches)."""


def piled_boxes(disparity_map: Any, xyxy: np.ndarray, shrink: float) -> np.ndarray:
    """(N,) bool: boxes with :data:`PILE_SHARE` of their known pixels within 1 px of the end of the range.

    ``disparity_map`` must know its range (a ``DisparityMap``: ``params.max_disparity`` and
    ``measured_disparity``, filled pixels left out); for a plain array every box is False (nothing to compare with).
    """
    out = np.zeros(len(xyxy), dtype=bool)
    top = getattr(getattr(disparity_map, "params", None), "max_disparity", None)
    disp = getattr(disparity_map, "measured_disparity", None)
    if top is None or disp is None:
        return out
    disp = np.asarray(disp)
    h, w = disp.shape
    for i, box in enumerate(np.asarray(xyxy, dtype=np.float64)):
        u0, v0, u1, v1 = shrunk_pixel_box(box, shrink, w, h)
        if u1 > u0 and v1 > v0:
            out[i] = range_saturation(disp[v0:v1, u0:u1], float(top)) >= PILE_SHARE
    return out


def warn_if_piled(disparity_map: Any, xyxy: np.ndarray, labels: Sequence[str], distance_m: np.ndarray,
                  status: Sequence[str], shrink: float, *, stacklevel: int = 3) -> bool:
    """Warn (:class:`RangeWarning`) about the measured objects whose boxes are :func:`piled_boxes`; True if it did."""
    suspect = piled_boxes(disparity_map, xyxy, shrink) & (np.asarray(status) == "ok")
    if not suspect.any():
        return False
    top = disparity_map.params.max_disparity
    names = ", ".join(f"{labels[i]} at {distance_m[i]:.2f} m" for i in np.flatnonzero(suspect))
    warnings.warn(
        f"localize: {names}: {PILE_SHARE:.0%} or more of the box's measured disparities sit at the end of the "
        f"searched range ({top:g} px): the object may be nearer than the range reaches and its distance too far. "
        "Search more disparities, or use stereo_classic.Localizer, whose frame checks look again and mark such "
        "objects 'beyond_range' (range_warning=False: the caller checks the range itself)",
        RangeWarning, stacklevel=stacklevel)
    return True
