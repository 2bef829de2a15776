"""The weak-texture penalty factors (numba): per pixel, P1 and P2 times a factor in sixteenths that grows where the
left image has little texture (``weak_texture_scale``; the constants and ``max_penalty_scale`` are in :mod:`.cost`).

``weak_texture_rows`` makes them for a stripe of rows, so that ``core._prepare_cost``'s workers make them beside the
census and Sobel rows of the left view (before: OpenCV's Sobel and box filter on the whole image, one task whose own
threads competed with the workers).
"""

from __future__ import annotations

import cv2
import numpy as np
from numba import njit

from stereo_classic.matching._kernels.cost import TEXTURE_REFERENCE, TEXTURE_WINDOW, max_penalty_scale

__all__ = ["scale_of_sum", "texture_table", "weak_texture_rows", "weak_texture_scale"]


def _scale_table(top: int) -> np.ndarray:
    """``weak_texture_scale``'s value for each window sum 0 .. TEXTURE_REFERENCE * n (above: 16), uint8."""
    n = TEXTURE_WINDOW * TEXTURE_WINDOW
    sums = np.arange(TEXTURE_REFERENCE * n + 1, dtype=np.int64)
    # 16 * REF / (sums / n), rounded half up: (32 * REF * n + sums) // (2 * sums); a flat window (sums 0) gets the top
    table = (32 * TEXTURE_REFERENCE * n + sums) // np.maximum(2 * sums, 1)
    return np.clip(table, 16, top).astype(np.uint8)


_SCALE_TABLES: dict[int, np.ndarray] = {}


def texture_table(gain: float) -> np.ndarray:
    """``weak_texture_scale``'s table for ``gain``: the factor (uint8 sixteenths) of each window sum of ``|Sobel_x|``
    from 0 to TEXTURE_REFERENCE * TEXTURE_WINDOW^2 (every larger sum: 16); the one entry 16 when ``gain`` <= 1."""
    top = max_penalty_scale(gain)
    if top <= 16:
        return np.full(1, 16, np.uint8)
    table = _SCALE_TABLES.get(top)
    if table is None:
        table = _SCALE_TABLES[top] = _scale_table(top)
    return table


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def scale_of_sum(s, top):  # pragma: no cover - numba
    """``_scale_table``'s entry for the window sum ``s`` (int16, >= 0; every sum above the table: 16) and the largest
    factor ``top`` (float32): ``clip((32 * REF * n + s) // max(2 s, 1), 16, top)`` as uint8, in float32. Exact for
    every sum 0 .. 25 * 1020 (tested against the table): where the quotient is no integer it is at least 1 / (2 s)
    from one, far above float32's rounding error at these sizes (below 2 ** -10 / s)."""
    sf = np.float32(s)
    q = np.floor((np.float32(32 * TEXTURE_REFERENCE * TEXTURE_WINDOW * TEXTURE_WINDOW) + sf)
                 / max(sf + sf, np.float32(1.0)))
    return np.uint8(min(max(q, np.float32(16.0)), top))


@njit(cache=True, nogil=True, error_model="numpy")
def weak_texture_rows(padded, y0, y1, table, out):  # pragma: no cover - numba
    """``weak_texture_scale`` for the rows [y0, y1): ``out[y, x] = table[min(s, len(table) - 1)]``, ``s`` the
    TEXTURE_WINDOW x TEXTURE_WINDOW window sum (borders replicated) of ``|Sobel_x|`` of the image ``padded`` by one
    replicated pixel (the unclipped ``sobel_rows``). In 16-bit lanes (a sum is at most 25 * 1020), the |Sobel| rows
    in a ring of TEXTURE_WINDOW rows made once each, the window's column sums moved along the row. A table of one
    entry: that entry everywhere, no Sobel made.

    The table's entries are computed (``scale_of_sum``), not looked up: a gather a pixel, which LLVM does not
    vectorise; 0.88 -> 0.45 ms a KITTI image (docs/matching.md, "Thirteenth round")."""
    if table.shape[0] == 1:
        out[y0:y1] = table[0]
        return
    H = padded.shape[0] - 2
    W = padded.shape[1] - 2
    r = TEXTURE_WINDOW // 2
    n = 2 * r + 1
    top = np.float32(table[0])  # the factor of a flat window (sum 0): the largest
    ring = np.empty((n, W), np.int16)  # |Sobel_x| of row yy in ring[yy % n]
    cols = np.empty(W + 2 * r, np.int16)  # column sums of the window's rows, borders replicated
    made = max(0, y0 - r) - 1  # the last row made
    for y in range(y0, y1):
        last = min(H - 1, y + r)
        while made < last:
            made += 1
            a, b, c = padded[made], padded[made + 1], padded[made + 2]
            g = ring[made % n]
            for x in range(W):
                gx = ((np.int16(a[x + 2]) - np.int16(a[x])) + np.int16(2) * (np.int16(b[x + 2]) - np.int16(b[x]))
                      + (np.int16(c[x + 2]) - np.int16(c[x])))
                g[x] = gx if gx >= 0 else -gx
        for x in range(W):
            cols[x + r] = 0
        for i in range(-r, r + 1):
            g = ring[min(max(y + i, 0), H - 1) % n]
            for x in range(W):
                cols[x + r] += g[x]
        for j in range(r):
            cols[j] = cols[r]
            cols[W + r + j] = cols[W + r - 1]
        o = out[y]
        for x in range(W):
            s = np.int16(0)
            for j in range(n):
                s += cols[x + j]
            o[x] = scale_of_sum(s, top)


def weak_texture_scale(left: np.ndarray, gain: float, out: np.ndarray | None = None, *, scratch=None) -> np.ndarray:
    """(H, W) uint8 penalty factors in sixteenths: ``clip(16 * TEXTURE_REFERENCE / t, 16, max_penalty_scale(gain))``
    rounded half up, ``t`` the TEXTURE_WINDOW x TEXTURE_WINDOW window mean of ``|Sobel_x(left)|`` (borders
    replicated), exact (the table's integer formula, ``scale_of_sum``: the same numbers on every machine and thread
    count); all 16 when ``gain`` <= 1. ``scratch(name, shape, dtype)`` gives the temporaries (a workspace's: no fresh
    arrays per call), default new arrays."""
    if out is None:
        out = np.empty(left.shape, np.uint8)
    table = texture_table(gain)
    if table.shape[0] == 1:
        out[...] = table[0]
        return out
    H, W = left.shape
    padded = cv2.copyMakeBorder(left, 1, 1, 1, 1, cv2.BORDER_REPLICATE,
                                dst=None if scratch is None else scratch("texture_padded", (H + 2, W + 2), np.uint8))
    weak_texture_rows(padded, 0, H, table, out)
    return out
