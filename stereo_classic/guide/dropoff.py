"""Drop-offs: where the ground ahead falls away by more than a step (stairs down, a kerb, a platform edge).

Along a strip (the walking corridor, or the corridor turned to another bearing) the points at ground level
(within half a step of the plane) and the points clearly below it (lower than ``step_height``) are counted in
10 cm bins of forward distance. A drop-off is where the points below the ground begin, across at least half the
strip's width (a gap under a bed is not a drop-off), while the ground before it was seen: its edge is the far end of the ground seen before the lower surface. A lower surface at ``drop`` metres
below a camera ``h`` metres up is hidden behind the edge up to ``edge * (h + drop) / h``; when no ground is seen
before it (the edge right at the feet, or outside the view), that relation gives the edge instead. Ground that
just ends without a lower surface in view is not reported: stereo also loses texture-less floors, and a
warning there would be an invented distance.

>>> import numpy as np
>>> from stereo_classic.guide import GuideParams
>>> lat, f = (a.ravel() for a in np.meshgrid(np.linspace(-1, 1, 21), np.linspace(1.0, 6.0, 200)))
>>> h = np.where(f < 3.0, 0.0, -0.4)                                        # 40 cm down at 3 m
>>> seen = (f < 3.0) | (f > 3.0 * (1.2 + 0.4) / 1.2)                          # hidden behind the edge
>>> pts = np.column_stack([lat, f, h])[seen]
>>> drop = find_dropoff(pts, np.full(len(pts), 0.01), GuideParams(), camera_height=1.2)
>>> round(drop.distance_m, 1), round(drop.drop_m, 2)
(3.0, 0.4)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stereo_classic.guide._stats import median, percentile
from stereo_classic.guide.obstacles import clock_of
from stereo_classic.guide.params import GuideParams

__all__ = ["BIN_M", "MIN_DROP_AREA", "DropOff", "find_dropoff"]

#: Length of a forward bin, metres.
BIN_M = 0.1
_MIN_AREA = 0.003
#: Surface (square metres, as seen from the camera) of a lower surface over half a metre: a few stray depths
#: below the ground are not a drop-off.
MIN_DROP_AREA = 0.03


@dataclass(frozen=True)
class DropOff:
    """A drop-off ahead.

    Attributes
    ----------
    distance_m : float, metres along the strip to the edge
    bearing_deg : float, degrees, bearing of the strip (0 ahead, positive right)
    lateral_m, forward_m : float, metres, the edge's centre in the ground frame
    drop_m : float, metres, how far the lower surface lies below the ground (median)
    edge_seen : bool
        Whether the ground was seen in front of the edge (in the half metre before it the ground outweighs
        the lower surface). False: the edge lies nearer than the ground the camera sees (or outside the view)
        and ``distance_m`` is where the nearest ray to the lower surface crosses the ground, an upper bound.
    predicted : bool
        False: seen in this frame. True: not seen in this frame but tracked (the edge has left the view nearer
        than the ground the camera sees, or one frame missed it): where its track puts it now, from its last
        positions and their speed (``Guide``, :data:`~stereo_classic.guide.tracking.DROP_HOLD_S`).
    """

    distance_m: float
    bearing_deg: float
    lateral_m: float
    forward_m: float
    drop_m: float
    edge_seen: bool = True
    predicted: bool = False

    @property
    def clock(self) -> int:
        return clock_of(self.bearing_deg)


#: Width of the directions (azimuth, degrees) in which a lower surface is compared with the ground before it:
#: a few sample columns, narrow enough that an edge seen at an angle is at one distance within one.
SLICE_DEG = 2.0


def _beyond_the_ground(ground_points: np.ndarray, seen: np.ndarray, lower: np.ndarray, camera_height: float) -> bool:
    """Whether the ``lower`` points are seen beyond the ``seen`` ground, as over an edge.

    The ray to a point ``d`` under the ground at horizontal range ``r`` crosses the ground's plane at
    ``r h / (h + d)``: a property of its pixel (depth noise moves the point along its ray). Over an edge the
    lower surface shows only past the farthest ground in its direction (every such crossing lies beyond it);
    a lower surface seen under ground of the same direction (nearer the feet in the image) is the floor in
    front of a raised surface (a bed, a crib, a bench taken for the ground), or the plane is wrong. False when
    more of the lower points with ground seen in their direction (2-degree slices of azimuth) are under it than
    beyond it; True when none has (the edge is then nearer than the view, or outside it).
    """
    lat, fwd, hgt = ground_points[:, 0], ground_points[:, 1], ground_points[:, 2]
    rng = np.hypot(lat, fwd)
    crossing = rng * camera_height / np.maximum(camera_height - hgt, 1e-6)
    direction = np.floor(np.degrees(np.arctan2(lat, fwd)) / SLICE_DEG).astype(np.int64)
    if not seen.any() or not lower.any():
        return True
    lo = int(min(direction[seen].min(), direction[lower].min()))
    farthest = np.full(int(max(direction[seen].max(), direction[lower].max())) - lo + 1, -np.inf)
    np.maximum.at(farthest, direction[seen] - lo, crossing[seen])
    ground_there = farthest[direction[lower] - lo]
    judged = np.isfinite(ground_there)
    under = int((crossing[lower][judged] < ground_there[judged]).sum())
    return under <= int(judged.sum()) - under


def find_dropoff(ground_points: np.ndarray, area: np.ndarray, params: GuideParams, *, camera_height: float,
                 bearing_deg: float = 0.0) -> DropOff | None:
    """The nearest drop-off along the strip at ``bearing_deg``, within ``params.look_ahead``, or None.

    Parameters
    ----------
    ground_points : (N, 3) float64, lateral, forward, height above the ground (metres)
    area : (N,) float64, square metres each point stands for
    params : GuideParams
        ``corridor_width`` (strip width), ``step_height``, ``look_ahead``.
    camera_height : float, metres (for the hidden part behind an edge)
    """
    b = math.radians(bearing_deg)
    lat, fwd, hgt = ground_points[:, 0], ground_points[:, 1], ground_points[:, 2]
    along = lat * math.sin(b) + fwd * math.cos(b)
    across = lat * math.cos(b) - fwd * math.sin(b)
    step = params.step_height
    reach = params.look_ahead * (camera_height + 2.0) / camera_height     # lower floors are seen further away
    strip = (np.abs(across) < params.corridor_width / 2) & (along > 0) & (along < reach)
    below = strip & (hgt < -step) & (hgt > -5.0)
    if area[below].sum() < MIN_DROP_AREA:
        return None
    level = strip & (np.abs(hgt) < step / 2)
    nbins = math.ceil(reach / BIN_M)
    below_area = np.bincount((along[below] / BIN_M).astype(np.int64), weights=area[below], minlength=nbins)[:nbins]
    level_area = np.bincount((along[level] / BIN_M).astype(np.int64), weights=area[level], minlength=nbins)[:nbins]
    # The lower surface starts at the first bin from which points below outweigh ground for half a metre.
    win = max(1, round(0.5 / BIN_M))
    kernel = np.ones(win)
    below_run = np.convolve(below_area, kernel)[win - 1:win - 1 + nbins]
    level_run = np.convolve(level_area, kernel)[win - 1:win - 1 + nbins]
    start = np.nonzero((below_area >= _MIN_AREA / 3) & (below_run >= MIN_DROP_AREA) & (below_run > 2 * level_run))[0]
    # ... and spreads across half the strip at least: a gap under a bed or a dark hole is not a drop-off.
    first = None
    across_below, along_below = across[below], along[below]
    for s in start[:30]:
        band = (along_below >= s * BIN_M) & (along_below < s * BIN_M + 0.5)
        if band.sum() >= 3 and np.ptp(percentile(across_below[band], [5, 95])) >= 0.5 * params.corridor_width:
            first = int(s)
            break
    if first is None:
        return None
    lower_near = along[below] >= first * BIN_M
    drop = float(-median(hgt[below][lower_near]))
    seen = level & (along < (first + 1) * BIN_M)
    window = (along >= first * BIN_M) & (along < first * BIN_M + 0.5)     # where the lower surface outweighs
    if not _beyond_the_ground(ground_points, level & (along < first * BIN_M + 0.5), below & window, camera_height):
        return None
    if area[seen].sum() >= _MIN_AREA:
        edge = float(percentile(along[seen], 99))
    else:
        edge = float(percentile(along[below][lower_near], 1)) * camera_height / (camera_height + drop)
    before = slice(max(0, math.floor(edge / BIN_M) - win), max(0, math.floor(edge / BIN_M)))
    edge_seen = bool(level_area[before].sum() > below_area[before].sum())
    if edge > params.look_ahead:
        return None
    pick = below & (np.abs(along - along[below][lower_near].min()) < 0.5)
    offset = float(median(across[pick])) if pick.any() else 0.0
    lat_c = edge * math.sin(b) + offset * math.cos(b)
    fwd_c = edge * math.cos(b) - offset * math.sin(b)
    return DropOff(distance_m=edge, bearing_deg=float(bearing_deg), lateral_m=lat_c, forward_m=fwd_c, drop_m=drop,
                   edge_seen=edge_seen)
