"""Checks of one frame's disparity that catch confident wrong numbers: disparities piling up at the end of the
search range (an object nearer than the range reaches) and a left/right swapped or mismatched pair.

Both checks read one cheap second look at the pair, made once a frame at half resolution (a quarter of the
pixels) with fixed settings (census, 1 px left-right check, no hole filling, whatever the caller's), over
disparities from minus the mirror of the range (what the images have when they are swapped) to twice the
full-size reach (what an object nearer than the range has):

* **Range.** A pixel whose true disparity is beyond ``params.max_disparity`` has no correct candidate; its
  cost keeps falling towards the end of the range, so such pixels pile up in the last pixel of disparity.
  Measured on every shared scene at the range ``run`` picks, at most 0.2 % of the valid pixels lie within
  1 px of the end; a near object beyond the range puts 1.4 to 4 % there (KITTI pair at 64 or 128, OAK-D hands,
  selfie and controllers at 64). :data:`SATURATION_WARN` is 0.5 %: at 640x480 about 1 500 pixels, an object's
  worth, two and a half times the largest share seen on a scene that fits. A box is suspect when
  :data:`BOX_SATURATION` (5 %) of its known pixels are at the end, or fewer than :data:`BOX_SPARSE` (60 %) of
  its pixels are known (a fine texture beyond the range matches the wall behind rather than pile up; a
  hole-filled map hides this). The half-size look reaches twice as far: the frame's warning says which range
  would fit, and each object whose disparity there lies more than 2 px (the look's own step) beyond the
  full-size range gets the status ``"beyond_range"`` instead of a distance (what it had was the best of wrong
  candidates).
* **Pair.** Swapped images have negative disparities (the right image's content lies right of the left one's),
  which the frame's search does not cover; the look covers both signs, so the two orders compete for every
  pixel in one aggregation. Its shares: the pixels that match left-right consistently at disparities only the
  given order can have (at least 1 px, and beyond the mirror of a negative ``min_disparity``), and those at
  disparities only the exchanged order can have (the negatives of those). On every shared scene the given
  order's share is 42 to 95 % and the other's at most 1 %; swapped, the other way round (44 to 93 % against at
  most 1 %; stairs 42 % as given, 44 % swapped); two unrelated OAK-D images at most 3 % either way
  (``python -m benchmarks.pair_check``). The pair is called swapped when the exchanged order's share is
  :data:`SWAP_MARGIN` (3 points) larger and at least :data:`MISMATCH_VALID` (30 %), and mismatched when neither
  order is preferred by more than that or neither keeps 30 % of the pixels. A right image shifted by 15 rows keeps
  12 to 39 % (9 of the 12 OAK-D pairs are called mismatched, 3 pass): a vertical offset is what the rectification
  check of ``RectifiedRig.rectify_pair`` measures. Every object of a swapped or mismatched frame gets the status
  ``"pair_mismatch"``. The check runs on every frame, so that a frame's result never depends on the frames
  before it; ``Localizer(checks=False)`` turns the checks off.
* **Cheap on good frames.** The pair check reads the frame's own match first: with :data:`PAIR_CLEAR` (half) of
  all pixels measured, consistent within 1 px, at disparities only the given order can have, the pair is taken
  as given and the look is not made for it (swapped or unrelated pairs reach at most 27 % there; see the
  constant). The range check looks only when its signals are raised, and after a cleared pair its look covers
  the given order's side and the suspect part of the frame only (:meth:`FrameChecker._window`). A good frame
  then costs the shares and histograms of the main match: 1.5 ms CPU on a 640x480 OAK-D frame and 1.8 ms on a
  1242x375 KITTI frame at 144 disparities, against 12 and 27 ms with the look (docs/robustness.md).

The one look replaced three (each order at half the range for the pair check, the given order at twice the reach
for the range check): the kernels' time per pixel depends little on the number of disparities, and in one
aggregation the two orders compete for each pixel, so a real pair prefers its order by 42 points or more instead
of 16 (stairs: 42 % against 0 %, then 47 % against 31 %). Measured with the default detector at 2 threads (the
``checks`` stage of ``benchmarks.objects.pipeline_fps``, median of 9 frames, alternated twice with the three
looks): the KITTI pair at 128 disparities (its near car is beyond the range, so both checks look) 40.7 / 41.3 ->
28.9 / 28.1 ms; selfie (640x480 at 64, its hand beyond the range) 38.8 / 33.0 -> 25.9 / 29.5 ms.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import cv2
import numpy as np

from stereo_classic.fusion import FusionParams, LocalizedObjects, localize
from stereo_classic.fusion.boxes import shrunk_pixel_box
from stereo_classic.fusion.range_hint import PILE_SHARE, range_saturation
from stereo_classic.matching import DisparityMap, SGMParams, StereoMatcher, load_kernels

__all__ = [
    "BOX_SATURATION",
    "BOX_SPARSE",
    "MIN_CHECK_HEIGHT",
    "MIN_CHECK_WIDTH",
    "MISMATCH_VALID",
    "PAIR_CLEAR",
    "SATURATION_WARN",
    "SWAP_MARGIN",
    "FrameChecker",
    "FrameWarning",
    "range_saturation",
]

#: Fraction of the valid pixels within 1 px of the end of the range above which the frame is warned about.
SATURATION_WARN = 0.005
#: Fraction of a box's known pixels within 1 px of the end of the range that makes it suspect.
BOX_SATURATION = PILE_SHARE  # the same share as a bare localize() call warns at (fusion.range_hint)
#: A box with fewer known pixels than this fraction is suspect too: an object beyond the range can also give
#: mostly inconsistent matches instead of a pile at the end (a fine texture: its pixels match the wall behind).
BOX_SPARSE = 0.6
#: How much larger (absolute fraction of pixels) the reverse order's valid fraction must be to call a pair swapped.
SWAP_MARGIN = 0.03
#: Below this valid fraction (half size) in both orders the images are not a rectified pair.
MISMATCH_VALID = 0.30
#: Share of all pixels of the frame's own match that, left-right consistent within 1 px and measured (not filled),
#: lie at disparities only the given order can have, from which the pair is taken as given without the half-size
#: look: a majority of the image explained by the given order. Swapped, the true disparities are outside the
#: search, and a pixel is consistent at a positive disparity only where the texture repeats at that offset both
#: ways; measured with the default matcher at the range ``run`` picks (``python -m benchmarks.pair_check``): real
#: pairs 35 to 94 %, swapped at most 27 % (Cloth1's repeating weave), unrelated images at most 8 %, a right image
#: 15 rows down at most 40 %. Below it (stairs 35 %, corridor 46 %, pov_hands 50 %) the look decides as before.
PAIR_CLEAR = 0.5
#: Rows (full size) added above and below the part of a cleared frame that the range check's look reads: the
#: look's paths get this much context beyond the suspect boxes (its census window and penalties act within a few
#: pixels; 32 rows are 16 at half size, where a path's memory of a wrong start has faded).
WINDOW_MARGIN = 32
#: The pair check needs half-size images at least this wide (and 32 columns wider than the disparities) and this
#: high: at 80x60 (an OAK-D frame at --scale 0.25) nearly every match is consistent in both orders.
MIN_CHECK_WIDTH, MIN_CHECK_HEIGHT = 128, 64


class FrameWarning(NamedTuple):
    """Something wrong with a frame that is not an error: ``code`` ("range_saturated", "swapped_pair",
    "pair_mismatch") and a sentence for a person."""

    code: str
    message: str

    def to_json(self) -> dict[str, str]:
        return {"code": self.code, "message": self.message}


def _half(image: np.ndarray) -> np.ndarray:
    h, w = image.shape[:2]
    return cv2.resize(image, (max(1, w // 2), max(1, h // 2)), interpolation=cv2.INTER_AREA)


class _Halves:
    """The half-size left and right images of one frame, each made once, and the frame's look at them, made once
    when a check first needs it: the pair check and the range check share both."""

    def __init__(self, left: np.ndarray, right: np.ndarray) -> None:
        self._full = (left, right)
        self._half: dict[int, np.ndarray] = {}
        self.look: DisparityMap | None = None
        self.looked = False
        self.cleared = False  # the pair check passed the pair on the frame's own match: no negative side needed
        self.window: tuple[int, int, int, int] | None = None  # (u0, v0, u1, v1) at half size: the look's crop

    def get(self, side: int) -> np.ndarray:
        """0: the left image at half size, 1: the right one."""
        if side not in self._half:
            self._half[side] = _half(self._full[side])
        return self._half[side]


def _fit_range(needed: float) -> int:
    """The smallest multiple of 16 disparities that holds ``needed`` px with a 1 px margin."""
    return int(16 * math.ceil((needed + 2) / 16))


class FrameChecker:
    """The range and pair checks of :class:`stereo_classic.Localizer`, with the state a stream needs.

    Parameters
    ----------
    params : SGMParams
        The matcher's parameters (the half-size look uses the same ones).
    """

    def __init__(self, params: SGMParams) -> None:
        self.params = params
        self._matcher: StereoMatcher | None = None
        self._range_matcher: StereoMatcher | None = None

    def halves(self, left: np.ndarray, right: np.ndarray) -> _Halves:
        """The half-size images of one frame, for its checks to share (pass it to each check of that frame)."""
        return _Halves(left, right)

    def look_range(self) -> tuple[int, int]:
        """(min_disparity, num_disparities) of the half-size look: from minus the mirror of the full range's end
        (half of it, rounded up to 16) up to the full range's start at half size plus ``num_disparities`` (twice
        the reach)."""
        p = self.params
        start = math.floor(p.min_disparity / 2)
        mirror = 16 * math.ceil((p.max_disparity + 1) / 32)
        low = min(start, -mirror)
        return low, start + p.num_disparities - low

    def look_params(self, cleared: bool) -> SGMParams:
        """The half-size look's matcher settings: over :meth:`look_range` or, after a cleared pair (``cleared``),
        from the range's start at half size over ``num_disparities`` (see :meth:`_look`)."""
        low, num = self.look_range()
        if cleared:
            low, num = math.floor(self.params.min_disparity / 2), self.params.num_disparities
        return self.params.replace(
            min_disparity=low, num_disparities=num, cost="census", p1=None, p2=None, weak_texture_gain=1.0,
            lr_check=1.0, lr_mode="full", fill_holes=False, median_filter=False)

    def load_kernels(self) -> None:
        """Load the looks' compiled kernels now (:func:`stereo_classic.matching.load_kernels`): their ranges differ
        from the frame's, and the kernels are compiled per range, so a stream's first look would otherwise wait for
        them."""
        for cleared in (True, False):
            try:
                load_kernels(self.look_params(cleared))
            except ValueError:  # a range the look cannot take: each frame's look says so, as before
                pass

    def _look(self, halves: _Halves, window: tuple[int, int, int, int] | None = None) -> DisparityMap | None:
        """The frame's half-size look (made once, kept on ``halves``), or None when the half-size images are too
        small for its range. Fixed settings, whatever the caller's (census cost with its default penalties, the
        full 1 px left-right check, no hole filling, no median): every disparity a measured, left-right consistent
        one, as the checks' shares and thresholds were measured.
        When the pair check cleared the pair on the frame's own match (``halves.cleared``) the look covers the
        given order's side only (from the range's start at half size, twice the reach): the range check reads
        nothing else, and a third fewer disparities cost a third less. ``window`` (u0, v0, u1, v1, full-size
        pixels): only that part of the frame is read (with a cleared pair; see :meth:`_window`)."""
        if halves.looked:
            return halves.look
        halves.looked = True
        try:
            matcher = self._range_matcher if halves.cleared else self._matcher
            if matcher is None:
                matcher = StereoMatcher(self.look_params(halves.cleared))
                if halves.cleared:
                    self._range_matcher = matcher
                else:
                    self._matcher = matcher
            if halves.cleared and window is not None:  # only the window is resized and matched
                full_h, full_w = halves._full[0].shape[:2]
                u0, v0 = max(0, window[0] // 2), max(0, window[1] // 2)
                u1, v1 = min(full_w // 2, -(-window[2] // 2)), min(full_h // 2, -(-window[3] // 2))
                halves.window = (u0, v0, u1, v1)
                left, right = (_half(img[2 * v0:2 * v1, 2 * u0:2 * u1]) for img in halves._full)
            else:
                left, right = halves.get(0), halves.get(1)
            halves.look = matcher.compute(left, right)
        except ValueError:  # StereoInputError, MemoryBudgetError: the images are too small for the range
            halves.look = None
        return halves.look

    def given_share(self, dmap: DisparityMap) -> float | None:
        """Fraction of all pixels of ``dmap`` (the frame's own match) measured at disparities only the given order
        can have (the full-size equivalent of :meth:`order_shares`' threshold), or None when ``dmap`` was not made
        with the full 1 px left-right check (its pixels need not be consistent, so the share proves nothing)."""
        p = dmap.params
        if p.lr_check is None or p.lr_check > 1.0 or p.lr_mode != "full":
            return None
        d = dmap.measured_disparity
        with np.errstate(invalid="ignore"):
            return int(np.count_nonzero(d >= 2.0 * self._order_threshold())) / max(1, d.size)

    def _order_threshold(self) -> float:
        """Half-size disparity from which only the given order has pixels: 1 px, beyond the mirror of a negative
        ``min_disparity``."""
        return 1.0 + max(0.0, -self.params.min_disparity / 2.0)

    def _reach(self, look: DisparityMap, w: int, h: int,
               window: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """The look as a full-size disparity map of the given order (``w`` x ``h``, pixels at full scale). Unknown:
        the pixels it matched below the range's start at half size (the exchanged order's side), and the left
        border's columns that reach less than ``border_reach`` of the given order's ``num_disparities`` (the
        look's own border rule counts its negative side too)."""
        p = self.params
        start = math.floor(p.min_disparity / 2)
        d = look.disparity.copy()
        if window is not None:  # a cropped look: unknown outside its window
            u0, v0, u1, v1 = window
            d = np.full((max(h // 2, v1), max(w // 2, u1)), np.nan, np.float32)
            d[v0:v1, u0:u1] = look.disparity
        with np.errstate(invalid="ignore"):
            d[d < start] = np.nan
        d[:, :max(0, math.ceil(start + p.effective_border_reach * p.num_disparities - 1))] = np.nan
        return cv2.resize(d * np.float32(2.0), (w, h), interpolation=cv2.INTER_NEAREST)

    def order_shares(self, look: DisparityMap) -> tuple[float, float]:
        """(given, exchanged): the fractions of the look's pixels that are consistent at disparities only the given
        order can have (at least 1 px, and beyond the mirror of a negative ``min_disparity``) and at those only
        the exchanged order can have (their negatives)."""
        t = self._order_threshold()
        d = look.disparity
        with np.errstate(invalid="ignore"):
            return (int(np.count_nonzero(d >= t)) / d.size, int(np.count_nonzero(d <= -t)) / d.size)

    def close(self) -> None:
        for matcher in (self._matcher, self._range_matcher):
            if matcher is not None:
                matcher.release()

    # ------------------------------------------------------------------------------------------ pair
    def check_pair(self, left: np.ndarray, right: np.ndarray, dmap: DisparityMap,
                   halves: _Halves | None = None) -> FrameWarning | None:
        """The swapped / mismatched pair warning, or None. ``dmap`` (the full-size disparity) is quoted;
        ``halves``: :meth:`halves` of this frame, when another check of it shares them."""
        valid = dmap.valid_fraction
        if _same_image(left, right):
            return FrameWarning("pair_mismatch", "left and right are the same image (every disparity is 0, every "
                                                 "depth infinite); no distance is reported")
        h, w = left.shape[:2]
        if w // 2 < max(MIN_CHECK_WIDTH, self.params.num_disparities // 2 + 32) or h // 2 < MIN_CHECK_HEIGHT:
            return None  # too small to tell: on tiny images nearly every match is consistent both ways
        if self.params.max_disparity / 2.0 < self._order_threshold() + 2.0:
            return None  # a range (nearly) symmetric about 0: both orders have the same disparities
        halves = self.halves(left, right) if halves is None else halves
        share = self.given_share(dmap) if dmap.disparity.shape == (h, w) else None
        if share is not None and share >= PAIR_CLEAR and not halves.looked:
            halves.cleared = True  # a majority consistent in the given order: no look needed for the pair
            return None
        look = self._look(halves)
        if look is None:
            return None
        given, other = self.order_shares(look)
        if other > given + SWAP_MARGIN and other >= MISMATCH_VALID:
            return FrameWarning("swapped_pair", (
                f"left and right look swapped: {other:.0%} of the pixels match consistently as if the images were "
                f"the other way round, against {given:.0%} as given ({valid:.0%} valid at full size); no distance "
                "is reported; swap the images (or the cameras' order in the calibration)"))
        if max(given, other) < MISMATCH_VALID or given - other <= SWAP_MARGIN:
            return FrameWarning("pair_mismatch", (
                f"the images do not match as a rectified pair: {given:.0%} of the pixels match consistently as "
                f"given, and {other:.0%} with left and right exchanged (a real pair keeps 40 % or more in its own "
                "order and almost none the other way); are they from the same moment, the same rig and this "
                "calibration? No distance is reported"))
        return None

    # ------------------------------------------------------------------------------------------ range
    def check_range(self, left: np.ndarray, right: np.ndarray, dmap: DisparityMap, objects: LocalizedObjects,
                    rig: Any, fusion: FusionParams, seed: int, halves: _Halves | None = None
                    ) -> tuple[LocalizedObjects, FrameWarning | None]:
        """The objects (those beyond the range re-marked ``"beyond_range"``) and the range warning, or None;
        ``halves`` as for :meth:`check_pair`."""
        disp = dmap.disparity  # filled pixels are guesses: they neither saturate nor count as known
        top = float(dmap.params.max_disparity)
        frame_share = range_saturation(disp, top)
        boxes = _suspect_boxes(disp, objects, top, fusion.box_shrink)
        if frame_share < SATURATION_WARN and not boxes.any():
            return objects, None
        halves = self.halves(left, right) if halves is None else halves
        probe = self._look(halves, self._window(disp, objects, boxes, top, frame_share))
        if probe is None:
            return objects, (FrameWarning("range_saturated", _range_message(frame_share, top, rig, None))
                             if frame_share >= SATURATION_WARN else None)
        h, w = disp.shape
        wide = self._reach(probe, w, h, halves.window)
        beyond = np.zeros(len(objects), dtype=bool)
        needed_by_objects: float | None = None
        if frame_share >= SATURATION_WARN:
            boxes[:] = True  # the frame is suspect: every object is looked at again
        if boxes.any():
            again = localize(objects.xyxy[boxes], wide, rig, fusion, rng=seed)
            with np.errstate(divide="ignore", invalid="ignore"):
                d_again = rig.focal_px * rig.baseline_m / again.distance_m - rig.doffs
            # beyond the end by more than the half-size look's own step (1 px there, 2 px here)
            far_out = np.array(again.ok) & (d_again >= top + 2.0)
            beyond[np.flatnonzero(boxes)] = far_out
            if far_out.any():
                needed_by_objects = float(d_again[far_out].max())
        if beyond.any():
            objects = objects.with_status(beyond, "beyond_range")
        if frame_share < SATURATION_WARN and not beyond.any():
            return objects, None
        needed = _needed(disp, wide, top)
        if needed_by_objects is not None and (needed is None or needed_by_objects > needed):
            needed = math.inf if needed_by_objects >= 2 * top - 2 else needed_by_objects
        share = frame_share if frame_share >= SATURATION_WARN else None
        return objects, FrameWarning("range_saturated", _range_message(share, top, rig, needed, int(beyond.sum()),
                                                                       dmap.params.min_disparity))


    def _window(self, disp: np.ndarray, objects: LocalizedObjects, boxes: np.ndarray, top: float,
                frame_share: float) -> tuple[int, int, int, int]:
        """(u0, v0, u1, v1), full-size pixels: the part of the frame the range check reads in the look (the suspect
        boxes; every box and the pixels piled at the end when the frame is), widened leftwards by the look's reach
        (a pixel's match lies up to that far left in the right image, so the window's pixels search all of it), and by
        :data:`WINDOW_MARGIN` rows up and down (the aggregation's context)."""
        h, w = disp.shape
        xs: list[float] = []
        ys: list[float] = []
        chosen = np.ones(len(objects), dtype=bool) if frame_share >= SATURATION_WARN else boxes
        for box in objects.xyxy[chosen].astype(np.float64):
            xs += [box[0], box[2]]
            ys += [box[1], box[3]]
        if frame_share >= SATURATION_WARN:
            with np.errstate(invalid="ignore"):
                piled = disp >= top - 1.0
            rows, cols = np.flatnonzero(piled.any(axis=1)), np.flatnonzero(piled.any(axis=0))  # their extent
            if rows.size:
                xs += [cols[0], cols[-1] + 1]
                ys += [rows[0], rows[-1] + 1]
        if not xs:
            return 0, 0, w, h
        reach = max(0, self.params.min_disparity) + 2 * self.params.num_disparities  # the look's end, full-size px
        u0 = max(0, int(min(xs)) - reach)
        v0 = max(0, int(min(ys)) - WINDOW_MARGIN)
        return u0, v0, min(w, int(math.ceil(max(xs)))), min(h, int(math.ceil(max(ys))) + WINDOW_MARGIN)

    def range_warning(self, left: np.ndarray, right: np.ndarray, dmap: DisparityMap) -> FrameWarning | None:
        """The range warning of a disparity map without a rig or objects (the ``disparity`` command), or None."""
        top = float(dmap.params.max_disparity)
        disp = dmap.disparity  # as check_range: filled pixels neither saturate nor count as known
        share = range_saturation(disp, top)
        if share < SATURATION_WARN:
            return None
        probe = self._look(self.halves(left, right))
        needed = None
        if probe is not None:
            h, w = disp.shape
            wide = self._reach(probe, w, h)
            needed = _needed(disp, wide, top)
        return FrameWarning("range_saturated", _range_message(share, top, None, needed, 0, dmap.params.min_disparity))


def _same_image(left: np.ndarray, right: np.ndarray) -> bool:
    """``np.array_equal(left, right)`` for two images of one shape, deciding most different pairs on every 8th row
    and column first (a real pair differs there; the whole comparison took 0.5 ms a KITTI frame)."""
    if left.shape != right.shape:
        return False
    return np.array_equal(left[::8, ::8], right[::8, ::8]) and np.array_equal(left, right)


def _needed(disp: np.ndarray, wide: np.ndarray, top: float) -> float | None:
    """The disparity (px) the pixels piled at the end of the range have in the half-size look (95th percentile);
    inf when that look is at its own end too, None when too few of them are known there."""
    with np.errstate(invalid="ignore"):
        reach = wide[disp >= top - 1.0]  # the piled pixels (NaN is never piled)
    reach = reach[np.isfinite(reach)]
    if reach.size < 20:
        return None
    needed = float(np.percentile(reach, 95))
    return math.inf if needed >= 2 * top - 2 else needed


def _suspect_boxes(disp: np.ndarray, objects: LocalizedObjects, top: float, shrink: float) -> np.ndarray:
    """(N,) bool: boxes whose known pixels (inside the shrunk box) are piled at the end of the range, or too few."""
    out = np.zeros(len(objects), dtype=bool)
    h, w = disp.shape
    for i, box in enumerate(objects.xyxy.astype(np.float64)):
        u0, v0, u1, v1 = shrunk_pixel_box(box, shrink, w, h)  # the pixels localize() looks at
        if u1 > u0 and v1 > v0:
            crop = disp[v0:v1, u0:u1]
            out[i] = range_saturation(crop, top) >= BOX_SATURATION or np.isfinite(crop).mean() < BOX_SPARSE
    return out


def _range_message(share: float | None, top: float, rig: Any, needed: float | None, n_beyond: int = 0,
                   min_disparity: int = 0) -> str:
    def metres(d: float) -> float:
        return rig.focal_px * rig.baseline_m / (d + rig.doffs) if d + rig.doffs > 0 else math.inf

    at = f"{top:g} px" + (f" = {metres(top):.2f} m" if rig is not None else "")
    nearer = f"nearer than {metres(top):.2f} m" if rig is not None else "nearer than the range reaches"
    if share is not None:
        text = (f"{share:.1%} of the valid pixels sit at the end of the disparity range ({at}): something is "
                f"{nearer} and its disparities are wrong")
        if n_beyond:
            text += f"; {n_beyond} object(s) marked beyond_range"
    else:
        text = (f"{n_beyond} object(s) are nearer than the end of the disparity range ({at}); their disparities are "
                "wrong and they are marked beyond_range")
    if needed is None:
        return text + "; search more disparities (num_disparities, --num-disparities)"
    if math.isinf(needed):
        return text + (f"; search at least {_fit_range(2 * top - min_disparity)} disparities (num_disparities, "
                       "--num-disparities)")
    fit = _fit_range(needed - min_disparity)
    reach = f" reaches {metres(min_disparity + fit - 1):.2f} m" if rig is not None else ""
    return text + f"; about {needed:.0f} px are needed: num_disparities={fit} (--num-disparities {fit}){reach}"
