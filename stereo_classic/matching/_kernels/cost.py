"""Matching costs for the SGM kernels: census + Hamming, and SAD on a brightness-robust prefilter.

Layout: disparity innermost and contiguous. Disparity index ``k`` in ``[0, D)`` stands for the
disparity ``min_disparity + k``; the left pixel ``x`` is matched with the right pixel
``x - min_disparity - k``. Right-image rows are stored *reversed* (``rrev[j]`` holds right column
``K - j``), so that the D candidates of one left pixel are the contiguous slice ``rrev[j0:j0 + D]``
(straight vector loads, no gathers).

Costs where ``x - min_disparity - k`` falls outside the image are replaced by ``invalid_cost``
(see ``core``), never computed from padding.

SAD cost (the paper's n x n window, with its "brightness processing"): per-pixel difference
``|sobel_L - sobel_R| + |I_L - I_R| // 4`` where ``sobel`` is the horizontal Sobel response clipped
to +-31 (OpenCV StereoSGBM's prefilter), summed over ``block_size x block_size`` with running
sums (a column sum per (x, k) updated by one row in, one row out; a running sum along x), borders
replicated, then right-shifted by ``sad_shift`` so that the SGM sums fit int16.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit
from numba.core.compiler import CompilerBase, DefaultPassBuilder

from stereo_classic.matching._kernels.intrinsics import (
    absdiff16,
    add16,
    popcnt16,
    shr16,
    sub16,
)

__all__ = [
    "SOBEL_CAP",
    "SAD_PIXEL_MAX",
    "CENSUS",
    "CENSUS_GRAD",
    "GRAD_SHIFT",
    "SAD",
    "CostImages",
    "CostSettings",
    "census_transform",
    "census_bits",
    "sad_prefilter",
    "cost_volume_kernel",
    "NoAliasCompiler",
]

SOBEL_CAP = 31
SAD_PIXEL_MAX = 2 * SOBEL_CAP + 255 // 4  # largest per-pixel SAD term (125)
#: ``CostSettings.kind`` of the census cost and of the SAD cost.
CENSUS = 0
SAD = 1
#: census + x-gradient SAD: the census Hamming cost plus the window mean of |Sobel_x(L) - Sobel_x(R)|
#: (no intensity term: gradients do not change with an exposure offset between the cameras).
CENSUS_GRAD = 2
#: The gradient term of CENSUS_GRAD is (window sum * grad_mul) >> GRAD_SHIFT, i.e. the window mean.
GRAD_SHIFT = 10


class CostImages(NamedTuple):
    """The arrays the matching cost reads for one pair (numba takes the tuple as one argument).

    The cost not in use gets distinct small placeholders of the same dtype and number of
    dimensions (one compiled kernel serves both costs; no two fields may share a buffer, see
    ``NoAliasCompiler``).

    Attributes
    ----------
    left : (H, W) uint8
        The left grey image (adaptive P2 reads it; its shape is the image size).
    left_code, right_code : uint16 or uint64
        Census codes: (H, W, 4) uint16 (four 16-bit quarters, quarter 0 = bits 0-15) for the fused
        passes, (H, W) uint64 for ``cost_volume_kernel``; (1, 1[, 4]) placeholders for SAD.
    left_sobel, left_intensity, right_sobel, right_intensity : (H, W) int16
        The SAD channels of ``sad_prefilter``; (1, 1) placeholders for census.
    """

    left: np.ndarray
    left_code: np.ndarray
    right_code: np.ndarray
    left_sobel: np.ndarray
    left_intensity: np.ndarray
    right_sobel: np.ndarray
    right_intensity: np.ndarray


class CostSettings(NamedTuple):
    """How the cost of disparity index ``k`` is computed (all plain ints).

    Attributes
    ----------
    kind : int
        ``CENSUS`` (0), ``SAD`` (1) or ``CENSUS_GRAD`` (2).
    min_disparity : int
        Disparity of index 0, pixels (may be negative).
    half_block : int
        ``block_size // 2`` for SAD, 0 for census.
    shift : int
        Right shift of the SAD window sum (0 for census), see ``core.cost_scale``.
    cmax : int
        Largest cost after the shift.
    invalid_cost : int
        Cost of a disparity whose match lies outside the right image: ``cmax + 2 * p2_scaled + 1``.
    grad_mul : int
        ``CENSUS_GRAD``: ``round(2**GRAD_SHIFT / block_size**2)``, the gradient window sum to its mean; 0 otherwise.
    """

    kind: int
    min_disparity: int
    half_block: int
    shift: int
    cmax: int
    invalid_cost: int
    grad_mul: int = 0


def census_bits(census_window: tuple[int, int]) -> int:
    """Number of bits of a census code (window pixels minus the centre)."""
    w, h = census_window
    return w * h - 1


@njit(cache=True, nogil=True)
def _census_kernel(padded, hw, hh, out):  # pragma: no cover - numba
    H, W = out.shape
    for y in range(H):
        row = out[y]
        row[:] = 0
        centre = padded[y + hh, hw:hw + W]
        for dy in range(-hh, hh + 1):
            for dx in range(-hw, hw + 1):
                if dy == 0 and dx == 0:
                    continue
                nb = padded[y + hh + dy, hw + dx:hw + dx + W]
                for x in range(W):
                    row[x] = (row[x] << np.uint64(1)) | np.uint64(nb[x] < centre[x])


def census_transform(image: np.ndarray, census_window: tuple[int, int]) -> np.ndarray:
    """Census codes: bit set where the neighbour is darker than the centre, borders replicated.

    Parameters
    ----------
    image : (H, W) uint8
    census_window : (width, height), both odd, ``width * height - 1 <= 64``

    Returns
    -------
    (H, W) uint64 codes.
    """
    w, h = census_window
    padded = np.pad(image, ((h // 2, h // 2), (w // 2, w // 2)), mode="edge")
    out = np.empty(image.shape, np.uint64)
    _census_kernel(padded, w // 2, h // 2, out)
    return out


def sad_prefilter(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The two channels the SAD cost compares.

    Returns ``(sobel, intensity)``, both (H, W) int16: ``sobel`` is the horizontal 3x3 Sobel
    response clipped to +-31 and shifted to ``[0, 62]`` (replicated borders); ``intensity`` is the
    image itself.
    """
    img = image.astype(np.int16)
    p = np.pad(img, 1, mode="edge")
    gx = (p[:-2, 2:] - p[:-2, :-2]) + 2 * (p[1:-1, 2:] - p[1:-1, :-2]) + (p[2:, 2:] - p[2:, :-2])
    sob = (np.clip(gx, -SOBEL_CAP, SOBEL_CAP) + SOBEL_CAP).astype(np.int16)
    return np.ascontiguousarray(sob), np.ascontiguousarray(img)


# ----------------------------------------------------------------------------------------------
# Per-row helpers shared by the fused SGM passes and by cost_volume_kernel (so the volume that the
# tests compare with the numpy reference is computed by exactly the code the fast path runs).


class NoAliasCompiler(CompilerBase):
    """numba's nopython pipeline with its ``noalias`` flag (numba uses it for parfors): the array
    arguments are declared to LLVM as not aliasing each other, so the vectorised loops need no
    runtime overlap checks per pixel (measured: -20 % time in the passes). Callers must never pass
    the same buffer twice (``_run`` allocates a separate placeholder for every unused argument)."""

    def define_pipelines(self):
        self.state.flags.noalias = True
        return [DefaultPassBuilder.define_nopython_pipeline(self.state)]


_U = np.uint64  # unsigned indices: numba adds no negative-index wraparound, LLVM emits plain vector loads


@njit(cache=True, nogil=True)
def _clamp(i, n):  # pragma: no cover - numba
    return 0 if i < 0 else (n - 1 if i >= n else i)


@njit(cache=True, nogil=True)
def census_reverse_row(rcode, y, rrev, dmin):  # pragma: no cover - numba
    """rrev[j] = rcode[y, clamp(W - 1 - dmin - j)] for j in [0, len(rrev))."""
    W = rcode.shape[1]
    K = W - 1 - dmin
    for j in range(rrev.shape[0]):
        rrev[j] = rcode[y, _clamp(K - j, W)]


@njit(cache=True, nogil=True)
def census_pixel_cost(lc, rrev, x, W, C, D):  # pragma: no cover - numba
    """C[k] = popcount(lc ^ census_right[x - dmin - k]) (rrev from census_reverse_row)."""
    j0 = W - 1 - x
    for k in range(D):
        C[k] = popcnt16(lc ^ rrev[_U(j0 + k)])


@njit(cache=True, nogil=True)
def sad_reverse_row(rsob, rint, y, srev, irev, dmin, h):  # pragma: no cover - numba
    """srev[j] = rsob[y, clamp(W - 1 + h - dmin - j)], same for the intensity row."""
    W = rsob.shape[1]
    K = W - 1 + h - dmin
    for j in range(srev.shape[0]):
        c = _clamp(K - j, W)
        srev[j] = rsob[y, c]
        irev[j] = rint[y, c]


@njit(cache=True, nogil=True, pipeline_class=NoAliasCompiler)
def sad_colsum_row(colsum, add, lsob, lint, y, srev, irev, h, D):  # pragma: no cover - numba
    """colsum[(x' + h) * D + k] (+/-)= AD(x', x' - dmin - k) for x' in [-h, W + h), one image row.

    AD = |sobel_L - sobel_R| + |I_L - I_R| // 4. srev/irev come from sad_reverse_row for the
    same row.
    """
    W = lsob.shape[1]
    two = np.int16(2)
    for xp in range(-h, W + h):
        c = _clamp(xp, W)
        ls = lsob[y, c]
        li = lint[y, c]
        j0 = W - 1 + h - xp
        base = (xp + h) * D
        if add:
            for k in range(D):
                ad = add16(absdiff16(ls, srev[_U(j0 + k)]), shr16(absdiff16(li, irev[_U(j0 + k)]), two))
                colsum[_U(base + k)] = add16(colsum[_U(base + k)], ad)
        else:
            for k in range(D):
                ad = add16(absdiff16(ls, srev[_U(j0 + k)]), shr16(absdiff16(li, irev[_U(j0 + k)]), two))
                colsum[_U(base + k)] = sub16(colsum[_U(base + k)], ad)


@njit(cache=True, nogil=True, pipeline_class=NoAliasCompiler)
def sad_colsum_init(colsum, y, lsob, lint, rsob, rint, srev, irev, dmin, h, D):  # pragma: no cover
    """colsum = sum of AD rows clamp(y - h) .. clamp(y + h)."""
    H = lsob.shape[0]
    colsum[:] = 0
    for yy in range(y - h, y + h + 1):
        yc = _clamp(yy, H)
        sad_reverse_row(rsob, rint, yc, srev, irev, dmin, h)
        sad_colsum_row(colsum, True, lsob, lint, yc, srev, irev, h, D)


@njit(cache=True, nogil=True, pipeline_class=NoAliasCompiler)
def sad_colsum_advance(colsum, y, step, lsob, lint, rsob, rint, srev, irev, dmin, h, D):  # pragma: no cover
    """Move the column window from row y - step to row y (add row y + step*h, drop y - step*(h+1))."""
    H = lsob.shape[0]
    yin = _clamp(y + step * h, H)
    yout = _clamp(y - step * (h + 1), H)
    if yin == yout:
        return
    sad_reverse_row(rsob, rint, yin, srev, irev, dmin, h)
    sad_colsum_row(colsum, True, lsob, lint, yin, srev, irev, h, D)
    sad_reverse_row(rsob, rint, yout, srev, irev, dmin, h)
    sad_colsum_row(colsum, False, lsob, lint, yout, srev, irev, h, D)


@njit(cache=True, nogil=True)
def sad_hsum_init(hsum, colsum, x, h, D):  # pragma: no cover - numba
    """hsum[k] = sum of colsum over x' in [x - h, x + h]."""
    for k in range(D):
        hsum[k] = 0
    for xp in range(x - h, x + h + 1):
        base = (xp + h) * D
        for k in range(D):
            hsum[k] += colsum[_U(base + k)]


@njit(cache=True, nogil=True)
def sad_hsum_advance(hsum, colsum, x, step, h, D):  # pragma: no cover - numba
    """Move the row window from x - step to x."""
    bin_ = (x + step * h + h) * D
    bout = (x - step * (h + 1) + h) * D
    for k in range(D):
        hsum[k] += np.int32(colsum[_U(bin_ + k)]) - np.int32(colsum[_U(bout + k)])


@njit(cache=True, nogil=True)
def sad_pixel_cost(hsum, shift, cmax, C, D):  # pragma: no cover - numba
    """C[k] = min(hsum[k] >> shift, cmax) as int16."""
    for k in range(D):
        v = hsum[k] >> shift
        C[k] = np.int16(v if v < cmax else cmax)


@njit(cache=True, nogil=True)
def fill_invalid(C, x, W, dmin, cinv, D):  # pragma: no cover - numba
    """Set C[k] = cinv where x - dmin - k is outside [0, W); return (k_lo, k_hi) valid, inclusive."""
    k_lo = x - dmin - W + 1
    if k_lo < 0:
        k_lo = 0
    k_hi = x - dmin
    if k_hi > D - 1:
        k_hi = D - 1
    if k_lo > k_hi:
        for k in range(D):
            C[k] = cinv
        return k_lo, k_hi
    for k in range(0, k_lo):
        C[k] = cinv
    for k in range(k_hi + 1, D):
        C[k] = cinv
    return k_lo, k_hi


@njit(cache=True, nogil=True)
def cost_volume_kernel(images, cost, out):  # pragma: no cover - numba
    """Fill ``out`` (H, W, D) int16 with the cost the fused passes use.

    ``images``: a ``CostImages`` (census codes as (H, W) uint64); ``cost``: a ``CostSettings``.
    """
    H, W, D = out.shape
    kind = cost.kind
    dmin = cost.min_disparity
    h = cost.half_block
    cinv = np.int16(cost.invalid_cost)
    lcode = images.left_code
    rcode = images.right_code
    lsob = images.left_sobel
    lint = images.left_intensity
    rsob = images.right_sobel
    rint = images.right_intensity
    C = np.empty(D, np.int16)
    if kind != 1:  # census, alone or as the first term
        rrev = np.empty(W + D - 1, np.uint64)
        for y in range(H):
            census_reverse_row(rcode, y, rrev, dmin)
            for x in range(W):
                census_pixel_cost(lcode[y, x], rrev, x, W, C, D)
                if kind == 0:
                    fill_invalid(C, x, W, dmin, cinv, D)
                out[y, x, :] = C
    if kind != 0:  # SAD, or the gradient term added to the census cost
        L = W + 2 * h + D - 1
        srev = np.empty(L, np.int16)
        irev = np.empty(L, np.int16)
        colsum = np.zeros((W + 2 * h) * D, np.int16)
        hsum = np.zeros(D, np.int32)
        for y in range(H):
            if y == 0:
                sad_colsum_init(colsum, y, lsob, lint, rsob, rint, srev, irev, dmin, h, D)
            else:
                sad_colsum_advance(colsum, y, 1, lsob, lint, rsob, rint, srev, irev, dmin, h, D)
            for x in range(W):
                if x == 0:
                    sad_hsum_init(hsum, colsum, x, h, D)
                else:
                    sad_hsum_advance(hsum, colsum, x, 1, h, D)
                if kind == 1:
                    sad_pixel_cost(hsum, cost.shift, cost.cmax, C, D)
                else:
                    for k in range(D):
                        C[k] = np.int16(out[y, x, k] + ((hsum[k] * cost.grad_mul) >> GRAD_SHIFT))
                fill_invalid(C, x, W, dmin, cinv, D)
                out[y, x, :] = C
