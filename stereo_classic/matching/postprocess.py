"""Post-processing of float32 disparity maps (NaN = unknown): speckle filter and optional hole filling.

Both functions take and return ``(H, W) float32`` disparity in pixels with NaN where unknown, and
never modify their input.

>>> import numpy as np
>>> d = np.full((20, 20), 10.0, np.float32); d[5, 5] = 30.0
>>> int(np.isnan(filter_speckles(d, max_size=4, max_diff=1.0)).sum())
1
"""

from __future__ import annotations

import cv2
import numpy as np
from numba import njit

__all__ = ["filter_speckles", "fill_holes", "fill_holes_marked"]

# int16 value that marks unknown pixels for cv2.filterSpeckles (it skips pixels equal to newVal).
_UNKNOWN_I16 = np.iinfo(np.int16).min
# Largest |scaled disparity| we put into int16 (leaves room below the sentinel).
_I16_LIMIT = 32000.0


def _check_disparity(disparity: np.ndarray, name: str = "disparity") -> np.ndarray:
    arr = np.asarray(disparity)
    if arr.ndim != 2 or arr.dtype != np.float32:
        raise ValueError(f"`{name}` must be a (H, W) float32 array, got shape {arr.shape} dtype {arr.dtype}")
    return arr


def filter_speckles(disparity: np.ndarray, *, max_size: int, max_diff: float) -> np.ndarray:
    """Set small connected regions of similar disparity unknown (NaN).

    Uses ``cv2.filterSpeckles`` on a scaled int16 copy (scale 16, i.e. 1/16 px resolution, or
    less where the disparity magnitude needs it).

    Parameters
    ----------
    disparity : (H, W) float32
        Pixels, NaN where unknown.
    max_size : int
        Regions with fewer pixels than this are removed; 0 returns a copy unchanged.
    max_diff : float
        Largest disparity difference, pixels, between 4-neighbours of one region.

    Returns
    -------
    (H, W) float32
        A new map; removed pixels are NaN.
    """
    disp = _check_disparity(disparity)
    if max_size < 0 or not np.isfinite(max_diff) or max_diff < 0:
        raise ValueError(f"`max_size` and `max_diff` must be non-negative, got {max_size!r} and {max_diff!r}")
    disp = np.ascontiguousarray(disp)
    lo, hi, n_valid = _finite_range(disp)
    if max_size == 0 or n_valid == 0:
        return disp.copy()
    magnitude = max(abs(float(lo)), abs(float(hi)))
    scale = 16.0 if magnitude * 16.0 <= _I16_LIMIT else _I16_LIMIT / magnitude
    scaled = np.empty(disp.shape, np.int16)
    _to_scaled_int16(disp, np.float32(scale), np.int16(_UNKNOWN_I16), scaled)
    max_diff_scaled = int(round(max_diff * scale))
    cv2.filterSpeckles(scaled, _UNKNOWN_I16, int(max_size), max_diff_scaled)
    out = np.empty_like(disp)
    _unknown_where(disp, scaled, np.int16(_UNKNOWN_I16), out)
    return out


@njit(cache=True, nogil=True)
def _finite_range(disp):  # pragma: no cover - numba
    """(smallest, largest, count) of the finite values (0, 0, 0 when there is none)."""
    lo = np.float32(np.inf)
    hi = np.float32(-np.inf)
    n = 0
    for v in disp.ravel():
        if np.isfinite(v):
            lo = min(lo, v)
            hi = max(hi, v)
            n += 1
    if n == 0:
        return np.float32(0), np.float32(0), 0
    return lo, hi, n


@njit(cache=True, nogil=True)
def _to_scaled_int16(disp, scale, unknown, out):  # pragma: no cover - numba
    """out = rint(disp * scale) as int16 (float32 arithmetic, ties to even), ``unknown`` where disp is not finite."""
    d = disp.ravel()
    o = out.ravel()
    for i in range(d.size):
        v = d[i]
        o[i] = np.int16(np.rint(v * scale)) if np.isfinite(v) else unknown


@njit(cache=True, nogil=True)
def _unknown_where(disp, scaled, unknown, out):  # pragma: no cover - numba
    """out = disp, NaN where ``scaled`` holds ``unknown`` (removed by the speckle filter, or unknown before)."""
    d = disp.ravel()
    s = scaled.ravel()
    o = out.ravel()
    nan = np.float32(np.nan)
    for i in range(d.size):
        o[i] = nan if s[i] == unknown else d[i]


@njit(cache=True, nogil=True)
def _background_fill(disp, filled, still_unknown):  # pragma: no cover - numba
    """Per row: each unknown pixel takes the smaller of the nearest known values to its left and right (the one
    that exists); rows without any known pixel get 0 and ``still_unknown``."""
    height, width = disp.shape
    inf = np.float32(np.inf)
    for y in range(height):
        last = inf
        for x in range(width):  # left neighbour
            v = disp[y, x]
            if v == v:
                last = v
                filled[y, x] = v
            else:
                filled[y, x] = last
        nxt = inf
        for x in range(width - 1, -1, -1):  # right neighbour, the smaller of the two
            v = disp[y, x]
            if v == v:
                nxt = v
            else:
                b = filled[y, x]
                b = nxt if nxt < b else b
                unknown = b == inf
                still_unknown[y, x] = unknown
                filled[y, x] = np.float32(0.0) if unknown else b
                continue
            still_unknown[y, x] = False


def fill_holes(disparity: np.ndarray) -> np.ndarray:
    """Fill unknown pixels from the background side of their row, then smooth the filled pixels.

    Each unknown pixel takes the smaller (farther, background) of the nearest known disparities to
    its left and right in the same row (or the one that exists). The filled pixels then take the
    3x3 median of the filled map; known pixels keep their value. Rows with no known pixel stay NaN.
    This is for users who need a dense map: the filled values are guesses, not measurements.

    Parameters
    ----------
    disparity : (H, W) float32
        Pixels, NaN where unknown.

    Returns
    -------
    (H, W) float32
        A new map.
    """
    return fill_holes_marked(disparity)[0]


def fill_holes_marked(disparity: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``fill_holes``, and the (H, W) bool mask of the pixels it filled (unknown before, known after)."""
    disp = np.ascontiguousarray(_check_disparity(disparity))
    valid = np.isfinite(disp)
    if valid.all() or not valid.any():
        return disp.copy(), np.zeros(disp.shape, np.bool_)
    filled = np.empty_like(disp)
    still_unknown = np.empty(disp.shape, dtype=np.bool_)
    _background_fill(disp, filled, still_unknown)
    median = cv2.medianBlur(filled, 3)
    if not still_unknown.any():  # every row has a known pixel: every hole takes the median of the filled map
        return np.where(valid, disp, median), ~valid
    holes = ~valid & ~still_unknown
    out = disp.copy()
    out[holes] = filled[holes]
    # the median must not see the placeholder of rows without any known pixel
    near_empty = cv2.dilate(still_unknown.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    smoothed = holes & ~near_empty
    out[smoothed] = median[smoothed]
    out[still_unknown] = np.nan
    return out, holes
