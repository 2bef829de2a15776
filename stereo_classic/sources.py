"""Input sources for ``python -m stereo_classic run``: where stereo pairs come from.

Every source yields :class:`Frame` objects (a stable ``name`` used for output file names, the left
and right images) and knows its frame names up front where it can, so that ``--resume`` skips finished
frames without reading them. Kinds:

* :class:`PairSource`: explicit left/right files, lists of them or glob patterns (sorted, paired in order).
* :class:`SceneSource`: the built-in demo scene or a dataset folder (Middlebury, KITTI, ...) read with
  ``stereo_classic.datasets``; each scene carries its own calibration.
* :class:`SideBySideSource`: a side-by-side stereo video file or a live side-by-side camera
  (``cv2.VideoCapture``); left half is the left image. A source that stops delivering frames ends the
  iteration (the run then finishes with its summary).
* ``stereo_classic.ros.bag.BagSource``: a rosbag2 (MCAP) recording, left and right paired by header stamp (it lives
  with the ROS code, as its dependencies are the ``bag`` extra's; docs/ros.md).
"""

from __future__ import annotations

import glob
import logging
import os
import re
import sys
import tempfile
import unicodedata
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from calib import RectifiedRig
from stereo_classic import datasets
from stereo_classic.datasets import Scene
from stereo_classic.io import read_image

__all__ = [
    "Frame",
    "FrameRef",
    "PairSource",
    "SceneSkipped",
    "SceneSource",
    "SideBySideSource",
    "SourceError",
    "expand_pairs",
]


class SourceError(ValueError):
    """An input that cannot be used (empty glob, unequal left/right lists, camera that cannot be opened)."""


@dataclass(frozen=True, eq=False)
class Frame:
    """One stereo pair from a source.

    Attributes
    ----------
    index : int
        Position in the source (0-based).
    name : str
        Stable, file-name-safe name of the frame (outputs are named after it).
    left, right : (H, W, 3) uint8 BGR (or as read)
    rig : calib.RectifiedRig or None
        The frame's own calibration when the source has one (dataset scenes), else None.
    max_disparity : int or None
        The scene's disparity range when known (Middlebury ``ndisp``, ground truth), else None.
    source : dict or None
        Where the frame came from, as its JSON record names it: ``{"left": path, "right": path}`` for image
        files, ``{"scene": folder}`` for a dataset scene, ``{"video": path, "frame": i}`` / ``{"camera": n,
        "frame": i}``.
    """

    index: int
    name: str
    left: np.ndarray
    right: np.ndarray
    rig: RectifiedRig | None = None
    max_disparity: int | None = None
    source: dict[str, Any] | None = None


class SceneSkipped(SourceError):
    """A scene that was read but cannot be measured (no calibration): the run names it and goes on."""


@dataclass(frozen=True)
class FrameRef:
    """One frame, described but not read: what a run hands to whoever processes it (this process or a worker).

    Attributes
    ----------
    index : int
        Position in the source (0-based).
    name : str
        The frame's name (outputs are named after it).
    what : str
        Where it comes from, for messages (the image paths, the scene folder).
    load : callable
        ``load()`` returns ``(left, right, rig, max_disparity)``; picklable for the files of pairs and datasets
        (a ``functools.partial`` of a module-level function), so only the description travels.
    source : dict or None
        Where it comes from, for the frame's record (:attr:`Frame.source`).
    """

    index: int
    name: str
    what: str
    load: Callable[[], tuple[np.ndarray, np.ndarray, RectifiedRig | None, int | None]] = field(repr=False)
    source: dict[str, Any] | None = None

    def read(self) -> Frame:
        """Read the frame's images (and, for a dataset scene, its calibration)."""
        left, right, rig, max_disparity = self.load()
        return Frame(self.index, self.name, left, right, rig, max_disparity, self.source)


def _read_pair(left: Path, right: Path) -> tuple[np.ndarray, np.ndarray, None, None]:
    return read_image(left), read_image(right), None, None


def _read_scene(load: Callable[[], Scene], name: str, what: str
                ) -> tuple[np.ndarray, np.ndarray, RectifiedRig | None, int | None]:
    scene = load()
    if scene.rig is None:
        raise SceneSkipped(f"scene {name} ({what}) has no calibration (metric distances need one): skipped")
    return scene.left, scene.right, scene.rig, scene.max_disparity


def _given(left: np.ndarray, right: np.ndarray, rig: RectifiedRig | None = None, max_disparity: int | None = None
           ) -> tuple[np.ndarray, np.ndarray, RectifiedRig | None, int | None]:
    return left, right, rig, max_disparity


#: Characters no file system (Windows, macOS, Linux) takes in a file name, and control characters.
_UNSAFE = re.compile(r'[<>:"/\\|?*\x00-\x1f\x7f]+')
#: Names Windows reserves for devices, with or without an extension.
_RESERVED = re.compile(r"(CON|PRN|AUX|NUL|COM[0-9]|LPT[0-9])(\..*)?", re.IGNORECASE)
#: Longest frame name in UTF-8 bytes: room for the longest output suffix within a 255-byte file name.
_MAX_NAME_BYTES = 200


def _safe_name(text: str) -> str:
    """The input's stem as a file-name-safe frame name: letters of any script, digits, spaces and punctuation
    survive; only characters unsafe for file systems (``<>:"/\\|?*``, control characters) become ``_``.

    >>> _safe_name("Straße 1"), _safe_name("左 image"), _safe_name("a:b*c"), _safe_name("con"), _safe_name("..")
    ('Straße 1', '左 image', 'a_b_c', 'con_', 'frame')
    """
    name = _UNSAFE.sub("_", unicodedata.normalize("NFC", text)).strip(" ._")
    while len(name.encode("utf-8")) > _MAX_NAME_BYTES:
        name = name[:-1]
    name = name.rstrip(" .")
    if _RESERVED.fullmatch(name):
        name += "_"
    return name or "frame"


def _unique(names: Sequence[str]) -> list[str]:
    """Names made unique by ``_1``, ``_2``, ...; names that differ only in case collide too (macOS and Windows
    file systems do not tell them apart), and a suffixed name never takes a name that is already given.

    >>> _unique(["a", "a", "A", "a_1"])
    ['a', 'a_2', 'A_3', 'a_1']
    """
    taken = {n.casefold() for n in names}
    used: set[str] = set()
    counts: dict[str, int] = {}
    out = []
    for n in names:
        key = n.casefold()
        if key not in used:
            used.add(key)
            out.append(n)
            continue
        k = counts.get(key, 0)
        while True:
            k += 1
            candidate = f"{n}_{k}"
            if candidate.casefold() not in used and candidate.casefold() not in taken:
                break
        counts[key] = k
        used.add(candidate.casefold())
        out.append(candidate)
    return out


def _expand(items: Sequence[str | os.PathLike[str]], what: str) -> list[Path]:
    paths: list[Path] = []
    for item in items:
        text = os.fspath(item)
        if glob.has_magic(text):
            hits = sorted(glob.glob(text))
            if not hits:
                raise SourceError(f"{what}: the pattern {text!r} matches no file")
            paths.extend(Path(h) for h in hits)
        else:
            paths.append(Path(text))
    return paths


def expand_pairs(left: Sequence[str | os.PathLike[str]],
                 right: Sequence[str | os.PathLike[str]]) -> list[tuple[Path, Path]]:
    """Expand glob patterns (sorted) on both sides and pair them in order.

    Raises
    ------
    SourceError
        An empty glob, or different numbers of left and right files (the images without a partner are named).
    FileNotFoundError
        A named (non-glob) file that does not exist, or a directory given where image files belong.
    """
    lefts, rights = _expand(left, "--left"), _expand(right, "--right")
    for option, paths in (("--left", lefts), ("--right", rights)):
        for p in paths:
            if p.is_dir():
                raise FileNotFoundError(f"{option} {p} is a directory, expected image files (or a quoted glob "
                                        f"such as '{p / '*.png'}')")
    if len(lefts) != len(rights):
        n = min(len(lefts), len(rights))
        side, other, extra = ("left", "right", lefts[n:]) if len(lefts) > n else ("right", "left", rights[n:])
        shown = ", ".join(str(p) for p in extra[:5]) + (f" and {len(extra) - 5} more" if len(extra) > 5 else "")
        raise SourceError(f"--left gives {len(lefts)} file(s) but --right gives {len(rights)}; they are paired in "
                          f"order, so these {side} image(s) have no {other} image: {shown}")
    if not lefts:
        raise SourceError("no stereo pairs given (--left/--right are empty)")
    for p in lefts + rights:
        if not p.is_file():
            raise FileNotFoundError(f"input file not found: {p}")
    return list(zip(lefts, rights))


def _quietly(open_capture: Callable[[], Any]) -> Any:
    """Open a capture with OpenCV's own warnings ("can't open camera by index") and FFmpeg's ("moov atom not
    found", written by native code straight to file descriptor 2) held back: the caller says it in one line.
    What they wrote is logged at debug level; ``-vv`` (debug logging) shows them as they come."""
    log_api = getattr(getattr(cv2, "utils", None), "logging", None)
    if log_api is None or logging.getLogger().isEnabledFor(logging.DEBUG):
        return open_capture()
    previous = log_api.getLogLevel()
    log_api.setLogLevel(log_api.LOG_LEVEL_ERROR)
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):  # no real stderr (embedded interpreters)
        saved = None
    try:
        if saved is None:
            return open_capture()
        with tempfile.TemporaryFile() as tmp:
            os.dup2(tmp.fileno(), 2)
            try:
                return open_capture()
            finally:
                os.dup2(saved, 2)
                os.close(saved)
                tmp.seek(0)
                noise = tmp.read().decode("utf-8", "replace").strip()
                if noise:
                    logging.getLogger(__name__).debug("while opening the capture, OpenCV/FFmpeg said: %s", noise)
    finally:
        log_api.setLogLevel(previous)


class PairSource:
    """Left/right image files (from :func:`expand_pairs`), read lazily with ``stereo_classic.io.read_image``."""

    def __init__(self, pairs: Sequence[tuple[Path, Path]]) -> None:
        if not pairs:
            raise SourceError("no stereo pairs given")
        self.pairs = list(pairs)
        stems = [_safe_name(p[0].stem) for p in self.pairs]
        self._names = _unique(stems)
        self.rig = None

    def __len__(self) -> int:
        return len(self.pairs)

    @property
    def names(self) -> list[str] | None:
        return list(self._names)

    def refs(self, skip: Callable[[str], bool] = lambda name: False) -> Iterator[FrameRef]:
        """The frames not skipped, described (paths), not read."""
        for i, ((lp, rp), name) in enumerate(zip(self.pairs, self._names)):
            if not skip(name):
                yield FrameRef(i, name, f"{lp} + {rp}", partial(_read_pair, lp, rp),
                               {"left": str(lp), "right": str(rp)})

    def frames(self, skip: Callable[[str], bool] = lambda name: False) -> Iterator[Frame]:
        for ref in self.refs(skip):
            yield ref.read()

    def close(self) -> None:
        pass


def _scene_itself(scene: Scene) -> Scene:
    return scene


class SceneSource:
    """Scenes from ``stereo_classic.datasets``: the demo scene, one scene folder, or every scene below a folder.

    A dataset streams: the folder is scanned for scene descriptions (names and loaders) up front, and each scene is
    read when its frame is processed, so memory does not grow with the number of scenes. A scene without a
    calibration is skipped when it is read (:class:`SceneSkipped`: the run names it and goes on).

    Parameters
    ----------
    scenes : sequence of Scene or of (name, what, load)
        Scenes in memory, or descriptions: the scene's name, where it is (for messages) and ``load()`` returning the
        :class:`~stereo_classic.datasets.Scene`.
    """

    def __init__(self, scenes: Sequence[Scene | tuple[str, str, Callable[[], Scene]]]) -> None:
        if not scenes:
            raise SourceError("no scenes found")
        self.scenes: list[tuple[str, str, Callable[[], Scene]]] = [
            (s.name or "scene", str(s.path or s.name), partial(_scene_itself, s)) if isinstance(s, Scene) else s
            for s in scenes]
        first = scenes[0]
        self.rig = first.rig if len(scenes) == 1 and isinstance(first, Scene) else None
        #: The disparity range of the first scene a run reads, when opening the source read it (the demo; a dataset's
        #: first scene with a calibration), else None: the commands load the matcher's kernels for it before the
        #: first frame (they are compiled per range).
        self.first_max_disparity: int | None = first.max_disparity if isinstance(first, Scene) else None
        #: Things found in the folder but not taken as scenes (a left image without its right image), one line each.
        self.notes: list[str] = []

    @classmethod
    def demo(cls) -> SceneSource:
        scene = datasets.demo_scene()
        source = cls([(scene.name, "the built-in demo scene", datasets.demo_scene)])
        source.rig = scene.rig
        source.first_max_disparity = scene.max_disparity
        return source

    @classmethod
    def from_folder(cls, root: str | os.PathLike[str]) -> SceneSource:
        """Every scene at or below ``root``, described, not read (one scene is read to check for a calibration).

        Raises
        ------
        FileNotFoundError
            ``root`` does not exist.
        SourceError
            ``root`` is a file, holds no scene, or none of its scenes has a calibration.
        """
        path = Path(root)
        if not path.exists():
            raise FileNotFoundError(f"dataset folder not found: {path}")
        if not path.is_dir():
            raise SourceError(f"--dataset must be a folder, got a file: {path}")
        log = logging.getLogger("stereo_classic.run")
        notes: list[str] = []
        entries = [(name, f"{d / name}" if d.name != name else str(d), load)
                   for name, d, load in datasets.iter_scene_refs(path, on_skip=notes.append)]
        for note in notes:
            log.warning("skipping %s", note)
        if not entries:
            raise SourceError(f"no stereo scene (Middlebury, KITTI, ...) found in {path}")
        source = cls(entries)
        source.notes = notes
        rig = source._first_rig(path)
        if len(entries) == 1:
            source.rig = rig
        return source

    def _first_rig(self, path: Path) -> RectifiedRig:
        """Read scenes until one has a calibration (usually the first): a dataset without any fails before work."""
        failures: list[str] = []
        for name, what, load in self.scenes:
            try:
                scene = load()
            except (OSError, ValueError) as exc:  # a corrupt scene: the run meets it again and reports it
                failures.append(f"{name}: {exc}")
                continue
            if scene.rig is not None:
                self.first_max_disparity = scene.max_disparity
                return scene.rig
            failures.append(f"{name}: no calibration")
        names = ", ".join(f[: f.index(":")] for f in failures[:3])
        if all(f.endswith("no calibration") for f in failures):
            raise SourceError(f"no scene in {path} has a calibration (metric distances need one): {names}")
        raise SourceError(f"no scene in {path} could be read with a calibration; first: {failures[0]}")

    def __len__(self) -> int:
        return len(self.scenes)

    @property
    def names(self) -> list[str] | None:
        return _unique([_safe_name(name or "scene") for name, _, _ in self.scenes])

    def refs(self, skip: Callable[[str], bool] = lambda name: False) -> Iterator[FrameRef]:
        """The scenes not skipped, described (folder and loader), not read."""
        for i, ((_, what, load), name) in enumerate(zip(self.scenes, self.names or [])):
            if not skip(name):
                yield FrameRef(i, name, what, partial(_read_scene, load, name, what), {"scene": what})

    def frames(self, skip: Callable[[str], bool] = lambda name: False) -> Iterator[Frame]:
        """The scenes not skipped, read one at a time (scenes without a calibration are left out)."""
        for ref in self.refs(skip):
            try:
                yield ref.read()
            except SceneSkipped as exc:
                logging.getLogger("stereo_classic.run").warning("%s", exc)

    def close(self) -> None:
        pass


class SideBySideSource:
    """Frames of a side-by-side stereo video file or live camera; the left half is the left image.

    Parameters
    ----------
    capture : str, os.PathLike or int
        A video file path, or a camera index (``--camera N``).
    max_frames : int, optional
        Stop after this many frames.
    capture_factory : callable, optional
        Replaces ``cv2.VideoCapture`` (tests).

    Raises
    ------
    FileNotFoundError
        The video file does not exist.
    SourceError
        The video or camera cannot be opened, or its frame width is odd.
    """

    def __init__(self, capture: str | os.PathLike[str] | int, *, max_frames: int | None = None,
                 capture_factory: Callable[[Any], Any] | None = None) -> None:
        self.is_camera = isinstance(capture, int)
        if not self.is_camera and not Path(capture).is_file():
            raise FileNotFoundError(f"video file not found: {capture}")
        factory = capture_factory or cv2.VideoCapture
        what = f"camera {capture}" if self.is_camera else f"video {capture}"
        self.what = what
        self._source: dict[str, Any] = {"camera": capture} if self.is_camera else {"video": os.fspath(capture)}
        self.cap = _quietly(lambda: factory(capture if self.is_camera else os.fspath(capture)))
        if self.cap is None or not self.cap.isOpened():
            raise SourceError(f"cannot open {what}" + (" (is it connected and free?)" if self.is_camera else
                                                       " (not a video OpenCV can decode)"))
        count = -1 if self.is_camera else int(self.cap.get(cv2.CAP_PROP_FRAME_COUNT) or -1)
        self._count = count if count > 0 else None
        if max_frames is not None:
            self._count = max_frames if self._count is None else min(self._count, max_frames)
        self.max_frames = max_frames
        self.rig = None
        self.stopped_early = False
        self.frames_read = 0

    def __len__(self) -> int:
        return self._count or 0

    @property
    def names(self) -> list[str] | None:
        return None if self._count is None else [f"frame_{i:06d}" for i in range(self._count)]

    def frames(self, skip: Callable[[str], bool] = lambda name: False) -> Iterator[Frame]:
        for ref in self.refs(skip):
            yield ref.read()

    def refs(self, skip: Callable[[str], bool] = lambda name: False) -> Iterator[FrameRef]:
        """The frames not skipped, read from the capture as they are asked for (a video cannot be described by
        path and index alone: its images travel with the description)."""
        i = 0
        while self.max_frames is None or i < self.max_frames:
            ok, image = self.cap.read()
            if not ok or image is None:
                if self.is_camera or (self._count is not None and i < self._count):
                    self.stopped_early = True
                break
            self.frames_read += 1
            name = f"frame_{i:06d}"
            if image.ndim < 2 or image.shape[1] < 2 or image.shape[1] % 2:
                raise SourceError(f"{self.what}: a side-by-side frame needs an even width, got {image.shape[1]} px")
            if not skip(name):
                half = image.shape[1] // 2
                yield FrameRef(i, name, f"{self.what} frame {i}", partial(
                    _given, np.ascontiguousarray(image[:, :half]), np.ascontiguousarray(image[:, half:])),
                    {**self._source, "frame": i})
            i += 1

    def close(self) -> None:
        if self.cap is not None:
            self.cap.release()
