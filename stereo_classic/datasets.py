"""Stereo datasets as :class:`Scene` objects: Middlebury, KITTI (stereo and object + LiDAR), OAK-D.

Every loader returns the pair as read (BGR uint8), the ground truth in the project's convention
(float32 disparity in pixels, NaN where unknown; sparse LiDAR depth in metres, NaN where no point),
the non-occluded mask when the dataset has one, and the :class:`calib.RectifiedRig` when the dataset
says how the pair was taken. Scale factors of the files are applied here and only here.

Layouts (one loader each; :func:`load_scene` and :func:`iter_scenes` pick the right one):

============================  ==================================================================
layout                        files
============================  ==================================================================
Middlebury 2014 / MiddEval3   ``im0.png im1.png disp0GT.pfm|disp0.pfm mask0nocc.png calib.txt``
                              (``trainingQ/H/F/<Scene>``); PFM ``inf`` -> NaN; mask 255 = non-occluded
Middlebury 2001               ``im3 im4 disp3.pgm`` (Tsukuba, x16); ``im2 im6 disp2.pgm`` (Venus,
                              Sawtooth, ..., x8)
Middlebury 2003               ``im2 im6 disp2.png`` (Cones, Teddy quarter size, x4)
Middlebury 2005 / 2006        ``view1 view5 disp1.png`` (x1, see :func:`load_middlebury_classic`)
named pair (Adirondack)       ``<Name>_left.png <Name>_right.png <Name>_gt.png <Name>_mask.png``
KITTI 2012 / 2015 stereo      ``image_2 image_3 disp_occ_0 disp_noc_0 calib_cam_to_cam/`` (2015) or
                              ``colored_0 colored_1 disp_occ disp_noc calib/`` (2012); frames
                              ``<id>_10.png``; disparity x256, 0 unknown
KITTI object + LiDAR          ``training/{image_2,image_3,calib,velodyne}/<id>`` or one folder with
                              ``left.png right.png calib.txt lidar.bin``
OAK-D (stereodemo)            ``<name>_left.png <name>_right.png stereodemo_calibration.json``
============================  ==================================================================

Example
-------
>>> from stereo_classic.datasets import demo_scene
>>> scene = demo_scene()
>>> scene.left.shape, scene.gt_disparity.dtype, round(scene.rig.baseline_m, 6)
((500, 741, 3), dtype('float32'), 0.193001)
"""

from __future__ import annotations

import math
import os
import re
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from calib import RectifiedRig, read_kitti_calib, read_middlebury_calib, read_oakd_calib
from stereo_classic.io import (
    FileFormatError,
    read_image,
    read_kitti_disparity,
    read_pfm,
    read_scaled_disparity,
)

__all__ = [
    "Scene",
    "load_scene",
    "iter_scenes",
    "demo_scene",
    "load_middlebury2014",
    "load_middlebury_classic",
    "load_named_pair",
    "load_kitti_stereo",
    "iter_kitti_stereo",
    "load_kitti_object",
    "iter_kitti_object",
    "load_kitti_lidar_folder",
    "load_oakd",
    "iter_oakd",
    "project_lidar",
    "read_kitti_calib_file",
    "read_velodyne",
]

_IMAGE_EXTS = (".png", ".ppm", ".pgm", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


# --------------------------------------------------------------------------------------------------
# Scene
# --------------------------------------------------------------------------------------------------


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
        Dense ground-truth disparity of the left image (d = x_left - x_right).
    nonocc_mask : (H, W) bool or None
        True where the left pixel is visible in the right image and the ground truth is known.
    rig : calib.RectifiedRig or None
        The rectified geometry, when the dataset gives it.
    gt_depth : (H, W) float32 metres, NaN where no LiDAR point, or None
        Sparse depth (KITTI LiDAR), Z in the left rectified camera frame.
    max_disparity : int or None
        Disparity range that covers the scene (Middlebury ``ndisp``; otherwise the largest ground
        truth disparity rounded up to a multiple of 16).
    lidar_points : (N, 3) float32 metres or None
        LiDAR points that fall inside the left image, in the left rectified camera frame.
    layout : str
        Which loader made it, e.g. ``"middlebury2014"``.
    path : Path or None
        Folder (or file) it came from.
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


# --------------------------------------------------------------------------------------------------
# small helpers
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


# --------------------------------------------------------------------------------------------------
# Middlebury
# --------------------------------------------------------------------------------------------------


def load_middlebury2014(folder: str | os.PathLike) -> Scene:
    """Load one Middlebury 2014 / MiddEval3 scene folder (e.g. ``trainingQ/Motorcycle``).

    Reads ``im0``/``im1``, ``disp0GT.pfm`` (or ``disp0.pfm``; ``inf`` -> NaN), ``mask0nocc.png``
    (255 = non-occluded; pixels with unknown ground truth are False), and ``calib.txt`` (rig via
    :meth:`calib.RectifiedRig.from_middlebury`, baseline converted from mm; ``max_disparity`` =
    ``ndisp``). Files other than the images are optional (test scenes have no ground truth).
    """
    d = _folder(folder, "Middlebury 2014 scene folder")
    left, right = _read_pair(_need(d, "im0", "left image"), _need(d, "im1", "right image"))
    hw = left.shape[:2]
    gt = None
    gt_path = _find(d, "disp0GT", (".pfm",)) or _find(d, "disp0", (".pfm",))
    if gt_path is not None:
        raw = read_pfm(gt_path)
        if raw.ndim != 2:
            raise FileFormatError(f"ground truth {gt_path} must be a grey PFM, got {raw.shape[2]} channels")
        _check_shape(raw, hw, gt_path, "ground truth")
        gt = np.where(np.isfinite(raw), raw, np.nan).astype(np.float32)
    mask = None
    mask_path = _find(d, "mask0nocc", (".png",))
    if mask_path is not None:
        mask = _read_mask(mask_path, hw)
        if gt is not None:
            mask &= np.isfinite(gt)
    rig, max_disp = None, None
    calib_path = d / "calib.txt"
    if calib_path.is_file():
        rig = RectifiedRig.from_middlebury(calib_path, image_size=(hw[1], hw[0]))
        ndisp = read_middlebury_calib(calib_path).get("ndisp")
        if ndisp is not None:
            if isinstance(ndisp, np.ndarray) or not (math.isfinite(ndisp) and float(ndisp).is_integer()):
                raise FileFormatError(f"{calib_path}: ndisp must be a whole number, got {ndisp!r}")
            max_disp = int(ndisp)
    if max_disp is None or max_disp <= 0:
        max_disp = _range_from_gt(gt)
    return Scene(d.name, left, right, gt, mask, rig, None, max_disp, None, "middlebury2014", d)


#: (left stem, right stem, ground-truth stem, {gt extension: scale or None}) of the older Middlebury sets;
#: None: the map stores full-resolution disparities, the scale follows from the image width.
_CLASSIC_LAYOUTS: tuple[tuple[str, str, str, dict[str, float | None]], ...] = (
    ("im3", "im4", "disp3", {".pgm": 16.0, ".png": 16.0}),  # 2001 Tsukuba
    ("im2", "im6", "disp2", {".pgm": 8.0, ".png": None}),  # 2001 Venus & co (pgm x8), 2003 Cones/Teddy (png)
    ("view1", "view5", "disp1", {".png": None, ".pgm": None}),  # 2005 / 2006
)

#: Full-resolution width and the published sizes (factors) of the sets whose maps hold
#: full-resolution disparities: 2003 Cones/Teddy 1800 px (full, half, quarter), 2005/2006
#: 1240..1396 px (full, half, third).
_FULL_SIZES = {"im2": (1800, (1, 2, 4)), "view1": (1390, (1, 2, 3))}


def _full_resolution_scale(left_stem: str, width: int) -> float:
    """Stored value per pixel of disparity for maps that hold full-resolution disparities.

    The published size whose width is nearest: 2003 full 1800 px (x1), half 900 (x2), quarter 450
    (x4); 2005/2006 full 1240..1396 (x1), half 620..698 (x2), third 413..465 (x3).
    """
    full, factors = _FULL_SIZES[left_stem]
    return float(min(factors, key=lambda f: abs(full / f - width)))


def _classic_layout(d: Path) -> tuple[str, str, str, dict[str, float | None]] | None:
    for layout in _CLASSIC_LAYOUTS:
        if _find(d, layout[0]) is not None and _find(d, layout[1]) is not None:
            return layout
    return None


def load_middlebury_classic(folder: str | os.PathLike, *, disparity_scale: float | None = None) -> Scene:
    """Load a Middlebury 2001, 2003, 2005 or 2006 scene folder.

    Ground-truth scale (stored value = disparity x scale, 0 = unknown), as the datasets define it:

    * 2001 Tsukuba ``im3``/``im4`` + ``disp3.pgm``: x16;
    * 2001 Venus, Sawtooth, Bull, Poster, Barn ``im2``/``im6`` + ``disp2.pgm``: x8;
    * 2003 Cones/Teddy ``im2``/``im6`` + ``disp2.png``: the maps hold full-resolution disparities,
      so quarter size (450 px wide, the common download) is x4, half size x2, full size x1;
    * 2005/2006 ``view1``/``view5`` + ``disp1.png``: likewise full-resolution disparities, so third
      size (about 450 px wide) is x3, half size x2, full size (about 1390 px) x1.

    For 2003 and 2005/2006 the published size nearest to the image width gives the factor. Pass
    ``disparity_scale`` to override. These datasets have no calibration: ``rig`` is None and
    ``max_disparity`` is the largest ground truth rounded up to a multiple of 16.
    """
    d = _folder(folder, "Middlebury scene folder")
    layout = _classic_layout(d)
    if layout is None:
        raise FileNotFoundError(
            f"no Middlebury 2001-2006 pair in {d}: expected im3+im4 (Tsukuba), im2+im6 or view1+view5"
        )
    left_stem, right_stem, gt_stem, scales = layout
    left, right = _read_pair(_need(d, left_stem, "left image"), _need(d, right_stem, "right image"))
    gt = None
    gt_path = _find(d, gt_stem, tuple(scales))
    if gt_path is not None:
        scale = disparity_scale
        if scale is None:
            scale = scales[gt_path.suffix.lower()] or _full_resolution_scale(left_stem, left.shape[1])
        gt = read_scaled_disparity(gt_path, scale)
        _check_shape(gt, left.shape[:2], gt_path, "ground truth")
    year = {"im3": "2001", "view1": "2005/2006"}.get(left_stem)
    if year is None:
        year = "2001" if gt_path is not None and gt_path.suffix.lower() == ".pgm" else "2003"
    return Scene(d.name, left, right, gt, None, None, None, _range_from_gt(gt), None, f"middlebury{year}", d)


def _named_pairs(d: Path) -> list[str]:
    names = []
    for left in sorted(d.glob("*_left.*")):
        if left.suffix.lower() in _IMAGE_EXTS:
            name = left.name[: -len("_left" + left.suffix)]
            if _find(d, f"{name}_right") is not None:
                names.append(name)
    return names


def load_named_pair(
    folder: str | os.PathLike, name: str | None = None, *, disparity_scale: float = 1.0
) -> Scene:
    """Load a ``<Name>_left/_right`` pair with optional ``<Name>_gt.png`` and ``<Name>_mask.png``.

    This is the layout of ``../shared/data/adirondackQ`` (Middlebury 2014 Adirondack, quarter size,
    not the official file names): ``_gt.png`` 8-bit, disparity x ``disparity_scale`` (1), 0 = unknown;
    ``_mask.png`` 255 = non-occluded. No calibration: ``rig`` is None.

    Parameters
    ----------
    folder : folder holding the files
    name : pair name; may be omitted when the folder holds exactly one pair.
    """
    d = _folder(folder, "scene folder")
    if name is None:
        names = _named_pairs(d)
        if len(names) != 1:
            raise ValueError(
                f"`name` is needed: {d} holds {len(names)} <name>_left/<name>_right pairs ({', '.join(names[:5])})"
            )
        name = names[0]
    left, right = _read_pair(_need(d, f"{name}_left", "left image"), _need(d, f"{name}_right", "right image"))
    hw = left.shape[:2]
    gt = None
    gt_path = _find(d, f"{name}_gt", (".png", ".pgm", ".pfm"))
    if gt_path is not None:
        if gt_path.suffix.lower() == ".pfm":
            raw = read_pfm(gt_path)
            gt = np.where(np.isfinite(raw), raw, np.nan).astype(np.float32)
        else:
            gt = read_scaled_disparity(gt_path, disparity_scale)
        _check_shape(gt, hw, gt_path, "ground truth")
    mask = None
    mask_path = _find(d, f"{name}_mask", (".png",))
    if mask_path is not None:
        mask = _read_mask(mask_path, hw)
        if gt is not None:
            mask &= np.isfinite(gt)
    return Scene(name, left, right, gt, mask, None, None, _range_from_gt(gt), None, "named_pair", d)


# --------------------------------------------------------------------------------------------------
# OAK-D (stereodemo)
# --------------------------------------------------------------------------------------------------

_OAKD_JSON = "stereodemo_calibration.json"


def _oakd_max_disparity(json_path: Path, rig: Any) -> int | None:
    depth_range = read_oakd_calib(json_path).get("depth_range")  # checked there: 0 < near < far
    if depth_range is None:
        return None
    top = rig.focal_px * rig.baseline_m / depth_range[0] - rig.doffs
    return max(16, int(math.ceil(top / 16.0)) * 16) if top > 0 else None


def load_oakd(folder: str | os.PathLike, name: str) -> Scene:
    """Load one OAK-D pair ``<name>_left.png`` / ``<name>_right.png`` (rectified grey, no ground truth).

    The rig comes from ``stereodemo_calibration.json`` in the same folder
    (:meth:`calib.RectifiedRig.from_oakd_json`); ``max_disparity`` from its ``depth_range`` near limit
    (f B / near, rounded up to 16) when present.
    """
    d = _folder(folder, "OAK-D folder")
    if not isinstance(name, str) or not name:
        raise ValueError(f"`name` must be a non-empty pair name, got {name!r}")
    left, right = _read_pair(_need(d, f"{name}_left", "left image"), _need(d, f"{name}_right", "right image"))
    json_path = d / _OAKD_JSON
    if not json_path.is_file():
        raise FileNotFoundError(f"OAK-D calibration not found: {json_path}")
    rig = RectifiedRig.from_oakd_json(json_path)
    return Scene(name, left, right, None, None, rig, None, _oakd_max_disparity(json_path, rig), None, "oakd", d)


def iter_oakd(folder: str | os.PathLike) -> Iterator[Scene]:
    """Every pair of an OAK-D folder, sorted by name."""
    d = _folder(folder, "OAK-D folder")
    for name in _named_pairs(d):
        yield load_oakd(d, name)


# --------------------------------------------------------------------------------------------------
# KITTI
# --------------------------------------------------------------------------------------------------


def read_kitti_calib_file(path: str | os.PathLike) -> dict[str, np.ndarray | None]:
    """Every ``key: numbers`` line of a KITTI calibration text file, as float64 arrays.

    An alias of :func:`calib.read_kitti_calib` (one parser for the format): object ``calib.txt``
    (``P0``..``P3``, ``R0_rect``, ``Tr_velo_to_cam``) and raw ``calib_*_to_*.txt`` files; non-numeric
    values (``calib_time: ...``) are None; a malformed line raises :class:`calib.CalibrationError`.
    """
    p = Path(os.fspath(path))
    if not p.is_file():
        raise FileNotFoundError(f"KITTI calibration file not found: {p}")
    return read_kitti_calib(p)


def _calib_matrix(calib: dict[str, np.ndarray | None], keys: tuple[str, ...], shape: tuple[int, int], path: Path) -> np.ndarray:
    for key in keys:
        if key in calib:
            v = calib[key]
            if v is None:
                raise FileFormatError(f"{path}: {key} must hold numbers")
            if v.size != shape[0] * shape[1]:
                raise FileFormatError(f"{path}: {key} must have {shape[0] * shape[1]} numbers, got {v.size}")
            if not np.isfinite(v).all():
                raise FileFormatError(f"{path}: {key} has non-finite numbers")
            return v.reshape(shape)
    raise FileFormatError(f"{path}: missing {' or '.join(keys)}")


def read_velodyne(path: str | os.PathLike) -> np.ndarray:
    """Read a KITTI Velodyne scan (``.bin``: float32 x, y, z, reflectance per point).

    Returns
    -------
    points : (N, 4) float32, metres in the Velodyne frame (x forward, y left, z up) and reflectance.
    """
    p = Path(os.fspath(path))
    if not p.exists():
        raise FileNotFoundError(f"Velodyne file not found: {p}")
    if p.is_dir():
        raise FileNotFoundError(f"Velodyne: expected a file, got a directory: {p}")
    size = p.stat().st_size
    if size == 0 or size % 16:
        raise FileFormatError(
            f"Velodyne file {p} must hold float32 x, y, z, r records (a multiple of 16 bytes), got {size} bytes"
        )
    points = np.fromfile(p, dtype="<f4").reshape(-1, 4)
    return points.astype(np.float32, copy=False)


def project_lidar(
    points: np.ndarray,
    *,
    P: np.ndarray,
    R0_rect: np.ndarray,
    Tr_velo_to_cam: np.ndarray,
    image_size: tuple[int, int],
    pixel_rounding: str = "nearest",
    min_depth: float = 0.1,
) -> tuple[np.ndarray, np.ndarray]:
    """Project LiDAR points into a rectified camera image as sparse depth (KITTI convention).

    ``x_image ~ P @ R0_rect @ Tr_velo_to_cam @ X_velo``. The depth is the third component of
    ``P @ ...``, i.e. Z in the frame of the camera ``P`` belongs to (KITTI's P2 includes the small
    offset of camera 2 from camera 0). Where several points fall on one pixel the nearest wins.

    Parameters
    ----------
    points : (N, 3) or (N, 4) float, Velodyne frame, metres (a 4th column, reflectance, is ignored)
    P : (3, 4) projection matrix of the camera (``P2`` for the left colour camera)
    R0_rect : (3, 3) rectifying rotation
    Tr_velo_to_cam : (3, 4) Velodyne -> camera 0
    image_size : (width, height)
    pixel_rounding : {"nearest", "floor"}, keyword-only
        "nearest": the pixel whose centre is closest (integer coordinates are pixel centres);
        "floor": truncate, as ``lidar_depth_left.npy`` in ``../shared/data`` was made.
    min_depth : float, keyword-only
        Points closer than this (metres, including everything behind the camera) are dropped.

    Returns
    -------
    depth : (H, W) float32 metres, NaN where no point
    points_cam : (M, 3) float32, the points that fall inside the image, camera frame
        (X right, Y down, Z forward; ``P = K [I | t]`` -> ``K^-1 P X``).
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] not in (3, 4):
        raise ValueError(f"`points` must have shape (N, 3) or (N, 4), got {pts.shape}")
    P = np.asarray(P, dtype=np.float64)
    R0 = np.asarray(R0_rect, dtype=np.float64)
    Tr = np.asarray(Tr_velo_to_cam, dtype=np.float64)
    for name, m, shape in (("P", P, (3, 4)), ("R0_rect", R0, (3, 3)), ("Tr_velo_to_cam", Tr, (3, 4))):
        if m.shape != shape or not np.isfinite(m).all():
            raise ValueError(f"`{name}` must be a finite {shape} matrix, got shape {m.shape}")
    try:
        width, height = (int(v) for v in image_size)
    except (TypeError, ValueError):
        raise ValueError(f"`image_size` must be (width, height), got {image_size!r}") from None
    if width <= 0 or height <= 0:
        raise ValueError(f"`image_size` must be positive (width, height), got {image_size!r}")
    if pixel_rounding not in ("nearest", "floor"):
        raise ValueError(f"`pixel_rounding` must be 'nearest' or 'floor', got {pixel_rounding!r}")
    if not (isinstance(min_depth, (int, float)) and math.isfinite(min_depth) and min_depth >= 0):
        raise ValueError(f"`min_depth` must be a finite number >= 0, got {min_depth!r}")
    xyz = pts[:, :3]
    xyz = xyz[np.isfinite(xyz).all(axis=1)]
    rect = R0 @ (Tr[:, :3] @ xyz.T + Tr[:, 3:4])  # (3, N) rectified camera 0 frame
    proj = P[:, :3] @ rect + P[:, 3:4]
    w = proj[2]
    front = w > min_depth
    proj, w = proj[:, front], w[front]
    u, v = proj[0] / w, proj[1] / w
    if pixel_rounding == "nearest":
        ui, vi = np.floor(u + 0.5), np.floor(v + 0.5)
    else:
        ui, vi = np.floor(u), np.floor(v)
    inside = (ui >= 0) & (ui < width) & (vi >= 0) & (vi < height)
    ui, vi, z = ui[inside].astype(np.intp), vi[inside].astype(np.intp), w[inside]
    depth = np.full((height, width), np.nan, dtype=np.float32)
    order = np.argsort(-z, kind="stable")  # far first, so the nearest point is written last
    depth[vi[order], ui[order]] = z[order]
    points_cam = np.linalg.solve(P[:, :3], proj[:, inside]).T.astype(np.float32)
    return depth, points_cam


def _kitti_lidar_scene(
    name: str, left_path: Path, right_path: Path, calib_path: Path, velo_path: Path | None, layout: str, where: Path
) -> Scene:
    left, right = _read_pair(left_path, right_path)
    h, w = left.shape[:2]
    rig = RectifiedRig.from_kitti(calib_path, left=2, right=3, image_size=(w, h))
    depth = points_cam = None
    max_disp = None
    if velo_path is not None:
        calib = read_kitti_calib_file(calib_path)
        P2 = _calib_matrix(calib, ("P2", "P_rect_02"), (3, 4), calib_path)
        R0 = _calib_matrix(calib, ("R0_rect", "R_rect_00", "R_rect"), (3, 3), calib_path)
        Tr = _calib_matrix(calib, ("Tr_velo_to_cam", "Tr_velo_cam"), (3, 4), calib_path)
        depth, points_cam = project_lidar(
            read_velodyne(velo_path), P=P2, R0_rect=R0, Tr_velo_to_cam=Tr, image_size=(w, h)
        )
        if np.isfinite(depth).any():
            near = float(np.nanmin(depth))
            max_disp = _range_from_gt(np.array([rig.focal_px * rig.baseline_m / near - rig.doffs]))
    return Scene(name, left, right, None, None, rig, depth, max_disp, points_cam, layout, where)


def load_kitti_lidar_folder(folder: str | os.PathLike) -> Scene:
    """Load one KITTI object frame kept in a single folder (``../shared/data/kitti_object_pair``).

    Files: ``left.png`` and ``right.png`` (or ``image_2.png``/``image_3.png``), ``calib.txt`` (object
    format: ``P0``..``P3``, ``R0_rect``, ``Tr_velo_to_cam``) and ``lidar.bin`` (or ``velodyne.bin``).
    The LiDAR points are projected into the left image (P2) as ``gt_depth``; see :func:`project_lidar`.
    """
    d = _folder(folder, "KITTI frame folder")
    left = _find(d, "left") or _find(d, "image_2")
    right = _find(d, "right") or _find(d, "image_3")
    if left is None or right is None:
        raise FileNotFoundError(f"KITTI frame folder {d} needs left.png and right.png (or image_2/image_3)")
    calib_path = d / "calib.txt"
    if not calib_path.is_file():
        raise FileNotFoundError(f"KITTI calibration not found: {calib_path}")
    velo = _find(d, "lidar", (".bin",)) or _find(d, "velodyne", (".bin",))
    return _kitti_lidar_scene(d.name, left, right, calib_path, velo, "kitti_lidar", d)


def _training_dir(root: Path, markers: tuple[str, ...]) -> Path:
    if any((root / m).is_dir() for m in markers):
        return root
    if (root / "training").is_dir():
        return root / "training"
    raise FileNotFoundError(f"{root} is not a KITTI folder: expected {', '.join(markers)} or training/")


def _frame_id(frame: int | str, suffix: str = "") -> str:
    if isinstance(frame, bool):
        raise TypeError(f"`frame` must be an int or a str id, got {frame!r}")
    if isinstance(frame, (int, np.integer)):
        if frame < 0:
            raise ValueError(f"`frame` must be >= 0, got {frame}")
        return f"{int(frame):06d}{suffix}"
    if isinstance(frame, str) and re.fullmatch(r"[\w.-]+", frame):
        stem = frame.rsplit(".", 1)[0] if frame.endswith(".png") else frame
        return stem if (not suffix or stem.endswith(suffix)) else stem + suffix
    raise ValueError(f"`frame` must be an int or an id like '000000', got {frame!r}")


_KITTI_STEREO_DIRS = (  # (left, right, disp_occ, disp_noc)
    ("image_2", "image_3", "disp_occ_0", "disp_noc_0"),  # 2015
    ("colored_0", "colored_1", "disp_occ", "disp_noc"),  # 2012 colour
    ("image_0", "image_1", "disp_occ", "disp_noc"),  # 2012 grey
)


def _kitti_stereo_dirs(t: Path) -> tuple[str, str, str, str] | None:
    for dirs in _KITTI_STEREO_DIRS:
        if (t / dirs[0]).is_dir() and (t / dirs[1]).is_dir():
            return dirs
    return None


def _kitti_stereo_calib(t: Path, fid: str) -> Path | None:
    seq = fid.split("_")[0]
    for candidate in (
        t / "calib_cam_to_cam" / f"{seq}.txt",
        t / "calib" / f"{seq}.txt",
        t / "calib_cam_to_cam.txt",
        t / "calib.txt",
    ):
        if candidate.is_file():
            return candidate
    return None


def load_kitti_stereo(root: str | os.PathLike, frame: int | str) -> Scene:
    """Load frame ``frame`` (``<id>_10.png``) of a KITTI 2012 or 2015 stereo folder.

    Parameters
    ----------
    root : the ``training`` (or ``testing``) folder, or the folder above it
    frame : 0, "000000" or "000000_10"

    ``gt_disparity`` is ``disp_occ_0`` (``disp_occ`` in 2012; x256, 0 -> NaN); ``nonocc_mask`` is where
    ``disp_noc_0`` is known. The rig comes from ``calib_cam_to_cam/<id>.txt`` (2015, ``P_rect_02/03``)
    or ``calib/<id>.txt`` (2012, ``P2/P3``; for the grey ``image_0/1`` pair ``P0/P1``) when present.
    """
    r = _folder(root, "KITTI stereo folder")
    t = _training_dir(r, ("image_2", "colored_0", "image_0"))
    dirs = _kitti_stereo_dirs(t)
    if dirs is None:
        raise FileNotFoundError(f"{t} has no KITTI stereo image folders (image_2+image_3 or colored_0+colored_1)")
    fid = _frame_id(frame, "_10")
    left, right = _read_pair(_need(t / dirs[0], fid, "left image"), _need(t / dirs[1], fid, "right image"))
    hw = left.shape[:2]
    gt = mask = None
    occ = t / dirs[2] / f"{fid}.png"
    noc = t / dirs[3] / f"{fid}.png"
    if occ.is_file():
        gt = read_kitti_disparity(occ)
        _check_shape(gt, hw, occ, "ground truth")
    if noc.is_file():
        noc_disp = read_kitti_disparity(noc)
        _check_shape(noc_disp, hw, noc, "ground truth")
        mask = np.isfinite(noc_disp)
        if gt is None:
            gt = noc_disp
    rig = None
    calib_path = _kitti_stereo_calib(t, fid)
    if calib_path is not None:
        cams = (0, 1) if dirs[0] == "image_0" else (2, 3)
        rig = RectifiedRig.from_kitti(calib_path, left=cams[0], right=cams[1], image_size=(hw[1], hw[0]))
    return Scene(fid, left, right, gt, mask, rig, None, _range_from_gt(gt), None, "kitti_stereo", t)


def _kitti_stereo_frames(t: Path, dirs: tuple[str, ...]) -> list[str]:
    return sorted(p.stem for p in (t / dirs[0]).glob("*_10.png") if (t / dirs[1] / p.name).is_file())


def iter_kitti_stereo(root: str | os.PathLike) -> Iterator[Scene]:
    """Every ``<id>_10`` frame of a KITTI 2012/2015 stereo folder, sorted."""
    t = _training_dir(_folder(root, "KITTI stereo folder"), ("image_2", "colored_0", "image_0"))
    dirs = _kitti_stereo_dirs(t)
    if dirs is None:
        raise FileNotFoundError(f"{t} has no KITTI stereo image folders (image_2+image_3 or colored_0+colored_1)")
    for fid in _kitti_stereo_frames(t, dirs):
        yield load_kitti_stereo(t, fid)


def load_kitti_object(root: str | os.PathLike, frame: int | str) -> Scene:
    """Load frame ``frame`` of the KITTI object layout (``image_2``, ``image_3``, ``calib``, ``velodyne``).

    ``root`` is the ``training`` folder or the folder above it. The Velodyne scan (when present) is
    projected into the left image (P2) as ``gt_depth``; see :func:`project_lidar`.
    """
    r = _folder(root, "KITTI object folder")
    t = _training_dir(r, ("velodyne", "calib"))
    fid = _frame_id(frame)
    left = _need(t / "image_2", fid, "left image")
    right = _need(t / "image_3", fid, "right image")
    calib_path = t / "calib" / f"{fid}.txt"
    if not calib_path.is_file():
        raise FileNotFoundError(f"KITTI calibration not found: {calib_path}")
    velo = t / "velodyne" / f"{fid}.bin"
    return _kitti_lidar_scene(fid, left, right, calib_path, velo if velo.is_file() else None, "kitti_object", t)


def _kitti_object_frames(t: Path) -> list[str]:
    return sorted(
        p.stem for p in (t / "image_2").glob("*.png")
        if (t / "image_3" / p.name).is_file() and (t / "calib" / f"{p.stem}.txt").is_file()
    )  # fmt: skip


def iter_kitti_object(root: str | os.PathLike) -> Iterator[Scene]:
    """Every frame of a KITTI object folder (with ``image_2``, ``image_3`` and ``calib``), sorted."""
    t = _training_dir(_folder(root, "KITTI object folder"), ("velodyne", "calib"))
    for fid in _kitti_object_frames(t):
        yield load_kitti_object(t, fid)


# --------------------------------------------------------------------------------------------------
# demo
# --------------------------------------------------------------------------------------------------

#: Rig of ``skimage.data.stereo_motorcycle`` (Middlebury 2014 Motorcycle at 741 x 500).
DEMO_FOCAL_PX = 994.978
DEMO_BASELINE_M = 0.193001
DEMO_DOFFS_PX = 31.086
DEMO_CX_LEFT_PX = 311.193
DEMO_CY_PX = 254.877


def demo_scene() -> Scene:
    """The Middlebury Motorcycle pair that ships with scikit-image (works offline).

    ``skimage.data.stereo_motorcycle()`` returns RGB images and a disparity with ``inf`` for unknown;
    here they become BGR and NaN. Rig as ``stereo_motorcycle.__doc__`` gives it: f = 994.978 px,
    baseline 0.193001 m, principal point x 311.193 px, y 254.877 px, dx (doffs) 31.086 px, so
    ``cx_left = 311.193``, ``cx_right = cx_left + doffs``, ``cy = 254.877``.
    """
    from skimage import data

    rgb_left, rgb_right, disp = data.stereo_motorcycle()
    left = np.ascontiguousarray(cv2.cvtColor(rgb_left, cv2.COLOR_RGB2BGR))
    right = np.ascontiguousarray(cv2.cvtColor(rgb_right, cv2.COLOR_RGB2BGR))
    gt = np.where(np.isfinite(disp), disp, np.nan).astype(np.float32)
    h, w = gt.shape
    rig = RectifiedRig(
        focal_px=DEMO_FOCAL_PX,
        cx_left=DEMO_CX_LEFT_PX,
        cx_right=DEMO_CX_LEFT_PX + DEMO_DOFFS_PX,
        cy=DEMO_CY_PX,
        baseline_m=DEMO_BASELINE_M,
        image_size=(w, h),
    )
    return Scene("motorcycle (skimage)", left, right, gt, None, rig, None, _range_from_gt(gt), None, "demo", None)


# --------------------------------------------------------------------------------------------------
# discovery
# --------------------------------------------------------------------------------------------------

SceneRef = tuple[str, Callable[[], Scene]]


def _scan(d: Path) -> list[SceneRef] | None:
    """The scenes a folder holds as one layout, or None when it is not a scene folder."""
    if _find(d, "im0") is not None and _find(d, "im1") is not None:
        return [(d.name, lambda: load_middlebury2014(d))]
    if _classic_layout(d) is not None:
        return [(d.name, lambda: load_middlebury_classic(d))]
    if (d / "calib.txt").is_file() and (_find(d, "lidar", (".bin",)) or _find(d, "velodyne", (".bin",))):
        return [(d.name, lambda: load_kitti_lidar_folder(d))]
    if (d / "image_2").is_dir() and (d / "image_3").is_dir() and (d / "calib").is_dir() and (d / "velodyne").is_dir():
        return [(fid, lambda fid=fid: load_kitti_object(d, fid)) for fid in _kitti_object_frames(d)]
    dirs = _kitti_stereo_dirs(d)
    if dirs is not None:
        return [(fid, lambda fid=fid: load_kitti_stereo(d, fid)) for fid in _kitti_stereo_frames(d, dirs)]
    names = _named_pairs(d)
    if names:
        if (d / _OAKD_JSON).is_file():
            return [(n, lambda n=n: load_oakd(d, n)) for n in names]
        return [(n, lambda n=n: load_named_pair(d, n)) for n in names]
    return None


def iter_scenes(root: str | os.PathLike, *, skip_errors: bool = False) -> Iterator[Scene]:
    """Every scene found at or below ``root``, in sorted path order, loaded one at a time.

    A folder recognised as a layout (see the module docstring) is not searched further; hidden folders
    are skipped.

    Parameters
    ----------
    root : folder to search
    skip_errors : bool, keyword-only
        False (default): a scene that fails to load raises (``FileNotFoundError``/``ValueError`` naming
        the file). True: it is skipped with a ``UserWarning`` that says which and why.
    """
    top = _folder(root, "dataset folder")
    stack = [top]
    while stack:
        d = stack.pop()
        refs = _scan(d)
        if refs is not None:
            for name, load in refs:
                try:
                    scene = load()
                except (OSError, ValueError) as exc:
                    if not skip_errors:
                        raise
                    warnings.warn(f"skipped scene {name!r} in {d}: {exc}", UserWarning, stacklevel=2)
                    continue
                yield scene
            continue
        subdirs = sorted((p for p in d.iterdir() if p.is_dir() and not p.name.startswith(".")), reverse=True)
        stack.extend(subdirs)


def _first_scene_folder_below(d: Path, depth: int = 3) -> Path | None:
    if depth == 0:
        return None
    try:
        subdirs = sorted(p for p in d.iterdir() if p.is_dir() and not p.name.startswith("."))
    except OSError:
        return None
    for sub in subdirs:
        if _scan(sub):
            return sub
        found = _first_scene_folder_below(sub, depth - 1)
        if found is not None:
            return found
    return None


def load_scene(path: str | os.PathLike) -> Scene:
    """Load the scene at ``path``, whatever its layout.

    ``path`` may be a scene folder (Middlebury, Adirondack-style, KITTI LiDAR frame folder), a pair
    name inside a folder of ``<name>_left/_right`` pairs (``.../oakd/toy``), or the left image of such
    a pair (``.../oakd/toy_left.png``). Folders holding several scenes (KITTI, OAK-D) raise
    ``ValueError`` pointing at :func:`iter_scenes` or the per-layout loader.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"`path` must be a str or os.PathLike, got {type(path).__name__}")
    p = Path(os.fspath(path))
    if p.is_file():
        m = re.fullmatch(r"(.+)_left", p.stem)
        if m and p.suffix.lower() in _IMAGE_EXTS:
            p = p.parent / m.group(1)
        else:
            raise ValueError(f"`path` {p} is a file: pass a scene folder or a <name>_left image")
    if not p.exists():
        if p.parent.is_dir() and _find(p.parent, f"{p.name}_left") is not None:
            if (p.parent / _OAKD_JSON).is_file():
                return load_oakd(p.parent, p.name)
            return load_named_pair(p.parent, p.name)
        raise FileNotFoundError(f"scene not found: {p}")
    refs = _scan(p)
    if refs is None:
        below = _first_scene_folder_below(p)
        if below is not None:
            raise ValueError(
                f"{p} is not a scene folder but holds scenes below it (e.g. {below}): use "
                f"iter_scenes({str(p)!r}) or load_scene on one of them"
            )
        raise FileFormatError(
            f"no supported stereo layout in {p}: expected Middlebury (im0/im1, im2/im6, im3/im4, view1/view5), "
            "<name>_left/_right, KITTI (image_2/image_3) or a KITTI frame with calib.txt + lidar.bin"
        )
    if len(refs) != 1:
        names = ", ".join(name for name, _ in refs[:4])
        raise ValueError(
            f"{p} holds {len(refs)} scenes ({names}, ...): use iter_scenes({str(p)!r}) or the loader of its "
            "layout with a name or frame (load_oakd, load_named_pair, load_kitti_stereo, load_kitti_object)"
        )
    return refs[0][1]()
