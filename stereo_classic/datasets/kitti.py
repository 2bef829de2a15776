"""KITTI loaders: stereo 2012/2015 (disparity x256), object frames with Velodyne LiDAR, and the LiDAR helpers.

The LiDAR scan is projected into the left rectified image as sparse depth (float32 metres, NaN where no
point); see :func:`project_lidar`.

Example
-------
>>> import numpy as np
>>> from stereo_classic.datasets import project_lidar
>>> P = np.array([[100.0, 0, 50, 0], [0, 100.0, 40, 0], [0, 0, 1, 0]])
>>> Tr = np.hstack([np.eye(3), np.zeros((3, 1))])  # points given in camera coordinates
>>> depth, points = project_lidar(np.array([[0.0, 0.0, 5.0]]), P=P, R0_rect=np.eye(3),
...                               Tr_velo_to_cam=Tr, image_size=(100, 80))
>>> float(depth[40, 50]), int(np.isfinite(depth).sum())
(5.0, 1)
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from calib import RectifiedRig, read_kitti_calib
from stereo_classic.datasets.scene import (
    Scene,
    _calib_matrix,
    _check_shape,
    _find,
    _folder,
    _need,
    _range_from_gt,
    _read_pair,
)
from stereo_classic.io import FileFormatError, read_kitti_disparity

__all__ = [
    "load_kitti_stereo",
    "iter_kitti_stereo",
    "load_kitti_object",
    "iter_kitti_object",
    "load_kitti_lidar_folder",
    "project_lidar",
    "read_kitti_calib_file",
    "read_velodyne",
]


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
