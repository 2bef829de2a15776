"""benchmarks.objects: detector latency, pipeline fps and distance errors on the real scenes."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks import objects
from benchmarks.scenes import BenchScene, load_scenes


@pytest.fixture(scope="module")
def motorcycle(shared_data) -> BenchScene:
    scenes = load_scenes(shared_data, ["motorcycle"])
    assert len(scenes) == 1 and scenes[0].rig is not None
    return scenes[0]


@pytest.fixture(scope="module")
def kitti(shared_data) -> BenchScene:
    scenes = load_scenes(shared_data, ["kitti"])
    assert len(scenes) == 1 and scenes[0].gt_depth is not None
    return scenes[0]


def test_distance_of_ground_truth_is_exact_and_noise_is_measured(motorcycle, yolox_nano):
    gt = motorcycle.gt_disparity
    shifted = gt + np.float32(2.0)   # a disparity 2 px too large: the object looks nearer
    res = objects.distance_errors(motorcycle, yolox_nano, {"gt": gt, "gt+2": shifted, "nothing": np.full_like(gt, np.nan)})
    assert res["available"] and res["reference"].startswith("the same fusion")
    moto = [o for o in res["objects"] if o["label"] == "motorcycle"]
    assert len(moto) == 1 and moto[0]["confidence"] >= 0.8
    obj = moto[0]
    assert 2.0 < obj["reference_m"] < 2.6
    assert obj["methods"]["gt"]["error_pct"] == pytest.approx(0.0, abs=1e-9)
    assert obj["methods"]["gt+2"]["error_m"] < 0 and 2.0 < obj["methods"]["gt+2"]["error_pct"] < 6.0
    assert obj["methods"]["nothing"]["distance_m"] is None and obj["methods"]["nothing"]["status"] != "ok"


def test_kitti_reference_is_lidar(kitti, yolox_nano):
    depth = kitti.gt_depth
    # the LiDAR depth turned into disparity is, by construction, close to the LiDAR reference
    disp = np.where(np.isfinite(depth), kitti.rig.focal_px * kitti.rig.baseline_m / np.where(np.isfinite(depth), depth, 1.0) - kitti.rig.doffs, np.nan)
    res = objects.distance_errors(kitti, yolox_nano, {"lidar": disp.astype(np.float32)})
    assert res["available"] and "LiDAR" in res["reference"]
    cars = [o for o in res["objects"] if o["label"] == "car"]
    assert len(cars) >= 3
    assert all(o["reference_m"] is not None and 2.0 < o["reference_m"] < 40.0 for o in cars)


def test_unavailable_is_a_value_not_an_exception(motorcycle):
    no_rig = BenchScene("x", motorcycle.left, motorcycle.right, gt_disparity=motorcycle.gt_disparity)
    assert objects.distance_errors(no_rig, None, {})["available"] is False
    assert objects.distance_errors(motorcycle, None, {})["available"] is False
    assert objects.pipeline_fps(no_rig, None, num_disparities=64)["available"] is False
    assert objects.detector_latency([], motorcycle.left)["available"] is False
    assert objects.find_detector_models(None) == []


def test_detector_latency_rows(motorcycle, yolox_nano):
    res = objects.detector_latency([yolox_nano], motorcycle.left[:200, :300], threads=(1,), repeat=1)
    assert res["available"]
    (row,) = res["rows"]
    assert row["model"] == "yolox_nano.onnx" and row["threads"] == 1
    assert row["total_ms"] > 0 and row["median_ms"] == row["total_ms"]


def test_pipeline_fps_on_motorcycle(motorcycle, yolox_nano):
    res = objects.pipeline_fps(motorcycle, yolox_nano, num_disparities=64, threads=1, repeat=1)
    assert res["available"], res.get("reason")
    assert res["fps"] > 0 and res["objects"] >= 1
    assert res["fps"] == pytest.approx(1000.0 / res["median_ms"])
    assert "total" in res["stages_median_ms"] or res["stages_median_ms"]
