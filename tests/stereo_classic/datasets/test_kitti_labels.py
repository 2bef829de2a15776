"""KITTI 3D labels: the reader (rows, DontCare, named errors) and the LiDAR points inside a labelled box."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stereo_classic.datasets import (
    KittiLabel,
    KittiLabelError,
    box_corners,
    lidar_points_in_labels,
    points_in_box,
    read_kitti_calib_file,
    read_kitti_labels,
    read_velodyne,
    velodyne_to_rect,
)
from stereo_classic.io import FileFormatError

ROWS = (
    "Car 0.81 0 -2.08 812.76 184.44 1241.00 374.00 1.46 1.56 4.11 2.54 1.55 4.31 -1.58\n"
    "\n"
    "Pedestrian 0.00 2 0.30 10.5 20.0 30.0 90.25 1.80 0.60 0.80 -1.00 1.70 12.00 0.10 0.87\n"
    "DontCare -1 -1 -10 579.44 175.79 595.04 188.10 -1 -1 -1 -1000 -1000 -1000 -10\n"
)
GOOD = "Car 0.00 0 -1.44 470.09 178.30 539.83 233.30 1.58 1.65 3.91 -3.28 1.77 22.89 -1.58"


def _write(tmp_path, text: str, name: str = "label.txt"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_reads_rows_in_file_order_with_units_and_line_numbers(tmp_path):
    labels = read_kitti_labels(_write(tmp_path, ROWS))
    assert [lab.type for lab in labels] == ["Car", "Pedestrian", "DontCare"]
    assert [lab.line for lab in labels] == [1, 3, 4]  # the blank line 2 is skipped, numbers stay the file's
    car, ped, dc = labels
    assert car == KittiLabel("Car", 0.81, 0, -2.08, (812.76, 184.44, 1241.0, 374.0), (1.46, 1.56, 4.11),
                             (2.54, 1.55, 4.31), -1.58, None, 1)
    assert isinstance(car.occluded, int) and car.score is None and not car.is_dontcare
    assert ped.score == pytest.approx(0.87) and ped.occluded == 2 and ped.box2d[3] == pytest.approx(90.25)
    assert dc.is_dontcare and dc.truncated == -1.0 and dc.location == (-1000.0, -1000.0, -1000.0)
    with pytest.raises(AttributeError):
        car.type = "Van"  # frozen


def test_dontcare_rows_are_kept_by_default_and_dropped_on_request(tmp_path):
    path = _write(tmp_path, ROWS)
    assert sum(lab.is_dontcare for lab in read_kitti_labels(path)) == 1
    kept = read_kitti_labels(path, dontcare=False)
    assert [lab.type for lab in kept] == ["Car", "Pedestrian"] and [lab.line for lab in kept] == [1, 3]


def test_an_empty_file_is_a_frame_without_objects(tmp_path):
    assert read_kitti_labels(_write(tmp_path, "")) == ()
    assert read_kitti_labels(_write(tmp_path, "\n  \n", "blank.txt")) == ()


@pytest.mark.parametrize("row, line, words", [
    ("Car 0.0 0 0.1 1 2 3 4 1.5 1.6 4.0 0 1.5", 2, ["line 2", "15 values", "got 13"]),
    ("Car 0.0 0 0.1 1 2 3 4 1.5 1.6 4.0 0 1.5 10 0.2 0.9 7", 2, ["line 2", "got 17"]),
    ("Car 0.0 0 0.1 1 2 3 4 1.5 one 4.0 0 1.5 10 0.2", 2, ["line 2", "field `w`", "'one'"]),
    ("Car 0.0 0 0.1 1 2 3 4 1.5 1.6 4.0 0 1.5 nan 0.2", 2, ["line 2", "field `z`", "finite", "'nan'"]),
    ("Car 1.5 0 0.1 1 2 3 4 1.5 1.6 4.0 0 1.5 10 0.2", 2, ["field `truncated`", "0..1", "'1.5'"]),
    ("Car 0.0 4 0.1 1 2 3 4 1.5 1.6 4.0 0 1.5 10 0.2", 2, ["field `occluded`", "'4'"]),
    ("Car 0.0 0 0.1 1 2 3 4 -1.5 1.6 4.0 0 1.5 10 0.2", 2, ["field `h`", "positive", "'-1.5'"]),
    ("Car 0.0 0 0.1 30 2 3 4 1.5 1.6 4.0 0 1.5 10 0.2", 2, ["field `x2`", "at least x1", "'3'"]),
    ("Car 0.0 0 0.1 1 20 3 4 1.5 1.6 4.0 0 1.5 10 0.2", 2, ["field `y2`", "'4'"]),
    ("Car 0.0 0 0.1 1 2 3 4 1.5 1.6 4.0 0 1.5 10 0.2 high", 2, ["field `score`", "'high'"]),
    ("DontCare -1 0.5 -10 1 2 3 4 -1 -1 -1 -1000 -1000 -1000 -10", 2, ["field `occluded`", "integer"]),
])
def test_malformed_rows_name_line_field_and_value(tmp_path, row, line, words):
    path = _write(tmp_path, GOOD + "\n" + row + "\n")
    with pytest.raises(KittiLabelError) as info:
        read_kitti_labels(path)
    assert isinstance(info.value, FileFormatError) and isinstance(info.value, ValueError)
    message = str(info.value)
    assert str(path) in message
    for word in words:
        assert word in message, message


def test_missing_file_folder_and_binary_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="not found"):
        read_kitti_labels(tmp_path / "nope.txt")
    with pytest.raises(FileNotFoundError, match="directory"):
        read_kitti_labels(tmp_path)
    (tmp_path / "bin.txt").write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe")
    with pytest.raises(KittiLabelError, match="not ASCII"):
        read_kitti_labels(tmp_path / "bin.txt")


def _label(yaw: float, location=(1.0, 1.6, 10.0), dims=(1.5, 1.8, 4.2)) -> KittiLabel:
    return KittiLabel("Car", 0.0, 0, 0.0, (0.0, 0.0, 1.0, 1.0), dims, location, yaw)


def test_box_corners_bottom_at_location_top_h_above_and_yaw_turns_length():
    corners = box_corners(_label(0.0))
    assert corners.shape == (8, 3) and corners.dtype == np.float64
    np.testing.assert_allclose(corners[:4, 1], 1.6)
    np.testing.assert_allclose(corners[4:, 1], 1.6 - 1.5)  # y down: the top is h above the bottom
    np.testing.assert_allclose(np.ptp(corners[:, 0]), 4.2)  # yaw 0: the length along camera x
    np.testing.assert_allclose(corners.mean(axis=0), [1.0, 1.6 - 0.75, 10.0])
    turned = box_corners(_label(math.pi / 2))
    np.testing.assert_allclose([np.ptp(turned[:, 0]), np.ptp(turned[:, 2])], [1.8, 4.2], atol=1e-12)
    with pytest.raises(ValueError, match="DontCare"):
        box_corners(KittiLabel("DontCare", -1, -1, -10, (0, 0, 1, 1), (-1, -1, -1), (-1000, -1000, -1000), -10))


@pytest.mark.parametrize("yaw", [0.0, 0.7, -1.58, math.pi])
def test_points_in_a_rotated_box_match_their_position_in_the_box_frame(yaw):
    rng = np.random.default_rng(3)
    label = _label(yaw)
    h, w, length = label.dimensions
    local = rng.uniform([-length, -2 * h, -w], [length, h, w], size=(4000, 3))  # box frame, around the box
    truth = (np.abs(local[:, 0]) < length / 2) & (np.abs(local[:, 2]) < w / 2) & (local[:, 1] < 0) & (local[:, 1] > -h)
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    cam = local @ rot.T + np.asarray(label.location)
    inside = points_in_box(cam, label)
    assert inside.dtype == bool and inside.shape == (4000,)
    np.testing.assert_array_equal(inside, truth)
    assert 0 < truth.sum() < 4000
    assert points_in_box(box_corners(label), label).all()  # faces count as inside


def test_a_point_inside_the_axis_aligned_hull_but_outside_the_turned_box():
    label = _label(math.pi / 4, location=(0.0, 0.0, 0.0), dims=(1.0, 1.0, 4.0))
    # yaw 45 degrees: the box's long axis runs along (1, 0, -1); (1.2, -0.5, 1.2) is 1.7 m off it sideways
    assert points_in_box(np.array([[1.2, -0.5, -1.2], [1.2, -0.5, 1.2]]), label).tolist() == [True, False]


def test_points_in_box_checks_its_input():
    with pytest.raises(ValueError, match=r"`points` must have shape \(N, 3\)"):
        points_in_box(np.zeros((5, 2)), _label(0.0))


def test_velodyne_to_rect_and_points_per_label():
    tr = np.array([[0.0, -1, 0, 0], [0, 0, -1, 0], [1, 0, 0, -0.5]])  # velodyne x forward, y left, z up
    velo = np.array([[10.5, -1.0, -0.8, 0.3], [50.0, 0.0, 0.0, 0.1]], dtype=np.float32)
    rect = velodyne_to_rect(velo, R0_rect=np.eye(3), Tr_velo_to_cam=tr)
    np.testing.assert_allclose(rect, [[1.0, 0.8, 10.0], [0.0, 0.0, 49.5]], atol=1e-6)
    dc = KittiLabel("DontCare", -1, -1, -10, (0, 0, 1, 1), (-1, -1, -1), (-1000, -1000, -1000), -10)
    per_label = lidar_points_in_labels(velo, [_label(0.0), dc], R0_rect=np.eye(3), Tr_velo_to_cam=tr)
    assert per_label[1] is None
    np.testing.assert_allclose(per_label[0], rect[:1], atol=1e-6)
    with pytest.raises(ValueError, match="`Tr_velo_to_cam` must be a finite"):
        velodyne_to_rect(velo, R0_rect=np.eye(3), Tr_velo_to_cam=np.eye(3))
    with pytest.raises(ValueError, match="`points` must have shape"):
        velodyne_to_rect(np.zeros(3), R0_rect=np.eye(3), Tr_velo_to_cam=tr)


def test_shared_kitti_frame_labels_and_lidar_inside_each_car(shared_data):
    folder = shared_data / "kitti_object_pair"
    labels = read_kitti_labels(folder / "label_2.txt")
    assert [lab.type for lab in labels].count("Car") == 7 and sum(lab.is_dontcare for lab in labels) == 2
    assert labels[0].truncated == pytest.approx(0.81)
    calib = read_kitti_calib_file(folder / "calib.txt")
    inside = lidar_points_in_labels(read_velodyne(folder / "lidar.bin"), labels,
                                    R0_rect=calib["R0_rect"].reshape(3, 3),
                                    Tr_velo_to_cam=calib["Tr_velo_to_cam"].reshape(3, 4))
    for lab, pts in zip(labels, inside):
        if lab.is_dontcare:
            assert pts is None
            continue
        assert len(pts) >= 5, lab
        depth = np.median(pts[:, 2])
        # the visible surface: in front of the box centre, behind its nearest corner
        assert box_corners(lab)[:, 2].min() - 0.2 <= depth <= lab.location[2], (lab, depth)
