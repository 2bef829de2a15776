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
"""

from __future__ import annotations

import glob
import logging
import os
import re
import unicodedata
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
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
    "SourceError",
    "PairSource",
    "SceneSource",
    "SideBySideSource",
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
    """

    index: int
    name: str
    left: np.ndarray
    right: np.ndarray
    rig: RectifiedRig | None = None
    max_disparity: int | None = None


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
    """Open a capture with OpenCV's own warnings ("can't open camera by index") silenced: the caller says it
    in one line. ``-vv`` (debug logging) keeps them."""
    log_api = getattr(getattr(cv2, "utils", None), "logging", None)
    if log_api is None or logging.getLogger().isEnabledFor(logging.DEBUG):
        return open_capture()
    previous = log_api.getLogLevel()
    log_api.setLogLevel(log_api.LOG_LEVEL_ERROR)
    try:
        return open_capture()
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

    def frames(self, skip: Callable[[str], bool] = lambda name: False) -> Iterator[Frame]:
        for i, ((lp, rp), name) in enumerate(zip(self.pairs, self._names)):
            if skip(name):
                continue
            yield Frame(i, name, read_image(lp), read_image(rp))

    def close(self) -> None:
        pass


class SceneSource:
    """Scenes from ``stereo_classic.datasets``: the demo scene, one scene folder, or every scene below a folder."""

    def __init__(self, scenes: Sequence[Scene]) -> None:
        if not scenes:
            raise SourceError("no scenes found")
        self.scenes = list(scenes)
        self._names = _unique([_safe_name(s.name or "scene") for s in self.scenes])
        self.rig = self.scenes[0].rig if len(self.scenes) == 1 else None

    @classmethod
    def demo(cls) -> SceneSource:
        return cls([datasets.demo_scene()])

    @classmethod
    def from_folder(cls, root: str | os.PathLike[str]) -> SceneSource:
        path = Path(root)
        if not path.exists():
            raise FileNotFoundError(f"dataset folder not found: {path}")
        if not path.is_dir():
            raise SourceError(f"--dataset must be a folder, got a file: {path}")
        try:
            scenes = [datasets.load_scene(path)]
        except (ValueError, FileNotFoundError):
            scenes = list(datasets.iter_scenes(path))
        if not scenes:
            raise SourceError(f"no stereo scene (Middlebury, KITTI, ...) found in {path}")
        calibrated = [s for s in scenes if s.rig is not None]
        if not calibrated:
            raise SourceError(f"no scene in {path} has a calibration (metric distances need one): "
                              f"{', '.join(s.name for s in scenes[:3])}")
        if len(calibrated) < len(scenes):
            logging.getLogger("stereo_classic.run").warning(
                "skipping %d scene(s) without a calibration in %s", len(scenes) - len(calibrated), path)
        return cls(calibrated)

    def __len__(self) -> int:
        return len(self.scenes)

    @property
    def names(self) -> list[str] | None:
        return list(self._names)

    def frames(self, skip: Callable[[str], bool] = lambda name: False) -> Iterator[Frame]:
        for i, (scene, name) in enumerate(zip(self.scenes, self._names)):
            if skip(name):
                continue
            yield Frame(i, name, scene.left, scene.right, scene.rig, scene.max_disparity)

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
                yield Frame(i, name, np.ascontiguousarray(image[:, :half]), np.ascontiguousarray(image[:, half:]))
            i += 1

    def close(self) -> None:
        if self.cap is not None:
            self.cap.release()
