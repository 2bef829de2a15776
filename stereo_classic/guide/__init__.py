"""The guide: what is ahead of a walking person (or a robot), over time, from the pipeline's results.

Feed :class:`Guide` each frame's :class:`~stereo_classic.pipeline.PipelineResult` with its time; it fits the
ground, finds obstacles without a class and drop-offs in the walking corridor, tracks objects and obstacles
(approach speed, time to contact), finds the clear path and chooses the messages (:class:`Event`). The
``guide`` command (``python -m stereo_classic guide``) writes them to ``events.jsonl``, speaks them
(:mod:`~stereo_classic.guide.speech`) and draws them (:mod:`~stereo_classic.guide.render`). See docs/guide.md.
"""

from stereo_classic.guide.core import Guide, GuideFrame, TrackView
from stereo_classic.guide.dropoff import DropOff, find_dropoff
from stereo_classic.guide.gravity import Gravity, estimate_gravity
from stereo_classic.guide.ground import (
    GroundPlane,
    PointSample,
    fit_ground,
    sample_points,
)
from stereo_classic.guide.ground_tracker import GroundTracker
from stereo_classic.guide.messages import (
    KINDS,
    PRIORITIES,
    Candidate,
    Event,
    MessagePolicy,
)
from stereo_classic.guide.obstacles import (
    Obstacle,
    OccupancyGrid,
    clock_of,
    find_obstacles,
    free_distances,
)
from stereo_classic.guide.params import DIRECTIONS, UNITS, GuideInputError, GuideParams
from stereo_classic.guide.tracking import Measurement, Track, Tracker

__all__ = [
    "DIRECTIONS",
    "KINDS",
    "PRIORITIES",
    "UNITS",
    "Candidate",
    "DropOff",
    "Event",
    "Gravity",
    "GroundPlane",
    "GroundTracker",
    "Guide",
    "GuideFrame",
    "GuideInputError",
    "GuideParams",
    "Measurement",
    "MessagePolicy",
    "Obstacle",
    "OccupancyGrid",
    "PointSample",
    "Track",
    "TrackView",
    "Tracker",
    "clock_of",
    "estimate_gravity",
    "find_dropoff",
    "find_obstacles",
    "fit_ground",
    "free_distances",
    "sample_points",
]
