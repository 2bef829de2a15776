"""Parameters of the guide: one frozen, self-checking dataclass (``GuideParams``) and its error class.

The command-line flags of ``python -m stereo_classic guide`` are generated from the fields' metadata
(:mod:`stereo_classic.cli.options`), so every default is written once, here. Why each default is what it
is: ``docs/guide.md``.

>>> from stereo_classic.guide import GuideParams
>>> p = GuideParams(corridor_width=0.8)
>>> p.corridor_width, p.head_height, p.units
(0.8, 2.0, 'metres')
>>> GuideParams(camera_height=40)
Traceback (most recent call last):
...
stereo_classic.guide.params.GuideInputError: `camera_height` must be between 0.1 and 5.0 metres (a camera worn or \
mounted on a person or a small robot), got 40.0
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass, field
from typing import Any

__all__ = ["DIRECTIONS", "ESTIMATED_HEIGHT_RANGE", "HEIGHT_RANGE", "UNITS", "GuideInputError", "GuideParams"]

#: Values of ``GuideParams.units``.
UNITS: tuple[str, ...] = ("metres", "feet")
#: Values of ``GuideParams.directions``: clock hours ("2 o'clock") or words ("slightly left").
DIRECTIONS: tuple[str, ...] = ("clock", "leftright")
#: Plausible camera heights above the ground, metres (a given or estimated height outside is refused).
HEIGHT_RANGE: tuple[float, float] = (0.1, 5.0)
#: Camera heights above the ground that an *estimated* ground may give, metres: a camera held, worn or mounted
#: on a walking person (hand, chest, head: up to the head of a tall person) or held low near the floor. A plane
#: that gives another height is not taken for the ground (a higher mounting is given with ``camera_height``).
ESTIMATED_HEIGHT_RANGE: tuple[float, float] = (0.3, 2.0)


class GuideInputError(ValueError):
    """Bad input to the guide (parameters, timestamps, results); the message names the parameter."""


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)):
        raise GuideInputError(f"`{name}` must be a finite number, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class GuideParams:
    """Everything that decides what the guide reports and when, checked when built.

    Attributes
    ----------
    camera_height : float or None, metres
        Height of the left camera's centre above the ground; None: estimated from the ground plane.
    camera_pitch : float or None, degrees
        Downward tilt of the optical axis (positive = looking down); None: estimated.
    head_height : float, metres
        Points up to this height above the ground are obstacles (a branch at head height counts).
    min_height : float, metres
        Points lower than this above the ground are ground (stereo noise, kerbs to step over).
    corridor_width : float, metres
        Width of the walking corridor straight ahead in which obstacles and drop-offs are reported.
    look_ahead : float, metres
        How far ahead obstacles, drop-offs and the free distance of the clear path are measured.
    step_height : float, metres
        The ground falling away by more than this is a drop-off (a kerb or a stair step down).
    danger_distance, warning_distance : float, metres
        Things in the corridor nearer than these are "danger" / "warning" (else "info").
    danger_ttc : float, seconds
        An approaching thing reached sooner than this is "danger".
    units : {"metres", "feet"}
    directions : {"clock", "leftright"}
    min_interval : float, seconds
        Fewest seconds between two spoken messages that are not dangers (dangers interrupt at any time).
    repeat_after : float, seconds
        An unchanged danger is said again after this long; unchanged warnings and infos are not repeated.
    track_window : float, seconds
        Distances of a track within this window are fitted by a line: its value now is the smoothed distance,
        its slope the approach speed.
    max_gap : float, seconds
        A pause between frames longer than this (a camera that stopped) ends every track.
    sectors : int
        Number of haptic sectors across the field of view.
    vertical_lines : bool
        Measure which way is up from the image's vertical lines (door frames, poles, balusters) when
        ``camera_pitch`` is not given, and take only a level plane for the ground
        (:mod:`~stereo_classic.guide.gravity`); False: the prior of a carried camera alone.
    """

    camera_height: float | None = field(default=None, metadata={
        "help": "camera height above the ground in metres (default: estimated)", "metavar": "M"})
    camera_pitch: float | None = field(default=None, metadata={
        "help": "camera tilt in degrees, positive = looking down (default: estimated)", "metavar": "DEG"})
    head_height: float = field(default=2.0, metadata={
        "help": "obstacles up to this height above the ground, metres", "metavar": "M"})
    min_height: float = field(default=0.1, metadata={
        "help": "lower points are ground, metres", "metavar": "M"})
    corridor_width: float = field(default=1.0, metadata={
        "help": "width of the walking corridor, metres", "metavar": "M"})
    look_ahead: float = field(default=5.0, metadata={
        "help": "distance watched ahead, metres", "metavar": "M"})
    step_height: float = field(default=0.15, metadata={
        "help": "a drop of the ground by more than this is a drop-off, metres", "metavar": "M"})
    danger_distance: float = field(default=1.0, metadata={
        "help": "nearer things in the corridor are dangers, metres", "metavar": "M"})
    warning_distance: float = field(default=2.5, metadata={
        "help": "nearer things in the corridor are warnings, metres", "metavar": "M"})
    danger_ttc: float = field(default=2.0, metadata={
        "help": "things reached sooner are dangers, seconds", "metavar": "S"})
    units: str = field(default="metres", metadata={"help": "spoken units", "metavar": None, "choices": UNITS})
    directions: str = field(default="clock", metadata={
        "help": "clock hours or left/right words", "metavar": None, "choices": DIRECTIONS})
    min_interval: float = field(default=3.0, metadata={
        "help": "fewest seconds between messages that are not dangers", "metavar": "S"})
    repeat_after: float = 4.0
    track_window: float = 1.0
    max_gap: float = 1.0
    sectors: int = 5
    vertical_lines: bool = field(default=True, metadata={
        "help": "do not measure which way is up from the image's vertical lines (door frames, poles) when "
                "--camera-pitch is not given: the ground may then be any plane a carried camera could stand on"})

    def __post_init__(self) -> None:
        def set_(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        lo, hi = HEIGHT_RANGE
        if self.camera_height is not None:
            h = _number("camera_height", self.camera_height)
            if not lo <= h <= hi:
                raise GuideInputError(f"`camera_height` must be between {lo} and {hi} metres (a camera worn or "
                                      f"mounted on a person or a small robot), got {h}")
            set_("camera_height", h)
        if self.camera_pitch is not None:
            p = _number("camera_pitch", self.camera_pitch)
            if not -60.0 <= p <= 80.0:
                raise GuideInputError(f"`camera_pitch` must be between -60 and 80 degrees (positive = looking "
                                      f"down), got {p}")
            set_("camera_pitch", p)
        for name in ("head_height", "min_height", "corridor_width", "look_ahead", "step_height", "danger_distance",
                     "warning_distance", "danger_ttc", "min_interval", "repeat_after", "track_window", "max_gap"):
            value = _number(name, getattr(self, name))
            if value <= 0:
                raise GuideInputError(f"`{name}` must be > 0, got {value}")
            set_(name, value)
        if self.min_height >= self.head_height:
            raise GuideInputError(f"`min_height` must be below `head_height`, got {self.min_height} and "
                                  f"{self.head_height}")
        if self.danger_distance > self.warning_distance:
            raise GuideInputError(f"`danger_distance` must not exceed `warning_distance`, got {self.danger_distance} "
                                  f"and {self.warning_distance}")
        if self.look_ahead > 30:
            raise GuideInputError(f"`look_ahead` must be at most 30 metres (stereo depth is too coarse further), "
                                  f"got {self.look_ahead}")
        if self.units not in UNITS:
            raise GuideInputError(f"`units` must be one of {UNITS}, got {self.units!r}")
        if self.directions not in DIRECTIONS:
            raise GuideInputError(f"`directions` must be one of {DIRECTIONS}, got {self.directions!r}")
        if isinstance(self.sectors, bool) or not isinstance(self.sectors, int) or not 1 <= self.sectors <= 24:
            raise GuideInputError(f"`sectors` must be an int from 1 to 24, got {self.sectors!r}")
        if not isinstance(self.vertical_lines, bool):
            raise GuideInputError(f"`vertical_lines` must be True or False, got {self.vertical_lines!r}")

    def replace(self, **overrides: Any) -> GuideParams:
        """A copy with some fields changed (checked again); an unknown name raises GuideInputError."""
        names = [f.name for f in dataclasses.fields(self)]
        unknown = sorted(set(overrides) - set(names))
        if unknown:
            raise GuideInputError(f"unknown guide parameter(s) {', '.join(map(repr, unknown))}; "
                                  f"expected some of: {', '.join(names)}")
        return dataclasses.replace(self, **overrides)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-friendly dict of the fields."""
        return dataclasses.asdict(self)
