"""Every file ``python -m stereo_classic run`` writes for a frame, as a library.

Outputs per frame ``NAME`` (``save`` chooses; ``ply=True`` adds the point cloud):

* ``NAME_boxes.png``           left image with labelled boxes ("car 12.4 m")
* ``NAME_disparity.png``       colourised disparity (TURBO, unknown black)
* ``NAME_depth.png``           colourised depth (TURBO, near = blue, unknown black)
* ``NAME_disparity.pfm``       float32 disparity in pixels, NaN unknown
* ``NAME_disparity_kitti.png`` KITTI 16-bit PNG (disparity x 256, 0 unknown)
* ``NAME_points.ply``          coloured point cloud in metres
* ``NAME_objects.json``        the frame's record (:func:`frame_record`); a sequence appends one line per
  frame to ``objects.jsonl`` (:class:`JsonlSink`) instead.

Every file is written atomically and the objects record last, so a frame is either complete or absent:
when any file fails (or Ctrl-C arrives) the frame's other files are removed again.

Examples
--------
>>> import tempfile
>>> from stereo_classic.outputs import FrameWriter
>>> with tempfile.TemporaryDirectory() as tmp:
...     writer = FrameWriter(tmp, save=("pfm", "json"))
...     [p.name for p in writer.expected_files("frame")]
['frame_disparity.pfm', 'frame_objects.json']
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import logging
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from calib import RectifiedRig
from stereo_classic import io
from stereo_classic.fusion import FusionParams, LocalizedObjects
from stereo_classic.outputs.visualize import colorize, draw_boxes
from stereo_classic.pipeline import PipelineResult

__all__ = ["SAVE_KINDS", "DEFAULT_SAVE", "JSONL_NAME", "FrameWriter", "JsonlSink", "frame_record", "box_labels",
           "write_all_or_nothing"]

log = logging.getLogger("stereo_classic.outputs")

#: What ``save`` can name, and the file each writes (``{name}`` is the frame name).
SAVE_KINDS: dict[str, str] = {
    "boxes": "{name}_boxes.png",
    "disparity": "{name}_disparity.png",
    "depth": "{name}_depth.png",
    "pfm": "{name}_disparity.pfm",
    "kitti": "{name}_disparity_kitti.png",
    "dense": "{name}_disparity_filled.pfm",
    "confidence": "{name}_confidence.png",
    "ply": "{name}_points.ply",
    "json": "{name}_objects.json",
}
#: Kinds written only when named: the point cloud, the filled (dense, partly guessed) disparity, the confidence.
ON_REQUEST: frozenset[str] = frozenset({"ply", "dense", "confidence"})
#: What ``run`` saves by default: every kind but those of :data:`ON_REQUEST`. The disparity files hold measured
#: pixels only (NaN / 0 where unknown); the filled map is ``dense``'s ``NAME_disparity_filled.pfm``.
DEFAULT_SAVE: tuple[str, ...] = tuple(k for k in SAVE_KINDS if k not in ON_REQUEST)
#: The objects file of a sequence: one JSON line per finished frame.
JSONL_NAME = "objects.jsonl"
#: The fusion parameters a user can set (command line, config file): the ones a record lists.
_USER_FUSION_FIELDS = frozenset(f.name for f in dataclasses.fields(FusionParams) if "help" in f.metadata)


def write_all_or_nothing(jobs: Iterable[tuple[Path, Callable[[Path], None]]]) -> list[Path]:
    """Call each ``write(path)`` in order; when one fails (or Ctrl-C arrives) remove every path of the group.

    Parameters
    ----------
    jobs : iterable of (path, write)
        ``write`` writes the file at ``path`` (atomically, as every writer of :mod:`stereo_classic.io` does).
        Evaluated lazily, so a job may use what an earlier one computed.

    Returns
    -------
    list of Path
        The paths written, in order.
    """
    written: list[Path] = []
    try:
        for path, write in jobs:
            written.append(path)
            write(path)
    except BaseException:
        for path in written:
            path.unlink(missing_ok=True)
        raise
    return written


def box_labels(objects: LocalizedObjects) -> list[str]:
    """One label per object for a picture: "car 12.4 m", or "car ?" when it has no distance.

    >>> from stereo_classic.fusion import LocalizedObjects
    >>> box_labels(LocalizedObjects.empty())
    []
    """
    return [f"{label} {dist:.1f} m" if status == "ok" else f"{label} ?"
            for label, status, dist in zip(objects.labels, objects.status, objects.distance_m)]


def frame_record(name: str, index: int, result: PipelineResult, rig: RectifiedRig, *, detector: str | None,
                 fusion: FusionParams, seed: int, source: Mapping[str, Any] | None = None,
                 original_size: tuple[int, int] | None = None) -> dict[str, Any]:
    """The JSON record of one frame: where it came from, its size, the rig, the settings and the objects.

    Parameters
    ----------
    name, index : str, int
        Frame name (outputs are named after it) and position in the run.
    result : PipelineResult
        What :class:`stereo_classic.Localizer` returned for the frame.
    rig : calib.RectifiedRig
        The geometry the frame was measured with (scaled when the images were).
    detector : str or None
        The detector's name (model file stem), None for depth only.
    fusion : FusionParams
        The fusion parameters; the ones a user can set (command line, config) are recorded.
    seed : int
        The RANSAC seed.
    source : mapping, optional
        Where the frame came from, e.g. ``{"left": "a/L.png", "right": "a/R.png"}``; recorded as ``"source"``.
    original_size : (width, height), optional
        The size of the input images when they were resized (``--scale``) before matching. Then
        ``"image_size"`` is this size, ``"processed_size"`` the matched one, and every box is given in the
        input image's pixels; ``"rig"``, the disparity files and the pictures are of the processed size.

    Returns
    -------
    dict
        JSON-ready (no NaN: unknown numbers are None). ``"boxes_in"`` says which pixels the boxes are in.

    Examples
    --------
    >>> import numpy as np
    >>> from types import SimpleNamespace
    >>> from stereo_classic.matching import SGMParams
    >>> from stereo_classic.fusion import LocalizedObjects
    >>> disparity = SimpleNamespace(disparity=np.zeros((50, 80), np.float32), params=SGMParams(), valid_fraction=1.0)
    >>> result = SimpleNamespace(disparity=disparity, objects=LocalizedObjects.empty())
    >>> rig = SimpleNamespace(focal_px=350.0, baseline_m=0.1, doffs=0.0)
    >>> rec = frame_record("a", 0, result, rig, detector=None, fusion=FusionParams(), seed=0,
    ...                    source={"left": "a.png", "right": "b.png"}, original_size=(160, 100))
    >>> rec["source"], rec["image_size"], rec["processed_size"], rec["boxes_in"]
    ({'left': 'a.png', 'right': 'b.png'}, [160, 100], [80, 50], 'input image pixels (image_size)')
    """
    params = result.disparity.params.to_dict()
    for volatile in ("threads", "memory_limit"):  # how, not what: the same result for any value
        params.pop(volatile, None)
    settings = {k: v for k, v in fusion.to_dict().items() if k in _USER_FUSION_FIELDS}
    h, w = result.disparity.disparity.shape
    in_w, in_h = (int(original_size[0]), int(original_size[1])) if original_size is not None else (w, h)
    objects = result.objects.to_json()
    if (in_w, in_h) != (w, h):  # boxes back into the input image's pixels
        sx, sy = in_w / w, in_h / h
        for obj in objects:
            x1, y1, x2, y2 = obj["box_xyxy"]
            obj["box_xyxy"] = [round(x1 * sx, 2), round(y1 * sy, 2), round(x2 * sx, 2), round(y2 * sy, 2)]
    return {
        "frame": name,
        "index": index,
        "source": None if source is None else {str(k): v for k, v in source.items()},
        "image_size": [in_w, in_h],
        "processed_size": [w, h],
        "boxes_in": "input image pixels (image_size)",
        "rig": {"focal_px": round(float(rig.focal_px), 4), "baseline_m": round(float(rig.baseline_m), 6),
                "doffs": round(float(rig.doffs), 4)},
        "detector": detector,
        "valid_fraction": round(float(result.disparity.valid_fraction), 4),
        "warnings": [w.to_json() for w in getattr(result, "warnings", ())],  # stereo_classic.checks
        "settings": {**settings, "seed": seed, "matcher": params},
        "objects": objects,
    }


class JsonlSink:
    """``objects.jsonl``: one complete line per finished frame, appended and fsynced.

    With ``resume=True`` the lines already there are kept (a torn last line is dropped) and their frames are in
    :attr:`done`; without it the file is started afresh on the first append.
    """

    def __init__(self, path: str | os.PathLike[str], resume: bool = False) -> None:
        self.path = Path(path)
        self.done: set[str] = set()
        self.lines: list[str] = []
        if resume and self.path.is_file():
            for line in self.path.read_text(encoding="utf-8").splitlines():
                try:
                    rec = json.loads(line)
                    self.done.add(str(rec["frame"]))
                    self.lines.append(line)
                except (ValueError, KeyError, TypeError):
                    log.info("dropping an incomplete line from %s", self.path)
                    break
        self._started = False

    def append(self, record: dict[str, Any]) -> None:
        """Append one frame's record (a dict with a "frame" key) as one line."""
        line = json.dumps(record, allow_nan=False, separators=(",", ":"))
        if not self._started:  # rewrite what is kept (nothing without resume), atomically
            self.path.parent.mkdir(parents=True, exist_ok=True)
            with io.atomic_write(self.path, "w") as f:
                f.write("".join(s + "\n" for s in self.lines))
            self._started = True
        with open(self.path, "a", encoding="utf-8", newline="\n") as f:
            f.write(line + "\n")
            f.flush()
            os.fsync(f.fileno())
        self.done.add(str(record["frame"]))


class FrameWriter:
    """Write what ``run`` writes for each frame into one folder.

    Parameters
    ----------
    outdir : path
        Output folder (created on the first write).
    save : sequence of str
        Kinds among :data:`SAVE_KINDS` (default :data:`DEFAULT_SAVE`).
    ply : bool
        Also write the point cloud (the same as adding "ply" to ``save``).
    depth_range : (near, far) metres
        Colour range of the depth picture and the depths kept in the point cloud.
    sequence : bool
        Several frames: the records go to ``objects.jsonl`` instead of one ``NAME_objects.json`` each.
    resume : bool
        :meth:`finished` reports frames whose files are all present (and, in a sequence, recorded).

    Raises
    ------
    ValueError
        An unknown kind in ``save`` (the message names ``save`` and the valid kinds).
    """

    def __init__(self, outdir: str | os.PathLike[str], *, save: Sequence[str] = DEFAULT_SAVE, ply: bool = False,
                 depth_range: tuple[float, float] = FusionParams().depth_range, sequence: bool = False,
                 resume: bool = False) -> None:
        bad = [s for s in save if s not in SAVE_KINDS]
        if bad:
            raise ValueError(f"`save`: unknown output {bad[0]!r}; choose among {', '.join(SAVE_KINDS)}")
        self.outdir = Path(outdir)
        self.kinds = set(save) | ({"ply"} if ply else set())
        if sequence:
            self.kinds.discard("json")
        self.depth_range = (float(depth_range[0]), float(depth_range[1]))
        self.resume = bool(resume)
        self.jsonl = JsonlSink(self.outdir / JSONL_NAME, resume) if sequence and "json" in save else None

    def expected_files(self, name: str) -> list[Path]:
        """The files a finished frame ``name`` has (the JSONL line aside)."""
        return [self.outdir / SAVE_KINDS[k].format(name=name) for k in SAVE_KINDS if k in self.kinds]

    def finished(self, name: str) -> bool:
        """True when resuming and frame ``name`` is complete (all its files, and its JSONL line)."""
        if not self.resume:
            return False
        if self.jsonl is not None and name not in self.jsonl.done:
            return False
        return all(p.is_file() for p in self.expected_files(name))

    def write(self, name: str, result: PipelineResult, rig: RectifiedRig, record: dict[str, Any]) -> list[Path]:
        """Write frame ``name``'s files, the record last; on a failure remove the frame's files again.

        Returns the files written (the JSONL, when used, is appended, not listed).
        """
        text = json.dumps(record, indent=2, allow_nan=False) + "\n"  # fails here, before any file, if malformed
        self.outdir.mkdir(parents=True, exist_ok=True)

        def write_json(path: Path) -> None:
            with io.atomic_write(path, "w") as f:
                f.write(text)

        jobs = self._image_jobs(name, result, rig)  # lazy: each picture is made just before it is written
        if self.jsonl is None and "json" in self.kinds:
            jobs = itertools.chain(jobs, [(self._path("json", name), write_json)])
        written = write_all_or_nothing(jobs)
        if self.jsonl is not None:  # the record marks the frame as finished: after every file
            try:
                self.jsonl.append(record)
            except BaseException:
                for path in written:
                    path.unlink(missing_ok=True)
                raise
        return written

    def _path(self, kind: str, name: str) -> Path:
        return self.outdir / SAVE_KINDS[kind].format(name=name)

    def _image_jobs(self, name: str, result: PipelineResult, rig: RectifiedRig
                    ) -> Iterable[tuple[Path, Callable[[Path], None]]]:
        save = self.kinds
        disp = result.disparity.disparity  # measured pixels only: NaN where unknown or filled
        near, far = self.depth_range
        # depth and points from measured pixels only (filled values are guesses, never distances)
        depth = rig.depth(disp) if {"depth", "ply"} & save else None
        if "boxes" in save:
            objs = result.objects
            image = draw_boxes(result.left, objs.xyxy, box_labels(objs)) if len(objs) else result.left
            yield self._path("boxes", name), lambda p: io.write_image(p, image)
        if "disparity" in save:
            params = result.disparity.params
            colour = colorize(disp, vmin=max(0, params.min_disparity), vmax=params.max_disparity)
            yield self._path("disparity", name), lambda p: io.write_image(p, colour)
        if "depth" in save:
            finite = depth[np.isfinite(depth)]
            vmax = float(np.clip(np.percentile(finite, 98), near * 1.01, far)) if finite.size else far
            shown = colorize(np.where(depth <= far, depth, np.nan), vmin=near, vmax=vmax)
            yield self._path("depth", name), lambda p: io.write_image(p, shown)
        if "pfm" in save:
            yield self._path("pfm", name), lambda p: io.write_pfm(p, disp)
        if "dense" in save:  # asked for by name: the holes filled from the background (guesses, not measurements)
            filled = result.disparity.filled_disparity
            yield self._path("dense", name), lambda p: io.write_pfm(p, filled)
        if "confidence" in save:  # 8-bit grey, DisparityMap.confidence: 0 unknown or filled, 1..255 measured
            conf = result.disparity.confidence
            yield self._path("confidence", name), lambda p: io.write_image(p, conf)
        if "kitti" in save:
            # The KITTI PNG holds 0..255.996 px; anything else is stored as unknown (0), and said so.
            outside = np.isfinite(disp) & ((disp < 0) | (disp > 65535 / 256))
            if outside.any():
                log.warning("%s: %d disparities outside 0..255.996 px do not fit a KITTI PNG and are stored as "
                            "unknown there (the PFM keeps them)", name, int(outside.sum()))
            yield self._path("kitti", name), lambda p: io.write_kitti_disparity(
                p, np.where(outside, np.float32(np.nan), disp))
        if "ply" in save:
            points = rig.points(disp)
            keep = np.isfinite(depth) & (depth >= near) & (depth <= far)
            left = result.left
            colors = left if left.ndim == 3 else np.repeat(left[..., None], 3, axis=2)
            yield self._path("ply", name), lambda p: io.write_ply(p, points[keep], colors[keep])
