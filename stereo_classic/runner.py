"""Run the pipeline over a source of frames into an output folder: what ``python -m stereo_classic run`` does.

:func:`run_source` takes frames from a :mod:`stereo_classic.sources` source, keeps one
:class:`~stereo_classic.pipeline.Localizer` per rig (a dataset brings a rig per scene; the previous
Localizer's buffers are freed on a change), optionally scales the images, and hands every result to a
:class:`~stereo_classic.outputs.FrameWriter`. Frames are read one at a time, when processed (sources yield
:class:`~stereo_classic.sources.FrameRef` descriptions); with an ``executor`` (:mod:`stereo_classic.cluster`)
they are processed on a Dask cluster and still written here, in order. Ctrl-C and SIGTERM finish nothing half:
the frame in progress leaves no file, finished frames are complete (a writer with ``resume=True`` skips them
next time), and the :class:`RunSummary` says it was interrupted (and by which signal). ``on_error="skip"``
records a frame that fails and goes on.

Examples
--------
>>> import pathlib, tempfile
>>> from stereo_classic.sources import SceneSource
>>> from stereo_classic.outputs import FrameWriter
>>> with tempfile.TemporaryDirectory() as out:
...     summary = run_source(SceneSource.demo(), FrameWriter(out, save=("pfm", "json")),
...                          params_for=lambda max_disparity: SGMParams(num_disparities=80))
...     sorted(p.name for p in pathlib.Path(out).iterdir())
['motorcycle_skimage_disparity.pfm', 'motorcycle_skimage_objects.json']
>>> summary.frames, summary.objects, summary.interrupted
(1, 0, False)
"""

from __future__ import annotations

import dataclasses
import logging
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from typing import Any, Self

import cv2
import numpy as np
from tqdm import tqdm

from calib import RectifiedRig
from stereo_classic.fusion import FusionParams
from stereo_classic.matching import SGMParams
from stereo_classic.outputs import FrameWriter, frame_record
from stereo_classic.pipeline import Localizer, PipelineResult
from stereo_classic.sources import (
    Frame,
    FrameRef,
    PairSource,
    SceneSkipped,
    SceneSource,
    SideBySideSource,
)

__all__ = ["ON_ERROR", "DetectorSpec", "FrameOutput", "FrameProcessor", "RunSummary", "Terminated", "in_order",
           "run_source", "scale_pair"]

log = logging.getLogger("stereo_classic.run")

Source = PairSource | SceneSource | SideBySideSource


#: What ``on_error`` can be: "stop" (the first failing frame ends the run with its error) or "skip" (it is recorded
#: in :attr:`RunSummary.failed` and the run goes on).
ON_ERROR = ("stop", "skip")


class Terminated(KeyboardInterrupt):
    """SIGTERM (``timeout``, systemd, ``docker stop``) arrived: handled as Ctrl-C is, with its own exit code."""


@dataclass
class RunSummary:
    """What :func:`run_source` did.

    Attributes
    ----------
    frames, objects, skipped : int
        Frames processed and written, objects found in them, finished frames skipped (resume).
    interrupted : bool
        Ctrl-C (or SIGTERM) ended the run; the frame in progress was not written.
    signal : str or None
        "SIGINT" or "SIGTERM" when interrupted.
    timings_ms : list of dict
        ``PipelineResult.timings_ms`` of every processed frame.
    failed : list of (name, error)
        Frames that failed and were skipped (``on_error="skip"``).
    skipped_scenes : list of str
        Scenes read but not measured (no calibration), one line each.
    workers : dict
        Per worker (executor "dask"): ``{address: [frames, busy seconds]}``.
    first_written : float or None
        ``time.perf_counter()`` when the first frame was written (None: none was).
    """

    frames: int = 0
    objects: int = 0
    skipped: int = 0
    interrupted: bool = False
    signal: str | None = None
    timings_ms: list[dict[str, float]] = field(default_factory=list)
    failed: list[tuple[str, str]] = field(default_factory=list)
    skipped_scenes: list[str] = field(default_factory=list)
    workers: dict[str, list[float]] = field(default_factory=dict)
    first_written: float | None = None


def _raise_signal(signum: int) -> None:
    raise Terminated if signum == signal.SIGTERM else KeyboardInterrupt


class _DeferInterrupt:
    """Hold Ctrl-C and SIGTERM while one frame's files are written, then raise: a frame is all or nothing."""

    def __enter__(self) -> Self:
        self.received: int | None = None
        self.active = threading.current_thread() is threading.main_thread()
        if self.active:
            self.previous = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
            for s in self.previous:
                signal.signal(s, self._handler)
        return self

    def _handler(self, signum: int, frame: Any) -> None:
        self.received = signum

    def __exit__(self, *exc: object) -> None:
        if self.active:
            for s, handler in self.previous.items():
                signal.signal(s, handler)
            if self.received is not None and exc[0] is None:
                _raise_signal(self.received)


class _RunInterrupts:
    """For the length of a run (in the main thread): SIGTERM raises :class:`Terminated` (a KeyboardInterrupt), so it
    ends a run as Ctrl-C does (nothing half written, a summary, its own exit code 143), and both signals are also
    remembered. A KeyboardInterrupt is raised wherever the main thread happens to be, and where that is a finalizer
    (``__del__``, a file object's close at garbage collection) Python discards it; :meth:`check`, called between
    frames, raises it again, so Ctrl-C cannot be lost. SIGINT is only taken over from Python's own handler (an
    application's handler, or SIG_IGN, is left alone)."""

    def __enter__(self) -> Self:
        self.received: int | None = None
        self.active = threading.current_thread() is threading.main_thread()
        self.previous: dict[int, Any] = {}
        if self.active:
            self.previous[signal.SIGTERM] = signal.getsignal(signal.SIGTERM)
            if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
                self.previous[signal.SIGINT] = signal.default_int_handler
            for s in self.previous:
                signal.signal(s, self._handler)
        return self

    def _handler(self, signum: int, frame: Any) -> None:
        self.received = signum
        _raise_signal(signum)

    def check(self) -> None:
        """Raise the interrupt a signal of this run asked for, if one did (even if it was raised and discarded)."""
        if self.received is not None:
            _raise_signal(self.received)

    def __exit__(self, *exc: object) -> None:
        for s, handler in self.previous.items():
            signal.signal(s, handler)


@dataclass(frozen=True)
class DetectorSpec:
    """An ONNX detector described, not opened: what travels to a worker, which opens it once (``open()``)."""

    path: str
    conf: float = 0.3
    iou: float = 0.45
    threads: int | None = None
    square_input: bool = False

    def open(self, threads: int | None = None) -> Any:
        from stereo_classic.pipeline import open_detector

        return open_detector(self.path, square_input=self.square_input, conf_threshold=self.conf,
                             iou_threshold=self.iou, threads=threads or self.threads)


def scale_pair(left: np.ndarray, right: np.ndarray, rig: RectifiedRig, size: tuple[int, int]
               ) -> tuple[np.ndarray, np.ndarray]:
    """Rectify with the full-size ``rig`` (when it has maps), then resize both images to ``size`` (w, h).

    Raises
    ------
    ValueError
        The images are not of the rig's size (the message gives both).
    """
    expected = tuple(int(v) for v in rig.image_size)
    if (left.shape[1], left.shape[0]) != expected or left.shape != right.shape:
        raise ValueError(f"the calibration is for {expected[0]}x{expected[1]} images but the images are "
                         f"{left.shape[1]}x{left.shape[0]} and {right.shape[1]}x{right.shape[0]}")
    if rig.has_maps:
        left, right = rig.rectify_pair(left, right)
    size = (int(size[0]), int(size[1]))
    interp = cv2.INTER_AREA if size[0] < left.shape[1] else cv2.INTER_LINEAR
    return cv2.resize(left, size, interpolation=interp), cv2.resize(right, size, interpolation=interp)


@dataclass(frozen=True)
class FrameOutput:
    """One processed frame: what the writer needs (and, from a worker, who made it and in how long)."""

    index: int
    name: str
    result: PipelineResult | None = None
    rig: RectifiedRig | None = None
    record: dict[str, Any] | None = None
    error: str | None = None
    skipped_scene: str | None = None
    worker: str | None = None
    seconds: float = 0.0


@dataclass
class FrameProcessor:
    """The pipeline for frames of one run: one :class:`~stereo_classic.pipeline.Localizer` per rig, kept between
    frames (its matcher buffers and the detector stay warm). Serial runs use one; each Dask worker keeps one.

    ``detector`` is an object with ``detect(image)``, a :class:`DetectorSpec` (opened on first use) or None.
    ``threads`` (when set) overrides the matcher's and the opened detector's thread count.
    """

    params_for: Callable[[int | None], SGMParams]
    rig: RectifiedRig | None = None
    detector: Any = None
    detector_name: str | None = None
    fusion: FusionParams = field(default_factory=FusionParams)
    seed: int = 0
    classes: tuple[str, ...] | None = None
    concurrent: bool = False
    scale: float = 1.0
    threads: int | None = None
    on_error: str = "stop"

    def __post_init__(self) -> None:
        self._current: list[Any] = []  # [original rig, scaled rig, Localizer]

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        state["_current"] = []
        return state

    def _detector(self) -> Any:
        if isinstance(self.detector, DetectorSpec):
            self.detector = self.detector.open(self.threads)
        return self.detector

    def process(self, frame: Frame) -> FrameOutput:
        """Run the pipeline on one frame; the output carries the record the writer writes.

        Raises
        ------
        ValueError
            A frame without a calibration, or images that do not fit their rig.
        """
        loc, frame_rig, original, left, right = self._prepare(frame)
        return self._output(frame, loc(left, right), frame_rig, original)

    def _prepare(self, frame: Frame) -> tuple[Localizer, RectifiedRig, RectifiedRig, np.ndarray, np.ndarray]:
        """The frame's Localizer (a new one when the rig changes), its rig as matched, its own rig, and the images
        as matched (scaled)."""
        frame_rig = original = frame.rig if frame.rig is not None else self.rig
        if frame_rig is None:
            raise ValueError(f"frame {frame.name}: no calibration")
        if not self._current or self._current[0] is not original:
            # Each Localizer's matcher holds ~2*H*W*D bytes of buffers: free them before the next allocates.
            self.close()
            if self.scale != 1.0:
                frame_rig = (frame_rig.without_maps() if frame_rig.has_maps else frame_rig).scaled(self.scale)
            params = self.params_for(frame.max_disparity)
            if self.threads:
                params = dataclasses.replace(params, threads=self.threads)
            self._current[:] = [original, frame_rig, Localizer(
                frame_rig, self._detector(), params, fusion=self.fusion, seed=self.seed, classes=self.classes,
                concurrent=self.concurrent)]
        _, frame_rig, loc = self._current
        left, right = frame.left, frame.right
        if self.scale != 1.0:
            left, right = scale_pair(left, right, original, frame_rig.image_size)
        return loc, frame_rig, original, left, right

    def _output(self, frame: Frame, result: PipelineResult, frame_rig: RectifiedRig,
                original: RectifiedRig) -> FrameOutput:
        record = frame_record(frame.name, frame.index, result, frame_rig, detector=self.detector_name,
                              fusion=self.fusion, seed=self.seed, source=frame.source,
                              original_size=tuple(original.image_size) if self.scale != 1.0 else None)
        return FrameOutput(frame.index, frame.name, result, frame_rig, record)

    def process_ref(self, ref: FrameRef, read: Callable[[], Frame] | None = None) -> FrameOutput:
        """Read and process one described frame. A scene without a calibration, and (``on_error="skip"``) a frame
        that fails to read or to process, come back as an output that says so instead of raising. ``read``: what
        gives the frame instead of ``ref.read`` (a read done ahead, raising what the read raised)."""
        return self.start(ref, read, pipelined=False)()

    def start(self, ref: FrameRef, read: Callable[[], Frame] | None = None, *,
              pipelined: bool = True) -> Callable[[], FrameOutput]:
        """Read one described frame and start its processing: it is matched here, and (``pipelined``) its
        detection, fusion and checks go on in its Localizer's worker thread (:meth:`Localizer.submit`). Returns a
        function giving the frame's output (waiting for the worker), as :meth:`process_ref` gives it; errors as
        there, from this call or from that function, whichever part failed."""
        try:
            frame = (read or ref.read)()
            loc, frame_rig, original, left, right = self._prepare(frame)
            if not pipelined:
                done = self._output(frame, loc(left, right), frame_rig, original)
                return lambda: done
            future = loc.submit(left, right)
        except SceneSkipped as exc:
            skipped = FrameOutput(ref.index, ref.name, skipped_scene=str(exc))
            return lambda: skipped
        except (OSError, ValueError) as exc:
            failed = self._failed(ref, exc)
            return lambda: failed

        def finish() -> FrameOutput:
            try:
                result = future.result()
            except (OSError, ValueError) as exc:
                return self._failed(ref, exc)
            return self._output(frame, result, frame_rig, original)

        return finish

    def _failed(self, ref: FrameRef, exc: Exception) -> FrameOutput:
        """The output of a frame that failed (``on_error="skip"``); ``exc`` raised again otherwise."""
        if self.on_error != "skip":
            raise exc
        return FrameOutput(ref.index, ref.name, error=f"{type(exc).__name__}: {exc}")

    def close(self) -> None:
        if self._current:
            self._current.pop().close()
            self._current.clear()


class _Collector:
    """The client's side of a run: writes finished frames in order with the writer and keeps the summary."""

    def __init__(self, writer: FrameWriter, summary: RunSummary, on_frame: Callable[..., None] | None,
                 bar: Any) -> None:
        self.writer, self.summary, self.on_frame, self.bar = writer, summary, on_frame, bar

    def take(self, out: FrameOutput) -> None:
        summary = self.summary
        if out.skipped_scene is not None:
            log.warning("%s", out.skipped_scene)
            summary.skipped_scenes.append(out.skipped_scene)
        elif out.error is not None:
            log.error("frame %s failed and is skipped (--on-error skip): %s", out.name, out.error)
            summary.failed.append((out.name, out.error))
        else:
            assert out.result is not None and out.rig is not None and out.record is not None
            with _DeferInterrupt():
                self.writer.write(out.name, out.result, out.rig, out.record)
                summary.frames += 1  # counted with the write, before a held Ctrl-C is raised
                if summary.first_written is None:
                    summary.first_written = time.perf_counter()
                summary.timings_ms.append(out.result.timings_ms)
                summary.objects += len(out.result.objects)
            if out.worker is not None:
                entry = summary.workers.setdefault(out.worker, [0, 0.0])
                entry[0] += 1
                entry[1] += out.seconds
            if self.on_frame is not None:
                self.on_frame(Frame(out.index, out.name, out.result.left, out.result.left, out.rig), out.result)
        self.bar.update(1)


def _read_ahead(refs: Iterable[FrameRef]) -> Iterator[tuple[FrameRef, Callable[[], Frame]]]:
    """The frames of ``refs`` with their reads, each read (and the next description taken) in a reader thread
    while the frame before is processed: ``(ref, read)``, where ``read()`` gives the frame or raises what its read
    raised. One read at a time, in order; an interrupted run waits for the read in progress (no file is written
    by a read)."""
    it = iter(refs)

    def fetch() -> tuple[FrameRef, Future] | None:
        ref = next(it, None)
        if ref is None:
            return None
        done: Future = Future()
        try:
            done.set_result(ref.read())
        except BaseException as exc:  # noqa: BLE001 - handed to the frame's processing, which decides
            done.set_exception(exc)
        return ref, done

    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="stereo-reader") as pool:
        ahead = pool.submit(fetch)
        while True:
            item = ahead.result()
            if item is None:
                return
            ahead = pool.submit(fetch)
            ref, done = item
            yield ref, done.result


def in_order(items: Iterable[Any], start: Callable[[Any], Any], finish: Callable[[Any], None], *,
             overlap: bool = True) -> None:
    """``start(item)`` for each item in turn and ``finish`` of what it returned, in the same order. With ``overlap``
    an item is finished once the next one has started (what its start left running, in a worker thread, overlaps
    that start), the last one at the end; a start that raises (or Ctrl-C during it) first finishes the item started
    before it, as finishing each in turn would have, then raises. Without ``overlap`` each is finished at once.
    ``run``'s pipelined loop and ``guide``'s use it."""
    before: list[Any] = []  # the item started before, not yet finished
    for item in items:
        try:
            started = start(item)
        except BaseException:
            if before:
                finish(before.pop())
            raise
        if before:
            finish(before.pop())
        if overlap:
            before.append(started)
        else:
            finish(started)
    if before:
        finish(before.pop())


def _run_overlapped(refs: Iterable[FrameRef], processor: FrameProcessor, take: Callable[[FrameOutput], None],
                    check: Callable[[], None] = lambda: None, read_ahead: bool = False,
                    pipeline: bool = False) -> None:
    """Process the frames here, one after another, while a writer thread writes the frame before (and, with
    ``read_ahead``, a reader thread reads the frame after: :func:`_read_ahead`).

    The files of frame N are encoded and written while frame N + 1 is read and matched, so a frame costs the
    slower of the two, not their sum; frames are still written one at a time and in order (the same bytes as
    writing them in turn). With ``pipeline`` frame N's detection, fusion and checks run in the Localizer's worker
    thread (:meth:`FrameProcessor.start`) while frame N + 1 is read and matched here; its output is taken when
    frame N + 1's match is done, so the order, and each frame's output, stay those of processing in turn (a
    frame that fails to start, or Ctrl-C while one starts, hands on the frame before it first, as processing in
    turn would have written it). A write that fails raises here at the next frame or at the end. Ctrl-C or SIGTERM
    (raised in this, the main thread) waits for the write in progress, so that frame is complete and counted; the
    frame in progress is not written (the worker's part of it ends before the run returns: ``processor.close()``).
    ``check`` raises an interrupt that was asked for and discarded (:class:`_RunInterrupts`); it is called after
    each frame is processed and after the last write.
    """
    frames = _read_ahead(refs) if read_ahead else ((ref, None) for ref in refs)
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="stereo-writer") as pool:
        pending: Future | None = None

        def hand(out: FrameOutput) -> None:
            nonlocal pending
            if pending is not None:
                pending.result()
            pending = pool.submit(take, out)

        def start(item: tuple[FrameRef, Callable[[], Frame] | None]) -> Callable[[], FrameOutput]:
            ref, read = item
            started = processor.start(ref) if read is None else processor.start(ref, read)
            check()
            return started

        try:
            if pipeline:
                in_order(frames, start, lambda started: hand(started()))
            else:
                for ref, read in frames:
                    out = processor.process_ref(ref) if read is None else processor.process_ref(ref, read)
                    check()
                    hand(out)
        finally:
            frames.close()  # a read in progress ends before this returns
            if pending is not None:
                wait([pending])
        if pending is not None:
            pending.result()
        check()


def run_source(source: Source, writer: FrameWriter, *, params_for: Callable[[int | None], SGMParams],
               rig: RectifiedRig | None = None, detector: Any = None, detector_name: str | None = None,
               fusion: FusionParams | None = None, seed: int = 0, classes: Iterable[str] | None = None,
               concurrent: bool = False, scale: float = 1.0, progress: bool = False,
               on_frame: Callable[[Frame, PipelineResult], None] | None = None, on_error: str = "stop",
               executor: Any = None, read_ahead: bool = False, pipeline: bool = True) -> RunSummary:
    """Run the pipeline on every frame of ``source`` and write each frame with ``writer``.

    Parameters
    ----------
    source : PairSource, SceneSource or SideBySideSource
        Where the frames come from; a frame's own rig (dataset scenes) wins over ``rig``. Frames are read one at
        a time, when processed.
    writer : FrameWriter
        Writes each frame's files; its :meth:`~stereo_classic.outputs.FrameWriter.finished` decides which
        frames are skipped.
    params_for : callable
        The matcher parameters for a frame, given the frame's known disparity range (or None).
    rig : calib.RectifiedRig, optional
        The calibration of frames that bring none (image pairs, video, camera).
    detector : object with ``detect(image)``, a :class:`DetectorSpec`, or None
        None: depth only. ``detector_name`` is recorded in each frame's record. A Dask executor needs a spec.
    fusion, seed, classes, concurrent
        As for :class:`~stereo_classic.pipeline.Localizer`.
    scale : float
        Resize the (rectified) images by this factor before matching; the rig is scaled with them.
    progress : bool
        Show a progress bar on stderr.
    on_frame : callable, optional
        Called with each frame and its result after the frame is written (the command line prints there). The
        frame carries its name, index, rig and left image (``right`` is the left image too: the right image is
        not kept after matching, nor sent back by a cluster).
    on_error : {"stop", "skip"}
        A frame that cannot be read or processed (corrupt image, wrong size) ends the run ("stop", raising its
        error) or is recorded in :attr:`RunSummary.failed` and the run goes on ("skip").
    executor : object with ``run(frames, processor, take)``, optional
        Where frames are processed: None = here, one after another; a
        :class:`stereo_classic.cluster.DaskExecutor` = on a Dask cluster. Either way the frames are written here,
        in frame order, so the output folder is the same byte for byte.
    read_ahead : bool
        Processing here: read (and decode) the next frame in a thread while this one is processed (the images'
        decoding releases the GIL). Default False: beside the pipeline it gained nothing on 2 idle cores
        (docs/cli.md, "Output"); the earlier measurements without it (KITTI pair x30: 4.74 / 3.86, 5.00 / 6.25,
        2.61 / 2.22 frames/s without / with) were taken on a host whose other programs took the second core, where
        no thread can gain. Never for a live camera, whose next frame would wait a frame time before it is
        processed. The output is the same either way.
    pipeline : bool
        Processing here: each frame's detection, fusion and checks run in its Localizer's worker thread while the
        next frame is read and matched here (:meth:`FrameProcessor.start`, :meth:`Localizer.submit`); the frames
        are still handed to the writer one at a time and in order. Default True: on 2 idle cores the KITTI pair
        x30 ran at 7.8-9.4 frames/s against 6.3-7.2 in turn, the 12 OAK-D scenes x3 at 11.2-14.2 against
        10.4-12.7 (docs/cli.md, "Output"). The output is the same bytes either way (tested), Ctrl-C, SIGTERM and
        ``resume`` as without it; ``concurrent`` then changes nothing (the detector is in the worker anyway).

    Returns
    -------
    RunSummary
        ``interrupted`` (and ``signal``) when Ctrl-C or SIGTERM ended the run.

    Raises
    ------
    ValueError
        A frame without a calibration, or images that do not fit their rig (``on_error="stop"``), or a wrong
        ``on_error``.
    """
    if on_error not in ON_ERROR:
        raise ValueError(f"`on_error` must be one of {', '.join(ON_ERROR)}, got {on_error!r}")
    summary = RunSummary()
    processor = FrameProcessor(params_for, rig, detector, detector_name, fusion or FusionParams(), seed,
                               tuple(classes) if classes else None, concurrent, scale, on_error=on_error)

    def skip(name: str) -> bool:
        if writer.finished(name):
            summary.skipped += 1
            return True
        return False

    bar = tqdm(total=len(source) or None, unit="frame", file=sys.stderr, leave=False, disable=not progress)
    collector = _Collector(writer, summary, on_frame, bar)
    try:
        with _RunInterrupts() as interrupts:
            if executor is None:
                live = isinstance(source, SideBySideSource) and source.is_camera
                _run_overlapped(source.refs(skip), processor, collector.take, interrupts.check,
                                read_ahead=read_ahead and not live, pipeline=pipeline)
            else:
                executor.run(source.refs(skip), processor, collector.take)
                interrupts.check()
    except KeyboardInterrupt as exc:
        summary.interrupted = True
        summary.signal = "SIGTERM" if isinstance(exc, Terminated) else "SIGINT"
    finally:
        bar.close()
        processor.close()
    return summary
