"""Obstacles without a class and the free distance along each direction, from ground-frame points.

Input: points in ground coordinates (lateral m, right positive; forward m; height above the ground m; see
:meth:`stereo_classic.guide.ground.GroundPlane.to_ground`) with the surface area each stands for. A point
between ``min_height`` and ``head_height`` above the ground and within ``look_ahead`` is an obstacle point. They
are binned into a top-down grid of 10 cm cells; a cell is occupied when its points cover at least
:data:`MIN_AREA` square metres (so a distant obstacle, seen by fewer pixels, counts the same as a near one, and
a few stray depths do not), and occupied cells at most one empty cell apart form one obstacle. Obstacles reaching into the
walking corridor (``corridor_width`` wide, straight ahead) are reported, nearest first.

>>> import numpy as np
>>> from stereo_classic.guide import GuideParams
>>> lat, fwd = np.meshgrid(np.linspace(-0.2, 0.2, 20), [3.0])              # a 40 cm wide face 3 m ahead
>>> pts = np.column_stack([lat.ravel(), fwd.ravel(), np.full(lat.size, 0.5)])
>>> obs, grid = find_obstacles(pts, np.full(len(pts), 0.001), GuideParams())
>>> len(obs), round(obs[0].nearest_m, 2), obs[0].clock
(1, 3.0, 12)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from stereo_classic.guide._stats import percentile
from stereo_classic.guide.params import GuideParams

__all__ = ["CELL_M", "MIN_AREA", "Obstacle", "OccupancyGrid", "clock_of", "find_obstacles", "free_distances"]

#: Side of a grid cell, metres.
CELL_M = 0.1
#: Surface (square metres) of obstacle points that makes a cell occupied.
MIN_AREA = 0.004


def clock_of(bearing_deg: float) -> int:
    """Clock hour (1..12) of a bearing in degrees (0 = straight ahead = 12, positive = right).

    >>> clock_of(0.0), clock_of(31.0), clock_of(-44.0), clock_of(-46.0)
    (12, 1, 11, 10)
    """
    hour = round(float(bearing_deg) / 30.0) % 12
    return 12 if hour == 0 else int(hour)


@dataclass(frozen=True)
class Obstacle:
    """One cluster of obstacle points.

    Attributes
    ----------
    lateral_m, forward_m : float, metres, centroid of its points inside the corridor (ground frame)
    nearest_m : float, metres, horizontal distance to its nearest part inside the corridor
    bearing_deg : float, degrees, direction of the centroid (0 ahead, positive right)
    width_m, depth_m : float, metres, extent across and along the walking direction (whole cluster)
    top_m : float, metres, height of its highest point above the ground
    bottom_m : float, metres, height of its lowest point above the ground (a bar at head height is high here)
    area_m2 : float, square metres of surface seen
    """

    lateral_m: float
    forward_m: float
    nearest_m: float
    bearing_deg: float
    width_m: float
    depth_m: float
    top_m: float
    bottom_m: float
    area_m2: float

    @property
    def distance_m(self) -> float:
        """Horizontal distance of the centroid, metres."""
        return math.hypot(self.lateral_m, self.forward_m)

    @property
    def clock(self) -> int:
        return clock_of(self.bearing_deg)


@dataclass(frozen=True, eq=False)
class OccupancyGrid:
    """The top-down grid of one frame.

    Attributes
    ----------
    occupied : (rows, cols) bool, row 0 = nearest (forward 0), column 0 = leftmost (lateral ``-extent``)
    labels : (rows, cols) int32, obstacle cluster of each cell (0 = free; clusters not reported keep theirs)
    extent : float, metres, half width of the grid (= look_ahead); forward runs from 0 to look_ahead
    points : (M, 2) float64, lateral and forward of every obstacle point in an occupied cell
    mask : (N,) bool, which of the input points those are
    """

    occupied: np.ndarray
    labels: np.ndarray
    extent: float
    points: np.ndarray
    mask: np.ndarray

    def cells(self) -> np.ndarray:
        """(C, 2) lateral and forward of the near edge's centre of every occupied cell, metres."""
        rows, cols = np.nonzero(self.occupied)
        return np.column_stack([-self.extent + (cols + 0.5) * CELL_M, rows * CELL_M])


def find_obstacles(ground_points: np.ndarray, area: np.ndarray, params: GuideParams
                   ) -> tuple[list[Obstacle], OccupancyGrid]:
    """Obstacles in the corridor, nearest first, and the occupancy grid.

    Parameters
    ----------
    ground_points : (N, 3) float64, lateral, forward, height above the ground (metres)
    area : (N,) float64, square metres of surface each point stands for
    params : GuideParams
        ``min_height``, ``head_height``, ``look_ahead``, ``corridor_width``.
    """
    ext = params.look_ahead
    cols, rows = round(2 * ext / CELL_M), round(ext / CELL_M)
    lat, fwd, hgt = ground_points[:, 0], ground_points[:, 1], ground_points[:, 2]
    sel = ((hgt > params.min_height) & (hgt < params.head_height) & (fwd > 0.0) & (fwd < ext) & (np.abs(lat) < ext))
    lat, fwd, hgt, area = lat[sel], fwd[sel], hgt[sel], area[sel]
    ci = np.clip(((lat + ext) / CELL_M).astype(np.int64), 0, cols - 1)
    ri = np.clip((fwd / CELL_M).astype(np.int64), 0, rows - 1)
    flat = ri * cols + ci
    cover = np.bincount(flat, weights=area, minlength=rows * cols).reshape(rows, cols)
    occupied = cover >= MIN_AREA
    # Cells up to one empty cell apart are one obstacle (a box's front face and its top, seen from above).
    near = cv2.dilate(occupied.astype(np.uint8), np.ones((3, 3), np.uint8))
    count, labels = cv2.connectedComponents(near, connectivity=8)
    labels[~occupied] = 0
    point_label = labels.reshape(-1)[flat]
    keep = point_label > 0
    half = params.corridor_width / 2
    obstacles: list[Obstacle] = []
    if count > 1 and keep.any():
        lab = point_label[keep]
        lt, fw, hg, ar = lat[keep], fwd[keep], hgt[keep], area[keep]
        order = np.argsort(lab, kind="stable")
        lab, lt, fw, hg, ar = lab[order], lt[order], fw[order], hg[order], ar[order]
        starts = np.searchsorted(lab, np.arange(1, count))
        ends = np.searchsorted(lab, np.arange(1, count), side="right")
        for s, e in zip(starts, ends):
            if e - s == 0:
                continue
            inside = np.abs(lt[s:e]) < half
            if not inside.any():
                continue
            li, fi, ai = lt[s:e][inside], fw[s:e][inside], ar[s:e][inside]
            if ai.sum() < MIN_AREA:
                continue
            rng = np.hypot(li, fi)
            near = float(percentile(rng, 2))
            cl, cf = float(np.average(li, weights=ai)), float(np.average(fi, weights=ai))
            obstacles.append(Obstacle(
                lateral_m=cl, forward_m=cf, nearest_m=near, bearing_deg=math.degrees(math.atan2(cl, cf)),
                width_m=float(np.ptp(lt[s:e])) + CELL_M, depth_m=float(np.ptp(fw[s:e])) + CELL_M,
                top_m=float(hg[s:e].max()), bottom_m=float(hg[s:e].min()), area_m2=float(ar[s:e].sum())))
    obstacles.sort(key=lambda o: o.nearest_m)
    mask = np.zeros(len(ground_points), bool)
    mask[np.nonzero(sel)[0][keep]] = True
    grid = OccupancyGrid(occupied=occupied, labels=labels.astype(np.int32), extent=ext,
                         points=np.column_stack([lat[keep], fwd[keep]]), mask=mask)
    return obstacles, grid


def free_distances(points: np.ndarray, bearings_deg: np.ndarray, width: float, limit: float) -> np.ndarray:
    """(K,) metres one can walk along each bearing in a strip ``width`` wide before a point of ``points``
    ((M, 2) lateral, forward: obstacle points, drop-off edges), at most ``limit``.

    >>> free_distances(np.array([[0.0, 2.0]]), np.array([0.0, 45.0]), 1.0, 5.0).tolist()
    [2.0, 5.0]
    """
    b = np.radians(np.asarray(bearings_deg, np.float64))
    if len(points) == 0:
        return np.full(len(b), float(limit))
    sin, cos = np.sin(b)[:, None], np.cos(b)[:, None]
    along = points[:, 0][None, :] * sin + points[:, 1][None, :] * cos       # (K, M)
    across = points[:, 0][None, :] * cos - points[:, 1][None, :] * sin
    blocked = (np.abs(across) < width / 2) & (along > 0)
    dist = np.where(blocked, along, np.inf).min(axis=1)
    return np.minimum(dist, float(limit))
