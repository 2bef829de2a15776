"""Per-object distance errors against ground truth, and whether each object's reported uncertainty covers its error.

``python -m benchmarks.objects`` (or ``python -m benchmarks.object_errors``) runs the fusion on every frame with
per-object ground truth and reports, per set and over all of them: the median and 90th percentile of the absolute
error in percent, the share within 5 %, the share of objects whose error is within three times their reported
``distance_sigma_m`` ("covered"), and the objects reported ok whose error exceeds that (the issue-31 bar: none).
Both fusions side by side: ``before`` (``ground_contact=False``: the consistent set alone, as before issue 31)
and ``after`` (``FusionParams()`` defaults). An object without a distance (another status) is counted apart, never
as a small error.

Sets:

* **rendered**: :func:`benchmarks.road_scenes.road_scenes` (cars 25-60 m, persons 10-30 m at the DrivingStereo
  rig), boxes = the object's pixels grown by 10 %, reference = median depth of the object's pixels.
* **drivingstereo**: the shared DrivingStereo frames, the default detector's boxes (every class), reference =
  ``stereo_classic.fusion.sparse_depth_reference`` on the LiDAR depth (the nearest dense cluster in the shrunk box).
* **kitti**: the KITTI frame's labelled cars matched to detections (``benchmarks.kitti_objects``: the LiDAR points
  of each labelled 3D box that the left camera sees, median depth).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["object_rows", "summarise", "render_markdown", "main"]

FUSIONS = {"before": {"ground_contact": False}, "after": {}}
WITHIN_PCT = 5.0
COVER_SIGMAS = 3.0


def _row(set_name: str, frame: str, label: str, ref: float | None, objs: Any, i: int) -> dict[str, Any]:
    d, sigma, status = float(objs.distance_m[i]), float(objs.distance_sigma_m[i]), str(objs.status[i])
    ok = status == "ok" and np.isfinite(d)
    err = 100.0 * (d - ref) / ref if ok and ref else None
    return {"set": set_name, "frame": frame, "label": label, "reference_m": ref, "distance_m": d if ok else None,
            "sigma_m": sigma if ok else None, "status": status, "error_pct": err,
            "covered": None if err is None else bool(abs(d - ref) <= COVER_SIGMAS * sigma)}


def _rendered(fusions: dict[str, Any]) -> list[dict[str, Any]]:
    import stereo_classic as sc
    from benchmarks.road_scenes import road_scenes
    from stereo_classic.fusion import localize

    rows = []
    matcher = sc.StereoMatcher(num_disparities=96, threads=2)
    for scene in road_scenes():
        dmap = matcher.compute(scene.left, scene.right)
        dets = _detections(scene.boxes, scene.labels)
        for name, fusion in fusions.items():
            objs = localize(dets, dmap, scene.rig, fusion, rng=0)
            rows += [{**_row("rendered", scene.name, scene.labels[i], float(scene.reference_m[i]), objs, i),
                      "fusion": name} for i in range(len(objs))]
    return rows


def _detections(boxes: np.ndarray, labels: Sequence[str]) -> Any:
    from detectors import COCO_CLASSES, Detections

    n = len(labels)
    return Detections(xyxy=np.asarray(boxes, np.float32).reshape(-1, 4), confidence=np.ones(n, np.float32),
                      class_id=np.array([COCO_CLASSES.index(name) for name in labels], np.int64))


def _driving(data_dir: Any, fusions: dict[str, Any]) -> list[dict[str, Any]]:
    import stereo_classic as sc
    from benchmarks.scenes import disparity_range, load_scenes
    from detectors import resolve_model
    from stereo_classic.fusion import localize, sparse_depth_reference

    scenes = [s for s in load_scenes(data_dir) if s.family == "driving" and s.gt_disparity is not None
              and s.rig is not None]
    if not scenes:
        return []
    detector = sc.pipeline.open_detector(resolve_model("yolox_nano"), conf_threshold=0.3, iou_threshold=0.45,
                                         threads=2)  # as run opens it
    rows = []
    for scene in scenes:
        with sc.Localizer(scene.rig, detector, {"num_disparities": disparity_range(scene), "threads": 2}) as loc:
            result = loc(scene.left, scene.right)
        dets = result.detections
        if dets is None or len(dets) == 0:
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            depth = np.where(scene.gt_disparity > 0, scene.rig.focal_px * scene.rig.baseline_m /
                             (scene.gt_disparity + scene.rig.doffs), 0.0)
        refs = sparse_depth_reference(np.nan_to_num(depth, nan=0.0), np.asarray(dets.xyxy, np.float64), box_shrink=0.2)
        for name, fusion in fusions.items():
            objs = localize(dets, result.disparity, scene.rig, fusion, rng=0)
            for i in range(len(objs)):
                ref = float(refs[i]) if np.isfinite(refs[i]) else None
                if ref is not None:
                    rows.append({**_row("drivingstereo", scene.name, dets.labels[i], ref, objs, i), "fusion": name})
    return rows


def _kitti(data_dir: Any, fusions: dict[str, Any]) -> list[dict[str, Any]]:
    from benchmarks.kitti_objects import kitti_object_benchmark
    from stereo_classic.fusion import FusionParams

    rows = []
    for name, fusion in fusions.items():
        try:
            res = kitti_object_benchmark(data_dir, methods=("run",), threads=2, fusion=FusionParams(**fusion))
        except FileNotFoundError:
            return []
        for o in res["objects"]:
            if o["detection"] is None or o["reference_m"] is None:
                continue
            m = o["methods"]["run"]
            ok = m["status"] == "ok" and m["distance_m"] is not None
            ref, d, sigma = o["reference_m"], m["distance_m"], m.get("distance_sigma_m")
            err = 100.0 * (d - ref) / ref if ok else None
            rows.append({"set": "kitti", "frame": res["frame"], "label": f"car {o['label_index']}",
                         "reference_m": ref, "distance_m": d if ok else None, "sigma_m": sigma if ok else None,
                         "status": m["status"], "error_pct": err, "fusion": name,
                         "covered": None if err is None or sigma is None
                         else bool(abs(d - ref) <= COVER_SIGMAS * sigma)})
    return rows


def object_rows(data_dir: Any = None, *, sets: Sequence[str] = ("rendered", "drivingstereo", "kitti")) -> list[dict]:
    """One dict per object, set and fusion (``before`` / ``after``): reference, distance, sigma, status, signed
    error in percent (None without a distance), covered (error within ``COVER_SIGMAS`` sigmas)."""
    from benchmarks.scenes import default_data_dir
    from stereo_classic.fusion import FusionParams

    data_dir = default_data_dir() if data_dir is None else data_dir
    fusions = {name: FusionParams(**over) for name, over in FUSIONS.items()}
    rows: list[dict[str, Any]] = []
    if "rendered" in sets:
        rows += _rendered(fusions)
    if "drivingstereo" in sets and data_dir is not None:
        rows += _driving(data_dir, fusions)
    if "kitti" in sets and data_dir is not None:
        rows += _kitti(data_dir, FUSIONS)
    return rows


def summarise(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Objects, with a distance, median / p90 absolute error %, share within 5 %, share covered, and the
    objects reported ok whose error exceeds ``COVER_SIGMAS`` sigmas (their frame and label)."""
    errs = np.array([abs(r["error_pct"]) for r in rows if r["error_pct"] is not None])
    covered = [r["covered"] for r in rows if r["covered"] is not None]
    return {
        "objects": len(rows), "with_distance": int(errs.size),
        "median_pct": float(np.median(errs)) if errs.size else None,
        "p90_pct": float(np.percentile(errs, 90)) if errs.size else None,
        "within_5_pct": float(np.mean(errs <= WITHIN_PCT) * 100) if errs.size else None,
        "covered_pct": float(np.mean(covered) * 100) if covered else None,
        "ok_beyond_3_sigma": [f"{r['frame']} {r['label']}" for r in rows if r["covered"] is False],
        "statuses": sorted({r["status"] for r in rows if r["status"] != "ok"}),
    }


def _f(v: Any, spec: str = ".1f") -> str:
    return "–" if v is None else format(v, spec)


def render_markdown(rows: Sequence[dict[str, Any]]) -> str:
    lines = ["| set | fusion | objects | with distance | median % | p90 % | within 5 % | covered by 3 sigma % | "
             "ok beyond 3 sigma | other statuses |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    sets = list(dict.fromkeys(r["set"] for r in rows)) + ["all"]
    for s in sets:
        for fusion in FUSIONS:
            chosen = [r for r in rows if r["fusion"] == fusion and (s == "all" or r["set"] == s)]
            if not chosen:
                continue
            m = summarise(chosen)
            lines.append(f"| {s} | {fusion} | {m['objects']} | {m['with_distance']} | {_f(m['median_pct'], '.2f')} | "
                         f"{_f(m['p90_pct'], '.2f')} | {_f(m['within_5_pct'])} | {_f(m['covered_pct'])} | "
                         f"{', '.join(m['ok_beyond_3_sigma']) or 'none'} | {', '.join(m['statuses']) or '–'} |")
    lines += ["", "| set | frame | label | reference m | fusion | distance m | sigma m | status | error % |",
              "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['set']} | {r['frame']} | {r['label']} | {_f(r['reference_m'], '.2f')} | {r['fusion']} | "
                     f"{_f(r['distance_m'], '.2f')} | {_f(r['sigma_m'], '.2f')} | {r['status']} | "
                     f"{_f(r['error_pct'], '+.1f')} |")
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.objects", description=__doc__.split("\n\n")[0])
    p.add_argument("--data", default=None, help="folder of scenes (default: $STEREO_CLASSIC_DATA or ../shared/data)")
    p.add_argument("--sets", nargs="+", default=["rendered", "drivingstereo", "kitti"],
                   choices=["rendered", "drivingstereo", "kitti"], help="which sets (default: all)")
    p.add_argument("--out", default=None, help="also write the markdown here")
    args = p.parse_args(argv)
    text = render_markdown(object_rows(args.data, sets=args.sets))
    sys.stdout.write(text)
    if args.out:
        from pathlib import Path

        Path(args.out).write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
