"""calib.load.load_rig and every reader's common error paths: missing, empty, binary, random bytes (hypothesis)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib import CalibrationError, RectifiedRig, StereoRig, load_rig


# --------------------------------------------------------------------------- every reader's error paths
READERS = {
    "middlebury": (RectifiedRig.from_middlebury, "calib.txt"),
    "kitti": (RectifiedRig.from_kitti, "calib.txt"),
    "kitti_raw": (StereoRig.from_kitti, "calib_cam_to_cam.txt"),
    "oakd": (RectifiedRig.from_oakd_json, "calib.json"),
    "opencv": (StereoRig.from_opencv_yaml, "rig.yaml"),
    "opencv_rect": (RectifiedRig.from_opencv_yaml, "rig.yaml"),
    "ros": (lambda p: StereoRig.from_ros(p, p), "left.yaml"),
    "load_rig": (load_rig, "rig.yaml"),
}


@pytest.mark.parametrize("reader", READERS)
def test_missing_file(tmp_path, reader):
    func, name = READERS[reader]
    with pytest.raises(FileNotFoundError, match=name):
        func(tmp_path / name)


@pytest.mark.parametrize("reader", READERS)
@pytest.mark.parametrize("content", ["", "   \n\n"])
def test_empty_file(tmp_path, reader, content):
    func, name = READERS[reader]
    (tmp_path / name).write_text(content)
    with pytest.raises(CalibrationError, match=rf"{name}.* empty"):
        func(tmp_path / name)


@pytest.mark.parametrize("reader", READERS)
def test_binary_garbage(tmp_path, reader):
    func, name = READERS[reader]
    (tmp_path / name).write_bytes(bytes(range(256)) * 4)
    with pytest.raises(CalibrationError, match=name):
        func(tmp_path / name)


def test_directory_instead_of_file(tmp_path):
    with pytest.raises(CalibrationError, match="not a regular file"):
        load_rig(tmp_path)


# --------------------------------------------------------------------------- hostile files (hypothesis)
@settings(max_examples=180, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(max_size=300), which=st.sampled_from(sorted(READERS)))
def test_property_random_bytes_give_a_clear_error(tmp_path, data, which):
    func, name = READERS[which]
    path = tmp_path / name
    path.write_bytes(data)
    try:
        rig = func(path)
    except CalibrationError as exc:
        assert str(tmp_path) in str(exc) or name in str(exc)
    else:  # random bytes that parse must still give a well-formed rig
        assert isinstance(rig, (StereoRig, RectifiedRig))
        if isinstance(rig, RectifiedRig):
            assert rig.focal_px > 0 and rig.baseline_m > 0
            assert np.isfinite([rig.focal_px, rig.cx_left, rig.cx_right, rig.cy, rig.baseline_m]).all()
        else:
            assert all(np.isfinite(m).all() for m in (rig.K_left, rig.K_right, rig.R, rig.T, rig.dist_left, rig.dist_right))
        assert len(rig.image_size) == 2 and min(rig.image_size) > 0


# --------------------------------------------------------------------------- the format recognised by content
@pytest.mark.parametrize(
    "relpath, kind",
    [
        ("middlebury2014/trainingQ/Motorcycle/calib.txt", RectifiedRig),
        ("kitti_object_pair/calib.txt", RectifiedRig),
        ("oakd/stereodemo_calibration.json", RectifiedRig),
    ],
)
def test_load_rig_on_the_real_files(shared_data, relpath, kind):
    rig = load_rig(shared_data / relpath)
    assert type(rig) is kind
    assert load_rig(str(shared_data / relpath)) == rig  # str or Path


def test_load_rig_passes_image_size(tmp_path, shared_data):
    path = shared_data / "kitti_object_pair/calib.txt"
    assert load_rig(path, image_size=(1240, 376)).image_size == (1240, 376)
    assert load_rig(path, image_size=(1240, 376)) == RectifiedRig.from_kitti(path, image_size=(1240, 376))
    with pytest.raises(CalibrationError, match="image_size"):
        load_rig(path, image_size=(0, 376))


def test_load_rig_on_opencv_files(tmp_path, stereo_rig):
    raw, rect = tmp_path / "raw.yaml", tmp_path / "rect.xml"
    stereo_rig.to_opencv_yaml(raw)
    stereo_rig.rectify().to_opencv_yaml(rect)
    assert type(load_rig(raw)) is StereoRig and load_rig(raw) == stereo_rig
    assert type(load_rig(rect)) is RectifiedRig and load_rig(rect) == stereo_rig.rectify().without_maps()
