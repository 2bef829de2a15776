"""``python -m stereo_classic guide``: say what is ahead of a walking person, frame after frame.

Takes every input ``run`` takes (``--left/--right`` files or globs in order as a sequence at ``--fps``,
``--dataset``, ``--video``, ``--camera``; none = the demo scene) and the same detector, fusion and matcher
options, runs the pipeline and :class:`stereo_classic.guide.Guide` on each frame, and writes into the output
folder (default ``guide_out``):

* ``events.jsonl``: one JSON object per event (kind ``object``, ``obstacle``, ``drop_off``, ``clear_path``) and
  one ``haptics`` line per frame; each line is written whole and flushed to disk before the next frame;
* with ``--save overlay,birdseye``: ``NAME_overlay.png`` and ``NAME_birdseye.png`` per frame;
* with ``--speak-to DIR``: each spoken message as a WAV file in DIR.

``--speak`` speaks the messages with an offline engine (espeak-ng or pyttsx3; without one a line says what to
install and the run goes on). Dataset scenes and a single pair are separate scenes (the guide starts afresh for
each); pairs, a video and a camera are one sequence in time.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from concurrent.futures import Future
from pathlib import Path
from typing import Any

import cv2
from tqdm import tqdm

import calib
from stereo_classic import io, sources
from stereo_classic.cli import run as run_command
from stereo_classic.cli.errors import UsageError
from stereo_classic.cli.inputs import Source, add_input_options, open_source
from stereo_classic.cli.options import add_options, option_names, read_options
from stereo_classic.guide import Guide, GuideInputError, GuideParams
from stereo_classic.guide.render import draw_birdseye, draw_overlay
from stereo_classic.guide.speech import Speaker
from stereo_classic.outputs.files import JsonlSink
from stereo_classic.pipeline import Localizer, format_rate, format_timings, load_frame_kernels
from stereo_classic.runner import in_order, scale_pair

__all__ = ["EVENTS_NAME", "GUIDE_SAVE", "add_parser", "func"]

log = logging.getLogger("stereo_classic.guide")

#: Pictures ``--save`` can name.
GUIDE_SAVE: tuple[str, ...] = ("overlay", "birdseye")
#: The events file in the output folder.
EVENTS_NAME = "events.jsonl"
_DEFAULT_FPS = 10.0


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Register the ``guide`` sub-command."""
    p = subparsers.add_parser(
        "guide", help="say what is ahead of a walking person: objects, obstacles, drop-offs, a clear path",
        description="The pipeline over a sequence of frames, then the guide: the ground, obstacles in the walking "
                    "corridor, drop-offs, tracked objects with approach speed, the clear path; events in "
                    "OUTPUT/events.jsonl, optionally spoken. See docs/guide.md.")
    add_input_options(p)
    out = p.add_argument_group("output")
    out.add_argument("-o", "--output", default=None, metavar="DIR", help="output folder (default: guide_out)")
    out.add_argument("--save", dest="guide_save", default="", metavar="LIST",
                     help=f"comma-separated pictures among {','.join(GUIDE_SAVE)}, and mcap (results.mcap: the "
                          "results and events as ROS 2 messages, docs/ros.md) (default: none)")
    out.add_argument("--fps", type=float, default=None, metavar="F",
                     help=f"frames per second of an image sequence (default: the video's, else {_DEFAULT_FPS:g})")
    out.add_argument("--speak", action="store_true", help="speak the messages (offline: espeak-ng or pyttsx3)")
    out.add_argument("--speak-to", default=None, metavar="DIR", help="write each spoken message as a WAV file")
    out.add_argument("--no-progress", action="store_true", help="no progress bar")
    guide = p.add_argument_group("guide")
    add_options(guide, GuideParams, show_defaults=GuideParams())
    run_command.add_pipeline_options(p)
    more = p.add_argument_group("run")
    more.add_argument("--threads", type=int, default=None, metavar="N",
                      help="threads for the matcher and the detector (default: all for the matcher, 1 for the "
                           "detector)")
    more.add_argument("--concurrent", action=argparse.BooleanOptionalAction, default=None,
                      help="run the detector in a thread beside the matcher")
    more.add_argument("--pipeline", action=argparse.BooleanOptionalAction, default=None,
                      help="detect, localize and check each frame in a worker thread while the next frame is read "
                           "and matched (default on, not for a live camera; same events either way)")
    more.add_argument("--config", metavar="FILE.toml", help="read the run options from a TOML file (flags win)")
    p.set_defaults(func=func, save=None, ply=None)
    return p


def _guide_params(args: argparse.Namespace) -> GuideParams:
    given = {k: v for k, v in read_options(args, GuideParams).items() if v is not None}
    try:
        return GuideParams(**given)
    except GuideInputError as exc:
        raise UsageError(option_names(str(exc), GuideParams)) from None


def _save_kinds(text: str) -> list[str]:
    kinds = [s.strip() for s in (text or "").split(",") if s.strip()]
    bad = [k for k in kinds if k not in GUIDE_SAVE and k != "mcap"]  # mcap: results.mcap (docs/ros.md)
    if bad:
        raise UsageError(f"--save: unknown picture {bad[0]!r}; choose among {', '.join(GUIDE_SAVE)}, mcap")
    return kinds


def func(args: argparse.Namespace) -> int:
    """Run the guide over the chosen input; see the module docstring."""
    cfg = run_command._options(args)
    params = _guide_params(args)
    kinds = _save_kinds(args.guide_save)
    if args.fps is not None and not (0 < args.fps <= 1000):
        raise UsageError(f"--fps must be in (0, 1000], got {args.fps}")
    outdir = Path(args.output or "guide_out")
    if outdir.exists() and not outdir.is_dir():
        raise UsageError(f"-o/--output {outdir} exists and is not a folder")
    source, base_rig = open_source(args, cfg["max_frames"] or None)
    try:
        return _run(args, cfg, params, kinds, outdir, source, base_rig)
    finally:
        source.close()


def _fps(args: argparse.Namespace, source: Source) -> float:
    if args.fps is not None:
        return float(args.fps)
    if isinstance(source, sources.SideBySideSource) and not source.is_camera:
        fps = float(source.cap.get(cv2.CAP_PROP_FPS) or 0.0)
        if 0 < fps <= 1000:
            return fps
    if isinstance(source, sources.PairSource) and len(source) > 1:
        log.info("an image sequence without --fps: assuming %g frames per second", _DEFAULT_FPS)
    return _DEFAULT_FPS


def _mcap_sink(outdir: Path) -> Any:
    from stereo_classic.outputs.mcap import MCAP_NAME, McapSink
    from stereo_classic.ros import MissingDependencyError

    try:
        return McapSink(outdir / MCAP_NAME)
    except MissingDependencyError as exc:
        raise UsageError(str(exc)) from None


def _done(result: Any) -> Future:
    """A future already holding ``result`` (a frame processed in turn, handed on as a started one is)."""
    future: Future = Future()
    future.set_result(result)
    return future


def mcap_stamp(record: dict[str, Any]) -> int:
    from stereo_classic.outputs.mcap import frame_stamp_ns

    return frame_stamp_ns(record)


def _run(args: argparse.Namespace, cfg: dict[str, Any], params: GuideParams, kinds: list[str], outdir: Path,
         source: Source, base_rig: calib.RectifiedRig | None) -> int:
    detector, _ = run_command._open_detector(cfg)
    quiet = getattr(args, "quiet", False)
    separate = isinstance(source, sources.SceneSource) or len(source) == 1   # scenes are not a walk
    live = isinstance(source, sources.SideBySideSource) and source.is_camera
    fps = _fps(args, source)
    outdir.mkdir(parents=True, exist_ok=True)
    sink = JsonlSink(outdir / EVENTS_NAME)
    speaker = Speaker(speak=args.speak, wav_dir=args.speak_to)
    guide = Guide(params)
    mcap = _mcap_sink(outdir) if "mcap" in kinds else None
    kinds = [k for k in kinds if k != "mcap"]
    current: list[Any] = []          # [original rig, rig of the images matched, Localizer]
    timings: list[dict[str, float]] = []
    frames = events = 0
    # before the first frame, not while it waits; its settings: a scene's own range when the source knows it (the
    # demo, a dataset)
    load_frame_kernels(run_command._matcher_params(cfg, getattr(source, "first_max_disparity", None)))
    start = time.monotonic()
    first_done: float | None = None  # when the first frame was guided
    bar = tqdm(total=len(source) or None, unit="frame", file=sys.stderr, leave=False,
               disable=quiet or args.no_progress or not sys.stderr.isatty())
    interrupted = False
    # Pipelined (files and video, not a live camera, whose frame would be told a match later): frame N's
    # detection, fusion and checks run in the Localizer's worker while frame N + 1 is read and matched here, and
    # frame N is guided (in order, here) once frame N + 1's match is done; the same events as in turn.
    pipelined = bool(cfg["pipeline"]) and not live

    def guided(frame: Any, rig: calib.RectifiedRig, future: Any) -> None:
        nonlocal frames, events, first_done
        try:
            result = future.result()
        except ValueError as exc:
            raise ValueError(f"frame {frame.name}: {exc}") from None
        if separate:
            guide.reset()
        t = time.monotonic() - start if live else (0.0 if separate else frame.index / fps)
        if not separate and frame.source and "time_s" in frame.source:  # a recording: its stamps
            t = float(frame.source["time_s"])
        t0 = time.perf_counter()
        gframe = guide.update(result, rig, t, frame=frame.name)
        guide_ms = (time.perf_counter() - t0) * 1e3
        for event in gframe.events:
            sink.append(event.to_dict())
            tqdm.write(f"[{frame.name}] {event.priority}: {event.text}", file=sys.stdout)
            speaker(event)
        sink.append(gframe.haptics_record())
        if mcap is not None:  # the frame's results and its events as ROS 2 messages
            record = {"frame": frame.name, "index": frame.index, "source": frame.source,
                      "objects": result.objects.to_json()}
            mcap.write_frame(result, rig, record)
            mcap.write_events([e.to_dict() for e in gframe.events], mcap_stamp(record))
        for kind in kinds:
            picture = (draw_overlay(result.left, gframe, rig, params) if kind == "overlay"
                       else draw_birdseye(gframe, params))
            io.write_image(outdir / f"{frame.name}_{kind}.png", picture)
        timings.append({**result.timings_ms, "guide": guide_ms})
        frames += 1
        if first_done is None:
            first_done = time.monotonic()
        events += len(gframe.events)
        bar.update(1)

    def begin(frame: Any) -> tuple[Any, calib.RectifiedRig, Future]:
        original = frame.rig if frame.rig is not None else base_rig
        if original is None:
            raise ValueError(f"frame {frame.name}: no calibration")
        if not current or current[0] is not original:
            if current:
                current.pop().close()  # (waits for its worker: a frame started there stays readable)
            rig = original
            if cfg["scale"] != 1.0:
                rig = (rig.without_maps() if rig.has_maps else rig).scaled(cfg["scale"])
            current[:] = [original, rig, Localizer(
                rig, detector, run_command._matcher_params(cfg, frame.max_disparity), fusion=cfg["fusion"],
                seed=cfg["seed"], classes=cfg["classes"] or None, concurrent=cfg["concurrent"])]
        _, rig, loc = current
        left, right = frame.left, frame.right
        try:
            if cfg["scale"] != 1.0:
                left, right = scale_pair(left, right, original, rig.image_size)
            return frame, rig, loc.submit(left, right) if pipelined else _done(loc(left, right))
        except ValueError as exc:
            raise ValueError(f"frame {frame.name}: {exc}") from None

    try:
        # a failure or Ctrl-C while a frame starts: the frame before is guided first, as guiding in turn would have
        in_order(source.frames(), begin, lambda started: guided(*started), overlap=pipelined)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        bar.close()
        speaker.close()
        if mcap is not None:
            mcap.close()
        if current:
            current[-1].close()
    wall = time.monotonic() - start
    if timings and not quiet:
        print(format_timings(timings, rate=False), file=sys.stderr)
        print(format_rate(frames, wall, None if first_done is None else first_done - start,
                          "reading, matching, detecting, checking, guiding, writing"), file=sys.stderr)
    text = f"{frames} frame(s), {events} event(s), events in {outdir / EVENTS_NAME}"
    if speaker.written:
        text += f", {len(speaker.written)} WAV file(s) in {args.speak_to}"
    if interrupted:
        print(f"interrupted: {text}", file=sys.stderr)
        return 130
    if isinstance(source, sources.SideBySideSource) and source.stopped_early:
        what = source.what
        if live:
            print(f"error: {what} stopped delivering frames after {frames} frame(s): the guide stopped; {text}",
                  file=sys.stderr)
            return 1
        log.warning("%s stopped delivering frames after %d frame(s); finishing", what, frames)
    log.info(text)
    return 0
