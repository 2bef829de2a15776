"""KITTI calibration text files: object/tracking ``calib.txt`` (``P0:``..``P3:``) and raw ``calib_cam_to_cam.txt``.

Readers return plain values; ``RectifiedRig.from_kitti`` and ``StereoRig.from_kitti`` build the rigs.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np

from calib.errors import CalibrationError
from calib.formats._common import PathLike, finite, read_text, rectified_from_projections
from calib.geometry import check_image_size

__all__ = ["KITTI_OBJECT_IMAGE_SIZE", "read_kitti_calib", "read_rectified", "read_raw_stereo"]

log = logging.getLogger(__name__)

#: Size of most KITTI object/tracking images; ``from_kitti`` uses it when neither the file nor the caller says.
KITTI_OBJECT_IMAGE_SIZE = (1242, 375)


def read_kitti_calib(path: PathLike) -> dict[str, np.ndarray | None]:
    """All ``key: numbers`` lines of a KITTI calibration text file.

    Returns
    -------
    dict
        Key -> ``(n,) float64`` array of the numbers on its line, as stored (None where the value is not
        numeric, e.g. ``calib_time: 09-Jan-2012 13:57:47``).
    """
    path, text = read_text(path, "KITTI calibration")
    out: dict[str, np.ndarray | None] = {}
    for line_no, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        key, sep, rest = line.partition(":")
        if not sep or not key.strip() or " " in key.strip():
            raise CalibrationError(f"{path}: line {line_no} is not `key: values`: {line[:60]!r}")
        try:
            out[key.strip()] = np.array([float(v) for v in rest.split()], dtype=np.float64)
        except ValueError:
            out[key.strip()] = None  # e.g. calib_time: 09-Jan-2012 13:57:47
    if not out:
        raise CalibrationError(f"{path}: no `key: values` lines")
    return out


def _kitti_value(path: Path, values: dict[str, np.ndarray | None], key: str, shape: tuple[int, ...]) -> np.ndarray:
    if key not in values:
        raise CalibrationError(f"{path}: missing key `{key}`")
    arr = values[key]
    if arr is None:
        raise CalibrationError(f"{path}: key `{key}` must hold numbers")
    if arr.size != int(np.prod(shape)):
        raise CalibrationError(f"{path}: key `{key}` must hold {int(np.prod(shape))} numbers ({shape}), got {arr.size}")
    return finite(path, key, arr.reshape(shape))


def _kitti_indices(left: Any, right: Any) -> tuple[int, int]:
    for name, value in (("left", left), ("right", right)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value <= 3:
            raise CalibrationError(f"`{name}` must be a KITTI camera index 0..3, got {value!r}")
    if left == right:
        raise CalibrationError(f"`left` and `right` must be different cameras, got {left} and {right}")
    return int(left), int(right)


def read_rectified(path: PathLike, *, left: int = 2, right: int = 3,
                   image_size: tuple[int, int] | None = None) -> dict[str, Any]:
    """The rectified geometry of KITTI ``calib.txt`` (``P0:``..``P3:``) or raw ``calib_cam_to_cam.txt``.

    ``baseline = (P_left[0,3] - P_right[0,3]) / P_left[0,0]``. The image size comes from ``S_rect_0N`` (raw
    files), ``image_size=``, or else :data:`KITTI_OBJECT_IMAGE_SIZE` (1242x375, logged: object frames vary
    slightly in size, pass the real one when you know it).

    Parameters
    ----------
    path : str or os.PathLike
    left, right : int in 0..3
        KITTI camera indices (2, 3: the colour cameras).
    image_size : (width, height) or None

    Returns
    -------
    dict
        ``focal_px``, ``cx_left``, ``cx_right``, ``cy`` (pixels), ``baseline_m`` (metres), ``image_size``.
    """
    left, right = _kitti_indices(left, right)
    values = read_kitti_calib(path)
    path = Path(path)
    if f"P_rect_0{left}" in values or "P_rect_00" in values:
        kl, kr, ks = f"P_rect_0{left}", f"P_rect_0{right}", f"S_rect_0{left}"
    else:
        kl, kr, ks = f"P{left}", f"P{right}", None
    p_left = _kitti_value(path, values, kl, (3, 4))
    p_right = _kitti_value(path, values, kr, (3, 4))
    if image_size is not None:
        size = check_image_size("image_size", image_size)
    elif ks is not None and ks in values:
        s = _kitti_value(path, values, ks, (2,))
        if not all(float(v).is_integer() and v > 0 for v in s):
            raise CalibrationError(f"{path}: key `{ks}` must be two positive integers, got {s.tolist()}")
        size = (int(s[0]), int(s[1]))
    else:
        size = KITTI_OBJECT_IMAGE_SIZE
        log.info("%s: no image size in the file, assuming KITTI's %dx%d", path, *size)
    return rectified_from_projections(path, p_left, p_right, size, (kl, kr))


def read_raw_stereo(path: PathLike, *, left: int = 2, right: int = 3) -> dict[str, Any]:
    """The raw (unrectified) stereo calibration of KITTI raw ``calib_cam_to_cam.txt``.

    Each camera ``i`` has ``X_i = R_0i X_0 + T_0i``; the pose of ``right`` relative to ``left`` follows.

    Returns
    -------
    dict
        ``K_left``, ``dist_left``, ``K_right``, ``dist_right``, ``R`` (float64), ``T`` (3,) float64 metres,
        ``image_size`` (from ``S_0N``): the arguments of ``StereoRig``.
    """
    left, right = _kitti_indices(left, right)
    values = read_kitti_calib(path)
    path = Path(path)
    if f"K_0{left}" not in values and f"P{left}" in values:
        raise CalibrationError(
            f"{path}: a KITTI object calib.txt holds only rectified projections (no `K_0{left}`): use RectifiedRig.from_kitti"
        )

    def cam(i: int) -> tuple[np.ndarray, ...]:
        return (_kitti_value(path, values, f"K_0{i}", (3, 3)), _kitti_value(path, values, f"D_0{i}", (5,)),
                _kitti_value(path, values, f"R_0{i}", (3, 3)), _kitti_value(path, values, f"T_0{i}", (3,)),
                _kitti_value(path, values, f"S_0{i}", (2,)))

    kl, dl, rl, tl, sl = cam(left)
    kr, dr, rr, tr, sr = cam(right)
    if not np.array_equal(sl, sr) or not all(float(v).is_integer() and v > 0 for v in sl):
        raise CalibrationError(f"{path}: keys `S_0{left}`/`S_0{right}` must be the same two positive integers, got {sl.tolist()} and {sr.tolist()}")
    r_rel = rr @ rl.T
    t_rel = tr - r_rel @ tl
    return {"K_left": kl, "dist_left": dl, "K_right": kr, "dist_right": dr, "R": r_rel, "T": t_rel,
            "image_size": (int(sl[0]), int(sl[1]))}
