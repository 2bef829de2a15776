"""Learned features to the int8 unit vectors the row cost reads (``cost.feature_row_cost``): one numba pass.

``quantise_rows`` takes a feature network's float32 output (C, H + 2m, W + 2m) (the margin m cut off here),
normalises each pixel's C-vector to unit length and stores ``round(FEATURE_QUANT * f)`` as int8, one image row per
channel (H, C, W); it counts the values that are not finite (the caller refuses the model then).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from stereo_classic.matching._kernels.cost import FEATURE_QUANT

__all__ = ["quantise_rows"]


@njit(cache=True, nogil=True)
def quantise_rows(feat, margin, y0, y1, out, sq):  # pragma: no cover - numba
    """Rows [y0, y1) of ``out`` (H, C, W) int8, from ``feat`` (C, H + 2m,
    W + 2m) float32 (m = ``margin``). ``sq``: (W,) float64 scratch. Returns the number of non-finite values read
    (the rows are then undefined). A zero vector stays zero (its dot product with anything is 0)."""
    C = feat.shape[0]
    W = sq.shape[0]
    q = np.float64(FEATURE_QUANT)
    bad = 0
    for y in range(y0, y1):
        yy = y + margin
        sq[:] = 0.0
        for c in range(C):
            row = feat[c, yy]
            for x in range(W):
                v = np.float64(row[x + margin])
                sq[x] += v * v
        for x in range(W):
            s = sq[x]
            if not np.isfinite(s):
                bad += 1
                s = 0.0
            sq[x] = q / np.sqrt(s) if s > 0.0 else 0.0
        for c in range(C):
            row = feat[c, yy]
            for x in range(W):
                v = np.float64(row[x + margin]) * sq[x]
                r = np.floor(v + 0.5) if np.isfinite(v) else 0.0
                out[y, c, x] = np.int8(min(max(r, -q), q))
    return bad
