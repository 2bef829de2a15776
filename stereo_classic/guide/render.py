"""Pictures of a guide frame: the left image with what the guide found (``overlay``) and a top-down view
(``birdseye``).

Overlay: the walking corridor on the ground (green), obstacle pixels in the corridor (red), the drop-off edge
(magenta), tracked objects and obstacles with their id, distance and approach speed, the horizon of the up
direction measured from the vertical lines (dashed cyan), the haptic sectors along the bottom (white = free,
red = blocked) and the frame's messages at the top. Bird's-eye: 10 cm cells of the
occupancy grid (grey; red inside the corridor), the corridor, one ray per clock hour as long as its free
distance (green: the clear path), the drop-off edge, the tracks, a line every metre; the camera at the bottom.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from calib import RectifiedRig
from stereo_classic.guide.core import GuideFrame
from stereo_classic.guide.params import GuideParams

__all__ = ["draw_birdseye", "draw_overlay"]

_GREEN, _RED, _MAGENTA, _YELLOW, _WHITE, _CYAN = (60, 200, 60), (40, 40, 230), (220, 60, 220), (0, 220, 255), \
    (255, 255, 255), (230, 200, 40)


def _bgr(image: np.ndarray) -> np.ndarray:
    if image.ndim == 2:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    return image.copy()


def _project(xyz: np.ndarray, rig: RectifiedRig) -> np.ndarray:
    z = np.maximum(xyz[:, 2], 1e-6)
    return np.column_stack([rig.focal_px * xyz[:, 0] / z + rig.cx_left, rig.focal_px * xyz[:, 1] / z + rig.cy])


def _text(img: np.ndarray, text: str, org: tuple[int, int], colour: tuple[int, int, int], scale: float = 0.45) -> None:
    """``text`` in ``colour`` on a black box (readable on any background; a thick black copy of the text under it
    does not line up: OpenCV spaces the letters of thicker text wider)."""
    (tw, th), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
    x, y = org
    cv2.rectangle(img, (x - 2, y - th - 2), (x + tw + 2, y + base), (0, 0, 0), -1)
    cv2.putText(img, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, colour, 1, cv2.LINE_AA)


def _ground_line(frame: GuideFrame, rig: RectifiedRig, lateral: np.ndarray, forward: np.ndarray) -> np.ndarray | None:
    if frame.ground is None:
        return None
    cam = frame.ground.to_camera(lateral, forward)
    ok = cam[:, 2] > 0.2
    if ok.sum() < 2:
        return None
    return np.round(_project(cam[ok], rig)).astype(np.int32)


def _horizon(img: np.ndarray, frame: GuideFrame, rig: RectifiedRig) -> None:
    """The horizon of ``frame.gravity`` (the image points whose rays are level), dashed, with the camera's pitch
    and roll; where it lies outside the view, the label at the border it lies beyond."""
    if frame.gravity is None:
        return
    h, w = img.shape[:2]
    up, f = frame.gravity.up, rig.focal_px
    label = f"horizon (vertical lines): pitch {frame.gravity.pitch_deg:.0f}, roll {frame.gravity.roll_deg:.0f} deg"
    if abs(up[1]) < 1e-3:
        return
    us = np.array([0.0, w - 1.0])
    vs = rig.cy - (up[2] * f + up[0] * (us - rig.cx_left)) / up[1]     # up . (u - cx, v - cy, f) = 0
    if max(vs) < 0 or min(vs) > h - 1:
        below = min(vs) > h - 1
        _text(img, label + (" (below the view)" if below else " (above the view)"), (6, h - 16 if below else 60),
              _CYAN, 0.4)
        return
    n = 24
    for i in range(0, n, 2):                                            # dashed: every other piece
        a, b = i / n, (i + 1) / n
        p0 = (round(us[0] + a * (us[1] - us[0])), round(vs[0] + a * (vs[1] - vs[0])))
        p1 = (round(us[0] + b * (us[1] - us[0])), round(vs[0] + b * (vs[1] - vs[0])))
        cv2.line(img, p0, p1, _CYAN, 1, cv2.LINE_AA)
    y = int(np.clip(vs[1] - 6, 24, h - 16))
    (tw, _), _ = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, 0.4, 1)
    _text(img, label, (max(2, w - tw - 6), y), _CYAN, 0.4)


def draw_overlay(image: np.ndarray, frame: GuideFrame, rig: RectifiedRig, params: GuideParams,
                 obstacle_uv: np.ndarray | None = None) -> np.ndarray:
    """The left image ((H, W) or (H, W, 3) uint8) with the frame drawn on it; (H, W, 3) uint8 BGR."""
    img = _bgr(image)
    h, w = img.shape[:2]
    obstacle_uv = frame.obstacle_uv if obstacle_uv is None else obstacle_uv
    half = params.corridor_width / 2
    if obstacle_uv is not None and len(obstacle_uv):
        for u, v in np.round(obstacle_uv).astype(int):
            cv2.circle(img, (int(u), int(v)), 1, _RED, -1)
    fwd = np.linspace(0.5, params.look_ahead, 20)
    for side in (-half, half):
        line = _ground_line(frame, rig, np.full_like(fwd, side), fwd)
        if line is not None:
            cv2.polylines(img, [line], False, _GREEN, 1, cv2.LINE_AA)
    if frame.dropoff is not None:
        d = frame.dropoff
        b = math.radians(d.bearing_deg)
        offs = np.linspace(-half, half, 9)
        line = _ground_line(frame, rig, d.lateral_m + offs * math.cos(b), d.forward_m - offs * math.sin(b))
        if line is not None:
            cv2.polylines(img, [line], False, _MAGENTA, 3, cv2.LINE_AA)
            x, y = line[0]
            _text(img, f"drop {d.drop_m:.2f} m at {d.distance_m:.1f} m", (int(x), int(y) - 6), _MAGENTA)
    for t in frame.tracks:
        speed = f" {t.approach_mps:+.1f} m/s" if t.approach_mps is not None else ""
        label = f"#{t.track_id} {t.label} {t.nearest_m:.1f} m{speed}"
        if t.box is not None:
            x0, y0, x1, y1 = (round(v) for v in t.box)
            cv2.rectangle(img, (x0, y0), (x1, y1), _YELLOW, 2)
            _text(img, label, (x0, max(12, y0 - 4)), _YELLOW)
        elif frame.ground is not None:
            cam = frame.ground.to_camera(np.array([t.lateral_m]), np.array([t.forward_m]), 1.0)
            if cam[0, 2] > 0.2:
                u, v = np.round(_project(cam, rig)[0]).astype(int)
                _text(img, label, (int(np.clip(u - 40, 0, w - 80)), int(np.clip(v, 12, h - 30))), _CYAN)
    _horizon(img, frame, rig)
    n = len(frame.haptics)
    for i, value in enumerate(frame.haptics):
        x0, x1 = int(i * w / n), int((i + 1) * w / n) - 2
        colour = tuple(int(c) for c in (np.array(_WHITE) * (1 - value) + np.array(_RED) * value))
        cv2.rectangle(img, (x0, h - 10), (x1, h - 2), colour, -1)
    y = 16
    for e in frame.events[:4]:
        _text(img, f"[{e.priority}] {e.text}", (6, y), _RED if e.priority == "danger" else _WHITE)
        y += 16
    for note in frame.notes[:2]:
        _text(img, note, (6, y), _YELLOW, 0.4)
        y += 14
    return img


def draw_birdseye(frame: GuideFrame, params: GuideParams, *, px_per_m: float = 50.0) -> np.ndarray:
    """Top-down view, (H, W, 3) uint8 BGR: lateral -look_ahead..look_ahead across, forward 0..look_ahead up."""
    ext = params.look_ahead
    w, h = int(2 * ext * px_per_m), int(ext * px_per_m) + 20
    img = np.full((h, w, 3), 30, np.uint8)

    def px(lat: float, fwd: float) -> tuple[int, int]:
        return round((lat + ext) * px_per_m), round(h - 10 - fwd * px_per_m)

    for m in range(1, int(ext) + 1):
        cv2.line(img, px(-ext, m), px(ext, m), (60, 60, 60), 1)
        _text(img, f"{m} m", (4, px(0, m)[1] - 2), (150, 150, 150), 0.35)
    half = params.corridor_width / 2
    if frame.grid is not None:
        rows, cols = np.nonzero(frame.grid.occupied)
        cell = ext * 2 / frame.grid.occupied.shape[1]
        for r, c in zip(rows, cols):
            lat, fwd = -ext + c * cell, r * cell
            inside = abs(lat + cell / 2) < half
            cv2.rectangle(img, px(lat, fwd + cell), px(lat + cell, fwd), _RED if inside else (150, 150, 150), -1)
    cv2.rectangle(img, px(-half, ext), px(half, 0), _GREEN, 1)
    origin = px(0, 0)
    for hour, free in zip(frame.hours, frame.free_m):
        if not math.isfinite(float(free)):
            continue
        b = math.radians(((int(hour) % 12) * 30 + 180) % 360 - 180)
        end = px(free * math.sin(b), free * math.cos(b))
        colour = _GREEN if frame.clear_clock == int(hour) else (120, 160, 120)
        cv2.line(img, origin, end, colour, 2 if frame.clear_clock == int(hour) else 1, cv2.LINE_AA)
        _text(img, f"{hour}", (end[0] - 6, max(12, end[1] - 4)), colour, 0.4)
    if frame.dropoff is not None:
        d = frame.dropoff
        b = math.radians(d.bearing_deg)
        a = px(d.lateral_m - half * math.cos(b), d.forward_m + half * math.sin(b))
        z = px(d.lateral_m + half * math.cos(b), d.forward_m - half * math.sin(b))
        cv2.line(img, a, z, _MAGENTA, 3)
    for t in frame.tracks:
        centre = px(t.lateral_m, t.forward_m)
        cv2.circle(img, centre, 5, _YELLOW if t.kind == "object" else _CYAN, -1)
        _text(img, f"#{t.track_id} {t.label}", (centre[0] + 6, centre[1]), _YELLOW if t.kind == "object" else _CYAN,
              0.35)
    cv2.circle(img, origin, 5, _WHITE, -1)
    return img
