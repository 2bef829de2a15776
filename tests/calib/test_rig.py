"""calib.rig.StereoRig: checks when built, rectification (and the rectify_pair of the rig it makes)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib import CalibrationError, RectifiedRig, StereoRig

K = np.array([[700.0, 0.0, 320.0], [0.0, 702.0, 240.0], [0.0, 0.0, 1.0]])
D = np.array([-0.1, 0.02, 0.001, -0.001, 0.0])
R_SMALL = cv2.Rodrigues(np.array([0.004, -0.01, 0.002]))[0]


def make_rig(**overrides):
    args = dict(K_left=K, dist_left=D, K_right=K, dist_right=D, R=R_SMALL, T=[-0.12, 0.001, 0.0], image_size=(640, 480))
    args.update(overrides)
    return StereoRig(**args)


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

