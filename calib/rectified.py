"""RectifiedRig: the geometry of a rectified stereo pair (what depth and 3D points need)."""

from __future__ import annotations

import logging
import math
import os
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from calib.errors import CalibrationError, prefix_errors
from calib.features import vertical_offset
from calib.formats import kitti, middlebury, oakd, opencv
from calib.geometry import check_finite, check_image_size, depth_from_disparity, disparity_from_depth, points_from_disparity

__all__ = ["BASELINE_RANGE_M", "FOCAL_RANGE_PX", "MAX_FOV_DEG", "RectificationWarning", "RectifiedRig",
           "check_image_size", "check_intrinsics"]

log = logging.getLogger(__name__)

#: Above this median vertical offset (pixels) `rectify_pair` warns.
VERTICAL_OFFSET_WARN_PX = 1.0


#: Plausible ranges; values outside them are refused (they make Q overflow or are unit mistakes).
FOCAL_RANGE_PX = (1e-3, 1e8)
BASELINE_RANGE_M = (1e-6, 1e4)


#: Widest horizontal/vertical field of view a pinhole (rectified) camera can have, degrees: a focal length
#: below ``size / (2 tan(MAX_FOV_DEG / 2))`` (2.2 % of the image width) is a unit or scaling mistake.
MAX_FOV_DEG = 175.0


def check_intrinsics(fx: float, fy: float, principal: dict[str, float], image_size: tuple[int, int],
                     *, name: str = "focal_px") -> None:
    """CalibrationError unless the focal lengths and principal point(s) are plausible for ``image_size``.

    The field of view must be below :data:`MAX_FOV_DEG` (fx >= 2.2 % of the width, fy of the height), and
    every principal point must lie within half an image of the image: ``-W/2 <= cx <= 3W/2`` and
    ``-H/2 <= cy <= 3H/2``. Outside these, every depth would be wrong (or every box out of view).

    Parameters
    ----------
    fx, fy : float, pixels
    principal : dict
        Principal point coordinates by name, e.g. ``{"cx_left": 320.0, "cy": 240.0}``; names containing
        "cx" are checked against the width, the others against the height.
    image_size : (width, height)
    name : str
        How the focal length is named in the message.

    Examples
    --------
    >>> check_intrinsics(0.001, 0.001, {}, (640, 480))
    Traceback (most recent call last):
    ...
    calib.errors.CalibrationError: `focal_px` = 0.001 px is implausible for 640x480 images: a field of view over 175 degrees needs focal_px >= 14 px (is the calibration for another image size or unit?)
    """
    width, height = image_size
    tan = math.tan(math.radians(MAX_FOV_DEG / 2.0))
    for f, extent in ((fx, width), (fy, height)):
        least = extent / (2.0 * tan)
        if f < least:
            raise CalibrationError(
                f"`{name}` = {f:g} px is implausible for {width}x{height} images: a field of view over "
                f"{MAX_FOV_DEG:g} degrees needs {name} >= {least:.2g} px (is the calibration for another image "
                "size or unit?)")
    for key, value in principal.items():
        extent = width if "cx" in key else height
        lo, hi = -extent / 2.0, 1.5 * extent
        if not lo <= value <= hi:
            raise CalibrationError(
                f"`{key}` = {value:g} px is outside the plausible range [{lo:g}, {hi:g}] px for {width}x{height} "
                "images (the principal point lies near the image centre): is the calibration for another image "
                "size?")


class RectificationWarning(UserWarning):
    """The rectified pair still has a vertical offset (epipolar lines are not image rows)."""


def _check_maps(name: str, maps: Any, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray] | None:
    if maps is None:
        return None
    if not (isinstance(maps, tuple) and len(maps) == 2):
        raise CalibrationError(f"`{name}` must be a (map1, map2) tuple from cv2.initUndistortRectifyMap, got {type(maps).__name__}")
    width, height = size
    if np.shape(maps[0])[:2] != (height, width):
        raise CalibrationError(f"`{name}` maps have shape {np.shape(maps[0])}, expected (H, W)=({height}, {width}) of the rectified image")
    return maps


_RECTIFY_DTYPES = (np.dtype(np.uint8), np.dtype(np.uint16), np.dtype(np.float32))
_RECTIFY_INTERPOLATIONS = (cv2.INTER_NEAREST, cv2.INTER_LINEAR, cv2.INTER_CUBIC, cv2.INTER_LANCZOS4)


@dataclass(frozen=True)
class RectifiedRig:
    """Geometry of a rectified stereo pair (row-aligned images).

    Parameters
    ----------
    focal_px : float > 0
        Rectified focal length, pixels (the same for both cameras and both axes).
    cx_left, cx_right : float
        Principal point columns of the rectified left and right cameras, pixels.
    cy : float
        Principal point row (shared), pixels.
    baseline_m : float > 0
        Distance between the camera centres, metres.
    image_size : (width, height) ints
        Size of the rectified images.
    maps_left, maps_right : (map1, map2) or None
        ``cv2.initUndistortRectifyMap`` outputs that turn raw images into rectified ones (set by
        :meth:`StereoRig.rectify`); None for data that is already rectified.
    raw_image_size : (width, height) or None
        Size of the raw images the maps expect.
    roi_left, roi_right : (x, y, w, h) or None
        Regions of the rectified images where every pixel is valid (from ``cv2.stereoRectify``).

    ``doffs = cx_right - cx_left`` and ``Z = focal_px * baseline_m / (d + doffs)``.

    Examples
    --------
    >>> rig = RectifiedRig(focal_px=1000.0, cx_left=320.0, cx_right=330.0, cy=240.0, baseline_m=0.1,
    ...                    image_size=(640, 480))
    >>> float(rig.depth(np.array([[90.0]]))[0, 0])
    1.0
    """

    focal_px: float
    cx_left: float
    cx_right: float
    cy: float
    baseline_m: float
    image_size: tuple[int, int]
    maps_left: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False, compare=False)
    maps_right: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False, compare=False)
    raw_image_size: tuple[int, int] | None = field(default=None, compare=False)
    roi_left: tuple[int, int, int, int] | None = field(default=None, compare=False)
    roi_right: tuple[int, int, int, int] | None = field(default=None, compare=False)
    _checks: dict[str, float] = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        def _num(name: str, positive: bool = False) -> float:
            try:
                value = check_finite(name, getattr(self, name))
            except ValueError as exc:
                raise CalibrationError(str(exc)) from None
            if positive and value <= 0.0:
                raise CalibrationError(f"`{name}` must be > 0, got {value!r}")
            return value

        object.__setattr__(self, "focal_px", _num("focal_px", positive=True))
        object.__setattr__(self, "baseline_m", _num("baseline_m", positive=True))
        for name, (lo, hi), unit in (("focal_px", FOCAL_RANGE_PX, "px"), ("baseline_m", BASELINE_RANGE_M, "m")):
            value = getattr(self, name)
            if not lo <= value <= hi:
                raise CalibrationError(f"`{name}` = {value!r} {unit} is outside the plausible range [{lo:g}, {hi:g}] {unit}")
        for name in ("cx_left", "cx_right", "cy"):
            object.__setattr__(self, name, _num(name))
        size = check_image_size("image_size", self.image_size)
        object.__setattr__(self, "image_size", size)
        # the left camera's principal point (boxes and X, Y are in its pixels); cx_right only enters as doffs,
        # which a cropped rectification can make large
        check_intrinsics(self.focal_px, self.focal_px, {"cx_left": self.cx_left, "cy": self.cy}, size)
        if (self.maps_left is None) != (self.maps_right is None):
            raise CalibrationError("`maps_left` and `maps_right` must both be given or both be None")
        object.__setattr__(self, "maps_left", _check_maps("maps_left", self.maps_left, size))
        object.__setattr__(self, "maps_right", _check_maps("maps_right", self.maps_right, size))
        if self.maps_left is not None:
            if self.raw_image_size is None:
                raise CalibrationError("`raw_image_size` is required when rectification maps are given")
        if self.raw_image_size is not None:
            object.__setattr__(self, "raw_image_size", check_image_size("raw_image_size", self.raw_image_size))
        for name in ("roi_left", "roi_right"):
            roi = getattr(self, name)
            if roi is not None:
                roi = tuple(int(v) for v in roi)
                if len(roi) != 4 or min(roi) < 0:
                    raise CalibrationError(f"`{name}` must be (x, y, w, h) with non-negative ints, got {getattr(self, name)!r}")
                object.__setattr__(self, name, roi)
        if self.baseline_m > 10.0:
            log.warning("baseline of %.3f m is unusually large: is it in millimetres? calib works in metres", self.baseline_m)

    # ----------------------------------------------------------------- derived geometry
    @property
    def doffs(self) -> float:
        """``cx_right - cx_left`` in pixels (Middlebury's ``doffs``); 0 for OpenCV zero-disparity rectification."""
        return self.cx_right - self.cx_left

    @property
    def Q(self) -> np.ndarray:  # noqa: N802 (OpenCV's name)
        """4x4 disparity-to-depth matrix as ``cv2.reprojectImageTo3D`` expects it (float64).

        ``[X Y Z W]^T = Q [u v d 1]^T`` gives ``Z / W = focal_px * baseline_m / (d + doffs)``.
        """
        b = self.baseline_m
        return np.array(
            [
                [1.0, 0.0, 0.0, -self.cx_left],
                [0.0, 1.0, 0.0, -self.cy],
                [0.0, 0.0, 0.0, self.focal_px],
                [0.0, 0.0, 1.0 / b, self.doffs / b],
            ]
        )

    @property
    def P_left(self) -> np.ndarray:  # noqa: N802
        """3x4 projection matrix of the rectified left camera (float64)."""
        return np.array([[self.focal_px, 0.0, self.cx_left, 0.0], [0.0, self.focal_px, self.cy, 0.0], [0.0, 0.0, 1.0, 0.0]])

    @property
    def P_right(self) -> np.ndarray:  # noqa: N802
        """3x4 projection matrix of the rectified right camera, ``P[0, 3] = -focal_px * baseline_m`` (float64)."""
        p = self.P_left
        p[0, 2] = self.cx_right
        p[0, 3] = -self.focal_px * self.baseline_m
        return p

    @property
    def has_maps(self) -> bool:
        """True when :meth:`rectify_pair` remaps raw images (rig made by ``StereoRig.rectify``)."""
        return self.maps_left is not None

    def depth(self, disparity: Any) -> np.ndarray:
        """Depth in metres, ``(H, W) float32``, NaN where unknown (see :func:`calib.depth_from_disparity`).

        ``disparity`` must come from images of ``image_size``; for resized images use :meth:`scaled` first.
        """
        return depth_from_disparity(disparity, self.focal_px, self.baseline_m, self.doffs)

    def disparity(self, depth: Any) -> np.ndarray:
        """Disparity in pixels (float32, NaN where unknown) of a depth map in metres."""
        return disparity_from_depth(depth, self.focal_px, self.baseline_m, self.doffs)

    def points(self, disparity: Any) -> np.ndarray:
        """``(H, W, 3) float32`` X, Y, Z in metres, left rectified camera frame (X right, Y down, Z forward)."""
        return points_from_disparity(disparity, self)

    def scaled(self, factor: float) -> RectifiedRig:
        """The rig for images resized by ``factor`` (e.g. 0.5 for half size), as ``cv2.resize`` does it.

        Focal length scales by ``factor``; principal points by ``(c + 0.5) * factor - 0.5`` (pixel centres);
        image size is rounded. The baseline is unchanged. Rectification maps are dropped: the scaled rig
        describes already rectified, resized images.
        """
        try:
            factor = check_finite("factor", factor)
        except ValueError as exc:
            raise CalibrationError(str(exc)) from None
        if factor <= 0.0:
            raise CalibrationError(f"`factor` must be > 0, got {factor!r}")
        width, height = self.image_size
        new_size = (int(round(width * factor)), int(round(height * factor)))
        if min(new_size) < 1:
            raise CalibrationError(f"`factor` {factor!r} shrinks the {width}x{height} image to nothing")
        return RectifiedRig(
            focal_px=self.focal_px * factor,
            cx_left=(self.cx_left + 0.5) * factor - 0.5,
            cx_right=(self.cx_right + 0.5) * factor - 0.5,
            cy=(self.cy + 0.5) * factor - 0.5,
            baseline_m=self.baseline_m,
            image_size=new_size,
        )

    def without_maps(self) -> RectifiedRig:
        """The same geometry for images that are already rectified (no remapping)."""
        return replace(self, maps_left=None, maps_right=None, raw_image_size=None)

    # ----------------------------------------------------------------- images
    def rectify_pair(self, left: np.ndarray, right: np.ndarray, *, check_offset: bool | None = None,
                     interpolation: int = cv2.INTER_LINEAR) -> tuple[np.ndarray, np.ndarray]:
        """Rectify a raw pair (when the rig has maps) or check an already rectified one.

        Parameters
        ----------
        left, right : (H, W) or (H, W, C) images of the same shape
            Raw images of ``raw_image_size`` when the rig has maps, else rectified images of ``image_size``.
        check_offset : bool or None
            Measure the residual vertical offset with feature matching (:func:`calib.vertical_offset`, about
            0.1-0.5 s) and warn (``RectificationWarning`` and a log message) when it is above 1 px.
            True: every call. False: never. None (default): on the first pair this rig remaps, so that a video
            loop pays for it once.

        interpolation : int
            ``cv2.INTER_NEAREST``, ``cv2.INTER_LINEAR`` (default), ``cv2.INTER_CUBIC`` or ``cv2.INTER_LANCZOS4``.

        Images must be uint8, uint16 or float32 with 1 to 4 channels.

        Returns
        -------
        left, right : rectified images, same dtype, size ``image_size``.
        """
        left, right = np.asarray(left), np.asarray(right)
        for name, img in (("left", left), ("right", right)):
            if img.ndim not in (2, 3) or img.size == 0:
                raise ValueError(f"`{name}` must be an (H, W) or (H, W, C) image, got shape {img.shape}")
            if img.dtype not in _RECTIFY_DTYPES:
                raise ValueError(f"`{name}` must be a uint8, uint16 or float32 image, got dtype {img.dtype}")
            channels = 1 if img.ndim == 2 else img.shape[2]
            if not 1 <= channels <= 4:
                raise ValueError(f"`{name}` must have 1 to 4 channels, got shape {img.shape}")
        if left.shape != right.shape:
            raise ValueError(f"`left` and `right` must have the same shape, got {left.shape} and {right.shape}")
        if left.dtype != right.dtype:
            raise ValueError(f"`left` and `right` must have the same dtype, got {left.dtype} and {right.dtype}")
        if isinstance(interpolation, bool) or not isinstance(interpolation, (int, np.integer)) or \
                int(interpolation) not in _RECTIFY_INTERPOLATIONS:
            raise ValueError(
                "`interpolation` must be one of cv2.INTER_NEAREST, cv2.INTER_LINEAR, cv2.INTER_CUBIC, "
                f"cv2.INTER_LANCZOS4, got {interpolation!r}"
            )
        interpolation = int(interpolation)
        expected = self.raw_image_size if self.has_maps else self.image_size
        width, height = expected
        if left.shape[:2] != (height, width):
            what = "raw" if self.has_maps else "rectified"
            raise ValueError(
                f"images are {left.shape[1]}x{left.shape[0]} but the rig expects {what} images of {width}x{height}"
                + ("" if self.has_maps else "; use rig.scaled(factor) for resized images")
            )
        if self.has_maps:
            left = cv2.remap(left, *self.maps_left, interpolation)  # type: ignore[misc]
            right = cv2.remap(right, *self.maps_right, interpolation)  # type: ignore[misc]
        if check_offset is None:
            check_offset = self.has_maps and "vertical_offset_px" not in self._checks
        if check_offset:
            offset = vertical_offset(left, right)
            self._checks["vertical_offset_px"] = offset
            if math.isnan(offset):
                log.info("rectify_pair: too few feature matches to measure the vertical offset")
            elif offset > VERTICAL_OFFSET_WARN_PX:
                msg = (f"rectified pair has a median vertical offset of {offset:.2f} px (> {VERTICAL_OFFSET_WARN_PX} px): "
                       "the calibration does not fit these images; disparities will be wrong")
                log.warning(msg)
                warnings.warn(msg, RectificationWarning, stacklevel=2)
            else:
                log.debug("rectify_pair: median vertical offset %.2f px", offset)
        return left, right

    # ----------------------------------------------------------------- readers / writers
    @classmethod
    def _from_file_values(cls, path: str | os.PathLike[str], values: dict[str, Any]) -> RectifiedRig:
        """``cls(**values)``, a refused value reported with the file's name in front."""
        with prefix_errors(Path(path)):
            return cls(**values)

    @classmethod
    def from_middlebury(cls, calib_txt: str | os.PathLike[str], *, image_size: tuple[int, int] | None = None) -> RectifiedRig:
        """Middlebury 2014/2021 ``calib.txt`` (``cam0``, ``cam1``, ``doffs``, ``baseline`` in **mm**, width, height).

        See :func:`calib.formats.middlebury.read_rectified` (a ``calib.txt`` of another resolution is scaled
        to ``image_size`` when the aspect ratio agrees).
        """
        return cls._from_file_values(calib_txt, middlebury.read_rectified(calib_txt, image_size=image_size))

    @classmethod
    def from_kitti(cls, calib_txt: str | os.PathLike[str], *, left: int = 2, right: int = 3,
                   image_size: tuple[int, int] | None = None) -> RectifiedRig:
        """KITTI object ``calib.txt`` (``P0:``..``P3:``) or raw ``calib_cam_to_cam.txt`` (``P_rect_0N``).

        ``left``/``right`` are KITTI camera indices 0..3; the image size comes from ``S_rect_0N``,
        ``image_size=`` or else 1242x375 (see :func:`calib.formats.kitti.read_rectified`).
        """
        return cls._from_file_values(calib_txt, kitti.read_rectified(calib_txt, left=left, right=right, image_size=image_size))

    @classmethod
    def from_oakd_json(cls, path: str | os.PathLike[str]) -> RectifiedRig:
        """The stereodemo / OAK-D JSON (``fx``, ``cx0``, ``cx1``, ``cy``, ``baseline_meters``, width, height)."""
        return cls._from_file_values(path, oakd.read_rectified(path))

    @classmethod
    def from_opencv_yaml(cls, path: str | os.PathLike[str], *, image_size: tuple[int, int] | None = None,
                         maps: bool = False) -> RectifiedRig:
        """OpenCV FileStorage YAML/XML with ``P1`` and ``P2`` (or ``Q``) of an already rectified pair.

        ``maps=True``: also build the rectification maps from the file's ``K1 D1 K2 D2 R1 R2 P1 P2``, so that
        :meth:`rectify_pair` takes raw images and rectifies them exactly as the file says.
        """
        if not maps:
            return cls._from_file_values(path, opencv.read_rectified(path, image_size=image_size))
        rig = cls._from_file_values(path, opencv.read_projections(path, image_size=image_size))
        return replace(rig, **opencv.read_rectify_maps(path, image_size=rig.image_size))

    def to_opencv_yaml(self, path: str | os.PathLike[str]) -> None:
        """Write ``P1``, ``P2``, ``Q`` and the image size to an OpenCV YAML (or XML, by extension), atomically."""
        opencv.write_rectified(path, P_left=self.P_left, P_right=self.P_right, Q=self.Q, image_size=self.image_size)
