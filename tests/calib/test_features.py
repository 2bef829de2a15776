"""calib.features.vertical_offset: the residual vertical offset of a pair, on the real rectified pairs."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from calib import vertical_offset


class TestVerticalOffset:
    def test_vertical_offset_of_a_rectified_pair_is_small(self, motorcycle_pair):
        _, left, right = motorcycle_pair
        offset = vertical_offset(left, right)
        assert 0.05 < offset < 0.5  # sub-pixel, not whole pixels; calib.txt says dyavg = 0.23
        assert vertical_offset(left, np.roll(right, 3, axis=0)) == pytest.approx(3.0, abs=0.4)
        half_px = cv2.warpAffine(right, np.float32([[1, 0, 0], [0, 1, 1.5]]), (right.shape[1], right.shape[0]))
        assert 1.0 < vertical_offset(left, half_px) < 2.0

    def test_vertical_offset_of_the_kitti_pair(self, kitti_pair):
        left, right = kitti_pair
        assert vertical_offset(left, right) < 0.5
        assert vertical_offset(left[..., 1].astype(np.float32), right[..., 1].astype(np.float32)) < 0.5  # any dtype

    def test_vertical_offset_errors(self):
        with pytest.raises(ValueError, match="left"):
            vertical_offset(np.zeros((0, 5), np.uint8), np.zeros((5, 5), np.uint8))
        with pytest.raises(ValueError, match="right"):
            vertical_offset(np.zeros((5, 5), np.uint8), np.array([["a"]]))
        with pytest.raises(ValueError, match="max_features"):
            vertical_offset(np.zeros((5, 5), np.uint8), np.zeros((5, 5), np.uint8), max_features=0)

    def test_vertical_offset_soft_failure_on_blank_images(self):
        blank = np.full((100, 120), 128, np.uint8)
        assert np.isnan(vertical_offset(blank, blank))
