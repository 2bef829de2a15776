"""The guide's fast percentile / median (stereo_classic.guide._stats) and the ground search's numba loops
(stereo_classic.guide._kernels) against their NumPy definitions."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_classic.guide._kernels import inlier_mask, inlier_scatter, score_hypotheses
from stereo_classic.guide._stats import median, percentile


def test_percentile_and_median_equal_numpy_to_the_last_bit():
    rng = np.random.default_rng(0)
    for i in range(3000):
        n = int(rng.integers(1, 300))
        x = rng.normal(size=n) * rng.choice([1e-3, 1.0, 1e3])
        if i % 4 == 0:
            x = np.round(x, 1)  # ties
        for q in (0, 1, 2, 5, 37.3, 50, 95, 99, 99.9, 100, [5, 95], [1, 50, 99]):
            ours, theirs = percentile(x, q), np.percentile(x, q)
            np.testing.assert_array_equal(ours, theirs)
            assert isinstance(ours, float) == (np.ndim(q) == 0)
        assert median(x) == np.median(x)


def test_percentile_and_median_fall_back_to_numpy():
    x32 = np.array([3.0, 1.0, 2.0, 10.0], np.float32)
    assert percentile(x32, 50) == np.percentile(x32, 50) and median(x32) == np.median(x32)
    with_nan = np.array([1.0, np.nan, 3.0])
    assert np.isnan(percentile(with_nan, 50)) and np.isnan(median(with_nan))
    with pytest.raises(IndexError):
        percentile(np.zeros(0), 50)  # as NumPy: an empty sample has no percentile


def _score_reference(cand, band, mask, normals, offsets):
    signed = cand @ normals.T + offsets[None, :]
    inlier = np.abs(signed) < band[:, None]
    support = (mask[:, None] & inlier).sum(axis=0)
    reach = (cand[:, 2:3] * inlier).sum(axis=0) / np.maximum(inlier.sum(axis=0), 1)
    below = ((signed < -3 * band[:, None]) & (cand[:, 2:3] < reach[None, :])).sum(axis=0)
    return int(np.argmax(support - below))


def test_ground_kernels_equal_their_numpy_definitions():
    rng = np.random.default_rng(1)
    for _ in range(60):
        n, k = int(rng.integers(5, 400)), int(rng.integers(1, 40))
        floor = np.column_stack([rng.uniform(-2, 2, n), rng.normal(1.2, 0.05, n), rng.uniform(0.5, 4, n)])
        cand = np.where(rng.random((n, 1)) < 0.3, floor - [0, rng.uniform(0, 0.8), 0], floor)  # a table top
        band = rng.uniform(0.03, 0.1, n)
        mask = rng.random(n) < 0.8
        normals = rng.normal([0, -1, 0], 0.2, (k, 3))
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        offsets = rng.uniform(0.3, 2.0, k)
        assert score_hypotheses(cand, band, mask, normals, offsets) == _score_reference(cand, band, mask, normals,
                                                                                       offsets)
        inl = np.empty(n, np.bool_)
        count = inlier_mask(cand, band, normals[0], float(offsets[0]), inl)
        np.testing.assert_array_equal(inl, np.abs(cand @ normals[0] + offsets[0]) < band)
        assert count == inl.sum()
        if count:
            centre, scatter = inlier_scatter(cand, inl)
            d = cand[inl] - cand[inl].mean(axis=0)
            np.testing.assert_allclose(centre, cand[inl].mean(axis=0), rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(scatter, d.T @ d, rtol=1e-9, atol=1e-9)
