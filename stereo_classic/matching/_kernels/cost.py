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
sums (a column sum per (x, k) updated by one row in, one row out, :mod:`.colsums`; a running sum along x), borders
replicated, then right-shifted by ``sad_shift`` so that the SGM sums fit int16.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from stereo_classic.matching._kernels.colsums import (moved_column, sad_colsum_advance, sad_colsum_columns,
                                                      sad_colsum_init, sad_hsum_init, sad_reverse_pair)
from stereo_classic.matching._kernels.features import (FEATURE_QUANT, FEATURE_SCALE, FEATURES, _census_at,
                                                       _hamming, feature_row_cost, reverse_code_row)
from stereo_classic.matching._kernels.intrinsics import (
    add16,
    lshr16,
    max16,
    min16,
    mulhi16,
    mullo16,
    mulshr16,
    sub16,
)
from stereo_classic.matching._kernels.pipeline import NoAliasCompiler
from stereo_classic.matching._kernels.tags import tag_disparities

# ``_nrt=False``: kernels that run per row and allocate nothing, compiled without numba's reference counts on their
# array arguments (atomic updates, on every call, of counters both workers share; docs/matching.md, seventh round).
__all__ = [
    "SOBEL_CAP",
    "SAD_PIXEL_MAX",
    "CENSUS",
    "CENSUS_GRAD",
    "FEATURES",
    "FEATURE_SCALE",
    "FEATURE_QUANT",
    "GRAD_SHIFT",
    "SAD",
    "CostImages",
    "CostSettings",
    "census_quarters",
    "census_quarters_rows",
    "census_bits",
    "row_cost",
    "valid_range",
    "RowCostBuffers",
    "sad_prefilter",
    "sobel_rows",
    "cost_volume_kernel",
    "feature_row_cost",
    "NoAliasCompiler",
    "TEXTURE_REFERENCE",
    "TEXTURE_WINDOW",
    "largest_p2",
    "max_penalty_scale",
    "pixel_penalties",
    "scaled_penalty",
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
#: Weak texture: a pixel whose TEXTURE_WINDOW x TEXTURE_WINDOW window mean of |Sobel_x| (left image, grey levels)
#: is below TEXTURE_REFERENCE gets its penalties multiplied by TEXTURE_REFERENCE / that mean, at most by the gain.
#: 16 is the Sobel_x response of an intensity slope of 2 grey levels per pixel, about three times the mean
#: |Sobel_x| that pure sensor noise of 2 grey levels gives (2 * sqrt(12) * 0.8 = 5.5; 2 is the median
#: left-right residual at the true match on both dataset families here): below it the cost's minimum is mostly
#: noise, and the path's neighbours are the better witnesses. See docs/matching.md, "Weak texture".
TEXTURE_REFERENCE = 16
TEXTURE_WINDOW = 5


class CostImages(NamedTuple):
    """The arrays the matching cost reads for one pair (numba takes the tuple as one argument).

    The cost not in use gets distinct small placeholders of the same dtype and number of
    dimensions (one compiled kernel serves both costs; no two fields may share a buffer, see
    ``NoAliasCompiler``).

    Attributes
    ----------
    left : (H, W) uint8
        The left grey image (adaptive P2 reads it; its shape is the image size).
    left_code, right_code : (H, 4, W) uint16
        Census codes as four 16-bit quarters, each a plane of the row (quarter 0 = bits 0-15,
        ``census_quarters``); (1, 1, 1) placeholders for SAD.
    left_sobel, left_intensity, right_sobel, right_intensity : (H, W) int16
        The SAD channels of ``sad_prefilter``; (1, 1) placeholders for census (and the intensities for
        census+grad, which has no intensity term).
    penalty_scale : (H, W) uint8
        Per pixel, the factor of P1 and P2 in sixteenths (16 = 1), ``weak_texture_scale``: the aggregation
        uses ``(P * scale + 8) >> 4`` at the pixel.
    left_features, right_features : (H, C, W) int8
        ``FEATURES``: the quantised unit feature vectors of each view, one image row per channel; (1, 1, 1)
        otherwise.
    """

    left: np.ndarray
    left_code: np.ndarray
    right_code: np.ndarray
    left_sobel: np.ndarray
    left_intensity: np.ndarray
    right_sobel: np.ndarray
    right_intensity: np.ndarray
    penalty_scale: np.ndarray
    left_features: np.ndarray = np.zeros((1, 1, 1), np.int8)
    right_features: np.ndarray = np.zeros((1, 1, 1), np.int8)


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
    num_disparities : int
        Disparities searched. The row buffers may hold more per pixel (``core.padded_disparities``: whole vector
        blocks); the indices past ``num_disparities`` get ``invalid_cost``, like a match outside the right image.
    grad_mul : int
        ``CENSUS_GRAD``: ``round(2**GRAD_SHIFT / block_size**2)``, the gradient window sum to its mean; 0 otherwise.
    feature_l1 : int
        ``FEATURES``: 1 = L1 distance of the feature vectors, 0 = dot product.
    feature_base, feature_mul : float
        ``FEATURES``: the cost is ``clip(feature_base + acc * feature_mul, 0, cmax)`` truncated, ``acc`` the
        channel sum of the int8 products (dot) or absolute differences (L1), exact in float32.
    outside_cost : int
        Cost of a match outside the right image when >= 0 (neutral: such a winner is unknown); -1: ``invalid_cost``.
    feature_census_mul : int
        ``FEATURES``: the census term's multiplier (``features.census_term_mul``), 0: the learned cost alone.
    """

    kind: int
    min_disparity: int
    half_block: int
    shift: int
    cmax: int
    invalid_cost: int
    num_disparities: int
    grad_mul: int = 0
    feature_l1: int = 0
    feature_base: float = 0.0
    feature_mul: float = 0.0
    outside_cost: int = -1
    feature_census_mul: int = 0


def census_bits(census_window: tuple[int, int]) -> int:
    """Number of bits of a census code (window pixels minus the centre)."""
    w, h = census_window
    return w * h - 1


@njit(cache=True, nogil=True, inline="always")
def _census_byte(a, c, n0, n1, n2, n3, n4, n5, n6, n7, W):  # pragma: no cover - numba
    """a[x] = one byte of the census code of the pixels ``c``: bit 7 - j set where ``nj[x] < c[x]``."""
    one = np.uint8(1)
    for x in range(W):
        cx = c[x]
        a[x] = ((((((np.uint8(n0[x] < cx) << one | np.uint8(n1[x] < cx)) << one | np.uint8(n2[x] < cx)) << one
                  | np.uint8(n3[x] < cx)) << one | np.uint8(n4[x] < cx)) << one | np.uint8(n5[x] < cx)) << one
                | np.uint8(n6[x] < cx)) << one | np.uint8(n7[x] < cx)


@njit(cache=True, nogil=True)
def census_quarters_rows(padded, hw, hh, y0, y1, out):  # pragma: no cover - numba
    """out[y, q, x] for the rows [y0, y1): the 16-bit quarter q of the census code (neighbour n of the window, in
    row order, is bit nbits - 1 - n of the 64-bit code) of the image ``padded`` by (hh, hw) replicated pixels."""
    W = out.shape[2]
    ww = 2 * hw + 1
    nbits = ww * (2 * hh + 1) - 1
    centre_index = hh * ww + hw  # in the window, row order
    # the code's bytes, each made in one pass over the row from its (up to) eight neighbours, in 8-bit lanes: byte b
    # holds the neighbours n with (nbits - 1 - n) // 8 == b, neighbour n on bit (nbits - 1 - n) % 8. A byte's
    # missing neighbours (the top byte's, when nbits is no multiple of 8) are the centre itself (never darker: 0).
    # One shift-in per neighbour over the whole row (62 passes reading and writing the byte rows) took 1.7x the time
    # (KITTI image, census 9 x 7: 1.18 -> 0.68 ms; docs/matching.md, "Thirteenth round").
    acc = np.zeros((8, W), np.uint8)
    rows = np.empty(8, np.int64)  # the byte's neighbours in ``padded``, highest bit first
    cols = np.empty(8, np.int64)
    nbytes = (nbits + 7) // 8
    for y in range(y0, y1):
        centre = padded[y + hh, hw:hw + W]
        for b in range(nbytes):
            for j in range(8):
                rows[j] = y + hh
                cols[j] = hw
            for n in range(max(0, nbits - 8 - 8 * b), nbits - 8 * b):
                i = n if n < centre_index else n + 1
                j = 7 - (nbits - 1 - n) % 8
                rows[j] = y + i // ww
                cols[j] = i % ww
            _census_byte(acc[b], centre, padded[rows[0], cols[0]:cols[0] + W], padded[rows[1], cols[1]:cols[1] + W],
                         padded[rows[2], cols[2]:cols[2] + W], padded[rows[3], cols[3]:cols[3] + W],
                         padded[rows[4], cols[4]:cols[4] + W], padded[rows[5], cols[5]:cols[5] + W],
                         padded[rows[6], cols[6]:cols[6] + W], padded[rows[7], cols[7]:cols[7] + W], W)
        for q in range(4):  # quarter q: bytes 2q (low) and 2q + 1 of the code, 32 pixels a vector
            lo = acc[2 * q]
            hi = acc[2 * q + 1]
            o = out[y, q]
            for x in range(W):
                o[x] = np.uint16(lo[x]) | (np.uint16(hi[x]) << np.uint16(8))


def census_quarters(image: np.ndarray, census_window: tuple[int, int]) -> np.ndarray:
    """Census codes as four 16-bit quarters: ``(H, 4, W) uint16``, ``[y, q]`` the quarter q (bits 16q .. 16q + 15)
    of row y's 64-bit codes (bit set where the neighbour is darker than the centre, borders replicated;
    ``reference.census_reference``), each quarter a plane of the row: the costs read them in 16-bit lanes (four
    times as many per vector as 64-bit codes), and a right row reversed is four reversed runs."""
    w, h = census_window
    padded = np.pad(image, ((h // 2, h // 2), (w // 2, w // 2)), mode="edge")
    out = np.empty((image.shape[0], 4, image.shape[1]), np.uint16)
    census_quarters_rows(padded, w // 2, h // 2, 0, image.shape[0], out)
    return out


@njit(cache=True, nogil=True)
def sobel_rows(padded, y0, y1, out):  # pragma: no cover - numba
    """``sad_prefilter``'s Sobel channel for the rows [y0, y1), from the image ``padded`` by one replicated pixel."""
    W = out.shape[1]
    cap = SOBEL_CAP
    for y in range(y0, y1):
        a, b, c = padded[y], padded[y + 1], padded[y + 2]
        for x in range(W):
            gx = ((np.int32(a[x + 2]) - np.int32(a[x])) + 2 * (np.int32(b[x + 2]) - np.int32(b[x]))
                  + (np.int32(c[x + 2]) - np.int32(c[x])))
            out[y, x] = np.int16(min(max(gx, -cap), cap) + cap)


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


_U = np.uint64  # unsigned indices: numba adds no negative-index wraparound, LLVM emits plain vector loads


class RowCostBuffers(NamedTuple):
    """Per-thread state of ``row_cost`` (int16 unless said otherwise).

    Attributes
    ----------
    colsum : ((W + 2h) * D,) int16
        Column sums of the per-pixel SAD / gradient differences over the rows y - h .. y + h ((1,) for census).
    hsum : (D,) int16
        Window sum of the current pixel (the 16 bits hold the unsigned sum, at most 21 * 21 * 125 < 65536).
    rrev : (4 * (W + D - 1),) uint16
        Census code quarters of the current right row, reversed ((1,) for SAD and for ``FEATURES`` without a census
        term).
    srev, irev : (2 * (W + 2h + D - 1),) int16
        Gradient and intensity channels of two right rows (the one entering the column window, the one leaving
        it), reversed ((1,) for census; irev (1,) but for SAD).
    floor : (D,) int16
        0 for the disparities of the range, the invalid cost for the padding past it (``CostSettings``): the SAD and
        learned costs of index k are at least ``floor[k]`` (one vector max, instead of a remainder loop per pixel).
        The census costs need no max: they are never negative nor above the invalid cost, so ``row_cost`` writes
        the invalid cost on their padding once the row is made (one load and one max fewer per 32 costs; VGA, 64
        disparities, 2 threads: ``row_cost`` 4.99 -> 4.46 CPU ms a frame, ``benchmarks.kernel_profile``).
    tag : tuple
        ``tags.disparity_tag(D)``: ``row_cost`` reads D from it (compiled once per D).
    frev : (C * (W + D - 1),) float32
        ``FEATURES``: the right row's features, reversed, one run per channel ((1,) otherwise).
    facc : (D,) float32
        ``FEATURES``: the channel sums of the current pixel ((1,) otherwise).
    """

    colsum: np.ndarray
    hsum: np.ndarray
    rrev: np.ndarray
    srev: np.ndarray
    irev: np.ndarray
    floor: np.ndarray
    tag: tuple
    frev: np.ndarray = np.zeros(1, np.float32)
    facc: np.ndarray = np.zeros(1, np.float32)


@njit(cache=True, nogil=True, inline="always")
def valid_range(x, W, dmin, D):  # pragma: no cover - numba
    """(k_lo, k_hi), inclusive: the disparity indices of column ``x`` whose match ``x - dmin - k`` lies inside the
    right image (none when k_lo > k_hi)."""
    return max(0, x - dmin - W + 1), min(D - 1, x - dmin)


@njit(cache=True, nogil=True, inline="always")
def _moved_sum(hsum, colsum, bout, bin_, k):  # pragma: no cover - numba
    """The gradient window sum of index k moved one column on (column sums ``bout`` out, ``bin_`` in), stored."""
    hs = add16(sub16(hsum[k], colsum[_U(bout + k)]), colsum[_U(bin_ + k)])
    hsum[k] = hs
    return hs


@njit(_nrt=False, cache=True, nogil=True, pipeline_class=NoAliasCompiler)
def _census_columns(lcode, y, x0, W, rrev, hsum, colsum, crow, h, gmul, ghi, grad, narrow, tag,
                    move, lsob, srev, yin, yout, L):  # pragma: no cover - numba
    """``row_cost``'s census costs of the columns x0 .. W - 1 (with ``grad``: plus the gradient window mean, the window
    sum moved on from column x - 1: x0 >= 1), in a function of its own: inside ``row_cost``, among its other costs'
    branches and values, the same loop took about 4 ns a pixel more (OAK-D VGA, 64 disparities: ``row_cost`` over
    the image 8.1 -> 6.9 ms; docs/matching.md, "Twelfth round").

    ``move``: the column sums entering the window (column x + h) are moved on from the row before here, where they
    are first read (``sad_reverse_pair``'s rows ``yin`` / ``yout`` and ``srev``, ``L``), not in a pass of their own
    over the W x D sums (``sad_colsum_advance``); the columns up to 2h are moved on already."""
    D = tag_disparities(tag)
    nrr = W + D - 1
    gshift = np.int16(GRAD_SHIFT)
    for x in range(x0, W):
        cb = x * D
        bin_ = (x + 2 * h) * D
        bout = (x - 1) * D
        a0, a1, a2, a3, j0, j1, j2, j3 = _census_at(lcode, y, x, W, nrr)
        if move:  # the column leaving the window first (a loop of its own: it reads the sums the other one writes)
            c = min(x + h, W - 1)
            la = lsob[yin, c]
            lb = lsob[yout, c]
            s0 = W - 1 - x
            for k in range(D):
                hsum[k] = sub16(hsum[k], colsum[_U(bout + k)])
            if narrow:
                for k in range(D):
                    hs = add16(hsum[k], moved_column(colsum, srev, la, lb, s0, s0 + L, bin_, k))
                    hsum[k] = hs
                    crow[_U(cb + k)] = add16(_hamming(rrev, a0, a1, a2, a3, j0, j1, j2, j3, k),
                                             mullo16(hs, gmul, gshift))
            else:
                for k in range(D):
                    hs = add16(hsum[k], moved_column(colsum, srev, la, lb, s0, s0 + L, bin_, k))
                    hsum[k] = hs
                    crow[_U(cb + k)] = add16(_hamming(rrev, a0, a1, a2, a3, j0, j1, j2, j3, k), mulhi16(hs, ghi))
        elif grad and narrow:  # census + the window mean of the gradient differences: (sum * grad_mul) >> GRAD_SHIFT
            for k in range(D):
                hs = _moved_sum(hsum, colsum, bout, bin_, k)
                crow[_U(cb + k)] = add16(_hamming(rrev, a0, a1, a2, a3, j0, j1, j2, j3, k), mullo16(hs, gmul, gshift))
        elif grad:  # the same through the high half of a 16-bit product
            for k in range(D):
                hs = _moved_sum(hsum, colsum, bout, bin_, k)
                crow[_U(cb + k)] = add16(_hamming(rrev, a0, a1, a2, a3, j0, j1, j2, j3, k), mulhi16(hs, ghi))
        else:
            for k in range(D):
                crow[_U(cb + k)] = _hamming(rrev, a0, a1, a2, a3, j0, j1, j2, j3, k)


@njit(_nrt=False, cache=True, nogil=True, pipeline_class=NoAliasCompiler)
def row_cost(images, cost, y, first, step, bufs, crow):  # pragma: no cover - numba
    """The matching cost of every pixel of row ``y``: ``crow[x * D + k]`` (int16), disparity ``min_disparity + k``.

    ``images``: a ``CostImages`` with census codes as (H, 4, W) uint16 quarters; ``cost``: a ``CostSettings``;
    ``bufs``: a ``RowCostBuffers``. The SAD / gradient column sums are built from scratch when ``first``, else
    moved on from row ``y - step`` (``step`` +1 or -1: rows must then come in that order). Disparities whose
    match falls outside the right image get ``outside_cost`` (``invalid_cost`` when it is -1), the padding indices
    ``k >= cost.num_disparities`` ``invalid_cost`` (``crow`` holds ``len(crow) // W`` per pixel).
    """
    if cost.kind == FEATURES:  # learned features: a cost of their own (``feature_row_cost``)
        feature_row_cost(images.left_features, images.right_features, cost, y, bufs.frev, bufs.facc, bufs.floor,
                         crow, images.left_code, images.right_code, bufs.rrev, bufs.hsum)
        return
    lcode = images.left_code
    rcode = images.right_code
    lsob = images.left_sobel
    lint = images.left_intensity
    rsob = images.right_sobel
    rint = images.right_intensity
    colsum = bufs.colsum
    hsum = bufs.hsum
    rrev = bufs.rrev
    srev = bufs.srev
    irev = bufs.irev
    floor = bufs.floor
    kind = cost.kind
    dmin = cost.min_disparity
    h = cost.half_block
    W = images.left.shape[1]
    D = tag_disparities(bufs.tag)  # crow.shape[0] // W, as a constant
    cinv = np.int16(cost.invalid_cost)
    cout = np.int16(cost.outside_cost) if cost.outside_cost >= 0 else cinv
    grad = kind != CENSUS  # SAD, or the gradient term of census+grad (no intensity term)
    # (sum * grad_mul) >> GRAD_SHIFT == (sum * (grad_mul << (16 - GRAD_SHIFT))) >> 16 exactly while the scaled
    # multiplier fits 16 bits (every block size but 1): the high half of a 16-bit product (one vpmulhuw for 32
    # lanes, not two widened 32-bit multiplies and a narrowing), measured about a third of the gradient term.
    gmul_hi = cost.grad_mul << (16 - GRAD_SHIFT)
    high = gmul_hi < 65536
    # Past the first column: the product itself in 16 bits (``mullo16``, two instructions for 32 lanes where numba's
    # LLVM turns ``mulhi16`` into eight) while the largest window sum (2 * SOBEL_CAP a pixel) times grad_mul stays
    # below 2 ** 16: every block size but 15, 17 and 19, which keep ``mulhi16``. docs/matching.md, fifth round.
    narrow = 2 * SOBEL_CAP * (2 * h + 1) * (2 * h + 1) * cost.grad_mul < 65536
    # the census cost, and census + grad past the first column, in loops of their own (_census_columns)
    fast = kind == CENSUS or (kind == CENSUS_GRAD and (narrow or high))
    yin = yout = L = 0
    move = False  # census + grad: _census_columns moves the column sums on where it first reads them
    if grad:
        intensity = kind == SAD
        if first:
            sad_colsum_init(colsum, y, lsob, lint, rsob, rint, srev, irev, dmin, h, D, intensity)
        elif fast:  # the columns of the first column's window here, the others in _census_columns
            yin, yout, L = sad_reverse_pair(y, step, rsob, rint, srev, irev, dmin, h, False)
            move = yin != yout
            if move:
                sad_colsum_columns(colsum, -h, h + 1, yin, yout, lsob, lint, srev, irev, L, h, bufs.tag, False)
        else:
            sad_colsum_advance(colsum, y, step, lsob, lint, rsob, rint, srev, irev, dmin, h, bufs.tag, intensity)
    shift = np.int16(cost.shift)
    cmax = np.int16(cost.cmax)
    gmul = np.int16(cost.grad_mul)
    gshift = np.int16(GRAD_SHIFT)
    ghi = np.int16((gmul_hi - 65536 if gmul_hi >= 32768 else gmul_hi) if high else 0)  # its 16 bits, as int16
    nrr = W + D - 1
    if kind != SAD:  # census: four 16-bit quarters per code (vpopcntw), all in int16 lanes
        reverse_code_row(rcode, y, dmin, nrr, rrev)
    for x in range(W if not fast else (0 if kind == CENSUS else 1)):  # SAD, and census + grad's first column
        cb = x * D
        if x == 0:  # the window sum of the pixel: hsum over the column sums x - h .. x + h
            sad_hsum_init(hsum, colsum, 0, h, D)
        else:
            bin_ = (x + 2 * h) * D
            bout = (x - 1) * D
            for k in range(D):
                hsum[k] = add16(sub16(hsum[k], colsum[_U(bout + k)]), colsum[_U(bin_ + k)])
        if kind == SAD:
            for k in range(D):
                crow[_U(cb + k)] = max16(min16(lshr16(hsum[k], shift), cmax), floor[k])
            continue
        a0, a1, a2, a3, j0, j1, j2, j3 = _census_at(lcode, y, x, W, nrr)
        if high:  # the window sum made above, through the high half of a 16-bit product
            for k in range(D):
                crow[_U(cb + k)] = add16(_hamming(rrev, a0, a1, a2, a3, j0, j1, j2, j3, k), mulhi16(hsum[k], ghi))
        else:  # the same in 32-bit products (block size 1: grad_mul is 2 ** GRAD_SHIFT)
            for k in range(D):
                crow[_U(cb + k)] = add16(_hamming(rrev, a0, a1, a2, a3, j0, j1, j2, j3, k),
                                         mulshr16(hsum[k], gmul, gshift))
    if fast:
        _census_columns(lcode, y, 0 if kind == CENSUS else 1, W, rrev, hsum, colsum, crow, h, gmul, ghi, grad, narrow,
                        bufs.tag, move, lsob, srev, yin, yout, L)
    nd = cost.num_disparities
    if kind != SAD and nd < D:  # the padding past the range: the invalid cost (the census costs need no floor in it)
        for x in range(W):
            cb = x * D
            for k in range(nd, D):
                crow[_U(cb + k)] = cinv
    # disparities whose match is outside the right image: k outside [k_lo, k_hi], only in the columns x < dmin + nd - 1
    # (k_hi < nd - 1) and x > W - 1 + dmin (k_lo > 0)
    left_end = min(W, max(0, dmin + nd - 1))
    right_start = max(left_end, min(W, W + dmin))
    for i in range(left_end + W - right_start):
        x = i if i < left_end else right_start + i - left_end
        k_lo, k_hi = valid_range(x, W, dmin, nd)
        cb = x * D
        # two runs of stores (a loop over the range testing each index cost ~6 ns a pixel of the image at KITTI size)
        for k in range(min(k_lo, nd)):
            crow[_U(cb + k)] = cout
        for k in range(max(k_hi + 1, 0), nd):
            crow[_U(cb + k)] = cout


@njit(cache=True, nogil=True)
def cost_volume_kernel(images, cost, bufs, out):  # pragma: no cover - numba
    """Fill ``out`` (H, W, D) int16 with the cost the passes use, row by row with ``row_cost``.

    ``images``: a ``CostImages`` (census codes as (H, 4, W) uint16 quarters); ``cost``: a ``CostSettings``;
    ``bufs``: a ``RowCostBuffers``.
    """
    H, W, D = out.shape
    crow = np.empty(W * D, np.int16)
    for y in range(H):
        row_cost(images, cost, y, y == 0, 1, bufs, crow)
        out[y] = crow.reshape(W, D)


def max_penalty_scale(gain: float) -> int:
    """The largest ``weak_texture_scale`` value (sixteenths) for ``gain``: ``round(16 * gain)``, at least 16."""
    return max(16, int(round(16 * float(gain))))


def largest_p2(p2: int, gain: float) -> int:
    """The largest P2 any pixel gets for ``gain``: what the int16 bound and the cost scaling must leave room for."""
    return (int(p2) * max_penalty_scale(gain) + 8) >> 4


@njit(cache=True, nogil=True, inline="always")
def scaled_penalty(p, scale):  # pragma: no cover - numba
    """A penalty (int32) of a pixel as int16: times its ``weak_texture_scale`` (sixteenths), rounded."""
    return np.int16((p * np.int32(scale) + 8) >> 4)


@njit(cache=True, nogil=True, inline="always")
def pixel_penalties(p1, p2, scale):  # pragma: no cover - numba
    """(P1, P2) of a pixel as int16: the int32 penalties times its ``weak_texture_scale`` (sixteenths), rounded."""
    return scaled_penalty(p1, scale), scaled_penalty(p2, scale)
