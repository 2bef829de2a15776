"""Three-direction SGM in one sweep down a stripe (numba): ``three_path_stripe`` and its buffers.

The directions are OpenCV MODE_SGBM_3WAY's: from the left, from above, from the right (the default
``paths=3``). They need no second pass over the image, so nothing is stored per image but the output:

* per row, ``row_cost`` writes the cost of every pixel of the row once (``crow``, W x D int16);
* a left-to-right sweep updates the top path (skewed row buffer, as in :mod:`.aggregate`: the vector of
  pixel ``x`` of row ``r`` is written at slot ``x - r + n_rows`` and its predecessor read one slot on) and
  the left path, and stores their sum per pixel (``srow``);
* a right-to-left sweep adds the right path, keeping the complete sum in ``srow`` and its minimum per pixel;
  it runs one row behind, in the same pass over the columns as the next row's left-to-right sweep (two
  independent pixel-to-pixel chains side by side: at short ranges the chains' latency set the pace);
* the right view's winners are found in the right-to-left sweep where D is 32, 64 or 128
  (``pathvec.right_path_view``, a window of D right pixels carried from pixel to pixel), else by
  ``select.right_view_row`` over the finished row, and ``select.select_row`` resolves the row (winner-takes-all,
  uniqueness, subpixel, left-right check).

Where D is 32, 64 or 128 (``pathvec.vector_paths``) a pixel's path updates are made on whole LLVM vectors
(:mod:`.pathvec`: the previous vector loaded once, its neighbours at d +- 1 made in registers; the left / right
paths' vectors and the right view's window carried from pixel to pixel in registers), elsewhere by the loops over
the disparities; the same values either way.

Per thread this touches about 5 x W x D x 2 bytes (1.6 MB at 1242 x 128), which stays in L2, against a
H x W x D volume written and read back by the two-pass kernel. The values are those of
:func:`.aggregate.sgm_pass` run forward (left, top) then backward (right) over the same stripe and warm-up rows,
bit for bit (checked against the numpy reference by the tests).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from stereo_classic.matching._kernels.aggregate import _INT16_MAX, _SENTINEL, _lr, _p2_at, cross_penalty
from stereo_classic.matching._kernels.aligned import aligned_empty, aligned_zeros
from stereo_classic.matching._kernels.cost import (
    NoAliasCompiler,
    pixel_penalties,
    row_cost,
)
from stereo_classic.matching._kernels.intrinsics import add16, umin16
from stereo_classic.matching._kernels.pathvec import (right_path_sum, right_path_view, store_vector, top_and_left,
                                                      top_path, vector_of, vector_paths)
from stereo_classic.matching._kernels.select import right_view_row, select_row
from stereo_classic.matching._kernels.tags import disparity_tag, tag_disparities

# ``_nrt=False``: kernels that run per row and allocate nothing, compiled without numba's reference counts on their
# array arguments (atomic updates, on every call, of counters both workers share; docs/matching.md, seventh round).
__all__ = ["RowPassBuffers", "StripePlan", "three_path_stripe", "path_slots", "row_pass_buffers", "row_pass_bytes",
           "slot_size"]

#: int16 elements per 64-byte cache line: a path slot's size is a whole number of them (``slot_size``).
_SLOT_ALIGN = 32
_U = np.uint64  # unsigned flat indices: no wraparound code, contiguous vector loads


class StripePlan(NamedTuple):
    """The rows one call of ``three_path_stripe`` covers.

    Attributes
    ----------
    y_first : int
        First row, warm-up rows included.
    n_rows : int
        Rows, warm-up rows included.
    warmup : int
        The first ``warmup`` rows only run the top path in (nothing is selected or written for them).
    keep_sums : bool
        Write the complete sums of the stripe's own rows to ``PassOutputs.sums`` (test entry ``sum_volume``).
    select : bool
        Resolve the pixels (else only the sums are computed).
    cached : bool
        The warm-up rows' costs are in the first rows of ``RowPassBuffers.costs`` and the cost state
        (``RowCostBuffers``) has just made the row before the stripe: this worker ran the stripe above, whose last
        rows these are. Their costs are read instead of made again (integer costs: the same numbers either way).
    tail : int
        Make the costs of the last ``tail`` rows into the first rows of ``costs`` (the next stripe's warm-up rows),
        0: none.
    """

    y_first: int
    n_rows: int
    warmup: int
    keep_sums: bool
    select: bool
    cached: bool = False
    tail: int = 0


class RowPassBuffers(NamedTuple):
    """Row buffers of one thread (int16 unless said otherwise; E = ``slot_size(D)``).

    Attributes
    ----------
    costs : (R + 2, W * D) int16
        Cost of every pixel of a row: rows R and R + 1 for the current rows (by the row's parity: a row's costs are
        read again by its right-to-left sweep, one pass after its own), rows 0 .. R - 1 for a stripe's last R rows
        (R = the warm-up rows), which the same worker's next stripe warms up on (one array, so that the kernel
        reads every row's costs from one buffer: a choice between two buffers cost the loops their vectorisation).
    srow : (2, W * D) int16
        Per row parity: left + top sums of the row, then (after its right-to-left sweep) the complete sums.
    path_v : ((W + H + 1) * E,) int16
        Skewed top-path vectors, one slot of E each: a sentinel, the D disparities (64-byte aligned), a sentinel,
        padding.
    min_v : (W + H + 1,) int16
        Minimum of each top-path vector.
    path_h : (2 * E,) int16
        The horizontal path's previous and current vector (their minima are carried in registers), for the loops:
        where D is 32, 64 or 128 the vectors themselves are carried in registers (``pathvec.PathVector``).
    path_r : (2 * E,) int16
        The same for the right path (the row above's, swept beside the left path of the row: its own array, as
        two slots of ``path_h`` cost the loops their speed-up).
    row_min : (W,) int16
        Minimum complete sum per pixel of the row.
    k_index : (D,) int16
        0 .. D - 1 (the first index of the minimum is found with vector selects).
    right_sums, right_k : (W + D - 1,) int16
        Right view: best sum and its disparity index per right pixel.
    best : (W,) int64
        Winning disparity index per pixel of the row (-1: none).
    counts : (3,) int64
        Pixels rejected by uniqueness, by the LR check, and won by a match outside the right image.
    claim_cost, claim_k : (W,) int16
        OpenCV-style LR check: cost and disparity index of each right pixel's claim.
    tag : tuple
        ``tags.disparity_tag(D)``: the kernel reads D from it, so it is compiled once per D.
    """

    costs: np.ndarray
    srow: np.ndarray
    path_v: np.ndarray
    min_v: np.ndarray
    path_h: np.ndarray
    path_r: np.ndarray
    row_min: np.ndarray
    k_index: np.ndarray
    right_sums: np.ndarray
    right_k: np.ndarray
    best: np.ndarray
    counts: np.ndarray
    claim_cost: np.ndarray
    claim_k: np.ndarray
    tag: tuple


@njit(cache=True, nogil=True, inline="always")
def slot_size(D):  # pragma: no cover - numba
    """int16 elements of one path vector's slot for D disparities: a sentinel, the D values, a sentinel, then padding
    to a whole number of 64-byte cache lines, so that with the buffer's element 1 on a cache line every slot's values
    start on one (the kernel writes each vector whole; docs/matching.md, "Fourth round: buffers on a cache line").
    The buffers' makers and the kernel both call it.

    >>> slot_size(64), slot_size(128)
    (96, 160)
    """
    return -(-(D + 2) // _SLOT_ALIGN) * _SLOT_ALIGN


def path_slots(n: int, D: int, width: int | None = None) -> np.ndarray:
    """``n`` path-vector slots of ``width`` values (default ``slot_size(D)``; the 4/8-path kernel's are D + 2), flat:
    zeros (the path start) between a sentinel either side, element 1 (slot 0's first disparity) on a cache line."""
    P = aligned_zeros((n, slot_size(D) if width is None else width), np.int16, lead=1)
    P[:, 0] = P[:, D + 1] = _SENTINEL
    return P.reshape(-1)


def row_pass_buffers(H: int, W: int, D: int, warm_rows: int = 0) -> RowPassBuffers:
    """Fresh buffers for one worker (path vectors zero = the path start, sentinels in place)."""
    slots = W + H + 1
    return RowPassBuffers(
        costs=aligned_empty((warm_rows + 2, W * D), np.int16), srow=aligned_empty((2, W * D), np.int16),
        path_v=path_slots(slots, D), min_v=np.zeros(slots, np.int16), path_h=path_slots(2, D),
        path_r=path_slots(2, D),
        row_min=aligned_empty(W, np.int16), k_index=np.arange(D, dtype=np.int16),
        right_sums=aligned_empty(W + D - 1, np.int16), right_k=aligned_empty(W + D - 1, np.int16),
        best=np.empty(W, np.int64), counts=np.zeros(3, np.int64),
        claim_cost=np.empty(W, np.int16), claim_k=np.empty(W, np.int16), tag=disparity_tag(D))


def row_pass_bytes(H: int, W: int, D: int, warm_rows: int = 0) -> int:
    """Bytes of ``row_pass_buffers(H, W, D, warm_rows)``."""
    E = slot_size(D)
    slots = W + H + 1
    return (2 * (warm_rows + 4) * W * D + 2 * slots * E + 2 * slots + 2 * 2 * 2 * E + 2 * W + 2 * D
            + 2 * 2 * (W + D - 1) + 8 * W + 24 + 2 * 2 * W)


@njit(_nrt=False, cache=True, nogil=True, pipeline_class=NoAliasCompiler)
def three_path_stripe(images, cost, settings, plan, cbufs, bufs, out):  # pragma: no cover - numba
    """Aggregate the left, top and right paths over ``plan``'s rows and resolve each row at once.

    One pass over the columns per row r runs the left-to-right sweep of row r (top and left paths) and, beside it,
    the right-to-left sweep of row r - 1 (right path), which is then resolved; one more pass ends the stripe. The
    two rows use separate buffers, so the numbers are those of one sweep after the other.

    Parameters
    ----------
    images : CostImages
        Left image and census quarters / gradient channels (see :mod:`.cost`).
    cost : CostSettings
    settings : aggregate.PassSettings
        Penalties and selection settings (``path_mask`` is not read: the directions are fixed).
    plan : StripePlan
    cbufs : cost.RowCostBuffers
        This worker's cost state.
    bufs : RowPassBuffers
        This worker's row buffers; the path vectors the first row reads (slots ``n_rows + 1`` ..
        ``n_rows + W``) must hold zeros (the path start) on entry.
    out : aggregate.PassOutputs
        Disparity maps, and the flat sum volume when ``plan.keep_sums``.
    """
    limg = images.left
    W = limg.shape[1]
    p1_32 = np.int32(settings.p1)
    p2_32 = np.int32(settings.p2)
    p1c_32 = np.int32(settings.p1_cross)
    cross_texture = settings.cross_texture
    pscale = images.penalty_scale
    adaptive = settings.adaptive_p2
    dmin = cost.min_disparity
    srows = bufs.srow
    PV = bufs.path_v
    MV = bufs.min_v
    PH = bufs.path_h
    PR = bufs.path_r
    nsrow = bufs.row_min
    kidx = bufs.k_index
    rv = bufs.right_sums
    rd = bufs.right_k
    right_view = settings.right_view
    Sf = out.sums
    D = tag_disparities(bufs.tag)  # len(bufs.k_index), as a constant: compiled once per D
    E = slot_size(D)
    vec = vector_paths(bufs.tag)  # whole-vector path updates (pathvec): a constant, the other branch is dropped
    top = np.int16(-1)  # 65535 read as unsigned: where the vectors' minima (umin16, non-negative values) start
    big = np.int16(_INT16_MAX)
    fused_view = vec and right_view  # the right view made in the right-to-left sweep (pathvec.right_path_view)
    zero = np.int16(0)
    n_rows = plan.n_rows
    cached = plan.cached
    tail_start = n_rows - plan.tail
    costs = bufs.costs
    n_warm = costs.shape[0] - 2  # rows 0 .. n_warm - 1: the tail's costs; the last two: the two current rows
    slot = 0  # costs row of row r
    slot_p = 0  # costs row of row r - 1
    for r in range(n_rows + 1):
        y = plan.y_first + r
        cur = r < n_rows  # row r: the left-to-right sweep in this pass over the columns
        warming = r < plan.warmup
        prev = r - 1 >= plan.warmup  # row r - 1: the right-to-left sweep in this pass
        srow = srows[r & 1]  # row r's sums; row r - 1's are in the other row of srows
        srow_p = srows[1 - (r & 1)]
        slot_p = slot
        if cur:
            if warming and cached:  # made by the stripe above on this worker (its last rows)
                slot = r
            else:
                slot = r - tail_start if r >= tail_start else n_warm + (r & 1)
                row_cost(images, cost, y, r == 0 and not cached, 1, cbufs, costs[slot])
        crow = costs[slot]
        crow_p = costs[slot_p]
        # where D is 32, 64 or 128 the left / right paths' previous vectors and the right view's window are
        # carried from pixel to pixel in registers (pathvec.PathVector): PH / PR serve the loops only
        if not vec:
            for k in range(D):
                PH[k + 1] = zero
                PR[k + 1] = zero
        hvec = vector_of(zero, bufs.tag)
        rvec = vector_of(zero, bufs.tag)
        wvv = vector_of(big, bufs.tag)
        wvk = vector_of(top, bufs.tag)
        mh_run = zero  # the left / right path's previous minimum, carried in a register
        mr_run = zero
        yp = y - 1
        for i in range(W):
            if prev:  # --- row r - 1, right to left: the right path, the complete sums and their minimum
                x = W - 1 - i
                cb = x * D
                p1, p2 = pixel_penalties(p1_32, p2_32, pscale[yp, x])
                rhs = i & 1
                whs = 1 - rhs
                mh = mr_run
                qh = add16(mh, _p2_at(limg, yp, x, yp, x + 1, p1, p2, adaptive) if adaptive else p2)
                wh = whs * E
                rh = rhs * E
                if fused_view:
                    nh, ns, fv, fk, rvec, wvv, wvk = right_path_view(rvec, crow_p, cb, mh, qh, p1, srow_p, wvv, wvk,
                                                                     bufs.tag)
                    if i > 0:  # right pixel i - 1 is complete
                        rv[i - 1] = fv
                        rd[i - 1] = fk
                elif vec:
                    nh, ns, rvec = right_path_sum(rvec, crow_p, cb, mh, qh, p1, srow_p, bufs.tag)
                else:
                    nh = top
                    ns = top
                    for k in range(D):
                        vh = _lr(PR, rh, crow_p[_U(cb + k)], mh, qh, p1, k)
                        PR[_U(wh + 1 + k)] = vh
                        nh = umin16(nh, vh)
                        sm = add16(vh, srow_p[_U(cb + k)])
                        srow_p[_U(cb + k)] = sm
                        ns = umin16(ns, sm)
                mr_run = nh
                nsrow[x] = ns
            if cur:  # --- row r, left to right: the top path (slot w = x - r + n_rows, predecessor at w + 1), left
                x = i
                cb = x * D
                p1, p2 = pixel_penalties(p1_32, p2_32, pscale[y, x])  # times the pixel's weak-texture factor
                p1v = cross_penalty(p1c_32, pscale[y, x], cross_texture)  # the top path's P1
                wvs = x - r + n_rows
                wv = wvs * E
                rvb = wv + E
                mv = MV[wvs + 1]
                qv = add16(mv, _p2_at(limg, y, x, y - 1, x, p1v, p2, adaptive) if adaptive else p2)
                nv = top
                if warming and vec:
                    nv = top_path(PV, rvb, wv, crow, cb, mv, qv, p1v, bufs.tag)
                elif warming:
                    for k in range(D):
                        vv = _lr(PV, rvb, crow[_U(cb + k)], mv, qv, p1v, k)
                        PV[_U(wv + 1 + k)] = vv
                        nv = umin16(nv, vv)
                else:
                    rhs = x & 1
                    whs = 1 - rhs
                    mh = mh_run
                    qh = add16(mh, _p2_at(limg, y, x, y, x - 1, p1, p2, adaptive) if adaptive else p2)
                    wh = whs * E
                    rh = rhs * E
                    if vec:
                        nv, nh, hvec = top_and_left(PV, rvb, wv, hvec, crow, cb, mv, qv, p1v, mh, qh, p1, srow,
                                                    bufs.tag)
                    else:
                        nh = top
                        for k in range(D):
                            c = crow[_U(cb + k)]
                            vv = _lr(PV, rvb, c, mv, qv, p1v, k)
                            vh = _lr(PH, rh, c, mh, qh, p1, k)
                            PV[_U(wv + 1 + k)] = vv
                            PH[_U(wh + 1 + k)] = vh
                            nv = umin16(nv, vv)
                            nh = umin16(nh, vh)
                            srow[_U(cb + k)] = add16(vv, vh)
                    mh_run = nh
                MV[wvs] = nv
        if not prev:
            continue
        if fused_view:  # the window holds the row's last D right pixels
            store_vector(rv, W - 1, wvv)
            store_vector(rd, W - 1, wvk)
        elif right_view:
            right_view_row(srow_p, rv, rd, W, bufs.tag)
        if plan.keep_sums:
            base = yp * W * D
            for j in range(W * D):
                Sf[_U(base + j)] = srow_p[_U(j)]
        if plan.select:
            select_row(yp, settings, dmin, cost.num_disparities, srow_p, nsrow, kidx, rv, rd, bufs.best, bufs.counts,
                       bufs.claim_cost, bufs.claim_k, out, bufs.tag)
