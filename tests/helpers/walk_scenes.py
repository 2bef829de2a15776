"""Synthetic stereo frames of a walk: a textured floor (optionally stepping down), walls, boxes and a bar, seen by a
rectified pair mounted at a known height and pitch (test helper, no API).

World frame: x right, y up, z forward along the ground, metres; the left camera sits at (0, height, 0) looking
forward and down by ``pitch_deg``; the right camera is ``baseline_m`` to its right. Every surface is an
axis-aligned box with a texture fixed to its faces, so both images show the same surface points: exact geometry,
occlusions included. Ray casting per pixel (slab test), bilinear texture lookup, 2x2 super-sampling.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from tests.helpers.scenes import make_rig


@dataclass(frozen=True)
class Box:
    """An axis-aligned box ``[x0, x1] x [y0, y1] x [z0, z1]`` in the world frame (metres); its texture's grey
    levels are multiplied by ``tone`` (below 1: darker than the rest, so that its edges are lines)."""

    x0: float
    x1: float
    y0: float
    y1: float
    z0: float
    z1: float
    seed: int = 0
    tone: float = 1.0

    def moved(self, dz: float) -> Box:
        return Box(self.x0, self.x1, self.y0, self.y1, self.z0 + dz, self.z1 + dz, self.seed, self.tone)


def _texture(seed: int, size: int = 1024) -> np.ndarray:
    rng = np.random.default_rng(seed)
    tex = rng.random((size, size)).astype(np.float32)
    tex = cv2.GaussianBlur(tex, (0, 0), 1.2)
    tex = (tex - tex.min()) / (np.ptp(tex) + 1e-9)
    return 30.0 + 200.0 * tex


_TEXTURES: dict[int, np.ndarray] = {}


def _lookup(seed: int, a: np.ndarray, b: np.ndarray, px_per_m: float = 100.0) -> np.ndarray:
    tex = _TEXTURES.setdefault(seed, _texture(seed))
    size = tex.shape[0]
    x = np.mod(a * px_per_m, size - 1)
    y = np.mod(b * px_per_m, size - 1)
    x0, y0 = x.astype(np.int64), y.astype(np.int64)
    fx, fy = x - x0, y - y0
    top = tex[y0, x0] * (1 - fx) + tex[y0, x0 + 1] * fx
    bottom = tex[y0 + 1, x0] * (1 - fx) + tex[y0 + 1, x0 + 1] * fx
    return (top * (1 - fy) + bottom * fy).astype(np.float32)


def floor(*, step_at: float | None = None, step_down: float = 0.3, seed: int = 100) -> list[Box]:
    """The ground (top face at y = 0), ending at ``step_at`` metres ahead where it drops by ``step_down``."""
    if step_at is None:
        return [Box(-40, 40, -1, 0, -1, 60, seed)]
    return [Box(-40, 40, -1, 0, -1, step_at, seed), Box(-40, 40, -1 - step_down, -step_down, step_at, 60, seed + 1)]


def stairs_down(landing: float = 1.0, *, tread: float = 0.28, riser: float = 0.17, steps: int = 14,
                seed: int = 100, balusters: bool = False) -> list[Box]:
    """A landing (top face at y = 0) up to ``landing`` metres ahead, then a flight of ``steps`` stairs down
    (``tread`` deep, ``riser`` high each), as wide as the floor; the last step runs on as the floor below. With
    ``balusters``, dark vertical bars 1 m tall 0.75 m to either side, every 0.3 m along the landing and one on
    every step (a banister's)."""
    boxes = [Box(-40, 40, -1, 0, -1, landing, seed)]
    for k in range(1, steps + 1):
        z0 = landing + tread * (k - 1)
        boxes.append(Box(-40, 40, -1 - riser * k, -riser * k, z0, z0 + tread if k < steps else 60, seed + k))
    if balusters:
        feet = [(0.0, z) for z in np.arange(-1.0, landing, 0.3)] + \
            [(-riser * k, landing + tread * (k - 0.5)) for k in range(1, steps)]
        boxes += [Box(x - 0.02, x + 0.02, y, y + 1.0, z - 0.02, z + 0.02, seed + 60, tone=0.25)
                  for y, z in feet for x in (-0.75, 0.75)]
    return boxes


def stairs_up(start: float = 0.5, *, tread: float = 0.28, riser: float = 0.17, steps: int = 14,
              width: float = 1.6, balusters: bool = True, seed: int = 100) -> list[Box]:
    """The floor (top face at y = 0), then from ``start`` metres ahead a flight of ``steps`` stairs up, ``width``
    wide (centred), and with ``balusters`` a row of dark vertical bars 1 m tall on each side of every step (as a
    banister's): the scene of the OAK-D ``stairs`` frame, seen from the bottom."""
    half = width / 2
    boxes = [Box(-40, 40, -1, 0, -1, 60, seed)]
    for k in range(1, steps + 1):
        z0 = start + tread * (k - 1)
        boxes.append(Box(-half, half, -1, riser * k, z0, start + tread * steps + 5.0, seed + k))
    if balusters:
        for k in range(steps):
            z = start + tread * k + tread / 2
            for x in (-half + 0.05, half - 0.05):
                boxes.append(Box(x - 0.02, x + 0.02, riser * (k + 1), riser * (k + 1) + 1.0, z - 0.02, z + 0.02,
                                 seed + 60 + k, tone=0.25))
    return boxes


def poles(*, seed: int = 200) -> list[Box]:
    """Dark vertical poles 3 m tall, 8 cm square, 1.5-6 m ahead and 2 m to either side: the door frames and lamp
    posts of a scene, whose lines meet at the vertical vanishing point."""
    spots = [(-1.8, 2.0), (1.9, 2.5), (-2.2, 4.0), (2.0, 4.5), (-1.5, 6.0), (1.6, 6.5), (-0.9, 3.2), (1.0, 5.5)]
    return [Box(x - 0.04, x + 0.04, 0.0, 3.0, z - 0.04, z + 0.04, seed + i, tone=0.25)
            for i, (x, z) in enumerate(spots)]


def camera_up(pitch_deg: float, roll_deg: float = 0.0) -> np.ndarray:
    """The world's up in the camera frame of :func:`render` (X right, Y down, Z forward) for this pitch and roll:
    ``stereo_classic.guide.gravity.Gravity(up)`` has this pitch and roll."""
    t, r = math.radians(pitch_deg), math.radians(roll_deg)
    return np.array([math.sin(r) * math.cos(t), -math.cos(r) * math.cos(t), -math.sin(t)])


def render(boxes: list[Box], *, width: int = 320, height: int = 240, focal_px: float = 300.0,
           baseline_m: float = 0.12, cam_height: float = 1.2, pitch_deg: float = 15.0, roll_deg: float = 0.0,
           background: float = 110.0, supersample: int = 2):
    """Left and right (H, W, 3) uint8 BGR images, the left (H, W) float64 depth (Z, NaN: nothing hit) and the rig.
    ``roll_deg`` turns the camera about its optical axis (positive: as ``GroundPlane.roll_deg``)."""
    rig = make_rig(width, height, focal_px=focal_px, baseline_m=baseline_m)
    t = math.radians(pitch_deg)
    right_w, down_w, fwd_w = np.array([1.0, 0, 0]), np.array([0, -math.cos(t), -math.sin(t)]), \
        np.array([0, -math.sin(t), math.cos(t)])
    if roll_deg:
        r = math.radians(roll_deg)
        right_w, down_w = math.cos(r) * right_w - math.sin(r) * down_w, math.sin(r) * right_w + math.cos(r) * down_w
    s = supersample
    offs = (np.arange(s) + 0.5) / s - 0.5
    us = (np.arange(width)[:, None] + offs[None, :]).reshape(-1)
    vs = (np.arange(height)[:, None] + offs[None, :]).reshape(-1)
    uu, vv = np.meshgrid((us - rig.cx_left) / focal_px, (vs - rig.cy) / focal_px)
    dirs = uu[..., None] * right_w + vv[..., None] * down_w + fwd_w        # (H*s, W*s, 3), camera z = 1
    dirs = dirs.reshape(-1, 3)
    images, depth = [], None
    for cam_x in (0.0, baseline_m):
        origin = np.array([0.0, cam_height, 0.0]) + cam_x * right_w      # the baseline along the camera x
        best = np.full(len(dirs), np.inf)
        value = np.full(len(dirs), background, np.float32)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / dirs
        for box in boxes:
            lo = np.array([box.x0, box.y0, box.z0]) - origin
            hi = np.array([box.x1, box.y1, box.z1]) - origin
            with np.errstate(invalid="ignore"):
                t1, t2 = lo * inv, hi * inv
            tmin = np.nanmax(np.minimum(t1, t2), axis=1)
            tmax = np.nanmin(np.maximum(t1, t2), axis=1)
            hit = (tmax >= tmin) & (tmin > 1e-6) & (tmin < best)
            if not hit.any():
                continue
            idx = np.nonzero(hit)[0]
            tt = tmin[idx]
            p = origin + dirs[idx] * tt[:, None]
            axis = np.argmax(np.minimum(t1, t2)[idx], axis=1)                # the face entered
            a = np.where(axis == 0, p[:, 2], p[:, 0])
            b = np.where(axis == 1, p[:, 2], p[:, 1])
            value[idx] = _lookup(box.seed * 3 + 0, a + 7.0 * axis, b) * box.tone
            best[idx] = tt
        img = value.reshape(height, s, width, s).mean(axis=(1, 3))
        images.append(cv2.cvtColor(np.clip(img + 0.5, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR))
        if cam_x == 0.0:
            z = best.reshape(height, s, width, s)[:, s // 2, :, s // 2]    # camera-z of the centre samples
            depth = np.where(np.isfinite(z), z, np.nan)
    return images[0], images[1], depth, rig


#: The camera of the test walks: 1.2 m up, looking down 10 degrees, 320x240, f = 300 px, B = 0.12 m.
CAMERA = {"cam_height": 1.2, "pitch_deg": 10.0}


def approach(n: int = 10, fps: float = 10.0, speed: float = 1.0, start: float = 3.0, lateral: float = 0.0):
    """A box (0.6 m wide, 0.8 m tall) coming straight at the camera at ``speed`` m/s from ``start`` metres ahead
    (its front face), a wall on the right. Returns ``[(left, right, front_distance, time_s)], rig``."""
    frames, rig = [], None
    for i in range(n):
        t = i / fps
        front = start - speed * t
        boxes = floor() + [Box(lateral - 0.3, lateral + 0.3, 0.0, 0.8, front, front + 0.4, seed=5),
                           Box(1.8, 1.9, 0.0, 3.0, 0.0, 20.0, seed=7)]
        left, right, _, rig = render(boxes, supersample=1, **CAMERA)
        frames.append((left, right, front, t))
    return frames, rig


def still(boxes: list[Box], **floor_kw):
    """One frame of ``boxes`` on the floor (``floor_kw`` for :func:`floor`): ``left, right, depth, rig``."""
    return render(floor(**floor_kw) + boxes, supersample=1, **CAMERA)
