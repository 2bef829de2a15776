"""Synthetic stereo scenes with planted objects for the fusion, pipeline and CLI tests (test helper, no API).

A textured box at depth ``z_box`` stands in front of a textured wall at ``z_wall``. Each surface carries
its own texture attached to the surface (a function of the left-image column), so the right image is the
left one with every surface shifted by its own disparity ``d = f B / Z - doffs``: exactly what a pinhole
stereo pair of two fronto-parallel planes shows, occlusions included.
"""

from __future__ import annotations

import cv2
import numpy as np

from calib import RectifiedRig


def make_rig(width: int, height: int, *, focal_px: float = 700.0, baseline_m: float = 0.12,
             doffs: float = 0.0) -> RectifiedRig:
    """A rectified rig with the principal point at the image centre."""
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    return RectifiedRig(focal_px=focal_px, cx_left=cx, cx_right=cx + doffs, cy=cy, baseline_m=baseline_m,
                        image_size=(width, height))


def disparity_of(z: float, rig) -> float:
    return rig.focal_px * rig.baseline_m / z - rig.doffs


def _texture(shape, seed: int, width_extra: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    h, w = shape
    tex = rng.random((h, w + width_extra)).astype(np.float32)
    tex = cv2.GaussianBlur(tex, (0, 0), 1.0)
    tex = (tex - tex.min()) / (np.ptp(tex) + 1e-9)
    return 30.0 + 200.0 * tex


def planted_scene(*, width: int = 240, height: int = 160, z_wall: float = 8.0, z_box: float = 3.0,
                  box: tuple[int, int, int, int] = (80, 50, 160, 110), rig=None, seed: int = 0):
    """Left/right uint8 BGR images, ground-truth left disparity (float32) and the rig.

    ``box`` is the object's (x0, y0, x1, y1) in the left image (exclusive ends).
    """
    rig = rig or make_rig(width, height)
    d_wall, d_box = disparity_of(z_wall, rig), disparity_of(z_box, rig)
    pad = int(np.ceil(d_box)) + 4
    wall = _texture((height, width), seed, pad)          # indexed by left column + pad
    obj = _texture((height, width), seed + 1, pad)
    x0, y0, x1, y1 = box
    cols = np.arange(width, dtype=np.float32)

    def sample(tex, xs, row):
        return np.interp(xs + pad, np.arange(tex.shape[1]), tex[row])

    left = np.empty((height, width), np.float32)
    right = np.empty((height, width), np.float32)
    gt = np.full((height, width), d_wall, np.float32)
    gt[y0:y1, x0:x1] = d_box
    for r in range(height):
        in_rows = y0 <= r < y1
        left[r] = sample(wall, cols, r)
        if in_rows:
            left[r, x0:x1] = sample(obj, cols[x0:x1], r)
        xl_wall, xl_box = cols + d_wall, cols + d_box   # left column seen at right column x
        right[r] = sample(wall, xl_wall, r)
        if in_rows:
            hit = (xl_box >= x0) & (xl_box < x1)
            right[r, hit] = sample(obj, xl_box[hit], r)
    to_bgr = lambda a: cv2.cvtColor(np.clip(a + 0.5, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR)  # noqa: E731
    return to_bgr(left), to_bgr(right), gt, rig
