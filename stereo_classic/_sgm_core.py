"""Fused two-thread semi-global matching kernels (numba).

Design (see ``.notes/readme_sgm_core.md``):

* One int16 sum volume ``S`` (H, W, D), disparity innermost. No stored cost volume and no
  per-path volumes: costs are recomputed per pixel (census: popcount of a xor; SAD: running box
  sums kept per thread), and the path recursions keep only row buffers.
* The 8 directions are split into a *forward* pass (rows top-down, x left-to-right: from the left,
  from above, from the top-left, from the top-right) and a *backward* pass (rows bottom-up, x
  right-to-left: the four opposite directions).
* Phase 1: thread A runs the forward pass over the top half of the rows, thread B the backward
  pass over the bottom half, each *storing* its 4-path partial sums into ``S``. Phase 2 (after the
  barrier): thread A continues forward over the bottom half and thread B backward over the top
  half, each *adding* its 4 paths to the stored partial sum; every row is then complete and is
  resolved at once (winner-takes-all, uniqueness, parabola subpixel, right-view argmin, left-right
  check) while it is still in cache: no separate argmin pass.
* Row buffers are updated in place. The two diagonal directions use a skewed index
  (``x - y + H`` and ``x + y + 1``) so that the previous pixel on the path sits at the same slot as
  the current one: three (W + H + 1, D + 2) int16 buffers per thread (about 1.2 MB at
  1242 x 375 x 128), small enough for a 2 MB L2.
* Arithmetic stays in int16 through LLVM intrinsics (``_sgm_intrinsics``).

Bounds: every path value satisfies ``L <= C + P2`` and costs are at most ``invalid_cost =
Cmax + 2 * P2 + 1``, so ``8 * (invalid_cost + P2) <= 32767`` keeps the 8-path sum inside int16
(checked by ``check_penalties``). Disparities whose match falls outside the right image get
``invalid_cost``, which is larger than ``min_prev + P2`` for every predecessor, so they never
influence the path minimum of a valid disparity and never win; a pixel is NaN only when no
disparity of the range maps inside the right image.
"""

from __future__ import annotations

import math
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numba import njit

from ._sgm_cost import (
    SAD_PIXEL_MAX,
    _clamp,
    census_bits,
    census_pixel_cost,
    census_reverse_row,
    census_transform,
    cost_volume_kernel,
    fill_invalid,
    sad_colsum_advance,
    sad_colsum_init,
    sad_hsum_advance,
    sad_hsum_init,
    sad_pixel_cost,
    sad_prefilter,
)
from ._sgm_intrinsics import add16, min16, sub16

__all__ = ["sgm_match", "memory_bytes", "cost_volume", "check_penalties", "cost_scale", "ALL_PATHS", "PATH_NAMES"]

#: Bit i of a path mask selects direction PATH_NAMES[i]. Bits 0-3 run in the forward pass,
#: bits 4-7 in the backward pass. (dx, dy) is the step from the previous pixel on the path.
PATH_NAMES = ("left", "top", "top-left", "top-right", "right", "bottom", "bottom-right", "bottom-left")
PATH_STEPS = ((1, 0), (0, 1), (1, 1), (-1, 1), (-1, 0), (0, -1), (-1, -1), (1, -1))
ALL_PATHS = 0xFF
FOUR_PATHS = 0x33  # left, top, right, bottom

_INT16_MAX = 32767
_SENTINEL = 16383  # padding at both disparity ends of every path vector: "no neighbour"
_KIND = {"census": 0, "sad": 1}


# ----------------------------------------------------------------------------------------------
# parameters


def cost_scale(cost: str, block_size: int, census_window: tuple[int, int], p2: int) -> tuple[int, int]:
    """(shift, cmax): the SAD window sum is shifted right by ``shift`` so that the SGM sums fit
    int16; ``cmax`` is the largest cost after scaling. Census has shift 0 and cmax = bits."""
    if cost == "census":
        return 0, census_bits(census_window)
    raw = block_size * block_size * SAD_PIXEL_MAX
    shift = 0
    while ((raw >> shift) + 3 * (p2 >> shift) + 1) * 8 > _INT16_MAX:
        shift += 1
    return shift, raw >> shift


def check_penalties(cost: str, block_size: int, census_window: tuple[int, int], p1: int, p2: int) -> None:
    """Raise ValueError when the penalties cannot be represented in the int16 sums."""
    if not (0 <= p1 <= p2):
        raise ValueError(f"penalties must satisfy 0 <= p1 <= p2, got p1={p1}, p2={p2}")
    shift, cmax = cost_scale(cost, block_size, census_window, p2)
    p2s = p2 >> shift
    if 8 * (cmax + 3 * p2s + 1) > _INT16_MAX:
        limit = (_INT16_MAX // 8 - 1 - cmax) // 3
        raise ValueError(f"`p2` too large for int16 sums with cost {cost!r}: at most {limit}, got {p2}")


# ----------------------------------------------------------------------------------------------
# kernels


@njit(cache=True, nogil=True, inline="always")
def _path_step(C, prev, mp, p1, p2, out, acc):  # pragma: no cover - numba
    """One pixel of one path: out[1:D+1] = L, acc += L; returns min(L).

    prev/out are (D + 2,) vectors whose ends hold the sentinel (no neighbour at d = -1, D).
    """
    D = C.shape[0]
    pm = prev[0:D]
    p0 = prev[1:D + 1]
    pp = prev[2:D + 2]
    o = out[1:D + 1]
    base = add16(mp, p2)
    mn = np.int16(_INT16_MAX)
    for k in range(D):
        v = min16(min16(p0[k], add16(min16(pm[k], pp[k]), p1)), base)
        v = add16(sub16(C[k], mp), v)
        o[k] = v
        acc[k] = add16(acc[k], v)
        mn = min16(mn, v)
    return mn


@njit(cache=True, nogil=True, inline="always")
def _copy_vec(src, dst):  # pragma: no cover - numba
    D = src.shape[0] - 2
    s = src[1:D + 1]
    d = dst[1:D + 1]
    for k in range(D):
        d[k] = s[k]


@njit(cache=True, nogil=True, inline="always")
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


@njit(cache=True, nogil=True)
def _select_row(Srow, dmin, uniq, lr_thr, subpix, drow, drrow, rv, rd, best):  # pragma: no cover
    """Resolve one complete row of sums: WTA, uniqueness, subpixel, right view, LR check.

    rv/rd: (W + D - 1,) scratch indexed by q = W - 1 - x + k (the right pixel x - dmin - k).
    """
    W, D = Srow.shape
    big = np.int16(_INT16_MAX)
    for q in range(rv.shape[0]):
        rv[q] = big
        rd[q] = np.int16(-1)
    nan = np.float32(np.nan)
    for x in range(W):
        k_lo = x - dmin - W + 1
        if k_lo < 0:
            k_lo = 0
        k_hi = x - dmin
        if k_hi > D - 1:
            k_hi = D - 1
        if k_lo > k_hi:
            best[x] = -1
            drow[x] = nan
            continue
        s = Srow[x]
        sv = s[k_lo:k_hi + 1]
        n = k_hi - k_lo + 1
        m = big
        for i in range(n):
            m = min16(m, sv[i])
        bi = big
        for i in range(n):
            bi = min16(bi, np.int16(i) if sv[i] == m else big)
        b = k_lo + np.int64(bi)
        best[x] = b
        # right view: candidates for right pixel x - dmin - k, ties keep the smallest k
        q0 = W - 1 - x + k_lo
        rvs = rv[q0:q0 + n]
        rds = rd[q0:q0 + n]
        for i in range(n):
            v = sv[i]
            old = rvs[i]
            lt = v < old
            rvs[i] = v if lt else old
            rds[i] = np.int16(k_lo + i) if lt else rds[i]
        if uniq > 0.0:
            m2 = big
            for k in range(k_lo, b - 1):
                m2 = min16(m2, s[k])
            for k in range(b + 2, k_hi + 1):
                m2 = min16(m2, s[k])
            if m2 < big and np.float64(m2) * (1.0 - uniq) < np.float64(m):
                drow[x] = nan
                continue
        off = 0.0
        if subpix and b - 1 >= k_lo and b + 1 <= k_hi:
            sm = np.int64(s[b - 1])
            sp = np.int64(s[b + 1])
            den = sm + sp - 2 * np.int64(m)
            if den > 0:
                off = (sm - sp) / (2.0 * den)
        drow[x] = np.float32(dmin + b + off)
    if lr_thr >= 0.0:
        for x in range(W):
            b = best[x]
            if b < 0 or drow[x] != drow[x]:
                continue
            q = W - 1 - x + b
            if abs(np.float64(b - rd[q])) > lr_thr:
                drow[x] = nan
    # right-view disparity of right pixel xr: q = W - 1 - dmin - xr
    nq = rv.shape[0]
    for xr in range(W):
        q = W - 1 - dmin - xr
        if 0 <= q < nq and rd[q] >= 0:
            drrow[xr] = np.float32(dmin + rd[q])
        else:
            drrow[xr] = nan


@njit(cache=True, nogil=True)
def sgm_pass(kind, lcode, rcode, lsob, lint, rsob, rint, limg,
             S, y_first, nrows, step, accumulate, select, init_cost,
             bufV, minV, bufA, minA, bufB, minB, work,
             colsum, hsum, rrev, srev, irev,
             dmin, h, shift, cmax, cinv, p1, p2, adaptive, path_mask,
             uniq, lr_thr, subpix, disp, dispR, rv, rd, best):  # pragma: no cover - numba
    """Run the forward (step=+1) or backward (step=-1) 4-path pass over nrows rows from y_first.

    accumulate: add to S instead of storing; select: resolve each row after it is aggregated;
    init_cost: (SAD) build the column sums from scratch at the first row.
    """
    H, W, D = S.shape
    m4 = (path_mask & 15) if step > 0 else ((path_mask >> 4) & 15)
    C = work[0, 1:D + 1]
    tmp = work[1]
    hprev = work[2]
    hnext = work[3]
    sent = np.int16(_SENTINEL)
    zero = np.int16(0)
    p1_16 = np.int16(p1)
    p2_16 = np.int16(p2)
    cinv16 = np.int16(cinv)
    for r in range(nrows):
        y = y_first + step * r
        # --- per-row cost preparation
        if kind == 0:
            census_reverse_row(rcode[y], rrev, dmin)
        else:
            if r == 0 and init_cost:
                sad_colsum_init(colsum, y, lsob, lint, rsob, rint, srev, irev, dmin, h)
            else:
                sad_colsum_advance(colsum, y, step, lsob, lint, rsob, rint, srev, irev, dmin, h)
        for k in range(1, D + 1):
            hprev[k] = zero
        hprev[0] = sent
        hprev[D + 1] = sent
        hnext[0] = sent
        hnext[D + 1] = sent
        mh = zero
        Srow = S[y]
        for i in range(W):
            x = i if step > 0 else W - 1 - i
            # --- cost of pixel (y, x)
            if kind == 0:
                census_pixel_cost(lcode[y, x], rrev, x, C)
            else:
                if i == 0:
                    sad_hsum_init(hsum, colsum, x, h)
                else:
                    sad_hsum_advance(hsum, colsum, x, step, h)
                sad_pixel_cost(hsum, shift, cmax, C)
            fill_invalid(C, x, W, dmin, cinv16)
            acc = Srow[x]
            if not accumulate:
                for k in range(D):
                    acc[k] = zero
            # --- horizontal (from x - step)
            if m4 & 1:
                p2e = _p2_at(limg, y, x, y, x - step, p1_16, p2_16, adaptive)
                mh = _path_step(C, hprev, mh, p1_16, p2e, hnext, acc)
                hprev, hnext = hnext, hprev
            # --- vertical (from y - step)
            if m4 & 2:
                p2e = _p2_at(limg, y, x, y - step, x, p1_16, p2_16, adaptive)
                minV[x] = _path_step(C, bufV[x], minV[x], p1_16, p2e, tmp, acc)
                _copy_vec(tmp, bufV[x])
            # --- diagonal A (from (y - step, x - step)): slot x - y + H
            if m4 & 4:
                s = x - y + H
                p2e = _p2_at(limg, y, x, y - step, x - step, p1_16, p2_16, adaptive)
                minA[s] = _path_step(C, bufA[s], minA[s], p1_16, p2e, tmp, acc)
                _copy_vec(tmp, bufA[s])
            # --- diagonal B (from (y - step, x + step)): slot x + y + 1
            if m4 & 8:
                s = x + y + 1
                p2e = _p2_at(limg, y, x, y - step, x + step, p1_16, p2_16, adaptive)
                minB[s] = _path_step(C, bufB[s], minB[s], p1_16, p2e, tmp, acc)
                _copy_vec(tmp, bufB[s])
        if select:
            _select_row(Srow, dmin, uniq, lr_thr, subpix, disp[y], dispR[y], rv, rd, best)


# ----------------------------------------------------------------------------------------------
# driver

_POOL: ThreadPoolExecutor | None = None
_POOL_LOCK = threading.Lock()


def _pool() -> ThreadPoolExecutor:
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(max_workers=1, thread_name_prefix="sgm")
        return _POOL


def _thread_buffers(H: int, W: int, D: int, kind: int, h: int) -> dict[str, np.ndarray]:
    n_diag = W + H + 1
    bufV = np.zeros((W, D + 2), np.int16)
    bufA = np.zeros((n_diag, D + 2), np.int16)
    bufB = np.zeros((n_diag, D + 2), np.int16)
    for b in (bufV, bufA, bufB):
        b[:, 0] = _SENTINEL
        b[:, D + 1] = _SENTINEL
    work = np.zeros((4, D + 2), np.int16)
    work[:, 0] = _SENTINEL
    work[:, D + 1] = _SENTINEL
    if kind == 1:
        colsum = np.zeros((W + 2 * h, D), np.int16)
        rrev = np.zeros(1, np.uint64)
        srev = np.zeros(W + 2 * h + D - 1, np.int16)
        irev = np.zeros(W + 2 * h + D - 1, np.int16)
    else:
        colsum = np.zeros((1, D), np.int16)
        rrev = np.zeros(W + D - 1, np.uint64)
        srev = irev = np.zeros(1, np.int16)
    return {
        "bufV": bufV, "minV": np.zeros(W, np.int16),
        "bufA": bufA, "minA": np.zeros(n_diag, np.int16),
        "bufB": bufB, "minB": np.zeros(n_diag, np.int16),
        "work": work, "colsum": colsum, "hsum": np.zeros(D, np.int32),
        "rrev": rrev, "srev": srev, "irev": irev,
        "rv": np.empty(W + D - 1, np.int16), "rd": np.empty(W + D - 1, np.int16),
        "best": np.empty(W, np.int64),
    }


def memory_bytes(height: int, width: int, num_disparities: int, *, paths: int = 8, lr_check: bool = True,
                 cost: str = "census", block_size: int = 5) -> int:
    """Bytes ``sgm_match`` allocates for an image of this size (without the input images).

    The int16 sum volume (2 * H * W * D) dominates; the rest is two float32 outputs, the cost
    inputs (census codes or prefiltered images) and per-thread row buffers.
    """
    H, W, D = int(height), int(width), int(num_disparities)
    h = block_size // 2
    total = 2 * H * W * D  # sum volume
    total += 2 * 4 * H * W  # left and right disparity
    total += 2 * 8 * H * W if cost == "census" else 4 * 2 * H * W + 2 * (H + 2) * (W + 2)
    per_thread = 2 * (D + 2) * (W + 2 * (W + H + 1) + 4) + 2 * 3 * (W + H + 1)
    per_thread += 2 * 2 * (W + D) + 8 * W + 4 * D
    per_thread += 2 * (W + 2 * h) * D + 2 * 2 * (W + 2 * h + D) if cost == "sad" else 8 * (W + D)
    return total + 2 * per_thread


def _prepare_cost(left, right, cost, census_window):
    if cost == "census":
        lcode = census_transform(left, census_window)
        rcode = census_transform(right, census_window)
        dummy = np.zeros((1, 1), np.int16)
        return lcode, rcode, dummy, dummy, dummy, dummy
    lsob, lint = sad_prefilter(left)
    rsob, rint = sad_prefilter(right)
    dummy = np.zeros((1, 1), np.uint64)
    return dummy, dummy, lsob, lint, rsob, rint


def _run(left, right, *, cost, min_disparity, num_disparities, block_size, census_window, p1, p2,
         path_mask, adaptive_p2, uniqueness, lr_check, subpixel, threads, select=True):
    if cost not in _KIND:
        raise ValueError(f"`cost` must be one of {sorted(_KIND)}, got {cost!r}")
    check_penalties(cost, block_size, census_window, int(p1), int(p2))
    kind = _KIND[cost]
    H, W = left.shape
    D = int(num_disparities)
    dmin = int(min_disparity)
    h = block_size // 2 if kind == 1 else 0
    shift, cmax = cost_scale(cost, block_size, census_window, int(p2))
    p1s, p2s = int(p1) >> shift, int(p2) >> shift
    cinv = cmax + 2 * p2s + 1
    timings = {}

    t0 = time.perf_counter()
    lcode, rcode, lsob, lint, rsob, rint = _prepare_cost(left, right, cost, census_window)
    t1 = time.perf_counter()
    timings["cost"] = (t1 - t0) * 1e3

    S = np.empty((H, W, D), np.int16)
    disp = np.empty((H, W), np.float32)
    dispR = np.empty((H, W), np.float32)
    bufs = [_thread_buffers(H, W, D, kind, h) for _ in range(2)]
    lr_thr = -1.0 if lr_check is None else float(lr_check)
    mid = H // 2

    def job(t, phase):
        b = bufs[t]
        if t == 0:  # forward: top half, then bottom half
            y_first, nrows, step = (0, mid, 1) if phase == 0 else (mid, H - mid, 1)
            fresh = phase == 0 or mid == 0
        else:  # backward: bottom half, then top half
            y_first, nrows, step = (H - 1, H - mid, -1) if phase == 0 else (mid - 1, mid, -1)
            fresh = phase == 0 or H - mid == 0
        if nrows == 0:
            return
        sgm_pass(kind, lcode, rcode, lsob, lint, rsob, rint, left,
                 S, y_first, nrows, step, phase == 1, select and phase == 1, fresh,
                 b["bufV"], b["minV"], b["bufA"], b["minA"], b["bufB"], b["minB"], b["work"],
                 b["colsum"], b["hsum"], b["rrev"], b["srev"], b["irev"],
                 dmin, h, shift, cmax, cinv, p1s, p2s, bool(adaptive_p2), int(path_mask),
                 float(uniqueness), lr_thr, bool(subpixel), disp, dispR, b["rv"], b["rd"], b["best"])

    for phase in (0, 1):
        if threads >= 2:
            fut = _pool().submit(job, 1, phase)
            job(0, phase)
            fut.result()
        else:
            job(0, phase)
            job(1, phase)
    t2 = time.perf_counter()
    timings["aggregate"] = (t2 - t1) * 1e3
    timings["select"] = 0.0  # fused into the second phase of "aggregate"
    return disp, dispR, S, timings


def sgm_match(left: np.ndarray, right: np.ndarray, *, cost: str = "census", min_disparity: int = 0,
              num_disparities: int = 64, block_size: int = 5, census_window: tuple[int, int] = (9, 7),
              p1: int = 10, p2: int = 120, paths: int = 8, adaptive_p2: bool = False,
              uniqueness: float = 0.0, lr_check: float | None = 1.0, subpixel: bool = True,
              threads: int = 2) -> tuple[np.ndarray, np.ndarray | None, dict[str, float]]:
    """Semi-global matching of a rectified grey pair (inputs already validated by the caller).

    Parameters
    ----------
    left, right : (H, W) uint8, C-contiguous, same shape.
    cost : "census" (census_window, Hamming distance) or "sad" (block_size x block_size SAD on
        the x-Sobel + intensity/4 prefilter). Penalties are in the units of the cost: bits for
        census, raw window SAD for "sad" (scaled internally with the cost so the sums fit int16).
    min_disparity, num_disparities : disparity range [min, min + num), d = x_left - x_right.
    p1, p2 : SGM penalties, 0 <= p1 <= p2.
    paths : 8 or 4 (left, right, top, bottom).
    adaptive_p2 : P2 / (1 + |I(p) - I(p - r)|), never below P1.
    uniqueness : reject when a disparity more than 1 away has sum * (1 - uniqueness) < best sum.
    lr_check : max |d_left - d_right| in pixels for the left-right check; None = off.
    subpixel : parabola fit through the best sum and its two neighbours.
    threads : 1 or 2.

    Returns
    -------
    disparity : (H, W) float32, pixels, NaN where unknown.
    disparity_right : (H, W) float32, the right view's winner-takes-all disparity (integer values),
        NaN where no disparity of the range maps inside the left image.
    timings : ms for "cost" (census transform / prefilter), "aggregate" (both passes including
        per-pixel costs and the fused selection), "select" (0: fused).
    """
    if paths not in (4, 8):
        raise ValueError(f"`paths` must be 4 or 8, got {paths}")
    mask = ALL_PATHS if paths == 8 else FOUR_PATHS
    disp, dispR, _, timings = _run(left, right, cost=cost, min_disparity=min_disparity,
                                   num_disparities=num_disparities, block_size=block_size,
                                   census_window=census_window, p1=p1, p2=p2, path_mask=mask,
                                   adaptive_p2=adaptive_p2, uniqueness=uniqueness, lr_check=lr_check,
                                   subpixel=subpixel, threads=threads)
    return disp, dispR, timings


def sum_volume(left: np.ndarray, right: np.ndarray, *, path_mask: int = ALL_PATHS, threads: int = 2,
               **kwargs) -> np.ndarray:
    """Test entry: the (H, W, D) int16 sum over the directions in ``path_mask`` (see PATH_NAMES),
    computed by the same fused passes as ``sgm_match``. Keyword args as ``sgm_match``."""
    kw = dict(cost="census", min_disparity=0, num_disparities=64, block_size=5, census_window=(9, 7),
              p1=10, p2=120, adaptive_p2=False, uniqueness=0.0, lr_check=1.0, subpixel=True)
    kw.update(kwargs)
    _, _, S, _ = _run(left, right, path_mask=path_mask, threads=threads, **kw)
    return S


def cost_volume(left: np.ndarray, right: np.ndarray, *, cost: str = "census", min_disparity: int = 0,
                num_disparities: int = 64, block_size: int = 5, census_window: tuple[int, int] = (9, 7),
                p2: int = 120) -> np.ndarray:
    """(H, W, D) int16 matching cost, entry [y, x, k] for disparity min_disparity + k.

    Exactly the costs the fused passes use (SAD scaled by ``cost_scale``, which depends on p2);
    disparities whose match falls outside the right image hold the invalid cost
    ``cmax + 2 * p2_scaled + 1``. Not used on the fast path (it allocates the full volume).
    """
    if cost not in _KIND:
        raise ValueError(f"`cost` must be one of {sorted(_KIND)}, got {cost!r}")
    kind = _KIND[cost]
    H, W = left.shape
    D = int(num_disparities)
    shift, cmax = cost_scale(cost, block_size, census_window, int(p2))
    cinv = cmax + 2 * (int(p2) >> shift) + 1
    h = block_size // 2 if kind == 1 else 0
    lcode, rcode, lsob, lint, rsob, rint = _prepare_cost(left, right, cost, census_window)
    out = np.empty((H, W, D), np.int16)
    cost_volume_kernel(kind, lcode, rcode, lsob, lint, rsob, rint, int(min_disparity), h, shift, cmax,
                       np.int16(cinv), out)
    return out
