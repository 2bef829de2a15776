"""Tests for stereo_classic.fusion.ransac: ransac_1d against a brute-force reference, sequential_clusters."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stereo_classic.fusion import FusionInputError, ransac_1d
from stereo_classic.fusion.ransac import sequential_clusters


# --- ransac_1d against a brute-force reference -------------------------------------------------------

def _brute_force_best_count(values, tol):
    return max(int(((values >= h - tol) & (values <= h + tol)).sum()) for h in values)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(-100, 100, allow_nan=False), min_size=1, max_size=60),
       st.floats(0.01, 20))
def test_ransac_1d_finds_the_largest_consistent_set(values, tol):
    v = np.array(values)
    centre, inl = ransac_1d(v, tol)
    assert inl.shape == v.shape and inl.dtype == bool
    assert inl.sum() >= _brute_force_best_count(v, tol)  # refinement never loses support
    assert np.all((v[inl] >= centre - tol) & (v[inl] <= centre + tol))


def test_ransac_1d_edge_cases():
    c, m = ransac_1d(np.zeros(0), 1.0)
    assert math.isnan(c) and m.shape == (0,)
    with pytest.raises(FusionInputError, match="tolerance"):
        ransac_1d(np.ones(3), -1.0)
    with pytest.raises(FusionInputError, match="finite"):
        ransac_1d(np.array([1.0, np.inf]), 1.0)


@pytest.mark.parametrize("kwargs, needle", [
    ({"max_iterations": 0}, "`max_iterations`"),
    ({"max_iterations": -3}, "`max_iterations`"),
    ({"max_iterations": 2.5}, "`max_iterations`"),
    ({"max_iterations": True}, "`max_iterations`"),
    ({"tolerance": "1"}, "`tolerance`"),
    ({"tolerance": None}, "`tolerance`"),
    ({"tolerance": [1.0]}, "`tolerance`"),
    ({"tolerance": np.nan}, "`tolerance`"),
    ({"tolerance": True}, "`tolerance`"),
])
def test_ransac_1d_checks_its_parameters(kwargs, needle):
    # both on an empty and on a non-empty input: the check comes before any work
    for values in (np.zeros(0), np.array([1.0, 1.1, 5.0])):
        call = {"tolerance": 1.0, **kwargs}
        with pytest.raises(FusionInputError, match=needle):
            ransac_1d(values, call.pop("tolerance"), **call)


def test_sequential_clusters_heaviest_first_with_disjoint_members():
    rng = np.random.default_rng(0)
    values = np.concatenate([10.0 + 0.1 * rng.standard_normal(60), 25.0 + 0.1 * rng.standard_normal(30)])
    clusters = sequential_clusters(values, np.ones(values.size), 1.0, 0.0, 3, 256, np.random.default_rng(0), 5)
    assert [round(c.centre) for c in clusters] == [10, 25]
    assert [int(c.mask.sum()) for c in clusters] == [60, 30] and clusters[0].support == 60.0
    assert not np.any(clusters[0].mask & clusters[1].mask)
    assert all(c.low <= c.centre <= c.high for c in clusters)
    # fewer remaining values than min_pixels: no further round
    assert len(sequential_clusters(values, np.ones(values.size), 1.0, 0.0, 3, 256, np.random.default_rng(0), 40)) == 1
