"""A small fake benchmark report (the dict of ``benchmarks.run.run_benchmark``) for the renderers' tests."""

from __future__ import annotations

from typing import Any

import numpy as np

from benchmarks.metrics import scene_metrics
from benchmarks.run import family_means

#: (scene name, family, source) of the fake report.
FAKE_SCENES: tuple[tuple[str, str, str], ...] = (
    ("teddy", "Middlebury-style", "/data/middlebury2003/teddy"),
    ("2018-07-09-16-11-56_2018-07-09-16-11-57-101", "driving", "/data/drivingstereo"),
    ("2018-07-09-16-11-56_2018-07-09-16-11-58-603", "driving", "/data/drivingstereo"),
)
METHODS = ("sc-default", "ocv-3way")


def fake_accuracy(seed: int = 0) -> dict[str, dict[str, Any]]:
    """Per scene: sc-default filled (dense) with a measured subset, ocv-3way with holes; real metrics of both."""
    rng = np.random.default_rng(seed)
    out: dict[str, dict[str, Any]] = {}
    for k, (name, _, _) in enumerate(FAKE_SCENES):
        gt = rng.uniform(5, 40, (12, 20)).astype(np.float32)
        ours = gt + rng.normal(0, 1.0 + k, gt.shape).astype(np.float32)
        measured = ours.copy()
        measured[:, :4] = np.nan
        theirs = gt + rng.normal(0, 1.5, gt.shape).astype(np.float32)
        theirs[:, :6] = np.nan
        ours_m = scene_metrics(ours, gt, max_disparity=4)
        for region, views in scene_metrics(measured, gt, max_disparity=4).items():
            ours_m[region]["valid"] = views["valid"]
        out[name] = {"sc-default": ours_m, "ocv-3way": scene_metrics(theirs, gt, max_disparity=4)}
    return out


def fake_report() -> dict[str, Any]:
    """A report with two families, thread scaling, pipeline rows and no KITTI objects."""
    acc = fake_accuracy()
    scenes = [{"name": n, "family": f, "size": [20, 12], "num_disparities": 16, "has_gt": True, "has_nonocc": False,
               "has_lidar": False, "has_rig": False, "source": src} for n, f, src in FAKE_SCENES]
    speed = [{"input": "kitti_object_pair", "kind": "scene", "note": "", "width": 1242, "height": 375, "num_disparities": 128,
              "threads": 2, "method": m, "median_ms": ms, "min_ms": ms, "max_ms": ms, "mde_per_s": 1.0, "first_call_ms": ms,
              "times_ms": [ms]} for m, ms in (("sc-default", 40.0), ("ocv-3way", 50.0))]
    rows = []
    for m, base in (("sc-default", 80.0), ("ocv-3way", 90.0)):
        for t in (1, 2, 4, 8):
            ms = base / min(t, 2)
            fastest = 0.9 * base / min(t, 2) ** 0.5 if t > 1 else 0.9 * base  # speed-up by the fastest calls: 1.41
            rows.append({"method": m, "threads": t, "median_ms": ms, "min_ms": fastest, "max_ms": ms, "first_call_ms": ms,
                         "cpu_s_per_call": base / 1000, "times_ms": [ms], "speedup": base / ms,
                         "speedup_best": 0.9 * base / fastest,
                         "efficiency": base / ms / min(t, 2), "cpu_ratio": 1.0, "identical": m == "sc-default" or t == 1})
    scaling = {"available": True, "input": "kitti_object_pair", "width": 1242, "height": 375, "num_disparities": 128,
               "block_size": 5, "cores": 2, "threads": [1, 2, 4, 8], "repeat": 1, "methods": list(METHODS),
               "rows": rows, "how": "fake", "note": "fake"}
    pipeline = [{"available": True, "scene": s, "size": list(size), "num_disparities": d, "threads": 2,
                 "model": "yolox_nano.onnx", "first_call_ms": 100.0, "objects": 3, "fps": fps, "median_ms": 1000 / fps,
                 "min_ms": 1000 / fps, "max_ms": 1000 / fps, "times_ms": [1000 / fps],
                 "stages_median_ms": {"disparity": 30.0, "detect": 10.0}, "input": s, "concurrent": conc}
                for s, size, d, fps, conc in (("kitti_object_pair", (1242, 375), 128, 15.0, False),
                                              ("kitti_object_pair", (1242, 375), 128, 17.5, True),
                                              ("selfie", (640, 480), 64, 30.0, False))]
    return {
        "schema": "stereo_classic.benchmarks/2",
        "command": ["python", "-m", "benchmarks", "--fake"],
        "machine": {"date_utc": "2026-01-01 00:00:00", "cpu_model": "Fake CPU", "logical_cpus": 2, "usable_cpus": 2,
                    "memory_gib": 1.0, "os": "fake", "python": "3", "versions": {"cv2": "5", "numba": "0"},
                    "opencv_threads_default": 2, "git_commit": "abc"},
        "config": {"data_dir": None, "repeat": 1, "threads": [2], "block_size": 5, "sizes": [], "quick": True,
                   "min_disparity": 0, "disparity_range": "fake", "accuracy_threads": 2},
        "notes": [],
        "methods": [{"name": m, "family": "x", "description": m, "available": True, "reason": None, "params": {}}
                    for m in METHODS],
        "scenes": scenes,
        "accuracy": acc,
        "accuracy_mean": family_means(acc, {n: f for n, f, _ in FAKE_SCENES}, METHODS),
        "errors": {},
        "scaling": scaling,
        "speed": speed,
        "memory": [],
        "pipeline": pipeline,
        "kitti_objects": {"available": False, "reason": "fake: no KITTI labels"},
    }
