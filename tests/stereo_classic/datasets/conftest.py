"""Fixtures of the dataset tests: the checks every loaded scene must pass."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from stereo_classic.datasets import Scene


def _check_scene(s: Scene, shape: tuple[int, int]) -> None:
    assert s.left.shape == shape + (3,) and s.right.shape == shape + (3,)
    assert s.left.dtype == np.uint8 and s.right.dtype == np.uint8
    if s.gt_disparity is not None:
        gt = s.gt_disparity
        assert gt.shape == shape and gt.dtype == np.float32
        assert not np.isinf(gt).any(), "unknown must be NaN, never inf"
        assert np.nanmin(gt) > 0
    if s.nonocc_mask is not None:
        assert s.nonocc_mask.shape == shape and s.nonocc_mask.dtype == bool
        if s.gt_disparity is not None:
            assert np.isfinite(s.gt_disparity[s.nonocc_mask]).all()
    if s.rig is not None:
        assert s.rig.image_size == (shape[1], shape[0])


@pytest.fixture
def check_scene() -> Callable[[Scene, tuple[int, int]], None]:
    """``check_scene(scene, (H, W))``: the pair, ground truth, mask and rig agree in shape, dtype and convention."""
    return _check_scene
