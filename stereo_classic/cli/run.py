"""``python -m stereo_classic run``: the whole pipeline from the command line.

With no arguments it runs the built-in demo scene (Middlebury Motorcycle from scikit-image) with the
default detector, prints one line per object and writes every output into ``./stereo_out``. This module
parses the options, opens the input, the rig and the detector, and calls :func:`stereo_classic.runner.run_source`,
which runs the pipeline per frame and writes with a :class:`stereo_classic.outputs.FrameWriter` (``--save``
chooses the files, ``--ply`` adds the point cloud). Ctrl-C finishes nothing half: the frame in progress leaves
no file, finished frames are complete, and ``--resume`` skips them.
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
from pathlib import Path
from typing import Any

from tqdm import tqdm

import calib
from detectors import ModelNotFoundError, OnnxDetector, resolve_model
from stereo_classic import sources
from stereo_classic.cli.config import (
    FUSION_OPTIONS,
    RUN_DEFAULTS,
    ConfigError,
    dump_config,
    load_config,
    merge_config,
)
from stereo_classic.cli.errors import UsageError
from stereo_classic.cli.inputs import Source, add_input_options, open_source
from stereo_classic.cli.options import add_options, read_options
from stereo_classic.fusion import FusionInputError, FusionParams, as_generator
from stereo_classic.fusion.objects import TABLE_COLUMNS
from stereo_classic.matching import SGMParams
from stereo_classic.outputs import SAVE_KINDS, FrameWriter
from stereo_classic.pipeline import PipelineResult, format_timings
from stereo_classic.runner import run_source

__all__ = ["add_parser", "func"]

log = logging.getLogger("stereo_classic.run")


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Register the ``run`` sub-command."""
    p = subparsers.add_parser(
        "run", help="detect objects and say how far away each one is (default: the demo scene)",
        description="Stereo depth + object detection + per-object distance. With no input options the "
                    "built-in demo scene (Middlebury Motorcycle) is used. Options may also come from "
                    "--config FILE.toml (flags win).")
    add_input_options(p)

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
    add_options(fus, FusionParams, show_defaults=FusionParams())
    fus.add_argument("--seed", type=int, default=None, help="RANSAC seed (default 0)")

    mat = p.add_argument_group("matcher (the same options as the disparity command; default: SGMParams')")
    add_options(mat, SGMParams, dest_prefix="matcher_", help_overrides={
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
    """Defaults < config file < flags, checked; ``cfg["fusion"]`` is the FusionParams built from them."""
    flags = {k: getattr(args, k, None) for k in RUN_DEFAULTS}
    matcher_flags = read_options(args, SGMParams, dest_prefix="matcher_")
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
    if cfg["threads"] < 0:
        raise UsageError(f"--threads must be >= 1 (0 = all), got {cfg['threads']}")
    if not (0 < cfg["scale"] <= 4):
        raise UsageError(f"--scale must be in (0, 4], got {cfg['scale']}")
    for key in ("conf", "iou"):
        if not (0.0 <= cfg[key] <= 1.0):
            raise UsageError(f"--{key} must be between 0 and 1, got {cfg[key]}")
    try:  # check the fusion options and the seed before any work
        as_generator(cfg["seed"], name="seed")
        cfg["fusion"] = FusionParams(**{k: cfg[k] for k in FUSION_OPTIONS})
    except FusionInputError as exc:
        raise UsageError(str(exc)) from None
    return cfg


def _matcher_params(cfg: dict[str, Any], max_disparity: int | None) -> SGMParams:
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


def _open_detector(cfg: dict[str, Any]) -> tuple[OnnxDetector | None, str | None]:
    if str(cfg["model"]).lower() in ("none", "off", ""):
        return None, None
    try:
        path = resolve_model(cfg["model"])
    except ModelNotFoundError as exc:
        hint = str(exc).splitlines()[0]
        if "python -m detectors fetch" not in hint:
            hint += "; `python -m detectors fetch` downloads the official models"
        log.warning("no detector, computing depth only: %s", hint)
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
# the command
# --------------------------------------------------------------------------------------------------
def func(args: argparse.Namespace) -> int:
    """Run the pipeline over the chosen input; see the module docstring."""
    cfg = _options(args)
    if args.dump_config:
        sys.stdout.write(dump_config(cfg))
        return 0
    source, base_rig = open_source(args, cfg["max_frames"] or None)
    try:
        return _run(args, cfg, source, base_rig)
    finally:
        source.close()


def _run(args: argparse.Namespace, cfg: dict[str, Any], source: Source, base_rig: calib.RectifiedRig | None) -> int:
    outdir = Path(cfg["output"])
    if outdir.exists() and not outdir.is_dir():
        raise UsageError(f"-o/--output {outdir} exists and is not a folder")
    names = source.names
    sequence = isinstance(source, sources.SideBySideSource) or (names is not None and len(names) != 1)
    fusion: FusionParams = cfg["fusion"]
    writer = FrameWriter(outdir, save=cfg["save"], ply=cfg["ply"], depth_range=fusion.depth_range,
                         sequence=sequence, resume=args.resume)
    detector, detector_name = _open_detector(cfg)
    quiet = getattr(args, "quiet", False)

    header_shown = []

    def show(frame: sources.Frame, result: PipelineResult) -> None:
        table = result.objects.format_table(header=not sequence)
        if sequence:
            if not header_shown and detector is not None:  # the columns, once: "[frame] label confidence ..."
                tqdm.write("[frame] " + "  ".join(TABLE_COLUMNS), file=sys.stdout)
                header_shown.append(True)
            text = f"[{frame.name}] " + ("; ".join(table.splitlines()) if table else "no objects")
        else:
            text = table if table else ("no objects found" if detector is not None else "depth only (no detector)")
        tqdm.write(text, file=sys.stdout)

    summary = run_source(
        source, writer, params_for=lambda max_disparity: _matcher_params(cfg, max_disparity), rig=base_rig,
        detector=detector, detector_name=detector_name, fusion=fusion, seed=cfg["seed"],
        classes=cfg["classes"] or None, concurrent=cfg["concurrent"], scale=cfg["scale"],
        progress=not (quiet or args.no_progress) and sys.stderr.isatty(), on_frame=show)
    if isinstance(source, sources.SideBySideSource) and source.stopped_early and not summary.interrupted:
        log.warning("%s stopped delivering frames after %d frame(s); finishing", source.what, source.frames_read)
    if summary.timings_ms and not quiet:
        print(format_timings(summary.timings_ms), file=sys.stderr)
    text = f"{summary.frames} frame(s), {summary.objects} object(s), outputs in {outdir}"
    if summary.skipped:
        text += f"; {summary.skipped} finished frame(s) skipped (--resume)"
    if summary.interrupted:
        print(f"interrupted: {text}; the frame in progress was not written, rerun with --resume to continue",
              file=sys.stderr)
        return 130
    log.info(text)
    return 0
