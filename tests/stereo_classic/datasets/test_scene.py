"""stereo_classic.datasets.scene: a Scene checks itself when built."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_classic.datasets import Scene


def test_scene_checks_itself() -> None:
    img = np.zeros((4, 5, 3), np.uint8)
    Scene("ok", img, img, gt_disparity=np.full((4, 5), np.nan, np.float32), max_disparity=np.int64(16))
    with pytest.raises(ValueError, match="same shape"):
        Scene("x", img, img[:3])
    with pytest.raises(ValueError, match="gt_disparity"):
        Scene("x", img, img, gt_disparity=np.zeros((4, 5)))
    with pytest.raises(ValueError, match="NaN"):
        Scene("x", img, img, gt_disparity=np.full((4, 5), np.inf, np.float32))
    with pytest.raises(ValueError, match="nonocc_mask"):
        Scene("x", img, img, nonocc_mask=np.zeros((4, 5), np.uint8))
    with pytest.raises(ValueError, match="max_disparity"):
        Scene("x", img, img, max_disparity=0)
    with pytest.raises(TypeError, match="max_disparity"):
        Scene("x", img, img, max_disparity=16.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="lidar_points"):
        Scene("x", img, img, lidar_points=np.zeros((3, 2), np.float32))
    with pytest.raises(ValueError, match="left"):
        Scene("x", img.astype(np.float32), img)
