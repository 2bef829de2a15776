"""The results of a frame as ROS 2 messages, as plain dicts (the MCAP writer takes them as they are; the live node
fills ``rclpy`` messages from them with :func:`fill`).

* :func:`disparity_image`: ``stereo_msgs/DisparityImage`` of the **measured** disparity (filled pixels are guesses
  and stay unknown): ``32FC1`` pixels, ``d = x_left - x_right``; an unknown pixel (NaN) is written as
  ``min_disparity - 1``, below the message's valid range, as the message defines ("any disparity less than
  min_disparity is invalid"). ``f`` is the focal length (px), ``t`` the baseline (m); depth is
  ``Z = f * t / (d + doffs)`` with ``doffs = cx_right - cx_left`` of the CameraInfo (0 for the usual
  zero-disparity rectification).
* :func:`object_markers`: ``visualization_msgs/MarkerArray``: a DELETEALL, then per object with a distance a
  translucent CUBE (the detector's box back-projected at the object's distance; its depth extent twice the
  object's spread, at least 0.2 m and at most its width) and a TEXT_VIEW_FACING label ("car 12.4 m") above it, in the
  left rectified camera's optical frame (x right, y down, z forward).
* :func:`json_string`: a ``std_msgs/String`` holding JSON (the frame's record, a guide event).
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

__all__ = ["DEFAULT_FRAME_ID", "disparity_image", "header", "json_string", "object_markers", "fill"]

#: The frame id of results whose input carried none (image files, datasets, videos).
DEFAULT_FRAME_ID = "stereo_left_optical_frame"
_COLOURS = [(0.12, 0.47, 0.71), (1.0, 0.5, 0.05), (0.17, 0.63, 0.17), (0.84, 0.15, 0.16), (0.58, 0.4, 0.74),
            (0.55, 0.34, 0.29), (0.89, 0.47, 0.76), (0.5, 0.5, 0.5), (0.74, 0.74, 0.13), (0.09, 0.75, 0.81)]


def header(stamp_ns: int, frame_id: str) -> dict[str, Any]:
    """A ``std_msgs/Header``.

    >>> header(1_500_000_001, "cam")
    {'stamp': {'sec': 1, 'nanosec': 500000001}, 'frame_id': 'cam'}
    """
    return {"stamp": {"sec": int(stamp_ns // 1_000_000_000), "nanosec": int(stamp_ns % 1_000_000_000)},
            "frame_id": frame_id}


def disparity_image(disparity: np.ndarray, rig: Any, params: Any, hdr: dict[str, Any]) -> dict[str, Any]:
    """``stereo_msgs/DisparityImage`` of ``disparity`` ((H, W) float32 px, NaN unknown) for ``rig`` and the matcher
    ``params`` (``min_disparity``, ``max_disparity``, ``subpixel``)."""
    d = np.asarray(disparity, dtype=np.float32)
    lo = float(params.min_disparity)
    out = np.where(np.isfinite(d), d, np.float32(lo - 1.0)).astype("<f4")
    h, w = out.shape
    return {"header": hdr,
            "image": {"header": hdr, "height": h, "width": w, "encoding": "32FC1", "is_bigendian": 0,
                      "step": 4 * w, "data": out.tobytes()},
            "f": float(rig.focal_px), "t": float(rig.baseline_m),
            "valid_window": {"x_offset": 0, "y_offset": 0, "height": h, "width": w, "do_rectify": False},
            "min_disparity": lo, "max_disparity": float(params.max_disparity),
            "delta_d": 1.0 / 16.0 if getattr(params, "subpixel", True) else 1.0}


def object_markers(objects: Any, rig: Any, hdr: dict[str, Any]) -> dict[str, Any]:
    """``visualization_msgs/MarkerArray`` of ``objects`` (:class:`~stereo_classic.fusion.LocalizedObjects`, boxes in
    the pixels of ``rig``'s images)."""
    markers: list[dict[str, Any]] = [{"header": hdr, "ns": "objects", "id": 0, "action": 3}]  # DELETEALL
    for i in range(len(objects)):
        z = float(objects.distance_m[i])
        if not math.isfinite(z) or z <= 0:
            continue
        x1, y1, x2, y2 = (float(v) for v in objects.xyxy[i])
        f = rig.focal_px
        cx, cy = ((x1 + x2) / 2 - rig.cx_left) * z / f, ((y1 + y2) / 2 - rig.cy) * z / f
        width, height = max((x2 - x1) * z / f, 0.01), max((y2 - y1) * z / f, 0.01)
        spread = float(objects.spread_m[i]) if math.isfinite(float(objects.spread_m[i])) else 0.0
        depth = min(max(2 * spread, 0.2), max(width, 0.2))
        r, g, b = _COLOURS[int(objects.class_id[i]) % len(_COLOURS)]
        label = f"{objects.labels[i]} {z:.1f} m"
        pose = {"position": {"x": cx, "y": cy, "z": z + depth / 2}, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0,
                                                                                       "w": 1.0}}
        markers.append({"header": hdr, "ns": "objects", "id": i, "type": 1, "action": 0, "pose": pose,
                        "scale": {"x": width, "y": height, "z": depth},
                        "color": {"r": r, "g": g, "b": b, "a": 0.4}, "text": label})
        top = {"position": {"x": cx, "y": cy - height / 2 - 0.1 * height - 0.1, "z": z},
               "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}
        markers.append({"header": hdr, "ns": "labels", "id": i, "type": 9, "action": 0, "pose": top,
                        "scale": {"x": 0.0, "y": 0.0, "z": max(0.3, 0.15 * height)},
                        "color": {"r": 1.0, "g": 1.0, "b": 1.0, "a": 1.0}, "text": label})
    return {"markers": markers}


def json_string(value: Any) -> dict[str, Any]:
    """``std_msgs/String`` with ``value`` as compact JSON (no NaN: None where unknown)."""
    return {"data": json.dumps(value, allow_nan=False, separators=(",", ":"))}


def fill(msg: Any, values: dict[str, Any]) -> Any:
    """Set the fields of an ``rclpy`` message ``msg`` from a dict of this module (nested dicts and lists of dicts
    become nested messages; ``bytes`` fill a ``uint8[]`` field). Returns ``msg``."""
    for key, value in values.items():
        current = getattr(msg, key)
        if isinstance(value, dict):
            fill(current, value)
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            kind = type(msg).get_fields_and_field_types()[key]
            item_type = _message_class(kind)
            setattr(msg, key, [fill(item_type(), v) for v in value])
        else:
            setattr(msg, key, value)
    return msg


def _message_class(kind: str) -> Any:
    """The class of ``sequence<pkg/Type>`` (rclpy's field type text)."""
    import importlib

    inner = kind[kind.index("<") + 1: kind.rindex(">")] if "<" in kind else kind
    package, name = inner.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)
