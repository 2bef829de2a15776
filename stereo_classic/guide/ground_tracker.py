"""The ground over frames: one estimate kept stable (see :mod:`stereo_classic.guide.ground` for one frame's fit).

Small changes are smoothed, a lasting change (the camera was re-mounted, a step up was reached) is adopted
after a few frames, a frame without a fit keeps the last plane, and a given ``--camera-height`` /
``--camera-pitch`` replaces the estimate.
"""

from __future__ import annotations

import numpy as np

from stereo_classic.guide.gravity import is_level
from stereo_classic.guide.ground import (
    RESTARTS,
    GroundPlane,
    PointSample,
    agree,
    fit_ground,
)
from stereo_classic.guide.params import HEIGHT_RANGE, GuideParams

__all__ = ["EDGE_MARGIN_M", "GroundTracker"]


#: Points within this distance (metres) of a known drop-off edge are not the walker's ground: the edge is the far
#: end of the ground seen (its 99th percentile, in 10 cm bins), and the depth noise there is a few centimetres.
EDGE_MARGIN_M = 0.2


class GroundTracker:
    """One ground estimate over frames (see the module docstring).

    Parameters
    ----------
    params : GuideParams
        ``camera_height`` / ``camera_pitch`` when given replace the estimate (both given: nothing is fitted).
    smoothing : float in (0, 1], weight of a new agreeing fit
    """

    def __init__(self, params: GuideParams, *, smoothing: float = 0.3, switch_after: int = 3) -> None:
        self.params = params
        self.smoothing = smoothing
        self.switch_after = switch_after
        self.plane: GroundPlane | None = None
        self._disagree = 0
        self._tilted = 0            # frames in a row whose measured up contradicts the current plane
        self._frame = 0
        self.switched = False       # whether the last update replaced the plane by a disagreeing one

    def reset(self) -> None:
        self.plane = None
        self._disagree = self._tilted = 0

    def _given(self, plane: GroundPlane | None) -> GroundPlane | None:
        h, p = self.params.camera_height, self.params.camera_pitch
        if h is not None and p is not None:
            return GroundPlane.from_mounting(h, p)
        if plane is None:
            return None
        up = GroundPlane.from_mounting(1.0, p).up if p is not None else plane.up
        height = h if h is not None else plane.height_m
        if not HEIGHT_RANGE[0] <= height <= HEIGHT_RANGE[1]:
            return None
        return GroundPlane(up, height, plane.source, plane.inliers)

    def update(self, points: PointSample, focal_baseline: float, *, before_m: float | None = None,
               gravity: np.ndarray | None = None) -> GroundPlane | None:
        """The ground of this frame (None until a first plane is known).

        ``gravity``: the up direction measured in this frame's image (a unit 3-vector,
        :func:`~stereo_classic.guide.gravity.estimate_gravity`), or None: a fitted plane must then be level
        (:func:`~stereo_classic.guide.ground.fit_ground`'s ``gravity``). A given ``camera_pitch`` wins over it.

        ``before_m``: a drop-off edge is known this far ahead (metres, along the current plane). The walker's
        ground then is what lies before it: only the points nearer than the edge (by ``EDGE_MARGIN_M``) are
        fitted: neither the level past the edge nor a plane between both levels is taken for it. A plane that
        disagrees with the current one is still adopted after ``switch_after`` frames (the near ground itself
        changed: a step up was reached); :attr:`switched` says so, since what was measured against the old plane
        (a drop-off) no longer holds.
        """
        self._frame += 1
        self.switched = False
        if self.params.camera_height is not None and self.params.camera_pitch is not None:
            self.plane = self._given(None)
            return self.plane
        prior = self.plane
        holding = before_m is not None and prior is not None
        if holding:
            near = prior.to_ground(points.xyz)[:, 1] < before_m - EDGE_MARGIN_M
            points = PointSample(points.uv[near], points.xyz[near], points.stride, points.focal_px,
                                 None if points.textured is None else points.textured[near])
        kw = {"rng": self._frame, "min_width": self.params.corridor_width}  # the walking corridor fits on it
        if self.params.camera_pitch is not None:   # the ground's up is known: search its offset only
            kw["up"] = GroundPlane.from_mounting(1.0, self.params.camera_pitch).up
        elif gravity is not None:                  # measured in the image: the ground must be level
            kw["gravity"] = gravity
        # Near the last plane one search is enough: the prior leaves one surface to find, and a lasting change is
        # adopted only after ``switch_after`` agreeing frames. Without one, several searches must agree.
        fit = fit_ground(points, focal_baseline, prior=prior, restarts=1 if prior is not None else RESTARTS, **kw)
        if fit is None and prior is not None:
            fit = fit_ground(points, focal_baseline, prior=None, **kw)   # moved a lot
        fit = self._given(fit)
        # the measured up says the current plane is not level ground (stairs or a ramp taken for the floor
        # before the image showed which way is up)
        tilted = "gravity" in kw and prior is not None and not is_level(prior.up, gravity)   # (fit_ground checked it)
        self._tilted = self._tilted + 1 if tilted else 0
        if fit is None:
            if self.plane is not None:
                # kept, until the measured up has contradicted it for ``switch_after`` frames in a row
                kept = self._tilted < self.switch_after
                self.plane = GroundPlane(self.plane.up, self.plane.height_m, "kept", 0) if kept else None
                if not kept:
                    self._tilted = self._disagree = 0
            return self.plane
        old = self.plane
        if old is None:
            self.plane = fit
            return fit
        if agree(old, fit):
            self._disagree = 0
            a = self.smoothing
            up = (1 - a) * old.up + a * fit.up
            self.plane = GroundPlane(up, (1 - a) * old.height_m + a * fit.height_m, "fitted", fit.inliers)
        else:
            self._disagree += 1
            if self._disagree >= self.switch_after or tilted:   # a level plane against a tilted one: at once
                self._disagree = 0
                self.plane = fit
                self.switched = True
            else:
                self.plane = GroundPlane(old.up, old.height_m, "kept", 0)
        return self.plane
