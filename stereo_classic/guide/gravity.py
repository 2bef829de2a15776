"""Which way is up, from one image: the vanishing direction of the scene's vertical lines.

Door frames, wall corners, poles, table legs and balusters are vertical, and a camera sees them converge towards
one vanishing point; its direction from the camera is the direction of gravity (the "Manhattan world" of
J. M. Coughlan and A. L. Yuille, "Manhattan World: compass direction from a single image by Bayesian inference",
ICCV 1999; J. Kosecka and W. Zhang, "Video compass", ECCV 2002). A point cloud cannot give it: the steps of a
staircase seen along the flight make one plane, as a floor does, and only the direction of gravity tells a ramp
of 35 degrees from level ground (docs/guide.md, "Which way is up").

:func:`estimate_gravity` finds the line segments of the left image (OpenCV's fast line detector, on the image
halved), keeps those along which the matcher measured (the rectification's border has no lines of the scene),
and takes the direction through which the longest segments pass (RANSAC over pairs of segments, then least
squares), among those a carried camera can see as vertical (pitch -45 to 60 degrees, roll within 15). Too few
segments, too short in all, all in one plane through the camera, or no more than chance would line up (an
a-contrario test against the image's own rate of segments passing a random direction): None, and the guide
keeps its own prior.

Coordinates are the left rectified camera frame (X right, Y down, Z forward), as in
:mod:`stereo_classic.guide.ground`.

>>> import numpy as np
>>> t = np.radians(20.0)                               # a camera looking down 20 degrees, not rolled
>>> g = Gravity(np.array([0.0, -np.cos(t), -np.sin(t)]), lines=12, length_px=900.0)
>>> round(g.pitch_deg, 1), round(g.roll_deg, 1)
(20.0, 0.0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.special import bdtrc

from calib import RectifiedRig
from stereo_classic.guide.params import GuideInputError

__all__ = ["GRAVITY_TOLERANCE_DEG", "LEVEL_COS", "MAX_FALSE_ALARMS", "MIN_LENGTH_HEIGHTS", "MIN_LINES", "Gravity",
           "estimate_gravity", "is_level", "pitch_of", "roll_of"]

#: Fewest segments through the vanishing point for an estimate: a handful of door-frame edges or balusters.
MIN_LINES = 6
#: Their total length must be at least this many image heights (vertical lines are bounded by the height, also
#: in a wide driving frame): structure that spans the view. Texture alone (the rendered test scenes' noise) makes
#: short segments, of which a few meet anywhere by chance (0.6-0.9 heights); the OAK-D scenes' vertical lines add
#: up to 2.4-8 heights.
MIN_LENGTH_HEIGHTS = 1.5
#: Segments shorter than this share of the image height are not used.
MIN_SEGMENT_HEIGHTS = 0.08
#: The a-contrario test (Desolneux, Moisan and Morel; as LSD itself): the expected number of directions that
#: so many segments would meet by chance, over the hypotheses tried, must be below this.
MAX_FALSE_ALARMS = 1.0
#: A segment passes through the vanishing point when its plane through the camera misses it by less than this
#: (degrees): a 20-pixel segment of the halved image is drawn within about half a pixel.
LINE_TOLERANCE_DEG = 1.0
#: A ground plane whose normal is further than this (degrees) from the measured up is not level ground. On the
#: OAK-D scenes whose floor the guide fits, the floor's normal is 0.6-7.5 degrees from the up of the vertical lines
#: (the loosest: a floor seen only in a strip 2-4 m away, whose fitted roll is off; docs/guide.md); a ramp is at
#: most 1:12 (4.8 degrees); stairs rise 30-42 degrees indoors and about 23 at their gentlest outdoors (6 in risers,
#: 14 in treads). Halfway leaves both sides a margin of 7 degrees or more.
GRAVITY_TOLERANCE_DEG = 15.0
#: Its cosine: a unit normal ``n`` is level when ``n . up > LEVEL_COS``.
LEVEL_COS = math.cos(math.radians(GRAVITY_TOLERANCE_DEG))
#: Directions a carried camera can see as vertical: pitch (positive = looking down) and roll limits, degrees. A
#: walker's camera looks at most 60 degrees down (from chest height, the floor 0.8 m ahead) and 45 up. The limits
#: also keep out the lines that run ahead, level (floor and ceiling edges, handrails, table edges): their vanishing
#: point reads as a pitch of 90 minus the true one, beyond these limits for a camera pitched from 30 up to 45
#: down (measured on Middlebury's Cones, Teddy and Venus, level cameras: 72-78 degrees "down" before).
PITCH_RANGE = (-45.0, 60.0)
#: The roll limit of the ground's own prior (``fit_ground``'s ``max_roll_deg``): a chest, head or hand-held camera is
#: held nearly upright. Parallel lines that are not vertical (a chair's back slats, a handrail) can meet in a
#: direction rolled further (Middlebury's Adirondack, a level camera: 24 degrees before).
MAX_ROLL_DEG = 15.0
#: Pairs of segments tried (every pair when there are fewer).
HYPOTHESES = 512
#: The segments' planes through the camera must spread by this much (ratio of the two larger singular values of
#: their normals) for the vanishing point to be pinned: parallel segments side by side give only a plane.
MIN_SPREAD = 0.05


def is_level(normal: np.ndarray, up: np.ndarray) -> bool:
    """Whether a plane of unit ``normal`` is within :data:`GRAVITY_TOLERANCE_DEG` of level, ``up`` being the measured
    up direction (any length)."""
    return float(np.asarray(normal) @ np.asarray(up)) >= LEVEL_COS * float(np.linalg.norm(up))


def pitch_of(up: np.ndarray) -> np.ndarray:
    """Downward tilt of the optical axis (degrees; negative: looking up) of unit up vectors ``up`` ((3,) or
    (K, 3), camera frame): the one formula of :class:`Gravity` and :class:`~stereo_classic.guide.GroundPlane`."""
    return np.degrees(np.arcsin(np.clip(-np.asarray(up)[..., 2], -1.0, 1.0)))


def roll_of(up: np.ndarray) -> np.ndarray:
    """Sideways tilt (degrees; positive: the right side of the image is lower) of unit up vectors ``up``."""
    up = np.asarray(up)
    return np.degrees(np.arctan2(up[..., 0], -up[..., 1]))


@dataclass(frozen=True, eq=False)
class Gravity:
    """The up direction measured in one image.

    Attributes
    ----------
    up : (3,) float64, unit vector pointing up (against gravity), camera frame
    lines : int, segments through the vanishing point
    length_px : float, their total length, pixels of the full image
    """

    up: np.ndarray
    lines: int
    length_px: float

    def __post_init__(self) -> None:
        up = np.asarray(self.up, np.float64).reshape(3)
        norm = float(np.linalg.norm(up))
        if not (math.isfinite(norm) and norm > 0):
            raise ValueError(f"Gravity: `up` must be a finite non-zero vector, got {self.up!r}")
        object.__setattr__(self, "up", up / norm)

    @property
    def pitch_deg(self) -> float:
        """Downward tilt of the optical axis, degrees (negative: looking up)."""
        return float(pitch_of(self.up))

    @property
    def roll_deg(self) -> float:
        """Sideways tilt, degrees (positive: the right side of the image is lower)."""
        return float(roll_of(self.up))

    def angle_deg(self, up: np.ndarray) -> float:
        """Degrees between this up and the unit vector ``up`` (a plane's normal)."""
        return math.degrees(math.acos(float(np.clip(self.up @ np.asarray(up, np.float64), -1.0, 1.0))))

    def to_dict(self) -> dict[str, float | int]:
        return {"pitch_deg": round(self.pitch_deg, 2), "roll_deg": round(self.roll_deg, 2), "lines": self.lines}


def _grey(image: np.ndarray) -> np.ndarray:
    if image.ndim == 2:
        return image
    if image.shape[2] == 1:
        return image[..., 0]
    return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)


def _segments(grey: np.ndarray, measured: np.ndarray | None, min_length: float) -> np.ndarray:
    """(N, 4) float64 segments x1 y1 x2 y2 (full-image pixels) found on the halved image; with ``measured``,
    only those with a measured disparity at 3 of 9 points along them (a rectified image's black or smeared
    border has no depth, and its streaks are not lines of the scene)."""
    small = cv2.resize(grey, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
    fld = cv2.ximgproc.createFastLineDetector(length_threshold=max(4, int(round(min_length / 2))), do_merge=False)
    found = fld.detect(small)
    if found is None:
        return np.zeros((0, 4))
    seg = found.reshape(-1, 4).astype(np.float64) * 2.0 + 0.5     # centres of the halved pixels, full-image units
    if measured is not None and len(seg):
        t = np.linspace(0.1, 0.9, 9)
        u = seg[:, 0, None] + t * (seg[:, 2] - seg[:, 0])[:, None]
        v = seg[:, 1, None] + t * (seg[:, 3] - seg[:, 1])[:, None]
        h, w = measured.shape
        ui = np.clip(np.round(u).astype(np.int64), 0, w - 1)
        vi = np.clip(np.round(v).astype(np.int64), 0, h - 1)
        seg = seg[np.isfinite(measured[vi, ui]).mean(axis=1) >= 1.0 / 3.0]
    return seg


def _orient_down(v: np.ndarray) -> np.ndarray:
    """Vanishing directions turned to point down the image (camera +Y): a line has no sign, gravity has."""
    return v * np.where(v[..., 1] < 0, -1.0, 1.0)[..., None]


def _plausible(down: np.ndarray) -> np.ndarray:
    """(K,) bool: down vectors a carried camera can have (``PITCH_RANGE``, ``MAX_ROLL_DEG``)."""
    pitch, roll = pitch_of(-down), roll_of(-down)
    return (pitch >= PITCH_RANGE[0]) & (pitch <= PITCH_RANGE[1]) & (np.abs(roll) <= MAX_ROLL_DEG)


def _probe_directions(step_deg: float = 4.0) -> np.ndarray:
    """(K, 3) down vectors on a grid of the plausible pitches and rolls (``step_deg`` apart): the directions over
    which an image's chance rate of a segment passing through one is measured."""
    pitch = np.radians(np.arange(PITCH_RANGE[0], PITCH_RANGE[1] + 1e-9, step_deg))
    roll = np.radians(np.arange(-MAX_ROLL_DEG, MAX_ROLL_DEG + 1e-9, step_deg))
    t, r = (a.ravel() for a in np.meshgrid(pitch, roll))
    return np.column_stack([-np.sin(r) * np.cos(t), np.cos(r) * np.cos(t), np.sin(t)])   # -up of that pitch, roll


_PROBES = _probe_directions()


def estimate_gravity(image: np.ndarray, rig: RectifiedRig, *, measured: np.ndarray | None = None,
                     rng: int = 0) -> Gravity | None:
    """The up direction of the scene seen in ``image``, from its vertical lines, or None.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) uint8, the left rectified image (BGR)
    rig : calib.RectifiedRig of that image (its focal length and principal point)
    measured : (H, W) float32, optional
        The measured disparity (NaN unknown): segments along which nothing was measured are left out.
    rng : int, seeds the choice of segment pairs (the same image and seed give the same answer)

    Returns
    -------
    Gravity or None
        None when fewer than ``MIN_LINES`` segments meet in a direction a carried camera can see as vertical,
        when they add up to less than ``MIN_LENGTH_HEIGHTS`` image heights, when they do not pin it (all in
        nearly one plane through the camera), or when so many would meet somewhere by chance (the a-contrario
        test, ``MAX_FALSE_ALARMS``): no measurement rather than a guess.

    Raises
    ------
    GuideInputError (ValueError)
        ``image`` not a uint8 image of the rig's size, ``measured`` not of that size, ``rig`` not a RectifiedRig.
    """
    if not isinstance(rig, RectifiedRig):
        raise GuideInputError(f"`rig` must be a calib.RectifiedRig, got {type(rig).__name__}")
    size = tuple(int(v) for v in rig.image_size)
    if not (isinstance(image, np.ndarray) and image.dtype == np.uint8 and image.ndim in (2, 3)
            and (image.ndim == 2 or image.shape[2] in (1, 3)) and (image.shape[1], image.shape[0]) == size):
        got = f"{image.dtype} {image.shape}" if isinstance(image, np.ndarray) else type(image).__name__
        raise GuideInputError(f"`image` must be a uint8 (H, W) or (H, W, 3) image of the rig's size "
                              f"{size[0]}x{size[1]}, got {got}")
    if measured is not None and not (isinstance(measured, np.ndarray) and measured.shape == image.shape[:2]):
        got = measured.shape if isinstance(measured, np.ndarray) else type(measured).__name__
        raise GuideInputError(f"`measured` must be an (H, W) disparity of the image's size {image.shape[:2]}, "
                              f"got {got}")
    height = float(size[1])
    seg = _segments(_grey(image), measured, MIN_SEGMENT_HEIGHTS * height)
    if len(seg) < MIN_LINES:
        return None
    f = float(rig.focal_px)

    def ray(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.column_stack([(x - rig.cx_left) / f, (y - rig.cy) / f, np.ones(len(x))])

    normals = np.cross(ray(seg[:, 0], seg[:, 1]), ray(seg[:, 2], seg[:, 3]))  # each segment's plane through the camera
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    length = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    n = len(seg)
    pairs = np.column_stack(np.triu_indices(n, 1)) if n * (n - 1) // 2 <= HYPOTHESES \
        else np.random.default_rng(rng).integers(0, n, size=(HYPOTHESES, 2))
    cand = np.cross(normals[pairs[:, 0]], normals[pairs[:, 1]])
    norm = np.linalg.norm(cand, axis=1)
    cand = _orient_down(cand[norm > 1e-6] / norm[norm > 1e-6, None])
    cand = cand[_plausible(cand)]
    if not len(cand):
        return None
    tol = math.sin(math.radians(LINE_TOLERANCE_DEG))
    score = ((np.abs(normals @ cand.T) < tol) * length[:, None]).sum(axis=0)
    down = cand[int(np.argmax(score))]
    inl = np.abs(normals @ down) < tol
    for _ in range(5):                                     # least squares on the inliers, until they stop changing
        if inl.sum() < 2:
            break
        new = _orient_down(np.linalg.svd(normals[inl] * np.sqrt(length[inl])[:, None])[2][-1])
        new_inl = np.abs(normals @ new) < tol
        down = new
        if (new_inl == inl).all():
            break
        inl = new_inl
    k = int(inl.sum())
    if k < MIN_LINES or length[inl].sum() < MIN_LENGTH_HEIGHTS * height or not _plausible(down[None, :])[0]:
        return None
    s = np.linalg.svd(normals[inl], compute_uv=False)
    if s[1] < MIN_SPREAD * s[0]:
        return None
    # a-contrario: the share of segments that a plausible direction collects, over a grid of them (this image's
    # chance rate), and the expected number of hypotheses that collect k by chance (two segments make each one)
    chance = max(float((np.abs(normals @ _PROBES.T) < tol).mean()), 1.0 / (n * len(_PROBES)))  # (never 0)
    if len(pairs) * bdtrc(k - 3, n - 2, chance) >= MAX_FALSE_ALARMS:     # P(more than k - 3 of n - 2) by chance
        return None
    return Gravity(-down, k, float(length[inl].sum()))
