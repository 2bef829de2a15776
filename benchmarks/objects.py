"""Detector latency, whole-pipeline frame rate, and object distance error against LiDAR / ground truth.

Everything here depends on the ``detectors`` package and ``stereo_classic.localize`` /
``stereo_classic.Localizer``; where one is missing, the functions return ``{"available": False,
"reason": ...}`` and the report says "not available".

Distance references
-------------------
- KITTI pair: ``stereo_classic.fusion.sparse_depth_reference``: the median of the nearest dense
  cluster of the LiDAR depths projected into the box (shrunk as the fusion shrinks it).
- Motorcycle: the same fusion (``stereo_classic.localize``) applied to the ground-truth disparity.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "detector_latency",
    "pipeline_fps",
    "distance_errors",
    "find_detector_models",
]


def _unavailable(exc: BaseException | str) -> dict[str, Any]:
    reason = exc if isinstance(exc, str) else f"{type(exc).__name__}: {exc}"
    return {"available": False, "reason": reason}


def find_detector_models(models_dir: Path | None) -> list[Path]:
    """The ``*.onnx`` files in ``models_dir`` (sorted), or [] when there is none."""
    if models_dir is None or not Path(models_dir).is_dir():
        return []
    return sorted(Path(models_dir).glob("*.onnx"))


def _median_stats(times: Sequence[float]) -> dict[str, Any]:
    return {"median_ms": statistics.median(times), "min_ms": min(times), "max_ms": max(times), "times_ms": list(times)}


def detector_latency(models: Sequence[Path], image: np.ndarray, *, threads: Sequence[int] = (1, 2), repeat: int = 5) -> dict[str, Any]:
    """Latency of ``OnnxDetector.detect`` per model and thread count, via ``benchmarks.detector_latency.measure_latency``
    (median per stage: preprocess, inference, postprocess, total; thread counts interleaved; warm-up excluded)."""
    from benchmarks.detector_latency import measure_latency

    if not models:
        return _unavailable("no detector model found (give --models DIR or set STEREO_CLASSIC_MODELS)")
    rows: list[dict[str, Any]] = []
    for path in models:
        try:
            for r in measure_latency(str(path), [image], threads=tuple(int(t) for t in threads), repeats=max(3, repeat), warmup=1):
                r = dict(r)
                r["model"] = path.name
                r["input_size"] = list(r["input_size"]) if isinstance(r.get("input_size"), (tuple, list)) else r.get("input_size")
                r["median_ms"] = r.get("total_ms")
                rows.append(r)
        except Exception as exc:  # noqa: BLE001 - a model the detectors package cannot run is reported, not fatal
            rows.append({"model": path.name, "threads": None, "error": f"{type(exc).__name__}: {exc}"})
    how = "benchmarks.detector_latency.measure_latency: OnnxDetector.detect, median per stage, thread counts interleaved, warm-up excluded"
    return {"available": True, "image_size": [int(image.shape[1]), int(image.shape[0])], "rows": rows, "how": how}


def pipeline_fps(scene: Any, model: Path | None, *, num_disparities: int, threads: int = 2, repeat: int = 5,
                 concurrent: bool = False) -> dict[str, Any]:
    """Frames per second of ``stereo_classic.Localizer`` (matcher + detector + fusion) on one scene.

    ``concurrent``: the Localizer's option (the detector in a worker thread while the matcher runs).
    """
    if scene.rig is None:
        return _unavailable(f"scene {scene.name} has no calibration")
    try:
        from stereo_classic import pipeline
        detector: Any = None
        if model is not None:
            detector = pipeline.open_detector(str(model), threads=threads)  # as run opens it
        loc = pipeline.Localizer(scene.rig, detector, {"num_disparities": num_disparities, "threads": threads},
                                 concurrent=concurrent)
        t0 = time.perf_counter()
        first = loc(scene.left, scene.right)
        first_ms = (time.perf_counter() - t0) * 1000.0
    except Exception as exc:  # noqa: BLE001 - reported as not available with its reason
        return _unavailable(exc)
    times: list[float] = []
    stages: dict[str, list[float]] = {}
    for _ in range(repeat):
        t0 = time.perf_counter()
        res = loc(scene.left, scene.right)
        times.append((time.perf_counter() - t0) * 1000.0)
        for k, v in res.timings_ms.items():
            stages.setdefault(k, []).append(float(v))
    stats = _median_stats(times)
    return {
        "available": True,
        "scene": scene.name,
        "size": list(scene.size),
        "num_disparities": num_disparities,
        "threads": threads,
        "model": None if model is None else Path(model).name,
        "first_call_ms": first_ms,
        "objects": len(first.objects.labels) if hasattr(first.objects, "labels") else None,
        "fps": 1000.0 / stats["median_ms"],
        **stats,
        "stages_median_ms": {k: statistics.median(v) for k, v in stages.items()},
    }


def distance_errors(scene: Any, model: Path | None, outputs: Mapping[str, np.ndarray], *, box_shrink: float = 0.2, classes: Sequence[str] = ()) -> dict[str, Any]:
    """Distance of each detected object from each method's disparity, against the scene's reference.

    Reference: LiDAR (``scene.gt_depth``, ``stereo_classic.fusion.sparse_depth_reference``) when present, else the
    fusion applied to ``scene.gt_disparity``. Returns per object the reference and, per method, the
    fused distance, its error in metres and percent, and the fusion status.
    """
    if scene.rig is None:
        return _unavailable(f"scene {scene.name} has no calibration")
    if model is None:
        return _unavailable("no detector model found (give --models DIR or set STEREO_CLASSIC_MODELS)")
    try:
        from stereo_classic.fusion import localize
        from stereo_classic.pipeline import open_detector
        dets = open_detector(str(model)).detect(scene.left)
        if classes:
            dets = dets.only(*classes)
    except Exception as exc:  # noqa: BLE001
        return _unavailable(exc)
    labels = list(getattr(dets, "labels", []))
    boxes = np.asarray(dets.xyxy, dtype=np.float64)
    if scene.gt_depth is not None:
        from stereo_classic.fusion import sparse_depth_reference as reference

        how = "LiDAR: stereo_classic.fusion.sparse_depth_reference (median of the nearest dense cluster of LiDAR depths in the shrunk box)"
        ref_arr = reference(np.nan_to_num(scene.gt_depth, nan=0.0), boxes, box_shrink=box_shrink)
        refs = [float(v) if np.isfinite(v) else None for v in ref_arr]
    elif scene.gt_disparity is not None:
        how = "the same fusion (stereo_classic.localize) applied to the ground-truth disparity"
        try:
            ref_obj = localize(dets, scene.gt_disparity, scene.rig, box_shrink=box_shrink, rng=0)
        except Exception as exc:  # noqa: BLE001
            return _unavailable(exc)
        refs = [float(d) if np.isfinite(d) else None for d in ref_obj.distance_m]
    else:
        return _unavailable(f"scene {scene.name} has neither LiDAR nor ground-truth disparity")
    objects = []
    for i, label in enumerate(labels):
        objects.append({"label": label, "confidence": float(dets.confidence[i]), "xyxy": boxes[i].tolist(), "reference_m": refs[i], "methods": {}})
    for method, disp in outputs.items():
        try:
            loc = localize(dets, disp, scene.rig, box_shrink=box_shrink, rng=0)
        except Exception as exc:  # noqa: BLE001
            for obj in objects:
                obj["methods"][method] = {"error": f"{type(exc).__name__}: {exc}"}
            continue
        for i, obj in enumerate(objects):
            d = float(loc.distance_m[i])
            ref = obj["reference_m"]
            entry: dict[str, Any] = {"distance_m": d if np.isfinite(d) else None, "status": loc.status[i]}
            if ref is not None and np.isfinite(d):
                entry["error_m"] = d - ref
                entry["error_pct"] = 100.0 * abs(d - ref) / ref
            obj["methods"][method] = entry
    return {"available": True, "scene": scene.name, "reference": how, "model": Path(model).name, "objects": objects}


if __name__ == "__main__":  # python -m benchmarks.objects: the per-object error table (benchmarks.object_errors)
    from benchmarks.object_errors import main

    raise SystemExit(main())
