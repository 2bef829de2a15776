"""Winner selection of one row of complete SGM sums (numba): ``right_view_row`` and ``select_row``, shared by
both kernels.

Winner-takes-all (the first index of the minimum), uniqueness, parabola subpixel, the left-right check
("full": against the right view's winner from the same sums; "opencv": against the right pixels' claims) and
the right-view disparity. The kernels call it once per row, while the row's sums are still in cache.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from stereo_classic.matching._kernels.cost import NoAliasCompiler, valid_range
from stereo_classic.matching._kernels.intrinsics import MASK_LANES, cttz64, eq_mask32, min16, pick16
from stereo_classic.matching._kernels.tags import tag_disparities

# ``_nrt=False``: kernels that run per row and allocate nothing, compiled without numba's reference counts on their
# array arguments (atomic updates, on every call, of counters both workers share; docs/matching.md, seventh round).
__all__ = ["select_row", "right_view_row"]

_INT16_MAX = 32767
#: Rounds of the right view's sweep: pixels of one round are 32 int16 apart, a whole vector of the widest
#: (512-bit) registers.
_ROUNDS = 32
_U = np.uint64  # unsigned flat indices: no wraparound code, contiguous vector loads


@njit(_nrt=False, cache=True, nogil=True)
def first_equal(row, start, n, value):  # pragma: no cover - numba
    """The first i in 0 .. n - 1 with ``row[start + i] == value`` (``_INT16_MAX`` when there is none): whole blocks of
    MASK_LANES by a vector compare read as a bit mask and its trailing zeros (``eq_mask32``), the rest one by one.
    About 1.6 ns a pixel of 64 disparities against 6.3 for the select-and-reduce loop it replaces. Not inlined by
    numba into ``select_row`` (LLVM decides): inlined there, the one-sweep kernel (into which both are compiled) ran
    about 10 % slower on the OAK-D VGA pair (medians of 9 separate processes alternated: 20.7 against 18.5 ms)."""
    i0 = 0
    while i0 + MASK_LANES <= n:
        m = eq_mask32(row, _U(start + i0), value)
        if m != _U(0):
            return i0 + np.int64(cttz64(m))
        i0 += MASK_LANES
    for i in range(i0, n):
        if row[_U(start + i)] == value:
            return i
    return _INT16_MAX


@njit(_nrt=False, cache=True, nogil=True, pipeline_class=NoAliasCompiler)
def select_row(y, settings, dmin, ndisp, sums, row_min, k_index, right_sums, right_k, best, counts, claim_cost,
               claim_k, out, tag):  # pragma: no cover - numba
    """Resolve row ``y`` from its complete sums ``sums[x * D + k]`` (int16; D = ``len(k_index)``: the ``ndisp``
    disparities of the range, then padding, which sums higher than any of them), their minima ``row_min[x]`` and the
    right view's winners ``right_k`` (``right_sums`` / ``right_k`` per right pixel q = W - 1 - dmin - x_right:
    the lowest sum landing there and its disparity index, ties to the smallest; made by ``right_view_row``).

    Winner-takes-all (first index of the minimum; a winner whose match is outside the right image, which a
    neutral ``CostSettings.outside_cost`` allows, is unknown and counted in ``counts[2]``),
    uniqueness, parabola subpixel, then the left-right check of the row ("full":
    against the right view's winner; "opencv": against the claims, ties to the largest x), and the right-view
    disparity. ``tag``: ``disparity_tag(D)`` (D read from it as a constant).
    """
    uniq = settings.uniqueness
    lr_thr = settings.lr_threshold
    lr_claims = settings.lr_claims
    subpix = settings.subpixel
    right_view = settings.right_view
    srow = sums
    nsrow = row_min
    kidx = k_index
    rv = right_sums
    rd = right_k
    ccost = claim_cost
    ck = claim_k
    disp = out.disparity
    dispR = out.disparity_right
    W = disp.shape[1]
    D = tag_disparities(tag)  # len(k_index), as a constant: compiled once per D (tags.py)
    big = np.int16(_INT16_MAX)
    minus1 = np.int16(-1)
    nan = np.float32(np.nan)
    full_lr = right_view and lr_thr >= 0.0 and not lr_claims
    if lr_claims:
        for q in range(W):
            ccost[q] = big
            ck[q] = minus1
    for x in range(W):
        k_lo, k_hi = valid_range(x, W, dmin, ndisp)
        if k_lo > k_hi:
            disp[y, x] = nan
            best[x] = -1
            continue
        ns = nsrow[x]
        db = x * D
        bk = first_equal(srow, db, D, ns)  # the first index of the minimum
        best[x] = bk
        if bk < k_lo or bk > k_hi:  # the match is outside the right image (its neutral cost won): not a measurement
            disp[y, x] = nan
            best[x] = -1
            counts[2] += 1
            continue
        if uniq > 0.0:  # the lowest sum of the range but at bk - 1 .. bk + 1: one pass over the D sums
            m2 = big
            lo = np.int16(k_lo)
            hi = np.int16(k_hi)
            b0 = np.int16(bk - 1)
            b1 = np.int16(bk + 1)
            for k in range(D):
                kk = kidx[k]
                skip = (kk < lo) | (kk > hi) | ((kk >= b0) & (kk <= b1))
                m2 = min16(m2, pick16(skip, big, srow[_U(db + k)]))
            if m2 < big and np.float64(m2) * (1.0 - uniq) < np.float64(ns):
                disp[y, x] = nan
                counts[0] += 1
                continue
        if full_lr and abs(np.float64(bk - rd[W - 1 - x + bk])) > lr_thr:  # against the right view's winner
            disp[y, x] = nan
            counts[1] += 1
            continue
        if lr_claims:  # the right pixel x - d is claimed by the lowest sum landing there (ties: the largest x)
            xr = x - dmin - bk
            if ns <= ccost[xr]:
                ccost[xr] = ns
                ck[xr] = np.int16(bk)
        off = 0.0
        if subpix and bk - 1 >= k_lo and bk + 1 <= k_hi:
            sm_ = np.int64(srow[_U(db + bk - 1)])
            sp_ = np.int64(srow[_U(db + bk + 1)])
            den = sm_ + sp_ - 2 * np.int64(ns)
            if den > 0:
                off = (sm_ - sp_) / (2.0 * den)
        disp[y, x] = np.float32(dmin + bk + off)
    if lr_claims:
        # reject x only when the claims at both x - floor(d) and x - ceil(d) disagree with it
        for x in range(W):
            dv = disp[y, x]
            if dv != dv:
                continue
            t = np.float64(dv) - dmin
            kf = np.int64(np.floor(t))
            kc = np.int64(np.ceil(t))
            xf = x - dmin - kf
            xc = x - dmin - kc
            bad_f = 0 <= xf < W and ck[xf] >= 0 and abs(np.float64(ck[xf] - kf)) > lr_thr
            bad_c = 0 <= xc < W and ck[xc] >= 0 and abs(np.float64(ck[xc] - kc)) > lr_thr
            if bad_f and bad_c:
                disp[y, x] = nan
                counts[1] += 1
    if right_view:
        nq = rv.shape[0]
        for xr in range(W):
            q = W - 1 - dmin - xr
            if 0 <= q < nq and 0 <= rd[q] < ndisp:
                dispR[y, xr] = np.float32(dmin + rd[q])
            else:
                dispR[y, xr] = nan


@njit(_nrt=False, cache=True, nogil=True, pipeline_class=NoAliasCompiler)
def right_view_row(srow, rv, rd, W, tag):  # pragma: no cover - numba
    """The right view's winner of one row: per right pixel q = W - 1 - dmin - x_right, the lowest complete sum
    landing there (``rv``) and its disparity index (``rd``; ties: the smallest index, -1: none); ``tag``:
    ``disparity_tag(D)``.

    Pixel x adds its sums to q = W - 1 - x + k. Consecutive pixels overlap by D - 1 entries at an offset of one
    element, so a plain sweep over x reads every vector across two stores still in flight (store forwarding
    fails: measured 18 ms a KITTI frame). The sweep is made in 32 rounds instead (``_ROUNDS``), round p taking x = p,
    p + 32, ...: within a round consecutive pixels are one whole 32-lane vector apart. The tie rule does not depend on
    the order (lower sum, then lower index).
    """
    D = tag_disparities(tag)  # disparities per pixel, a constant: compiled once per D (tags.py)
    big = np.int16(_INT16_MAX)
    minus1 = np.int16(-1)
    for q in range(rv.shape[0]):
        rv[q] = big
        rd[q] = minus1
    for p in range(_ROUNDS):
        for x in range(p, W, _ROUNDS):
            q0 = W - 1 - x
            b = x * D
            for k in range(D):
                sv = srow[_U(b + k)]
                old = rv[_U(q0 + k)]
                rdo = rd[_U(q0 + k)]
                k16 = np.int16(k)
                take = (sv < old) | ((sv == old) & (k16 < rdo))
                rv[_U(q0 + k)] = min16(sv, old)
                rd[_U(q0 + k)] = pick16(take, k16, rdo)
