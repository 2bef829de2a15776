"""Left-border pixels confirmed by the right image's own match (``SGMParams.border_check``).

A left pixel near the left edge can only search the disparities whose match lies inside the right image. Where
its true disparity is larger, its winner is a wrong disparity from what is left, and the left-right check, whose
right view is read from the same (left) sums, often passes it. So ``border_reach`` sets every pixel that can search
less than that fraction of the range unknown, and the fill gives it its row's nearest value: wrong wherever the
surface changes in the strip (the curtain behind the basket at Laundry's left edge, a slanted table top).

Seen from the right image the same places lie well inside: the right pixel ``x - d`` has the whole range of
candidates. ``confirm_left_border`` matches the strip of the pair mirrored (the right image becomes the left one,
so the kernels need no second layout), reads the right view's own disparity, and keeps each border pixel whose
winner lands on a right pixel that agrees within ``lr_check``: measured from both sides, as a left-right check with
an independent right view (Pandora's "accurate" cross check) is, for the strip only.

Cost: one match of a strip ``n + num_disparities + |min_disparity| + STRIP_MARGIN`` columns wide (``n`` the border
columns: ``border_reach * num_disparities``), 15-25 % of the matcher's pixels at 1242 x 375 x 128, 640 x 480 x 64
and the Middlebury sizes.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

__all__ = ["STRIP_MARGIN", "left_border_columns", "strip_params", "strip_width", "confirm_left_border"]

#: Columns of the strip beyond what the checked pixels' matches can reach: the cost windows (census 9 x 7: 4 px,
#: the gradient term's block: 2 px) and some warm-up for the path that enters the strip at its cut edge.
STRIP_MARGIN = 16


def left_border_columns(short: np.ndarray) -> int:
    """How many leading columns of the (W,) bool mask ``short`` are set: the left border band (0: none)."""
    if short.size == 0 or not short[0]:
        return 0
    unset = np.flatnonzero(~short)
    return int(unset[0]) if unset.size else int(short.size)


def strip_width(columns: int, width: int, params) -> int:
    """Columns of the mirrored strip that checks the first ``columns`` columns of an image ``width`` wide: those, the
    range their matches can reach, and ``STRIP_MARGIN``."""
    return min(width, columns + abs(params.min_disparity) + params.num_disparities + STRIP_MARGIN)


def strip_params(params):
    """The ``SGMParams`` the mirrored strip is matched with: the caller's, without this check, the border rule and
    the fill (every pixel of the strip's right view a measurement), and without a right view of its own."""
    return params.replace(border_check=False, border_reach=0.0, fill_holes=False, right_view=False)


def confirm_left_border(left: np.ndarray, right: np.ndarray, disparity: np.ndarray, columns: int, params,
                        match: Callable) -> np.ndarray:
    """(H, columns) bool: the pixels of the first ``columns`` columns of ``disparity`` (finite = the left view's
    winner after its own checks) that the right image's own match confirms.

    ``left``, ``right``: the (H, W) uint8 grey pair; ``params``: the match's ``SGMParams`` (its ``lr_check`` is the
    tolerance, in pixels; it must not be None); ``match(left, right, params)``: the matcher, returning a
    ``DisparityMap`` (called once, on the mirrored strip, without the fill and without this check).
    """
    H, W = left.shape
    width = strip_width(columns, W, params)
    mirrored_left = np.ascontiguousarray(right[:, :width][:, ::-1])
    mirrored_right = np.ascontiguousarray(left[:, :width][:, ::-1])
    strip = match(mirrored_left, mirrored_right, strip_params(params))
    right_view = strip.disparity[:, ::-1]  # the right image's own disparity, columns 0 .. width - 1
    d = disparity[:, :columns]
    ys, xs = np.nonzero(np.isfinite(d))
    values = d[ys, xs]
    xr = np.rint(xs - values).astype(np.int64)
    inside = (xr >= 0) & (xr < width)
    agree = np.zeros(values.shape, bool)
    agree[inside] = np.abs(right_view[ys[inside], xr[inside]] - values[inside]) <= params.lr_check  # NaN: False
    keep = np.zeros((H, columns), bool)
    keep[ys[agree], xs[agree]] = True
    return keep
