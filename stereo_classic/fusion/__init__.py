"""Fusion of detections and disparity: one distance and one 3D position per detected object.

Data flow: ``params`` (:class:`FusionParams`, the settings) -> ``localize`` (boxes + disparity + rig ->
depths in each box -> ``ransac`` consistent set -> its median 3D point) -> ``objects`` (:class:`LocalizedObjects`,
the result). ``reference`` judges the result against sparse LiDAR depth.

>>> from types import SimpleNamespace
>>> import numpy as np
>>> from stereo_classic.fusion import FusionParams, localize
>>> rig = SimpleNamespace(focal_px=500.0, baseline_m=0.1, doffs=0.0, cx_left=20.0, cy=15.0, image_size=(40, 30))
>>> objs = localize([[24, 6, 40, 25]], np.full((30, 40), 10.0), rig, FusionParams(box_shrink=0.1))
>>> print(objs.format_table())
label   confidence  distance  x (m)  y (m)  z (m)  direction
object        1.00    5.00 m  +0.11  +0.00   5.00  ahead
"""

from __future__ import annotations

from stereo_classic.fusion.localize import localize
from stereo_classic.fusion.objects import STATUSES, LocalizedObjects, direction_phrase
from stereo_classic.fusion.params import FusionInputError, FusionParams, as_generator
from stereo_classic.fusion.range_hint import RangeWarning
from stereo_classic.fusion.ransac import ransac_1d
from stereo_classic.fusion.reference import sparse_depth_reference

__all__ = [
    "FusionParams",
    "FusionInputError",
    "as_generator",
    "localize",
    "LocalizedObjects",
    "STATUSES",
    "direction_phrase",
    "RangeWarning",
    "ransac_1d",
    "sparse_depth_reference",
]
