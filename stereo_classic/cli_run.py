"""``python -m stereo_classic run``: the whole pipeline from the command line.

With no arguments it runs the built-in demo scene (Middlebury Motorcycle from scikit-image) with the
default detector, prints one line per object and writes every output into ``./stereo_out``.

Outputs per frame ``NAME`` (``--save`` chooses; ``--ply`` adds the point cloud):

* ``NAME_boxes.png``          left image with labelled boxes ("car 12.4 m")
* ``NAME_disparity.png``      colourised disparity (TURBO, unknown black)
* ``NAME_depth.png``          colourised depth (TURBO, near = blue, unknown black)
* ``NAME_disparity.pfm``      float32 disparity in pixels, NaN unknown
* ``NAME_disparity_kitti.png`` KITTI 16-bit PNG (disparity x 256, 0 unknown)
* ``NAME_points.ply``         coloured point cloud in metres (``--ply``)
* ``NAME_objects.json``       objects of a single pair; sequences append one line per frame to
  ``objects.jsonl`` instead.

Every file is written atomically; the objects record is written last. Ctrl-C finishes nothing half: the
frame in progress leaves no file, finished frames are complete, and ``--resume`` skips them.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import signal
import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np

from stereo_classic._cli_options import add_matcher_options, matcher_fields
from stereo_classic.cli import UsageError

__all__ = ["add_parser", "func", "SAVE_KINDS"]

log = logging.getLogger("stereo_classic.run")

#: What ``--save`` can name, and the file each writes (``{name}`` is the frame name).
SAVE_KINDS: dict[str, str] = {
    "boxes": "{name}_boxes.png",
    "disparity": "{name}_disparity.png",
    "depth": "{name}_depth.png",
    "pfm": "{name}_disparity.pfm",
    "kitti": "{name}_disparity_kitti.png",
    "ply": "{name}_points.ply",
    "json": "{name}_objects.json",
}
JSONL_NAME = "objects.jsonl"

def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Register the ``run`` sub-command."""
    p = subparsers.add_parser(
        "run", help="detect objects and say how far away each one is (default: the demo scene)",
        description="Stereo depth + object detection + per-object distance. With no input options the "
                    "built-in demo scene (Middlebury Motorcycle) is used. Options may also come from "
                    "--config FILE.toml (flags win).")
    src = p.add_argument_group("input (one kind; none = the demo scene)")
    src.add_argument("--left", nargs="+", metavar="PATH",
                     help="left image(s) or glob pattern(s), paired in order with --right")
    src.add_argument("--right", nargs="+", metavar="PATH", help="right image(s) or glob pattern(s)")
    src.add_argument("--calib", metavar="FILE", help="calibration (OpenCV YAML/XML, KITTI, Middlebury calib.txt, ...)")
    src.add_argument("--rectify", action="store_true", help="the images are raw: rectify them with --calib")
    src.add_argument("--dataset", metavar="DIR", help="a dataset folder (Middlebury, KITTI, ...): every scene below it")
    src.add_argument("--video", metavar="FILE",
                     help="a side-by-side stereo video (left half = left image); needs --calib")
    src.add_argument("--camera", type=int, metavar="N", help="live side-by-side stereo camera N; needs --calib")
    src.add_argument("--max-frames", type=int, default=None, metavar="N", help="stop after N frames (0 = all)")
    src.add_argument("--scale", type=float, default=None, metavar="F",
                     help="resize the images by F (e.g. 0.5) before matching")

    out = p.add_argument_group("output")
    out.add_argument("-o", "--output", default=None, metavar="DIR", help="output folder (default: stereo_out)")
    out.add_argument("--save", default=None, metavar="LIST",
                     help=f"comma-separated outputs among {','.join(k for k in SAVE_KINDS if k != 'ply')} "
                          "(default: all of them)")
    out.add_argument("--ply", action=argparse.BooleanOptionalAction, default=None,
                     help="also write a coloured PLY point cloud")
    out.add_argument("--resume", action="store_true", help="skip frames whose outputs are all present")
    out.add_argument("--no-progress", action="store_true",
                     help="no progress bar (it is off anyway when stderr is not a terminal)")

    det = p.add_argument_group("detector")
    det.add_argument("--model", default=None, metavar="NAME|PATH",
                     help="ONNX detector name or path, or 'none' (default: yolox_nano)")
    det.add_argument("--conf", type=float, default=None, help="confidence threshold (default 0.3)")
    det.add_argument("--iou", type=float, default=None, help="NMS IoU threshold (default 0.45)")
    det.add_argument("--classes", default=None, metavar="LIST",
                     help="comma-separated class names to keep (e.g. car,person)")

    fus = p.add_argument_group("fusion")
    fus.add_argument("--method", choices=("ransac", "median"), default=None, help="distance per box (default ransac)")
    fus.add_argument("--box-shrink", type=float, default=None, metavar="F",
                     help="fraction of box width/height left out at the edges (default 0.2)")
    fus.add_argument("--depth-range", type=float, nargs=2, default=None, metavar=("NEAR", "FAR"),
                     help="metres (default 0.3 80)")
    fus.add_argument("--min-pixels", type=int, default=None, metavar="N",
                     help="fewest depth pixels per box (default 20)")
    fus.add_argument("--tolerance-px", type=float, default=None, metavar="PX",
                     help="RANSAC inlier band in disparity px (default 1)")
    fus.add_argument("--near-support", type=float, default=None, metavar="F",
                     help="a nearer set wins at this fraction of the largest one's support (default 0.5)")
    fus.add_argument("--centre-sigma", type=float, default=None, metavar="F",
                     help="centre weighting of votes, fraction of the box (default 0.25, 0 = off)")
    fus.add_argument("--grow-density", type=float, default=None, metavar="F",
                     help="grow the set over continuous depths (default 0.1, 0 = off)")
    fus.add_argument("--seed", type=int, default=None, help="RANSAC seed (default 0)")

    mat = p.add_argument_group("matcher (the same options as the disparity command; default: SGMParams')")
    add_matcher_options(mat, dest_prefix="matcher_", help_overrides={
        "num_disparities": "disparities searched (default: the scene's range, else 128)"})

    run = p.add_argument_group("run")
    run.add_argument("--threads", type=int, default=None, metavar="N",
                     help="threads for the matcher and the detector (default: all)")
    run.add_argument("--concurrent", action=argparse.BooleanOptionalAction, default=None,
                     help="run the detector in a thread beside the matcher (default off: not faster on 2 cores)")
    run.add_argument("--config", metavar="FILE.toml", help="read options from a TOML file (flags win)")
    run.add_argument("--dump-config", action="store_true", help="print the merged options as TOML and exit")
    p.set_defaults(func=func)
    return p


# --------------------------------------------------------------------------------------------------
# options
# --------------------------------------------------------------------------------------------------
def _options(args: argparse.Namespace) -> dict[str, Any]:
    from stereo_classic.config import RUN_DEFAULTS, ConfigError, load_config, merge_config

    flags = {k: getattr(args, k, None) for k in RUN_DEFAULTS}
    matcher_flags = matcher_fields(args, dest_prefix="matcher_")
    try:
        file_cfg = load_config(args.config) if args.config else None
        cfg = merge_config(file_cfg, flags, matcher_flags)
    except ConfigError as exc:
        raise UsageError(str(exc)) from None
    if cfg["max_frames"] < 0:  # the merged value: a flag or the config file
        raise UsageError(f"`max_frames` (--max-frames) must be >= 0 (0 = all), got {cfg['max_frames']}")
    bad = [s for s in cfg["save"] if s not in SAVE_KINDS]
    if bad:
        raise UsageError(f"--save: unknown output {bad[0]!r}; choose among {', '.join(SAVE_KINDS)}")
    if cfg["method"] not in ("ransac", "median"):
        raise UsageError(f"`method` must be ransac or median, got {cfg['method']!r}")
    if cfg["threads"] < 0:
        raise UsageError(f"--threads must be >= 1 (0 = all), got {cfg['threads']}")
    if not (0 < cfg["scale"] <= 4):
        raise UsageError(f"--scale must be in (0, 4], got {cfg['scale']}")
    for key in ("conf", "iou"):
        if not (0.0 <= cfg[key] <= 1.0):
            raise UsageError(f"--{key} must be between 0 and 1, got {cfg[key]}")
    if cfg["seed"] < 0:
        raise UsageError(f"--seed must be >= 0, got {cfg['seed']}")
    from stereo_classic.fusion import FusionInputError, check_options

    try:  # check the fusion options before any work
        check_options(method=cfg["method"], box_shrink=cfg["box_shrink"], depth_range=tuple(cfg["depth_range"]),
                      min_pixels=cfg["min_pixels"], tolerance_px=cfg["tolerance_px"],
                      near_support=cfg["near_support"], centre_sigma=cfg["centre_sigma"],
                      grow_density=cfg["grow_density"])
    except FusionInputError as exc:
        raise UsageError(str(exc)) from None
    return cfg


def _matcher_params(cfg: dict[str, Any], max_disparity: int | None) -> Any:
    from stereo_classic.params import SGMParams

    fields = dict(cfg["matcher"])
    if "num_disparities" not in fields:
        if max_disparity:
            scaled = max_disparity * cfg["scale"]
            fields["num_disparities"] = int(16 * math.ceil((scaled + 1) / 16))
        else:
            fields["num_disparities"] = 128
    if cfg["threads"] > 0:
        fields["threads"] = cfg["threads"]
    try:
        return SGMParams(**fields)
    except (TypeError, ValueError) as exc:
        raise UsageError(f"matcher: {exc}") from None


# --------------------------------------------------------------------------------------------------
# sources and rigs
# --------------------------------------------------------------------------------------------------
def _load_rig(path: str, rectify: bool) -> Any:
    import calib

    rig = calib.load_rig(path)
    if hasattr(rig, "rectify") and not hasattr(rig, "focal_px"):  # a raw StereoRig
        if not rectify:
            raise UsageError(f"--calib {path} holds a raw (unrectified) calibration; add --rectify to rectify "
                             "the images with it")
        rig = rig.rectify()
    elif rectify and not getattr(rig, "has_maps", False):
        raise UsageError(f"--rectify: {path} describes an already rectified pair (no distortion or rotation to undo)")
    return rig


def _open_source(args: argparse.Namespace, cfg: dict[str, Any]) -> tuple[Any, Any]:
    from stereo_classic import sources

    kinds = [k for k in ("left", "dataset", "video", "camera") if getattr(args, k) is not None]
    if args.right is not None and args.left is None:
        raise UsageError("--right needs --left")
    if len(kinds) > 1:
        raise UsageError(f"choose one input: --{kinds[0]} and --{kinds[1]} were both given")
    max_frames = cfg["max_frames"] or None
    kind = kinds[0] if kinds else "demo"
    if kind in ("left", "video", "camera") and not args.calib:
        raise UsageError(f"--{kind} needs --calib (the stereo calibration)")
    if kind in ("demo", "dataset") and (args.calib or args.rectify):
        raise UsageError("--calib/--rectify go with --left/--right, --video or --camera (scenes carry their own)")
    try:
        if kind == "left":
            if args.right is None:
                raise UsageError("--left needs --right")
            pairs = sources.expand_pairs(args.left, args.right)
            if max_frames:
                pairs = pairs[:max_frames]
            rig = _load_rig(args.calib, args.rectify)
            return sources.PairSource(pairs), rig
        if kind in ("video", "camera"):
            rig = _load_rig(args.calib, args.rectify)
            target = args.video if kind == "video" else args.camera
            return sources.SideBySideSource(target, max_frames=max_frames), rig
        if kind == "dataset":
            src = sources.SceneSource.from_folder(args.dataset)
        else:
            src = sources.SceneSource.demo()
    except sources.SourceError as exc:
        if "matches no file" in str(exc) or "paired in order" in str(exc):
            raise UsageError(str(exc)) from None
        raise
    if max_frames:
        src.scenes = src.scenes[:max_frames]
    return src, None


def _open_detector(cfg: dict[str, Any]) -> tuple[Any, str | None]:
    if str(cfg["model"]).lower() in ("none", "off", ""):
        return None, None
    from detectors import ModelNotFoundError, OnnxDetector, resolve_model

    try:
        path = resolve_model(cfg["model"])
    except ModelNotFoundError as exc:
        log.warning("no detector, computing depth only: %s", str(exc).splitlines()[0])
        return None, None
    kwargs: dict[str, Any] = {"conf_threshold": cfg["conf"], "iou_threshold": cfg["iou"]}
    if cfg["threads"] > 0:
        kwargs["threads"] = cfg["threads"]
    detector = OnnxDetector(path, **kwargs)  # a corrupt model raises ModelError: runtime failure (exit 1)
    if cfg["classes"]:
        unknown = [c for c in cfg["classes"] if c not in detector.class_names]
        if unknown:
            raise UsageError(f"--classes: unknown class name {unknown[0]!r} for model {Path(path).name}; "
                             f"valid names: {', '.join(detector.class_names)}")
    return detector, Path(path).stem


# --------------------------------------------------------------------------------------------------
# writing one frame
# --------------------------------------------------------------------------------------------------
class _DeferInterrupt:
    """Hold Ctrl-C while one frame's files are written, then raise it: a frame is all or nothing."""

    def __enter__(self) -> _DeferInterrupt:
        self.received = False
        self.active = threading.current_thread() is threading.main_thread()
        if self.active:
            self.previous = signal.getsignal(signal.SIGINT)
            signal.signal(signal.SIGINT, self._handler)
        return self

    def _handler(self, signum: int, frame: Any) -> None:
        self.received = True

    def __exit__(self, *exc: Any) -> None:
        if self.active:
            signal.signal(signal.SIGINT, self.previous)
            if self.received and exc[0] is None:
                raise KeyboardInterrupt


def _box_labels(objects: Any) -> list[str]:
    out = []
    for label, status, dist in zip(objects.labels, objects.status, objects.distance_m):
        out.append(f"{label} {dist:.1f} m" if status == "ok" else f"{label} ?")
    return out


def _frame_record(name: str, index: int, result: Any, detector_name: str | None, cfg: dict[str, Any],
                  rig: Any) -> dict[str, Any]:
    params = result.disparity.params.to_dict()
    for volatile in ("threads", "memory_limit"):
        params.pop(volatile, None)
    h, w = result.disparity.disparity.shape
    return {
        "frame": name,
        "index": index,
        "image_size": [w, h],
        "rig": {"focal_px": round(float(rig.focal_px), 4), "baseline_m": round(float(rig.baseline_m), 6),
                "doffs": round(float(rig.doffs), 4)},
        "detector": detector_name,
        "valid_fraction": round(float(result.disparity.valid_fraction), 4),
        "settings": {"method": cfg["method"], "box_shrink": cfg["box_shrink"], "depth_range": cfg["depth_range"],
                     "min_pixels": cfg["min_pixels"], "tolerance_px": cfg["tolerance_px"],
                     "near_support": cfg["near_support"], "centre_sigma": cfg["centre_sigma"],
                     "grow_density": cfg["grow_density"], "seed": cfg["seed"], "matcher": params},
        "objects": result.objects.to_json(),
    }


def _write_frame(outdir: Path, name: str, result: Any, rig: Any, cfg: dict[str, Any], record: dict[str, Any],
                 jsonl: Any) -> list[Path]:
    """Write one frame's files, the objects record last; on a failure remove the frame's files again."""
    from stereo_classic import io

    text = json.dumps(record, indent=2, allow_nan=False) + "\n"  # fails here, before any file, if malformed
    outdir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    try:
        _write_images(outdir, name, result, rig, cfg, written)
        # The objects record is written last: it marks the frame as finished.
        if jsonl is not None:
            jsonl.append(record)
        elif "json" in cfg["save"]:
            target = outdir / SAVE_KINDS["json"].format(name=name)
            written.append(target)
            with io.atomic_write(target, "w") as f:
                f.write(text)
    except BaseException:
        for p in written:
            p.unlink(missing_ok=True)
        raise
    return written


def _write_images(outdir: Path, name: str, result: Any, rig: Any, cfg: dict[str, Any], written: list[Path]) -> None:
    from stereo_classic import io, visualize

    save = set(cfg["save"]) | ({"ply"} if cfg["ply"] else set())
    disp = result.disparity.disparity

    def path(kind: str) -> Path:
        p = outdir / SAVE_KINDS[kind].format(name=name)
        written.append(p)
        return p

    depth = rig.depth(disp) if {"depth", "ply"} & save else None
    if "boxes" in save:
        objs = result.objects
        image = visualize.draw_boxes(result.left, objs.xyxy, _box_labels(objs)) if len(objs) else result.left
        io.write_image(path("boxes"), image)
    if "disparity" in save:
        params = result.disparity.params
        io.write_image(path("disparity"), visualize.colorize(disp, vmin=max(0, params.min_disparity),
                                                             vmax=params.max_disparity))
    if "depth" in save:
        finite = depth[np.isfinite(depth)]
        near, far = cfg["depth_range"]
        vmax = float(np.clip(np.percentile(finite, 98), near * 1.01, far)) if finite.size else far
        io.write_image(path("depth"), visualize.colorize(np.where(depth <= far, depth, np.nan), vmin=near, vmax=vmax))
    if "pfm" in save:
        io.write_pfm(path("pfm"), disp)
    if "kitti" in save:
        # The KITTI PNG holds 0..255.996 px; anything else is stored as unknown (0), and said so.
        outside = np.isfinite(disp) & ((disp < 0) | (disp > 65535 / 256))
        if outside.any():
            log.warning("%s: %d disparities outside 0..255.996 px do not fit a KITTI PNG and are stored as "
                        "unknown there (the PFM keeps them)", name, int(outside.sum()))
        io.write_kitti_disparity(path("kitti"), np.where(outside, np.float32(np.nan), disp))
    if "ply" in save:
        points = rig.points(disp)
        near, far = cfg["depth_range"]
        keep = np.isfinite(depth) & (depth >= near) & (depth <= far)
        colors = result.left if result.left.ndim == 3 else np.repeat(result.left[..., None], 3, axis=2)
        io.write_ply(path("ply"), points[keep], colors[keep])


class _JsonlSink:
    """objects.jsonl, one complete line per finished frame; a torn last line is dropped on --resume."""

    def __init__(self, path: Path, resume: bool) -> None:
        self.path = path
        self.done: set[str] = set()
        self.lines: list[str] = []
        if resume and path.is_file():
            for line in path.read_text(encoding="utf-8").splitlines():
                try:
                    rec = json.loads(line)
                    self.done.add(str(rec["frame"]))
                    self.lines.append(line)
                except (ValueError, KeyError, TypeError):
                    log.info("dropping an incomplete line from %s", path)
                    break
        self._started = False

    def append(self, record: dict[str, Any]) -> None:
        from stereo_classic.io import atomic_write

        line = json.dumps(record, allow_nan=False, separators=(",", ":"))
        if not self._started:  # rewrite what is kept (nothing without --resume), atomically
            self.path.parent.mkdir(parents=True, exist_ok=True)
            with atomic_write(self.path, "w") as f:
                f.write("".join(s + "\n" for s in self.lines))
            self._started = True
        with open(self.path, "a", encoding="utf-8", newline="\n") as f:
            f.write(line + "\n")
            f.flush()
            os.fsync(f.fileno())
        self.done.add(str(record["frame"]))


# --------------------------------------------------------------------------------------------------
# the command
# --------------------------------------------------------------------------------------------------
def func(args: argparse.Namespace) -> int:
    """Run the pipeline over the chosen input; see the module docstring."""
    from stereo_classic.config import dump_config

    cfg = _options(args)
    if args.dump_config:
        sys.stdout.write(dump_config(cfg))
        return 0
    source, base_rig = _open_source(args, cfg)
    try:
        return _run(args, cfg, source, base_rig)
    finally:
        source.close()


def _expected_files(outdir: Path, name: str, cfg: dict[str, Any], sequence: bool) -> list[Path]:
    save = set(cfg["save"]) | ({"ply"} if cfg["ply"] else set())
    if sequence:
        save.discard("json")
    return [outdir / SAVE_KINDS[k].format(name=name) for k in SAVE_KINDS if k in save]


def _run(args: argparse.Namespace, cfg: dict[str, Any], source: Any, base_rig: Any) -> int:
    from tqdm import tqdm

    from stereo_classic.pipeline import Localizer, format_timings
    from stereo_classic.sources import SideBySideSource

    outdir = Path(cfg["output"])
    if outdir.exists() and not outdir.is_dir():
        raise UsageError(f"-o/--output {outdir} exists and is not a folder")
    names = source.names
    sequence = isinstance(source, SideBySideSource) or (names is not None and len(names) != 1)
    jsonl = _JsonlSink(outdir / JSONL_NAME, args.resume) if sequence and "json" in cfg["save"] else None

    def finished(name: str) -> bool:
        if not args.resume:
            return False
        if jsonl is not None and name not in jsonl.done:
            return False
        return all(p.is_file() for p in _expected_files(outdir, name, cfg, sequence))

    detector, detector_name = _open_detector(cfg)
    # Only the current frame's Localizer is kept: in a --dataset run every scene brings its own rig, and
    # each Localizer's matcher holds ~2*H*W*D bytes of buffers, so the previous one is closed on a change.
    current: list[Any] = []  # [original rig, scaled rig, Localizer] of the frame in progress
    timings: list[dict[str, float]] = []
    n_objects = n_done = n_skipped = 0
    quiet = getattr(args, "quiet", False)

    def skip(name: str) -> bool:
        nonlocal n_skipped
        if finished(name):
            n_skipped += 1
            return True
        return False

    total = len(source) or None
    bar = tqdm(total=total, unit="frame", file=sys.stderr, leave=False,
               disable=quiet or args.no_progress or not sys.stderr.isatty())
    interrupted = False
    try:
        for frame in source.frames(skip):
            rig = original_rig = frame.rig if frame.rig is not None else base_rig
            if rig is None:
                raise ValueError(f"frame {frame.name}: no calibration")
            if not current or current[0] is not original_rig:
                if current:
                    current.pop().close()  # frees its matcher's buffers before the next one allocates
                    current.clear()
                if cfg["scale"] != 1.0:
                    base = rig.without_maps() if getattr(rig, "has_maps", False) else rig
                    rig = base.scaled(cfg["scale"])
                current[:] = [original_rig, rig, Localizer(
                    rig, detector, _matcher_params(cfg, frame.max_disparity), method=cfg["method"],
                    box_shrink=cfg["box_shrink"], depth_range=tuple(cfg["depth_range"]), min_pixels=cfg["min_pixels"],
                    tolerance_px=cfg["tolerance_px"], near_support=cfg["near_support"],
                    centre_sigma=cfg["centre_sigma"], grow_density=cfg["grow_density"], seed=cfg["seed"],
                    classes=cfg["classes"] or None, concurrent=cfg["concurrent"])]
            _, rig, loc = current
            left, right = frame.left, frame.right
            if cfg["scale"] != 1.0:
                left, right = _scaled(left, right, original_rig, rig.image_size)
            result = loc(left, right)
            record = _frame_record(frame.name, frame.index, result, detector_name, cfg, rig)
            with _DeferInterrupt():
                _write_frame(outdir, frame.name, result, rig, cfg, record, jsonl)
            timings.append(result.timings_ms)
            n_done += 1
            n_objects += len(result.objects)
            table = result.objects.format_table()
            if sequence:
                text = f"[{frame.name}] " + ("; ".join(table.splitlines()) if table else "no objects")
            else:
                text = table if table else ("no objects found" if detector is not None else "depth only (no detector)")
            tqdm.write(text, file=sys.stdout)
            bar.update(1)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        bar.close()
        if current:
            current[-1].close()
    if isinstance(source, SideBySideSource) and source.stopped_early and not interrupted:
        log.warning("%s stopped delivering frames after %d frame(s); finishing", source.what, source.frames_read)
    if timings and not quiet:
        print(format_timings(timings), file=sys.stderr)
    summary = f"{n_done} frame(s), {n_objects} object(s), outputs in {outdir}"
    if n_skipped:
        summary += f"; {n_skipped} finished frame(s) skipped (--resume)"
    if interrupted:
        print(f"interrupted: {summary}; the frame in progress was not written, rerun with --resume to continue",
              file=sys.stderr)
        return 130
    log.info(summary)
    return 0


def _scaled(left: np.ndarray, right: np.ndarray, rig: Any, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Rectify with the full-size rig (when it has maps), then resize both images to ``size`` (w, h)."""
    import cv2

    expected = tuple(int(v) for v in rig.image_size)
    if (left.shape[1], left.shape[0]) != expected or left.shape != right.shape:
        raise ValueError(f"the calibration is for {expected[0]}x{expected[1]} images but the images are "
                         f"{left.shape[1]}x{left.shape[0]} and {right.shape[1]}x{right.shape[0]}")
    if getattr(rig, "has_maps", False):
        left, right = rig.rectify_pair(left, right)
    size = (int(size[0]), int(size[1]))
    interp = cv2.INTER_AREA if size[0] < left.shape[1] else cv2.INTER_LINEAR
    return cv2.resize(left, size, interpolation=interp), cv2.resize(right, size, interpolation=interp)
