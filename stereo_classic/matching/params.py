"""Parameters of the semi-global matcher: one frozen, self-checking dataclass.

The fields that are command-line flags carry their help text in ``dataclasses.field(metadata=...)``:
``"help"``, and where needed ``"metavar"``, ``"choices"`` and ``"parse"`` (text -> value, raising
ValueError), so that the flags, the config file and the docs are generated from one place.

>>> from stereo_classic.matching import SGMParams
>>> params = SGMParams(num_disparities=64, block_size=5)
>>> params.effective_p1, params.effective_p2
(28, 112)
>>> params.replace(cost="sad").effective_p1
200
"""

from __future__ import annotations

import dataclasses
import numbers
import os
from dataclasses import dataclass
from typing import Any

from stereo_classic.matching._kernels import core as kernels
from stereo_classic.matching._kernels.cost import FEATURE_SCALE
from stereo_classic.matching._kernels.features import FEATURE_OUTSIDE
from stereo_classic.matching.parsing import (
    MEMORY_LIMIT_ENV,
    default_memory_limit,
    parse_bytes,
    parse_census_window,
    parse_lr_check,
)

__all__ = [
    "SGMParams",
    "MEMORY_LIMIT_ENV",
    "COSTS",
    "LEARNED_COSTS",
    "FEATURE_SIMILARITIES",
    "LR_MODES",
    "OUTSIDE_MATCHES",
    "MAX_BLOCK_SIZE",
    "MAX_NUM_DISPARITIES",
    "MAX_PENALTY",
    "MAX_TEXTURE_GAIN",
    "default_memory_limit",
    "parse_bytes",
    "parse_census_window",
    "parse_lr_check",
]

#: Matching costs: census + x-gradient (default), census transform + Hamming distance, or the paper's sum of
#: absolute differences.
COSTS = ("census+grad", "census", "sad", "mccnn", "features")
#: Learned costs (``stereo_classic.matching.learned``): the shipped MC-CNN, or any Siamese feature network (ONNX).
LEARNED_COSTS = ("mccnn", "features")
#: How learned features are compared: dot product of the unit vectors, or their L1 distance.
FEATURE_SIMILARITIES = ("dot", "l1")
#: Input normalisations of a feature network (``learned.FEATURE_INPUTS``).
_FEATURE_INPUTS = ("standardize", "unit", "raw")
#: ONNX Runtime execution providers (``learned.PROVIDERS``).
_PROVIDERS = ("cpu", "cuda", "auto")
#: Costs of a match outside the right image (see SGMParams.outside_match).
OUTSIDE_MATCHES = ("neutral", "forbidden")
#: Left-right check variants (see SGMParams.lr_mode).
LR_MODES = ("full", "opencv", "independent")
#: Largest accepted (odd) SAD window side.
MAX_BLOCK_SIZE = 21
#: Largest accepted disparity range; far above any real camera and image, it only keeps the int16 kernels safe.
MAX_NUM_DISPARITIES = 4096
#: Largest P1 / P2 accepted before the kernels' own, tighter limit for their int16 sums, which depends on
#: the cost and the weak-texture gain (e.g. P2 * gain <= 1344 for census 9x7, 1323 for census+grad; SAD penalties
#: are scaled with the cost).
MAX_PENALTY = 32767
#: Largest ``weak_texture_gain`` (the kernels hold the factor in sixteenths in a uint8).
MAX_TEXTURE_GAIN = 8.0
#: Census windows whose bit string fits the 64-bit kernel (width * height - 1 <= 64 bits).
_MAX_CENSUS_BITS = 64

# Census defaults: measured best on the developers' scenes (see docs/matching.md#parameters).
_CENSUS_P1 = 20
_CENSUS_P2 = 80
# census+grad defaults: the census penalties plus OpenCV's per-pixel 8 / 32 for the gradient term (a window mean).
_GRAD_P1 = 8
_GRAD_P2 = 32
# SAD defaults: OpenCV's recommendation 8 * cn * block^2 and 32 * cn * block^2 with cn = 1 (we match on grey).
_SAD_P1_PER_PIXEL = 8
_SAD_P2_PER_PIXEL = 32
# Learned costs, in the kernels' units (FEATURE_SCALE per unit of 1 - <fL, fR>): MC-CNN's SGM (Zbontar & LeCun 2016)
# uses P1 2.3 and P2 24.3 on the cost -<fL, fR>, divided by 4 where the image gradient along the path exceeds 0.08
# (20 grey levels) on one image and by 8 where it does on both. Here: half of them (between the full penalties of
# smooth pixels and the quarter at intensity edges) as the base, P2 divided by 1 + |I(p) - I(p - r)| along each path
# (the kernels' edge-aware rule, ``adaptive_p2``, always on for learned costs) and, as for every cost, up to
# ``weak_texture_gain`` times larger on weak texture: 1.15 * 25 and 12.15 * 25, rounded. Measured on the shared
# scenes (dense bad-2 Middlebury-style / driving) against MC-CNN's flat 2.3 / 24.3 without the edge rule 10.7 / 11.5,
# with it 6.9 / 10.4; this 7.1 / 9.4; with the neutral cost outside the right image (``_kernels.features``) and P1 / 1.5
# on the paths that cross rows 6.3 / 9.0 on the six Middlebury-style scenes (docs/matching.md, "Learned costs").
_LEARNED_P1 = round(2.3 / 2 * FEATURE_SCALE)
# MC-CNN's SGM divides P1 by 1.5 on its vertical paths (``sgm_V``): the P1 of the paths that cross rows.
_LEARNED_VERTICAL = 1.5
# border_reach of the classical costs (see the field).
_BORDER_REACH = 0.5
_LEARNED_P2 = round(24.3 / 2 * FEATURE_SCALE)
# The census cost's share of "mccnn": equal parts, the two similarities (each on the learned cost's scale) weighed
# alike; not fitted. Measured on the shared scenes (docs/matching.md, "Census beside the network"): better than the
# network alone on the Middlebury-style, 2001 and driving families, the same on 2005/2006.
_MCCNN_CENSUS = 0.5


def _is_int(value: Any) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _is_real(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


@dataclass(frozen=True)
class SGMParams:
    """Everything that decides a disparity map, checked when built.

    Parameters
    ----------
    min_disparity : int
        Smallest disparity searched, pixels (may be negative). Default 0.
    num_disparities : int
        Number of disparities searched: ``min_disparity .. min_disparity + num_disparities - 1``.
        Any positive integer (OpenCV needs a multiple of 16; this matcher does not). Default 64.
    block_size : int
        Odd side of the square SAD window, 1 .. 21 (used by ``cost="sad"`` and the gradient term of
        ``"census+grad"``). Default 5.
    p1, p2 : int or None
        Smoothness penalties for a disparity change of 1 px and of more than 1 px (``p2 > p1``).
        None uses defaults scaled to the cost: census 20 / 80 (measured best on real scenes);
        census+grad 28 / 112 (census's plus OpenCV's 8 / 32 per pixel for the gradient mean);
        SAD ``8 * block_size**2`` / ``32 * block_size**2`` (OpenCV's rule with one channel); learned costs 29 / 304
        (MC-CNN's 2.3 / 24.3 halved, in the kernels' 25 units per unit of dot product; P2 always divided by the
        intensity step along the path, as ``adaptive_p2``).
        Units are those of the cost: Hamming bits for census, raw window SAD for "sad" (the kernels
        scale SAD and the penalties together). P2 times ``weak_texture_gain`` is limited by the int16 path
        sums (census 9x7: at most 1344; census+grad 1323). See ``effective_p1`` / ``effective_p2``.
    p1_vertical : int or None
        P1 of the paths that cross rows (from above; with ``paths`` 4 and 8 also from below and the diagonals).
        None: ``p1``'s value (the default for ``cost`` when ``p1`` is None); a learned cost: that divided by 1.5
        (MC-CNN's rule), ``effective_p1_vertical``.
    p1_vertical_texture : bool
        Multiply ``p1_vertical`` by the weak-texture factor, as P1 and P2 are (default True). False: a surface slanted
        in y (a road seen from a car) steps by one disparity every few rows and pays P1 for each step on the paths
        that cross rows only, and does not pay it up to ``weak_texture_gain`` times: driving frames 7.98 -> 7.23
        dense bad-2, indoor scenes unchanged, but the guide finds the floor of fewer OAK-D scenes (docs/matching.md,
        "Slanted surfaces"), so it is not the default.
    cost : {"census+grad", "census", "sad"}
        Matching cost. "census+grad" (default): census Hamming distance plus the window mean of the
        absolute x-gradient difference: census is robust to exposure differences and fine structure,
        the gradient term gives weak-texture surfaces (roads, walls) a cost that is near zero when the
        texture is absent instead of census's noise, and has no intensity term (gradients do not change with
        an exposure offset). "census" alone, or "sad", the paper's sum of absolute differences on the
        x-Sobel + intensity/4 prefilter (OpenCV's cost). "mccnn": the learned cost of the shipped MC-CNN fast
        network (``1 - <fL, fR>`` of its features, with the census cost in equal parts: ``feature_census``);
        "features": any Siamese feature network given as ``feature_model``. See docs/matching.md, "Learned costs".
    feature_model : str or None
        Learned costs: an ONNX feature network (a path), or a shipped one by name ("mccnn-fast-dw", the default of
        "mccnn"; "mccnn-fast-int8", the paper's fast net with int8 layers). Required for ``cost="features"``.
    feature_input : {"standardize", "unit", "raw"}
        Learned costs: the network's input, per image ``(I - mean) / std`` (default, MC-CNN's), ``I / 255``, or the
        grey levels 0..255.
    feature_similarity : {"dot", "l1"}
        Learned costs: ``1 - <fL, fR>`` of the unit feature vectors (default) or their L1 distance over sqrt(C).
    feature_census : float or None
        Learned costs: the share (0 to 1) of the census cost (``census_window``, its Hamming distance over the bits)
        in the cost, the rest the network's, both on the learned cost's scale. None: 0.5 for "mccnn" (the network
        and census in equal parts: better than the network alone on the shared scenes, docs/matching.md), 0 for
        "features" (a given network alone). See ``effective_feature_census``.
    onnx_provider : {"cpu", "cuda", "auto"}
        Learned costs: ONNX Runtime's execution provider ("auto": CUDA where this onnxruntime has it).
    census_window : (int, int)
        Census window (width, height), both odd, at most 64 comparison bits. Default (9, 7).
    adaptive_p2 : bool
        Divide P2 by the intensity gradient along each path (Hirschmuller 2008). Default False.
    weak_texture_gain : float
        1 .. 8. Where the texture is weak, the matching cost's minimum is mostly noise: a pixel whose 5 x 5 window
        mean of |Sobel_x| (left image) is below 16 grey levels (an intensity slope of 2 levels per pixel, three
        times what sensor noise alone gives) gets P1 and P2 multiplied by 16 / that mean, at most by this factor,
        so that its path neighbours weigh more than its own cost. Textured pixels (and so depth edges, which are
        textured) keep the penalties as given. 1 = the same penalties everywhere. Default 4 (measured on both
        dataset families, docs/matching.md "Weak texture": the road of driving scenes gains most).
    uniqueness : float
        Uniqueness ratio in percent, 0 .. 100: the best cost must beat the second best (away
        from the winner's neighbours) by this margin, else the pixel is unknown. 0 = off (default).
    lr_check : float or None
        Maximum left-right disparity difference in pixels; None = no left-right check. Default 1.0:
        it removes occluded and mismatched pixels, and ``fill_holes`` then fills them from the background.
    lr_mode : {"full", "opencv", "independent"}
        How the left-right check finds the right view's disparity. "full" (default): the right
        image's own winner over the same sums (strict). "opencv": StereoSGBM's check, which only
        rejects a pixel that loses a collision (two left pixels claiming one right pixel) at both
        the floor and the ceiling of its disparity (lenient, keeps more pixels). "independent": the right
        image's own match (the pair matched again, mirrored: its own paths), both views' measured pixels
        given the 3x3 median first, as Pandora's "accurate" cross check; 1.5-1.9 times the matcher's time, better
        in every family of the benchmark (docs/matching.md, "An independent right view"). ``border_reach``
        None means 0 with it: the check covers the left border as ``border_check`` does.
    right_view : bool
        Also return the right view's disparity (``DisparityMap.disparity_right``) when the check
        does not compute it anyway. Default False.
    subpixel : bool
        Parabola subpixel refinement. Default True.
    speckle_size : int
        Connected regions (of disparities within ``speckle_range``) of at most this many
        pixels are set unknown; 0 = off. Default 100.
    speckle_range : float
        Largest disparity step inside one speckle region, pixels. Default 2.0.
    median_filter : bool
        Each measured pixel takes the lower median of the measured pixels of its 3x3 neighbourhood (after the
        speckle filter and the fill, which reads the measurements as they were): Hirschmuller's 3x3 median of
        SGM's disparity, on measurements only (an unknown pixel stays unknown, a filled one is neither changed nor
        read). Better in every benchmark view of every scene family (driving dense bad-2 7.92 -> 6.80), but not
        the default: the guide lost the floor of one OAK-D scene with it. Default False. See docs/matching.md,
        "The 3x3 median of the measurements".
    border_reach : float or None
        0 .. 1. Pixels near the image borders can search only the part of the range that maps inside the
        right image; those that can search less than this fraction of ``num_disparities`` are set unknown
        (their true match is likely out of reach: a winner at d ~ 0 reads as "far away"). With
        ``fill_holes`` they are then filled from the background next to them (marked as filled). 0 keeps
        every pixel with at least one candidate. None (default): 0.5 for the classical costs (measured on the
        shared scenes, dense bad-2, Middlebury-style / driving, with the same penalties everywhere: keep all
        6.8 / 18.6, 0.5 6.5 / 15.9, 1.0 8.2 / 16.8; with the weak-texture penalties: keep all 7.9 / 11.8, 0.5
        6.7 / 8.0), 0 for the learned ones with ``outside_match`` "neutral", whose candidates outside the right
        image have a neutral cost (a pixel whose match is out of reach picks one of them and is unknown by itself).
        See ``effective_border_reach``.
    outside_match : {"neutral", "forbidden"}
        The cost of a disparity whose match falls outside the right image (pixels near the left edge). "neutral"
        (default): what two unrelated census windows cost on average, half the census bits (31 for 9 x 7; a learned
        cost: half an unrelated pair's), so that it is neither preferred nor forbidden: a real match beats it, and the
        paths that cross the left band carry their neighbours' disparity on instead of being pushed to the few
        disparities that fit; a winner there is unknown. "forbidden": above anything a path can add up, never wins
        (the rule before issue 35; always for cost "sad"). See docs/matching.md, "The left border".
    border_check : bool
        Keep the left-border pixels that ``border_reach`` would set unknown where the right image's own match
        confirms them: the strip is matched again mirrored (the right image as the left one, where those places have
        the whole range) and each border pixel whose winner lands on a right pixel of the same disparity (within
        ``lr_check``; no check, no confirmation) stays measured (``matching.border``). Costs a match of a strip about
        1.5 ``num_disparities`` wide. Default False. See docs/matching.md, "The left border".
    fill_holes : bool
        Fill unknown pixels from the background side of each row, then a 3x3 median
        (dense output, not a measurement: ``DisparityMap.filled_disparity`` holds them, ``DisparityMap.filled``
        marks them, and ``DisparityMap.disparity`` keeps only the measured pixels). Default True.
    paths : {3, 4, 8}
        Aggregation directions: 3 = left, right, top (OpenCV MODE_SGBM_3WAY's set; default), 4 adds
        bottom, 8 adds the diagonals. Diagonal and bottom-up paths pay P1 at every row on surfaces slanted
        in y (the road, the floor) and measured worse there; see docs/matching.md.
    threads : int or None
        Worker threads for the kernels; None = every CPU this process may use (its affinity mask and
        cgroup CPU quota, see ``effective_threads``). The image is cut into stripes of about 32 rows fixed
        by its height, so the disparity is bit-identical for every thread count. Default None.
    memory_limit : int or None
        Refuse inputs whose estimated working memory exceeds this many bytes (MemoryBudgetError).
        None: ``$STEREO_CLASSIC_MEMORY_LIMIT`` or 50 % of physical RAM.
    """

    min_disparity: int = dataclasses.field(default=0, metadata={
        "help": "smallest disparity searched, px (may be negative)", "metavar": "PX"})
    num_disparities: int = dataclasses.field(default=64, metadata={
        "help": "number of disparities searched (any positive integer)", "metavar": "N"})
    block_size: int = dataclasses.field(default=5, metadata={
        "help": "odd SAD window side, 1..21 (cost sad)", "metavar": "N"})
    p1: int | None = dataclasses.field(default=None, metadata={
        "help": "penalty for a 1 px disparity change (default: by cost)", "metavar": "P1"})
    p2: int | None = dataclasses.field(default=None, metadata={
        "help": "penalty for larger disparity changes, > p1 (default: by cost)", "metavar": "P2"})
    p1_vertical: int | None = dataclasses.field(default=None, metadata={
        "help": "P1 of the paths that cross rows (default: P1)", "metavar": "P1"})
    p1_vertical_texture: bool = dataclasses.field(default=True, metadata={
        "help": "do not raise the vertical paths' P1 on weak texture (better on roads seen from a car)"})
    cost: str = dataclasses.field(default="census+grad", metadata={
        "help": "matching cost: census+grad (census + x-gradient), census, sad (the paper's), mccnn (the shipped "
                "learned cost) or features (--feature-model)",
        "metavar": "census+grad|census|sad|mccnn|features"})
    census_window: tuple[int, int] = dataclasses.field(default=(9, 7), metadata={
        "help": "census window, odd width x odd height, at most 64 bits (cost census)", "metavar": "WxH",
        "parse": parse_census_window})
    feature_model: str | None = dataclasses.field(default=None, metadata={
        "help": "learned cost: an ONNX feature network (path), or mccnn-fast-dw (default of mccnn) / mccnn-fast-int8",
        "metavar": "ONNX"})
    feature_input: str = dataclasses.field(default="standardize", metadata={
        "help": "learned cost: the network's input, per image standardised, I/255 or raw grey levels",
        "choices": _FEATURE_INPUTS})
    feature_similarity: str = dataclasses.field(default="dot", metadata={
        "help": "learned cost: dot product of the unit features, or their L1 distance", "choices": FEATURE_SIMILARITIES})
    feature_census: float | None = dataclasses.field(default=None, metadata={
        "help": "learned cost: share of the census cost in it, 0..1 (default: 0.5 for mccnn, 0 for features)",
        "metavar": "SHARE"})
    onnx_provider: str = dataclasses.field(default="cpu", metadata={
        "help": "learned cost: ONNX Runtime provider (auto: CUDA where available)", "choices": _PROVIDERS})
    adaptive_p2: bool = dataclasses.field(default=False, metadata={"help": "divide P2 by the intensity gradient"})
    weak_texture_gain: float = dataclasses.field(default=4.0, metadata={
        "help": "penalties up to this factor larger where the texture is weak (1 = the same everywhere)",
        "metavar": "FACTOR"})
    uniqueness: float = dataclasses.field(default=0.0, metadata={
        "help": "uniqueness ratio in percent, 0 = off", "metavar": "PCT"})
    lr_check: float | None = dataclasses.field(default=1.0, metadata={
        "help": "largest left-right disparity difference, px, or 'off'",
        "metavar": "PX|off", "parse": parse_lr_check})
    lr_mode: str = dataclasses.field(default="full", metadata={
        "help": "left-right check: full (strict), opencv (StereoSGBM's collision check) or independent (against the "
                "right image's own match: 1.5-1.9x the time, more accurate)", "choices": LR_MODES})
    right_view: bool = False
    subpixel: bool = dataclasses.field(default=True, metadata={"help": "integer disparities only"})
    speckle_size: int = dataclasses.field(default=100, metadata={
        "help": "remove regions of at most this many pixels, 0 = off", "metavar": "PIXELS"})
    speckle_range: float = dataclasses.field(default=2.0, metadata={
        "help": "largest disparity step inside one speckle region, px", "metavar": "PX"})
    median_filter: bool = dataclasses.field(default=False, metadata={
        "help": "each measured pixel takes the lower median of the measured pixels of its 3x3 neighbourhood "
                "(Hirschmuller's SGM median; unknown and filled pixels are neither changed nor read; off by "
                "default, see docs/matching.md)"})
    border_reach: float | None = dataclasses.field(default=None, metadata={
        "help": "border pixels that can search less than this fraction of the range are unknown (0 = keep all; "
                "default: 0.5, 0 for a learned cost)", "metavar": "FRACTION"})
    outside_match: str = dataclasses.field(default="neutral", metadata={
        "help": "cost of a match outside the right image: neutral (half an unrelated pair's) or forbidden",
        "choices": OUTSIDE_MATCHES})
    border_check: bool = dataclasses.field(default=False, metadata={
        "help": "keep the left-border pixels that the right image's own match of the strip confirms (border_reach "
                "sets the others unknown)"})
    fill_holes: bool = dataclasses.field(default=True, metadata={
        "help": "fill unknown pixels from the background side of their row (dense map; filled pixels are "
                "marked and never make a distance); --no-fill-holes leaves them unknown"})
    paths: int = dataclasses.field(default=3, metadata={
        "help": "aggregation directions: 3 (left, right, top), 4 (+bottom) or 8 (+diagonals)", "choices": (3, 4, 8)})
    threads: int | None = None
    memory_limit: int | None = None

    def __post_init__(self) -> None:
        def fail(field: str, expected: str, got: Any) -> None:
            raise ValueError(f"`{field}` must be {expected}, got {got!r}")

        def normalise(field: str, value: Any) -> None:
            object.__setattr__(self, field, value)

        # integers
        if not _is_int(self.min_disparity):
            fail("min_disparity", "an integer (pixels, may be negative)", self.min_disparity)
        if abs(int(self.min_disparity)) > MAX_NUM_DISPARITIES:
            fail("min_disparity", f"an integer between {-MAX_NUM_DISPARITIES} and {MAX_NUM_DISPARITIES}",
                 self.min_disparity)
        normalise("min_disparity", int(self.min_disparity))
        if not _is_int(self.num_disparities) or not 1 <= self.num_disparities <= MAX_NUM_DISPARITIES:
            fail("num_disparities", f"a positive integer (at most {MAX_NUM_DISPARITIES})", self.num_disparities)
        normalise("num_disparities", int(self.num_disparities))
        if not _is_int(self.block_size) or not 1 <= self.block_size <= MAX_BLOCK_SIZE or self.block_size % 2 == 0:
            fail("block_size", f"an odd integer between 1 and {MAX_BLOCK_SIZE}", self.block_size)
        normalise("block_size", int(self.block_size))

        # cost
        if not isinstance(self.cost, str) or self.cost.lower() not in COSTS:
            fail("cost", f"one of {', '.join(map(repr, COSTS))}", self.cost)
        normalise("cost", self.cost.lower())
        window = self.census_window
        if (not isinstance(window, (tuple, list)) or len(window) != 2 or not all(_is_int(v) for v in window)
                or not all(v >= 1 and v % 2 == 1 for v in window) or window[0] * window[1] - 1 > _MAX_CENSUS_BITS):
            fail("census_window", "(width, height) of odd positive integers with width * height - 1 <= 64, e.g. (9, 7)",
                 window)
        normalise("census_window", (int(window[0]), int(window[1])))
        self._check_learned(fail, normalise)

        # penalties
        for field in ("p1", "p2", "p1_vertical"):
            value = getattr(self, field)
            if value is not None:
                if not _is_int(value) or not 0 <= value <= MAX_PENALTY:
                    fail(field, f"None or an integer between 0 and {MAX_PENALTY}", value)
                normalise(field, int(value))
        p1, p2 = self.effective_p1, self.effective_p2
        if p2 <= p1:
            note = " (None means the default for this cost)" if self.p1 is None or self.p2 is None else ""
            raise ValueError(f"`p2` must be larger than `p1`, got p1={p1} and p2={p2}{note}")
        if self.p1_vertical is not None and self.p1_vertical >= p2:
            raise ValueError(f"`p1_vertical` must be smaller than p2={p2}, got {self.p1_vertical}")
        # the kernels' own, tighter limit on P2: their int16 path sums must not overflow
        if not _is_real(self.weak_texture_gain) or not 1 <= self.weak_texture_gain <= MAX_TEXTURE_GAIN:
            fail("weak_texture_gain", f"a number between 1 (off) and {MAX_TEXTURE_GAIN}", self.weak_texture_gain)
        normalise("weak_texture_gain", float(self.weak_texture_gain))
        kernels.check_penalties("features" if self.cost in LEARNED_COSTS else self.cost, self.block_size, self.census_window, p1, p2, self.weak_texture_gain)
        for field in ("adaptive_p2", "p1_vertical_texture", "subpixel", "median_filter", "fill_holes", "right_view",
                      "border_check"):
            value = getattr(self, field)
            if not isinstance(value, bool):
                fail(field, "True or False", value)

        # selection and post-processing
        if not _is_real(self.uniqueness) or not 0 <= self.uniqueness <= 100:
            fail("uniqueness", "a ratio in percent between 0 and 100 (0 = off)", self.uniqueness)
        normalise("uniqueness", float(self.uniqueness))
        if self.lr_check is not None:
            if not _is_real(self.lr_check) or not 0 <= self.lr_check < MAX_NUM_DISPARITIES:
                fail("lr_check", "None (off) or a non-negative number of pixels", self.lr_check)
            normalise("lr_check", float(self.lr_check))
        if not isinstance(self.outside_match, str) or self.outside_match.lower() not in OUTSIDE_MATCHES:
            fail("outside_match", f"one of {', '.join(map(repr, OUTSIDE_MATCHES))}", self.outside_match)
        normalise("outside_match", self.outside_match.lower())
        if not isinstance(self.lr_mode, str) or self.lr_mode.lower() not in LR_MODES:
            fail("lr_mode", f"one of {', '.join(map(repr, LR_MODES))}", self.lr_mode)
        normalise("lr_mode", self.lr_mode.lower())
        if not _is_int(self.speckle_size) or self.speckle_size < 0:
            fail("speckle_size", "a non-negative integer number of pixels (0 = off)", self.speckle_size)
        normalise("speckle_size", int(self.speckle_size))
        if self.border_reach is not None:
            if not _is_real(self.border_reach) or not 0.0 <= self.border_reach <= 1.0:
                fail("border_reach", "None (by cost) or a fraction between 0 and 1", self.border_reach)
            normalise("border_reach", float(self.border_reach))
        if not _is_real(self.speckle_range) or not 0 <= self.speckle_range <= MAX_NUM_DISPARITIES:
            fail("speckle_range", "a non-negative number of pixels", self.speckle_range)
        normalise("speckle_range", float(self.speckle_range))

        # execution
        if not _is_int(self.paths) or self.paths not in (3, 4, 8):
            fail("paths", "3, 4 or 8", self.paths)
        normalise("paths", int(self.paths))
        if self.threads is not None:
            if not _is_int(self.threads) or not 1 <= self.threads <= 1024:
                fail("threads", "None (all) or a positive integer", self.threads)
            normalise("threads", int(self.threads))
        if self.memory_limit is not None:
            if not _is_int(self.memory_limit) or self.memory_limit <= 0:
                fail("memory_limit", "None (default) or a positive number of bytes", self.memory_limit)
            normalise("memory_limit", int(self.memory_limit))

    def _check_learned(self, fail, normalise) -> None:
        for field, choices in (("feature_input", _FEATURE_INPUTS), ("feature_similarity", FEATURE_SIMILARITIES),
                               ("onnx_provider", _PROVIDERS)):
            value = getattr(self, field)
            if not isinstance(value, str) or value.lower() not in choices:
                fail(field, f"one of {', '.join(map(repr, choices))}", value)
            normalise(field, value.lower())
        model = self.feature_model
        if model is not None:
            if isinstance(model, os.PathLike):
                model = os.fspath(model)
            if not isinstance(model, str) or not model:
                fail("feature_model", "None or an ONNX file path (or a shipped model's name)", self.feature_model)
            normalise("feature_model", model)
        if self.cost == "features" and self.feature_model is None:
            fail("feature_model", "an ONNX feature network for cost 'features'", None)
        if self.feature_census is not None:
            if not _is_real(self.feature_census) or not 0.0 <= self.feature_census <= 1.0:
                fail("feature_census", "None (by cost) or a share between 0 and 1", self.feature_census)
            normalise("feature_census", float(self.feature_census))

    @property
    def learned(self) -> bool:
        """True for a learned cost (``LEARNED_COSTS``): features from a network, see ``learned``."""
        return self.cost in LEARNED_COSTS

    @property
    def effective_adaptive_p2(self) -> bool:
        """P2 divided by the intensity step along each path: ``adaptive_p2``, and always for a learned cost (MC-CNN's
        penalties drop at intensity edges; measured on the shared scenes, docs/matching.md "Learned costs")."""
        return self.adaptive_p2 or self.learned

    @property
    def effective_feature_model(self) -> str | None:
        """The feature network actually used: ``feature_model``, the shipped MC-CNN for "mccnn", None otherwise."""
        if not self.learned:
            return None
        return self.feature_model if self.feature_model is not None else "mccnn-fast-dw"

    @property
    def effective_feature_census(self) -> float:
        """The census cost's share of a learned cost: ``feature_census``, or when it is None 0.5 for "mccnn" and 0
        for "features"; 0 for a classical cost."""
        if not self.learned:
            return 0.0
        if self.feature_census is not None:
            return self.feature_census
        return _MCCNN_CENSUS if self.cost == "mccnn" else 0.0

    # -- derived values ---------------------------------------------------------------------
    @property
    def max_disparity(self) -> int:
        """Largest disparity searched, pixels: ``min_disparity + num_disparities - 1``."""
        return self.min_disparity + self.num_disparities - 1

    @property
    def effective_p1(self) -> int:
        """P1 actually used: ``p1``, or the default for ``cost`` when ``p1`` is None."""
        if self.p1 is not None:
            return self.p1
        if self.cost == "census+grad":
            return _CENSUS_P1 + _GRAD_P1
        if self.cost in LEARNED_COSTS:
            return _LEARNED_P1
        return _CENSUS_P1 if self.cost == "census" else _SAD_P1_PER_PIXEL * self.block_size**2

    @property
    def effective_p2(self) -> int:
        """P2 actually used: ``p2``, or the default for ``cost`` when ``p2`` is None."""
        if self.p2 is not None:
            return self.p2
        if self.cost == "census+grad":
            return _CENSUS_P2 + _GRAD_P2
        if self.cost in LEARNED_COSTS:
            return _LEARNED_P2
        return _CENSUS_P2 if self.cost == "census" else _SAD_P2_PER_PIXEL * self.block_size**2

    @property
    def effective_p1_vertical(self) -> int:
        """P1 of the paths that cross rows: ``p1_vertical``, or when it is None ``effective_p1`` (a learned cost:
        ``effective_p1 / 1.5`` rounded, MC-CNN's own rule for its vertical paths)."""
        if self.p1_vertical is not None:
            return self.p1_vertical
        return round(self.effective_p1 / _LEARNED_VERTICAL) if self.learned else self.effective_p1

    @property
    def independent_lr(self) -> bool:
        """The left-right check is made against the right image's own match: ``lr_mode="independent"`` with a check."""
        return self.lr_check is not None and self.lr_mode == "independent"

    @property
    def effective_border_reach(self) -> float:
        """``border_reach``, or when it is None 0.5 for a classical cost and 0 for a learned one (its candidates
        outside the right image have a neutral cost instead of a forbidding one: ``_kernels.features``) or with
        ``lr_mode="independent"`` (the right image's own match checks the border too)."""
        if self.border_reach is not None:
            return self.border_reach
        if self.independent_lr:  # the right image's own match checks the band
            return 0.0
        return 0.0 if self.learned and self.outside_match == "neutral" else _BORDER_REACH

    @property
    def outside_cost(self) -> int | None:
        """The cost of a match outside the right image (``outside_match``, in cost units), or None: forbidden
        (``"forbidden"``, and always for "sad"). Census costs: half the census bits; learned costs:
        ``_kernels.features.FEATURE_OUTSIDE``, half an unrelated pair's cost."""
        if self.outside_match != "neutral" or self.cost == "sad":
            return None
        if self.learned:
            return FEATURE_OUTSIDE
        return (self.census_window[0] * self.census_window[1] - 1) // 2

    @property
    def effective_threads(self) -> int:
        """Threads actually used: ``threads``, or every CPU this process may use when it is None."""
        return self.threads if self.threads is not None else kernels.usable_cpus()

    @property
    def effective_memory_limit(self) -> int:
        """Memory limit actually applied, bytes (see ``memory_limit``)."""
        return self.memory_limit if self.memory_limit is not None else default_memory_limit()

    def replace(self, **overrides: Any) -> SGMParams:
        """A copy with some fields changed (checked again); unknown names raise ValueError."""
        unknown = sorted(set(overrides) - {f.name for f in dataclasses.fields(self)})
        if unknown:
            names = ", ".join(f.name for f in dataclasses.fields(self))
            raise ValueError(f"unknown SGM parameter(s) {', '.join(map(repr, unknown))}; expected some of: {names}")
        return dataclasses.replace(self, **overrides)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-friendly dict of the fields (``census_window`` as a list)."""
        out = dataclasses.asdict(self)
        out["census_window"] = list(self.census_window)
        return out
