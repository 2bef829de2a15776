"""StereoRig: a calibrated (not yet rectified) stereo camera pair."""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from calib.errors import CalibrationError, prefix_errors
from calib.formats import kitti, opencv, ros
from calib.geometry import check_image_size
from calib.rectified import (
    BASELINE_RANGE_M,
    FOCAL_RANGE_PX,
    RectifiedRig,
    check_intrinsics,
)

__all__ = ["StereoRig"]

log = logging.getLogger(__name__)

_DIST_LENGTHS = (4, 5, 8, 12, 14)


def _matrix(name: str, value: Any, shape: tuple[int, ...]) -> np.ndarray:
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise CalibrationError(f"`{name}` must be a real {shape} array, got {type(value).__name__}") from None
    if shape == (3,) and arr.shape in ((3, 1), (1, 3)):
        arr = arr.reshape(3)
    if arr.shape != shape:
        raise CalibrationError(f"`{name}` must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise CalibrationError(f"`{name}` must be finite, got {arr.tolist()}")
    arr.setflags(write=False)
    return arr


def _camera_matrix(name: str, value: Any) -> np.ndarray:
    k = _matrix(name, value, (3, 3))
    if not (k[0, 0] > 0 and k[1, 1] > 0):
        raise CalibrationError(f"`{name}` focal lengths fx={k[0, 0]!r}, fy={k[1, 1]!r} must be > 0")
    lo, hi = FOCAL_RANGE_PX
    if not (lo <= k[0, 0] <= hi and lo <= k[1, 1] <= hi):
        raise CalibrationError(f"`{name}` focal lengths fx={k[0, 0]:g}, fy={k[1, 1]:g} are outside the plausible range [{lo:g}, {hi:g}] px")
    if abs(k[1, 0]) > 1e-9 or abs(k[2, 0]) > 1e-9 or abs(k[2, 1]) > 1e-9 or abs(k[2, 2] - 1.0) > 1e-9:
        raise CalibrationError(f"`{name}` must be a camera matrix [[fx, s, cx], [0, fy, cy], [0, 0, 1]], got {k.tolist()}")
    return k


def _distortion(name: str, value: Any) -> np.ndarray:
    if value is None:
        value = np.zeros(5)
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise CalibrationError(f"`{name}` must be real distortion coefficients, got {type(value).__name__}") from None
    if arr.ndim == 2 and 1 in arr.shape:
        arr = arr.reshape(-1)
    if arr.ndim != 1 or arr.shape[0] not in _DIST_LENGTHS:
        raise CalibrationError(f"`{name}` must hold 4, 5, 8, 12 or 14 coefficients (OpenCV order k1 k2 p1 p2 [k3 ...]), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise CalibrationError(f"`{name}` must be finite, got {arr.tolist()}")
    arr.setflags(write=False)
    return arr


def _check_alpha(alpha: Any) -> float:
    """``alpha`` of ``cv2.stereoRectify``: a number in [0, 1], or -1 for OpenCV's default."""
    if isinstance(alpha, bool) or not isinstance(alpha, (int, float, np.integer, np.floating)) or not (
        alpha == -1 or 0.0 <= float(alpha) <= 1.0
    ):
        raise CalibrationError(f"`alpha` must be in [0, 1] (or -1 for OpenCV's default), got {alpha!r}")
    return float(alpha)


@dataclass(frozen=True, eq=False)
class StereoRig:
    """A calibrated stereo pair: intrinsics, distortion and the pose of the right camera.

    Parameters
    ----------
    K_left, K_right : (3, 3) float64
        Camera matrices ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]``, pixels.
    dist_left, dist_right : (k,) float64, k in 4, 5, 8, 12, 14
        OpenCV distortion coefficients ``k1 k2 p1 p2 [k3 [k4 k5 k6 [s1..s4 [tx ty]]]]``.
    R : (3, 3) float64
        Rotation from the left to the right camera frame (``X_right = R @ X_left + T``).
    T : (3,) float64, metres
        Translation from the left to the right camera frame; about ``(-baseline, 0, 0)`` for a horizontal rig.
    image_size : (width, height) ints
        Size of the raw images both cameras deliver.

    Arrays are copied to read-only float64. ``==`` compares all values exactly.

    Examples
    --------
    >>> K = [[700.0, 0, 320], [0, 700.0, 240], [0, 0, 1]]
    >>> rig = StereoRig(K, [0, 0, 0, 0, 0], K, [0, 0, 0, 0, 0], np.eye(3), [-0.1, 0, 0], (640, 480))
    >>> round(rig.baseline_m, 3)
    0.1
    >>> rect = rig.rectify()
    """

    K_left: np.ndarray
    dist_left: np.ndarray
    K_right: np.ndarray
    dist_right: np.ndarray
    R: np.ndarray
    T: np.ndarray
    image_size: tuple[int, int]

    def __post_init__(self) -> None:
        object.__setattr__(self, "K_left", _camera_matrix("K_left", self.K_left))
        object.__setattr__(self, "K_right", _camera_matrix("K_right", self.K_right))
        object.__setattr__(self, "dist_left", _distortion("dist_left", self.dist_left))
        object.__setattr__(self, "dist_right", _distortion("dist_right", self.dist_right))
        r = _matrix("R", self.R, (3, 3))
        if not np.allclose(r.T @ r, np.eye(3), atol=1e-3) or abs(np.linalg.det(r) - 1.0) > 1e-3:
            raise CalibrationError(f"`R` must be a rotation matrix (orthonormal, det +1), got {r.tolist()}")
        object.__setattr__(self, "R", r)
        t = _matrix("T", self.T, (3,))
        if not np.linalg.norm(t) > 0:
            raise CalibrationError("`T` must not be zero: the cameras need a baseline")
        lo, hi = BASELINE_RANGE_M
        if not lo <= np.linalg.norm(t) <= hi:
            raise CalibrationError(f"`T` has length {np.linalg.norm(t):g} m, outside the plausible range [{lo:g}, {hi:g}] m")
        object.__setattr__(self, "T", t)
        object.__setattr__(self, "image_size", check_image_size("image_size", self.image_size))
        for name in ("K_left", "K_right"):
            k = getattr(self, name)
            check_intrinsics(k[0, 0], k[1, 1], {f"{name}[0,2] (cx)": k[0, 2], f"{name}[1,2] (cy)": k[1, 2]},
                             self.image_size, name=f"{name} focal length")
        if self.baseline_m > 10.0:
            log.warning("baseline of %.3f m is unusually large: is T in millimetres? calib works in metres", self.baseline_m)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, StereoRig):
            return NotImplemented
        return self.image_size == other.image_size and all(
            np.array_equal(getattr(self, n), getattr(other, n))
            for n in ("K_left", "dist_left", "K_right", "dist_right", "R", "T")
        )

    __hash__ = None  # type: ignore[assignment]

    def isclose(self, other: StereoRig, *, rtol: float = 1e-9, atol: float = 1e-12) -> bool:
        """True when ``other`` has the same image size and all values agree within ``rtol``/``atol``."""
        return self.image_size == other.image_size and all(
            getattr(self, n).shape == getattr(other, n).shape
            and np.allclose(getattr(self, n), getattr(other, n), rtol=rtol, atol=atol)
            for n in ("K_left", "dist_left", "K_right", "dist_right", "R", "T")
        )

    @property
    def baseline_m(self) -> float:
        """Distance between the two camera centres, metres (``|T|``)."""
        return float(np.linalg.norm(self.T))

    def rectify(self, *, alpha: float = 0.0, zero_disparity: bool = True) -> RectifiedRig:
        """Rectify with ``cv2.stereoRectify`` and build the undistort/rectify maps.

        Parameters
        ----------
        alpha : float in [0, 1], or -1
            0 crops to valid pixels only, 1 keeps every source pixel (black borders), -1 OpenCV's default.
        zero_disparity : bool
            ``CALIB_ZERO_DISPARITY``: both rectified principal points at the same column (``doffs = 0``).

        Returns
        -------
        RectifiedRig
            With ``maps_left``/``maps_right`` (fixed-point ``CV_16SC2`` maps), ``roi_left``/``roi_right``
            (valid pixel rectangles) and ``raw_image_size``; same image size as the raw images.
        """
        alpha = _check_alpha(alpha)
        t = self.T
        if abs(t[0]) < max(abs(t[1]), abs(t[2])):
            raise CalibrationError(
                f"`T` = {t.tolist()} is not mostly horizontal: only side-by-side rigs are supported (vertical rigs are not)"
            )
        if t[0] > 0:
            raise CalibrationError(
                f"`T` = {t.tolist()} has T[0] > 0: the 'right' camera is to the left of the 'left' one; swap the cameras"
            )
        size = self.image_size
        flags = cv2.CALIB_ZERO_DISPARITY if zero_disparity else 0
        r1, r2, p1, p2, _q, roi1, roi2 = cv2.stereoRectify(
            self.K_left, self.dist_left, self.K_right, self.dist_right, size, self.R, self.T.reshape(3, 1),
            flags=flags, alpha=float(alpha),
        )
        maps_left = cv2.initUndistortRectifyMap(self.K_left, self.dist_left, r1, p1, size, cv2.CV_16SC2)
        maps_right = cv2.initUndistortRectifyMap(self.K_right, self.dist_right, r2, p2, size, cv2.CV_16SC2)
        focal = float(p1[0, 0])
        if not (focal > 0 and abs(p1[1, 2] - p2[1, 2]) < 1e-6):
            raise CalibrationError(f"cv2.stereoRectify gave unusable projections P1={p1.tolist()}, P2={p2.tolist()}")
        return RectifiedRig(
            focal_px=focal,
            cx_left=float(p1[0, 2]),
            cx_right=float(p2[0, 2]),
            cy=float(p1[1, 2]),
            baseline_m=float(-p2[0, 3] / p2[0, 0]),
            image_size=size,
            maps_left=maps_left,
            maps_right=maps_right,
            raw_image_size=size,
            roi_left=tuple(int(v) for v in roi1),
            roi_right=tuple(int(v) for v in roi2),
        )

    def rectification(self, *, alpha: float = 0.0, zero_disparity: bool = True) -> dict[str, np.ndarray]:
        """``R1``, ``R2``, ``P1``, ``P2``, ``Q`` of ``cv2.stereoRectify`` (float64) for other tools.

        ``alpha`` as in :meth:`rectify` (checked the same way)."""
        alpha = _check_alpha(alpha)
        flags = cv2.CALIB_ZERO_DISPARITY if zero_disparity else 0
        r1, r2, p1, p2, q, _roi1, _roi2 = cv2.stereoRectify(
            self.K_left, self.dist_left, self.K_right, self.dist_right, self.image_size, self.R,
            self.T.reshape(3, 1), flags=flags, alpha=float(alpha),
        )
        return {"R1": r1, "R2": r2, "P1": p1, "P2": p2, "Q": q}

    # ----------------------------------------------------------------- readers / writers
    @classmethod
    def from_opencv_yaml(cls, path: str | os.PathLike[str], *, image_size: tuple[int, int] | None = None) -> StereoRig:
        """OpenCV FileStorage YAML or XML with ``K1 D1 K2 D2 R T`` (``M1``/``M2`` accepted for ``K1``/``K2``).

        The image size comes from ``image_width``/``image_height`` (or ``image_size``/``imageSize``) in the
        file, or from ``image_size=`` when the file has none. ``T`` must be in metres.
        """
        values = opencv.read_stereo(path, image_size=image_size)
        with prefix_errors(Path(path)):
            return cls(**values)

    @classmethod
    def from_kitti(cls, path: str | os.PathLike[str], *, left: int = 2, right: int = 3) -> StereoRig:
        """KITTI raw ``calib_cam_to_cam.txt`` (``K_0N``, ``D_0N``, ``R_0N``, ``T_0N``, ``S_0N``): unrectified cameras."""
        values = kitti.read_raw_stereo(path, left=left, right=right)
        with prefix_errors(Path(path)):
            return cls(**values)

    @classmethod
    def from_ros(cls, left_yaml: str | os.PathLike[str], right_yaml: str | os.PathLike[str]) -> StereoRig:
        """A pair of ROS ``camera_info`` YAML files (``camera_matrix``, ``distortion_coefficients``,
        ``rectification_matrix``, ``projection_matrix``, ``image_width``, ``image_height``)."""
        values = ros.read_stereo_pair(left_yaml, right_yaml)
        with prefix_errors(f"{Path(left_yaml)} + {Path(right_yaml)}"):
            return cls(**values)

    def to_opencv_yaml(self, path: str | os.PathLike[str]) -> None:
        """Write ``K1 D1 K2 D2 R T``, the image size and ``R1 R2 P1 P2 Q`` (alpha 0) atomically.

        YAML unless ``path`` ends in ``.xml``. :meth:`from_opencv_yaml` reads back the same rig exactly.
        A rig that OpenCV cannot rectify is still written, without ``R1 R2 P1 P2 Q`` (logged).
        """
        try:
            rectification = self.rectification(alpha=0.0)
        except cv2.error as exc:  # a rig OpenCV cannot rectify still gets written
            log.warning("could not compute R1 R2 P1 P2 Q for %s: %s", path, exc)
            rectification = {}
        opencv.write_stereo(path, K_left=self.K_left, dist_left=self.dist_left, K_right=self.K_right,
                            dist_right=self.dist_right, R=self.R, T=self.T, image_size=self.image_size,
                            rectification=rectification)
