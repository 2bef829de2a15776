"""The guide: fed frame by frame with the pipeline's result and a time, it says what is ahead.

:class:`Guide` chains the steps of this package for one frame: sample the disparity into points
(:mod:`~stereo_classic.guide.ground`), keep the ground plane, find obstacles in the corridor
(:mod:`~stereo_classic.guide.obstacles`) and drop-offs (:mod:`~stereo_classic.guide.dropoff`), measure the
detected objects, track both (:mod:`~stereo_classic.guide.tracking`), find the free distance per direction and
the clear path, and let :class:`~stereo_classic.guide.messages.MessagePolicy` choose the events. The result is a
:class:`GuideFrame`; nothing is written or spoken here (the ``guide`` command and
:mod:`~stereo_classic.guide.speech` do that).

Without a ground plane (none fitted yet and no ``camera_height`` / ``camera_pitch`` given) there are no
obstacles, drop-offs or clear path in that frame, only detected objects (measured in the camera frame), and
``GuideFrame.notes`` says so: no distance is invented.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from calib import RectifiedRig
from stereo_classic.guide._stats import percentile
from stereo_classic.guide.dropoff import DropOff, find_dropoff
from stereo_classic.guide.gravity import Gravity, estimate_gravity
from stereo_classic.guide.ground import (
    GroundPlane,
    PointSample,
    sample_points,
)
from stereo_classic.guide.ground_tracker import GroundTracker
from stereo_classic.guide.messages import (
    Candidate,
    Event,
    MessagePolicy,
    ground_unknown,
)
from stereo_classic.guide.obstacles import (
    Obstacle,
    OccupancyGrid,
    clock_of,
    find_obstacles,
    free_distances,
)
from stereo_classic.guide.params import GuideInputError, GuideParams
from stereo_classic.guide.tracking import Measurement, Track, Tracker

__all__ = ["Guide", "GuideFrame", "TrackView"]

#: While a fitted ground is tracked, the up is measured from the image's vertical lines this often (seconds).
GRAVITY_PERIOD_S = 1.0

#: Frame-check codes (``PipelineResult.warnings``) of a pair whose depths cannot be used.
_NOT_MEASURED = frozenset({"swapped_pair", "pair_mismatch"})


@dataclass(frozen=True)
class TrackView:
    """A track as it was in one frame (see :class:`~stereo_classic.guide.tracking.Track`)."""

    track_id: int
    kind: str
    label: str
    distance_m: float
    nearest_m: float
    bearing_deg: float
    approach_mps: float | None
    ttc_s: float | None
    lateral_m: float
    forward_m: float
    in_corridor: bool
    box: tuple[float, float, float, float] | None

    @property
    def clock(self) -> int:
        return clock_of(self.bearing_deg)


def frame_points(disparity: np.ndarray, rig: RectifiedRig, params: GuideParams,
                 image: np.ndarray | None = None) -> PointSample:
    """The samples one frame's ground, obstacles and drop-offs are found in: about 12 000 pixels of
    ``disparity`` (measured pixels only, NaN elsewhere) on a regular grid, back-projected out to 2.5 times the
    look-ahead (at least 10 m), textured where the left ``image`` says so
    (:func:`~stereo_classic.guide.ground.sample_points`)."""
    h, w = disparity.shape
    stride = max(2, round(math.sqrt(h * w / 12000.0)))
    return sample_points(disparity, rig, stride=stride, max_depth=max(2.5 * params.look_ahead, 10.0), image=image)


@dataclass(frozen=True, eq=False)
class GuideFrame:
    """What the guide found in one frame.

    Attributes
    ----------
    frame : str ; time_s : float, seconds
    ground : GroundPlane or None
    obstacles : list of Obstacle, in the corridor, nearest first (those a detected object explains left out)
    grid : OccupancyGrid or None
    dropoff : DropOff or None, straight ahead (the corridor): seen, or where its track puts it (``predicted``)
    hours : (K,) int, clock hours inside the field of view ; free_m : (K,) float, metres free along each
    clear_clock : int or None, the hour with the longest free distance (ties: the one nearest to 12)
    sectors_deg : (S,) float, haptic sector centres ; haptics : (S,) float in [0, 1], 1 = blocked at the feet
    tracks : list of TrackView (objects and obstacles) seen in this frame ; events : list of Event ; notes : tuple of str
    obstacle_uv : (M, 2) float64, left-image pixels (column, row) of the obstacle points in the corridor
    gravity : Gravity or None, the up direction measured from the image's vertical lines (None: not measured, or
        not estimated: ``camera_pitch`` given or ``vertical_lines`` off)
    """

    frame: str
    time_s: float
    ground: GroundPlane | None
    obstacles: list[Obstacle]
    grid: OccupancyGrid | None
    dropoff: DropOff | None
    hours: np.ndarray
    free_m: np.ndarray
    clear_clock: int | None
    sectors_deg: np.ndarray
    haptics: np.ndarray
    tracks: list[TrackView]
    events: list[Event]
    notes: tuple[str, ...] = ()
    obstacle_uv: np.ndarray | None = None
    gravity: Gravity | None = None

    def haptics_record(self) -> dict[str, Any]:
        """The frame's line of ``events.jsonl`` with the haptic vector, the free distances and the ground."""
        return {"frame": self.frame, "time_s": round(self.time_s, 3), "kind": "haptics",
                "sectors_deg": [round(float(b), 1) for b in self.sectors_deg],
                "intensity": [round(float(v), 3) for v in self.haptics],
                "hours": [int(h) for h in self.hours], "free_m": [round(float(v), 2) if math.isfinite(v) else None for v in self.free_m],
                "clear_clock": self.clear_clock,
                "ground": self.ground.to_dict() if self.ground is not None else None,
                "gravity": self.gravity.to_dict() if self.gravity is not None else None, "notes": list(self.notes)}


class Guide:
    """Feed it frames in time order; see the module docstring.

    Parameters
    ----------
    params : GuideParams, optional
    **overrides : GuideParams fields

    Usage::

        with Localizer(rig, "yolox_nano") as loc:
            guide = Guide(corridor_width=0.8)
            for i, (left, right) in enumerate(pairs):
                frame = guide.update(loc(left, right), rig, time_s=i / 10, frame=str(i))
                for event in frame.events:
                    print(event.text)                       # "person, 12 o'clock, 2.4 metres, approaching"
    """

    def __init__(self, params: GuideParams | None = None, **overrides: Any) -> None:
        if params is not None and not isinstance(params, GuideParams):
            raise GuideInputError(f"`params` must be a GuideParams or None, got {type(params).__name__}")
        self.params = (params or GuideParams()).replace(**overrides)
        self.ground = GroundTracker(self.params)
        self.tracker = Tracker(self.params)
        self.policy = MessagePolicy(self.params)
        self.last_time: float | None = None
        self.frames = 0
        self._rig_key: tuple | None = None
        self._drop_m = math.nan            # how far down the last drop-off seen went (metres)
        self._gravity_time: float | None = None   # when the up was last measured from the vertical lines

    def reset(self) -> None:
        """Forget the ground, the tracks and what was said (a new scene)."""
        self.ground.reset()
        self.tracker.reset()
        self.policy.reset()
        self.last_time = None
        self.frames = 0
        self._gravity_time = None

    def update(self, result: Any, rig: RectifiedRig, time_s: float, *, frame: str | None = None) -> GuideFrame:
        """Process one frame.

        Parameters
        ----------
        result : stereo_classic.PipelineResult (``disparity`` and ``objects`` are used; of the disparity map only
            the measured pixels, ``disparity``, never ``filled_disparity``)
        rig : calib.RectifiedRig, the rig of the images the matcher saw
        time_s : float, seconds, increasing from frame to frame
        frame : str, the frame's name in events (default: its number)

        Raises
        ------
        GuideInputError (ValueError)
            A time that is not finite or not after the previous one, a rig that is not a RectifiedRig, or a
            disparity map of another size than the rig's images.
        """
        if isinstance(time_s, bool) or not isinstance(time_s, (int, float, np.floating, np.integer)) \
                or not math.isfinite(float(time_s)):
            raise GuideInputError(f"`time_s` must be a finite number of seconds, got {time_s!r}")
        time_s = float(time_s)
        if not isinstance(rig, RectifiedRig):
            raise GuideInputError(f"`rig` must be a calib.RectifiedRig, got {type(rig).__name__}")
        dmap = getattr(result, "disparity", None)
        # the measured pixels only (``DisparityMap.disparity``; the filled ones, in ``filled_disparity``, are guesses
        # from the background beside a hole, and a guess must not make an obstacle, a ground or a distance)
        disparity = getattr(dmap, "disparity", None)
        if not isinstance(disparity, np.ndarray) or disparity.ndim != 2:
            raise GuideInputError(f"`result` must be a PipelineResult with a disparity map, got {type(result).__name__}")
        size = (disparity.shape[1], disparity.shape[0])
        if size != tuple(int(v) for v in rig.image_size):
            raise GuideInputError(f"`rig` is for {rig.image_size[0]}x{rig.image_size[1]} images but the disparity "
                                  f"map is {size[0]}x{size[1]}")
        notes: list[str] = []
        key = (size, float(rig.focal_px), float(rig.baseline_m))
        if self._rig_key is not None and key != self._rig_key:
            self.reset()
            notes.append("new camera geometry: ground and tracks started afresh")
        self._rig_key = key
        if self.last_time is not None:
            if time_s <= self.last_time:
                raise GuideInputError(f"`time_s` must increase from frame to frame, got {time_s} after "
                                      f"{self.last_time}")
            if time_s - self.last_time > self.params.max_gap:
                self.tracker.reset()
                self.policy.reset()
                notes.append(f"{time_s - self.last_time:.1f} s since the last frame: tracks started afresh")
        self.last_time = time_s
        self.frames += 1
        name = frame if frame is not None else str(self.frames - 1)
        return self._process(result, rig, disparity, time_s, name, notes)

    # ----------------------------------------------------------------------------------------------
    def _process(self, result: Any, rig: RectifiedRig, disparity: np.ndarray, time_s: float, name: str,
                 notes: list[str]) -> GuideFrame:
        p = self.params
        w = disparity.shape[1]
        fb = float(rig.focal_px * rig.baseline_m)
        left = getattr(result, "left", None)
        points = frame_points(disparity, rig, p, left if isinstance(left, np.ndarray) else None)
        stride = points.stride
        codes = {getattr(w, "code", "") for w in getattr(result, "warnings", ()) or ()}
        edge_ahead = self._edge_ahead(time_s)            # a tracked drop-off edge ahead, predicted to this frame
        gravity = None
        if codes & _NOT_MEASURED:  # a swapped or mismatched pair: its depths are not the scene's
            notes.append("the left/right pair is swapped or not a pair: nothing measured in this frame")
            points = PointSample(np.zeros((0, 2)), np.zeros((0, 3)), stride, float(rig.focal_px))
            plane = None
        else:
            if self._measure_gravity(left, time_s):
                gravity = estimate_gravity(left, rig, measured=disparity, rng=self.frames)
                self._gravity_time = time_s
            plane = self.ground.update(points, fb, before_m=edge_ahead,
                                       gravity=None if gravity is None else gravity.up)
            if self.ground.switched:  # a drop-off was measured against the old plane: it must be seen again
                self.tracker.tracks = [t for t in self.tracker.tracks if t.kind != "drop_off"]
                edge_ahead = None
        left_b = math.degrees(math.atan2(-rig.cx_left, rig.focal_px))
        right_b = math.degrees(math.atan2(w - 1 - rig.cx_left, rig.focal_px))
        hours_b = np.array([b for b in (-60.0, -30.0, 0.0, 30.0, 60.0) if left_b - 5 <= b <= right_b + 5])
        edges = np.linspace(left_b, right_b, p.sectors + 1)
        sectors = (edges[:-1] + edges[1:]) / 2
        obstacles: list[Obstacle] = []
        grid = dropoff = corridor_mask = None
        blocked = np.zeros((0, 2))
        if plane is None:
            notes.append("ground unknown: no obstacles, drop-offs or clear path in this frame")
            if gravity is not None and gravity.pitch_deg < -5.0:   # looking up: the ground is out of view, or nearly
                notes.append(f"the camera looks up {-gravity.pitch_deg:.0f} degrees (its vertical lines say): "
                             f"little or no ground in view")
        else:
            gp = plane.to_ground(points.xyz)
            area = points.footprint()
            obstacles, grid = find_obstacles(gp, area, p)
            corridor_mask = grid.mask & (np.abs(gp[:, 0]) < p.corridor_width / 2)
            blocked = grid.cells()
            low = gp[:, 2] < p.step_height / 2                  # the only points a drop-off search looks at
            gl, al = gp[low], area[low]
            drops = [find_dropoff(gl, al, p, camera_height=plane.height_m, bearing_deg=float(b)) for b in hours_b]
            dropoff = next((d for d, b in zip(drops, hours_b) if d is not None and b == 0.0), None)
            edge_pts = [self._edge_points(d) for d in drops if d is not None]
            if edge_pts:
                blocked = np.vstack([blocked] + edge_pts)
        measurements = self._measure_objects(result, rig, disparity, plane)
        if dropoff is not None and not dropoff.edge_seen and (edge_ahead is not None or plane.source == "kept"):
            # No ground seen before it: with a tracked edge ahead, the edge has left the view and its track says
            # where it is (below); on a kept plane (this frame's fit disagreed) it is the level now underfoot.
            dropoff = None
        if dropoff is not None and dropoff.edge_seen:   # an edge seen starts or moves a track (and holds the ground)
            self._drop_m = dropoff.drop_m
            measurements.append(Measurement("drop_off", "drop-off", dropoff.lateral_m, dropoff.forward_m,
                                            dropoff.distance_m, p.corridor_width))
        for m in measurements:
            if m.kind == "object":
                blocked = np.vstack([blocked, [[m.lateral_m * m.nearest_m / max(m.distance_m, 1e-6),
                                                m.forward_m * m.nearest_m / max(m.distance_m, 1e-6)]]])
        obstacles = [o for o in obstacles if not any(self._explains(m, o) for m in measurements if m.kind == "object")]
        measurements += [Measurement("obstacle", "obstacle", o.lateral_m, o.forward_m, o.nearest_m, o.width_m)
                         for o in obstacles]
        tracks = self.tracker.update(measurements, time_s)
        drop_track = next((t for t in tracks if t.kind == "drop_off"), None)
        if plane is not None and dropoff is None:
            dropoff, drop_track = self._predicted_dropoff(time_s, gl, al)
            if dropoff is not None:
                blocked = np.vstack([blocked, self._edge_points(dropoff)])
        first = self.frames == 1
        shown = [t for t in tracks if (t.hits >= 2 or first) and t.kind != "drop_off"]   # drop-offs: below
        views = [self._view(t) for t in shown]
        free = free_distances(blocked, hours_b, p.corridor_width, p.look_ahead) if plane is not None \
            else np.full(len(hours_b), np.nan)
        sector_free = free_distances(blocked, sectors, p.corridor_width, p.look_ahead) if plane is not None \
            else np.full(len(sectors), np.nan)
        haptics = np.nan_to_num(np.clip(1.0 - sector_free / p.look_ahead, 0.0, 1.0), nan=0.0)
        hours = np.array([clock_of(b) for b in hours_b], dtype=np.int64)
        clear = None
        if plane is not None and len(hours_b):
            order = sorted(range(len(hours_b)), key=lambda i: (-round(float(free[i]), 1), abs(hours_b[i])))
            clear = int(hours[order[0]])
        candidates = [Candidate(v.kind, v.label, v.track_id, v.distance_m, v.nearest_m, v.bearing_deg,
                                v.approach_mps, v.ttc_s, v.in_corridor) for v in views if v.kind != "drop_off"]
        if dropoff is not None:
            tid, approach, ttc = ((drop_track.track_id, drop_track.approach_mps, drop_track.ttc_s)
                                  if drop_track is not None else (None, None, None))
            candidates.append(Candidate("drop_off", "drop-off", tid, dropoff.distance_m, dropoff.distance_m,
                                        dropoff.bearing_deg, approach, ttc, True))
        if clear is not None and 0.0 in hours_b:
            ahead = float(free[list(hours_b).index(0.0)])
            best = float(free[list(hours).index(clear)])
            if clear != 12 and ahead < p.warning_distance and best > ahead + 1.0:
                candidates.append(Candidate("clear_path", "clear path", None, best, best,
                                            float(hours_b[list(hours).index(clear)]), None, None, False))
        if plane is None:
            candidates.append(ground_unknown())
        alive = {(t.kind, t.track_id) for t in self.tracker.tracks}
        events = self.policy.select(candidates, frame=name, time_s=time_s, alive=alive)
        return GuideFrame(frame=name, time_s=time_s, ground=plane, obstacles=obstacles, grid=grid, dropoff=dropoff,
                          hours=hours, free_m=free, clear_clock=clear, sectors_deg=sectors, haptics=haptics,
                          tracks=views, events=events, notes=tuple(notes),
                          obstacle_uv=points.uv[corridor_mask] if corridor_mask is not None else np.zeros((0, 2)),
                          gravity=gravity)

    def _measure_gravity(self, left: Any, time_s: float) -> bool:
        """Whether to measure the up from the vertical lines in this frame (about 2.5 ms at 640x480): when the
        ground has to be searched for (none yet, or last frame's fit failed and the plane was kept) and, while a
        ground is tracked, every ``GRAVITY_PERIOD_S`` (a plane taken before the image showed which way is up is
        dropped when the up contradicts it)."""
        p = self.params
        if not (p.vertical_lines and p.camera_pitch is None and isinstance(left, np.ndarray)):
            return False
        plane = self.ground.plane
        return (plane is None or plane.source != "fitted" or self._gravity_time is None
                or time_s - self._gravity_time >= GRAVITY_PERIOD_S)

    def _edge_ahead(self, time_s: float) -> float | None:
        """How far ahead (metres) the nearest tracked drop-off's edge is predicted at ``time_s``, or None."""
        ahead = [t.predict_fitted(time_s)[1] for t in self.tracker.tracks if t.kind == "drop_off"]
        ahead = [f for f in ahead if f > 0.0]
        return min(ahead) if ahead else None

    def _predicted_dropoff(self, time_s: float, low: np.ndarray, area: np.ndarray
                           ) -> tuple[DropOff | None, Track | None]:
        """The drop-off of a track kept unseen (its edge predicted ahead), where its track puts it now; None, and
        the track ended, when this frame contradicts it: beyond the predicted edge the corridor shows more ground
        at the walker's level than below it (``low``: ground-frame points below half a step up, ``area`` theirs;
        the walker turned away, or the edge was a mistake)."""
        p = self.params
        held = self.tracker.held(time_s)        # the tracker keeps them only while predicted ahead
        if not held:
            return None, None
        t = min(held, key=lambda t: t.predict_fitted(time_s)[1])
        lat, fwd = t.predict_fitted(time_s)
        beyond = (np.abs(low[:, 0]) < p.corridor_width / 2) & (low[:, 1] > fwd) & (low[:, 1] < p.look_ahead)
        level = beyond & (low[:, 2] > -p.step_height / 2)
        below = beyond & (low[:, 2] < -p.step_height)
        if area[level].sum() > area[below].sum():
            self.tracker.tracks = [k for k in self.tracker.tracks if k is not t]
            return None, None
        return DropOff(distance_m=math.hypot(lat, fwd), bearing_deg=0.0, lateral_m=lat, forward_m=fwd,
                       drop_m=self._drop_m, edge_seen=False, predicted=True), t

    def _edge_points(self, d: DropOff) -> np.ndarray:
        """Points along a drop-off's edge, across the corridor (they block the free distance)."""
        b = math.radians(d.bearing_deg)
        offs = np.linspace(-self.params.corridor_width / 2, self.params.corridor_width / 2, 5)
        return np.column_stack([d.lateral_m + offs * math.cos(b), d.forward_m - offs * math.sin(b)])

    @staticmethod
    def _explains(m: Measurement, o: Obstacle) -> bool:
        return (abs(m.lateral_m - o.lateral_m) < o.width_m / 2 + 0.3 + m.size_m / 2
                and abs(m.forward_m - o.forward_m) < o.depth_m / 2 + 0.5)

    def _measure_objects(self, result: Any, rig: RectifiedRig, disparity: np.ndarray,
                         plane: GroundPlane | None) -> list[Measurement]:
        objects = getattr(result, "objects", None)
        if objects is None or len(objects) == 0:
            return []
        out: list[Measurement] = []
        fb = float(rig.focal_px * rig.baseline_m)
        h, w = disparity.shape
        for i in range(len(objects)):
            if objects.status[i] != "ok":
                continue
            xyz = np.asarray(objects.xyz[i], np.float64)
            if not np.isfinite(xyz).all():
                continue
            x0, y0, x1, y1 = (float(v) for v in objects.xyxy[i])
            zc = float(xyz[2])
            mx, my = 0.1 * (x1 - x0), 0.1 * (y1 - y0)
            c0, c1 = int(np.clip(x0 + mx, 0, w - 1)), int(np.clip(x1 - mx, 1, w))
            r0, r1 = int(np.clip(y0 + my, 0, h - 1)), int(np.clip(y1 - my, 1, h))
            d = disparity[r0:r1:2, c0:c1:2]
            d = d[np.isfinite(d) & (d + rig.doffs > 0)]
            z = fb / (d + rig.doffs)
            z = z[np.abs(z - zc) < max(0.3, 0.15 * zc)]
            ratio = float(percentile(z, 5)) / zc if z.size >= 10 else 1.0
            if plane is not None:
                lat, fwd, _ = plane.to_ground(xyz[None, :])[0]
            else:
                lat, fwd = float(xyz[0]), float(xyz[2])
            dist = math.hypot(lat, fwd)
            size = (x1 - x0) * zc / rig.focal_px
            out.append(Measurement("object", str(objects.labels[i]), float(lat), float(fwd), dist * min(ratio, 1.0),
                                   size, (x0, y0, x1, y1)))
        return out

    def _view(self, t: Track) -> TrackView:
        m = t.last
        half = self.params.corridor_width / 2 + m.size_m / 2
        return TrackView(t.track_id, t.kind, t.label, t.distance_m, t.nearest_m, t.bearing_deg, t.approach_mps,
                         t.ttc_s, m.lateral_m, m.forward_m, abs(m.lateral_m) < half, m.box)
