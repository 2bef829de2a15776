"""ROS image and CameraInfo messages to arrays and rigs (no ROS needed: plain attribute objects)."""

from __future__ import annotations

from types import SimpleNamespace as Msg

import cv2
import numpy as np
import pytest

import calib
from stereo_classic.ros.images import ENCODINGS, ImageMessageError, image_from_msg, rig_from_camera_info

RNG = np.random.default_rng(0)
BGR = RNG.integers(0, 256, (6, 8, 3), dtype=np.uint8)


def _image(array: np.ndarray, encoding: str, pad: int = 0) -> Msg:
    rows = array.reshape(array.shape[0], -1)
    rows = np.hstack([rows, np.zeros((rows.shape[0], pad), np.uint8)])
    return Msg(encoding=encoding, height=array.shape[0], width=array.shape[1], step=rows.shape[1], is_bigendian=0,
               data=rows.tobytes())


@pytest.mark.parametrize("encoding, make, expected", [
    ("bgr8", lambda: BGR, lambda: BGR),
    ("rgb8", lambda: BGR[..., ::-1], lambda: BGR),
    ("bgra8", lambda: cv2.cvtColor(BGR, cv2.COLOR_BGR2BGRA), lambda: BGR),
    ("mono8", lambda: BGR[..., 0], lambda: BGR[..., 0]),
])
def test_encodings_and_row_padding(encoding, make, expected):
    for pad in (0, 3):  # a step wider than the row
        assert np.array_equal(image_from_msg(_image(np.ascontiguousarray(make()), encoding, pad), "t"), expected())


def test_bayer_follows_cv_bridge():
    raw = RNG.integers(0, 256, (6, 8), dtype=np.uint8)
    out = image_from_msg(_image(raw, "bayer_rggb8"), "t")
    assert out.shape == (6, 8, 3) and np.array_equal(out, cv2.cvtColor(raw, cv2.COLOR_BayerBG2BGR))
    assert all(ENCODINGS[k][0] == 1 for k in ENCODINGS if k.startswith("bayer"))


def test_compressed():
    ok, png = cv2.imencode(".png", BGR)
    assert np.array_equal(image_from_msg(Msg(format="png", data=png.tobytes()), "t"), BGR)
    with pytest.raises(ImageMessageError, match="cannot be decoded"):
        image_from_msg(Msg(format="jpeg", data=b"not an image"), "/cam")


@pytest.mark.parametrize("change, expected", [
    (dict(encoding="16UC1"), "image encoding '16UC1' cannot be converted; expected one of mono8"),
    (dict(step=4), "step must be >= width x 3"),
    (dict(data=bytes(10)), "image data holds 10 bytes"),
])
def test_bad_images_say_what(change, expected):
    msg = _image(BGR, "bgr8")
    with pytest.raises(ImageMessageError, match=expected.replace("(", r"\\(")):
        image_from_msg(Msg(**{**vars(msg), **change}), "/left")


def _info(P, size=(640, 480), R=np.eye(3), D=(0.0,) * 5):
    return Msg(width=size[0], height=size[1], k=list(np.asarray(P)[:, :3].ravel()), d=list(D), r=list(R.ravel()),
               p=list(np.asarray(P).ravel()), distortion_model="plumb_bob")


def test_rectified_rig_from_p_matrices():
    rig = calib.RectifiedRig(focal_px=700.0, cx_left=320.0, cx_right=330.0, cy=240.0, baseline_m=0.12,
                             image_size=(640, 480))
    got = rig_from_camera_info(_info(rig.P_left), _info(rig.P_right), rectify=False)
    assert got == rig
    with pytest.raises(ImageMessageError, match="P\\[0,3\\] is 0"):  # the left info twice
        rig_from_camera_info(_info(rig.P_left), _info(rig.P_left), rectify=False)
    with pytest.raises(ImageMessageError, match="different image sizes"):
        rig_from_camera_info(_info(rig.P_left), _info(rig.P_right, (320, 240)), rectify=False)


def test_raw_rig_rectifies_to_the_same_baseline():
    P_l = np.array([[700.0, 0, 320, 0], [0, 700, 240, 0], [0, 0, 1, 0]])
    P_r = P_l.copy()
    P_r[0, 3] = -700.0 * 0.1
    raw = rig_from_camera_info(_info(P_l, D=(0.01, 0, 0, 0, 0)), _info(P_r, D=(0.01, 0, 0, 0, 0)), rectify=True)
    assert isinstance(raw, calib.StereoRig) and raw.baseline_m == pytest.approx(0.1)
