"""Two-pass semi-global matching kernel for 4 and 8 paths (numba): ``sgm_pass`` and its argument records.

The Python side (stripes, threads, buffers, the public entry points) is :mod:`.core`; the default three
directions run in one sweep in :mod:`.rowpass` instead.

Design:

* One int16 sum volume ``S`` (H, W, D), disparity innermost. No stored cost volume and no
  per-path volumes: each pass computes a row's costs as it reaches the row (``cost.row_cost``, the same
  code as the one-sweep kernel's), and the path recursions keep only row buffers.
* The 8 directions are split into a *forward* pass (rows top-down, x left-to-right: from the left,
  from above, from the top-left, from the top-right) and a *backward* pass (rows bottom-up, x
  right-to-left: the four opposite directions).
* Per stripe of rows (``core.stripes``): the forward pass *stores* its partial sums into ``S``, then the
  backward pass *adds* its paths; every row is then complete and is resolved at once (``select.select_row``:
  winner-takes-all, uniqueness, parabola subpixel, left-right check) while it is still in cache.
* The 4 paths of a pass are updated in ONE loop over the disparities (int16 vectors, 32 lanes).
  Path vectors live in skewed row buffers: the new vector of a pixel is written one slot before
  the slot its predecessor is read from (vertical slot ``i - v + H``, diagonals ``i - 2v + 2H``
  and ``i + 1``), so every write lands on a vector the row has already consumed: no copies, no
  temporaries, about 1 MB per thread at 1242 x 375 x 128 (Zen 4: 1 MB L2 per core).
* In the backward pass the complete sums go to a row buffer, not back to ``S`` (only the test entry
  ``sum_volume`` keeps them).
* Arithmetic stays in int16 through LLVM intrinsics (``intrinsics``); flat arrays indexed
  with unsigned offsets (no wraparound code, plain vector loads); per-pixel loops written out in
  ``sgm_pass`` (separate numba functions are not inlined by LLVM, and inlining at numba-IR level
  adds reference counting per pixel).

Bounds: every path value satisfies ``L <= C + P2`` and costs are at most ``invalid_cost =
Cmax + 2 * P2 + 1``, so ``8 * (invalid_cost + P2) <= 32767`` keeps the 8-path sum inside int16
(checked by ``check_penalties``). Disparities whose match falls outside the right image get
``invalid_cost``, which is larger than ``min_prev + P2`` for every predecessor, so they never
influence the path minimum of a valid disparity and never win; a pixel is NaN only when no
disparity of the range maps inside the right image.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from stereo_classic.matching._kernels.cost import (
    CENSUS,
    CENSUS_GRAD,
    FEATURE_SCALE,
    FEATURES,
    GRAD_SHIFT,
    SAD,
    SAD_PIXEL_MAX,
    NoAliasCompiler,
    census_bits,
    largest_p2,
    pixel_penalties,
    row_cost,
    scaled_penalty,
)
from stereo_classic.matching._kernels.intrinsics import (
    add16,
    and16,
    min16,
    sub16,
)
from stereo_classic.matching._kernels.select import right_view_row, select_row
from stereo_classic.matching._kernels.tags import tag_disparities

__all__ = ["check_penalties", "cost_scale", "sgm_pass", "PassSettings", "PassPlan", "ThreadBuffers", "PassOutputs",
           "ALL_PATHS", "FOUR_PATHS", "THREE_PATHS", "PATH_NAMES", "PATH_STEPS", "grad_mul"]

#: Bit i of a path mask selects direction PATH_NAMES[i]. Bits 0-3 run in the forward pass,
#: bits 4-7 in the backward pass. (dx, dy) is the step from the previous pixel on the path.
PATH_NAMES = ("left", "top", "top-left", "top-right", "right", "bottom", "bottom-right", "bottom-left")
PATH_STEPS = ((1, 0), (0, 1), (1, 1), (-1, 1), (-1, 0), (0, -1), (-1, -1), (1, -1))
ALL_PATHS = 0xFF
FOUR_PATHS = 0x33  # left, top, right, bottom
THREE_PATHS = 0x13  # left, top, right (OpenCV MODE_SGBM_3WAY's directions)

_INT16_MAX = 32767
_SENTINEL = 16383  # padding at both disparity ends of every path vector: "no neighbour"
_KIND = {"census": CENSUS, "sad": SAD, "census+grad": CENSUS_GRAD, "features": FEATURES}


# ----------------------------------------------------------------------------------------------
# the arguments of sgm_pass, grouped (numba takes each NamedTuple as one argument and passes its
# arrays on to LLVM as separate, non-aliasing pointers: the compiled loops are those of plain arguments)


class PassSettings(NamedTuple):
    """Aggregation and selection settings, the same for every pass of one match.

    Attributes
    ----------
    p1, p2 : int
        Penalties in the units of the (scaled) cost.
    p1_cross : int
        P1 of the paths that cross rows (vertical and diagonal), same units.
    cross_texture : bool
        ``p1_cross`` is multiplied by the pixel's weak-texture factor too (as P1 and P2 always are); False: it is
        the same at every pixel (``SGMParams.vertical_p1``).
    adaptive_p2 : bool
        P2 / (1 + |I(p) - I(p - r)|), never below P1.
    path_mask : int
        Directions to aggregate (bit i: ``PATH_NAMES[i]``).
    uniqueness : float
        Fraction 0..1 (0 = off).
    lr_threshold : float
        Left-right check threshold, pixels; negative = no check.
    lr_claims : bool
        The check is OpenCV's collision check (``lr_mode="opencv"``).
    subpixel : bool
        Parabola subpixel refinement.
    right_view : bool
        Compute the right view's winner (for the "full" check or ``return_right``).
    """

    p1: int
    p2: int
    p1_cross: int
    cross_texture: bool
    adaptive_p2: bool
    path_mask: int
    uniqueness: float
    lr_threshold: float
    lr_claims: bool
    subpixel: bool
    right_view: bool


class PassPlan(NamedTuple):
    """The rows one call of ``sgm_pass`` covers and what it does with the sums.

    Attributes
    ----------
    y_first : int
        First row (top row of the range for the forward pass, bottom row for the backward pass).
    n_rows : int
        Number of rows.
    step : int
        +1: forward pass (rows down, x to the right); -1: backward pass.
    accumulate : bool
        Add this pass's paths to the stored partial sums (phase 2) instead of storing them (phase 1).
    select : bool
        Resolve every pixel once its sum is complete (winner, uniqueness, subpixel, LR check).
    init_cost : bool
        (SAD) build the column sums from scratch at the first row.
    keep_sums : bool
        Write the complete sums back to the volume (test entry ``sum_volume``).
    warmup : int
        The first ``warmup`` rows only run the paths in (so that the vertical and diagonal paths of a
        stripe start from a state that has seen the rows above it): nothing is read from or written to
        the volume's rows for them (they use ``scratch_row`` instead) and nothing is selected. See
        ``core.stripes``.
    scratch_row : int
        Row of the sums volume (past the image's H rows: one per worker) that warm-up rows write to.
    """

    y_first: int
    n_rows: int
    step: int
    accumulate: bool
    select: bool
    init_cost: bool
    keep_sums: bool
    warmup: int = 0
    scratch_row: int = 0


class ThreadBuffers(NamedTuple):
    """Row buffers of one thread (int16 unless said otherwise; E = D + 2).

    Attributes
    ----------
    path_h, path_v, path_a, path_b : (slots * E,) int16
        Skewed path-vector slots of the horizontal, vertical and two diagonal directions.
    min_h, min_v, min_a, min_b : (slots,) int16
        Minimum of each path vector.
    crow : (W * D,) int16
        Costs of the current row (``cost.row_cost``).
    sums : (W * D,) int16
        Complete sums of the current row (backward pass, when the volume does not keep them).
    row_min : (W,) int16
        Minimum complete sum per pixel of the row.
    k_index : (D,) int16
        0 .. D - 1.
    right_sums, right_k : (W + D - 1,) int16
        Right view: best sum and its disparity index per right pixel.
    best : (W,) int64
        Winning disparity index per pixel of the row (-1: none).
    counts : (3,) int64
        Pixels rejected by uniqueness, by the LR check, and won by a match outside the right image.
    claim_cost, claim_k : (W,) int16
        OpenCV-style LR check: cost and disparity index of each right pixel's claim.
    """

    path_h: np.ndarray
    path_v: np.ndarray
    path_a: np.ndarray
    path_b: np.ndarray
    min_h: np.ndarray
    min_v: np.ndarray
    min_a: np.ndarray
    min_b: np.ndarray
    crow: np.ndarray
    sums: np.ndarray
    row_min: np.ndarray
    k_index: np.ndarray
    right_sums: np.ndarray
    right_k: np.ndarray
    best: np.ndarray
    counts: np.ndarray
    claim_cost: np.ndarray
    claim_k: np.ndarray


class PassOutputs(NamedTuple):
    """What the passes write.

    Attributes
    ----------
    sums : (H * W * D,) int16
        The sum volume, flat, disparity innermost.
    disparity : (H, W) float32
        Left view, pixels, NaN where unknown.
    disparity_right : (H, W) float32
        Right view (written when ``PassSettings.right_view``).
    """

    sums: np.ndarray
    disparity: np.ndarray
    disparity_right: np.ndarray


# ----------------------------------------------------------------------------------------------
# parameters


def cost_scale(cost: str, block_size: int, census_window: tuple[int, int], p2: int) -> tuple[int, int]:
    """(shift, cmax): the SAD window sum is shifted right by ``shift`` so that the SGM sums fit
    int16; ``cmax`` is the largest cost after scaling. Census has shift 0 and cmax = bits."""
    if cost == "census":
        return 0, census_bits(census_window)
    if cost == "census+grad":  # Hamming bits + the window mean of |Sobel_x difference| (at most 2 * SOBEL_CAP)
        return 0, census_bits(census_window) + (SAD_PIXEL_MAX - 255 // 4)
    if cost == "features":  # FEATURE_SCALE * (1 - <fL, fR>), in [0, 2 * FEATURE_SCALE]
        return 0, 2 * FEATURE_SCALE
    raw = block_size * block_size * SAD_PIXEL_MAX
    shift = 0
    while ((raw >> shift) + 3 * (p2 >> shift) + 1) * 8 > _INT16_MAX:
        shift += 1
    return shift, raw >> shift


def grad_mul(block_size: int) -> int:
    """Multiplier of the gradient window sum of ``census+grad`` (then >> GRAD_SHIFT): the window mean."""
    return int(round(2**GRAD_SHIFT / (block_size * block_size)))


def check_penalties(cost: str, block_size: int, census_window: tuple[int, int], p1: int, p2: int,
                    weak_texture_gain: float = 1.0, p1_cross: int | None = None) -> None:
    """Raise ValueError when the penalties cannot be represented in the int16 sums (P2 at its largest, times the
    weak-texture gain), or P1 (or ``p1_cross``, the P1 of the paths that cross rows) exceeds P2."""
    if not (0 <= p1 <= p2):
        raise ValueError(f"penalties must satisfy 0 <= p1 <= p2, got p1={p1}, p2={p2}")
    if p1_cross is not None and not 0 <= p1_cross <= p2:
        raise ValueError(f"`p1_cross` must be between 0 and p2={p2}, got {p1_cross}")
    p2_top = largest_p2(p2, weak_texture_gain)
    shift, cmax = cost_scale(cost, block_size, census_window, p2_top)
    p2s = p2_top >> shift
    if 8 * (cmax + 3 * p2s + 1) > _INT16_MAX:
        limit = (_INT16_MAX // 8 - 1 - cmax) // 3
        if p2_top > p2:
            raise ValueError(f"`p2` too large for int16 sums with cost {cost!r} and weak_texture_gain "
                             f"{weak_texture_gain}: p2 * weak_texture_gain at most {limit}, got {p2} * "
                             f"{weak_texture_gain}")
        raise ValueError(f"`p2` too large for int16 sums with cost {cost!r}: at most {limit}, got {p2}")


# ----------------------------------------------------------------------------------------------
# kernels


_U = np.uint64  # unsigned flat indices: no wraparound code, contiguous vector loads


@njit(cache=True, nogil=True)
def _p2_at(limg, y, x, yp, xp, p1, p2, adaptive):  # pragma: no cover - numba
    """P2, divided by 1 + |I(p) - I(p - r)| when adaptive (never below P1)."""
    if not adaptive:
        return p2
    H, W = limg.shape
    if yp < 0 or yp >= H or xp < 0 or xp >= W:
        return p2
    diff = abs(np.int32(limg[y, x]) - np.int32(limg[yp, xp]))
    q = np.int16(np.int32(p2) // (1 + diff))
    return q if q > p1 else p1


@njit(cache=True, nogil=True, inline="always")
def cross_penalty(p1, scale, textured):  # pragma: no cover - numba
    """P1 of a path that crosses rows at a pixel, int16: ``p1`` times its ``weak_texture_scale`` (sixteenths) when
    ``textured``, else ``p1`` as given."""
    if textured:
        return scaled_penalty(p1, scale)
    return np.int16(p1)


@njit(cache=True, nogil=True)
def _lr(P, rb, c, m, q, p1, k):  # pragma: no cover - numba
    """New path value at disparity k from the previous vector at P[rb:rb + D + 2] (min m, m + P2 = q)."""
    return add16(sub16(c, m), min16(min16(P[_U(rb + 1 + k)], add16(min16(P[_U(rb + k)], P[_U(rb + 2 + k)]), p1)), q))


@njit(cache=True, nogil=True, pipeline_class=NoAliasCompiler)
def sgm_pass(images, cost, settings, plan, cbufs, bufs, out):  # pragma: no cover - numba
    """Run one 4-path pass: forward (``plan.step`` +1) or backward (-1), over ``plan.n_rows`` rows.

    Parameters
    ----------
    images : CostImages
        The left image and what the cost reads (census code quarters or SAD channels).
    cost : CostSettings
        Cost kind, disparity offset, SAD window and scaling, invalid cost.
    settings : PassSettings
        Penalties, path mask and the selection settings, the same for every pass of one match.
    plan : PassPlan
        Rows, direction, and what this pass does with the sums (store, accumulate, select).
    cbufs : cost.RowCostBuffers
        This thread's cost state (``cost.row_cost``).
    bufs : ThreadBuffers
        This thread's row buffers (never shared with a concurrent pass).
    out : PassOutputs
        The flat (H * W * D,) int16 sum volume and the (H, W) float32 disparity maps.

    ``plan.accumulate``: add to the sum volume instead of storing (the complete sums go back to it
    only when ``plan.keep_sums``, else to the row buffer ``bufs.sums``); ``plan.select`` (backward pass
    only): keep each pixel's minimum, and at the row's end find the right view's winners and resolve the row
    (``select.right_view_row``, ``select.select_row``); ``plan.init_cost``: (SAD and the gradient term) build
    the column sums from scratch at the first row.

    Path vectors: slots of E = D + 2 int16 (sentinels at both ends), minima in MH/MV/MA/MB. In pass
    coordinates (i = position along the row in processing order, v = rows processed since the
    pass started at the image edge), the new vector of pixel (v, i) is written at slot w and its
    predecessor is read at slot w + 1: vertical w = i - v + H, diagonal A (from (v-1, i-1))
    w = i - 2v + 2H, diagonal B (from (v-1, i+1)) w = i + 1. Each write overwrites a vector the
    row has already consumed, so no copies and no temporaries are needed; slots never written
    hold zeros = the path start. Horizontal: two slots, alternating.
    crow: the row's costs (``cost.row_cost``), those of pixel x at ``x * D``.
    """
    # Short local names for the loops below (the arithmetic reads like the paper's recursion).
    limg = images.left
    dmin = cost.min_disparity
    p1 = settings.p1
    p2 = settings.p2
    adaptive = settings.adaptive_p2
    path_mask = settings.path_mask
    right_view = settings.right_view
    y_first = plan.y_first
    nrows = plan.n_rows
    step = plan.step
    accumulate = plan.accumulate
    select = plan.select
    init_cost = plan.init_cost
    keep_sums = plan.keep_sums
    warmup = plan.warmup
    scratch = plan.scratch_row
    PH = bufs.path_h
    PV = bufs.path_v
    PA = bufs.path_a
    PB = bufs.path_b
    MH = bufs.min_h
    MV = bufs.min_v
    MA = bufs.min_a
    MB = bufs.min_b
    Srow = bufs.sums
    nsrow = bufs.row_min
    kidx = bufs.k_index
    rv = bufs.right_sums
    rd = bufs.right_k
    best = bufs.best
    counts = bufs.counts
    ccost = bufs.claim_cost
    ck = bufs.claim_k
    Sf = out.sums
    H = limg.shape[0]
    W = limg.shape[1]
    D = tag_disparities(cbufs.tag)  # len(kidx), as a constant: compiled once per D (tags.py)
    crow = bufs.crow
    E = D + 2
    m4 = (path_mask & 15) if step > 0 else ((path_mask >> 4) & 15)
    four = (m4 & 12) != 0
    horizontal_only = m4 == 1  # only the horizontal path of this direction: skip the vertical one
    minus1 = np.int16(-1)
    zero = np.int16(0)
    mk0 = minus1 if m4 & 1 else zero
    mk1 = minus1 if m4 & 2 else zero
    mk2 = minus1 if m4 & 4 else zero
    mk3 = minus1 if m4 & 8 else zero
    p1_32 = np.int32(p1)
    p2_32 = np.int32(p2)
    p1c_32 = np.int32(settings.p1_cross)
    cross_texture = settings.cross_texture
    pscale = images.penalty_scale
    big = np.int16(_INT16_MAX)
    forward = step > 0
    dst = Sf if keep_sums else Srow
    select_all = select
    for r in range(nrows):
        y = y_first + step * r
        v = y if forward else H - 1 - y
        # warm-up rows: the image rows of the volume are neither read nor written (the worker's scratch
        # row of the same array instead: one array keeps the loops' no-alias code), nothing is selected
        warming = r < warmup
        row = scratch if warming else y
        select = select_all and not warming
        row_cost(images, cost, y, r == 0 and init_cost, step, cbufs, crow)  # the costs of the row
        for k in range(D):
            PH[k + 1] = zero
        MH[0] = zero
        for i in range(W):
            x = i if forward else W - 1 - i
            cb = x * D  # the pixel's costs in crow
            sb = (row * W + x) * D
            db = sb if keep_sums else x * D
            p1_16, p2_16 = pixel_penalties(p1_32, p2_32, pscale[y, x])  # times its weak-texture factor
            p1v = cross_penalty(p1c_32, pscale[y, x], cross_texture)  # P1 of the paths that cross rows
            # --- slots: write w, read w + 1 (horizontal: alternate between slots 0 and 1)
            rhs = i & 1
            whs = 1 - rhs
            wvs = i - v + H
            mh = MH[rhs]
            mv = MV[wvs + 1]
            if adaptive:
                qh = add16(mh, _p2_at(limg, y, x, y, x - step, p1_16, p2_16, adaptive))
                qv = add16(mv, _p2_at(limg, y, x, y - step, x, p1v, p2_16, adaptive))
            else:
                qh = add16(mh, p2_16)
                qv = add16(mv, p2_16)
            wh = whs * E
            rh = rhs * E
            wv = wvs * E
            rvb = wv + E
            nh = big
            nv = big
            ns = big
            # The loops below are written out four times (4 or 2 paths, store or accumulate): as
            # separate functions they are not inlined by LLVM and the call per pixel costs ~20 %.
            if four:
                was = i - 2 * v + 2 * H
                wbs = i + 1
                ma = MA[was + 1]
                mb = MB[wbs + 1]
                if adaptive:
                    qa = add16(ma, _p2_at(limg, y, x, y - step, x - step, p1v, p2_16, adaptive))
                    qb = add16(mb, _p2_at(limg, y, x, y - step, x + step, p1v, p2_16, adaptive))
                else:
                    qa = add16(ma, p2_16)
                    qb = add16(mb, p2_16)
                wa = was * E
                ra = wa + E
                wb = wbs * E
                rb = wb + E
                na = big
                nb = big
                if accumulate:
                    for k in range(D):
                        c = crow[_U(cb + k)]
                        vh = _lr(PH, rh, c, mh, qh, p1_16, k)
                        vv = _lr(PV, rvb, c, mv, qv, p1v, k)
                        va = _lr(PA, ra, c, ma, qa, p1v, k)
                        vb = _lr(PB, rb, c, mb, qb, p1v, k)
                        PH[_U(wh + 1 + k)] = vh
                        PV[_U(wv + 1 + k)] = vv
                        PA[_U(wa + 1 + k)] = va
                        PB[_U(wb + 1 + k)] = vb
                        nh = min16(nh, vh)
                        nv = min16(nv, vv)
                        na = min16(na, va)
                        nb = min16(nb, vb)
                        sm = add16(add16(add16(and16(vh, mk0), and16(vv, mk1)), add16(and16(va, mk2), and16(vb, mk3))),
                                   Sf[_U(sb + k)])
                        dst[_U(db + k)] = sm
                        ns = min16(ns, sm)
                else:
                    for k in range(D):
                        c = crow[_U(cb + k)]
                        vh = _lr(PH, rh, c, mh, qh, p1_16, k)
                        vv = _lr(PV, rvb, c, mv, qv, p1v, k)
                        va = _lr(PA, ra, c, ma, qa, p1v, k)
                        vb = _lr(PB, rb, c, mb, qb, p1v, k)
                        PH[_U(wh + 1 + k)] = vh
                        PV[_U(wv + 1 + k)] = vv
                        PA[_U(wa + 1 + k)] = va
                        PB[_U(wb + 1 + k)] = vb
                        nh = min16(nh, vh)
                        nv = min16(nv, vv)
                        na = min16(na, va)
                        nb = min16(nb, vb)
                        Sf[_U(sb + k)] = add16(add16(and16(vh, mk0), and16(vv, mk1)),
                                               add16(and16(va, mk2), and16(vb, mk3)))
                MA[was] = na
                MB[wbs] = nb
            elif horizontal_only:  # one path (e.g. the backward pass of the 3-direction set): no vertical work
                if accumulate:
                    for k in range(D):
                        vh = _lr(PH, rh, crow[_U(cb + k)], mh, qh, p1_16, k)
                        PH[_U(wh + 1 + k)] = vh
                        nh = min16(nh, vh)
                        sm = add16(vh, Sf[_U(sb + k)])
                        dst[_U(db + k)] = sm
                        ns = min16(ns, sm)
                else:
                    for k in range(D):
                        vh = _lr(PH, rh, crow[_U(cb + k)], mh, qh, p1_16, k)
                        PH[_U(wh + 1 + k)] = vh
                        nh = min16(nh, vh)
                        Sf[_U(sb + k)] = vh
            else:
                if accumulate:
                    for k in range(D):
                        c = crow[_U(cb + k)]
                        vh = _lr(PH, rh, c, mh, qh, p1_16, k)
                        vv = _lr(PV, rvb, c, mv, qv, p1v, k)
                        PH[_U(wh + 1 + k)] = vh
                        PV[_U(wv + 1 + k)] = vv
                        nh = min16(nh, vh)
                        nv = min16(nv, vv)
                        sm = add16(add16(and16(vh, mk0), and16(vv, mk1)), Sf[_U(sb + k)])
                        dst[_U(db + k)] = sm
                        ns = min16(ns, sm)
                else:
                    for k in range(D):
                        c = crow[_U(cb + k)]
                        vh = _lr(PH, rh, c, mh, qh, p1_16, k)
                        vv = _lr(PV, rvb, c, mv, qv, p1v, k)
                        PH[_U(wh + 1 + k)] = vh
                        PV[_U(wv + 1 + k)] = vv
                        nh = min16(nh, vh)
                        nv = min16(nv, vv)
                        Sf[_U(sb + k)] = add16(and16(vh, mk0), and16(vv, mk1))
            MH[whs] = nh
            MV[wvs] = nv
            if select:  # a complete pixel (backward pass, selecting): its minimum; the row is resolved at its end
                nsrow[x] = ns
        if select:
            sums_row = Sf[_U(y * W * D):_U((y + 1) * W * D)] if keep_sums else Srow
            if right_view:
                right_view_row(sums_row, rv, rd, W, cbufs.tag)
            select_row(y, settings, dmin, cost.num_disparities, sums_row, nsrow, kidx, rv, rd, best, counts, ccost, ck,
                       out, cbufs.tag)
