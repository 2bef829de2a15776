"""Rendered driving scenes with exact ground truth per object: small, far cars and persons on a textured road.

The DrivingStereo rig (881x400, f = 1003.556 px, B = 0.5446 m, the camera 1.65 m above the road, level). Every
surface is an axis-aligned box with a texture fixed to its faces, ray-cast from both cameras (2x2 samples per
pixel), so both images show the same surface points: exact geometry and occlusions. A car is not one block: a body
(0.3-1.0 m), a cabin set 0.8 m back (1.0-1.45 m: pillars and roof around windows that show what lies beyond, as
glass shows what is behind it or what it reflects, both far), four wheels; the road under it, the background beside
the cabin and through its windows show inside its box, as on a real car; its paint has a fifth of the road's texture
contrast. A person: two legs, a torso, a head, the road between the legs. Around them: other traffic, a far row of
buildings.

The reference distance of an object is the median depth (Z) of the left-image pixels whose ray hits it: what the
LiDAR median of the points in its 3D box gives on the real frames. Its box is the bounding box of those pixels grown
by 10 % on each side (a detector's box is looser than the object).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["Part", "RoadObject", "RoadScene", "car", "person", "render_road_scene", "road_scenes", "DRIVING_RIG"]

#: The DrivingStereo half-resolution rig (docs of ``../shared/data``): width, height, focal px, baseline m.
DRIVING_RIG = {"width": 881, "height": 400, "focal_px": 1003.556, "baseline_m": 0.5446}
CAMERA_HEIGHT_M = 1.65


@dataclass(frozen=True)
class Part:
    """An axis-aligned box ``[x0, x1] x [y0, y1] x [z0, z1]`` (metres; x right, y up, z forward) with a texture:
    ``seed``, ``px_per_m`` texels per metre, grey mean ``tone`` and ``contrast`` (1: 30..230 grey levels)."""

    x0: float
    x1: float
    y0: float
    y1: float
    z0: float
    z1: float
    seed: int = 0
    tone: float = 130.0
    contrast: float = 1.0
    px_per_m: float = 20.0


@dataclass(frozen=True)
class RoadObject:
    label: str
    parts: tuple[Part, ...]


@dataclass(frozen=True)
class RoadScene:
    """Left and right (H, W, 3) uint8 BGR images, the rig, the objects' labels, boxes (N, 4) x0 y0 x1 y1 (the object's
    pixels grown by a margin, as a detector's) and reference distances (N,) metres, and ``name``."""

    name: str
    left: np.ndarray
    right: np.ndarray
    rig: object
    labels: tuple[str, ...]
    boxes: np.ndarray
    reference_m: np.ndarray


def car(x: float, z: float, seed: int, *, tone: float = 120.0, contrast: float = 0.2) -> RoadObject:
    """A car 1.8 m wide, 1.45 m tall, 4.2 m long, its rear face ``z`` metres ahead, centred at ``x``."""
    paint = {"tone": tone, "contrast": contrast, "seed": seed, "px_per_m": 20.0}
    cabin = {**paint, "tone": tone * 0.8}
    parts = [Part(x - 0.9, x + 0.9, 0.3, 1.0, z, z + 4.2, **paint),
             # the cabin: pillars and roof around a rear and a front window that show what lies beyond
             Part(x - 0.75, x - 0.6, 1.0, 1.45, z + 0.8, z + 3.2, **cabin),
             Part(x + 0.6, x + 0.75, 1.0, 1.45, z + 0.8, z + 3.2, **cabin),
             Part(x - 0.75, x + 0.75, 1.37, 1.45, z + 0.8, z + 3.2, **cabin)]
    for dx in (-0.85, 0.6):
        for z0 in (z + 0.4, z + 3.3):
            parts.append(Part(x + dx, x + dx + 0.25, 0.0, 0.35, z0, z0 + 0.6, seed + 1, 40.0, 0.5))
    return RoadObject("car", tuple(parts))


def person(x: float, z: float, seed: int, *, tone: float = 90.0, contrast: float = 0.4) -> RoadObject:
    """A person 1.75 m tall, 0.5 m wide, 0.3 m deep, ``z`` metres ahead, centred at ``x``."""
    cloth = {"tone": tone, "contrast": contrast, "seed": seed, "px_per_m": 40.0}
    return RoadObject("person", (
        Part(x - 0.2, x - 0.05, 0.0, 0.85, z, z + 0.3, **cloth),
        Part(x + 0.05, x + 0.2, 0.0, 0.85, z, z + 0.3, **cloth),
        Part(x - 0.25, x + 0.25, 0.85, 1.5, z, z + 0.3, **{**cloth, "tone": tone * 1.4}),
        Part(x - 0.1, x + 0.1, 1.5, 1.75, z + 0.05, z + 0.25, **{**cloth, "tone": 150.0})))


_TEXTURES: dict[int, np.ndarray] = {}


def _texture(seed: int, size: int = 512) -> np.ndarray:
    tex = _TEXTURES.get(seed)
    if tex is None:
        tex = np.random.default_rng(seed).random((size, size)).astype(np.float32)
        tex = cv2.GaussianBlur(tex, (0, 0), 1.2)
        tex = (tex - tex.min()) / (np.ptp(tex) + 1e-9) - 0.5  # -0.5 .. 0.5
        tex = _TEXTURES[seed] = tex
    return tex


def _shade(part: Part, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    tex = _texture(part.seed)
    size = tex.shape[0]
    x = np.mod(a * part.px_per_m, size - 1)
    y = np.mod(b * part.px_per_m, size - 1)
    x0, y0 = np.minimum(x.astype(np.int64), size - 2), np.minimum(y.astype(np.int64), size - 2)
    fx, fy = x - x0, y - y0
    v = (tex[y0, x0] * (1 - fx) + tex[y0, x0 + 1] * fx) * (1 - fy) + \
        (tex[y0 + 1, x0] * (1 - fx) + tex[y0 + 1, x0 + 1] * fx) * fy
    return (part.tone + 200.0 * part.contrast * v).astype(np.float32)


def _cast(parts: list[tuple[int, Part]], origin: np.ndarray, dirs: np.ndarray, grid: tuple[int, int], f: float,
          centre: tuple[float, float], sky: float):
    """Grey value, hit distance along the ray (camera z, dirs have z = 1) and the owner id (-1 none) per ray of the
    (rows, cols) ``grid`` (ray = row * cols + col, image coordinates ``centre + (col, row) / s``). A part in front
    of the camera is tested only against the rays inside its projected rectangle."""
    rows, cols = grid
    s = cols // DRIVING_RIG["width"] if cols >= DRIVING_RIG["width"] else 1
    n = len(dirs)
    best = np.full(n, np.inf)
    value = np.full(n, sky, np.float32)
    owner = np.full(n, -1, np.int32)
    for oid, part in parts:
        lo = np.array([part.x0, part.y0, part.z0]) - origin
        hi = np.array([part.x1, part.y1, part.z1]) - origin
        if lo[2] > 0.5:  # entirely ahead: only the rays of its projected rectangle
            xs, ys, zs = (lo[0], hi[0]), (lo[1], hi[1]), (lo[2], hi[2])
            us = [centre[0] + f * x / z for x in xs for z in zs]
            vs = [centre[1] - f * y / z for y in ys for z in zs]
            c0 = max(0, int(math.floor((min(us) + 0.5) * s)) - 1)
            c1 = min(cols, int(math.ceil((max(us) + 0.5) * s)) + 1)
            r0 = max(0, int(math.floor((min(vs) + 0.5) * s)) - 1)
            r1 = min(rows, int(math.ceil((max(vs) + 0.5) * s)) + 1)
            if c1 <= c0 or r1 <= r0:
                continue
            idx_all = (np.arange(r0, r1)[:, None] * cols + np.arange(c0, c1)[None, :]).ravel()
        else:
            idx_all = np.arange(n)
        d = dirs[idx_all]
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / d
            t1, t2 = lo * inv, hi * inv
        tmin = np.nanmax(np.minimum(t1, t2), axis=1)
        tmax = np.nanmin(np.maximum(t1, t2), axis=1)
        hit = (tmax >= tmin) & (tmin > 1e-6) & (tmin < best[idx_all])
        if not hit.any():
            continue
        sel = np.nonzero(hit)[0]
        idx = idx_all[sel]
        tt = tmin[sel]
        p = origin + d[sel] * tt[:, None]
        axis = np.argmax(np.minimum(t1, t2)[sel], axis=1)  # the face entered
        a = np.where(axis == 0, p[:, 2], p[:, 0])
        b = np.where(axis == 1, p[:, 2], p[:, 1])
        value[idx] = _shade(part, a + 7.0 * axis, b)
        best[idx] = tt
        owner[idx] = oid
    return value, best, owner


def render_road_scene(objects: list[RoadObject], *, name: str = "road", n_targets: int | None = None,
                      seed: int = 0, supersample: int = 2, margin: float = 0.1, shift: float = 0.0,
                      background_m: float = 140.0) -> RoadScene:
    """Render ``objects`` on the road in front of a far row of buildings. The first ``n_targets`` objects (all
    when None) are reported with boxes and references; the others are traffic only. A box is the object's pixels'
    bounding box grown by ``margin`` of its size on each side: a detector's box is looser than the object (the
    KITTI frame's detections match its labelled boxes at IoU 0.57 to 0.91; a 10 % margin gives 0.69). ``shift``
    moves the boxes up by that fraction of their height (a detector's box placed too high on a small object: 0.2
    keeps IoU 0.67 with the unshifted box, 0.35 0.48). ``background_m``: how far the row of buildings is."""
    from calib import RectifiedRig

    w, h, f, base = (DRIVING_RIG[k] for k in ("width", "height", "focal_px", "baseline_m"))
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    rig = RectifiedRig(focal_px=f, cx_left=cx, cx_right=cx, cy=cy, baseline_m=base, image_size=(w, h))
    road = Part(-60, 60, -1, 0, 0.5, 400, seed + 500, 110.0, 0.6, 20.0)  # its top face y = 0: cast analytically
    world: list[tuple[int, Part]] = [(-1, Part(-150, 150, 0, 25, background_m, background_m + 5, seed + 501, 140.0, 1.0,
                                               560.0 / background_m))]  # buildings (texels ~ 7 px wide at any distance)
    for i, obj in enumerate(objects):
        world += [(i, p) for p in obj.parts]
    s = supersample
    offs = (np.arange(s) + 0.5) / s - 0.5
    us = (np.arange(w)[:, None] + offs[None, :]).reshape(-1)
    vs = (np.arange(h)[:, None] + offs[None, :]).reshape(-1)
    uu, vv = np.meshgrid((us - cx) / f, (vs - cy) / f)
    dirs = np.stack([uu, -vv, np.ones_like(uu)], axis=-1).reshape(-1, 3)  # y up in the world, down in the image
    images = []
    depth = owner = None
    for cam_x in (0.0, base):
        value, t, who = _cast(world, np.array([cam_x, CAMERA_HEIGHT_M, 0.0]), dirs, (h * s, w * s), f, (cx, cy),
                              sky=200.0)
        below = np.nonzero(dirs[:, 1] < 0)[0]  # rays below the horizon meet the road at z = height / -dir_y
        tr = CAMERA_HEIGHT_M / -dirs[below, 1]
        on = below[tr < t[below]]
        tr = CAMERA_HEIGHT_M / -dirs[on, 1]
        value[on] = _shade(road, cam_x + dirs[on, 0] * tr, tr)
        t[on] = tr
        who[on] = -1
        img = value.reshape(h, s, w, s).mean(axis=(1, 3))
        images.append(cv2.cvtColor(np.clip(img + 0.5, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR))
        if cam_x == 0.0:
            depth = t.reshape(h, s, w, s)[:, s // 2, :, s // 2]
            owner = who.reshape(h, s, w, s)[:, s // 2, :, s // 2]
    n = len(objects) if n_targets is None else n_targets
    boxes, refs, labels = [], [], []
    for i in range(n):
        vv_, uu_ = np.nonzero(owner == i)
        if uu_.size == 0:
            continue
        x0, y0, x1, y1 = uu_.min(), vv_.min(), uu_.max() + 1.0, vv_.max() + 1.0
        mx, my = margin * (x1 - x0), margin * (y1 - y0)  # a detector's box: looser than the object
        up = shift * (y1 - y0 + 2 * my)
        boxes.append([max(0.0, x0 - mx), max(0.0, y0 - my - up), min(float(w), x1 + mx), min(float(h), y1 + my - up)])
        refs.append(float(np.median(depth[owner == i])))
        labels.append(objects[i].label)
    return RoadScene(name, images[0], images[1], rig, tuple(labels), np.array(boxes, np.float64).reshape(-1, 4),
                     np.array(refs))


def road_scenes(*, seed: int = 0) -> list[RoadScene]:
    """The benchmark's rendered scenes: a car 25 to 60 m ahead (6 distances, in the lane or one lane over) and a
    person 10 to 30 m ahead (5 distances), each with other traffic (a near car in the next lane, a far one
    behind) and the buildings 140 m away; then the failure of issue 31: a car 32, 36, 40 m ahead with buildings
    60 m away and a person 20, 28 m ahead with buildings 15 m behind, each with its box placed 0.2 and 0.35 of its
    height too high (10 scenes). Deterministic: the textures come from ``seed``."""
    out = []
    for k, z in enumerate((25.0, 32.0, 38.0, 45.0, 52.0, 60.0)):
        x = (0.0, 3.5, -3.5)[k % 3]
        traffic = [car(-3.5 if x >= 0 else 3.5, 12.0 + k, seed + 20 + k, tone=160.0),
                   car(x + 1.0, z + 25.0, seed + 40 + k, tone=90.0)]
        out.append(render_road_scene([car(x, z, seed + k * 7, tone=(120.0, 70.0, 180.0)[k % 3])] + traffic,
                                     name=f"car_{z:.0f}m", n_targets=1, seed=seed + k))
    for k, z in enumerate((10.0, 15.0, 20.0, 25.0, 30.0)):
        x = (2.5, -3.0, 4.0, -2.0, 3.0)[k]
        traffic = [car(0.0, z + 8.0, seed + 60 + k), car(-x, 0.7 * z + 6.0, seed + 70 + k, tone=170.0)]
        out.append(render_road_scene([person(x, z, seed + 80 + k)] + traffic, name=f"person_{z:.0f}m",
                                     n_targets=1, seed=seed + 10 + k))
    # the failure of issue 31: a box placed too high on a small far object, trees and buildings close behind it
    for k, (z, x) in enumerate(((32.0, 0.0), (36.0, 3.5), (40.0, -3.5))):
        for shift in (0.2, 0.35):
            out.append(render_road_scene([car(x, z, seed + 90 + k), car(-x if x else 3.5, 14.0 + k, seed + 95 + k)],
                                         name=f"car_{z:.0f}m_high{shift:.2f}", n_targets=1, seed=seed + 20 + k,
                                         shift=shift, background_m=60.0))
    for k, z in enumerate((20.0, 28.0)):
        for shift in (0.2, 0.35):
            out.append(render_road_scene([person((3.0, -2.5)[k], z, seed + 100 + k)],
                                         name=f"person_{z:.0f}m_high{shift:.2f}", n_targets=1, seed=seed + 30 + k,
                                         shift=shift, background_m=z + 15.0))
    return out
