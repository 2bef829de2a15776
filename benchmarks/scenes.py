"""The inputs of a benchmark run: real scenes with ground truth and the synthetic speed sizes.

Scenes come from ``stereo_classic.datasets`` (``iter_scenes(root)``, ``demo_scene()``). Without that
module, only the built-in demo scene (scikit-image's Middlebury Motorcycle) is available, read here
directly so that a fresh machine can still run the command.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

__all__ = [
    "FAMILIES",
    "BenchScene",
    "SpeedInput",
    "default_data_dir",
    "demo_scene",
    "disparity_range",
    "load_scenes",
    "parse_size",
    "scene_family",
    "short_name",
    "speed_inputs",
]

log = logging.getLogger("benchmarks")

REPO = Path(__file__).resolve().parents[1]

#: Dataset families, in report order: results are averaged per family, never across them.
#: "Middlebury-style" is the six developer scenes every documented number since the start averages (Tsukuba, Venus,
#: Cones, Teddy, Adirondack, Motorcycle: 2001-2014, real clutter); the 14 scenes added to ../shared/data for issue 35
#: are their own rows so those numbers stay comparable and neither collection hides the other: the ten
#: Middlebury 2005/2006 scenes, and the four piecewise-planar Middlebury 2001 scenes (Barn1, Barn2, Poster,
#: Sawtooth), which every method gets nearly right.
FAMILIES: tuple[str, ...] = ("Middlebury-style", "driving", "Middlebury 2005/2006", "Middlebury 2001 planar",
                             "indoor", "other")
#: Folder-name prefixes (lower case) of each family; the folder nearest the scene decides.
_FAMILY_KEYS: tuple[tuple[str, str], ...] = (
    ("drivingstereo", "driving"), ("kitti", "driving"), ("middlebury2005", "Middlebury 2005/2006"),
    ("middlebury", "Middlebury-style"), ("adirondack", "Middlebury-style"), ("motorcycle", "Middlebury-style"),
    ("built-in demo", "Middlebury-style"), ("oakd", "indoor"),
)

#: The planar Middlebury 2001 scenes (Scharstein and Szeliski 2002) besides Venus, which stays Middlebury-style.
_MIDDLEBURY_2001_PLANAR = frozenset({"barn1", "barn2", "poster", "sawtooth"})


def scene_family(name: str, source: str = "") -> str:
    """The dataset family of a scene from its source path (nearest folder first), else its name.

    >>> scene_family("Adirondack", "/data/adirondackQ"), scene_family("x", "/data/drivingstereo")
    ('Middlebury-style', 'driving')
    >>> scene_family("Baby1", "/d/middlebury2005_2006/Baby1"), scene_family("barn1", "/d/middlebury2001/barn1")
    ('Middlebury 2005/2006', 'Middlebury 2001 planar')
    >>> scene_family("Motorcycle", "built-in demo (skimage.data.stereo_motorcycle)"), scene_family("a", "/tmp/a")
    ('Middlebury-style', 'other')
    """
    parts = [p.lower() for p in reversed(Path(source).parts)] if source and not source.startswith("built-in") else []
    if name.lower() in _MIDDLEBURY_2001_PLANAR and any(p.startswith("middlebury2001") for p in parts):
        return "Middlebury 2001 planar"
    for part in parts + [source.lower(), name.lower()]:
        for key, family in _FAMILY_KEYS:
            if part.startswith(key):
                return family
    return "other"


def short_name(name: str) -> str:
    """A scene name short enough for a table column: a DrivingStereo ``<sequence>_<frame>`` name keeps its frame time.

    >>> short_name("2018-07-09-16-11-56_2018-07-09-16-11-57-101"), short_name("teddy")
    ('16-11-57-101', 'teddy')
    """
    seq, sep, frame = name.partition("_")
    if sep and len(frame) > 11 and frame[:10] == seq[:10] and frame[4:5] == "-":
        return frame[11:]
    return name


@dataclass
class BenchScene:
    """One stereo pair to evaluate.

    Attributes
    ----------
    name : str
    left, right : (H, W, 3) or (H, W) uint8 arrays, as read (BGR)
    gt_disparity : (H, W) float32 pixels, NaN unknown, or None
    nonocc_mask : (H, W) bool or None
    max_disparity : int or None
        The dataset's disparity bound (e.g. Middlebury ``ndisp``), when known.
    rig : calib.RectifiedRig or None
    gt_depth : (H, W) float32 metres, NaN unknown (sparse LiDAR), or None
    source : str
        Where it came from (a path, or "built-in demo").
    family : str
        One of :data:`FAMILIES`; empty: derived from ``source`` and ``name`` (:func:`scene_family`).
    """

    name: str
    left: np.ndarray
    right: np.ndarray
    gt_disparity: np.ndarray | None = None
    nonocc_mask: np.ndarray | None = None
    max_disparity: int | None = None
    rig: Any = None
    gt_depth: np.ndarray | None = None
    source: str = ""
    family: str = ""

    def __post_init__(self) -> None:
        if not self.family:
            self.family = scene_family(self.name, self.source)
        if self.family not in FAMILIES:
            raise ValueError(f"`family` must be one of {FAMILIES}, got {self.family!r}")

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        return int(self.left.shape[1]), int(self.left.shape[0])

    @classmethod
    def from_scene(cls, scene: Any, source: str = "") -> BenchScene:
        """From a ``stereo_classic.datasets.Scene``."""
        gt = getattr(scene, "gt_disparity", None)
        if gt is not None:
            gt = np.asarray(gt, dtype=np.float32).copy()
            gt[~np.isfinite(gt)] = np.nan
        depth = getattr(scene, "gt_depth", None)
        if depth is not None:
            depth = np.asarray(depth, dtype=np.float32).copy()
            depth[~np.isfinite(depth) | (depth <= 0)] = np.nan
        mask = getattr(scene, "nonocc_mask", None)
        return cls(
            name=str(scene.name),
            left=np.ascontiguousarray(scene.left),
            right=np.ascontiguousarray(scene.right),
            gt_disparity=gt,
            nonocc_mask=None if mask is None else np.asarray(mask, dtype=bool),
            max_disparity=getattr(scene, "max_disparity", None),
            rig=getattr(scene, "rig", None),
            gt_depth=depth,
            source=source,
        )


@dataclass(frozen=True)
class SpeedInput:
    """A speed-only input (no ground truth): a pair of a given size and disparity range."""

    name: str
    left: np.ndarray
    right: np.ndarray
    num_disparities: int
    note: str

    @property
    def size(self) -> tuple[int, int]:
        return int(self.left.shape[1]), int(self.left.shape[0])


def default_data_dir() -> Path | None:
    """``$STEREO_CLASSIC_DATA``, else ``../shared/data`` beside the repository, when it exists."""
    env = os.environ.get("STEREO_CLASSIC_DATA")
    path = Path(env) if env else REPO.parent / "shared" / "data"
    return path if path.is_dir() else None


def demo_scene() -> BenchScene:
    """The built-in demo scene (Middlebury Motorcycle from scikit-image, with its rig)."""
    from stereo_classic import datasets

    return BenchScene.from_scene(datasets.demo_scene(), source="built-in demo (skimage.data.stereo_motorcycle)")


def _matches(name: str, wanted: Sequence[str]) -> bool:
    low = name.lower()
    return any(w.lower() == low or w.lower() in low for w in wanted)


def load_scenes(data_dir: Path | None, names: Sequence[str] | None = None, *, include_no_gt: bool = False) -> list[BenchScene]:
    """Scenes below ``data_dir`` (or the demo scene when ``data_dir`` is None).

    Parameters
    ----------
    data_dir : Path or None
    names : sequence of str, optional
        Keep scenes whose name equals or contains one of these (case-insensitive). A scene named here
        is kept even without ground truth.
    include_no_gt : bool
        Keep scenes that have neither a ground-truth disparity nor LiDAR depth.

    Raises
    ------
    FileNotFoundError
        ``data_dir`` does not exist.
    ValueError
        No scene matched ``names``.
    """
    if data_dir is None:
        scenes = [demo_scene()]
    else:
        data_dir = Path(data_dir)
        if not data_dir.is_dir():
            raise FileNotFoundError(f"`--data` must be a folder of stereo scenes, got {str(data_dir)!r} which does not exist")
        from stereo_classic import datasets

        scenes = []
        for scene in datasets.iter_scenes(data_dir):
            bench = BenchScene.from_scene(scene, source=str(getattr(scene, "path", "") or data_dir))
            if names and not _matches(bench.name, names):
                continue
            if not names and not include_no_gt and bench.gt_disparity is None and bench.gt_depth is None:
                continue
            scenes.append(bench)
    if names:
        scenes = [s for s in scenes if _matches(s.name, names)]
        if not scenes:
            raise ValueError(f"`--scenes` {list(names)} matched no scene in {data_dir or 'the built-in demo'}")
    return scenes


def disparity_range(scene: BenchScene, default: int = 128) -> int:
    """``num_disparities`` for a scene.

    The ground-truth maximum + 1 rounded up to 16; for a LiDAR frame without a disparity map (the KITTI
    object pair) ``default`` (128, the range customary on KITTI and the issue's 1242x375x128 size);
    else the dataset's bound rounded up to 16; else ``default``.
    """
    if scene.gt_disparity is not None and np.isfinite(scene.gt_disparity).any():
        top = float(np.nanmax(scene.gt_disparity))
        return max(16, int(math.ceil((math.floor(top) + 1) / 16.0)) * 16)
    if scene.gt_depth is not None:
        return default
    if scene.max_disparity:
        return max(16, int(math.ceil(int(scene.max_disparity) / 16.0)) * 16)
    return default


def parse_size(text: str) -> tuple[int, int, int]:
    """``"1242x375x128"`` -> (1242, 375, 128)."""
    parts = text.lower().split("x")
    try:
        w, h, d = (int(p) for p in parts)
    except ValueError:
        raise ValueError(f"`--sizes` entries must look like WIDTHxHEIGHTxDISPARITIES (e.g. 1242x375x128), got {text!r}") from None
    if w < 16 or h < 16 or d <= 0 or d % 16:
        raise ValueError(f"`--sizes` entry {text!r} needs width, height >= 16 and disparities a positive multiple of 16")
    return w, h, d


def speed_inputs(scenes: Sequence[BenchScene], sizes: Sequence[tuple[int, int, int]]) -> list[SpeedInput]:
    """Speed-only pairs of the requested sizes not already covered by a real scene of that size.

    The texture is real: the KITTI pair when loaded (for its own size), else a scene with ground truth
    (Motorcycle first) resized with bicubic interpolation to (W, H). Rows stay aligned, so the pair
    stays rectified; only the disparities scale by W / w.
    """
    out = []
    covered = {(s.size[0], s.size[1], disparity_range(s)) for s in scenes}
    for w, h, d in sizes:
        if (w, h, d) in covered:
            continue
        same_size = [s for s in scenes if s.size == (w, h)]
        textured = sorted(scenes, key=lambda s: (0 if "motorcycle" in s.name.lower() else 1, -s.size[0] * s.size[1]))
        base = same_size[0] if same_size else (textured[0] if textured else demo_scene())
        left = cv2.resize(base.left, (w, h), interpolation=cv2.INTER_CUBIC)
        right = cv2.resize(base.right, (w, h), interpolation=cv2.INTER_CUBIC)
        note = f"{base.name} {base.size[0]}x{base.size[1]} resized to {w}x{h} (bicubic, synthetic size, real texture)"
        if same_size:
            note = f"{base.name} at its own size"
        out.append(SpeedInput(f"{w}x{h}x{d}", np.ascontiguousarray(left), np.ascontiguousarray(right), d, note))
    return out
