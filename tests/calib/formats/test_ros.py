"""calib.formats.ros: a left/right pair of ROS camera_info files gives back the rig; error paths; plain values."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from calib import CalibrationError, StereoRig, load_rig
from calib.formats import ros


# --------------------------------------------------------------------------- ROS camera_info
def _ros_text(name, k, d, r, p, width=640, height=480, header=""):
    def block(key, rows, cols, values):
        data = ", ".join(repr(float(v)) for v in np.ravel(values))
        return f"{key}:\n  rows: {rows}\n  cols: {cols}\n  data: [{data}]\n"

    return (header + f"image_width: {width}\nimage_height: {height}\ncamera_name: {name}\n" + block("camera_matrix", 3, 3, k)
            + "distortion_model: plumb_bob\n" + block("distortion_coefficients", 1, len(d), d)
            + block("rectification_matrix", 3, 3, r) + block("projection_matrix", 3, 4, p))


def _ros_pair(tmp_path, rig, header=""):
    rect = rig.rectification(alpha=0.0)
    left, right = tmp_path / "left.yaml", tmp_path / "right.yaml"
    left.write_text(_ros_text("left", rig.K_left, rig.dist_left, rect["R1"], rect["P1"], header=header))
    right.write_text(_ros_text("right", rig.K_right, rig.dist_right, rect["R2"], rect["P2"], header=header))
    return left, right


@pytest.mark.parametrize("header", ["", "%YAML:1.0\n---\n"])
def test_ros_pair_recovers_the_rig(tmp_path, header, stereo_rig):
    left, right = _ros_pair(tmp_path, stereo_rig, header=header)
    rig = StereoRig.from_ros(left, right)
    assert rig.isclose(stereo_rig, rtol=1e-9, atol=1e-12)
    with pytest.raises(CalibrationError, match="one camera"):
        load_rig(left)


def test_ros_errors(tmp_path, stereo_rig):
    left, right = _ros_pair(tmp_path, stereo_rig)
    with pytest.raises(CalibrationError, match="no baseline"):
        StereoRig.from_ros(left, left)
    bad = tmp_path / "fisheye.yaml"
    bad.write_text(left.read_text().replace("plumb_bob", "equidistant"))
    with pytest.raises(CalibrationError, match="distortion_model"):
        StereoRig.from_ros(bad, right)
    small = tmp_path / "small.yaml"
    small.write_text(left.read_text().replace("image_width: 640", "image_width: 320"))
    with pytest.raises(CalibrationError, match="different image sizes"):
        StereoRig.from_ros(small, right)
    with pytest.raises(FileNotFoundError, match="nothere"):
        StereoRig.from_ros(tmp_path / "nothere.yaml", right)


def test_readers_return_plain_values(tmp_path, stereo_rig):
    left, right = _ros_pair(tmp_path, stereo_rig)
    info = ros.read_ros_camera_info(left)
    assert info["camera_name"] == "left" and info["distortion_model"] == "plumb_bob"
    assert info["image_size"] == (640, 480) and info["path"] == Path(left)
    assert info["K"].shape == (3, 3) and info["D"].shape == (5,) and info["P"].shape == (3, 4)
    values = ros.read_stereo_pair(left, right)
    assert set(values) == {"K_left", "dist_left", "K_right", "dist_right", "R", "T", "image_size"}
    assert all(type(values[k]) is np.ndarray for k in ("K_left", "dist_left", "K_right", "dist_right", "R", "T"))
    assert StereoRig(**values) == StereoRig.from_ros(left, right)


def test_rig_errors_name_both_files(tmp_path, stereo_rig):
    left, right = _ros_pair(tmp_path, stereo_rig)
    # a focal length outside the plausible range passes the reader and is refused by StereoRig
    bad = tmp_path / "huge.yaml"
    text = left.read_text()
    fx = f"{float(stereo_rig.K_left[0, 0])!r}"
    bad.write_text(text.replace(f"data: [{fx},", "data: [1e+300,", 1))
    with pytest.raises(CalibrationError, match="plausible range") as info:
        StereoRig.from_ros(bad, right)
    assert f"{bad} + {right}: `K_left`" in str(info.value)
