"""The SAD cost's and the census + grad cost's window sums, one row at a time (numba): column sums per (x, k) moved
down the image by one row in and one row out, and the window sum of the first column (``row_cost`` moves it along
the row).

The right-image rows are read reversed, as in :mod:`.cost`: ``srev[j]`` (and ``irev``) hold right column
``clamp(W - 1 + h - dmin - j)``, so that the D candidates of a column are a contiguous slice.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from stereo_classic.matching._kernels.features import _clamp, reverse_run
from stereo_classic.matching._kernels.intrinsics import absdiff16, add16, shr16, sub16
from stereo_classic.matching._kernels.pipeline import NoAliasCompiler
from stereo_classic.matching._kernels.tags import tag_disparities

# ``_nrt=False``: kernels that run per row and allocate nothing, compiled without numba's reference counts on their
# array arguments (atomic updates, on every call, of counters both workers share; docs/matching.md, seventh round).
__all__ = ["moved_column", "sad_colsum_advance", "sad_colsum_columns", "sad_colsum_init", "sad_colsum_row",
           "sad_hsum_init", "sad_reverse_pair", "sad_reverse_row"]

_U = np.uint64  # unsigned indices: numba adds no negative-index wraparound, LLVM emits plain vector loads


@njit(_nrt=False, cache=True, nogil=True)
def sad_reverse_row(rsob, rint, y, srev, irev, dmin, h, intensity):  # pragma: no cover - numba
    """srev[j] = rsob[y, clamp(W - 1 + h - dmin - j)], same for the intensity row (when ``intensity``)."""
    K = rsob.shape[1] - 1 + h - dmin
    reverse_run(rsob[y], K, srev, 0, srev.shape[0])
    if intensity:
        reverse_run(rint[y], K, irev, 0, irev.shape[0])


@njit(_nrt=False, cache=True, nogil=True, pipeline_class=NoAliasCompiler)
def sad_colsum_row(colsum, add, lsob, lint, y, srev, irev, h, D, intensity):  # pragma: no cover - numba
    """colsum[(x' + h) * D + k] (+/-)= AD(x', x' - dmin - k) for x' in [-h, W + h), one image row.

    AD = |sobel_L - sobel_R| (+ |I_L - I_R| // 4 when ``intensity``, the SAD cost). srev/irev come from
    sad_reverse_row for the same row.
    """
    W = lsob.shape[1]
    two = np.int16(2)
    for xp in range(-h, W + h):
        c = _clamp(xp, W)
        ls = lsob[y, c]
        li = lint[y, c] if intensity else np.int16(0)
        j0 = W - 1 + h - xp
        base = (xp + h) * D
        if add and intensity:
            for k in range(D):
                ad = add16(absdiff16(ls, srev[_U(j0 + k)]), shr16(absdiff16(li, irev[_U(j0 + k)]), two))
                colsum[_U(base + k)] = add16(colsum[_U(base + k)], ad)
        elif intensity:
            for k in range(D):
                ad = add16(absdiff16(ls, srev[_U(j0 + k)]), shr16(absdiff16(li, irev[_U(j0 + k)]), two))
                colsum[_U(base + k)] = sub16(colsum[_U(base + k)], ad)
        elif add:
            for k in range(D):
                colsum[_U(base + k)] = add16(colsum[_U(base + k)], absdiff16(ls, srev[_U(j0 + k)]))
        else:
            for k in range(D):
                colsum[_U(base + k)] = sub16(colsum[_U(base + k)], absdiff16(ls, srev[_U(j0 + k)]))


@njit(_nrt=False, cache=True, nogil=True, pipeline_class=NoAliasCompiler)
def sad_colsum_init(colsum, y, lsob, lint, rsob, rint, srev, irev, dmin, h, D, intensity):  # pragma: no cover
    """colsum = sum of AD rows clamp(y - h) .. clamp(y + h)."""
    H = lsob.shape[0]
    colsum[:] = 0
    for yy in range(y - h, y + h + 1):
        yc = _clamp(yy, H)
        sad_reverse_row(rsob, rint, yc, srev, irev, dmin, h, intensity)
        sad_colsum_row(colsum, True, lsob, lint, yc, srev, irev, h, D, intensity)


@njit(_nrt=False, cache=True, nogil=True)
def sad_reverse_pair(y, step, rsob, rint, srev, irev, dmin, h, intensity):  # pragma: no cover - numba
    """The two image rows that move the column window from row y - step to row y (``yin`` = y + step * h enters,
    ``yout`` = y - step * (h + 1) leaves, both clamped), and, unless they are the same row, their right rows
    reversed: ``srev`` (and ``irev`` when ``intensity``) holds the one in, then the one out, each of length
    ``L = W + 2h + D - 1`` (D = ``len(srev) // 2 - W - 2h + 1``). Returns (yin, yout, L)."""
    H = rsob.shape[0]
    W = rsob.shape[1]
    yin = _clamp(y + step * h, H)
    yout = _clamp(y - step * (h + 1), H)
    L = srev.shape[0] // 2
    if yin == yout:
        return yin, yout, L
    K = W - 1 + h - dmin
    reverse_run(rsob[yin], K, srev, 0, L)
    reverse_run(rsob[yout], K, srev, L, L)
    if intensity:
        reverse_run(rint[yin], K, irev, 0, L)
        reverse_run(rint[yout], K, irev, L, L)
    return yin, yout, L


@njit(_nrt=False, cache=True, nogil=True, inline="always")
def moved_column(colsum, srev, a, b, j0, j1, base, k):  # pragma: no cover - numba
    """The gradient column sum ``colsum[base + k]`` moved on by one row (|a - srev[j0 + k]| in, |b - srev[j1 + k]|
    out), stored and returned."""
    cs = add16(colsum[_U(base + k)], sub16(absdiff16(a, srev[_U(j0 + k)]), absdiff16(b, srev[_U(j1 + k)])))
    colsum[_U(base + k)] = cs
    return cs


@njit(_nrt=False, cache=True, nogil=True, pipeline_class=NoAliasCompiler)
def sad_colsum_columns(colsum, xp0, xp1, yin, yout, lsob, lint, srev, irev, L, h, tag,
                       intensity):  # pragma: no cover
    """Move the column sums of the padded columns xp + h, xp in [xp0, xp1), from row y - step to row y
    (``sad_reverse_pair``'s rows; ``tag``: ``disparity_tag(D)``)."""
    D = tag_disparities(tag)
    W = lsob.shape[1]
    two = np.int16(2)
    for xp in range(xp0, xp1):
        c = _clamp(xp, W)
        a = lsob[yin, c]
        b = lsob[yout, c]
        j0 = W - 1 + h - xp
        j1 = j0 + L
        base = (xp + h) * D
        if intensity:
            ai = lint[yin, c]
            bi = lint[yout, c]
            for k in range(D):
                add = add16(absdiff16(a, srev[_U(j0 + k)]), shr16(absdiff16(ai, irev[_U(j0 + k)]), two))
                drop = add16(absdiff16(b, srev[_U(j1 + k)]), shr16(absdiff16(bi, irev[_U(j1 + k)]), two))
                colsum[_U(base + k)] = add16(colsum[_U(base + k)], sub16(add, drop))
        else:
            for k in range(D):
                moved_column(colsum, srev, a, b, j0, j1, base, k)


@njit(_nrt=False, cache=True, nogil=True, pipeline_class=NoAliasCompiler)
def sad_colsum_advance(colsum, y, step, lsob, lint, rsob, rint, srev, irev, dmin, h, tag,
                       intensity):  # pragma: no cover
    """Move the column window from row y - step to row y: add row y + step*h and drop row y - step*(h+1), in
    one sweep over the column sums (``srev`` / ``irev`` hold two reversed rows: the one in, then the one out;
    ``tag``: ``disparity_tag(D)``)."""
    yin, yout, L = sad_reverse_pair(y, step, rsob, rint, srev, irev, dmin, h, intensity)
    if yin != yout:
        sad_colsum_columns(colsum, -h, lsob.shape[1] + h, yin, yout, lsob, lint, srev, irev, L, h, tag, intensity)


@njit(_nrt=False, cache=True, nogil=True)
def sad_hsum_init(hsum, colsum, x, h, D):  # pragma: no cover - numba
    """hsum[k] = sum of colsum over x' in [x - h, x + h]."""
    for k in range(D):
        hsum[k] = 0
    for xp in range(x - h, x + h + 1):
        base = (xp + h) * D
        for k in range(D):
            hsum[k] += colsum[_U(base + k)]
