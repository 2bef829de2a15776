"""benchmarks.kitti_objects: label-detection matching, the DepthAI-style median, and the benchmark on the KITTI frame."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from benchmarks import kitti_objects as ko

RIG = SimpleNamespace(focal_px=500.0, baseline_m=0.1, doffs=0.0, cx_left=20.0, cy=15.0, image_size=(40, 30))


def test_matching_is_one_to_one_and_maximises_total_iou():
    labels = np.array([[0, 0, 10, 10], [2, 0, 12, 10]], dtype=float)
    dets = np.array([[0.5, 0, 10.5, 10], [-2, 0, 8, 10], [30, 30, 40, 40]], dtype=float)
    # greedy by IoU takes label 0 - det 0 (0.905) first, leaving det 1 (0.43) to label 1: 1.33 in all;
    # the best one-to-one assignment is label 0 - det 1 (0.667) and label 1 - det 0 (0.739): 1.41
    got = ko.match_labels(labels, dets, min_iou=0.1)
    assert [g[0] for g in got] == [1, 0]
    assert got[0][1] == pytest.approx(8 / 12, abs=1e-4) and got[1][1] == pytest.approx(8.5 / 11.5, abs=1e-4)


def test_matching_refuses_pairs_below_min_iou_and_handles_empty_inputs():
    labels = np.array([[0, 0, 10, 10], [50, 50, 60, 60]], dtype=float)
    assert ko.match_labels(labels, np.array([[5, 0, 15, 10]], dtype=float)) == [None, None]  # IoU 1/3 < 0.5
    assert ko.match_labels(labels, np.zeros((0, 4))) == [None, None]
    assert ko.match_labels(np.zeros((0, 4)), np.array([[0, 0, 1, 1]], dtype=float)) == []


def test_half_box_median_uses_the_centre_half_of_the_box():
    disp = np.full((30, 40), 5.0, np.float32)  # background: 10 m
    disp[10:20, 15:25] = 20.0                  # the object's centre: 2.5 m
    dist, n = ko.half_box_median(disp, (10, 5, 30, 25), RIG)  # half box: x 15..25, y 10..20
    assert dist == pytest.approx(2.5) and n == 100
    disp[12, 16] = np.nan
    assert ko.half_box_median(disp, (10, 5, 30, 25), RIG) == (pytest.approx(2.5), 99)


def test_half_box_median_at_the_border_and_without_depth():
    disp = np.full((30, 40), 10.0, np.float32)
    dist, n = ko.half_box_median(disp, (-20, -10, 20, 10), RIG)  # half box x -10..10, y -5..5: clipped
    assert dist == pytest.approx(5.0) and n == 10 * 5
    nan = np.full((30, 40), np.nan, np.float32)
    dist, n = ko.half_box_median(nan, (10, 5, 30, 25), RIG)
    assert math.isnan(dist) and n == 0


@pytest.mark.parametrize("methods, word", [(("run", "sgbm"), "sgbm"), ((), "non-empty"), ("run", "non-empty")])
def test_unknown_methods_are_named_before_any_work(methods, word, tmp_path):
    with pytest.raises(ValueError, match="`methods`") as info:
        ko.kitti_object_benchmark(tmp_path, methods=methods)
    assert word in str(info.value)


def test_a_folder_without_labels_is_named(tmp_path):
    with pytest.raises(FileNotFoundError, match="label_2.txt"):
        ko.kitti_object_benchmark(tmp_path)
    assert ko.main(["--data", str(tmp_path)]) == 2


def test_cli_refuses_an_output_in_a_missing_folder(tmp_path, capsys):
    assert ko.main(["--out", str(tmp_path / "no" / "table.md")]) == 2
    assert "--out" in capsys.readouterr().err


@pytest.fixture(scope="module")
def kitti_result(shared_data) -> dict:
    from detectors import ModelNotFoundError

    try:
        return ko.kitti_object_benchmark(shared_data, threads=1)
    except ModelNotFoundError as exc:
        pytest.skip(f"default detector not available: {exc}")


def test_every_labelled_car_has_a_lidar_reference_and_is_matched_or_reported(kitti_result):
    res = kitti_result
    objects = res["objects"]
    assert [o["type"] for o in objects] == ["Car"] * 7
    assert [o["label_index"] for o in objects] == list(range(7))  # the file's rows 0..6; Misc and DontCare after
    for o in objects:
        assert o["lidar_points"] >= 5
        assert 2.0 < o["reference_p10_m"] <= o["reference_m"] < 50.0
        assert o["reference_m"] < o["label_z_m"]  # the visible surface is in front of the box centre
    refs = [o["reference_m"] for o in objects]
    assert refs == sorted(refs)  # the frame's cars are labelled near to far
    matched = [o for o in objects if o["detection"] is not None]
    assert len(matched) >= 3 and all(o["detection"]["iou"] >= 0.5 for o in matched)
    assert len({o["detection"]["index"] for o in matched}) == len(matched)
    for o in objects:
        if o["detection"] is None:
            assert o["methods"] == {}
            continue
        assert set(o["methods"]) == set(ko.DEFAULT_METHODS)
        for entry in o["methods"].values():
            assert isinstance(entry["status"], str)
            if entry["distance_m"] is not None:
                assert 1.0 < entry["distance_m"] < 80.0
                assert entry["error_pct"] == pytest.approx(100 * (entry["distance_m"] / o["reference_m"] - 1))


def test_the_reference_is_what_the_camera_sees_of_the_box(kitti_result):
    """The near car is 81 % truncated by the image's right border: of the 4145 LiDAR points in its box only those
    that project into the left image are its visible surface (before, the points past the border made its
    reference 2.72 m, nearer than anything the camera sees of it); the cars in full view keep every point."""
    objects = kitti_result["objects"]
    for o in objects:
        if o["truncated"] == 0:
            assert o["lidar_points"] == o["lidar_points_in_box"]
    near = objects[0]
    assert near["truncated"] > 0.5 and 0 < near["lidar_points"] < 0.5 * near["lidar_points_in_box"]
    assert near["reference_m"] == pytest.approx(3.52, abs=0.01) and near["reference_p10_m"] == pytest.approx(2.66, abs=0.01)


def test_in_view_keeps_the_points_that_project_into_the_image():
    p2 = np.array([[700.0, 0, 600, 45.0], [0, 700.0, 180, 0], [0, 0, 1, 0.005]])
    pts = np.array([[0.0, 0, 5], [5.0, 0, 5], [-5.0, 0, 5], [0, 3.0, 5], [0.0, 0, -5], [0.8, 0.2, 3]])
    kept = ko.in_view(pts, p2, 1242, 375)
    np.testing.assert_array_equal(kept, pts[[0, 5]])
    assert ko.in_view(np.zeros((0, 3)), p2, 1242, 375).shape == (0, 3)


def test_fusion_nearest_surface_and_the_bar(kitti_result):
    res = kitti_result
    assert res["nearest"]["available"], res["nearest"]["reason"]  # the fusion reports its nearest surface
    for o in res["objects"]:
        for name in ("run", "ocv-3way"):
            entry = o["methods"].get(name)
            if entry is not None and entry["status"] == "ok":
                assert entry["nearest_m"] is not None and entry["nearest_m"] <= entry["distance_m"] + 1e-9
    for name, bar in res["bar"].items():
        checked = [o for o in res["objects"] if o["label_index"] in bar["checked"]]
        assert checked and all(o["truncated"] <= ko.MAX_TRUNCATION and o["detection"] for o in checked)
        outside = [o["label_index"] for o in checked if abs(o["methods"][name]["error_pct"] or math.inf) > ko.BAR_PCT]
        assert bar["failing"] == outside and bar["holds"] == (not outside)
    assert 0 not in res["bar"]["run"]["checked"]  # the near car is truncated (0.81)
    assert res["matcher"]["num_disparities"] == 128 and res["model"] == "yolox_nano.onnx"


def test_markdown_has_a_row_per_label_and_a_verdict_per_method(kitti_result, tmp_path):
    text = ko.render_markdown(kitti_result)
    rows = [line for line in text.splitlines() if line.startswith("| ") and not line.startswith("| label")]
    assert len(rows) == 7 and rows[0].startswith("| 0 | 0.81 |")
    assert sum("not detected" in r for r in rows) == sum(o["detection"] is None for o in kitti_result["objects"])
    for title in ("`run`", "3WAY + fusion", "DepthAI median"):
        assert f"- {title}: every detected car" in text
    assert "not available" in ko.render_markdown({"available": False, "reason": "no data"})
