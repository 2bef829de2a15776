"""Tests for stereo_classic.fusion.reference: the LiDAR reference itself."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stereo_classic.fusion import FusionInputError, sparse_depth_reference


def test_sparse_depth_reference_picks_the_nearest_dense_cluster():
    rng = np.random.default_rng(7)
    depth = np.zeros((100, 200))
    sample = rng.random((100, 200)) < 0.1  # sparse like projected LiDAR
    scene = np.full((100, 200), 30.0)                   # background wall
    scene[20:80, 50:150] = 10.0 + 0.02 * rng.standard_normal((60, 100))  # the object
    scene[20:80, 50:58] = 4.0                           # a thin occluder at the box edge (< 20 %)
    depth[sample] = scene[sample]
    depth[3, 3] = 2.0                                   # a stray point outside the box
    ref = sparse_depth_reference(depth, [[40, 10, 160, 90], [0, 0, 10, 10], [170, 0, 200, 20]])
    assert ref[0] == pytest.approx(10.0, abs=0.02)
    assert math.isnan(ref[1])                           # only one point there: no dense cluster (min 5)
    assert ref[2] == pytest.approx(30.0)                # only the wall


def test_sparse_depth_reference_occluder_that_is_dense_wins_and_bad_input():
    depth = np.zeros((50, 50))
    depth[::2, ::2] = 20.0
    depth[::2, 10:26:2] = 5.0  # a large near object: dense, nearest
    assert sparse_depth_reference(depth, [[0, 0, 50, 50]], box_shrink=0.0)[0] == 5.0
    with pytest.raises(FusionInputError, match="sparse_depth"):
        sparse_depth_reference(np.zeros(5), [[0, 0, 1, 1]])
    with pytest.raises(FusionInputError, match="box_shrink"):
        sparse_depth_reference(depth, [[0, 0, 1, 1]], box_shrink=1.5)
