"""Run the pipeline over a source of frames into an output folder: what ``python -m stereo_classic run`` does.

:func:`run_source` takes frames from a :mod:`stereo_classic.sources` source, keeps one
:class:`~stereo_classic.pipeline.Localizer` per rig (a dataset brings a rig per scene; the previous
Localizer's buffers are freed on a change), optionally scales the images, and hands every result to a
:class:`~stereo_classic.outputs.FrameWriter`. Ctrl-C finishes nothing half: the frame in progress leaves no
file, finished frames are complete (a writer with ``resume=True`` skips them next time), and the
:class:`RunSummary` says it was interrupted.

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

import signal
import sys
import threading
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from tqdm import tqdm

from calib import RectifiedRig
from stereo_classic.fusion import FusionParams
from stereo_classic.matching import SGMParams
from stereo_classic.outputs import FrameWriter, frame_record
from stereo_classic.pipeline import Localizer, PipelineResult
from stereo_classic.sources import Frame, PairSource, SceneSource, SideBySideSource

__all__ = ["RunSummary", "run_source", "scale_pair"]

Source = PairSource | SceneSource | SideBySideSource


@dataclass
class RunSummary:
    """What :func:`run_source` did.

    Attributes
    ----------
    frames, objects, skipped : int
        Frames processed and written, objects found in them, finished frames skipped (resume).
    interrupted : bool
        Ctrl-C ended the run; the frame in progress was not written.
    timings_ms : list of dict
        ``PipelineResult.timings_ms`` of every processed frame.
    """

    frames: int = 0
    objects: int = 0
    skipped: int = 0
    interrupted: bool = False
    timings_ms: list[dict[str, float]] = field(default_factory=list)


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


def run_source(source: Source, writer: FrameWriter, *, params_for: Callable[[int | None], SGMParams],
               rig: RectifiedRig | None = None, detector: Any = None, detector_name: str | None = None,
               fusion: FusionParams | None = None, seed: int = 0, classes: Iterable[str] | None = None,
               concurrent: bool = False, scale: float = 1.0, progress: bool = False,
               on_frame: Callable[[Frame, PipelineResult], None] | None = None) -> RunSummary:
    """Run the pipeline on every frame of ``source`` and write each frame with ``writer``.

    Parameters
    ----------
    source : PairSource, SceneSource or SideBySideSource
        Where the frames come from; a frame's own rig (dataset scenes) wins over ``rig``.
    writer : FrameWriter
        Writes each frame's files; its :meth:`~stereo_classic.outputs.FrameWriter.finished` decides which
        frames are skipped.
    params_for : callable
        The matcher parameters for a frame, given the frame's known disparity range (or None).
    rig : calib.RectifiedRig, optional
        The calibration of frames that bring none (image pairs, video, camera).
    detector : object with ``detect(image)``, or None
        None: depth only. ``detector_name`` is recorded in each frame's record.
    fusion, seed, classes, concurrent
        As for :class:`~stereo_classic.pipeline.Localizer`.
    scale : float
        Resize the (rectified) images by this factor before matching; the rig is scaled with them.
    progress : bool
        Show a progress bar on stderr.
    on_frame : callable, optional
        Called with each frame and its result after the frame is written (the command line prints there).

    Returns
    -------
    RunSummary

    Raises
    ------
    ValueError
        A frame without a calibration, or images that do not fit their rig.
    """
    fusion = fusion or FusionParams()
    summary = RunSummary()
    current: list[Any] = []  # [original rig, scaled rig, Localizer] of the frame in progress

    def skip(name: str) -> bool:
        if writer.finished(name):
            summary.skipped += 1
            return True
        return False

    bar = tqdm(total=len(source) or None, unit="frame", file=sys.stderr, leave=False, disable=not progress)
    try:
        for frame in source.frames(skip):
            frame_rig = original = frame.rig if frame.rig is not None else rig
            if frame_rig is None:
                raise ValueError(f"frame {frame.name}: no calibration")
            if not current or current[0] is not original:
                # Each Localizer's matcher holds ~2*H*W*D bytes of buffers: free them before the next allocates.
                if current:
                    current.pop().close()
                    current.clear()
                if scale != 1.0:
                    frame_rig = (frame_rig.without_maps() if frame_rig.has_maps else frame_rig).scaled(scale)
                current[:] = [original, frame_rig, Localizer(
                    frame_rig, detector, params_for(frame.max_disparity), fusion=fusion, seed=seed, classes=classes,
                    concurrent=concurrent)]
            _, frame_rig, loc = current
            left, right = frame.left, frame.right
            if scale != 1.0:
                left, right = scale_pair(left, right, original, frame_rig.image_size)
            result = loc(left, right)
            record = frame_record(frame.name, frame.index, result, frame_rig, detector=detector_name, fusion=fusion,
                                  seed=seed)
            with _DeferInterrupt():
                writer.write(frame.name, result, frame_rig, record)
            summary.timings_ms.append(result.timings_ms)
            summary.frames += 1
            summary.objects += len(result.objects)
            if on_frame is not None:
                on_frame(frame, result)
            bar.update(1)
    except KeyboardInterrupt:
        summary.interrupted = True
    finally:
        bar.close()
        if current:
            current[-1].close()
    return summary

