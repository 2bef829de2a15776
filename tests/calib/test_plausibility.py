"""Implausible calibrations are refused with a named error (issue #15 item 5): a focal length of 0.001 px, a
principal point far outside the image, a text file that is no calibration; each message names the file once."""

from __future__ import annotations

import json

import numpy as np
import pytest

from calib import CalibrationError, RectifiedRig, StereoRig, load_rig

OAKD = {"width": 640, "height": 480, "baseline_meters": 0.075, "fx": 451.03, "fy": 451.03,
        "cx0": 299.04, "cx1": 299.04, "cy": 255.17}
K = [[700.0, 0, 320], [0, 700.0, 240], [0, 0, 1]]


def _write_json(tmp_path, **changes):
    path = tmp_path / "calib.json"
    path.write_text(json.dumps({**OAKD, **changes}))
    return path


@pytest.mark.parametrize(("changes", "words"), [
    ({"fx": 0.001}, ["`focal_px` = 0.001 px", "640x480", "field of view"]),
    ({"fx": 5.0}, ["`focal_px` = 5 px"]),
    ({"cx0": 5000.0}, ["`cx_left` = 5000 px", "[-320, 960]", "640x480"]),
    ({"cy": 2000.0}, ["`cy` = 2000 px", "[-240, 720]"]),
])
def test_implausible_oakd_json_is_refused_naming_the_value(tmp_path, changes, words):
    path = _write_json(tmp_path, **changes)
    with pytest.raises(CalibrationError) as info:
        load_rig(path)
    msg = str(info.value)
    for word in words:
        assert word in msg
    assert msg.count(str(path)) == 1  # the file once, not twice


def test_plausible_values_still_load(tmp_path):
    rig = load_rig(_write_json(tmp_path, fx=20.0, cx0=-300.0, cx1=950.0))  # 172 degrees, cx half an image out
    assert rig.focal_px == 20.0 and rig.cx_left == -300.0


@pytest.mark.parametrize(("kwargs", "name"), [
    ({"focal_px": 0.001}, "focal_px"),
    ({"cx_left": 5000.0}, "cx_left"),
    ({"cy": -1000.0}, "cy"),
])
def test_rectified_rig_checks_intrinsics_against_the_image_size(kwargs, name):
    values = {"focal_px": 450.0, "cx_left": 320.0, "cx_right": 320.0, "cy": 240.0, "baseline_m": 0.1,
              "image_size": (640, 480), **kwargs}
    with pytest.raises(CalibrationError, match=f"`{name}`"):
        RectifiedRig(**values)


def test_scaled_rig_stays_plausible():
    rig = RectifiedRig(focal_px=450.0, cx_left=320.0, cx_right=320.0, cy=240.0, baseline_m=0.1, image_size=(640, 480))
    small = rig.scaled(1 / 64)
    assert small.image_size == (10, 8)


@pytest.mark.parametrize(("which", "value", "name"), [
    ((0, 0), 0.001, "K_left focal length"),
    ((0, 2), 5000.0, "K_left[0,2] (cx)"),
    ((1, 2), -900.0, "K_left[1,2] (cy)"),
])
def test_stereo_rig_checks_intrinsics_against_the_image_size(which, value, name):
    k_left = np.array(K)
    k_left[which] = value
    with pytest.raises(CalibrationError, match=name.replace("[", r"\[").replace("(", r"\(").replace(")", r"\)")):
        StereoRig(k_left, np.zeros(5), K, np.zeros(5), np.eye(3), [-0.1, 0, 0], (640, 480))


@pytest.mark.parametrize("text", [
    "hello world\nthis is a text file\n",
    "Calibration notes: measured on Monday\n",
    "1 2 3\n4 5 6\n",
])
def test_a_text_file_as_calibration_gives_a_named_error_without_opencv_noise(tmp_path, text):
    path = tmp_path / "notes.txt"
    path.write_text(text)
    with pytest.raises(CalibrationError) as info:
        load_rig(path)
    msg = str(info.value)
    assert "not a calibration file" in msg or "unrecognised calibration file" in msg or "not a readable" in msg
    assert "returned a result with an exception set" not in msg and "cv2" not in msg
    assert msg.count(str(path)) == 1


@pytest.mark.parametrize(("name", "text"), [
    ("calib.txt", ("cam0=[0.001 0 320; 0 700 240; 0 0 1]\ncam1=[700 0 330; 0 700 240; 0 0 1]\n"
                   "doffs=10\nbaseline=100\nwidth=640\nheight=480\n")),
    ("kitti.txt", "P2: 7 0 600 0 0 7 180 0 0 0 1 0\nP3: 7 0 600 -3 0 7 180 0 0 0 1 0\n"),
    ("bad.yaml", "%YAML:1.0\nP1: [1, 2]\nP2: [1, 2]\nimage_width: 640\nimage_height: 480\n"),
])
def test_every_format_names_the_file_once(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(CalibrationError) as info:
        load_rig(path)
    assert str(info.value).count(str(path)) == 1
