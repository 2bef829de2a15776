"""What to say and when: events with priorities, phrasing, hysteresis, only-on-change, rate limiting, dangers first.

Every frame the guide proposes candidates (tracked objects and obstacles, a drop-off, a clear path, and the
``status`` "ground unknown" when it has no ground plane: then it sees no obstacle, drop-off or clear way);
:class:`MessagePolicy` decides which become events:

* **priority**: "danger" (in the corridor nearer than ``danger_distance``, or reached within ``danger_ttc``
  seconds, or a drop-off nearer than ``warning_distance``), "warning" (in the corridor nearer than
  ``warning_distance``, or approaching in it), else "info";
* **only on change**: a thing is said again only when its spoken direction, spoken distance, approach or
  priority changed (a new track is a change);
* **hysteresis**: the spoken clock hour changes only when the bearing leaves the last hour by more than 20
  degrees (not 15: no flicker between 12 and 1 o'clock); the spoken distance changes only when the distance
  moved by more than 15 % (at least 0.3 m) from the one last said;
* **rate limiting**: at most one message that is not a danger per ``min_interval`` seconds, the most urgent
  (then the nearest) first; what is not said stays a change and may be said later;
* **danger interrupts**: a danger is said at once (the frame's first danger has ``interrupt=True``: speech stops
  what it is saying; the frame's other dangers follow it), and an unchanged danger again after ``repeat_after``
  seconds.

>>> policy = MessagePolicy(GuideParams())
>>> c = Candidate("object", "person", 3, 2.4, 2.2, 60.0, 0.8, None, in_corridor=False)
>>> [e.text for e in policy.select([c], frame="f0", time_s=0.0)]
["person, 2 o'clock, 2.4 metres, approaching"]
>>> policy.select([c], frame="f1", time_s=0.5)  # nothing changed
[]
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from stereo_classic.fusion import direction_phrase
from stereo_classic.guide.obstacles import clock_of
from stereo_classic.guide.params import GuideParams
from stereo_classic.guide.tracking import MIN_APPROACH

__all__ = ["GROUND_UNKNOWN_TEXT", "KINDS", "PRIORITIES", "Candidate", "Event", "MessagePolicy", "ground_unknown",
           "say_direction", "say_distance"]

#: Values of ``Event.kind``. "status": what the guide cannot see (``label`` "ground unknown": without a ground
#: there are no obstacles, drop-offs or clear path, so silence must not pass for a clear way).
KINDS: tuple[str, ...] = ("object", "obstacle", "drop_off", "clear_path", "status")
#: What the "ground unknown" status says.
GROUND_UNKNOWN_TEXT = "ground not seen, drop-offs not checked"
#: Values of ``Event.priority``, most urgent first.
PRIORITIES: tuple[str, ...] = ("danger", "warning", "info")
_FEET_PER_M = 3.28084


def _r(value: float | None, digits: int) -> float | None:
    return None if value is None or not math.isfinite(value) else round(float(value), digits)


@dataclass(frozen=True)
class Event:
    """One message, as written to ``events.jsonl`` (:meth:`to_dict`) and spoken (``text``)."""

    frame: str
    time_s: float
    kind: str
    label: str
    track_id: int | None
    distance_m: float | None
    nearest_m: float | None
    clock: int
    bearing_deg: float
    approach_mps: float | None
    ttc_s: float | None
    priority: str
    text: str
    interrupt: bool = False

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"`kind` must be one of {KINDS}, got {self.kind!r}")
        if self.priority not in PRIORITIES:
            raise ValueError(f"`priority` must be one of {PRIORITIES}, got {self.priority!r}")
        if not 1 <= self.clock <= 12:
            raise ValueError(f"`clock` must be 1..12, got {self.clock!r}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: metres and seconds rounded, unknown values None (null)."""
        return {"frame": self.frame, "time_s": round(self.time_s, 3), "kind": self.kind, "label": self.label,
                "track_id": self.track_id, "distance_m": _r(self.distance_m, 2), "nearest_m": _r(self.nearest_m, 2),
                "clock": self.clock, "bearing_deg": _r(self.bearing_deg, 1),
                "approach_mps": _r(self.approach_mps, 2), "ttc_s": _r(self.ttc_s, 1), "priority": self.priority,
                "text": self.text, "interrupt": self.interrupt}


@dataclass(frozen=True)
class Candidate:
    """Something that may be said: ``distance_m`` is the centre's, ``nearest_m`` the nearest part's (both
    horizontal, metres); the spoken distance is ``nearest_m`` for obstacles and drop-offs, ``distance_m`` for
    objects."""

    kind: str
    label: str
    track_id: int | None
    distance_m: float
    nearest_m: float
    bearing_deg: float
    approach_mps: float | None
    ttc_s: float | None
    in_corridor: bool = True

    @property
    def key(self) -> tuple[str, int | None]:
        return (self.kind, self.track_id)

    @property
    def spoken_m(self) -> float:
        return self.distance_m if self.kind == "object" else self.nearest_m


def say_distance(metres: float, units: str) -> str:
    """ "2.4 metres", "12 metres", "8 feet".

    >>> say_distance(2.44, "metres"), say_distance(12.3, "metres"), say_distance(2.44, "feet")
    ('2.4 metres', '12 metres', '8 feet')
    """
    if units == "feet":
        feet = max(1, round(metres * _FEET_PER_M))
        return f"{feet} foot" if feet == 1 else f"{feet} feet"
    if metres < 10:
        return f"{metres:.1f} metres"
    return f"{round(metres)} metres"


def say_direction(clock: int, bearing_deg: float, directions: str) -> str:
    """ "2 o'clock", or in words ("slightly left", "ahead") from the bearing."""
    if directions == "clock":
        return f"{clock} o'clock"
    b = math.radians(bearing_deg)
    return direction_phrase([math.sin(b), 0.0, math.cos(b)])


def ground_unknown() -> Candidate:
    """The status candidate of a frame without a ground plane: said once when the ground is lost (or not found
    at the start), again only after the ground was seen in between; a warning, at 12 o'clock."""
    return Candidate("status", "ground unknown", None, 0.0, 0.0, 0.0, None, None, in_corridor=False)


@dataclass
class _Said:
    clock: int
    bearing_deg: float
    metres: float
    approaching: bool
    priority: str
    time_s: float


class MessagePolicy:
    """Turn candidates into events (see the module docstring). Keeps what was said per track."""

    def __init__(self, params: GuideParams) -> None:
        self.params = params
        self.said: dict[tuple[str, int | None], _Said] = {}
        self.last_time: float = -math.inf

    def reset(self) -> None:
        self.said.clear()
        self.last_time = -math.inf

    def priority(self, c: Candidate) -> str:
        p = self.params
        if c.kind == "drop_off":
            return "danger" if c.nearest_m < p.warning_distance else "warning"
        if c.kind == "clear_path":
            return "info"
        if c.kind == "status":
            return "warning"
        if c.in_corridor and (c.nearest_m < p.danger_distance or (c.ttc_s is not None and c.ttc_s < p.danger_ttc)):
            return "danger"
        approaching = c.approach_mps is not None and c.approach_mps > MIN_APPROACH
        if c.in_corridor and (c.nearest_m < p.warning_distance or approaching):
            return "warning"
        return "info"

    def _clock(self, c: Candidate, last: _Said | None) -> int:
        if last is not None:
            centre = (last.clock % 12) * 30.0
            diff = (c.bearing_deg - centre + 180.0) % 360.0 - 180.0
            if abs(diff) <= 20.0:
                return last.clock
        return clock_of(c.bearing_deg)

    def _metres(self, c: Candidate, last: _Said | None) -> float:
        m = c.spoken_m
        if last is not None and abs(m - last.metres) <= max(0.3, 0.15 * last.metres):
            return last.metres
        return m

    def _text(self, c: Candidate, clock: int, metres: float, approaching: bool) -> str:
        p = self.params
        if c.kind == "status":
            return GROUND_UNKNOWN_TEXT
        direction = say_direction(clock, c.bearing_deg, p.directions)
        if c.kind == "clear_path":
            return f"clear at {direction}" if p.directions == "clock" else f"clear {direction}"
        parts = [c.label, direction, say_distance(metres, p.units)]
        if approaching:
            parts.append("approaching")
        return ", ".join(parts)

    def select(self, candidates: list[Candidate], *, frame: str, time_s: float,
               alive: set[tuple[str, int | None]] | None = None) -> list[Event]:
        """The events of this frame, dangers first; what was said of keys neither among ``candidates`` nor in
        ``alive`` (tracks not seen in this frame but not ended) is forgotten."""
        p = self.params
        rank = {name: i for i, name in enumerate(PRIORITIES)}
        staged = []
        for c in candidates:
            last = self.said.get(c.key)
            prio = self.priority(c)
            clock, metres = self._clock(c, last), self._metres(c, last)
            approaching = c.approach_mps is not None and c.approach_mps > MIN_APPROACH and c.kind != "clear_path"
            changed = (last is None or clock != last.clock or metres != last.metres
                       or approaching != last.approaching or rank[prio] < rank[last.priority])
            due = prio == "danger" and last is not None and time_s - last.time_s >= p.repeat_after
            if changed or due:
                staged.append((rank[prio], c.spoken_m, c, prio, clock, metres, approaching))
        staged.sort(key=lambda s: (s[0], s[1]))
        events: list[Event] = []
        for _, _, c, prio, clock, metres, approaching in staged:
            if prio != "danger" and (events or time_s - self.last_time < p.min_interval):
                continue  # the rate limit: one message that is not a danger per min_interval
            events.append(Event(
                frame=frame, time_s=time_s, kind=c.kind, label=c.label, track_id=c.track_id,
                distance_m=c.distance_m if c.kind not in ("clear_path", "status") else None,
                nearest_m=c.nearest_m if c.kind != "status" else None,
                clock=clock, bearing_deg=c.bearing_deg, approach_mps=c.approach_mps, ttc_s=c.ttc_s, priority=prio,
                text=self._text(c, clock, metres, approaching),
                interrupt=prio == "danger" and not any(e.interrupt for e in events)))
            self.said[c.key] = _Said(clock, c.bearing_deg, metres, approaching, prio, time_s)
            self.last_time = time_s
        live = {c.key for c in candidates} | set(alive or ())
        for key in [k for k in self.said if k not in live]:
            del self.said[key]
        return events
