"""OAK-D pairs as the ``stereodemo`` project saves them: ``<name>_left.png``, ``<name>_right.png`` and
``stereodemo_calibration.json`` (rectified grey images, no ground truth).

Usage (needs files that are not part of the package)::

    from stereo_classic.datasets import iter_oakd
    [s.name for s in iter_oakd("../shared/data/oakd")][:2]
    # -> ['bottles', 'chair']
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from pathlib import Path

from calib import RectifiedRig, read_oakd_calib
from stereo_classic.datasets.scene import Scene, _folder, _named_pairs, _need, _read_pair

__all__ = ["load_oakd", "iter_oakd"]

_OAKD_JSON = "stereodemo_calibration.json"


def _oakd_max_disparity(json_path: Path, rig: RectifiedRig) -> int | None:
    depth_range = read_oakd_calib(json_path).get("depth_range")  # checked there: 0 < near < far
    if depth_range is None:
        return None
    top = rig.focal_px * rig.baseline_m / depth_range[0] - rig.doffs
    return max(16, int(math.ceil(top / 16.0)) * 16) if top > 0 else None


def load_oakd(folder: str | os.PathLike, name: str) -> Scene:
    """Load one OAK-D pair ``<name>_left.png`` / ``<name>_right.png`` (rectified grey, no ground truth).

    The rig comes from ``stereodemo_calibration.json`` in the same folder
    (:meth:`calib.RectifiedRig.from_oakd_json`); ``max_disparity`` from its ``depth_range`` near limit
    (f B / near, rounded up to 16) when present.
    """
    d = _folder(folder, "OAK-D folder")
    if not isinstance(name, str) or not name:
        raise ValueError(f"`name` must be a non-empty pair name, got {name!r}")
    left, right = _read_pair(_need(d, f"{name}_left", "left image"), _need(d, f"{name}_right", "right image"))
    json_path = d / _OAKD_JSON
    if not json_path.is_file():
        raise FileNotFoundError(f"OAK-D calibration not found: {json_path}")
    rig = RectifiedRig.from_oakd_json(json_path)
    return Scene(name, left, right, None, None, rig, None, _oakd_max_disparity(json_path, rig), None, "oakd", d)


def iter_oakd(folder: str | os.PathLike) -> Iterator[Scene]:
    """Every pair of an OAK-D folder, sorted by name."""
    d = _folder(folder, "OAK-D folder")
    for name in _named_pairs(d):
        yield load_oakd(d, name)

