"""A reference distance per box from sparse depth (projected LiDAR), to judge the fusion against.

Not a localizer: the tests and benchmarks compare :func:`~stereo_classic.fusion.localize` with it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from stereo_classic.fusion.boxes import shrunk_pixel_box
from stereo_classic.fusion.params import FusionInputError

__all__ = ["sparse_depth_reference"]


def sparse_depth_reference(
    sparse_depth: Any,
    xyxy: Any,
    *,
    box_shrink: float = 0.2,
    gap_m: float = 0.3,
    gap_rel: float = 0.03,
    min_points: int = 5,
    min_fraction: float = 0.2,
) -> np.ndarray:
    """Reference distance per box from sparse depth (projected LiDAR): the nearest dense depth cluster.

    This is how the tests and benchmarks judge :func:`localize` against LiDAR, not a localizer itself.

    1. Take the depths ``> 0`` and finite inside the box shrunk exactly as ``localize`` shrinks it.
    2. Sort them and cut between neighbours further apart than ``max(gap_m, gap_rel * Z)``: a real
       surface gives a run of depths without such a gap, a jump to another surface makes one.
    3. A cluster is *dense* when it holds at least ``max(min_points, min_fraction * n)`` of the box's
       ``n`` points (stray points bleeding through the box edge or from an occluder corner are not).
    4. The reference is the **median** depth of the nearest dense cluster (the object is in front of its
       background); the median, because LiDAR points seen past the object's silhouette from the
       LiDAR's own viewpoint (0.27 m behind and 0.08 m above the camera) land inside the box too.

    Parameters
    ----------
    sparse_depth : (H, W) float array
        Depth in metres, 0 or NaN where there is no point (KITTI ``lidar_depth_left.npy``).
    xyxy : (N, 4) array_like
        Boxes in pixels.
    box_shrink : float in [0, 1)
        As ``FusionParams.box_shrink``.
    gap_m, gap_rel : float
        A gap between sorted neighbours wider than ``max(gap_m, gap_rel * Z)`` (metres) cuts a cluster.
    min_points : int
        Fewest points of a dense cluster.
    min_fraction : float
        Fewest points of a dense cluster as a fraction of the box's points.

    Returns
    -------
    (N,) float64
        Reference depth in metres, NaN where the box has no dense cluster.

    Raises
    ------
    FusionInputError (ValueError)
        ``sparse_depth`` not 2-D or ``box_shrink`` outside [0, 1).

    Examples
    --------
    >>> depth = np.zeros((10, 10))
    >>> depth[2:8, 2:8] = 7.5
    >>> sparse_depth_reference(depth, [[0, 0, 10, 10]]).tolist()
    [7.5]
    """
    depth = np.asarray(sparse_depth, dtype=np.float64)
    if depth.ndim != 2:
        raise FusionInputError(f"`sparse_depth` must be an (H, W) array, got shape {depth.shape}")
    boxes = np.asarray(xyxy, dtype=np.float64).reshape(-1, 4)
    if not (0.0 <= float(box_shrink) < 1.0):
        raise FusionInputError(f"`box_shrink` must be in [0, 1), got {box_shrink!r}")
    out = np.full(boxes.shape[0], np.nan)
    h, w = depth.shape
    for i, box in enumerate(boxes):
        u0, v0, u1, v1 = shrunk_pixel_box(box, float(box_shrink), w, h)
        sub = depth[v0:v1, u0:u1]
        z = np.sort(sub[np.isfinite(sub) & (sub > 0)])
        if z.size == 0:
            continue
        cuts = np.flatnonzero(np.diff(z) > np.maximum(gap_m, gap_rel * z[:-1])) + 1
        need = max(min_points, min_fraction * z.size)
        for cluster in np.split(z, cuts):
            if cluster.size >= need:
                out[i] = float(np.median(cluster))
                break
    return out
