"""Tracks over frames: association (Hungarian assignment, ``scipy.optimize.linear_sum_assignment``), smoothing,
approach speed and time to contact.

Each frame's measurements (detected objects, obstacles and drop-off edges, in ground coordinates) are matched
to the tracks' predicted positions by the least total distance; a pair further apart than the gate (0.5 m plus 1.5 m/s times
the time since the track was last seen, plus half the obstacle's size), or of different labels, is not matched.
A track keeps its measurements of the last ``track_window`` seconds; a straight line fitted to their distances
gives the smoothed distance (its value now) and the approach speed (minus its slope): a least-squares fit is
what a constant speed needs, without the tuning of a Kalman filter. Time to contact = nearest distance /
approach speed, for tracks approaching faster than :data:`MIN_APPROACH`.

>>> tracker = Tracker(GuideParams())
>>> for i in range(6):                                       # something 4 m ahead, coming closer at 1 m/s
...     tracks = tracker.update([Measurement("object", "person", 0.0, 4.0 - 0.1 * i, 4.0 - 0.1 * i)], 0.1 * i)
>>> t = tracks[0]
>>> t.track_id, round(t.distance_m, 2), round(t.approach_mps, 2), round(t.ttc_s, 1)
(1, 3.5, 1.0, 3.5)
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from stereo_classic.guide.obstacles import clock_of
from stereo_classic.guide.params import GuideParams

__all__ = ["DROP_HOLD_S", "MIN_APPROACH", "Measurement", "Track", "Tracker"]

#: Approach speeds below this (m/s) are "not approaching": no time to contact.
MIN_APPROACH = 0.2
#: Seconds a drop-off track lives unseen while it is predicted ahead. An edge leaves the view before the walker
#: reaches it (a camera 1.2 m up looking down 10 degrees with a 44-degree vertical field sees the ground from
#: 1.9 m on): at 1.0-1.4 m/s that is 1.4-1.9 s of walking, and the edge is still there.
DROP_HOLD_S = 3.0


@dataclass(frozen=True)
class Measurement:
    """One thing seen in one frame.

    Attributes
    ----------
    kind : "object" (detector), "obstacle" (depth only) or "drop_off" (its edge)
    label : class name, "obstacle" or "drop-off"
    lateral_m, forward_m : centre in the ground frame, metres
    nearest_m : horizontal distance of its nearest part, metres
    size_m : extent across, metres (widens the association gate)
    box : (x0, y0, x1, y1) in left-image pixels, or None
    """

    kind: str
    label: str
    lateral_m: float
    forward_m: float
    nearest_m: float
    size_m: float = 0.0
    box: tuple[float, float, float, float] | None = None

    @property
    def distance_m(self) -> float:
        return math.hypot(self.lateral_m, self.forward_m)


@dataclass(eq=False)
class Track:
    """A tracked thing; the fields below are those of the last update.

    Attributes
    ----------
    track_id : int, from 1, never reused within a Guide
    kind, label : as of the measurements
    distance_m, nearest_m : smoothed horizontal distances of the centre and of the nearest part, metres
    bearing_deg : degrees of the last measured centre (0 ahead, positive right)
    approach_mps : float or None, m/s towards the camera (negative: moving away); None until enough history
    ttc_s : float or None, seconds to contact when approaching
    hits : frames in which it was seen; misses : frames since it was last seen
    """

    track_id: int
    kind: str
    label: str
    last: Measurement
    last_time: float
    hits: int = 1
    misses: int = 0
    history: deque = field(default_factory=deque)
    distance_m: float = math.nan
    nearest_m: float = math.nan
    bearing_deg: float = 0.0
    approach_mps: float | None = None
    ttc_s: float | None = None
    lateral_mps: float = 0.0
    forward_mps: float = 0.0
    fitted: tuple[float, float] | None = None      # (lateral_m, forward_m) of the fitted lines at ``last_time``

    @property
    def clock(self) -> int:
        return clock_of(self.bearing_deg)

    def predict(self, time_s: float) -> tuple[float, float]:
        dt = time_s - self.last_time
        return self.last.lateral_m + self.lateral_mps * dt, self.last.forward_m + self.forward_mps * dt

    def predict_fitted(self, time_s: float) -> tuple[float, float]:
        """:meth:`predict` from the fitted lines' position instead of the last measurement (the mean of the last
        ``track_window`` of them: what carries a track that is no longer seen); :meth:`predict` without a fit."""
        if self.fitted is None:
            return self.predict(time_s)
        dt = time_s - self.last_time
        return self.fitted[0] + self.lateral_mps * dt, self.fitted[1] + self.forward_mps * dt


def _line(t: np.ndarray, y: np.ndarray, now: float) -> tuple[float, float]:
    """Least-squares line through (t, y): (value at ``now``, slope)."""
    tc = t - now
    tm, ym = tc.mean(), y.mean()
    var = float(((tc - tm) ** 2).sum())
    slope = float(((tc - tm) * (y - ym)).sum()) / var if var > 0 else 0.0
    return float(ym - slope * tm), slope


class Tracker:
    """Tracks of objects and obstacles over frames (see the module docstring).

    Parameters
    ----------
    params : GuideParams
        ``track_window`` (seconds of history fitted) and ``max_gap`` (a longer pause ends the tracks).
    max_misses : int, frames a track survives unseen; a drop-off's track instead lives unseen for
        :data:`DROP_HOLD_S` seconds while its predicted edge is still ahead (:meth:`held`)
    """

    def __init__(self, params: GuideParams, *, max_misses: int = 3) -> None:
        # Imported by the first tracker, not with this module: scipy.optimize adds ~34 MB to every command that
        # imports the CLI (run included), and about 0.15 s, which a tracker pays before its first frame.
        from scipy.optimize import linear_sum_assignment

        self._assign = linear_sum_assignment
        self.params = params
        self.max_misses = max_misses
        self.tracks: list[Track] = []
        self._next_id = 1

    def reset(self) -> None:
        """Forget every track (ids keep counting)."""
        self.tracks = []

    def _gate(self, track: Track, m: Measurement, dt: float) -> float:
        return 0.5 + 1.5 * max(dt, 0.0) + 0.5 * max(m.size_m, track.last.size_m)

    def update(self, measurements: list[Measurement], time_s: float) -> list[Track]:
        """Associate this frame's measurements; returns the tracks seen in this frame (nearest first)."""
        tracks = self.tracks
        matched_m: set[int] = set()
        if tracks and measurements:
            cost = np.full((len(tracks), len(measurements)), 1e6)
            for i, tr in enumerate(tracks):
                px, pz = tr.predict(time_s)
                dt = time_s - tr.last_time
                for j, m in enumerate(measurements):
                    if m.label != tr.label or m.kind != tr.kind:
                        continue
                    d = math.hypot(m.lateral_m - px, m.forward_m - pz)
                    if d <= self._gate(tr, m, dt):
                        cost[i, j] = d
            rows, cols = self._assign(cost)
            for i, j in zip(rows, cols):
                if cost[i, j] < 1e6:
                    self._add(tracks[i], measurements[j], time_s)
                    matched_m.add(int(j))
        seen = {id(t) for t in tracks if t.last_time == time_s}
        for t in tracks:
            if id(t) not in seen:
                t.misses += 1
        self.tracks = [t for t in tracks if (self._ahead(t, time_s) if t.kind == "drop_off"
                                             else t.misses <= self.max_misses)]
        for j, m in enumerate(measurements):
            if j not in matched_m:
                t = Track(self._next_id, m.kind, m.label, m, time_s)
                self._next_id += 1
                t.history.append((time_s, m.distance_m, m.nearest_m, m.lateral_m, m.forward_m))
                self._smooth(t, time_s)
                self.tracks.append(t)
        current = [t for t in self.tracks if t.last_time == time_s]
        current.sort(key=lambda t: t.nearest_m)
        return current

    @staticmethod
    def _ahead(t: Track, time_s: float) -> bool:
        return t.misses == 0 or (time_s - t.last_time <= DROP_HOLD_S + 1e-9 and t.predict_fitted(time_s)[1] > 0.0)

    def held(self, time_s: float) -> list[Track]:
        """The drop-off tracks not seen at ``time_s`` but kept (their edge predicted ahead)."""
        return [t for t in self.tracks if t.kind == "drop_off" and t.last_time != time_s]

    def _add(self, track: Track, m: Measurement, time_s: float) -> None:
        track.last, track.last_time = m, time_s
        track.hits += 1
        track.misses = 0
        track.history.append((time_s, m.distance_m, m.nearest_m, m.lateral_m, m.forward_m))
        self._smooth(track, time_s)

    def _smooth(self, track: Track, now: float) -> None:
        hist = track.history
        while hist and hist[0][0] < now - self.params.track_window - 1e-9:
            hist.popleft()
        arr = np.array(hist, dtype=np.float64)
        m = track.last
        track.bearing_deg = math.degrees(math.atan2(m.lateral_m, m.forward_m))
        if len(arr) >= 3 and arr[-1, 0] - arr[0, 0] >= 0.25:
            t = arr[:, 0]
            track.distance_m, slope = _line(t, arr[:, 1], now)
            track.nearest_m, _ = _line(t, arr[:, 2], now)
            lat, track.lateral_mps = _line(t, arr[:, 3], now)
            fwd, track.forward_mps = _line(t, arr[:, 4], now)
            track.fitted = (lat, fwd)
            track.approach_mps = -slope
        else:
            track.distance_m, track.nearest_m = m.distance_m, m.nearest_m
            track.approach_mps = None
            track.fitted = None
        track.nearest_m = min(track.nearest_m, track.distance_m)
        a = track.approach_mps
        track.ttc_s = track.nearest_m / a if a is not None and a > MIN_APPROACH and track.nearest_m > 0 else None
