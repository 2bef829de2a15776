"""Integer-coded maps: KITTI 16-bit disparity and depth PNGs (x 256), Middlebury scaled disparity PGM/PNG.

Inside the project disparity is float32 pixels and depth float32 metres, NaN for unknown; the scale
factors of these files (KITTI x256, Middlebury x4/x8/x16) and their "0 = unknown" exist only here.

Example
-------
>>> import numpy as np, tempfile, pathlib
>>> from stereo_classic.io import read_kitti_disparity, write_kitti_disparity
>>> path = pathlib.Path(tempfile.mkdtemp()) / "000000_10.png"
>>> write_kitti_disparity(path, np.array([[1.5, np.nan]], np.float32))
>>> read_kitti_disparity(path)
array([[1.5, nan]], dtype=float32)
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from stereo_classic.io._common import (
    PathLike,
    as_path,
    as_real_array,
    encode_image,
    read_single_channel,
)
from stereo_classic.io.atomic import atomic_write
from stereo_classic.io.errors import FileFormatError

__all__ = [
    "read_kitti_disparity",
    "write_kitti_disparity",
    "read_kitti_depth",
    "write_kitti_depth",
    "read_scaled_disparity",
    "write_scaled_disparity",
]


def read_kitti_disparity(path: PathLike) -> np.ndarray:
    """Read a KITTI 2012/2015 disparity PNG (uint16, disparity x 256, 0 = unknown).

    Returns
    -------
    disparity : (H, W) float32, pixels, NaN where unknown.
    """
    p, raw = read_single_channel(path, "KITTI disparity")
    if raw.dtype != np.uint16:
        raise FileFormatError(f"KITTI disparity {p} must be a 16-bit PNG, got {raw.dtype}")
    return _from_x256(raw)


def _from_x256(raw: np.ndarray) -> np.ndarray:
    """KITTI's 16-bit coding (value x 256, 0 = unknown) as float32 with NaN for unknown."""
    values = raw.astype(np.float32) / np.float32(256.0)
    values[raw == 0] = np.nan
    return values


def _write_x256(p: Path, values: np.ndarray, known: np.ndarray) -> None:
    """Write ``values`` (checked: known ones in [0, 65535/256]) as KITTI's 16-bit PNG, atomically.

    A known value that rounds to 0 is stored as 1/256 so that it stays known.
    """
    raw = np.zeros(values.shape, dtype=np.uint16)
    raw[known] = np.clip(np.rint(values[known] * 256.0), 1, 65535).astype(np.uint16)
    data = encode_image(p, raw)
    with atomic_write(p, "wb") as f:
        f.write(data)


def _check_disparity(disparity: Any, name: str = "disparity") -> np.ndarray:
    d = as_real_array(disparity, name)
    if d.ndim != 2 or d.shape[0] == 0 or d.shape[1] == 0:
        raise ValueError(f"`{name}` must be a non-empty (H, W) array, got shape {d.shape}")
    return d.astype(np.float64, copy=False)


def write_kitti_disparity(path: PathLike, disparity: np.ndarray) -> None:
    """Write a disparity map as a KITTI 16-bit PNG (x 256, rounded; NaN -> 0 = unknown), atomically.

    A known disparity of exactly 0 is stored as 1/256 px (the KITTI devkit does the same) so it stays
    known. Negative values, +-inf and values above 65535/256 (~256 px) cannot be stored and raise
    ``ValueError``.
    """
    p = as_path(path)
    d = _check_disparity(disparity)
    known = ~np.isnan(d)
    vals = d[known]
    if vals.size:
        bad = ~np.isfinite(vals) | (vals < 0) | (vals > 65535 / 256.0)
        if bad.any():
            raise ValueError(
                "`disparity` values must be NaN (unknown) or in [0, 255.996] px for a KITTI PNG, got "
                f"{int(bad.sum())} values outside (min {np.min(vals)}, max {np.max(vals)})"
            )
    if p.suffix.lower() != ".png":
        raise ValueError(f"KITTI disparity must be written as .png, got {p.name}")
    _write_x256(p, d, known)



def read_kitti_depth(path: PathLike) -> np.ndarray:
    """Read a KITTI-style 16-bit depth PNG (depth in metres x 256, 0 = no measurement).

    The format of KITTI depth completion and of the DrivingStereo ``*-depth-map`` folders.

    Returns
    -------
    depth : (H, W) float32, metres, NaN where unknown.

    Raises
    ------
    FileNotFoundError, FileFormatError
        Missing file; not a PNG OpenCV reads, several channels, or not 16-bit.
    """
    p, raw = read_single_channel(path, "depth map")
    if raw.dtype != np.uint16:
        raise FileFormatError(f"depth map {p} must be a 16-bit PNG (metres x 256), got {raw.dtype}")
    return _from_x256(raw)


def write_kitti_depth(path: PathLike, depth: np.ndarray) -> None:
    """Write a depth map as a KITTI-style 16-bit PNG (metres x 256, rounded; NaN -> 0 = unknown), atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Target ``.png`` file.
    depth : (H, W) real array, metres, NaN where unknown
        Known values must be in (0, 255.996] m; a positive depth that rounds to 0 is stored as
        1/256 m so that it stays known. Zero, negative values, +-inf and values above 65535/256 m
        raise ``ValueError``.
    """
    p = as_path(path)
    d = _check_disparity(depth, "depth")
    known = ~np.isnan(d)
    vals = d[known]
    if vals.size:
        bad = ~np.isfinite(vals) | (vals <= 0) | (vals > 65535 / 256.0)
        if bad.any():
            raise ValueError(
                "`depth` values must be NaN (unknown) or in (0, 255.996] m for a KITTI depth PNG, got "
                f"{int(bad.sum())} values outside (min {np.min(vals)}, max {np.max(vals)})"
            )
    if p.suffix.lower() != ".png":
        raise ValueError(f"KITTI depth must be written as .png, got {p.name}")
    _write_x256(p, d, known)

def _check_scale(scale: Any) -> float:
    if isinstance(scale, bool) or not isinstance(scale, (int, float, np.integer, np.floating)):
        raise TypeError(f"`scale` must be a number, got {type(scale).__name__}")
    s = float(scale)
    if not np.isfinite(s) or s <= 0:
        raise ValueError(f"`scale` must be a positive finite number, got {scale}")
    return s


def read_scaled_disparity(path: PathLike, scale: float) -> np.ndarray:
    """Read a Middlebury-style integer disparity map (PGM or PNG, 8 or 16 bit): value = disparity x scale.

    Parameters
    ----------
    path : str or os.PathLike
    scale : float
        Stored value per pixel of disparity: 16 for Tsukuba ``disp3.pgm``, 8 for Venus
        ``disp2.pgm``, 4 for the quarter-size Cones/Teddy ``disp2.png``, 1 for 2005/2006 maps and
        for the Adirondack ground truth in ``../shared/data``.

    Returns
    -------
    disparity : (H, W) float32, pixels, NaN where the stored value is 0 (unknown).
    """
    s = _check_scale(scale)
    p, raw = read_single_channel(path, "disparity map")
    if raw.dtype not in (np.uint8, np.uint16):
        raise FileFormatError(f"disparity map {p} must be 8- or 16-bit, got {raw.dtype}")
    disparity = (raw.astype(np.float64) / s).astype(np.float32)
    disparity[raw == 0] = np.nan
    return disparity


def write_scaled_disparity(path: PathLike, disparity: np.ndarray, scale: float, *, bits: int = 8) -> None:
    """Write a disparity map as a Middlebury-style integer PGM/PNG (value = round(d x scale), 0 = unknown).

    Values that round to 0 are stored as 1 so that they stay known. Negative values, inf and values
    above the range of ``bits`` raise ``ValueError``.
    """
    p = as_path(path)
    s = _check_scale(scale)
    if bits not in (8, 16):
        raise ValueError(f"`bits` must be 8 or 16, got {bits}")
    d = _check_disparity(disparity)
    top = 255 if bits == 8 else 65535
    known = ~np.isnan(d)
    vals = d[known] * s
    if vals.size:
        bad = ~np.isfinite(vals) | (vals < 0) | (np.rint(vals) > top)
        if bad.any():
            raise ValueError(
                f"`disparity` x scale must be NaN or in [0, {top}] for a {bits}-bit map, got {int(bad.sum())} "
                f"values outside (max disparity {np.max(d[known])}, scale {s})"
            )
    raw = np.zeros(d.shape, dtype=np.uint8 if bits == 8 else np.uint16)
    raw[known] = np.clip(np.rint(vals), 1, top)
    data = encode_image(p, raw)
    with atomic_write(p, "wb") as f:
        f.write(data)
