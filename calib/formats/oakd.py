"""The stereodemo / OAK-D calibration JSON: ``width``, ``height``, ``fx``, ``cx0``, ``cx1``, ``cy``, ``baseline_meters``.

Readers return plain values; ``RectifiedRig.from_oakd_json`` builds the rig.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from calib.errors import CalibrationError
from calib.formats._common import PathLike, read_text

__all__ = ["read_oakd_calib", "read_rectified"]


def read_oakd_calib(path: PathLike) -> dict[str, Any]:
    """The stereodemo/OAK-D JSON object as stored, with ``depth_range`` (when present) checked and returned
    as a ``(near, far)`` tuple of metres (finite, 0 < near < far)."""
    path, text = read_text(path, "OAK-D calibration JSON")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise CalibrationError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise CalibrationError(f"{path}: expected a JSON object at the top level, got {type(data).__name__}")
    if "depth_range" in data:
        dr = data["depth_range"]
        if not (isinstance(dr, list) and len(dr) == 2 and all(
            not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v) for v in dr
        ) and 0 < dr[0] < dr[1]):
            raise CalibrationError(f"{path}: key `depth_range` must be [near, far] in metres with 0 < near < far, got {dr!r}")
        data["depth_range"] = (float(dr[0]), float(dr[1]))
    return data


def read_rectified(path: PathLike) -> dict[str, Any]:
    """The rectified geometry of the stereodemo/OAK-D JSON (``fy`` optional; fx is used).

    Returns
    -------
    dict
        ``focal_px``, ``cx_left``, ``cx_right``, ``cy`` (pixels), ``baseline_m`` (metres), ``image_size``.
    """
    data = read_oakd_calib(path)
    path = Path(path)

    def num(key: str) -> float:
        if key not in data:
            raise CalibrationError(f"{path}: missing key `{key}`")
        value = data[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise CalibrationError(f"{path}: key `{key}` must be a finite number, got {value!r}")
        return float(value)

    width, height = num("width"), num("height")
    if not (width.is_integer() and height.is_integer() and width > 0 and height > 0):
        raise CalibrationError(f"{path}: keys `width`/`height` must be positive integers, got {data['width']!r}/{data['height']!r}")
    return {"focal_px": num("fx"), "cx_left": num("cx0"), "cx_right": num("cx1"), "cy": num("cy"),
            "baseline_m": num("baseline_meters"), "image_size": (int(width), int(height))}
