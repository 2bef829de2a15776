"""Disparity <-> depth <-> 3D points for a rectified pair.

Conventions: disparity ``d = x_left - x_right`` in pixels (float32), depth ``Z`` in metres, NaN means
unknown. With ``doffs = cx_right - cx_left`` (pixels) the depth is ``Z = f * B / (d + doffs)``; where
``d + doffs <= 0`` or the input is not finite the result is NaN (never ``inf``, never ``1e8``).

The ``check_*`` helpers validate the scalar values (and image sizes) that the rigs and the file readers share.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np

from calib.errors import CalibrationError

__all__ = [
    "depth_from_disparity",
    "disparity_from_depth",
    "points_from_disparity",
    "points_from_pixels",
    "check_positive",
    "check_finite",
    "check_image_size",
]


class _RigLike(Protocol):
    focal_px: float
    cx_left: float
    cy: float
    baseline_m: float
    image_size: tuple[int, int]

    @property
    def doffs(self) -> float: ...


def check_positive(name: str, value: Any) -> float:
    """``value`` as a finite float > 0, else ValueError naming ``name``."""
    value = check_finite(name, value)
    if value <= 0.0:
        raise ValueError(f"`{name}` must be a finite number > 0, got {value!r}")
    return value


def check_finite(name: str, value: Any) -> float:
    """``value`` as a finite float, else ValueError naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"`{name}` must be a real number, got {type(value).__name__} {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"`{name}` must be finite, got {value!r}")
    return value


def check_image_size(name: str, value: Any) -> tuple[int, int]:
    """``(width, height)`` as two positive Python ints, else CalibrationError naming ``name``.

    Examples
    --------
    >>> check_image_size("image_size", (640.0, 480))
    (640, 480)
    """
    try:
        items = tuple(value)
    except TypeError:
        raise CalibrationError(f"`{name}` must be (width, height), two positive ints, got {value!r}") from None
    if len(items) != 2:
        raise CalibrationError(f"`{name}` must be (width, height), two positive ints, got {value!r}")
    out = []
    for item in items:
        if isinstance(item, (bool, np.bool_)):
            raise CalibrationError(f"`{name}` must be (width, height), two positive ints, got {value!r}")
        if isinstance(item, (float, np.floating)) and float(item).is_integer():
            item = int(item)
        if not isinstance(item, (int, np.integer)) or int(item) <= 0:
            raise CalibrationError(f"`{name}` must be (width, height), two positive ints, got {value!r}")
        out.append(int(item))
    return out[0], out[1]


def _as_real_array(name: str, values: Any) -> np.ndarray:
    arr = np.asarray(values)
    if arr.dtype == np.bool_ or not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
        raise ValueError(f"`{name}` must be an array of real numbers (int or float), got dtype {arr.dtype}")
    return arr


def _work_dtype(arr: np.ndarray) -> type:
    """float64 for 64-bit input, else float32 (half the memory of float64 temporaries on large maps)."""
    return np.float64 if arr.dtype.itemsize > 4 else np.float32


def _finite_float32(values: np.ndarray) -> np.ndarray:
    """Cast float64 to float32, turning anything that is not finite after the cast into NaN."""
    with np.errstate(over="ignore", invalid="ignore"):
        out = values.astype(np.float32)  # a copy: never the caller's array
    out[~np.isfinite(out)] = np.nan
    return out


def depth_from_disparity(disparity: Any, focal_px: float, baseline_m: float, doffs: float = 0.0) -> np.ndarray:
    """Depth in metres from disparity in pixels: ``Z = focal_px * baseline_m / (disparity + doffs)``.

    Parameters
    ----------
    disparity : array_like of real numbers, any shape, pixels, NaN where unknown
        ``x_left - x_right`` in the rectified images.
    focal_px : float > 0
        Rectified focal length, pixels.
    baseline_m : float > 0
        Distance between the camera centres, metres.
    doffs : float
        ``cx_right - cx_left`` of the rectified cameras, pixels (0 for OpenCV's zero-disparity rectification).

    Returns
    -------
    depth : float32 array, same shape, metres
        NaN where the disparity is not finite, where ``disparity + doffs <= 0`` or where the depth does not fit
        float32 (too large, or so small that it underflows to a subnormal number or 0: no camera measures
        1e-38 m, and a subnormal depth does not convert back to its disparity).

    Examples
    --------
    >>> depth_from_disparity([10.0, 0.0, float("nan")], 1000.0, 0.1)
    array([10., nan, nan], dtype=float32)
    """
    focal_px = check_positive("focal_px", focal_px)
    baseline_m = check_positive("baseline_m", baseline_m)
    doffs = check_finite("doffs", doffs)
    d = _as_real_array("disparity", disparity)
    d = d.astype(_work_dtype(d), copy=False)
    denom = d + d.dtype.type(doffs)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        z = np.where(np.isfinite(denom) & (denom > 0), d.dtype.type(focal_px * baseline_m) / denom, d.dtype.type(np.nan))
    z = _finite_float32(np.asarray(z))
    with np.errstate(invalid="ignore"):
        z[z < np.finfo(np.float32).tiny] = np.nan  # underflow (subnormal or 0) is not a depth
    return z


def disparity_from_depth(depth: Any, focal_px: float, baseline_m: float, doffs: float = 0.0) -> np.ndarray:
    """Disparity in pixels from depth in metres: ``d = focal_px * baseline_m / depth - doffs``.

    Parameters
    ----------
    depth : array_like of real numbers, any shape, metres, NaN where unknown
    focal_px, baseline_m, doffs : as in :func:`depth_from_disparity`

    Returns
    -------
    disparity : float32 array, same shape, pixels
        NaN where the depth is not finite or ``<= 0`` (the inverse of :func:`depth_from_disparity`).
    """
    focal_px = check_positive("focal_px", focal_px)
    baseline_m = check_positive("baseline_m", baseline_m)
    doffs = check_finite("doffs", doffs)
    z = _as_real_array("depth", depth)
    z = z.astype(_work_dtype(z), copy=False)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        d = np.where(np.isfinite(z) & (z > 0), z.dtype.type(focal_px * baseline_m) / z - z.dtype.type(doffs), z.dtype.type(np.nan))
    return _finite_float32(np.asarray(d))


def points_from_disparity(disparity: Any, rig: _RigLike) -> np.ndarray:
    """Per-pixel 3D points (X, Y, Z) in the left rectified camera frame, metres.

    Parameters
    ----------
    disparity : (H, W) real array, pixels, NaN where unknown
        Must match ``rig.image_size`` (width, height); use ``rig.scaled(f)`` for a resized disparity map.
    rig : RectifiedRig
        Anything with ``focal_px``, ``cx_left``, ``cy``, ``baseline_m``, ``doffs`` and ``image_size``.

    Returns
    -------
    points : (H, W, 3) float32, metres, X right, Y down, Z forward; all three NaN where the depth is unknown.
    """
    d = _as_real_array("disparity", disparity)
    if d.ndim != 2:
        raise ValueError(f"`disparity` must be a 2-D (H, W) array, got shape {d.shape}")
    width, height = rig.image_size
    if d.shape != (height, width):
        raise ValueError(
            f"`disparity` shape {d.shape} does not match the rig's image size (width={width}, height={height}); "
            f"use rig.scaled(factor) for resized images"
        )
    f = check_positive("rig.focal_px", rig.focal_px)
    cx = check_finite("rig.cx_left", rig.cx_left)
    cy = check_finite("rig.cy", rig.cy)
    z = depth_from_disparity(d, f, rig.baseline_m, rig.doffs)  # float32, NaN where unknown
    u = ((np.arange(width, dtype=np.float64) - cx) / f).astype(np.float32)[None, :]
    v = ((np.arange(height, dtype=np.float64) - cy) / f).astype(np.float32)[:, None]
    points = np.empty((height, width, 3), dtype=np.float32)  # 12 bytes per pixel, no float64 temporaries
    with np.errstate(over="ignore", invalid="ignore"):
        np.multiply(u, z, out=points[..., 0])
        np.multiply(v, z, out=points[..., 1])
    points[..., 2] = z
    points[~np.isfinite(points).all(axis=-1)] = np.nan
    return points


def points_from_pixels(u: Any, v: Any, disparity: Any, rig: _RigLike) -> np.ndarray:
    """3D points (X, Y, Z) of chosen pixels in the left rectified camera frame, metres, float64.

    The same pinhole geometry as :func:`points_from_disparity`, for a set of pixels instead of a whole
    image and in float64: ``Z = f B / (d + doffs)``, ``X = (u - cx_left) Z / f``, ``Y = (v - cy) Z / f``.

    Parameters
    ----------
    u, v : (N,) real arrays
        Column and row of each pixel in the left rectified image.
    disparity : (N,) real array, pixels
        Disparity of each pixel; a pixel with ``d + doffs <= 0`` or a non-finite value gets NaN.
    rig : RectifiedRig
        Anything with ``focal_px``, ``cx_left``, ``cy``, ``baseline_m`` and ``doffs``.

    Returns
    -------
    points : (N, 3) float64, metres, X right, Y down, Z forward.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> rig = SimpleNamespace(focal_px=500.0, baseline_m=0.1, doffs=0.0, cx_left=20.0, cy=15.0)
    >>> points_from_pixels([30], [15], [10.0], rig).tolist()
    [[0.1, 0.0, 5.0]]
    """
    uu = _as_real_array("u", u).astype(np.float64, copy=False).ravel()
    vv = _as_real_array("v", v).astype(np.float64, copy=False).ravel()
    d = _as_real_array("disparity", disparity).astype(np.float64, copy=False).ravel()
    if not (uu.shape == vv.shape == d.shape):
        raise ValueError(f"`u`, `v` and `disparity` must have the same length, got {uu.size}, {vv.size} and {d.size}")
    f = check_positive("rig.focal_px", rig.focal_px)
    doffs = check_finite("rig.doffs", rig.doffs)
    fb = f * check_positive("rig.baseline_m", rig.baseline_m)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        z = np.where(np.isfinite(d) & (d + doffs > 0), fb / (d + doffs), np.nan)
        x = (uu - check_finite("rig.cx_left", rig.cx_left)) * z / f
        y = (vv - check_finite("rig.cy", rig.cy)) * z / f
    return np.stack([x, y, z], axis=-1)
