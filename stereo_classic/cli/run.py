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
import os
import sys
import time
from contextlib import ExitStack
from functools import partial
from pathlib import Path
from typing import Any

from tqdm import tqdm

import calib
from detectors import ModelNotFoundError, OnnxDetector, resolve_model
from stereo_classic import sources
from stereo_classic.cli.config import (
    FUSION_OPTIONS,
    INPUT_OPTIONS,
    RUN_DEFAULTS,
    ConfigError,
    dump_config,
    load_config,
    merge_config,
)
from stereo_classic.cli.errors import UsageError
from stereo_classic.cli.inputs import Source, add_input_options, open_source
from stereo_classic.cli.options import CLI_NUM_DISPARITIES, add_options, read_options
from stereo_classic.cli.paths import check_output_dir
from stereo_classic.fusion import FusionInputError, FusionParams, as_generator
from stereo_classic.fusion.objects import TABLE_COLUMNS
from stereo_classic.matching import SGMParams
from stereo_classic.outputs import (
    DEFAULT_SAVE,
    SAVE_KINDS,
    FrameWriter,
    OutputFolder,
    SettingsMismatchError,
)
from stereo_classic.pipeline import (PipelineResult, format_rate, format_timings, load_frame_kernels,
                                     open_detector)
from stereo_classic.runner import ON_ERROR, DetectorSpec, RunSummary, run_source

#: Where frames can be processed (``--executor``).
EXECUTORS = ("serial", "dask")

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
                     help=f"comma-separated outputs among {','.join(SAVE_KINDS)},mcap "
                          f"(default: {','.join(DEFAULT_SAVE)}; dense, the filled disparity, confidence, ply and mcap "
                          "(results.mcap, a ROS 2 recording) only when named; --ply adds the point cloud to any list)")
    out.add_argument("--ply", action=argparse.BooleanOptionalAction, default=None,
                     help="also write a coloured PLY point cloud")
    out.add_argument("--resume", action="store_true", help="skip frames whose outputs are all present")
    out.add_argument("--no-progress", action="store_true",
                     help="no progress bar (it is off anyway when stderr is not a terminal)")

    add_pipeline_options(p)

    run = p.add_argument_group("run")
    run.add_argument("--threads", type=int, default=None, metavar="N",
                     help="threads for the matcher and the detector (default: all for the matcher, 1 for the "
                          "detector)")
    run.add_argument("--concurrent", action=argparse.BooleanOptionalAction, default=None,
                     help="run the detector in a thread beside the matcher (default off; the pipelined run, the "
                          "default, does so anyway)")
    run.add_argument("--read-ahead", action=argparse.BooleanOptionalAction, default=None,
                     help="read and decode the next frame in a thread while one is processed (default off: no "
                          "measurable gain beside the pipeline on 2 cores; same output either way)")
    run.add_argument("--pipeline", action=argparse.BooleanOptionalAction, default=None,
                     help="detect, localize and check each frame in a worker thread while the next frame is read "
                          "and matched (default on; same output either way)")
    run.add_argument("--on-error", choices=ON_ERROR, default=None,
                     help="a frame that cannot be read or processed: stop the run (default) or skip it, "
                          "naming it in the summary")
    run.add_argument("--executor", choices=EXECUTORS, default=None,
                     help="where frames are processed: here (serial, default) or on a Dask cluster "
                          "(needs the dask extra; see docs/scale.md)")
    run.add_argument("--scheduler", default=None, metavar="ADDRESS",
                     help="with --executor dask: tcp://host:8786 or a scheduler file of a running cluster "
                          "(default: start a local cluster)")
    run.add_argument("--config", metavar="FILE.toml", help="read options from a TOML file (flags win)")
    run.add_argument("--dump-config", action="store_true", help="print the merged options as TOML and exit")
    p.set_defaults(func=func)
    return p


#: ``--square-input``'s help (``run``, ``guide`` and ``ros``).
SQUARE_INPUT_HELP = ("letterbox each frame into the detector's full square input, as exported (default: the smallest "
                     "multiple-of-32 rectangle around the frame, the same scale and a third of the work on a KITTI "
                     "frame; models that run at their own size only get the square anyway)")


def add_pipeline_options(p: Any) -> None:
    """Register the detector, fusion and matcher option groups (shared by ``run`` and ``guide``)."""
    det = p.add_argument_group("detector")
    det.add_argument("--model", default=None, metavar="NAME|PATH",
                     help="ONNX detector name or path, or 'none' (default: yolox_nano)")
    det.add_argument("--conf", type=float, default=None, help="confidence threshold (default 0.3)")
    det.add_argument("--iou", type=float, default=None, help="NMS IoU threshold (default 0.45)")
    det.add_argument("--classes", nargs="+", default=None, metavar="LIST",
                     help="comma-separated class names to keep (e.g. car,person; spaces work too)")
    det.add_argument("--square-input", action=argparse.BooleanOptionalAction, default=None, help=SQUARE_INPUT_HELP)

    fus = p.add_argument_group("fusion")
    add_options(fus, FusionParams, show_defaults=FusionParams())
    fus.add_argument("--seed", type=int, default=None, help="RANSAC seed (default 0)")

    mat = p.add_argument_group("matcher (the same options as the disparity command; default: SGMParams')")
    add_options(mat, SGMParams, dest_prefix="matcher_", help_overrides={
        "num_disparities": f"disparities searched (default: the scene's range, else {CLI_NUM_DISPARITIES})"})


# --------------------------------------------------------------------------------------------------
# options
# --------------------------------------------------------------------------------------------------
def _options(args: argparse.Namespace) -> dict[str, Any]:
    """Defaults < config file < flags, checked; ``cfg["fusion"]`` is the FusionParams built from them."""
    flags = {k: getattr(args, k, None) for k in RUN_DEFAULTS}
    if not flags.get("rectify"):  # a store_true switch: absent is "not given", so the config file may set it
        flags["rectify"] = None
    matcher_flags = read_options(args, SGMParams, dest_prefix="matcher_", given_only=True)
    try:
        file_cfg = load_config(args.config) if args.config else None
        cfg = merge_config(file_cfg, flags, matcher_flags)
    except ConfigError as exc:
        raise UsageError(str(exc)) from None
    if cfg["max_frames"] < 0:  # the merged value: a flag or the config file
        raise UsageError(f"`max_frames` (--max-frames) must be >= 0 (0 = all), got {cfg['max_frames']}")
    bad = [s for s in cfg["save"] if s not in SAVE_KINDS and s != "mcap"]  # mcap: one file (outputs/mcap.py)
    if bad:
        raise UsageError(f"--save: unknown output {bad[0]!r}; choose among {', '.join(SAVE_KINDS)}, mcap")
    if "mcap" in cfg["save"]:
        from stereo_classic.ros import MissingDependencyError, require
        try:
            require("mcap_ros2.writer", "--save mcap (writing an MCAP recording)")
        except MissingDependencyError as exc:
            raise UsageError(str(exc)) from None
    if "mcap" in cfg["save"] and args.resume:
        raise UsageError("--save mcap writes one recording per run: it cannot be resumed (run again without --resume)")
    if cfg["threads"] < 0:
        raise UsageError(f"--threads must be >= 1 (0 = all), got {cfg['threads']}")
    if cfg["on_error"] not in ON_ERROR:
        raise UsageError(f"`on_error` (--on-error) must be one of {', '.join(ON_ERROR)}, got {cfg['on_error']!r}")
    if cfg["executor"] not in EXECUTORS:
        raise UsageError(f"`executor` (--executor) must be one of {', '.join(EXECUTORS)}, got {cfg['executor']!r}")
    if cfg["scheduler"] and cfg["executor"] != "dask":
        raise UsageError("--scheduler goes with --executor dask")
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
            fields["num_disparities"] = CLI_NUM_DISPARITIES
    if cfg["threads"] > 0:
        fields["threads"] = cfg["threads"]
    try:
        return SGMParams(**fields)
    except (TypeError, ValueError) as exc:
        raise UsageError(f"matcher: {exc}") from None


#: The detector's threads when --threads is not given (see _open_detector).
DETECTOR_THREADS = 1


def _open_detector(cfg: dict[str, Any]) -> tuple[OnnxDetector | None, str | None]:
    if str(cfg["model"]).lower() in ("none", "off", ""):
        return None, None
    try:
        path = resolve_model(cfg["model"])
    except ModelNotFoundError as exc:
        hint = str(exc).splitlines()[0]
        if cfg["model"] != RUN_DEFAULTS["model"][0]:  # a model the user named: a usage error, never a quiet fallback
            raise UsageError(f"--model {cfg['model']}: {hint} (--model none computes depth only)") from None
        if "python -m detectors fetch" not in hint:
            hint += "; `python -m detectors fetch` downloads the official models"
        log.warning("no detector, computing depth only: %s", hint)
        return None, None
    kwargs: dict[str, Any] = {"conf_threshold": cfg["conf"], "iou_threshold": cfg["iou"]}
    # One detector thread unless --threads says otherwise: on 2 cores a second one ran it no faster (12.0 against
    # 12.1 ms a KITTI frame, alternated) for 5 ms more CPU, and the pipelined run has it beside the matcher.
    kwargs["threads"] = cfg["threads"] if cfg["threads"] > 0 else DETECTOR_THREADS
    # a corrupt model raises ModelError: runtime failure (exit 1)
    detector = open_detector(path, square_input=bool(cfg.get("square_input")), **kwargs)
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
    for key in INPUT_OPTIONS:  # the input as merged (flags over the config file) is the input of the run
        setattr(args, key, cfg[key])
    check_output_dir(cfg["output"], "-o/--output")  # before the input is opened (a dataset scan takes time)
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
    writer: Any = FrameWriter(outdir, save=[k for k in cfg["save"] if k != "mcap"], ply=cfg["ply"],
                              depth_range=fusion.depth_range, sequence=sequence, resume=args.resume)
    detector, detector_name = _open_detector(cfg)
    quiet = getattr(args, "quiet", False)

    header_shown = []
    flagged: dict[str, list[str]] = {}  # warning code -> frames (the Localizer logs each kind once)

    def show(frame: sources.Frame, result: PipelineResult) -> None:
        for warning in getattr(result, "warnings", ()):
            flagged.setdefault(warning.code, []).append(frame.name)
        table = result.objects.format_table(header=not sequence)
        if sequence:
            if not header_shown and detector is not None:  # the columns, once: "[frame] label confidence ..."
                tqdm.write("[frame] " + "  ".join(TABLE_COLUMNS), file=sys.stdout)
                header_shown.append(True)
            text = f"[{frame.name}] " + ("; ".join(table.splitlines()) if table else "no objects")
        else:
            text = table if table else ("no objects found" if detector is not None else "depth only (no detector)")
        tqdm.write(text, file=sys.stdout)

    settings = _run_settings(args, cfg, detector_name, sorted(writer.kinds), sequence)
    with ExitStack() as stack:
        try:  # one run per folder; its settings recorded; a resume must match them
            stack.enter_context(OutputFolder(outdir, settings, resume=args.resume,
                                             outputs=[SAVE_KINDS[k] for k in sorted(writer.kinds)]))
        except SettingsMismatchError as exc:
            raise UsageError(str(exc)) from None
        executor = None
        if cfg["executor"] == "dask":
            executor = stack.enter_context(_dask_executor(cfg, quiet))
            if detector is not None:  # each worker opens its own, once
                detector = DetectorSpec(str(resolve_model(cfg["model"])), cfg["conf"], cfg["iou"],
                                        square_input=bool(cfg["square_input"]))
        if "mcap" in cfg["save"]:  # the results as one ROS 2 recording (the bag extra)
            writer = _mcap_writer(writer, outdir)
            stack.callback(writer.close)
        if executor is None:  # the matcher's compiled code loaded before the first frame, not while it waits
            # the first frame's settings: a scene's own range when the source knows it (the demo, a dataset)
            load_frame_kernels(_matcher_params(cfg, getattr(source, "first_max_disparity", None)))
        started = time.perf_counter()
        summary = run_source(
            source, writer, params_for=partial(_matcher_params, cfg), rig=base_rig,
            detector=detector, detector_name=detector_name, fusion=fusion, seed=cfg["seed"],
            classes=cfg["classes"] or None, concurrent=cfg["concurrent"], scale=cfg["scale"],
            progress=not (quiet or args.no_progress) and sys.stderr.isatty(), on_frame=show,
            on_error=cfg["on_error"], executor=executor, read_ahead=cfg["read_ahead"],
            pipeline=cfg["pipeline"])
        wall = time.perf_counter() - started
    first = None if summary.first_written is None else summary.first_written - started
    return _report(summary, source, outdir, quiet, wall, flagged, first)


def _mcap_writer(writer: FrameWriter, outdir: Path) -> Any:
    from stereo_classic.outputs.mcap import MCAP_NAME, McapFrameWriter
    from stereo_classic.ros import MissingDependencyError

    try:
        return McapFrameWriter(writer, outdir / MCAP_NAME)
    except MissingDependencyError as exc:
        raise UsageError(str(exc)) from None


def _input_settings(args: argparse.Namespace) -> dict[str, Any]:
    """The input of a run as recorded in its folder (absolute paths; --max-frames is not part of it)."""
    def absolute(path: str | None) -> str | None:
        return None if path is None else os.path.abspath(path)

    if args.left is not None:
        return {"left": [absolute(p) for p in args.left], "right": [absolute(p) for p in args.right or []],
                "calib": absolute(args.calib), "rectify": bool(args.rectify)}
    if args.dataset is not None:
        return {"dataset": absolute(args.dataset)}
    if args.video is not None:
        return {"video": absolute(args.video), "calib": absolute(args.calib), "rectify": bool(args.rectify)}
    if getattr(args, "bag", None) is not None:
        return {"bag": absolute(args.bag), **{k: getattr(args, k) for k in (
            "left_topic", "right_topic", "left_info_topic", "right_info_topic", "stamp_tolerance")},
            "calib": absolute(args.calib), "rectify": bool(args.rectify)}
    if args.camera is not None:
        return {"camera": args.camera, "calib": absolute(args.calib), "rectify": bool(args.rectify)}
    return {"demo": True}


def _run_settings(args: argparse.Namespace, cfg: dict[str, Any], detector_name: str | None, kinds: list[str],
                  sequence: bool) -> dict[str, Any]:
    """What decides the files of a run (recorded in ``run.json``; ``--resume`` must match): not threads, executor,
    --on-error, --max-frames or progress, which change how, not what."""
    detector = ({"model": detector_name, "conf": cfg["conf"], "iou": cfg["iou"], "square_input": cfg["square_input"]}
                if detector_name else {"model": None})
    return {"input": _input_settings(args), "outputs": kinds, "sequence": sequence, **detector,
            "classes": list(cfg["classes"]), **{k: cfg[k] for k in FUSION_OPTIONS}, "seed": cfg["seed"],
            "scale": cfg["scale"], "matcher": {k: v for k, v in cfg["matcher"].items()
                                               if k not in ("threads", "memory_limit")}}


def _dask_executor(cfg: dict[str, Any], quiet: bool) -> Any:
    try:
        from stereo_classic.cluster import DaskExecutor, DaskNotInstalledError
    except ImportError as exc:  # pragma: no cover - the module itself imports no dask
        raise UsageError(str(exc)) from None
    try:
        return DaskExecutor(cfg["scheduler"] or None,
                            on_dashboard=None if quiet else lambda link: print(f"Dask dashboard: {link}",
                                                                               file=sys.stderr))
    except DaskNotInstalledError as exc:
        raise UsageError(str(exc)) from None


def _report(summary: RunSummary, source: Source, outdir: Path, quiet: bool, wall: float,
            flagged: dict[str, list[str]] | None = None, first: float | None = None) -> int:
    """The end of a run: warnings, the timing table (per worker for Dask), the summary line, the exit code.

    ``flagged`` maps the frame checks' warning codes to the frames they came from: frames whose pair is swapped
    or mismatched measured nothing (exit code 1); disparities piled at the end of the range are named.
    """
    flagged = flagged or {}
    if isinstance(source, sources.SideBySideSource) and source.stopped_early and not summary.interrupted:
        log.warning("%s stopped delivering frames after %d frame(s); finishing", source.what, source.frames_read)
    if summary.timings_ms and not quiet:
        print(format_timings(summary.timings_ms, rate=wall <= 0), file=sys.stderr)
        for address, (frames, busy) in sorted(summary.workers.items()):
            print(f"worker {address}: {int(frames)} frame(s), {frames / busy if busy else 0:.2f} frames/s busy, "
                  f"{busy:.1f} s", file=sys.stderr)
        if wall > 0:
            print(format_rate(summary.frames, wall, first, "reading, matching, detecting, checking, writing"),
                  file=sys.stderr)
    text = f"{summary.frames} frame(s), {summary.objects} object(s), outputs in {outdir}"
    if summary.skipped:
        text += f"; {summary.skipped} finished frame(s) skipped (--resume)"
    unpaired = getattr(source, "unpaired", None)  # a recording's messages without a partner (BagSource)
    if unpaired and any(unpaired.values()):
        text += (f"; {sum(len(v) for v in unpaired.values())} image message(s) without a partner not used: "
                 + source.unpaired_text())
    if summary.skipped_scenes:
        text += f"; {len(summary.skipped_scenes)} scene(s) not measured (no calibration, named above)"
    if summary.failed:
        text += f"; {len(summary.failed)} frame(s) FAILED and skipped (--on-error skip): " + ", ".join(
            name for name, _ in summary.failed[:10]) + (", ..." if len(summary.failed) > 10 else "")
    if summary.interrupted:
        what = "terminated (SIGTERM)" if summary.signal == "SIGTERM" else "interrupted"
        print(f"{what}: {text}; the frame in progress was not written, rerun with --resume to continue",
              file=sys.stderr)
        return 143 if summary.signal == "SIGTERM" else 130
    bad_pair = sorted(set(flagged.get("swapped_pair", []) + flagged.get("pair_mismatch", [])))
    if flagged.get("range_saturated"):
        frames = flagged["range_saturated"]
        log.warning("%d frame(s) had disparities piled at the end of the range (objects there marked beyond_range; "
                    "the warning above says which --num-disparities fits): %s", len(frames),
                    ", ".join(frames[:10]) + (", ..." if len(frames) > 10 else ""))
    if bad_pair:
        text += (f"; {len(bad_pair)} frame(s) NOT MEASURED: left/right swapped or not a pair (objects marked "
                 f"pair_mismatch): " + ", ".join(bad_pair[:10]) + (", ..." if len(bad_pair) > 10 else ""))
    if summary.failed or bad_pair:
        log.error("%s", text)
        return 1
    if summary.frames == 0 and summary.skipped == 0 and summary.skipped_scenes:
        log.error("no frame could be measured: %s", text)
        return 1
    log.info(text)
    return 0
