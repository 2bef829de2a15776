"""calib StereoRig / RectifiedRig: checks when built, rectification, Q, scaling, vertical offset warnings."""

from __future__ import annotations

import logging
import warnings

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib import CalibrationError, RectificationWarning, RectifiedRig, StereoRig, vertical_offset

K = np.array([[700.0, 0.0, 320.0], [0.0, 702.0, 240.0], [0.0, 0.0, 1.0]])
D = np.array([-0.1, 0.02, 0.001, -0.001, 0.0])
R_SMALL = cv2.Rodrigues(np.array([0.004, -0.01, 0.002]))[0]


def make_rig(**overrides):
    args = dict(K_left=K, dist_left=D, K_right=K, dist_right=D, R=R_SMALL, T=[-0.12, 0.001, 0.0], image_size=(640, 480))
    args.update(overrides)
    return StereoRig(**args)


def motorcycle(shared_data):
    d = shared_data / "middlebury2014" / "trainingQ" / "Motorcycle"
    return d, *read_pair(d / "im0.png", d / "im1.png")


def read_pair(left_path, right_path):
    """Skip only when the shared images are absent; images that exist must decode."""
    if not (left_path.is_file() and right_path.is_file()):
        pytest.skip(f"{left_path.parent} not available")
    left, right = cv2.imread(str(left_path)), cv2.imread(str(right_path))
    assert left is not None, f"{left_path} exists but cannot be decoded"
    assert right is not None, f"{right_path} exists but cannot be decoded"
    return left, right


class TestStereoRig:
    def test_smoke(self):
        rig = make_rig()
        assert rig.baseline_m == pytest.approx(np.hypot(0.12, 0.001))
        assert rig.K_left.dtype == np.float64 and rig.T.shape == (3,)
        assert not rig.K_left.flags.writeable
        assert rig == make_rig() and rig != make_rig(T=[-0.13, 0, 0])

    def test_accepts_column_vectors(self):
        rig = make_rig(T=np.array([[-0.12], [0.001], [0.0]]), dist_left=D.reshape(1, 5), dist_right=D[:4])
        assert rig.T.shape == (3,) and rig.dist_left.shape == (5,) and rig.dist_right.shape == (4,)

    @pytest.mark.parametrize(
        "overrides, match",
        [
            ({"K_left": np.eye(2)}, "K_left.*shape"),
            ({"K_right": [[0.0, 0, 320], [0, 700, 240], [0, 0, 1]]}, "K_right.*focal"),
            ({"K_left": [[-700.0, 0, 320], [0, 700, 240], [0, 0, 1]]}, "K_left.*focal"),
            ({"K_left": [[700.0, 0, 320], [0, 700, 240], [0, 0, 2]]}, "K_left.*camera matrix"),
            ({"K_left": [[700.0, 0, np.nan], [0, 700, 240], [0, 0, 1]]}, "K_left.*finite"),
            ({"dist_left": [0.1, 0.2, 0.3]}, "dist_left.*coefficients"),
            ({"dist_right": [0.1, np.inf, 0, 0, 0]}, "dist_right.*finite"),
            ({"R": np.eye(3) * 2}, "`R` must be a rotation"),
            ({"R": np.diag([1.0, 1.0, -1.0])}, "`R` must be a rotation"),
            ({"T": [0.0, 0.0, 0.0]}, "`T` must not be zero"),
            ({"T": [-1e-9, 0.0, 0.0]}, "`T`.*plausible range"),
            ({"K_left": [[1e12, 0, 320], [0, 1e12, 240], [0, 0, 1]]}, "K_left.*plausible range"),
            ({"T": [0.1, 0.2]}, "`T`.*shape"),
            ({"T": ["a", "b", "c"]}, "`T`"),
            ({"image_size": (640, 0)}, "image_size"),
            ({"image_size": (640.5, 480)}, "image_size"),
            ({"image_size": (640, 480, 3)}, "image_size"),
            ({"image_size": 640}, "image_size"),
        ],
    )
    def test_errors_name_the_field(self, overrides, match):
        with pytest.raises(CalibrationError, match=match):
            make_rig(**overrides)

    def test_rectify(self):
        rect = make_rig().rectify()
        assert isinstance(rect, RectifiedRig) and rect.has_maps
        assert rect.doffs == 0.0  # CALIB_ZERO_DISPARITY
        assert rect.baseline_m == pytest.approx(np.hypot(0.12, 0.001), rel=1e-9)
        assert rect.image_size == (640, 480) and rect.raw_image_size == (640, 480)
        assert rect.roi_left is not None and len(rect.roi_left) == 4
        # maps take a rectified pixel to the raw pixel it samples: a 3D point seen by both cameras lands on the
        # same rectified row
        pts = np.array([[0.1, -0.05, 1.5], [-0.3, 0.2, 3.0], [0.0, 0.0, 0.8]])
        left_px = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), K, D)[0]
        right_px = cv2.projectPoints(pts, cv2.Rodrigues(R_SMALL)[0], np.array([-0.12, 0.001, 0.0]), K, D)[0]
        rect_mats = make_rig().rectification()
        yl = cv2.undistortPoints(left_px, K, D, R=rect_mats["R1"], P=rect_mats["P1"]).reshape(-1, 2)
        yr = cv2.undistortPoints(right_px, K, D, R=rect_mats["R2"], P=rect_mats["P2"]).reshape(-1, 2)
        np.testing.assert_allclose(yl[:, 1], yr[:, 1], atol=1e-6)
        # and the rectified disparity gives back the true depth (in the rectified left frame, rotated by R1)
        z_rect = (pts @ rect_mats["R1"].T)[:, 2]
        np.testing.assert_allclose(rect.depth(yl[:, 0] - yr[:, 0]), z_rect, rtol=1e-5)

    def test_rectify_keeps_doffs_without_zero_disparity(self):
        rect = make_rig().rectify(zero_disparity=False, alpha=1.0)
        assert rect.focal_px > 0 and np.isfinite(rect.doffs)

    @pytest.mark.parametrize("alpha", [-0.5, 1.5, float("nan"), "0"])
    def test_rectify_bad_alpha(self, alpha):
        with pytest.raises(CalibrationError, match="alpha"):
            make_rig().rectify(alpha=alpha)

    @pytest.mark.parametrize("alpha", [-0.5, 1.5, float("nan"), "0", True])
    def test_rectification_bad_alpha(self, alpha):
        with pytest.raises(CalibrationError, match="alpha"):
            make_rig().rectification(alpha=alpha)

    @pytest.mark.parametrize(
        "image, match",
        [
            (np.zeros((8, 8), bool), "uint8, uint16 or float32.*bool"),
            (np.zeros((8, 8), np.float64), "uint8, uint16 or float32.*float64"),
            (np.zeros((8, 8, 5), np.uint8), "1 to 4 channels"),
        ],
    )
    def test_rectify_pair_bad_image(self, image, match):
        rect = make_rig().rectify()
        w, h = rect.raw_image_size
        big = np.zeros((h, w) + image.shape[2:], image.dtype)
        with pytest.raises(ValueError, match=f"`left` must be .*{match}" if "channels" not in match else match):
            rect.rectify_pair(big, big)

    @pytest.mark.parametrize("interpolation", [cv2.INTER_AREA, 99, -1, True, 1.0, "linear"])
    def test_rectify_pair_bad_interpolation(self, interpolation):
        rect = make_rig().rectify()
        w, h = rect.raw_image_size
        img = np.zeros((h, w), np.uint8)
        with pytest.raises(ValueError, match="`interpolation` must be one of"):
            rect.rectify_pair(img, img, interpolation=interpolation, check_offset=False)

    @pytest.mark.parametrize("interpolation", [cv2.INTER_NEAREST, cv2.INTER_LINEAR, cv2.INTER_CUBIC, cv2.INTER_LANCZOS4])
    @pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
    def test_rectify_pair_good_input(self, interpolation, dtype):
        rect = make_rig().rectify()
        w, h = rect.raw_image_size
        img = np.full((h, w, 3), 7, dtype)
        out_l, out_r = rect.rectify_pair(img, img, interpolation=interpolation, check_offset=False)
        assert out_l.dtype == np.dtype(dtype) and out_l.shape == (rect.image_size[1], rect.image_size[0], 3)

    def test_rectify_refuses_vertical_and_swapped_rigs(self):
        with pytest.raises(CalibrationError, match="horizontal"):
            make_rig(T=[0.0, -0.12, 0.0]).rectify()
        with pytest.raises(CalibrationError, match="swap"):
            make_rig(T=[0.12, 0.0, 0.0]).rectify()


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
    def test_vertical_offset_of_a_rectified_pair_is_small(self, shared_data):
        _, left, right = motorcycle(shared_data)
        offset = vertical_offset(left, right)
        assert 0.05 < offset < 0.5  # sub-pixel, not whole pixels; calib.txt says dyavg = 0.23
        assert vertical_offset(left, np.roll(right, 3, axis=0)) == pytest.approx(3.0, abs=0.4)
        half_px = cv2.warpAffine(right, np.float32([[1, 0, 0], [0, 1, 1.5]]), (right.shape[1], right.shape[0]))
        assert 1.0 < vertical_offset(left, half_px) < 2.0

    def test_vertical_offset_of_the_kitti_pair(self, shared_data):
        left, right = read_pair(shared_data / "kitti_object_pair/left.png", shared_data / "kitti_object_pair/right.png")
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

    def test_warns_when_offset_above_one_pixel(self, shared_data, caplog):
        d, left, right = motorcycle(shared_data)
        rig = RectifiedRig.from_middlebury(d / "calib.txt")
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            rig.rectify_pair(left, right, check_offset=True)  # no warning on the real rectified pair
        with pytest.warns(RectificationWarning, match="vertical offset"):
            rig.rectify_pair(left, np.roll(right, 4, axis=0), check_offset=True)

    def test_maps_with_wrong_calibration_warn(self, shared_data):
        _, left, right = motorcycle(shared_data)
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
    fx=st.one_of(st.floats(-10.0, 5000.0), st.sampled_from([float("nan"), float("inf")])),
    cx=st.floats(-1e4, 1e4),
    tx=st.one_of(st.floats(-2.0, 2.0), st.just(float("nan"))),
    ty=st.floats(-0.05, 0.05),
    width=st.integers(-2, 2000),
)
def test_property_stereo_rig_valid_or_named_error(fx, cx, tx, ty, width):
    k = np.array([[fx, 0.0, cx], [0.0, abs(fx) if np.isfinite(fx) else 1.0, 240.0], [0.0, 0.0, 1.0]])
    try:
        rig = StereoRig(k, np.zeros(5), k, np.zeros(5), np.eye(3), [tx, ty, 0.0], (width, 480))
    except CalibrationError as exc:
        assert any(name in str(exc) for name in ("K_left", "K_right", "`T`", "image_size"))
    else:
        assert rig.baseline_m > 0 and rig.K_left[0, 0] > 0 and rig.image_size[0] > 0


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
