"""calib.rectified.RectifiedRig: checks when built, Q and projections, scaling, rectify_pair and its vertical
offset warnings."""

from __future__ import annotations

import logging
import warnings

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib import CalibrationError, RectificationWarning, RectifiedRig, StereoRig


class TestRectifiedRig:
    rig = RectifiedRig(focal_px=999.421, cx_left=294.182, cx_right=326.96, cy=252.932, baseline_m=0.193001, image_size=(741, 497))

    def test_doffs_q_projections(self):
        assert self.rig.doffs == pytest.approx(32.778)
        q = self.rig.Q
        assert q.shape == (4, 4)
        x, y, z, w = q @ np.array([100.0, 50.0, 40.0, 1.0])
        assert z / w == pytest.approx(999.421 * 0.193001 / (40.0 + 32.778))
        # P matrices agree with Q: project a point with both, disparity -> same depth
        point = np.array([0.3, -0.1, 2.5, 1.0])
        ul = self.rig.P_left @ point
        ur = self.rig.P_right @ point
        d = ul[0] / ul[2] - ur[0] / ur[2]
        assert float(self.rig.depth(np.array([d]))[0]) == pytest.approx(2.5, rel=1e-6)

    def test_scaled(self):
        half = self.rig.scaled(0.5)
        assert half.image_size == (370, 248) or half.image_size == (370, 249)
        assert half.focal_px == pytest.approx(999.421 / 2)
        assert half.baseline_m == self.rig.baseline_m
        assert half.doffs == pytest.approx(32.778 / 2)
        # the same point gives the same depth at both scales
        assert float(half.depth(np.array([20.0]))[0]) == pytest.approx(float(self.rig.depth(np.array([40.0]))[0]), rel=1e-6)

    @pytest.mark.parametrize("factor", [0.0, -1.0, float("nan"), float("inf"), 1e-6, "2"])
    def test_scaled_errors(self, factor):
        with pytest.raises(CalibrationError, match="factor"):
            self.rig.scaled(factor)

    @pytest.mark.parametrize(
        "overrides, match",
        [
            ({"focal_px": 0.0}, "focal_px"),
            ({"focal_px": float("nan")}, "focal_px"),
            ({"baseline_m": -0.1}, "baseline_m"),
            ({"cx_left": float("inf")}, "cx_left"),
            ({"cy": None}, "cy"),
            ({"image_size": (0, 10)}, "image_size"),
            ({"image_size": (True, 10)}, "image_size"),
            ({"maps_left": (np.zeros((2, 2)), None)}, "maps_left.*maps_right"),
            ({"roi_left": (0, 0, -1, 5)}, "roi_left"),
            ({"baseline_m": 1e-300}, "baseline_m.*plausible range"),
            ({"focal_px": 1e300}, "focal_px.*plausible range"),
        ],
    )
    def test_errors(self, overrides, match):
        args = dict(focal_px=700.0, cx_left=320.0, cx_right=320.0, cy=240.0, baseline_m=0.1, image_size=(640, 480))
        args.update(overrides)
        with pytest.raises(CalibrationError, match=match):
            RectifiedRig(**args)

    def test_millimetre_baseline_is_flagged(self, caplog):
        with caplog.at_level(logging.WARNING):
            RectifiedRig(focal_px=700.0, cx_left=320.0, cx_right=320.0, cy=240.0, baseline_m=193.0, image_size=(640, 480))
        assert "millimetres" in caplog.text

    def test_rectify_pair_without_maps_checks_size(self):
        left = np.zeros((497, 741, 3), np.uint8)
        out_l, out_r = self.rig.rectify_pair(left, left.copy())
        assert out_l is left or np.shares_memory(out_l, left)
        with pytest.raises(ValueError, match="scaled"):
            self.rig.rectify_pair(left[:100], left[:100])
        with pytest.raises(ValueError, match="same shape"):
            self.rig.rectify_pair(left, left[:, :, 0])


class TestRectifyPairOnRealImages:
    def test_warns_when_offset_above_one_pixel(self, motorcycle_pair, caplog):
        d, left, right = motorcycle_pair
        rig = RectifiedRig.from_middlebury(d / "calib.txt")
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            rig.rectify_pair(left, right, check_offset=True)  # no warning on the real rectified pair
        with pytest.warns(RectificationWarning, match="vertical offset"):
            rig.rectify_pair(left, np.roll(right, 4, axis=0), check_offset=True)

    def test_maps_with_wrong_calibration_warn(self, motorcycle_pair):
        _, left, right = motorcycle_pair
        h, w = left.shape[:2]
        k = np.array([[999.421, 0, 294.182], [0, 999.421, 252.932], [0, 0, 1]])
        good = StereoRig(k, np.zeros(5), k, np.zeros(5), np.eye(3), [-0.193, 0, 0], (w, h)).rectify()
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            rl, rr = good.rectify_pair(left, right)
        assert rl.shape == left.shape and rl.dtype == np.uint8
        tilted = StereoRig(k, np.zeros(5), k, np.zeros(5), cv2.Rodrigues(np.array([0.01, 0.0, 0.0]))[0],
                           [-0.193, 0, 0], (w, h)).rectify()
        with pytest.warns(RectificationWarning):
            tilted.rectify_pair(left, right)
        with warnings.catch_warnings():  # by default only the first pair is measured
            warnings.simplefilter("error")
            tilted.rectify_pair(left, right)
        with pytest.warns(RectificationWarning):
            tilted.rectify_pair(left, right, check_offset=True)
        with pytest.raises(ValueError, match="raw images"):
            good.rectify_pair(left[:200], right[:200])


@settings(max_examples=180, deadline=None)
@given(
    f=st.floats(allow_nan=True, allow_infinity=True),
    b=st.floats(allow_nan=True, allow_infinity=True),
    cx=st.floats(allow_nan=True, allow_infinity=True),
    size=st.tuples(st.integers(-3, 3000), st.integers(-3, 3000)),
)
def test_property_rectified_rig_valid_or_named_error(f, b, cx, size):
    try:
        rig = RectifiedRig(focal_px=f, cx_left=cx, cx_right=cx, cy=10.0, baseline_m=b, image_size=size)
    except CalibrationError as exc:
        assert any(name in str(exc) for name in ("focal_px", "baseline_m", "cx_left", "image_size"))
    else:
        assert rig.focal_px > 0 and rig.baseline_m > 0 and np.isfinite(rig.Q).all()
