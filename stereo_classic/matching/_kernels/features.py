"""Learned features (``stereo_classic.matching.learned``) in the kernels: their int8 form and their row cost.

``feature_row_cost`` is the row cost of the ``FEATURES`` kind (``cost.row_cost`` hands a row of that kind to it).
``quantise_rows`` takes a feature network's float32 output (C, H + 2m, W + 2m) (the margin m cut off here),
normalises each pixel's C-vector to unit length and stores ``round(FEATURE_QUANT * f)`` as int8, one image row per
channel (H, C, W); it counts the values that are not finite (the caller refuses the model then).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from stereo_classic.matching._kernels.intrinsics import add16, max16, min16, popxor16
from stereo_classic.matching._kernels.pipeline import NoAliasCompiler

__all__ = ["FEATURES", "FEATURE_SCALE", "FEATURE_QUANT", "FEATURE_OUTSIDE", "FEATURE_SIMILARITIES", "CENSUS_MUL_SHIFT",
           "census_term_mul", "check_features", "feature_cost_terms", "feature_row_cost", "quantise_rows",
           "reverse_code_row", "with_features"]

_U = np.uint64  # unsigned indices: plain vector loads (as in cost.py)

#: Learned features (``stereo_classic.matching.learned``): per pixel a unit vector of C channels from a feature
#: network, held as int8 (``round(FEATURE_QUANT * f)``); the cost is ``FEATURE_SCALE * (1 - <fL, fR>)`` (or the
#: scaled L1 distance), so it lies in [0, 2 * FEATURE_SCALE]. ``feature_row_cost`` computes it a row at a time.
FEATURES = 3
#: Cost units per unit of ``1 - <fL, fR>``: 25 leaves room in the int16 sums for twice MC-CNN's own P2 (24.3) times
#: the weak-texture gain 4 (``params.py``), in steps of 0.04 of the dot product (measured on the shared scenes: the
#: same bad-2 as steps of 0.02, within 0.1 point per family).
FEATURE_SCALE = 25
#: int8 features: ``round(FEATURE_QUANT * f)`` of a unit vector's components (|f| <= 1).
FEATURE_QUANT = 127
#: The learned cost of a disparity whose match falls outside the right image: half the cost of unrelated features
#: (``FEATURE_SCALE``, the dot product 0 of two unrelated unit vectors), i.e. the dot product 0.5. Such a candidate
#: has no evidence for or against it, so it is neither forbidden (the classical costs' ``invalid_cost``) nor
#: preferred: a real match (measured: a median 3 - 14 at the ground-truth disparity on the shared scenes) beats it,
#: a non-match (median 24) loses to it, and a path through the left band of the image goes on with its
#: neighbours' disparity instead of being pushed to the few disparities that map inside (which the left-to-right
#: path then carries into the image). A winner there is not a measurement (``select.select_row``: unknown). The
#: padding indices past ``num_disparities`` keep ``invalid_cost``.
FEATURE_OUTSIDE = FEATURE_SCALE // 2


@njit(cache=True, nogil=True, inline="always")
def _clamp(i, n):  # pragma: no cover - numba
    return 0 if i < 0 else (n - 1 if i >= n else i)


@njit(cache=True, nogil=True, inline="always")
def reverse_run(row, K, out, b, n):  # pragma: no cover - numba
    """``out[b + j] = row[clamp(K - j)]`` for j < n: the clamped ends apart, the middle a reversed copy that LLVM
    vectorises (unsigned indices; the clamp per element kept it a scalar loop: the gradient rows of a KITTI frame
    0.6-0.8 -> 0.3 ms, docs/matching.md "Thirteenth round")."""
    W = row.shape[0]
    j0 = min(max(K - (W - 1), 0), n)  # j < j0: column W - 1
    j1 = min(max(K + 1, j0), n)  # j0 <= j < j1: column K - j; j >= j1: column 0
    last = row[W - 1]
    for j in range(j0):
        out[_U(b + j)] = last
    for j in range(j0, j1):
        out[_U(b + j)] = row[_U(K - j)]
    first = row[0]
    for j in range(j1, n):
        out[_U(b + j)] = first


@njit(cache=True, nogil=True, inline="always")
def reverse_code_row(rcode, y, dmin, nrr, rrev):  # pragma: no cover - numba
    """``rrev[q * nrr + j]`` = quarter q of the right census code of row ``y`` at column ``clamp(W - 1 - dmin - j)``,
    j < ``nrr`` (W + D - 1): the right row reversed, so that a left pixel's D candidates are consecutive (the census
    costs' ``row_cost`` and a learned cost's census term)."""
    K = rcode.shape[2] - 1 - dmin
    for q in range(4):
        reverse_run(rcode[y, q], K, rrev, q * nrr, nrr)


@njit(cache=True, nogil=True, inline="always")
def _hamming(rrev, a0, a1, a2, a3, j0, j1, j2, j3, k):  # pragma: no cover - numba
    """Census cost of disparity index k: the differing bits of the left code's quarters a0 .. a3 and the reversed
    right row's (quarter q from ``rrev[jq]``)."""
    return add16(add16(popxor16(a0, rrev[_U(j0 + k)]), popxor16(a1, rrev[_U(j1 + k)])),
                 add16(popxor16(a2, rrev[_U(j2 + k)]), popxor16(a3, rrev[_U(j3 + k)])))


@njit(cache=True, nogil=True, inline="always")
def _census_at(lcode, y, x, W, nrr):  # pragma: no cover - numba
    """What ``_hamming`` reads for left pixel (y, x): its code's quarters, and where each quarter's reversed right row
    (``reverse_code_row``, rows of ``nrr``) has the pixel's first candidate."""
    j0 = W - 1 - x
    return (lcode[y, 0, x], lcode[y, 1, x], lcode[y, 2, x], lcode[y, 3, x], j0, j0 + nrr, j0 + 2 * nrr,
            j0 + 3 * nrr)


#: The census term of a learned cost is ``(h * census_mul + 2**(CENSUS_MUL_SHIFT - 1)) >> CENSUS_MUL_SHIFT`` for a
#: Hamming distance ``h`` (``census_term_mul``): exact integers, rounded half up.
CENSUS_MUL_SHIFT = 8


def census_term_mul(share: float, bits: int) -> int:
    """``CostSettings.feature_census_mul``: the census term's multiplier, so that a Hamming distance of all ``bits``
    bits costs ``share`` of the learned cost's range (``2 * FEATURE_SCALE``, in ``2**CENSUS_MUL_SHIFT``-ths); 0 for
    a share of 0 (no census term).

    >>> census_term_mul(0.5, 62), (62 * census_term_mul(0.5, 62) + 128) >> CENSUS_MUL_SHIFT  # all bits: half of 50
    (103, 25)
    """
    return int(round((1 << CENSUS_MUL_SHIFT) * float(share) * 2 * FEATURE_SCALE / int(bits))) if share > 0 else 0


@njit(cache=True, nogil=True, pipeline_class=NoAliasCompiler)
def feature_row_cost(lfeat, rfeat, cost, y, frev, facc, floor, crow, lcode, rcode, rrev, ham):  # pragma: no cover
    """``row_cost`` of ``FEATURES``: ``crow[x * D + k]`` from the int8 feature vectors of row ``y``.

    ``lfeat``, ``rfeat``: (H, C, W) int8 (``CostImages``). The right row is copied reversed into ``frev`` as
    float32, one run of ``W + D - 1`` per channel, so that the D candidates of a left pixel are a contiguous slice
    per channel; per pixel the channel sums (products for the dot product, absolute differences for L1) are
    accumulated over the D candidates at once (vectors over k), four channels a sweep of the sums (measured 1.26x
    faster than one). Every product and sum is an integer below 2**24, so float32 holds them exactly and the order
    of the additions does not matter. The cost is
    ``clip(feature_base + sum * feature_mul, 0, cmax)`` truncated to int16; matches outside the right image get
    ``cost.outside_cost`` (``FEATURE_OUTSIDE`` by default, a neutral cost; -1: ``invalid_cost``), the padding
    ``invalid_cost`` (``floor``) as in ``row_cost``.

    With ``cost.feature_census_mul`` > 0 (``SGMParams.feature_census``) the cost is a mix of the learned cost and the
    census cost: ``feature_base`` and ``feature_mul`` then hold the learned cost's share, and the census term
    ``(h * feature_census_mul + 128) >> 8`` of the Hamming distance ``h`` of the census codes ``lcode`` / ``rcode``
    ((H, 4, W) uint16 quarters, as ``row_cost`` reads them; ``rrev``: the right row's quarters reversed, ``ham``: (D,)
    int16 scratch) is added, at most ``cmax`` in all.
    """
    C = lfeat.shape[1]
    W = lfeat.shape[2]
    D = crow.shape[0] // W
    dmin = cost.min_disparity
    nrr = W + D - 1
    for ch in range(C):  # frev[ch * nrr + j] = right feature ch at column clamp(W - 1 - dmin - j), as float32
        reverse_run(rfeat[y, ch], W - 1 - dmin, frev, ch * nrr, nrr)
    fbase = np.float32(cost.feature_base)
    fmul = np.float32(cost.feature_mul)
    top = np.float32(cost.cmax)
    zero = np.float32(0.0)
    l1 = cost.feature_l1 != 0
    cmul = np.int32(cost.feature_census_mul)
    census = cmul > 0
    cmax16 = np.int16(cost.cmax)
    if census:
        reverse_code_row(rcode, y, dmin, nrr, rrev)
    for x in range(W):
        j0 = W - 1 - x
        for k in range(D):
            facc[k] = zero
        c4 = 0 if l1 else C - C % 4
        for ch in range(0, c4, 4):  # dot product, four channels at a time
            a0 = np.float32(lfeat[y, ch, x])
            a1 = np.float32(lfeat[y, ch + 1, x])
            a2 = np.float32(lfeat[y, ch + 2, x])
            a3 = np.float32(lfeat[y, ch + 3, x])
            b0 = ch * nrr + j0
            b1 = b0 + nrr
            b2 = b1 + nrr
            b3 = b2 + nrr
            for k in range(D):
                facc[k] += ((a0 * frev[_U(b0 + k)] + a1 * frev[_U(b1 + k)])
                            + (a2 * frev[_U(b2 + k)] + a3 * frev[_U(b3 + k)]))
        for ch in range(c4, C):
            a = np.float32(lfeat[y, ch, x])
            b = ch * nrr + j0
            if l1:
                for k in range(D):
                    facc[k] += abs(a - frev[_U(b + k)])
            else:
                for k in range(D):
                    facc[k] += a * frev[_U(b + k)]
        cb = x * D
        if census:
            a0, a1, a2, a3, q0, q1, q2, q3 = _census_at(lcode, y, x, W, nrr)
            for k in range(D):
                ham[k] = _hamming(rrev, a0, a1, a2, a3, q0, q1, q2, q3, k)
            for k in range(D):
                v = min(max(fbase + facc[k] * fmul, zero), top)
                t = np.int16((np.int32(ham[k]) * cmul + np.int32(1 << (CENSUS_MUL_SHIFT - 1))) >> CENSUS_MUL_SHIFT)
                crow[_U(cb + k)] = max16(min16(add16(np.int16(v), t), cmax16), floor[k])
            continue
        for k in range(D):
            v = min(max(fbase + facc[k] * fmul, zero), top)
            crow[_U(cb + k)] = max16(np.int16(v), floor[k])
    cout = np.int16(cost.outside_cost) if cost.outside_cost >= 0 else np.int16(cost.invalid_cost)
    nd = cost.num_disparities
    for x in range(W):  # disparities whose match is outside the right image (cost.valid_range): no evidence
        k_lo, k_hi = max(0, x - dmin - W + 1), min(nd - 1, x - dmin)
        if k_lo > 0 or k_hi < nd - 1:
            cb = x * D
            for k in range(nd):
                if k < k_lo or k > k_hi:
                    crow[_U(cb + k)] = cout


def check_features(features, H: int, W: int) -> tuple[np.ndarray, np.ndarray]:
    """The (left, right) pair of (H, C, W) int8 features of ``cost="features"``; ValueError otherwise."""
    ok = isinstance(features, (tuple, list)) and len(features) == 2
    if ok:
        lf, rf = features
        ok = (isinstance(lf, np.ndarray) and isinstance(rf, np.ndarray) and lf.dtype == rf.dtype == np.int8
              and lf.ndim == 3 and lf.shape == rf.shape and lf.shape[0] == H and lf.shape[2] == W
              and lf.shape[1] >= 1 and lf.flags.c_contiguous and rf.flags.c_contiguous and lf is not rf)
    if not ok:
        raise ValueError(f"`features` must be two distinct C-contiguous int8 arrays (H, C, W) with (H, W) = {(H, W)}, "
                         f"got {_describe(features)}")
    return lf, rf


def _describe(features) -> str:
    if isinstance(features, (tuple, list)):
        return ", ".join(f"{getattr(a, 'dtype', type(a).__name__)} {getattr(a, 'shape', '')}" for a in features)
    return type(features).__name__


def with_features(settings, features, similarity: str, H: int, W: int, census_share: float = 0.0,
                  census_bits: int = 62):
    """(settings, C): a ``cost.CostSettings`` of the ``FEATURES`` kind completed with ``feature_cost_terms`` for the
    checked ``features`` and their channel count, and the census term's multiplier (``census_term_mul``) for
    ``census_share`` of a census code of ``census_bits`` bits; any other kind unchanged and 0."""
    if settings.kind != FEATURES:
        return settings, 0
    channels = check_features(features, H, W)[0].shape[1]
    terms = feature_cost_terms(similarity, channels, census_share)
    return settings._replace(feature_l1=terms[0], feature_base=terms[1], feature_mul=terms[2],
                             feature_census_mul=census_term_mul(census_share, census_bits)), channels


#: ``feature_similarity`` values of ``sgm_match``.
FEATURE_SIMILARITIES = ("dot", "l1")


def feature_cost_terms(similarity: str, channels: int, census_share: float = 0.0) -> tuple[int, float, float]:
    """(feature_l1, feature_base, feature_mul) of ``CostSettings`` for int8 unit features of ``channels`` channels:
    dot: ``FEATURE_SCALE * (1 - acc / FEATURE_QUANT**2)`` rounded; L1: ``FEATURE_SCALE * acc / (FEATURE_QUANT *
    sqrt(C))`` rounded (the L1 distance of unit vectors over sqrt(C): about their L2 distance, at most 2 for
    vectors spread over the channels; clipped at 2). Both times ``1 - census_share`` (the rest of the range is the
    census term's)."""
    own = 1.0 - float(census_share)
    if similarity == "dot":
        return 0, own * FEATURE_SCALE + 0.5, -own * FEATURE_SCALE / FEATURE_QUANT**2
    if similarity == "l1":
        return 1, 0.5, own * FEATURE_SCALE / (FEATURE_QUANT * float(np.sqrt(channels)))
    raise ValueError(f"`feature_similarity` must be one of {', '.join(map(repr, FEATURE_SIMILARITIES))}, "
                     f"got {similarity!r}")



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
