"""Parameters of the fusion stage: one frozen, self-checking dataclass, and the one check of ``rng``.

``FusionParams`` is the single home of the fusion defaults; :func:`~stereo_classic.fusion.localize`
takes one (or its field names as keywords), and the CLI flags, the config file and the docs are
generated from its fields (``dataclasses.fields(FusionParams)[i].metadata`` holds the flag's help text).

>>> from stereo_classic.fusion import FusionParams
>>> params = FusionParams(box_shrink=0.1)
>>> params.box_shrink, params.depth_range
(0.1, (0.3, 80.0))
>>> params.replace(method="median").to_dict()["method"]
'median'
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = [
    "FusionParams",
    "FusionInputError",
    "METHODS",
    "as_generator",
    "check_count",
    "check_positive_float",
]

#: The distance estimators ``FusionParams.method`` can name.
METHODS: tuple[str, ...] = ("ransac", "median")


class FusionInputError(ValueError):
    """Bad input to :func:`localize` (shapes, parameters, boxes); the message names the parameter."""


def as_generator(rng: Any, *, name: str = "rng") -> np.random.Generator:
    """The random generator for ``rng``: the one check of the fusion's seed argument.

    Parameters
    ----------
    rng : None, int >= 0 or numpy.random.Generator
        ``None`` means seed 0 (reproducible by default); an int is a seed; a Generator is used as is.
    name : str
        The caller's name of the argument, for the message (``Localizer`` calls it ``seed``).

    Returns
    -------
    numpy.random.Generator

    Raises
    ------
    FusionInputError (ValueError)
        Anything else (a negative int, a bool, a string, ...); the message names ``name``.

    Examples
    --------
    >>> int(as_generator(None).integers(1000)) == int(as_generator(0).integers(1000))
    True
    """
    if rng is None:
        return np.random.default_rng(0)
    if isinstance(rng, np.random.Generator):
        return rng
    if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool) and int(rng) >= 0:
        return np.random.default_rng(int(rng))
    raise FusionInputError(f"`{name}` must be None, a non-negative int seed or a numpy Generator, got {rng!r}")


def check_count(name: str, value: Any) -> int:
    """``value`` as an int >= 1 (not a bool), else FusionInputError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise FusionInputError(f"`{name}` must be an int >= 1, got {value!r}")
    return int(value)


def check_positive_float(name: str, value: Any) -> float:
    """``value`` as a positive finite float, else FusionInputError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not (
            math.isfinite(float(value)) and float(value) > 0):
        raise FusionInputError(f"`{name}` must be a positive finite number, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class FusionParams:
    """Everything that decides how the depths inside a box become one distance, checked when built.

    Attributes
    ----------
    method : {"ransac", "median"}
        "ransac": the consistent set described in :mod:`stereo_classic.fusion.localize`. "median": the
        per-coordinate median of all valid points (for comparison; it is pulled towards the background).
    box_shrink : float in [0, 1)
        Fraction of the box width and height removed before sampling, half on each side (0.2 keeps the
        central 80 % x 80 %), so that the box edges, where the background shows, are left out.
    depth_range : (near, far) float, metres, 0 <= near < far
        Depths outside are ignored; if fewer than ``min_pixels`` remain the status is "out_of_range".
    min_pixels : int >= 1
        Fewest valid depth pixels (and fewest inliers) for a measurement.
    tolerance_px : float > 0, disparity pixels
        Half width of the inlier band (a depth band of ``Z**2 / (f B)`` per pixel).
    near_support : float in (0, 1]
        A nearer consistent set wins over the heaviest one when it has at least this fraction of the
        heaviest set's (weighted) support (1.0: strictly the heaviest set, ties to the nearer).
    centre_sigma : float >= 0, fraction of the box
        Each pixel's vote is weighted by a Gaussian centred on the box with this standard deviation as a
        fraction of the (shrunk) box width and height: detectors centre the box on the object, while the
        background and occluders enter from the box edges. 0: every pixel counts the same.
    grow_density : float in [0, 1]
        After RANSAC, the set grows over neighbouring disparities, in steps of ``tolerance_px``, while each
        step holds at least this fraction of the band's density (the object's depths are continuous, a
        slanted surface such as a car's side is one object); a sparse step (a gap) stops it. 0: no growth,
        the paper's plain consistent set.
    max_clusters : int >= 1
        How many consistent sets sequential RANSAC extracts per box.
    max_iterations : int >= 1
        Hypotheses per RANSAC round (all values when there are fewer).
    max_samples : int >= 1
        Boxes with more valid pixels find their consistent sets on a random sample of this many (drawn
        with the ``rng`` of :func:`localize`); every pixel inside the chosen set's disparity band then
        counts (speed: a box covering a 1-megapixel image costs the same as a 10 000-pixel one).
    occluder_ratio : float >= 1
        A nearer set that wins only through ``near_support`` is an occluder when the heaviest set is at least
        this many times farther (a hand at 0.48 m in front of a chair at 1.62 m: 3.4) ...
    occluder_offset : float in (0, 0.5]
        ... and the nearer set's pixels are centred at least this fraction of the (shrunk) box's width or
        height off the box centre, further off than the heaviest set's: detectors centre the box on the object,
        occluders enter from its edges (the hand: 0.30 of the height below the centre, the chair 0.20 above).
        Then the heaviest set (the one covering the object) gives the distance and the object is flagged
        ``occluded``. 0.5 turns the rule off.
    ground_contact : bool
        For objects that stand on the ground (``GROUND_CLASSES``: persons, cars, ...), a second, independent
        estimate from where the box's bottom meets the road (the road's disparity just below the box, extrapolated
        to the box's bottom row). Where it and the consistent set differ by more than three combined standard
        uncertainties the status is "estimates_disagree" (no distance: which one is right cannot be told).
        Also, such an object reaches its box's bottom: a chosen set that stays in the box's upper three quarters
        gives way to a nearer set, centred across the box, that reaches the bottom (the background behind a box
        placed too high is not the object). False: the consistent set alone, as before issue 31.

    Raises
    ------
    FusionInputError (ValueError)
        The first bad field; the message names it in backticks.

    Examples
    --------
    >>> FusionParams(depth_range=[1, 20]).depth_range
    (1.0, 20.0)
    >>> FusionParams(min_pixels=0)
    Traceback (most recent call last):
    ...
    stereo_classic.fusion.params.FusionInputError: `min_pixels` must be an int >= 1, got 0
    """

    method: str = field(default="ransac", metadata={
        "help": "distance per box", "metavar": None, "choices": METHODS})
    box_shrink: float = field(default=0.2, metadata={
        "help": "fraction of box width/height left out at the edges", "metavar": "F"})
    depth_range: tuple[float, float] = field(default=(0.3, 80.0), metadata={
        "help": "metres", "metavar": ("NEAR", "FAR"), "nargs": 2})
    min_pixels: int = field(default=20, metadata={
        "help": "fewest depth pixels per box", "metavar": "N"})
    tolerance_px: float = field(default=1.0, metadata={
        "help": "RANSAC inlier band in disparity px", "metavar": "PX"})
    near_support: float = field(default=0.5, metadata={
        "help": "a nearer set wins at this fraction of the largest one's support", "metavar": "F"})
    centre_sigma: float = field(default=0.25, metadata={
        "help": "centre weighting of votes, fraction of the box", "metavar": "F"})
    grow_density: float = field(default=0.1, metadata={
        "help": "grow the set over continuous depths", "metavar": "F"})
    max_clusters: int = 3
    max_iterations: int = 256
    max_samples: int = 10000
    occluder_ratio: float = field(default=1.5, metadata={
        "help": "a nearer off-centre set this many times nearer than the largest is an occluder", "metavar": "R"})
    occluder_offset: float = field(default=0.25, metadata={
        "help": "off-centre fraction of the box that makes a nearer set an occluder (0.5: never)", "metavar": "F"})
    ground_contact: bool = field(default=True, metadata={
        "help": "check each person's or vehicle's distance against where its box meets the road; "
                "--no-ground-contact: the consistent set alone", "metavar": None})

    def __post_init__(self) -> None:
        def set_(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        if self.method not in METHODS:
            raise FusionInputError(f"`method` must be one of {METHODS}, got {self.method!r}")
        try:
            box_shrink = float(self.box_shrink)
            tolerance_px = float(self.tolerance_px)
            near_support = float(self.near_support)
            centre_sigma = float(self.centre_sigma)
            grow_density = float(self.grow_density)
            occluder_ratio = float(self.occluder_ratio)
            occluder_offset = float(self.occluder_offset)
        except (TypeError, ValueError):
            raise FusionInputError("`box_shrink`, `tolerance_px`, `near_support`, `centre_sigma`, `grow_density`, "
                                   "`occluder_ratio` and `occluder_offset` must be numbers") from None
        if not (0.0 <= box_shrink < 1.0):
            raise FusionInputError(f"`box_shrink` must be in [0, 1), got {box_shrink!r}")
        if not (math.isfinite(tolerance_px) and tolerance_px > 0):
            raise FusionInputError(f"`tolerance_px` must be a positive finite number, got {tolerance_px!r}")
        if not (0.0 < near_support <= 1.0):
            raise FusionInputError(f"`near_support` must be in (0, 1], got {near_support!r}")
        if not (math.isfinite(centre_sigma) and centre_sigma >= 0):
            raise FusionInputError(f"`centre_sigma` must be >= 0 (0 = uniform weights), got {centre_sigma!r}")
        if not (math.isfinite(grow_density) and 0 <= grow_density <= 1):
            raise FusionInputError(f"`grow_density` must be in [0, 1] (0 = no growth), got {grow_density!r}")
        if not (math.isfinite(occluder_ratio) and occluder_ratio >= 1):
            raise FusionInputError(f"`occluder_ratio` must be a finite number >= 1, got {occluder_ratio!r}")
        if not (0 < occluder_offset <= 0.5):
            raise FusionInputError(f"`occluder_offset` must be in (0, 0.5] (0.5 = never), got {occluder_offset!r}")
        try:
            near, far = (float(v) for v in self.depth_range)
        except (TypeError, ValueError):
            raise FusionInputError(
                f"`depth_range` must be two numbers (near, far) in metres, got {self.depth_range!r}") from None
        if not (math.isfinite(near) and math.isfinite(far) and 0.0 <= near < far):
            raise FusionInputError(
                f"`depth_range` must satisfy 0 <= near < far (finite metres), got {self.depth_range!r}")
        if not isinstance(self.ground_contact, (bool, np.bool_)):
            raise FusionInputError(f"`ground_contact` must be True or False, got {self.ground_contact!r}")
        set_("ground_contact", bool(self.ground_contact))
        counts = {name: check_count(name, getattr(self, name))
                  for name in ("min_pixels", "max_clusters", "max_iterations", "max_samples")}
        set_("box_shrink", box_shrink)
        set_("depth_range", (near, far))
        set_("tolerance_px", tolerance_px)
        set_("near_support", near_support)
        set_("centre_sigma", centre_sigma)
        set_("grow_density", grow_density)
        set_("occluder_ratio", occluder_ratio)
        set_("occluder_offset", occluder_offset)
        for name, value in counts.items():
            set_(name, value)

    def replace(self, **overrides: Any) -> FusionParams:
        """A copy with some fields changed (checked again).

        Raises
        ------
        FusionInputError (ValueError)
            An unknown name (the message names it and lists the valid ones) or a bad value.
        """
        names = [f.name for f in dataclasses.fields(self)]
        unknown = sorted(set(overrides) - set(names))
        if unknown:
            raise FusionInputError(f"unknown fusion parameter(s) {', '.join(map(repr, unknown))}; "
                                   f"expected some of: {', '.join(names)}")
        return dataclasses.replace(self, **overrides)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-friendly dict of the fields (``depth_range`` as a ``[near, far]`` list)."""
        out = dataclasses.asdict(self)
        out["depth_range"] = list(self.depth_range)
        return out

