"""calib.formats.sniff: the format of a calibration file, recognised by its content, not its name."""

from __future__ import annotations

import pytest

from calib import CalibrationError
from calib.formats import sniff_format


@pytest.mark.parametrize(
    "relpath, kind",
    [
        ("middlebury2014/trainingQ/Motorcycle/calib.txt", "middlebury"),
        ("kitti_object_pair/calib.txt", "kitti"),
        ("oakd/stereodemo_calibration.json", "oakd"),
    ],
)
def test_real_files(shared_data, relpath, kind):
    assert sniff_format(shared_data / relpath) == kind


@pytest.mark.parametrize(
    "text, kind",
    [
        ('{"fx": 500}', "oakd"),
        ("cam0=[1 0 0; 0 1 0; 0 0 1]\n", "middlebury"),
        ("P0: 1 0 0\nP2: 7.2e+02 0 6.0e+02\n", "kitti"),
        ("calib_time: today\nP_rect_02: 7.2e+02 0\n", "kitti"),
        ("%YAML:1.0\n---\nM1: [1, 2]\n", "opencv_stereo"),
        ("%YAML:1.0\n---\nK1: [1, 2]\nP1: [1]\nP2: [1]\n", "opencv_stereo"),
        ("%YAML:1.0\n---\nP1: [1]\nP2: [1]\n", "opencv_rectified"),
        ("<?xml version=\"1.0\"?>\n<opencv_storage>\n<Q>1.</Q>\n</opencv_storage>\n", "opencv_rectified"),
        ("%YAML:1.0\n---\nP2: [1]\n", None),  # a YAML file is never KITTI
    ],
)
def test_content_decides(tmp_path, text, kind):
    path = tmp_path / "calibration.file"
    path.write_text(text)
    if kind is None:
        with pytest.raises(CalibrationError, match="unrecognised calibration file.*keys found: P2"):
            sniff_format(path)
    else:
        assert sniff_format(path) == kind


def test_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="calibration file not found"):
        sniff_format(tmp_path / "none.yaml")
    path = tmp_path / "left.yaml"
    path.write_text("image_width: 640\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n")
    with pytest.raises(CalibrationError, match="one camera"):
        sniff_format(path)
