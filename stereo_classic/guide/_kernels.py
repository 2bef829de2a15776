"""The ground search's inner loops (numba): scoring RANSAC hypotheses and the inlier statistics of a refit.

With NumPy each step of these made an (N, K) temporary (N candidate points, K hypotheses): eight passes over
about 77 000 values per RANSAC round, and a refit's fancy indexing per round; here each is one or two passes.
Counts are exact; sums run in a fixed order, so the same input gives the same output on any machine.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["inlier_mask", "inlier_scatter", "score_hypotheses"]


@njit(cache=True, nogil=True)
def score_hypotheses(cand, band, mask, normals, offsets):  # pragma: no cover - numba
    """The index of the best hypothesis: the most points of ``mask`` within ``band`` of its plane
    (``normals[k] . p + offsets[k]``) less the points more than three bands below it that are nearer (smaller z)
    than the mean depth of its inliers; the first of equal scores."""
    n = cand.shape[0]
    K = normals.shape[0]
    best = -1
    best_score = -(1 << 62)
    for k in range(K):
        a, b, c, o = normals[k, 0], normals[k, 1], normals[k, 2], offsets[k]
        support = 0
        count = 0
        zsum = 0.0
        for i in range(n):
            s = cand[i, 0] * a + cand[i, 1] * b + cand[i, 2] * c + o
            if abs(s) < band[i]:
                count += 1
                zsum += cand[i, 2]
                if mask[i]:
                    support += 1
        reach = zsum / max(count, 1)
        below = 0
        for i in range(n):
            s = cand[i, 0] * a + cand[i, 1] * b + cand[i, 2] * c + o
            if s < -3.0 * band[i] and cand[i, 2] < reach:
                below += 1
        score = support - below
        if score > best_score:
            best_score = score
            best = k
    return best


@njit(cache=True, nogil=True)
def inlier_mask(cand, band, up, h, out):  # pragma: no cover - numba
    """``out`` = |up . p + h| < band per point; returns how many are."""
    n_in = 0
    for i in range(cand.shape[0]):
        inside = abs(cand[i, 0] * up[0] + cand[i, 1] * up[1] + cand[i, 2] * up[2] + h) < band[i]
        out[i] = inside
        n_in += inside
    return n_in


@njit(cache=True, nogil=True)
def inlier_scatter(cand, inl):  # pragma: no cover - numba
    """The centre (3,) of the points of ``inl`` and their scatter matrix (3, 3) about it."""
    centre = np.zeros(3)
    n = 0
    for i in range(cand.shape[0]):
        if inl[i]:
            n += 1
            for j in range(3):
                centre[j] += cand[i, j]
    centre /= max(n, 1)
    scatter = np.zeros((3, 3))
    for i in range(cand.shape[0]):
        if inl[i]:
            d0, d1, d2 = cand[i, 0] - centre[0], cand[i, 1] - centre[1], cand[i, 2] - centre[2]
            scatter[0, 0] += d0 * d0
            scatter[0, 1] += d0 * d1
            scatter[0, 2] += d0 * d2
            scatter[1, 1] += d1 * d1
            scatter[1, 2] += d1 * d2
            scatter[2, 2] += d2 * d2
    scatter[1, 0] = scatter[0, 1]
    scatter[2, 0] = scatter[0, 2]
    scatter[2, 1] = scatter[1, 2]
    return centre, scatter
