"""stereo_classic.datasets.demo: the scikit-image Motorcycle pair as a Scene, rig as documented."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from stereo_classic.datasets import demo_scene


def test_demo_scene(check_scene: Callable[..., None]) -> None:
    s = demo_scene()
    check_scene(s, (500, 741))
    assert s.rig.focal_px == pytest.approx(994.978)
    assert s.rig.baseline_m == pytest.approx(0.193001)
    assert s.rig.doffs == pytest.approx(31.086)
    # principal point as documented in skimage.data.stereo_motorcycle.__doc__
    assert s.rig.cx_left == pytest.approx(311.193)
    assert s.rig.cx_right == pytest.approx(311.193 + 31.086)
    assert s.rig.cy == pytest.approx(254.877)
    from skimage import data

    rgb, _, disp = data.stereo_motorcycle()
    np.testing.assert_array_equal(s.left[..., ::-1], rgb)  # BGR
    np.testing.assert_array_equal(np.isnan(s.gt_disparity), ~np.isfinite(disp))
    assert float(np.nanmax(s.gt_disparity)) == pytest.approx(59.90896, abs=1e-4)
    depth = s.rig.depth(s.gt_disparity)
    assert 1.5 < np.nanmedian(depth) < 3.5  # a motorbike a few metres away
