"""Synthetic calibration views: a board pictured by a known virtual stereo rig (for tests and demos).

The renderer traces every (super-sampled) pixel of the distorted camera back to the board plane, so the
rendered corners sit exactly where ``cv2.projectPoints`` puts them, distortion included.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from calib.boards import Board, CheckerBoard, board_image
from calib.errors import CalibrationError
from calib.rig import StereoRig

__all__ = ["SyntheticViews", "render_view", "random_board_poses", "render_stereo_views", "normalized_rays"]


def normalized_rays(K: np.ndarray, dist: np.ndarray, image_size: tuple[int, int], supersample: int = 2) -> np.ndarray:
    """Undistorted normalised coordinates ``(x, y)`` of every sub-pixel sample, ``(H*s, W*s, 2) float64``."""
    width, height = image_size
    s = supersample
    offsets = (np.arange(s) + 0.5) / s - 0.5
    us = (np.arange(width)[:, None] + offsets[None, :]).reshape(-1)
    vs = (np.arange(height)[:, None] + offsets[None, :]).reshape(-1)
    grid = np.stack(np.meshgrid(us, vs), axis=-1).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)
    rays = cv2.undistortPoints(grid, K, dist, criteria=criteria)
    return rays.reshape(height * s, width * s, 2)


def render_view(rays: np.ndarray, rvec: np.ndarray, tvec: np.ndarray, texture: np.ndarray, px_per_m: float,
                origin_px: tuple[float, float], *, supersample: int = 2, background: int = 110) -> np.ndarray:
    """Render the board texture seen through ``rays`` (from :func:`normalized_rays`) at pose ``rvec, tvec``
    (board frame -> camera frame, metres). Returns ``(H, W) float32`` grey levels 0..255."""
    rot, _ = cv2.Rodrigues(np.asarray(rvec, np.float64).reshape(3, 1))
    hom = np.column_stack([rot[:, 0], rot[:, 1], np.asarray(tvec, np.float64).reshape(3)])
    inv = np.linalg.inv(hom)
    x, y = rays[..., 0], rays[..., 1]
    bx = inv[0, 0] * x + inv[0, 1] * y + inv[0, 2]
    by = inv[1, 0] * x + inv[1, 1] * y + inv[1, 2]
    bw = inv[2, 0] * x + inv[2, 1] * y + inv[2, 2]
    in_front = bw > 1e-12
    with np.errstate(divide="ignore", invalid="ignore"):
        map_x = np.where(in_front, bx / bw * px_per_m + origin_px[0], -1e6).astype(np.float32)
        map_y = np.where(in_front, by / bw * px_per_m + origin_px[1], -1e6).astype(np.float32)
    fine = cv2.remap(texture.astype(np.float32), map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                     borderValue=float(background))
    s = supersample
    h, w = fine.shape[0] // s, fine.shape[1] // s
    return fine.reshape(h, s, w, s).mean(axis=(1, 3))


def random_board_poses(board: Board, rig: StereoRig, n: int, *, rng: int | np.random.Generator = 0,
                       distance_m: tuple[float, float] = (0.45, 0.9), max_tilt_deg: float = 35.0,
                       margin_px: float = 25.0) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n`` poses (rvec, tvec) of the board in the left camera frame that both cameras see whole."""
    rng = np.random.default_rng(rng)
    obj = _board_outline(board)
    centre = obj.mean(axis=0)
    width, height = rig.image_size
    poses: list[tuple[np.ndarray, np.ndarray]] = []
    tries = 0
    while len(poses) < n:
        tries += 1
        if tries > 200 * n:
            raise CalibrationError(f"could not place the board in view of both cameras ({len(poses)} of {n} poses)")
        tilt = np.deg2rad(max_tilt_deg)
        rvec = np.array([rng.uniform(-tilt, tilt), rng.uniform(-tilt, tilt), rng.uniform(-0.3, 0.3)])
        rot, _ = cv2.Rodrigues(rvec)
        z = rng.uniform(*distance_m)
        target = np.array([rng.uniform(-0.25, 0.25) * z, rng.uniform(-0.18, 0.18) * z, z])
        tvec = target - rot @ centre
        ok = True
        for K, dist, r_cam, t_cam in ((rig.K_left, rig.dist_left, np.eye(3), np.zeros(3)),
                                      (rig.K_right, rig.dist_right, rig.R, rig.T)):
            r_view = r_cam @ rot
            t_view = r_cam @ tvec + t_cam
            pts_cam = obj @ r_view.T + t_view
            if np.any(pts_cam[:, 2] < 0.1):
                ok = False
                break
            img, _ = cv2.projectPoints(obj, cv2.Rodrigues(r_view)[0], t_view, K, dist)
            img = img.reshape(-1, 2)
            if (img.min(axis=0) < margin_px).any() or img[:, 0].max() > width - margin_px or img[:, 1].max() > height - margin_px:
                ok = False
                break
        if ok:
            poses.append((rvec, tvec))
    return poses


def _board_outline(board: Board) -> np.ndarray:
    """The four outer corners of the printed squares in the board frame (metres)."""
    if isinstance(board, CheckerBoard):
        s = board.square_m
        x0, y0, x1, y1 = -s, -s, board.cols * s, board.rows * s
    else:
        s = board.square_m
        x0, y0, x1, y1 = 0.0, 0.0, board.squares_x * s, board.squares_y * s
    return np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0]], dtype=np.float64)


@dataclass(frozen=True)
class SyntheticViews:
    """Rendered stereo views of a board: ``left``/``right`` lists of (H, W) uint8 and the poses used."""

    left: list[np.ndarray]
    right: list[np.ndarray]
    poses: list[tuple[np.ndarray, np.ndarray]]


def render_stereo_views(rig: StereoRig, board: Board, n_views: int, *, rng: int | np.random.Generator = 0,
                        noise_sigma: float = 1.5, supersample: int = 2, px_per_square: int = 48) -> SyntheticViews:
    """Render ``n_views`` pairs of the board seen by ``rig`` (grey uint8, Gaussian noise of ``noise_sigma``)."""
    rng = np.random.default_rng(rng)
    texture, px_per_m, origin = board_image(board, px_per_square=px_per_square)
    texture = (texture.astype(np.float32) * (200.0 / 255.0) + 30.0)  # printed black/white is never 0/255
    rays_left = normalized_rays(rig.K_left, rig.dist_left, rig.image_size, supersample)
    rays_right = normalized_rays(rig.K_right, rig.dist_right, rig.image_size, supersample)
    poses = random_board_poses(board, rig, n_views, rng=rng)
    left, right = [], []
    for rvec, tvec in poses:
        rot, _ = cv2.Rodrigues(rvec)
        r_right = rig.R @ rot
        t_right = rig.R @ tvec + rig.T
        for rays, rv, tv, out in ((rays_left, rvec, tvec, left), (rays_right, cv2.Rodrigues(r_right)[0], t_right, right)):
            img = render_view(rays, rv, tv, texture, px_per_m, origin, supersample=supersample)
            img = img + rng.normal(0.0, noise_sigma, img.shape)
            out.append(np.clip(np.rint(img), 0, 255).astype(np.uint8))
    return SyntheticViews(left=left, right=right, poses=poses)

