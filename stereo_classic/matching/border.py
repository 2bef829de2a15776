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

``independent_check`` is the same check for every pixel (``SGMParams.lr_mode="independent"``): the whole pair matched
again mirrored, a 3x3 median of the measured pixels of both views (Hirschmuller's, as Pandora runs it before its
cross check), and each left pixel kept where the right image's own disparity at its match agrees within
``lr_check``. Twice the matching, for fewer wrong measurements where the left view's sums agree with themselves
(docs/matching.md, "An independent right view").
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from numba import njit

from stereo_classic.matching.postprocess import median_measured

__all__ = ["STRIP_MARGIN", "column_reach", "confirm_left_border", "independent_check", "left_border_columns",
           "mirrored_params", "short_reach", "strip_params", "strip_width"]

#: Columns of the strip beyond what the checked pixels' matches can reach: the cost windows (census 9 x 7: 4 px,
#: the gradient term's block: 2 px) and some warm-up for the path that enters the strip at its cut edge.
STRIP_MARGIN = 16


def column_reach(width: int, params) -> np.ndarray:
    """(W,) int: per column, how many disparities of the range map inside the right image (fewer in the borders)."""
    x = np.arange(width)
    first = np.maximum(0, x - params.min_disparity - width + 1)
    last = np.minimum(params.num_disparities - 1, x - params.min_disparity)
    return np.maximum(0, last - first + 1)


def short_reach(reach: np.ndarray, params) -> np.ndarray:
    """(W,) bool: columns whose pixels can search fewer than ``effective_border_reach * num_disparities`` disparities.

    At the image borders part of the range maps outside the right image; where most of it does, the true
    match is likely out of reach and the winner of what is left is not a measurement (on the OAK-D scenes
    such pixels came out at d ~ 0, "far away", at the left edge of a room).
    """
    return (reach > 0) & (reach < params.effective_border_reach * params.num_disparities)


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
    width = strip_width(columns, left.shape[1], params)
    mirrored_left = np.ascontiguousarray(right[:, :width][:, ::-1])
    mirrored_right = np.ascontiguousarray(left[:, :width][:, ::-1])
    strip = match(mirrored_left, mirrored_right, strip_params(params))
    right_view = strip.disparity[:, ::-1]  # the right image's own disparity, columns 0 .. width - 1
    checked = np.array(disparity[:, :columns], dtype=np.float32)  # a copy: the check sets its disagreeing pixels NaN
    _reject_disagreeing(checked, np.ascontiguousarray(right_view, dtype=np.float32), float(params.lr_check))
    return np.isfinite(checked)


def mirrored_params(params):
    """The ``SGMParams`` of the right image's own match for ``independent_check``: the caller's, with no check, border
    rule, speckle filter, fill or median of its own (every winner a measurement) and no right view."""
    return strip_params(params).replace(lr_check=None, lr_mode="full", speckle_size=0, median_filter=False)


def independent_check(left: np.ndarray, right: np.ndarray, disparity: np.ndarray, params, match: Callable,
                      threads: int = 1) -> tuple[np.ndarray, np.ndarray, int]:
    """(checked, right_view, failed): the left-right check against the right image's own match.

    ``left``, ``right``: the (H, W) uint8 grey pair; ``disparity``: the left view's winners (NaN: none), matched
    without a check of its own; ``params``: its ``SGMParams`` (``lr_check``, px, the tolerance; not None);
    ``match(left, right, params)``: the matcher, called once on the mirrored pair with ``mirrored_params``.
    ``right_view`` is the right image's disparity after the 3x3 median of its measured pixels; ``checked`` is
    ``disparity`` after the same median, NaN where the right view at ``x - rint(d)`` is unknown, outside the image or
    farther than ``lr_check`` from ``d``; ``failed`` counts those pixels.
    """
    mirrored = match(np.ascontiguousarray(right[:, ::-1]), np.ascontiguousarray(left[:, ::-1]),
                     mirrored_params(params))
    right_view = median_measured(np.ascontiguousarray(mirrored.disparity[:, ::-1]), threads=threads)
    checked = median_measured(np.ascontiguousarray(disparity), threads=threads)
    return checked, right_view, int(_reject_disagreeing(checked, right_view, float(params.lr_check)))


@njit(cache=True, nogil=True)
def _reject_disagreeing(d, right_view, tolerance):  # pragma: no cover - numba
    """Set NaN, in place, every finite pixel of ``d`` (a left view's columns from 0) whose match ``x - rint(d)`` (x - d
    in float64, rounded half to even) is outside ``right_view``'s columns or where the right view is unknown or differs
    from ``d`` (in float32) by more than ``tolerance``; returns how many it set."""
    H, W = d.shape
    nan = np.float32(np.nan)
    n = 0
    for y in range(H):
        for x in range(W):
            v = d[y, x]
            if not np.isfinite(v):
                continue
            xr = np.int64(np.rint(np.float64(x) - np.float64(v)))
            if xr < 0 or xr >= right_view.shape[1] or not abs(right_view[y, xr] - v) <= tolerance:
                d[y, x] = nan
                n += 1
    return n
