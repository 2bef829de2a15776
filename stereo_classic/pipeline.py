"""The whole pipeline on one stereo pair: rectify, disparity, detect, localize.

``Localizer`` holds the matcher, the detector session and a worker thread across frames; calling it on
``(left, right)`` gives a :class:`PipelineResult`. With ``concurrent=True`` the detector runs in a second
thread beside the matcher (onnxruntime and the numba kernels release the GIL). Off by default: measured on
the KITTI pair on a 2-core machine, 8 interleaved repetitions, sequential 286 ms vs concurrent 301 ms
(median), since the matcher already keeps both cores busy. :meth:`Localizer.submit` is the pipelined call
(``run`` and ``guide``): the match here, the detector and then the fusion and checks in the worker thread, so
that a caller overlaps them with the next frame's read and match.
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Callable, Iterable, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from calib import RectifiedRig
from detectors import Detections, InputSizeError, OnnxDetector, resolve_model
from stereo_classic.checks import FrameChecker, FrameWarning
from stereo_classic.fusion import (
    FusionInputError,
    FusionParams,
    LocalizedObjects,
    as_generator,
    localize,
)
from stereo_classic.matching import (
    DisparityMap,
    SGMParams,
    StereoInputError,
    StereoMatcher,
    load_kernels,
)

__all__ = ["STAGES", "Localizer", "PipelineResult", "format_rate", "format_timings", "load_frame_kernels",
           "open_detector"]

log = logging.getLogger(__name__)


def open_detector(model: str | os.PathLike, *, square_input: bool = False, **options: Any) -> OnnxDetector:
    """The pipeline's detector: ``detectors.OnnxDetector(model, minimal_padding=True, **options)``.

    Each frame is letterboxed into the smallest multiple-of-32 rectangle around it at the model's scale, not into
    the model's full square: the square's padding is grey, not image, and a network's time grows with its input's
    area. With the shipped 416x416 YOLOX-nano a 1242x375 KITTI frame runs at 416x128 and a 640x480 OAK-D frame at
    416x320, the image at the same scale as in the square (measured at 1 thread, median of 5: 12.5 -> 4.2 ms and
    11.4 -> 8.5 ms; the same objects, confidences within 0.09, docs/detectors.md). A model that runs
    at its own size only (``detectors.InputSizeError``: a graph that reshapes to a fixed grid, e.g. the NanoDet
    and FastestDet exports), ``square_input=True``, or a ``minimal_padding`` in ``options`` get what they ask:
    the square for the first two."""
    if square_input or "minimal_padding" in options:
        return OnnxDetector(model, **options)
    try:
        return OnnxDetector(model, minimal_padding=True, **options)
    except InputSizeError as exc:
        log.info("%s: the detector gets its square input", exc)
    return OnnxDetector(model, **options)

#: Stage names in ``PipelineResult.timings_ms`` (in order).
STAGES: tuple[str, ...] = ("rectify", "disparity", "detect", "localize", "checks", "total")


@dataclass(frozen=True, eq=False)
class PipelineResult:
    """What :class:`Localizer` returns for one stereo pair.

    Attributes
    ----------
    left, right : (H, W, 3) or (H, W) uint8
        The rectified images the matcher saw (BGR).
    disparity : stereo_classic.DisparityMap
        Left disparity, pixels, NaN unknown.
    detections : detectors.Detections or None
        None when the localizer has no detector (depth only).
    objects : LocalizedObjects
        One row per detection (empty without a detector).
    timings_ms : dict[str, float]
        Wall milliseconds per stage (:data:`STAGES`); "detect" runs concurrently with "disparity"
        when the localizer is concurrent, so the stages need not add up to "total".
    cpu_ms : dict[str, float]
        Process CPU milliseconds per stage (``time.process_time`` deltas, every thread of the process: the
        matcher's workers, and whatever else runs meanwhile); with a concurrent localizer the detector's CPU is
        counted in "disparity" and "detect" is 0.
    warnings : tuple of stereo_classic.checks.FrameWarning
        What the frame checks found (:mod:`stereo_classic.checks`): disparities piled at the end of the range
        ("range_saturated"), a swapped or mismatched pair ("swapped_pair", "pair_mismatch"); the objects
        concerned carry the matching status instead of a distance.
    """

    left: np.ndarray
    right: np.ndarray
    disparity: DisparityMap
    detections: Detections | None
    objects: LocalizedObjects
    timings_ms: dict[str, float] = field(default_factory=dict)
    warnings: tuple[FrameWarning, ...] = ()
    cpu_ms: dict[str, float] = field(default_factory=dict)


def _as_params(params: SGMParams | Mapping[str, Any] | None) -> SGMParams:
    if params is None:
        return SGMParams()
    if isinstance(params, SGMParams):
        return params
    if isinstance(params, Mapping):
        return SGMParams(**params)
    raise ValueError(f"`params` must be None, an SGMParams or a dict of its fields, got {type(params).__name__}")


class Localizer:
    """Rectify, match, detect and localize, reusing the matcher and the detector across frames.

    Parameters
    ----------
    rig : calib.RectifiedRig
        Geometry of the pair (with rectification maps for raw pairs).
    detector : object with ``detect(image) -> Detections``, a model name/path, or None
        None: depth only. A string or path is resolved with ``detectors.resolve_model`` and opened
        with :func:`open_detector` (``detector_options`` its keyword arguments).
    params : SGMParams or dict, optional
        Matcher parameters (default ``SGMParams()``).
    fusion : FusionParams, optional
        Fusion parameters for :func:`stereo_classic.localize` (default ``FusionParams()``).
    seed : int
        Every frame uses ``rng=seed``, so a frame's result does not depend on the frames before it.
    classes : iterable of str, optional
        Keep only detections of these class names.
    concurrent : bool
        Run the detector in a worker thread while the matcher runs (default False: not faster on 2 cores).
    detector_options : dict, optional
        Keyword arguments for ``OnnxDetector`` when ``detector`` is a name or path.
    checks : bool
        Run the frame checks of :mod:`stereo_classic.checks` (default True): range saturation and a swapped or
        mismatched pair, each costing a half-size match only when due.
    **fusion_overrides
        FusionParams fields replacing those of ``fusion`` (``method="median"``, ``box_shrink=0.3``, ...).

    Examples
    --------
    Depth only (no detector) on the built-in demo scene; with ``detector="yolox_nano"`` the result's
    ``objects.format_table()`` is a table with a header: label, confidence, distance, x/y/z (m), direction.

    >>> from stereo_classic.datasets import demo_scene
    >>> scene = demo_scene()
    >>> with Localizer(scene.rig, None, {"num_disparities": 80}) as loc:
    ...     result = loc(scene.left, scene.right)
    >>> result.disparity.disparity.shape, len(result.objects), bool(result.disparity.valid_fraction > 0.85)
    ((500, 741), 0, True)
    """

    def __init__(self, rig: RectifiedRig, detector: Any = None,
                 params: SGMParams | Mapping[str, Any] | None = None, *, fusion: FusionParams | None = None,
                 seed: int = 0, classes: Iterable[str] | None = None, concurrent: bool = False,
                 detector_options: Mapping[str, Any] | None = None, checks: bool = True,
                 **fusion_overrides: Any) -> None:
        if not isinstance(rig, RectifiedRig):
            raise ValueError(f"`rig` must be a calib.RectifiedRig (a raw calib.StereoRig: rig.rectify() first), "
                             f"got {type(rig).__name__}")
        if fusion is not None and not isinstance(fusion, FusionParams):
            raise FusionInputError(f"`fusion` must be a FusionParams or None, got {type(fusion).__name__}")
        # Check every option before the matcher allocates or the detector loads.
        self.fusion = (fusion or FusionParams()).replace(**fusion_overrides)
        as_generator(seed, name="seed")  # the one check of a seed
        self.seed = seed
        self.rig = rig
        self.matcher = StereoMatcher(_as_params(params))
        if isinstance(detector, (str, os.PathLike)):
            detector = open_detector(resolve_model(detector), **dict(detector_options or {}))
        elif detector is not None and not callable(getattr(detector, "detect", None)):
            raise ValueError(f"`detector` must have a detect(image) method, a model name or None, got "
                             f"{type(detector).__name__}")
        self.detector = detector
        self.classes = tuple(classes) if classes else None
        self.concurrent = bool(concurrent) and detector is not None
        self.checker = FrameChecker(self.matcher.params) if checks else None
        self._warned: set[str] = set()
        self._pool: ThreadPoolExecutor | None = None
        self._first = True

    @property
    def params(self) -> Any:
        """The matcher's SGMParams."""
        return self.matcher.params

    def close(self) -> None:
        """Stop the worker thread and free the matcher's buffers (also done by ``with Localizer(...) as loc:``).

        Calling it again later is harmless; a closed Localizer can still be called (it allocates again).
        """
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None
        self.matcher.release()
        if self.checker is not None:
            self.checker.close()

    def __enter__(self) -> Localizer:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def _detect(self, image: np.ndarray) -> tuple[Any, float, float]:
        """Detections, wall ms and this thread's CPU ms."""
        t0, c0 = time.perf_counter(), time.thread_time()
        dets = self.detector.detect(image)
        if self.classes is not None:
            dets = dets.only(*self.classes)
        return dets, (time.perf_counter() - t0) * 1e3, (time.thread_time() - c0) * 1e3

    def _check_size(self, left: np.ndarray, right: np.ndarray) -> None:
        """StereoInputError naming the parameter (`left`, `right`, `rig`) when the sizes do not fit."""
        for name, img in (("left", left), ("right", right)):
            if not isinstance(img, np.ndarray) or img.ndim not in (2, 3):
                raise StereoInputError(f"`{name}` must be an (H, W) or (H, W, 3) image array, got "
                                       f"{type(img).__name__} {getattr(img, 'shape', '')}")
        if left.shape[:2] != right.shape[:2]:
            raise StereoInputError(f"`left` and `right` images differ in size: {left.shape[1]}x{left.shape[0]} "
                                   f"and {right.shape[1]}x{right.shape[0]}")
        raw = self.rig.has_maps
        size = tuple(int(s) for s in (self.rig.raw_image_size if raw else self.rig.image_size))
        if size != (left.shape[1], left.shape[0]):
            raise StereoInputError(
                f"`rig`: the calibration is for {size[0]}x{size[1]}{' raw' if raw else ''} images but `left` and "
                f"`right` are {left.shape[1]}x{left.shape[0]}; give the matching calibration "
                "(resized images: rig.scaled(f), or --scale on the command line)")

    def __call__(self, left: np.ndarray, right: np.ndarray) -> PipelineResult:
        """Run the pipeline on one pair (raw when the rig has rectification maps, else rectified)."""
        t0, c0 = time.perf_counter(), time.process_time()
        left, right = self._rectified(left, right)
        t1, c1 = time.perf_counter(), time.process_time()
        future = None
        if self.concurrent:
            future = self._worker().submit(self._detect, left)
        try:
            t_match = time.perf_counter()
            dmap = self.matcher.compute(left, right)
            t_match = (time.perf_counter() - t_match) * 1e3
            c_match = time.process_time()
        finally:
            if future is not None and not future.done():
                future.exception()  # wait: never leave the detector running after a failure
        detections, t_detect = (None, 0.0)
        if future is not None:
            detections, t_detect, _ = future.result()
        elif self.detector is not None:
            detections, t_detect, _ = self._detect(left)
        t2, c2 = time.perf_counter(), time.process_time()
        objects, warnings, (t3, c3) = self._localize_and_check(left, right, dmap, detections)
        t4, c4 = time.perf_counter(), time.process_time()
        cpu = {"rectify": c1 - c0, "disparity": (c2 if future is not None else c_match) - c1,
               "detect": 0.0 if future is not None else c2 - c_match, "localize": c3 - c2, "checks": c4 - c3,
               "total": c4 - c0}
        timings = {"rectify": (t1 - t0) * 1e3, "disparity": t_match, "detect": t_detect,
                   "localize": (t3 - t2) * 1e3, "checks": (t4 - t3) * 1e3, "total": (t4 - t0) * 1e3}
        return PipelineResult(left=left, right=right, disparity=dmap, detections=detections, objects=objects,
                              timings_ms=timings, warnings=warnings,
                              cpu_ms={k: v * 1e3 for k, v in cpu.items()})

    def submit(self, left: np.ndarray, right: np.ndarray) -> Future:
        """Start the pipeline on one pair and return a future of its :class:`PipelineResult`, the same as
        ``self(left, right)`` gives: the pair is checked, rectified and matched here (the call returns when the
        match is done), while the detector, and after the match the fusion and the frame checks, run in the
        Localizer's worker thread. A caller that submits the next pair before taking this one's result overlaps
        this frame's fusion and checks (single-threaded) with the next frame's reading and matching; the worker
        takes its jobs in order, one at a time, and every frame uses ``rng=seed``, so the results are those of
        calling the Localizer in turn. Errors of the first part are raised here, the others by ``result()``.

        In the result's ``cpu_ms``, "rectify" and "disparity" are process CPU over the stage (work of the
        worker thread that ran meanwhile included), "detect", "localize" and "checks" the worker thread's own
        CPU; "total" is their sum. ``timings_ms["total"]`` is the wall time from this call to the result.
        """
        t0, c0 = time.perf_counter(), time.process_time()
        left, right = self._rectified(left, right)
        t1, c1 = time.perf_counter(), time.process_time()
        worker = self._worker()
        detected = worker.submit(self._detect, left) if self.detector is not None else None
        try:
            dmap = self.matcher.compute(left, right)
        except BaseException:
            if detected is not None and not detected.cancel():
                detected.exception()  # wait: never leave the detector running after a failure
            raise
        t2, c2 = time.perf_counter(), time.process_time()
        stamps = {"rectify": ((t1 - t0) * 1e3, (c1 - c0) * 1e3), "disparity": ((t2 - t1) * 1e3, (c2 - c1) * 1e3)}
        return worker.submit(self._finish, left, right, dmap, detected, stamps, t0)

    def _finish(self, left: np.ndarray, right: np.ndarray, dmap: DisparityMap, detected: Future | None,
                stamps: dict[str, tuple[float, float]], t0: float) -> PipelineResult:
        """The worker's part of :meth:`submit` after the match: fusion and checks, and the result."""
        detections, t_detect, c_detect = (None, 0.0, 0.0) if detected is None else detected.result()
        t2, c2 = time.perf_counter(), time.thread_time()
        objects, warnings, (t3, c3) = self._localize_and_check(left, right, dmap, detections, time.thread_time)
        t4, c4 = time.perf_counter(), time.thread_time()
        timings = {k: w for k, (w, _) in stamps.items()}
        cpu = {k: c for k, (_, c) in stamps.items()}
        timings.update({"detect": t_detect, "localize": (t3 - t2) * 1e3, "checks": (t4 - t3) * 1e3,
                        "total": (t4 - t0) * 1e3})
        cpu.update({"detect": c_detect, "localize": (c3 - c2) * 1e3, "checks": (c4 - c3) * 1e3})
        cpu["total"] = sum(cpu.values())
        timings = {k: timings[k] for k in STAGES}
        return PipelineResult(left=left, right=right, disparity=dmap, detections=detections, objects=objects,
                              timings_ms=timings, warnings=warnings, cpu_ms={k: cpu[k] for k in STAGES})

    def _rectified(self, left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The pair checked against the rig and rectified (raw pairs; the vertical-offset check, by feature
        matching, on the first frame only)."""
        self._check_size(left, right)
        left, right = self.rig.rectify_pair(left, right, check_offset=self._first and self.rig.has_maps)
        self._first = False
        return left, right

    def _worker(self) -> ThreadPoolExecutor:
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="localizer")
        return self._pool

    def _localize_and_check(self, left: np.ndarray, right: np.ndarray, dmap: DisparityMap,
                            detections: Detections | None, clock: Callable[[], float] = time.process_time
                            ) -> tuple[LocalizedObjects, tuple[FrameWarning, ...], tuple[float, float]]:
        """The objects (checked) and the warnings of one frame, and (wall, ``clock``) when localize ended."""
        if detections is not None and len(detections):
            objects = localize(detections, dmap, self.rig, self.fusion, rng=self.seed,
                               range_warning=self.checker is None)  # the checks mark them instead
        else:
            objects = LocalizedObjects.empty(self.fusion.method)
        stamp = (time.perf_counter(), clock())
        objects, warnings = self._check(left, right, dmap, objects)
        return objects, warnings, stamp

    def _check(self, left: np.ndarray, right: np.ndarray, dmap: DisparityMap,
               objects: LocalizedObjects) -> tuple[LocalizedObjects, tuple[FrameWarning, ...]]:
        """The frame checks (:mod:`stereo_classic.checks`): objects re-marked, warnings (logged once per kind)."""
        if self.checker is None:
            return objects, ()
        halves = self.checker.halves(left, right)  # the half-size images, made once for both checks
        warning = self.checker.check_pair(left, right, dmap, halves)
        if warning is not None:
            objects = objects.with_status(np.ones(len(objects), dtype=bool), "pair_mismatch")
        else:
            objects, warning = self.checker.check_range(left, right, dmap, objects, self.rig, self.fusion, self.seed,
                                                        halves)
        if warning is None:
            return objects, ()
        (log.debug if warning.code in self._warned else log.warning)("%s", warning.message)
        self._warned.add(warning.code)
        return objects, (warning,)


def load_frame_kernels(params: SGMParams) -> None:
    """Load now the compiled kernels a :class:`Localizer` with the matcher's ``params`` runs on a frame: the matcher's
    (``matching.load_kernels``) and its frame checks' two half-size looks (``FrameChecker.load_kernels``), whose
    ranges are their own (the kernels are compiled once per range). ``run``, ``guide`` and the ROS 2 node call it
    before their first frame, so that it does not wait for them."""
    load_kernels(params)
    FrameChecker(params).load_kernels()


def format_rate(frames: int, wall_s: float, first_s: float | None, stages: str) -> str:
    """The frames/s line of ``run`` and ``guide``: frames over the wall clock of the whole frame loop (``stages``
    says what it holds), and, from two frames on, the rate after the first frame, whose time (``first_s``, from the
    loop's start to its record) includes one-time work: the buffers, the frame checks' matchers, the detector's first
    run (the commands load the kernels' compiled code before the loop: ``matching.load_kernels``). A camera that runs
    for minutes gets the second rate.

    >>> print(format_rate(30, 2.5, 0.4, "reading, matching").replace("; ", ";\\n"))
    30 frame(s) in 2.5 s: 12.00 frames/s (wall clock of the whole frame loop: reading, matching);
    after the first frame (0.40 s, one-time loading included): 13.81 frames/s
    """
    rate = frames / wall_s if wall_s > 0 else 0.0
    text = f"{frames} frame(s) in {wall_s:.1f} s: {rate:.2f} frames/s (wall clock of the whole frame loop: {stages})"
    if first_s is not None and frames >= 2 and wall_s > first_s:
        text += (f"; after the first frame ({first_s:.2f} s, one-time loading included): "
                 f"{(frames - 1) / (wall_s - first_s):.2f} frames/s")
    return text


def format_timings(timings: Iterable[Mapping[str, float]], *, stages: Iterable[str] | None = None,
                   rate: bool = True) -> str:
    """A short table of per-stage milliseconds over frames (median, and mean) plus frames per second.

    Parameters
    ----------
    timings : iterable of dict
        One ``timings_ms`` dict per frame.
    stages : iterable of str, optional
        Order of the rows; default: :data:`STAGES` first, then any other keys.
    rate : bool
        End with the frames per second of the median "total" (default); False: the number of frames only (for a
        caller that reports the rate it measured over the whole loop).

    Returns
    -------
    str
        Lines "stage  median ms  mean ms"; the last line gives frames and frames per second from the
        median of "total".
    """
    rows = [dict(t) for t in timings]
    if not rows:
        return "no frames"
    keys: list[str] = []
    for name in list(stages or STAGES) + [k for r in rows for k in r]:
        if name not in keys and any(name in r for r in rows):
            keys.append(name)
    width = max(len(k) for k in keys + ["stage"])
    lines = [f"{'stage':<{width}}  {'median ms':>9}  {'mean ms':>9}"]
    for k in keys:
        vals = np.array([r[k] for r in rows if k in r], dtype=np.float64)
        lines.append(f"{k:<{width}}  {np.median(vals):9.1f}  {vals.mean():9.1f}")
    totals = [r["total"] for r in rows if "total" in r]
    fps = 1000.0 / float(np.median(totals)) if totals and np.median(totals) > 0 else math.nan
    frames = f"{len(rows)} frame{'s' if len(rows) != 1 else ''}"
    lines.append(f"{frames}, {fps:.1f} frames/s" if rate else frames)
    return "\n".join(lines)
