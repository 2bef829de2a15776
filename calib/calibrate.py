"""Stereo calibration from image pairs of a checkerboard or a ChArUco board (OpenCV)."""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from calib.boards import Board, CharucoBoard, CheckerBoard, detect_board
from calib.errors import CalibrationError
from calib.rig import StereoRig

__all__ = ["CalibrationReport", "calibrate_stereo", "CheckerBoard", "CharucoBoard", "detect_board"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CalibrationReport:
    """How well a stereo calibration went.

    Attributes
    ----------
    rms_px : float
        RMS reprojection error over all corners of both cameras (``cv2.stereoCalibrate``), pixels.
    per_view_rms_px : (N, 2) float64
        RMS reprojection error of each used view, left and right camera, pixels.
    used_views : tuple of str
        Names of the views that went into the calibration (same order as ``per_view_rms_px``).
    rejected_views : tuple of (name, reason)
        Views left out, e.g. where the board was not found in one of the images.
    vertical_residual_px : float
        Median ``|y_left - y_right|`` of the detected corners after rectification (alpha 0), pixels.
    vertical_residual_max_px : float
        Largest such offset, pixels.
    image_size : (width, height)
    board : str
        Description of the board.
    """

    rms_px: float
    per_view_rms_px: np.ndarray = field(repr=False)
    used_views: tuple[str, ...]
    rejected_views: tuple[tuple[str, str], ...]
    vertical_residual_px: float
    vertical_residual_max_px: float
    image_size: tuple[int, int]
    board: str

    def summary(self) -> str:
        """A few human-readable lines."""
        lines = [
            f"board: {self.board}",
            f"image size: {self.image_size[0]}x{self.image_size[1]}",
            f"views used: {len(self.used_views)}, rejected: {len(self.rejected_views)}",
            f"RMS reprojection error: {self.rms_px:.3f} px",
            f"worst view: {self.worst_view()}",
            f"vertical residual after rectification: median {self.vertical_residual_px:.3f} px, "
            f"max {self.vertical_residual_max_px:.3f} px",
        ]
        lines += [f"  rejected {name}: {reason}" for name, reason in self.rejected_views]
        return "\n".join(lines)

    def worst_view(self) -> str:
        if len(self.used_views) == 0:
            return "-"
        i = int(np.argmax(self.per_view_rms_px.max(axis=1)))
        return f"{self.used_views[i]} ({self.per_view_rms_px[i, 0]:.3f} / {self.per_view_rms_px[i, 1]:.3f} px)"

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly dict."""
        return {
            "rms_px": self.rms_px,
            "per_view_rms_px": {n: [float(a), float(b)] for n, (a, b) in zip(self.used_views, self.per_view_rms_px)},
            "rejected_views": {n: r for n, r in self.rejected_views},
            "vertical_residual_px": self.vertical_residual_px,
            "vertical_residual_max_px": self.vertical_residual_max_px,
            "image_size": list(self.image_size),
            "board": self.board,
        }


def _load(item: Any, name: str) -> np.ndarray:
    if isinstance(item, (str, os.PathLike)):
        path = Path(item)
        if not path.is_file():
            raise FileNotFoundError(f"calibration image not found: {path}")
        # imdecode of the bytes, not cv2.imread: that returns None on non-ASCII paths on Windows
        image = cv2.imdecode(np.fromfile(path, np.uint8), cv2.IMREAD_GRAYSCALE)
        if image is None:
            raise CalibrationError(f"calibration image {path} could not be decoded (not an image or corrupt)")
        return image
    image = np.asarray(item)
    if image.dtype != np.uint8 or image.ndim not in (2, 3):
        raise CalibrationError(f"`{name}` must be a uint8 (H, W) or (H, W, 3) image or a path, got {image.dtype} {image.shape}")
    return image


def _view_name(item: Any, index: int) -> str:
    return Path(item).name if isinstance(item, (str, os.PathLike)) else f"view {index}"


def calibrate_stereo(left_images: Sequence[Any], right_images: Sequence[Any], *, board: Board, min_views: int = 5,
                     fix_k3: bool = False, rational_model: bool = False, names: Sequence[str] | None = None,
                     progress: bool = False) -> tuple[StereoRig, CalibrationReport]:
    """Calibrate a stereo pair from views of a board.

    Each camera is calibrated alone first (``cv2.calibrateCamera``), then both are refined together with
    ``cv2.stereoCalibrate`` (intrinsics as initial guess). Views where the board is not found in both images
    are listed in the report and skipped.

    Parameters
    ----------
    left_images, right_images : sequences of the same length
        ``(H, W)`` or ``(H, W, 3)`` uint8 images, or paths to image files; pair ``i`` shows the board at the
        same moment in both cameras.
    board : CheckerBoard or CharucoBoard
        Its ``square_m`` sets the unit of ``T``: metres.
    min_views : int >= 3
        Fewer usable views than this is an error.
    fix_k3 : bool
        Keep ``k3 = 0`` (for lenses with little distortion or few views).
    rational_model : bool
        Use 8 distortion coefficients (``CALIB_RATIONAL_MODEL``) instead of 5.
    names : sequence of str, optional
        View names for the report (default: file names, or ``"view i"``).
    progress : bool
        Show a tqdm progress bar over the views on stderr (only when it is a terminal).

    Returns
    -------
    rig : StereoRig
    report : CalibrationReport

    Raises
    ------
    CalibrationError
        Bad arguments, images of different sizes, or fewer than ``min_views`` usable views.
    FileNotFoundError
        An image path does not exist.
    """
    if not isinstance(board, (CheckerBoard, CharucoBoard)):
        raise CalibrationError(f"`board` must be a CheckerBoard or CharucoBoard, got {type(board).__name__}")
    if isinstance(min_views, bool) or not isinstance(min_views, int) or min_views < 3:
        raise CalibrationError(f"`min_views` must be an int >= 3, got {min_views!r}")
    if isinstance(left_images, (str, os.PathLike, np.ndarray)) or isinstance(right_images, (str, os.PathLike, np.ndarray)):
        raise CalibrationError("`left_images` and `right_images` must be sequences (lists) of images or paths")
    left_images, right_images = list(left_images), list(right_images)
    if len(left_images) != len(right_images):
        raise CalibrationError(f"`left_images` has {len(left_images)} items but `right_images` has {len(right_images)}")
    if not left_images:
        raise CalibrationError("`left_images` is empty: need image pairs of the board")
    if names is None:
        names = [_view_name(item, i) for i, item in enumerate(left_images)]
    else:
        names = [str(n) for n in names]
        if len(names) != len(left_images):
            raise CalibrationError(f"`names` has {len(names)} items for {len(left_images)} views")

    size: tuple[int, int] | None = None
    obj_points, pts_left, pts_right, used, rejected = [], [], [], [], []
    pairs = enumerate(zip(left_images, right_images))
    if progress:
        from tqdm import tqdm

        pairs = tqdm(pairs, total=len(left_images), desc="finding the board", unit="pair", disable=None, leave=False)
    for i, (item_l, item_r) in pairs:
        img_l, img_r = _load(item_l, f"left_images[{i}]"), _load(item_r, f"right_images[{i}]")
        for side, img in (("left", img_l), ("right", img_r)):
            this = (img.shape[1], img.shape[0])
            if size is None:
                size = this
            elif this != size:
                raise CalibrationError(f"{side} image of {names[i]} is {this[0]}x{this[1]}, earlier images are {size[0]}x{size[1]}")
        det_l = detect_board(img_l, board, name=f"left_images[{i}]")
        det_r = detect_board(img_r, board, name=f"right_images[{i}]")
        if det_l is None or det_r is None:
            where = "both images" if det_l is None and det_r is None else ("the left image" if det_l is None else "the right image")
            rejected.append((names[i], f"board not found in {where}"))
            log.info("%s: board not found in %s", names[i], where)
            continue
        ids_common, il, ir = np.intersect1d(det_l[0], det_r[0], return_indices=True)
        if len(ids_common) < 6:
            rejected.append((names[i], f"only {len(ids_common)} board corners seen in both images (need 6)"))
            continue
        obj_points.append(det_l[1][il].reshape(-1, 1, 3).astype(np.float32))
        pts_left.append(det_l[2][il].reshape(-1, 1, 2).astype(np.float32))
        pts_right.append(det_r[2][ir].reshape(-1, 1, 2).astype(np.float32))
        used.append(names[i])
    if len(used) < min_views:
        detail = "; ".join(f"{n}: {r}" for n, r in rejected) or "none rejected"
        raise CalibrationError(f"only {len(used)} of {len(left_images)} views are usable, need at least {min_views} ({detail})")
    if size is None:  # unreachable: at least min_views >= 3 views were read
        raise CalibrationError("no images were read")

    flags = 0
    if fix_k3:
        flags |= cv2.CALIB_FIX_K3
    if rational_model:
        flags |= cv2.CALIB_RATIONAL_MODEL
    criteria = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-10)
    try:
        _, k1, d1, _, _ = cv2.calibrateCamera(obj_points, pts_left, size, None, None, flags=flags, criteria=criteria)
        _, k2, d2, _, _ = cv2.calibrateCamera(obj_points, pts_right, size, None, None, flags=flags, criteria=criteria)
        rms, k1, d1, k2, d2, r, t, _e, _f, _rv, _tv, per_view = cv2.stereoCalibrateExtended(
            obj_points, pts_left, pts_right, k1, d1, k2, d2, size, np.eye(3), np.zeros((3, 1)),
            flags=flags | cv2.CALIB_USE_INTRINSIC_GUESS, criteria=criteria,
        )
    except cv2.error as exc:
        raise CalibrationError(f"OpenCV calibration failed ({str(exc).strip().splitlines()[-1]}): try more, more varied views") from None
    try:
        rig = StereoRig(K_left=k1, dist_left=d1.reshape(-1), K_right=k2, dist_right=d2.reshape(-1), R=r, T=t.reshape(3),
                        image_size=size)
    except CalibrationError as exc:
        raise CalibrationError(f"calibration gave an unusable rig ({exc}): try more, more varied views") from None

    vertical = _vertical_residuals(rig, pts_left, pts_right)
    report = CalibrationReport(
        rms_px=float(rms),
        per_view_rms_px=np.asarray(per_view, dtype=np.float64).reshape(len(used), 2),
        used_views=tuple(used),
        rejected_views=tuple(rejected),
        vertical_residual_px=float(np.median(vertical)) if len(vertical) else float("nan"),
        vertical_residual_max_px=float(np.max(vertical)) if len(vertical) else float("nan"),
        image_size=size,
        board=board.describe(),
    )
    return rig, report


def _vertical_residuals(rig: StereoRig, pts_left: list[np.ndarray], pts_right: list[np.ndarray]) -> np.ndarray:
    """``|y_left - y_right|`` of every corner pair after rectification (alpha 0), pixels."""
    try:
        rect = rig.rectification(alpha=0.0)
    except cv2.error:
        return np.empty(0)
    pl = np.concatenate(pts_left).astype(np.float64)
    pr = np.concatenate(pts_right).astype(np.float64)
    yl = cv2.undistortPoints(pl, rig.K_left, rig.dist_left, R=rect["R1"], P=rect["P1"]).reshape(-1, 2)[:, 1]
    yr = cv2.undistortPoints(pr, rig.K_right, rig.dist_right, R=rect["R2"], P=rect["P2"]).reshape(-1, 2)[:, 1]
    return np.abs(yl - yr)
