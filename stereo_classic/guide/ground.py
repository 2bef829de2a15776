"""The ground under the walker: a plane fitted robustly to the point cloud, kept stable over frames.

Coordinates: the left rectified camera frame (X right, Y down, Z forward, metres). The ground is the plane
``up . p + height = 0`` where ``up`` is the unit vector pointing up (away from the ground) and ``height`` the
camera's height above it; ``up . p + height`` is then any point's height above the ground. A camera that
looks down by ``pitch`` degrees (no roll) has ``up = (0, -cos(pitch), -sin(pitch))``.

:func:`sample_points` back-projects a grid of pixels (every ``stride``-th), :func:`fit_ground` finds the
planes of the lower image one after the other with RANSAC (3-point hypotheses that fit a carried camera: below
it, 0.3-2 m under it, near level; a depth-dependent inlier band, least-squares refits) and takes the lowest large
one that is wide enough to walk on, five times over, and the plane most of those searches agree on, or none
("ground unknown"), and :class:`~stereo_classic.guide.ground_tracker.GroundTracker`
keeps one estimate over frames.

>>> import numpy as np
>>> plane = GroundPlane.from_mounting(1.2, 10.0)
>>> round(plane.pitch_deg, 3), plane.height_m
(10.0, 1.2)
>>> level = GroundPlane.from_mounting(1.2, 0.0)
>>> float(level.heights(np.array([[0.0, 1.2, 3.0]]))[0])  # 1.2 m below the optical axis: on the ground
0.0
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib import RectifiedRig
from calib.geometry import points_from_pixels
from stereo_classic.guide._kernels import inlier_mask, inlier_scatter, score_hypotheses
from stereo_classic.guide._stats import median, percentile
from stereo_classic.guide.gravity import is_level, pitch_of, roll_of
from stereo_classic.guide.params import ESTIMATED_HEIGHT_RANGE

__all__ = ["AGREE_DEG", "AGREE_M", "RESTARTS", "GroundPlane", "PointSample", "agree", "consensus", "fit_ground",
           "sample_points"]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over the last axis (np.cross is slow for small arrays)."""
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1], a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


@dataclass(frozen=True, eq=False)
class PointSample:
    """Back-projected pixels of one frame (only those with a known depth).

    Attributes
    ----------
    uv : (N, 2) float64, pixels (column, row) in the left rectified image
    xyz : (N, 3) float64, metres, camera frame
    stride : int, pixels between samples
    focal_px : float
    textured : (N,) bool or None
        Samples where the left image has texture (None: all). Stereo matchers fill texture-less areas (white
        walls) by propagation, and the ground is fitted to textured samples only.
    """

    uv: np.ndarray
    xyz: np.ndarray
    stride: int
    focal_px: float
    textured: np.ndarray | None = None

    def footprint(self) -> np.ndarray:
        """(N,) float64, square metres of surface each sample stands for (facing the camera)."""
        size = self.xyz[:, 2] * self.stride / self.focal_px
        return size * size


def _texture(image: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Mean absolute horizontal central difference (grey levels) over a 3x3 grid of offsets 2 px apart, at
    pixels ``(u, v)`` (the reference of :func:`_texture_grid`)."""
    grey = image if image.ndim == 2 else image[..., 1]          # green: close enough to grey for a texture test
    h, w = grey.shape[:2]
    ui, vi = u.astype(np.int64), v.astype(np.int64)
    total = np.zeros(len(ui))
    for dv in (-2, 0, 2):
        rows = np.clip(vi + dv, 0, h - 1)
        for du in (-2, 0, 2):
            c = ui + du
            total += np.abs(grey[rows, np.clip(c + 1, 0, w - 1)].astype(np.float64)
                            - grey[rows, np.clip(c - 1, 0, w - 1)])
    return total / 9.0


def _texture_grid(image: np.ndarray, off: int, stride: int, shape: tuple[int, int]) -> np.ndarray:
    """:func:`_texture` at every pixel ``(off + i stride, off + j stride)`` of a ``shape`` grid: the same
    numbers, from the three rows and six columns around each grid pixel only (gathered once per offset)."""
    grey = image if image.ndim == 2 else image[..., 1]
    h, w = grey.shape[:2]
    gh, gw = shape
    rows = off + stride * np.arange(gh)
    cols = off + stride * np.arange(gw)
    c = (cols[None, :] + np.array([-2, 0, 2])[:, None]).ravel()             # the three column offsets at once
    plus, minus = np.clip(c + 1, 0, w - 1), np.clip(c - 1, 0, w - 1)
    total = np.zeros((gh, 3 * gw), np.int32)
    for dv in (-2, 0, 2):
        sub = grey[np.clip(rows + dv, 0, h - 1)].astype(np.int16)
        total += np.abs(sub[:, plus] - sub[:, minus])
    return total.reshape(gh, 3, gw).sum(axis=1) / 9.0


def sample_points(disparity: np.ndarray, rig: RectifiedRig, *, stride: int = 4, max_depth: float = 30.0,
                  image: np.ndarray | None = None, min_texture: float = 5.0) -> PointSample:
    """Every ``stride``-th pixel of ``disparity`` ((H, W) float32, px, NaN unknown) back-projected with ``rig``;
    depths beyond ``max_depth`` metres or not positive are dropped. With the left ``image`` ((H, W) or (H, W, 3)
    uint8), samples whose neighbourhood changes by less than ``min_texture`` grey levels between neighbouring
    columns are marked not ``textured``."""
    h, w = disparity.shape
    if (w, h) != tuple(int(v) for v in rig.image_size):
        raise ValueError(f"`disparity` is {w}x{h} but the rig's images are {rig.image_size[0]}x{rig.image_size[1]}")
    off = stride // 2
    vs, us = np.mgrid[off:h:stride, off:w:stride]
    d = disparity[off::stride, off::stride]
    keep = np.isfinite(d)
    u, v, d = us[keep].astype(np.float64), vs[keep].astype(np.float64), d[keep]
    xyz = points_from_pixels(u, v, d, rig)
    ok = np.isfinite(xyz[:, 2]) & (xyz[:, 2] > 0) & (xyz[:, 2] <= max_depth)
    u, v = u[ok], v[ok]
    textured = None
    if image is not None and image.shape[:2] == disparity.shape:
        textured = (_texture_grid(image, off, stride, keep.shape)[keep] >= min_texture)[ok]
    return PointSample(uv=np.column_stack([u, v]), xyz=xyz[ok], stride=stride, focal_px=float(rig.focal_px),
                       textured=textured)


@dataclass(frozen=True, eq=False)
class GroundPlane:
    """A ground plane in the camera frame.

    Attributes
    ----------
    up : (3,) float64, unit vector pointing up, camera frame
    height_m : float, camera height above the plane, metres
    source : str
        "given" (from ``camera_height`` and ``camera_pitch``), "fitted" or "kept" (last frame's plane).
    inliers : int, points that supported the fit (0 when given or kept)
    """

    up: np.ndarray
    height_m: float
    source: str = "fitted"
    inliers: int = 0

    def __post_init__(self) -> None:
        up = np.asarray(self.up, np.float64).reshape(3)
        norm = float(np.linalg.norm(up))
        if not (math.isfinite(norm) and norm > 0 and math.isfinite(self.height_m)):
            raise ValueError(f"GroundPlane: `up` must be a finite non-zero vector and `height_m` finite, got "
                             f"{self.up!r}, {self.height_m!r}")
        object.__setattr__(self, "up", up / norm)

    @classmethod
    def from_mounting(cls, height_m: float, pitch_deg: float, source: str = "given") -> GroundPlane:
        """The plane under a camera ``height_m`` metres up, looking down by ``pitch_deg`` degrees, no roll."""
        t = math.radians(pitch_deg)
        return cls(np.array([0.0, -math.cos(t), -math.sin(t)]), float(height_m), source)

    @property
    def pitch_deg(self) -> float:
        """Downward tilt of the optical axis, degrees."""
        return float(pitch_of(self.up))

    @property
    def roll_deg(self) -> float:
        """Sideways tilt, degrees (positive: the right side of the image is lower)."""
        return float(roll_of(self.up))

    def heights(self, xyz: np.ndarray) -> np.ndarray:
        """(N,) height of each point above the ground, metres."""
        return xyz @ self.up + self.height_m

    def axes(self) -> tuple[np.ndarray, np.ndarray]:
        """(right, forward): horizontal unit vectors in the camera frame (right follows the image's X)."""
        ex = np.array([1.0, 0.0, 0.0])
        right = ex - (ex @ self.up) * self.up
        right /= np.linalg.norm(right)
        return right, _cross(self.up, right)

    def to_ground(self, xyz: np.ndarray) -> np.ndarray:
        """(N, 3): lateral (m, right positive), forward (m), height above the ground (m) of each point."""
        right, forward = self.axes()
        return np.column_stack([xyz @ right, xyz @ forward, self.heights(xyz)])

    def to_camera(self, lateral: np.ndarray, forward: np.ndarray, height: np.ndarray | float = 0.0) -> np.ndarray:
        """(N, 3) camera-frame points of ground coordinates (the inverse of :meth:`to_ground`)."""
        right, fwd = self.axes()
        lateral, forward = np.asarray(lateral, np.float64), np.asarray(forward, np.float64)
        h = np.broadcast_to(np.asarray(height, np.float64), lateral.shape)
        return (lateral[:, None] * right + forward[:, None] * fwd + (h - self.height_m)[:, None] * self.up)

    def to_dict(self) -> dict[str, float | str]:
        return {"height_m": round(self.height_m, 3), "pitch_deg": round(self.pitch_deg, 2),
                "roll_deg": round(self.roll_deg, 2), "source": self.source}


def _band(z: np.ndarray, focal_baseline: float) -> np.ndarray:
    """Inlier half-width in metres: 3 cm plus the depth error of a quarter pixel of disparity, at most 10 cm."""
    return np.minimum(0.03 + 0.25 * z * z / focal_baseline, 0.10)


@dataclass(frozen=True, eq=False)
class _Surface:
    """A distinct plane among one frame's RANSAC hypotheses, refitted (see :func:`fit_ground`)."""

    up: np.ndarray
    height_m: float
    support: int          # candidate points within the inlier band (of those the fit works on)
    below: int            # candidate points clearly below it, nearer than its own points
    reason: str           # "" when it may be the ground, else why not
    points: np.ndarray    # (support, 3) its inliers, metres, camera frame
    band: np.ndarray      # (support,) their inlier half-widths, metres

    @property
    def score(self) -> int:
        return self.support - self.below

    def under(self, other: _Surface) -> bool:
        """Whether this surface lies below ``other``: most of its points are more than three inlier bands
        under ``other``'s plane (a tilted copy of the same floor straddles it instead)."""
        return bool(median(self.points @ other.up + other.height_m + 3 * self.band) < 0)


#: Candidate points a fit works on (every k-th of them beyond): the plane of 1200 points is as good as that of
#: 3000 for a ground seen over metres, and the cost of the hypotheses grows with the points.
MAX_POINTS = 1200


def _refit(cand: np.ndarray, band: np.ndarray, up: np.ndarray, h: float, ref: np.ndarray, rounds: int = 6
           ) -> tuple[np.ndarray, float, np.ndarray]:
    """Least-squares plane of the points within ``band`` of ``up . p + h = 0``, repeated on the new plane's
    inliers until it moves by less than 0.2 degrees and 5 mm (at most ``rounds`` times): a floor seen over a
    short span of depth leaves its pitch loosely pinned, and one refit from a hypothesis tilted by a few
    degrees stays tilted. Returns ``up`` (oriented like ``ref``), ``h`` and the inlier mask."""
    inl = np.empty(len(cand), np.bool_)
    n_in = inlier_mask(cand, band, up, h, inl)
    for _ in range(rounds):
        if n_in < 3:
            break
        centre, scatter = inlier_scatter(cand, inl)
        normal = np.linalg.eigh(scatter)[1][:, 0]              # the direction of least spread (3x3: cheap)
        new_up = normal if normal @ ref > 0 else -normal
        new_h = float(-(new_up @ centre))
        settled = float(new_up @ up) > _SETTLED_COS and abs(new_h - h) < 0.005
        up, h = new_up, new_h
        n_in = inlier_mask(cand, band, up, h, inl)
        if settled:
            break
    return up, h, inl


_SETTLED_COS = math.cos(math.radians(0.2))


def _refit_offset(cand: np.ndarray, band: np.ndarray, up: np.ndarray, h: float, rounds: int = 6
                  ) -> tuple[np.ndarray, float, np.ndarray]:
    """:func:`_refit` with ``up`` fixed (a given pitch): only the offset moves, to the mean of its inliers'."""
    inl = np.empty(len(cand), np.bool_)
    n_in = inlier_mask(cand, band, up, h, inl)
    for _ in range(rounds):
        if n_in < 1:
            break
        new_h = float(-(inlier_scatter(cand, inl)[0] @ up))
        settled = abs(new_h - h) < 0.005
        h = new_h
        n_in = inlier_mask(cand, band, up, h, inl)
        if settled:
            break
    return up, h, inl


#: Spacing of the offsets tried for a ground whose ``up`` is known (metres): finer than any inlier band (3 cm).
OFFSET_STEP_M = 0.01


def _level_hypotheses(pts: np.ndarray, up: np.ndarray, height_range: tuple[float, float]
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Planes with the known ``up`` at every offset (``OFFSET_STEP_M`` apart, within ``height_range``) where
    one of ``pts`` lies: every candidate plane, none drawn by chance. ``(K, 3)`` and ``(K,)`` as
    :func:`_hypotheses`."""
    offsets = -(pts @ up)
    offsets = offsets[(offsets >= height_range[0]) & (offsets <= height_range[1])]
    offsets = np.unique(np.round(offsets / OFFSET_STEP_M)) * OFFSET_STEP_M
    return np.tile(up, (len(offsets), 1)), offsets


def _hypotheses(pts: np.ndarray, gen: np.random.Generator, iterations: int, ref: np.ndarray, limit: float,
                max_roll_deg: float, height_range: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """3-point planes of ``pts`` that fit the prior: within ``limit`` radians of ``ref``, the roll and look-up
    limits, the camera above them by a height in ``height_range``: ``(K, 3)`` unit ``up`` vectors and ``(K,)``
    offsets ``h`` (``up . p + h = 0``)."""
    triples = gen.integers(0, len(pts), size=(iterations, 3))
    a, b, c = pts[triples[:, 0]], pts[triples[:, 1]], pts[triples[:, 2]]
    normals = _cross(b - a, c - a)
    norms = np.linalg.norm(normals, axis=1)
    good = norms > 1e-9
    normals[good] /= norms[good, None]
    normals *= np.where(normals @ ref < 0, -1.0, 1.0)[:, None]          # orient towards the reference up
    good &= (normals @ ref > math.cos(limit)) & (np.abs(normals[:, 0]) < math.sin(math.radians(max_roll_deg)))
    good &= -normals[:, 2] > math.sin(math.radians(-5.0))     # a walker's camera does not look up at the floor
    offsets = -np.einsum("ij,ij->i", normals, a)
    good &= (offsets >= height_range[0]) & (offsets <= height_range[1])  # the camera above its ground
    return normals[good], offsets[good]


class _Search:
    """The candidate points of one frame's ground search and the prior they are searched with."""

    def __init__(self, cand: np.ndarray, focal_baseline: float, ref: np.ndarray, limit: float, max_roll_deg: float,
                 iterations: int, rng: int, height_range: tuple[float, float], min_width: float,
                 fixed_up: bool = False, gravity: np.ndarray | None = None) -> None:
        self.gen = np.random.default_rng(rng)
        self.fixed_up = fixed_up                                   # ``ref`` is the ground's up: search offsets
        self.gravity = gravity                                     # the up measured in the image, or None
        every = -(-len(cand) // MAX_POINTS)
        self.cand = cand[::every]                                  # every k-th: at most MAX_POINTS (the cost)
        self.min_support = max(30 / every, 0.15 * len(self.cand))  # 30 of all the candidates, and 15 %
        self.band = _band(self.cand[:, 2], focal_baseline)
        self.ref, self.limit, self.max_roll_deg = ref, limit, max_roll_deg
        self.iterations, self.height_range, self.min_width = iterations, height_range, min_width

    def surface(self, mask: np.ndarray) -> tuple[_Surface | None, np.ndarray]:
        """One RANSAC round on the points of ``mask``: the best plane, refitted on all the candidates and
        checked (None: no hypothesis), and the points it explains (to leave out of the next round)."""
        cand, band = self.cand, self.band
        explained = np.zeros(len(cand), bool)
        rest = np.nonzero(mask)[0]
        if len(rest) < 3:                # fewer may still make a plane whose inliers (all of them) are enough
            return None, explained
        if self.fixed_up:
            normals, offsets = _level_hypotheses(cand[rest], self.ref, self.height_range)
        else:
            normals, offsets = _hypotheses(cand[rest], self.gen, self.iterations, self.ref, self.limit,
                                           self.max_roll_deg, self.height_range)
        if not len(normals):
            return None, explained
        # Score: the points of ``mask`` within a plane's band, less those below it. Nothing lies under the
        # ground (but a drop-off): points below a plane count against it, so a table top or a bed, with the
        # floor under it, loses to the floor. Only those nearer than the plane's own points (their mean depth):
        # beyond a floor's far edge a drop-off may lie below it.
        k = score_hypotheses(cand, band, mask, normals, offsets)
        if self.fixed_up:
            up, h, inl = _refit_offset(cand, band, self.ref, float(offsets[k]))
        else:
            up, h, inl = _refit(cand, band, normals[k], float(offsets[k]), self.ref)
        hyp = np.empty(len(cand), np.bool_)
        inlier_mask(cand, band, normals[k], float(offsets[k]), hyp)
        explained = inl | hyp
        return self._checked(up, h, inl), explained

    def _checked(self, up: np.ndarray, h: float, inl: np.ndarray) -> _Surface:
        cand, band = self.cand, self.band
        n_in = int(inl.sum())
        reach = float(cand[inl, 2].mean()) if n_in else 0.0
        n_below = int((((cand @ up + h) < -3 * band) & (cand[:, 2] < reach)).sum())
        plane = GroundPlane(up, h) if math.isfinite(h) else None
        reason = ""
        if n_in < self.min_support:
            reason = "too small"
        elif plane is None or not self.height_range[0] <= h <= self.height_range[1]:
            reason = "height"
        elif not self.fixed_up and (up @ self.ref < math.cos(self.limit) or abs(plane.roll_deg) > self.max_roll_deg
                                    or plane.pitch_deg < -5.0):
            reason = "tilt"
        elif self.gravity is not None and not is_level(up, self.gravity):
            reason = "not level"
        elif n_below > 0.5 * n_in:
            reason = "points below it"
        else:
            lateral = plane.to_ground(cand[inl])[:, 0]
            lo, hi = percentile(lateral, [5, 95])
            if hi - lo < self.min_width:
                reason = "too narrow"
        return _Surface(up, h, n_in, n_below, reason, cand[inl], band[inl])

    def surfaces(self, rounds: int = 3) -> list[_Surface]:
        """The distinct planes, found one after the other (sequential RANSAC: each round samples the points
        no plane found so far explains, so a floor holding fewer points than the table above it is found)."""
        remaining = np.ones(len(self.cand), bool)
        out: list[_Surface] = []
        for _ in range(rounds):
            if remaining.sum() < self.min_support:
                break
            s, explained = self.surface(remaining)
            if s is None:
                break
            remaining &= ~explained
            if not any(float(s.up @ o.up) > math.cos(math.radians(5.0)) and abs(s.height_m - o.height_m) < 0.1
                       for o in out):                                     # not refitted onto one already kept
                out.append(s)
        return out

    def under(self, ground: _Surface) -> np.ndarray:
        """(N,) bool: the candidates more than three inlier bands under ``ground``'s plane."""
        return self.cand @ ground.up + ground.height_m < -3 * self.band


#: Independent searches of one frame's ground without a prior (``fit_ground``'s ``restarts``).
RESTARTS = 5


def fit_ground(points: PointSample, focal_baseline: float, *, prior: GroundPlane | None = None,
               max_tilt_deg: float = 35.0, max_roll_deg: float = 15.0, iterations: int = 64, rng: int = 0,
               height_range: tuple[float, float] = ESTIMATED_HEIGHT_RANGE, min_width: float = 1.0,
               up: np.ndarray | None = None, restarts: int = RESTARTS, gravity: np.ndarray | None = None
               ) -> GroundPlane | None:
    """The ground plane of one frame, or None when the points show none that fits a carried camera.

    Parameters
    ----------
    points : PointSample
    focal_baseline : float, px * m (``f B`` of the rig: the depth error grows as ``Z**2 / (f B)``)
    prior : GroundPlane, optional
        The expected plane: hypotheses must be within ``max_tilt_deg / 2`` of its ``up`` and only points
        within 0.3 m of it are used. Without one, ``up`` must be within ``max_tilt_deg`` of straight up
        ((0, -1, 0)) and only the points below the camera in the lower half of the image are used. Only the
        ``textured`` points take part when the sample says which they are.
    max_roll_deg : float, the largest sideways tilt of a ground
    iterations : int, RANSAC hypotheses per round; ``rng`` seeds them (deterministic).
    height_range : (float, float), metres
        Camera heights above a ground that a carried or worn camera can have
        (:data:`ESTIMATED_HEIGHT_RANGE`); hypotheses giving another are not tried.
    min_width : float, metres
        The ground's points must span this much across (5th to 95th percentile): a walking corridor fits on
        it (a desk top beside a person, a stair tread seen end-on do not make a ground).
    up : (3,) array, optional
        The ground's up vector when it is known (a given camera pitch, an IMU's gravity): only the offset is
        searched, at every offset 1 cm apart where a candidate lies (no random draw; ``iterations`` and
        ``rng`` are unused), and the tilt, roll and look-up limits do not apply. Without it a plane tilted
        against the true one would be fitted and only its normal replaced: the stairs seen from their top
        make a plane along the nosings, and that plane's height under the camera is not the landing's.
    restarts : int
        Independent searches (each with its own draws from ``rng``); the ground is what more than half of them
        agree on (:func:`consensus`), else None. They run one after the other until a majority agrees or none
        can any more (a floor seen well: three). One search's answer depends on its draw where several
        surfaces compete (a corridor showing a strip of floor beside a stairwell: 0.47 to 1.83 m over eight
        seeds; 5 searches: 1.32 to 1.45 m for 5 of the seeds, unknown for 3, ``python -m benchmarks.guide_ground
        --seeds 8``); a well-seen floor gives the same plane in every search. 1 = one search, taken as it is.
        Unused with ``up`` (nothing is drawn).
    gravity : (3,) array, optional
        The up direction measured in this frame's image (:func:`~stereo_classic.guide.gravity.estimate_gravity`:
        the vanishing direction of its vertical lines), a unit vector: a plane (refitted) more than
        :data:`~stereo_classic.guide.gravity.GRAVITY_TOLERANCE_DEG` from level is not the ground, on top of
        the limits above (which a carried camera's tilt and roll set: the search itself is the same). Stairs
        seen along the flight make one plane like a floor, within those limits; its 30-42 degrees from level
        tell it apart. Unused with ``up`` (a given pitch wins).

    Returns
    -------
    GroundPlane or None
        Up to three distinct planes are found one after the other (sequential RANSAC), each refitted by least
        squares to convergence. A plane may be the ground when it lies below the camera at a height in
        ``height_range``, within the tilt and roll limits, holds at least 30 points and 15 % of the
        candidates, is ``min_width`` wide, and fewer points lie below it (nearer than its own) than half its
        support. Of those the best supported is taken, then, while another plane lies under it (most of its
        points three inlier bands or more below), that one: the lowest large plane (a desk, a table, a bed or
        a crib above the floor is not the ground). A round of RANSAC on the points under the current choice
        looks for such a plane when none of the three is. None when no plane qualifies or the searches do not
        agree: the ground is unknown, and the guide says so rather than inventing one.
    """
    if isinstance(restarts, bool) or not isinstance(restarts, (int, np.integer)) or restarts < 1:
        raise ValueError(f"`restarts` must be a positive integer (independent searches), got {restarts!r}")
    xyz, uv = points.xyz, points.uv
    if points.textured is not None:
        xyz, uv = xyz[points.textured], uv[points.textured]
    given = None if up is None else np.asarray(up, np.float64).reshape(3) / np.linalg.norm(up)
    level = None
    if gravity is not None and given is None:
        level = np.asarray(gravity, np.float64).reshape(-1)
        if level.shape != (3,) or not np.isfinite(level).all() or not np.linalg.norm(level) > 0:
            raise ValueError(f"`gravity` must be a finite non-zero 3-vector (the up direction), got {gravity!r}")
        level = level / np.linalg.norm(level)
    if prior is not None:
        cand = xyz[(np.abs(prior.heights(xyz)) < 0.3) & (xyz[:, 2] < 4.0)]
        ref, limit = prior.up if given is None else given, math.radians(max_tilt_deg / 2)
    else:
        ref, limit = np.array([0.0, -1.0, 0.0]) if given is None else given, math.radians(max_tilt_deg)
        cy = median(uv[:, 1]) if len(uv) else 0.0
        cand = xyz[(uv[:, 1] > cy) & (xyz @ ref < -0.05) & (xyz[:, 2] < 4.0)]     # below the camera, near
    if len(cand) < 30:
        return None
    search = _Search(cand, focal_baseline, ref, limit, max_roll_deg, iterations, rng, height_range, min_width,
                     fixed_up=up is not None, gravity=level)
    if up is not None:                                   # every offset is tried: nothing drawn, one search
        ground = _choose(search)
        return None if ground is None else _plane(ground, cand, focal_baseline)
    planes: list[GroundPlane] = []
    for done in range(1, restarts + 1):                  # one generator: each search draws anew
        ground = _choose(search)
        if ground is not None:
            planes.append(_plane(ground, cand, focal_baseline))
        best = len(_largest_group(planes))
        if 2 * best > restarts or 2 * (best + restarts - done) <= restarts:
            break                                        # a majority agrees, or none can any more
    return consensus(planes, restarts)


def _choose(search: _Search) -> _Surface | None:
    """One search's ground: the best supported qualifying surface, then the lowest large one (see
    :func:`fit_ground`); None when none qualifies."""
    surfaces = [s for s in search.surfaces() if not s.reason]
    if not surfaces:
        return None
    ground = max(surfaces, key=lambda s: s.score)
    for _ in range(4):                                     # the lowest large surface: step down while one is under
        lower = [s for s in surfaces if s is not ground and s.under(ground)]
        if not lower:
            found, _ = search.surface(search.under(ground))
            if found is None or found.reason or not found.under(ground):
                break
            surfaces.append(found)
            lower = [found]
        ground = max(lower, key=lambda s: s.score)
    return ground


def _plane(ground: _Surface, cand: np.ndarray, focal_baseline: float) -> GroundPlane:
    support = int((np.abs(cand @ ground.up + ground.height_m) < _band(cand[:, 2], focal_baseline)).sum())
    return GroundPlane(ground.up, ground.height_m, "fitted", support)


#: Two ground planes are the same ground when their normals differ by less than this (degrees) and their heights
#: by less than :data:`AGREE_M`: what one frame's fit moves by on a floor seen well, and what the tracker blends.
AGREE_DEG = 5.0
AGREE_M = 0.15


def agree(a: GroundPlane, b: GroundPlane) -> bool:
    """Whether two planes are the same ground (:data:`AGREE_DEG`, :data:`AGREE_M`)."""
    angle = math.degrees(math.acos(float(np.clip(a.up @ b.up, -1.0, 1.0))))
    return angle < AGREE_DEG and abs(a.height_m - b.height_m) < AGREE_M


def _largest_group(planes: list[GroundPlane]) -> list[GroundPlane]:
    """The planes that agree with the one most others agree with (the first such): [] when there are none."""
    if not planes:
        return []
    votes = [sum(agree(p, q) for q in planes) for p in planes]
    centre = planes[int(np.argmax(votes))]
    return [q for q in planes if agree(centre, q)]


def consensus(planes: list[GroundPlane], searches: int) -> GroundPlane | None:
    """The plane that more than half of ``searches`` independent searches agree on (:func:`agree`): the mean
    normal and height of the largest agreeing group, around the plane most others agree with (the first such);
    None when no group is a majority (a search that found no ground votes for none)."""
    group = _largest_group(planes)
    if 2 * len(group) <= searches:
        return None
    up = np.mean([q.up for q in group], axis=0)
    return GroundPlane(up, float(np.mean([q.height_m for q in group])), "fitted", max(q.inliers for q in group))
