"""The :class:`Scene` every dataset loader returns, and the small file helpers the loaders share.

Example
-------
>>> import numpy as np
>>> from stereo_classic.datasets import Scene
>>> pair = np.zeros((4, 6, 3), np.uint8)
>>> scene = Scene("flat", pair, pair, gt_disparity=np.full((4, 6), np.nan, np.float32))
>>> scene.shape, scene.image_size, scene.rig is None
((4, 6), (6, 4), True)
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from calib import RectifiedRig
from stereo_classic.io import FileFormatError, read_image

__all__ = ["Scene", "SceneRef"]

_IMAGE_EXTS = (".png", ".ppm", ".pgm", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


@dataclass(frozen=True)
class Scene:
    """One rectified stereo pair with whatever ground truth its dataset has.

    Attributes
    ----------
    name : str
        Scene name (folder name, frame id or pair name).
    left, right : (H, W, 3) uint8 BGR
        The rectified pair as read (grey files are expanded to three equal channels).
    gt_disparity : (H, W) float32 pixels, NaN where unknown, or None
        Ground-truth disparity of the left image (d = x_left - x_right); dense for Middlebury,
        sparse for KITTI and DrivingStereo (projected LiDAR).
    nonocc_mask : (H, W) bool or None
        True where the left pixel is visible in the right image and the ground truth is known.
    rig : calib.RectifiedRig or None
        The rectified geometry, when the dataset gives it.
    gt_depth : (H, W) float32 metres, NaN where no LiDAR point, or None
        Sparse depth (KITTI LiDAR, DrivingStereo depth maps), Z in the left rectified camera frame.
    max_disparity : int or None
        Disparity range that covers the scene (Middlebury ``ndisp``; otherwise the largest ground
        truth disparity rounded up to a multiple of 16).
    lidar_points : (N, 3) float32 metres or None
        LiDAR points that fall inside the left image, in the left rectified camera frame.
    layout : str
        Which loader made it, e.g. ``"middlebury2014"``.
    path : Path or None
        Folder (or file) it came from; the dataset root for layouts that spread a frame over several
        folders (KITTI ``training``, DrivingStereo).
    """

    name: str
    left: np.ndarray = field(repr=False)
    right: np.ndarray = field(repr=False)
    gt_disparity: np.ndarray | None = field(default=None, repr=False)
    nonocc_mask: np.ndarray | None = field(default=None, repr=False)
    rig: RectifiedRig | None = None
    gt_depth: np.ndarray | None = field(default=None, repr=False)
    max_disparity: int | None = None
    lidar_points: np.ndarray | None = field(default=None, repr=False)
    layout: str = ""
    path: Path | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise TypeError(f"Scene `name` must be a str, got {type(self.name).__name__}")
        for key in ("left", "right"):
            img = getattr(self, key)
            if not isinstance(img, np.ndarray):
                raise TypeError(f"Scene `{key}` must be a numpy array, got {type(img).__name__}")
            if img.dtype not in (np.uint8, np.uint16) or not (
                img.ndim == 2 or (img.ndim == 3 and img.shape[2] == 3)
            ):
                raise ValueError(
                    f"Scene `{key}` must be an (H, W, 3) or (H, W) uint8/uint16 image, got {img.dtype} {img.shape}"
                )
        if self.left.shape != self.right.shape:
            raise ValueError(
                f"Scene `left` and `right` must have the same shape, got {self.left.shape} and {self.right.shape}"
            )
        hw = self.left.shape[:2]
        for key, dtype in (("gt_disparity", np.float32), ("gt_depth", np.float32), ("nonocc_mask", np.bool_)):
            arr = getattr(self, key)
            if arr is None:
                continue
            if not isinstance(arr, np.ndarray) or arr.dtype != dtype or arr.shape != hw:
                got = f"{arr.dtype} {arr.shape}" if isinstance(arr, np.ndarray) else type(arr).__name__
                raise ValueError(f"Scene `{key}` must be {np.dtype(dtype)} {hw}, got {got}")
            if dtype == np.float32 and np.isinf(arr).any():
                raise ValueError(f"Scene `{key}` must use NaN for unknown, got inf")
        if self.lidar_points is not None:
            pts = self.lidar_points
            if not isinstance(pts, np.ndarray) or pts.dtype != np.float32 or pts.ndim != 2 or pts.shape[1] != 3:
                raise ValueError("Scene `lidar_points` must be an (N, 3) float32 array")
        if self.max_disparity is not None:
            if isinstance(self.max_disparity, bool) or not isinstance(self.max_disparity, (int, np.integer)):
                raise TypeError(f"Scene `max_disparity` must be an int or None, got {self.max_disparity!r}")
            if self.max_disparity <= 0:
                raise ValueError(f"Scene `max_disparity` must be positive, got {self.max_disparity}")
            object.__setattr__(self, "max_disparity", int(self.max_disparity))

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the pair."""
        return self.left.shape[:2]  # type: ignore[return-value]

    @property
    def image_size(self) -> tuple[int, int]:
        """(width, height) of the pair, as OpenCV and :class:`calib.RectifiedRig` count it."""
        return (self.left.shape[1], self.left.shape[0])



#: A scene found by discovery, not loaded yet: (name, loader).
SceneRef = tuple[str, Callable[[], Scene]]


# --------------------------------------------------------------------------------------------------
# helpers shared by the loaders (package-private)
# --------------------------------------------------------------------------------------------------


def _folder(path: Any, what: str) -> Path:
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"`{what}` must be a str or os.PathLike folder, got {type(path).__name__}")
    p = Path(os.fspath(path))
    if not p.exists():
        raise FileNotFoundError(f"{what} not found: {p}")
    if not p.is_dir():
        raise NotADirectoryError(f"{what} must be a folder, got a file: {p}")
    return p


def _find(folder: Path, stem: str, exts: tuple[str, ...] = _IMAGE_EXTS) -> Path | None:
    for ext in exts:
        candidate = folder / f"{stem}{ext}"
        if candidate.is_file():
            return candidate
    return None


def _need(folder: Path, stem: str, what: str, exts: tuple[str, ...] = _IMAGE_EXTS) -> Path:
    found = _find(folder, stem, exts)
    if found is None:
        names = ", ".join(f"{stem}{e}" for e in exts[:3])
        raise FileNotFoundError(f"{what} not found in {folder}: expected {names} ...")
    return found


def _read_pair(left: Path, right: Path) -> tuple[np.ndarray, np.ndarray]:
    a, b = read_image(left), read_image(right)
    if a.shape != b.shape:
        raise FileFormatError(f"left {left} is {a.shape[1]}x{a.shape[0]} but right {right} is {b.shape[1]}x{b.shape[0]}")
    return a, b


def _check_shape(arr: np.ndarray, shape: tuple[int, ...], path: Path, what: str) -> None:
    if arr.shape[:2] != shape:
        raise FileFormatError(f"{what} {path} is {arr.shape[1]}x{arr.shape[0]}, the images are {shape[1]}x{shape[0]}")


def _range_from_gt(values: np.ndarray | None) -> int | None:
    """Largest finite value rounded up to a multiple of 16 (None when there is none)."""
    if values is None:
        return None
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return None
    top = float(finite.max())
    return max(16, int(math.ceil(top / 16.0)) * 16)


def _read_mask(path: Path, shape: tuple[int, int]) -> np.ndarray:
    mask = read_image(path, grayscale=True)
    _check_shape(mask, shape, path, "mask")
    return mask == (255 if mask.dtype == np.uint8 else 65535)



def _named_pairs(d: Path) -> list[str]:
    names = []
    for left in sorted(d.glob("*_left.*")):
        if left.suffix.lower() in _IMAGE_EXTS:
            name = left.name[: -len("_left" + left.suffix)]
            if _find(d, f"{name}_right") is not None:
                names.append(name)
    return names


def _calib_matrix(
    calib: dict[str, np.ndarray | None], keys: tuple[str, ...], shape: tuple[int, ...], path: Path
) -> np.ndarray:
    """The first of ``keys`` found in ``calib``, checked (numbers, count, finite) and reshaped to ``shape``."""
    size = math.prod(shape)
    for key in keys:
        if key in calib:
            v = calib[key]
            if v is None:
                raise FileFormatError(f"{path}: {key} must hold numbers")
            if v.size != size:
                raise FileFormatError(f"{path}: {key} must have {size} numbers, got {v.size}")
            if not np.isfinite(v).all():
                raise FileFormatError(f"{path}: {key} has non-finite numbers")
            return v.reshape(shape)
    raise FileFormatError(f"{path}: missing {' or '.join(keys)}")
