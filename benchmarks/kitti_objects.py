"""Per-object distance against KITTI 3D labels: ``run`` vs OpenCV 3WAY + the same fusion vs a DepthAI-style median.

For each labelled car (not ``DontCare``) of a KITTI object frame the reference is the depth of its visible surface:
the LiDAR points inside its labelled 3D box (:func:`stereo_classic.datasets.lidar_points_in_labels`) that project
into the left image (:func:`in_view`: a truncated car's box reaches past the border, out of view), their median
depth along the left camera's optical axis (``z + P2[2, 3]``, camera 2) and their 10th percentile (the nearest
surface). Each label is matched to a vehicle detection of the default detector by 2D IoU (>= 0.5, Hungarian).

Methods (all on the same detections, the same rig, the same disparity range):

- ``run``: :class:`stereo_classic.Localizer` as ``run`` builds it: the default detector (``yolox_nano`` via
  ``detectors.resolve_model``, ``run``'s thresholds), ``SGMParams()`` defaults with ``run``'s disparity range
  (``CLI_NUM_DISPARITIES``), ``FusionParams()`` defaults, the frame checks on.
- ``run-mccnn``: ``run --cost mccnn``: the same :class:`stereo_classic.Localizer` with ``SGMParams(cost="mccnn")``
  (the learned cost of the shipped MC-CNN, the same range): the same detections, fusion, seed and frame checks.
- ``ocv-3way``: OpenCV ``MODE_SGBM_3WAY`` (``benchmarks.methods.opencv_methods``, block size = ``SGMParams()``'s)
  and the same fusion (:func:`stereo_classic.localize`, ``FusionParams()``, same seed).
- ``depthai-median``: the median depth of this project's measured disparity (``DisparityMap.disparity``:
  no filled pixels) inside the box shrunk to half its width and height about its centre (what DepthAI's
  SpatialLocationCalculator reports, without its depth thresholds).

For the two fusion methods the nearest surface is the fusion's own `LocalizedObjects.nearest_m` (the 10th
percentile of the depths of its inliers).

``python -m benchmarks.kitti_objects [--data DIR] [--out FILE.md]`` prints (or writes) the Markdown table.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.report import signed_zero_free

__all__ = ["DEFAULT_METHODS", "half_box_median", "in_view", "kitti_object_benchmark", "main", "match_labels",
           "render_markdown"]

log = logging.getLogger("benchmarks.kitti_objects")

#: Methods compared, in table order.
DEFAULT_METHODS: tuple[str, ...] = ("run", "run-mccnn", "ocv-3way", "depthai-median")
#: Detector classes a labelled car may be matched to (a car is sometimes called a truck).
VEHICLE_CLASSES: tuple[str, ...] = ("car", "truck", "bus")
#: Smallest 2D IoU of a label-detection match.
MIN_IOU = 0.5
#: The issue's bar: relative error of every detected, non-truncated car, percent.
BAR_PCT = 3.0
#: Labels with at most this truncation count as "not truncated" (KITTI's "easy" limit).
MAX_TRUNCATION = 0.15
_FUSION_METHODS = ("run", "run-mccnn", "ocv-3way")


def _pair_folder(data_dir: str | Path | None) -> Path:
    """The frame folder (``label_2.txt`` + ``calib.txt`` + images + ``lidar.bin``): ``data_dir`` or its
    ``kitti_object_pair`` subfolder; ``None``: ``$STEREO_CLASSIC_DATA`` or ``../shared/data``."""
    if data_dir is None:
        from benchmarks.scenes import default_data_dir

        data_dir = default_data_dir()
        if data_dir is None:
            raise FileNotFoundError("no data folder: give --data DIR (a KITTI frame folder with label_2.txt) or set "
                                    "STEREO_CLASSIC_DATA")
    root = Path(data_dir)
    for folder in (root, root / "kitti_object_pair"):
        if (folder / "label_2.txt").is_file():
            return folder
    raise FileNotFoundError(f"`data_dir` {root}: expected a KITTI frame folder with label_2.txt, calib.txt, "
                            "left.png, right.png and lidar.bin (or one in its kitti_object_pair subfolder)")


def _iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(len(a), len(b)) IoU of xyxy boxes."""
    a = np.asarray(a, dtype=np.float64).reshape(-1, 4)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 4)
    iw = np.clip(np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0]), 0, None)
    ih = np.clip(np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1]), 0, None)
    inter = iw * ih
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    union = area_a[:, None] + area_b[None, :] - inter
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(union > 0, inter / union, 0.0)


def match_labels(label_boxes: np.ndarray, det_boxes: np.ndarray, *, min_iou: float = MIN_IOU) -> list[tuple[int, float] | None]:
    """Match labels to detections one-to-one, maximising the total IoU (Hungarian), pairs below ``min_iou`` refused.

    Returns, per label, ``(detection index, IoU)`` or None.

    >>> match_labels(np.array([[0, 0, 10, 10], [20, 0, 30, 10]]), np.array([[21, 0, 30, 10], [0, 0, 10, 9]]))
    [(1, 0.9), (0, 0.9)]
    """
    from scipy.optimize import linear_sum_assignment

    out: list[tuple[int, float] | None] = [None] * len(label_boxes)
    if len(label_boxes) == 0 or len(det_boxes) == 0:
        return out
    iou = _iou(label_boxes, det_boxes)
    gain = np.where(iou >= min_iou, iou, 0.0)
    rows, cols = linear_sum_assignment(-gain)
    for r, c in zip(rows, cols):
        if iou[r, c] >= min_iou:
            out[int(r)] = (int(c), round(float(iou[r, c]), 4))
    return out


def half_box_median(disparity: np.ndarray, box: Sequence[float], rig: Any) -> tuple[float, int]:
    """DepthAI-style distance: the median depth (metres) of the known disparities inside the box shrunk to half
    its width and height about its centre, and how many pixels it used (NaN, 0 when none).

    ``disparity`` (H, W) float pixels, NaN unknown; ``box`` (x1, y1, x2, y2) pixels; depth
    ``Z = focal_px * baseline_m / (d + doffs)``.
    """
    height, width = disparity.shape
    x1, y1, x2, y2 = (float(v) for v in box)
    cx, cy, hw, hh = (x1 + x2) / 2, (y1 + y2) / 2, (x2 - x1) / 4, (y2 - y1) / 4
    u0, u1 = max(0, round(cx - hw)), min(width, round(cx + hw))
    v0, v1 = max(0, round(cy - hh)), min(height, round(cy + hh))
    crop = np.asarray(disparity[v0:v1, u0:u1], dtype=np.float64) + float(rig.doffs)
    known = crop[np.isfinite(crop) & (crop > 0)]
    if known.size == 0:
        return math.nan, 0
    return float(np.median(rig.focal_px * rig.baseline_m / known)), int(known.size)


def in_view(points: np.ndarray, p2: np.ndarray, width: int, height: int) -> np.ndarray:
    """The rows of ``points`` ((N, 3) rectified camera coordinates, metres) that project with ``p2`` (3x4) into a
    ``width`` x ``height`` image in front of the camera: what the camera sees of a box. A truncated car's LiDAR
    points reach past the image border, where neither camera nor matcher sees it.

    >>> p2 = np.array([[100.0, 0, 50, 0], [0, 100.0, 20, 0], [0, 0, 1, 0]])
    >>> in_view(np.array([[0.0, 0, 2], [2.0, 0, 2], [0.0, 0, -2]]), p2, 100, 40).tolist()
    [[0.0, 0.0, 2.0]]
    """
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    uvw = pts @ p2[:, :3].T + p2[:, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        u, v = uvw[:, 0] / uvw[:, 2], uvw[:, 1] / uvw[:, 2]
        keep = (uvw[:, 2] > 0) & (u >= 0) & (u <= width - 1) & (v >= 0) & (v <= height - 1)
    return pts[keep]


def _pct(value: float | None, ref: float | None) -> float | None:
    if value is None or ref is None or not math.isfinite(value) or ref <= 0:
        return None
    return 100.0 * (value - ref) / ref


def _num(value: float) -> float | None:
    return float(value) if math.isfinite(float(value)) else None


def _check_methods(methods: Sequence[str]) -> tuple[str, ...]:
    if isinstance(methods, str) or not methods:
        raise ValueError(f"`methods` must be a non-empty sequence of names from {DEFAULT_METHODS}, got {methods!r}")
    unknown = [m for m in methods if m not in DEFAULT_METHODS]
    if unknown:
        raise ValueError(f"`methods` must be names from {DEFAULT_METHODS}, got unknown {unknown}")
    return tuple(dict.fromkeys(methods))


def kitti_object_benchmark(data_dir: str | Path | None = None, *, methods: Sequence[str] = DEFAULT_METHODS,
                           threads: int = 1, model: str = "yolox_nano", label_types: Sequence[str] = ("Car",),
                           seed: int = 0, num_disparities: int | None = None, fusion: Any = None) -> dict[str, Any]:
    """Per labelled object of a KITTI frame: the LiDAR reference and each method's distance and error.

    Parameters
    ----------
    data_dir : path or None
        A KITTI frame folder (``label_2.txt``, ``calib.txt``, ``left.png``, ``right.png``, ``lidar.bin``) or a
        folder holding ``kitti_object_pair``; None: ``$STEREO_CLASSIC_DATA`` or ``../shared/data``.
    methods : sequence of str
        Names from :data:`DEFAULT_METHODS`.
    threads : int
        Threads of the matchers and the detector.
    model : str
        Detector name or path (``detectors.resolve_model``; default ``run``'s).
    label_types : sequence of str
        Label types benchmarked (default cars).
    seed : int
        The fusion's seed (``run``'s default 0).
    num_disparities : int or None
        Disparity range of both matchers; None: ``run``'s for a pair (``CLI_NUM_DISPARITIES``, 128). Every other
        matcher setting is ``SGMParams()``'s default.
    fusion : FusionParams or None
        The fusion's settings (None: ``FusionParams()``, ``run``'s).

    Returns
    -------
    dict
        ``objects`` (one dict per benchmarked label: ``label_index`` (0-based row of the file), ``truncated``,
        ``occluded``, ``lidar_points`` (in view), ``lidar_points_in_box``, ``reference_m`` (median),
        ``reference_p10_m``, ``detection`` (None when unmatched), ``methods`` {name: ``distance_m``, ``status``,
        ``error_pct`` (signed), and for the fusion methods ``nearest_m``, ``nearest_error_pct`` (against
        ``reference_p10_m``)}), ``bar`` (per method: whether every detected non-truncated car is within
        :data:`BAR_PCT`), ``unmatched_detections``, the settings.
    """
    import cv2  # noqa: F401 - OpenCV is a runtime dependency; imported here to fail early and plainly

    from benchmarks.methods import Setup, opencv_methods
    from detectors import resolve_model
    from stereo_classic import Localizer
    from stereo_classic.pipeline import open_detector
    from stereo_classic.cli.options import CLI_NUM_DISPARITIES
    from stereo_classic.datasets import (
        lidar_points_in_labels,
        load_kitti_lidar_folder,
        read_kitti_calib_file,
        read_kitti_labels,
        read_velodyne,
    )
    from stereo_classic.fusion import FusionParams, localize
    from stereo_classic.matching import SGMParams

    methods = _check_methods(methods)
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise ValueError(f"`threads` must be an integer >= 1, got {threads!r}")
    folder = _pair_folder(data_dir)
    scene = load_kitti_lidar_folder(folder)
    rig = scene.rig
    labels = read_kitti_labels(folder / "label_2.txt")
    calib = read_kitti_calib_file(folder / "calib.txt")
    velo = next((p for p in (folder / "lidar.bin", folder / "velodyne.bin") if p.is_file()), None)
    if velo is None:
        raise FileNotFoundError(f"{folder}: no lidar.bin (or velodyne.bin)")
    p2 = np.asarray(calib["P2"]).reshape(3, 4)
    inside = lidar_points_in_labels(read_velodyne(velo), labels, R0_rect=np.asarray(calib["R0_rect"]).reshape(3, 3),
                                    Tr_velo_to_cam=np.asarray(calib["Tr_velo_to_cam"]).reshape(3, 4))

    params = SGMParams(num_disparities=CLI_NUM_DISPARITIES if num_disparities is None else num_disparities,
                       threads=threads)
    fusion = FusionParams() if fusion is None else fusion
    model_path = resolve_model(model)
    detector = open_detector(model_path, conf_threshold=0.3, iou_threshold=0.45, threads=threads)  # as run does
    with Localizer(rig, detector, params, fusion=fusion, seed=seed) as loc:
        result = loc(scene.left, scene.right)
    dets = result.detections
    # DepthAI's median reads measured pixels only: values the matcher filled into holes are not measurements
    our_disp = np.asarray(result.disparity.disparity)
    fused: dict[str, Any] = {"run": result.objects}
    if "run-mccnn" in methods:  # run --cost mccnn: the same detector (so the same detections), fusion and checks
        with Localizer(rig, detector, params.replace(cost="mccnn"), fusion=fusion, seed=seed) as loc:
            learned = loc(scene.left, scene.right)
        if not np.array_equal(np.asarray(learned.detections.xyxy), np.asarray(dets.xyxy)):
            raise RuntimeError("the detector gave other detections on the second run: labels would not match")
        fused["run-mccnn"] = learned.objects
    if "ocv-3way" in methods:
        ocv = next(m for m in opencv_methods() if m.name == "ocv-3way")
        setup = Setup(num_disparities=params.num_disparities, min_disparity=params.min_disparity,
                      block_size=params.block_size, threads=threads)
        ocv_disp = ocv.prepare(setup)(scene.left, scene.right)
        fused["ocv-3way"] = localize(dets, ocv_disp, rig, fusion, rng=seed)

    det_labels = list(dets.labels) if dets is not None else []
    det_boxes = np.asarray(dets.xyxy, dtype=np.float64).reshape(-1, 4) if dets is not None else np.zeros((0, 4))
    vehicles = [i for i, name in enumerate(det_labels) if name in VEHICLE_CLASSES]
    wanted = [i for i, lab in enumerate(labels) if lab.type in tuple(label_types)]
    matches = match_labels(np.array([labels[i].box2d for i in wanted]).reshape(-1, 4), det_boxes[vehicles])

    objects = []
    height, width = scene.left.shape[:2]
    for li, match in zip(wanted, matches):
        lab, pts = labels[li], inside[li]
        box_points = 0 if pts is None else len(pts)
        pts = in_view(pts, p2, width, height) if box_points else None
        depth = pts[:, 2] + p2[2, 3] if pts is not None and len(pts) else np.zeros(0)
        ref = float(np.median(depth)) if depth.size else None
        ref10 = float(np.percentile(depth, 10)) if depth.size else None
        row: dict[str, Any] = {
            "label_index": li, "type": lab.type, "truncated": lab.truncated, "occluded": lab.occluded,
            "box2d": list(lab.box2d), "label_z_m": lab.location[2], "lidar_points": int(depth.size),
            "lidar_points_in_box": box_points,
            "reference_m": ref, "reference_p10_m": ref10, "detection": None, "methods": {},
        }
        if match is not None:
            di = vehicles[match[0]]
            row["detection"] = {"index": di, "label": det_labels[di], "confidence": round(float(dets.confidence[di]), 4),
                                "iou": match[1], "xyxy": [round(float(v), 2) for v in det_boxes[di]]}
            for name in methods:
                if name in fused:
                    objs = fused[name]
                    d = _num(objs.distance_m[di])
                    entry: dict[str, Any] = {"distance_m": d, "status": str(objs.status[di]), "error_pct": _pct(d, ref),
                                             "distance_sigma_m": _num(objs.distance_sigma_m[di])}
                    near = _num(objs.nearest_m[di]) if objs.status[di] == "ok" else None
                    entry["nearest_m"] = near
                    entry["nearest_error_pct"] = _pct(near, ref10)
                else:  # depthai-median
                    d, n = half_box_median(our_disp, det_boxes[di], rig)
                    entry = {"distance_m": _num(d), "status": "ok" if n else "no_depth", "pixels": n,
                             "error_pct": _pct(_num(d), ref)}
                row["methods"][name] = entry
        objects.append(row)

    matched = {o["detection"]["index"] for o in objects if o["detection"] is not None}
    unmatched = [{"index": i, "label": det_labels[i], "confidence": round(float(dets.confidence[i]), 4),
                  "xyxy": [round(float(v), 2) for v in det_boxes[i]]} for i in vehicles if i not in matched]
    bar = {}
    checked = [o for o in objects if o["truncated"] <= MAX_TRUNCATION and o["detection"] is not None]
    for name in methods:
        failing = [o["label_index"] for o in checked
                   if o["methods"][name]["error_pct"] is None or abs(o["methods"][name]["error_pct"]) > BAR_PCT]
        bar[name] = {"holds": bool(checked) and not failing, "checked": [o["label_index"] for o in checked],
                     "failing": failing}
    shown = {f.name: getattr(params, f.name) for f in dataclasses.fields(params)}
    return {
        "available": True, "frame": folder.name, "data": str(folder), "model": Path(model_path).name,
        "methods": list(methods), "threads": threads, "seed": seed,
        "matcher": {k: (v if isinstance(v, (int, float, str, bool, type(None))) else repr(v)) for k, v in shown.items()},
        "fusion": {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(fusion).items()},
        "warnings": [w.code for w in result.warnings],
        "reference": "LiDAR points inside the labelled 3D box that project into the left image (the visible "
                     "surface): median (reference_m) and 10th percentile (reference_p10_m) of their depth along "
                     "the left camera's optical axis (z + P2[2,3])",
        "bar_pct": BAR_PCT, "max_truncation": MAX_TRUNCATION, "min_iou": MIN_IOU,
        "objects": objects, "unmatched_detections": unmatched, "bar": bar,
        "nearest": {"available": True, "reason": ""},  # LocalizedObjects.nearest_m: the fusion reports it
    }


def _fmt(value: float | None, spec: str = ".2f", suffix: str = "") -> str:
    return "–" if value is None else f"{signed_zero_free(format(value, spec), spec)}{suffix}"


_TITLES = {"run": "`run`", "run-mccnn": "`run --cost mccnn`", "ocv-3way": "3WAY + fusion",
           "depthai-median": "DepthAI median"}


def render_markdown(result: dict[str, Any]) -> str:
    """The benchmark as Markdown: one row per labelled object, a line per method for the bar, the settings."""
    if not result.get("available", False):
        return f"Per-object distance against KITTI labels: not available ({result.get('reason', '')})\n"
    methods = result["methods"]
    head = ["label", "trunc.", "occl.", "LiDAR pts in view (in box)", "LiDAR median (m)", "LiDAR p10 (m)", "detection (IoU)"]
    for name in methods:
        head.append(f"{_TITLES[name]} m (err %)")
    near_methods = [m for m in methods if m in _FUSION_METHODS]
    head += [f"{_TITLES[m]} nearest m (err % vs p10)" for m in near_methods]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for o in result["objects"]:
        det = o["detection"]
        cells = [str(o["label_index"]), f"{o['truncated']:.2f}", str(o["occluded"]),
                 f"{o['lidar_points']} ({o.get('lidar_points_in_box', o['lidar_points'])})",
                 _fmt(o["reference_m"]), _fmt(o["reference_p10_m"]),
                 "not detected" if det is None else f"{det['label']} ({det['iou']:.2f})"]
        for name in methods:
            e = o["methods"].get(name)
            if e is None:
                cells.append("–")
            elif e["distance_m"] is None:
                cells.append(f"– ({e['status']})")
            else:
                cells.append(f"{_fmt(e['distance_m'])} ({_fmt(e['error_pct'], '+.1f')})")
        for name in near_methods:
            e = o["methods"].get(name)
            cells.append("–" if e is None else f"{_fmt(e['nearest_m'])} ({_fmt(e['nearest_error_pct'], '+.1f')})")
        lines.append("| " + " | ".join(cells) + " |")
    intro = (f"Frame `{result['frame']}`, detector `{result['model']}`, matcher `SGMParams()` defaults with "
             f"num_disparities {result['matcher']['num_disparities']}, `FusionParams()` defaults, seed {result['seed']}.")
    out = [intro, "", *lines, ""]
    for name in methods:
        b = result["bar"][name]
        verdict = "holds" if b["holds"] else "does not hold"
        fail = f" (outside: labels {', '.join(map(str, b['failing']))})" if b["failing"] else ""
        out.append(f"- {_TITLES[name]}: every detected car with truncation <= {result['max_truncation']} within "
                   f"{result['bar_pct']:g} % (labels {', '.join(map(str, b['checked'])) or 'none'}): **{verdict}**{fail}")
    if result["unmatched_detections"]:
        out.append("- vehicle detections matched to no label: " + ", ".join(
            f"{d['label']} {d['confidence']:.2f} at {d['xyxy']}" for d in result["unmatched_detections"]))
    if not result["nearest"]["available"]:
        out.append(f"- nearest surface of the fusion: missing ({result['nearest']['reason']})")
    if result["warnings"]:
        out.append(f"- frame checks: {', '.join(result['warnings'])}")
    out.append(f"- reference: {result['reference']}; labels matched to detections of "
               f"{'/'.join(VEHICLE_CLASSES)} by 2D IoU >= {result['min_iou']} (Hungarian).")
    return "\n".join(out) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m benchmarks.kitti_objects``: exit 0 on success, 1 on a runtime failure, 2 on a usage error."""
    p = argparse.ArgumentParser(prog="python -m benchmarks.kitti_objects",
                                description="Per-object distance against KITTI 3D labels (LiDAR inside each box).")
    p.add_argument("--data", type=Path, help="KITTI frame folder, or a folder holding kitti_object_pair "
                                             "(default: $STEREO_CLASSIC_DATA or ../shared/data)")
    p.add_argument("--out", type=Path, help="Markdown file to write (default: print to stdout)")
    p.add_argument("--threads", type=int, default=1, help="threads of the matchers and the detector (default 1)")
    p.add_argument("--num-disparities", type=int, help="disparity range of both matchers (default: run's, 128)")
    p.add_argument("-v", "--verbose", action="store_true")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING, format="%(message)s")

    from stereo_classic.cli import UsageError, run_guarded
    from stereo_classic.cli.paths import check_output_file

    def run() -> int:
        if args.threads < 1:
            raise UsageError(f"--threads must be >= 1, got {args.threads}")
        if args.out is not None:
            check_output_file(args.out, "--out")
        try:
            result = kitti_object_benchmark(args.data, threads=args.threads, num_disparities=args.num_disparities)
        except FileNotFoundError as exc:
            raise UsageError(str(exc)) from None
        text = render_markdown(result)
        if args.out is None:
            sys.stdout.write(text)
        else:
            from stereo_classic.io import atomic_write

            with atomic_write(args.out, "w") as f:
                f.write(text)
        return 0

    return run_guarded(run, verbose=bool(args.verbose))


if __name__ == "__main__":
    sys.exit(main())
