"""DrivingStereo (Yang et al., CVPR 2019): urban driving frames with projected-LiDAR disparity and depth.

Layout, as the dataset ships it (half resolution, 881 x 400; ``test-`` instead of ``train-`` for the
test split; frames are named ``<sequence>_<timestamp>``)::

    <root>/train-left-image/<sequence>/<frame>.jpg
    <root>/train-right-image/<sequence>/<frame>.jpg
    <root>/train-disparity-map/<sequence>/<frame>.png   16-bit, disparity x 256, 0 = unknown
    <root>/train-depth-map/<sequence>/<frame>.png       16-bit, depth in metres x 256, 0 = unknown
    <root>/half-image-calib/<sequence>.txt              KITTI raw style, cameras 101 (left), 103 (right)

The rig: focal length and left principal point from ``P_rect_101``, right principal point from
``P_rect_103``, baseline ``|T_103[0]|`` in metres. The ``tx`` entry of ``P_rect_103`` is in
full-resolution pixels (twice what the half-size images need), so it is not used. On every pixel where
both maps are known, disparity x depth = f x B (about 546.4 px m).

Usage (needs files that are not part of the package)::

    from stereo_classic.datasets import iter_drivingstereo
    scene = next(iter_drivingstereo("../shared/data/drivingstereo"))
    scene.image_size, round(scene.rig.focal_px, 3), round(scene.rig.baseline_m, 4)
    # -> ((881, 400), 1003.556, 0.5446)
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Iterator
from pathlib import Path

from calib import CalibrationError, RectifiedRig, read_kitti_calib
from stereo_classic.datasets.scene import (
    Scene,
    _calib_matrix,
    _check_shape,
    _folder,
    _need,
    _range_from_gt,
    _read_pair,
)
from stereo_classic.io import FileFormatError, read_kitti_depth, read_kitti_disparity

__all__ = ["load_drivingstereo", "iter_drivingstereo"]

_SPLITS = ("train", "test")
_FRAME_EXTS = (".jpg", ".jpeg", ".png")
_CALIB_DIR = "half-image-calib"


def _check_split(split: str) -> str:
    if split not in _SPLITS:
        raise ValueError(f"`split` must be one of {', '.join(map(repr, _SPLITS))}, got {split!r}")
    return split


def _frame_name(frame: str) -> tuple[str, str]:
    """(frame id, sequence) of ``frame`` (``<sequence>_<timestamp>``, an image or map suffix allowed)."""
    if not isinstance(frame, str):
        raise TypeError(f"`frame` must be a str frame name, got {type(frame).__name__}")
    stem = re.sub(r"\.(jpe?g|png)$", "", frame, flags=re.IGNORECASE)
    m = re.fullmatch(r"([\w-][\w.-]*?)_[\w.-]+", stem)
    if m is None:
        raise ValueError(
            f"`frame` must be a DrivingStereo frame name '<sequence>_<timestamp>' such as "
            f"'2018-07-09-16-11-56_2018-07-09-16-11-57-201', got {frame!r}"
        )
    return stem, m.group(1)


def _drivingstereo_rig(path: Path, image_size: tuple[int, int]) -> RectifiedRig:
    """The rectified rig of a DrivingStereo ``half-image-calib/<sequence>.txt`` for images of ``image_size``.

    Parameters
    ----------
    path : the calibration file (KITTI raw style: ``key: numbers`` lines)
    image_size : (width, height) of the images, pixels

    Raises
    ------
    calib.CalibrationError
        A line that is not ``key: values`` (file and line named), or values the rig refuses (e.g. a
        baseline out of range).
    FileFormatError
        A missing or malformed ``P_rect_101``, ``P_rect_103`` or ``T_103``, two projections that do not
        form a rectified pair, or an ``S_rect_101`` that disagrees with the images.
    """
    values = read_kitti_calib(path)
    p_left = _calib_matrix(values, ("P_rect_101",), (3, 4), path)
    p_right = _calib_matrix(values, ("P_rect_103",), (3, 4), path)
    t_right = _calib_matrix(values, ("T_103",), (3,), path)
    if "S_rect_101" in values:
        size = _calib_matrix(values, ("S_rect_101",), (2,), path)
        if (float(size[0]), float(size[1])) != (float(image_size[0]), float(image_size[1])):
            raise FileFormatError(
                f"{path}: S_rect_101 says {size[0]:g}x{size[1]:g} images, the images are "
                f"{image_size[0]}x{image_size[1]}"
            )
    focal = float(p_left[0, 0])
    if not (math.isclose(float(p_right[0, 0]), focal, rel_tol=1e-3) and abs(p_right[1, 2] - p_left[1, 2]) <= 0.5):
        raise FileFormatError(
            f"{path}: P_rect_101 and P_rect_103 must share the focal length and cy of a rectified pair, got "
            f"f {focal:g} / {p_right[0, 0]:g} px, cy {p_left[1, 2]:g} / {p_right[1, 2]:g} px"
        )
    try:
        return RectifiedRig(
            focal_px=focal,
            cx_left=float(p_left[0, 2]),
            cx_right=float(p_right[0, 2]),
            cy=float(p_left[1, 2]),
            baseline_m=abs(float(t_right[0])),
            image_size=image_size,
        )
    except CalibrationError as exc:  # the rig checks its values; say which file they came from
        raise CalibrationError(f"{path}: {exc}") from exc


def load_drivingstereo(root: str | os.PathLike, frame: str, *, split: str = "train") -> Scene:
    """Load one frame of a DrivingStereo folder.

    Parameters
    ----------
    root : str or os.PathLike
        The folder holding ``train-left-image``, ``train-right-image``, ... and ``half-image-calib``.
    frame : str
        Frame name ``<sequence>_<timestamp>``, e.g. ``"2018-07-09-16-11-56_2018-07-09-16-11-57-201"``
        (a ``.jpg``/``.png`` suffix is allowed).
    split : {"train", "test"}, keyword-only
        Which set of folders (``train-*`` or ``test-*``).

    Returns
    -------
    Scene
        ``left``/``right`` (H, W, 3) uint8 BGR; ``gt_disparity`` (H, W) float32 pixels from
        ``<split>-disparity-map`` and ``gt_depth`` (H, W) float32 metres from ``<split>-depth-map``
        (NaN where unknown; None when the map is absent); ``rig`` from ``half-image-calib/<sequence>.txt``
        (None when absent); ``max_disparity`` the largest ground truth rounded up to 16; layout
        ``"drivingstereo"``; ``path`` the root folder.

    Raises
    ------
    FileNotFoundError
        The root, the left or the right image is missing (the file is named).
    FileFormatError, calib.CalibrationError
        Unreadable images or maps, maps of another size, a malformed calibration file (file and key or
        line named).
    """
    r = _folder(root, "DrivingStereo folder")
    s = _check_split(split)
    fid, seq = _frame_name(frame)
    left, right = _read_pair(
        _need(r / f"{s}-left-image" / seq, fid, "left image", _FRAME_EXTS),
        _need(r / f"{s}-right-image" / seq, fid, "right image", _FRAME_EXTS),
    )
    hw = left.shape[:2]
    gt = depth = None
    disp_path = r / f"{s}-disparity-map" / seq / f"{fid}.png"
    if disp_path.is_file():
        gt = read_kitti_disparity(disp_path)
        _check_shape(gt, hw, disp_path, "ground truth")
    depth_path = r / f"{s}-depth-map" / seq / f"{fid}.png"
    if depth_path.is_file():
        depth = read_kitti_depth(depth_path)
        _check_shape(depth, hw, depth_path, "depth map")
    rig = None
    calib_path = r / _CALIB_DIR / f"{seq}.txt"
    if calib_path.is_file():
        rig = _drivingstereo_rig(calib_path, (hw[1], hw[0]))
    return Scene(fid, left, right, gt, None, rig, depth, _range_from_gt(gt), None, "drivingstereo", r)


def _drivingstereo_splits(root: Path) -> list[str]:
    """The splits of ``root`` that have both a left and a right image folder, in the order train, test."""
    return [s for s in _SPLITS if (root / f"{s}-left-image").is_dir() and (root / f"{s}-right-image").is_dir()]


def _drivingstereo_frames(root: Path, split: str) -> list[str]:
    """Every left image ``<sequence>/<sequence>_<timestamp>.<ext>`` of a split, as sorted frame names."""
    frames = []
    left_dir = root / f"{split}-left-image"
    for seq in sorted(p for p in left_dir.iterdir() if p.is_dir() and not p.name.startswith(".")):
        for image in seq.iterdir():
            if image.suffix.lower() in _FRAME_EXTS and image.stem.startswith(f"{seq.name}_") and image.is_file():
                frames.append(image.stem)
    return sorted(frames)


def iter_drivingstereo(root: str | os.PathLike, *, split: str = "train") -> Iterator[Scene]:
    """Every frame of a DrivingStereo folder (one per left image), sorted by sequence and time.

    A left image without its right image raises ``FileNotFoundError`` when its turn comes (use
    :func:`stereo_classic.datasets.iter_scenes` with ``skip_errors=True`` to skip such frames).
    """
    r = _folder(root, "DrivingStereo folder")
    s = _check_split(split)
    if s not in _drivingstereo_splits(r):
        raise FileNotFoundError(f"{r} is not a DrivingStereo folder: expected {s}-left-image/ and {s}-right-image/")
    for fid in _drivingstereo_frames(r, s):
        yield load_drivingstereo(r, fid, split=s)
