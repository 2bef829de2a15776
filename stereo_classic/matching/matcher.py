"""Public stereo matcher: checked input, one conversion to grey, numba SGM, post-processing.

>>> import numpy as np
>>> from stereo_classic.matching import compute_disparity
>>> rng = np.random.default_rng(0)
>>> right = rng.integers(0, 256, (40, 80), dtype=np.uint8)
>>> left = np.roll(right, 6, axis=1)                  # every pixel moved 6 px: d = x_left - x_right = 6
>>> dmap = compute_disparity(left, right, num_disparities=16, subpixel=False)
>>> float(np.nanmedian(dmap.disparity)), round(dmap.valid_fraction, 2)   # measured: not the left border's
(6.0, 0.91)
"""

from __future__ import annotations

import math
import threading
import time
from typing import Any

import cv2
import numpy as np

from stereo_classic.matching import learned
from stereo_classic.matching.border import (column_reach, confirm_left_border, independent_check, left_border_columns,
                                           mirrored_params, short_reach, strip_params, strip_width)
from stereo_classic.matching._kernels import core as kernels
from stereo_classic.matching._kernels.handout import handout_allocator
from stereo_classic.matching.params import SGMParams
from stereo_classic.matching.postprocess import (
    StripeLabels,
    _speckle_and_fill,
    fill_bytes,
    finite_in_columns,
    median_bytes,
    median_measured,
    speckle_bytes,
    speckle_fill_bytes,
)
from stereo_classic.matching.result import DisparityMap

__all__ = [
    "compute_disparity",
    "StereoMatcher",
    "DisparityMap",
    "estimate_memory",
    "load_kernels",
    "MemoryBudgetError",
    "StereoInputError",
    "to_gray_uint8",
    "SUPPORTED_DTYPES",
]

#: Image dtypes accepted by the matcher.
SUPPORTED_DTYPES = (np.dtype(np.uint8), np.dtype(np.uint16), np.dtype(np.float32), np.dtype(np.float64))
# Percentiles (of both images together) mapped to 0 and 255 when scaling uint16 / float images.
_SCALE_PERCENTILES = (0.1, 99.9)
# At most this many samples per image for the percentiles.
_SCALE_SAMPLES = 1 << 20
_GiB = 1024**3


class StereoInputError(ValueError):
    """A left/right image the matcher cannot use (shape, dtype, size mismatch, NaN/inf, too small)."""


class MemoryBudgetError(ValueError):
    """The estimated working memory exceeds the limit; raised before anything large is allocated."""


# --------------------------------------------------------------------------------------------------
# input checks and conversion
# --------------------------------------------------------------------------------------------------
def _as_image(name: str, image: Any) -> np.ndarray:
    if isinstance(image, (str, bytes)) or image is None:
        raise StereoInputError(f"`{name}` must be an image array (H, W) or (H, W, 3), got {type(image).__name__}"
                               + ("; read files with stereo_classic.io.read_image" if isinstance(image, str) else ""))
    try:
        arr = np.asarray(image)
    except (ValueError, TypeError) as exc:
        raise StereoInputError(f"`{name}` must be an image array, got {type(image).__name__} ({exc})") from None
    if not arr.dtype.isnative and arr.dtype.newbyteorder("=") in SUPPORTED_DTYPES:
        arr = arr.astype(arr.dtype.newbyteorder("="))  # e.g. big-endian '>f4' from a file
    if arr.dtype not in SUPPORTED_DTYPES:
        raise StereoInputError(f"`{name}` must have dtype uint8, uint16, float32 or float64, got {arr.dtype}")
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[:, :, 0]
    if not (arr.ndim == 2 or (arr.ndim == 3 and arr.shape[2] == 3)):
        raise StereoInputError(f"`{name}` must be grey (H, W) or colour BGR (H, W, 3), got shape {arr.shape}")
    if arr.size == 0:
        raise StereoInputError(f"`{name}` must not be empty, got shape {arr.shape}")
    return arr


def _min_size(params: SGMParams) -> tuple[int, int]:
    """Smallest (height, width) an image may have for these params."""
    if params.cost != "sad":  # census, alone or with the gradient term
        cw, ch = params.census_window
        return max(params.block_size, ch), max(params.block_size, cw)
    return params.block_size, params.block_size


def _check_pair(left: Any, right: Any, params: SGMParams) -> tuple[np.ndarray, np.ndarray]:
    """All checks that need no allocation; returns the two arrays (views of the input)."""
    left_arr, right_arr = _check_images(left, right)
    height, width = left_arr.shape[:2]
    min_h, min_w = _min_size(params)
    if height < min_h or width < min_w:
        what = (f"`block_size` {params.block_size} and `census_window` {params.census_window}"
                if params.cost == "census" else f"`block_size` {params.block_size}")
        raise StereoInputError(f"images must be at least {min_h} x {min_w} (height x width) for {what}, "
                               f"got {height} x {width}")
    if params.num_disparities > width:
        raise StereoInputError(f"`num_disparities` ({params.num_disparities}) must not be larger than the image "
                               f"width ({width})")
    if params.max_disparity >= width or params.min_disparity <= -width:
        raise StereoInputError(
            f"the disparity range `min_disparity`..`min_disparity + num_disparities - 1` "
            f"({params.min_disparity}..{params.max_disparity}) must lie within -{width - 1}..{width - 1} "
            f"for an image {width} px wide")
    return left_arr, right_arr


def _check_finite(name: str, arr: np.ndarray) -> None:
    if arr.dtype.kind != "f":
        return
    # min / max propagate NaN and expose inf without allocating a mask of the image size.
    if np.isfinite(arr.min()) and np.isfinite(arr.max()):
        return
    n_nan = int(np.isnan(arr).sum())
    n_inf = int(np.isinf(arr).sum())
    raise StereoInputError(f"`{name}` must hold finite values, got {n_nan} NaN and {n_inf} inf; "
                           "replace them (e.g. np.nan_to_num) or mask them out before matching")


def _gray_float(arr: np.ndarray) -> np.ndarray:
    """float64 grey of an (H, W) or (H, W, 3) BGR array (ITU-R 601 weights, as cv2.COLOR_BGR2GRAY).

    Accumulated in place, one channel temporary at a time: at most 16 bytes per pixel while it runs
    (the result and one float64 channel), the same values as ``0.114 * b + 0.587 * g + 0.299 * r``.
    """
    if arr.ndim == 2:
        return arr.astype(np.float64)
    out = arr[:, :, 0].astype(np.float64)
    out *= 0.114
    for channel, weight in ((1, 0.587), (2, 0.299)):
        term = arr[:, :, channel].astype(np.float64)
        term *= weight
        out += term
        del term
    return out


def _sample(gray: np.ndarray) -> np.ndarray:
    step = max(1, int(math.ceil(math.sqrt(gray.size / _SCALE_SAMPLES))))
    return gray[::step, ::step].ravel()


def _check_images(left: Any, right: Any) -> tuple[np.ndarray, np.ndarray]:
    """The checks on the pair itself (type, dtype, shape, same shape and dtype); returns the arrays."""
    left_arr = _as_image("left", left)
    right_arr = _as_image("right", right)
    if left_arr.shape != right_arr.shape:
        raise StereoInputError(f"`left` and `right` must have the same shape, got left {left_arr.shape} "
                               f"and right {right_arr.shape}")
    if left_arr.dtype != right_arr.dtype:
        raise StereoInputError(f"`left` and `right` must have the same dtype, got left {left_arr.dtype} "
                               f"and right {right_arr.dtype}")
    return left_arr, right_arr


def to_gray_uint8(left: Any, right: Any) -> tuple[np.ndarray, np.ndarray]:
    """Convert a pair once to C-contiguous (H, W) uint8 grey, both with the same mapping.

    The pair is checked as by ``compute_disparity``: (H, W) or (H, W, 3) arrays of dtype uint8,
    uint16, float32 or float64, the same shape and dtype, finite values; else ``StereoInputError``.

    uint8: colour via ``cv2.COLOR_BGR2GRAY``, grey as is (no copy when already contiguous).
    uint16 and float: grey with the same weights in float64, then one linear map shared by both
    images that sends the 0.1th percentile of their pixels to 0 and the 99.9th to 255 (clipped,
    rounded). Sharing the map keeps the brightness relation between the cameras; the percentiles
    make a few hot pixels or a 12-bit range in a 16-bit container harmless. A constant pair maps to 0.
    """
    left_arr, right_arr = _check_images(left, right)
    _check_finite("left", left_arr)
    _check_finite("right", right_arr)
    return _to_gray_uint8(left_arr, right_arr)


def _to_gray_uint8(left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``to_gray_uint8`` on a pair already checked (by ``_check_pair`` and ``_check_finite``)."""
    if left.dtype == np.uint8:
        def convert(arr: np.ndarray) -> np.ndarray:
            if arr.ndim == 3:
                return cv2.cvtColor(np.ascontiguousarray(arr), cv2.COLOR_BGR2GRAY)
            return np.ascontiguousarray(arr)

        return convert(left), convert(right)
    grays = [_gray_float(left), _gray_float(right)]
    samples = np.concatenate([_sample(grays[0]), _sample(grays[1])])
    lo, hi = (float(v) for v in np.percentile(samples, _SCALE_PERCENTILES, overwrite_input=True))
    if not hi > lo:
        lo, hi = float(samples.min()), float(samples.max())
    del samples
    out = []
    for i in range(2):
        gray, grays[i] = grays[i], None  # mapped in place, freed once converted
        if hi > lo:
            # Divide before subtracting so that extreme float64 values (1e308) cannot overflow.
            scale = max(abs(lo), abs(hi))
            span = hi / scale - lo / scale
            gray /= scale
            gray -= lo / scale
            gray *= 255.0 / span
            np.clip(gray, 0.0, 255.0, out=gray)
            np.rint(gray, out=gray)
            out.append(gray.astype(np.uint8))
        else:
            out.append(np.zeros(gray.shape, np.uint8))
        del gray
    return out[0], out[1]


def _conversion_bytes(image_shape: tuple[int, ...], dtype: Any) -> int:
    """Peak bytes of ``to_gray_uint8`` beyond its inputs: the uint8 outputs, and for uint16/float the
    float64 greys (the second one built next to the first: 24 B/px) or, while the percentiles are
    found, both greys and the float64 samples of both images (16 B/px + 8 B per sample)."""
    height, width = int(image_shape[0]), int(image_shape[1])
    pixels = height * width
    out = 2 * pixels  # the two uint8 grey images
    if np.dtype(dtype) != np.uint8:
        step = max(1, int(math.ceil(math.sqrt(pixels / _SCALE_SAMPLES))))
        samples = 2 * (-(-height // step)) * (-(-width // step))
        out += max(3 * 8 * pixels, 2 * 8 * pixels + 8 * samples)
    return out


# --------------------------------------------------------------------------------------------------
# memory
# --------------------------------------------------------------------------------------------------
def estimate_memory(image_shape: tuple[int, ...], params: SGMParams | None = None, *,
                    dtype: Any = np.uint8) -> int:
    """Bytes the matcher will allocate for one pair of this shape (not counting the input images).

    Parameters
    ----------
    image_shape : tuple
        (H, W) or (H, W, C) of one image.
    params : SGMParams, optional
        Default ``SGMParams()``.
    dtype : numpy dtype, keyword-only
        Input dtype (uint16/float inputs need float64 grey copies during conversion).

    Returns
    -------
    int
        Bytes: the kernels' working memory (row buffers; the sum volume for 4 and 8 paths) plus the grey
        copies, the output maps and the post-processing temporaries.
    """
    params = SGMParams() if params is None else params
    if not isinstance(params, SGMParams):
        raise ValueError(f"`params` must be an SGMParams or None, got {type(params).__name__}")
    if not isinstance(image_shape, (tuple, list)) or len(image_shape) not in (2, 3) or not all(
            isinstance(v, (int, np.integer)) and v >= 0 for v in image_shape):
        raise ValueError(f"`image_shape` must be (H, W) or (H, W, C) of non-negative integers, got {image_shape!r}")
    height, width = int(image_shape[0]), int(image_shape[1])
    pixels = height * width
    # the kernels: row buffers (and the sum volume of 4 / 8 paths), outputs (left and right float32), cost inputs
    channels, features = learned.memory_terms(params, height, width)  # a learned cost's features and network run
    core = kernels.memory_bytes(height, width, params.num_disparities, paths=params.paths,
                                lr_check=params.lr_check is not None,
                                cost="features" if params.learned else params.cost,
                                block_size=params.block_size, threads=params.effective_threads,
                                feature_channels=channels,
                                feature_census=params.effective_feature_census > 0) + features
    conversion = _conversion_bytes((height, width), dtype)
    post = 4 * pixels  # the border columns' copy
    if params.speckle_size > 0 and params.fill_holes:
        post += speckle_fill_bytes(height, width)  # run together
    else:
        post += speckle_bytes(height, width) if params.speckle_size > 0 else 0
        post += fill_bytes(height, width) if params.fill_holes else 0
    if params.median_filter:
        post += median_bytes(height, width)
    strip = 0
    if params.independent_lr:  # the mirrored pair's match, both medians
        strip += 2 * pixels + 12 * pixels + estimate_memory((height, width), mirrored_params(params))
    if params.border_check and params.lr_check is not None and params.effective_border_reach > 0:  # the mirrored strip
        columns = min(width, math.ceil(params.effective_border_reach * params.num_disparities))
        strip_cols = strip_width(columns, width, params)
        strip = 2 * height * strip_cols + estimate_memory((height, strip_cols), strip_params(params))
    return int(core + conversion + post + strip)


def _check_memory(shape: tuple[int, ...], dtype: Any, params: SGMParams, reserved: int = 0) -> int:
    """Estimate for this shape; MemoryBudgetError when it plus ``reserved`` (bytes another call of the
    same matcher is using) exceeds the limit."""
    need = estimate_memory(tuple(shape), params, dtype=dtype)
    limit = params.effective_memory_limit
    if need + reserved > limit:
        height, width = shape[0], shape[1]
        busy = (f" while another thread's call on the same StereoMatcher holds about {reserved / _GiB:.2f} GiB "
                f"({reserved} bytes)" if reserved else "")
        raise MemoryBudgetError(
            f"matching {width} x {height} px with num_disparities={params.num_disparities} needs about "
            f"{need / _GiB:.2f} GiB ({need} bytes){busy}, above the memory limit of {limit / _GiB:.2f} GiB "
            f"({limit} bytes); use a smaller disparity "
            f"range (num_disparities) or downscale the images (e.g. cv2.resize by 0.5 and halve the range), "
            f"or raise `memory_limit` / $STEREO_CLASSIC_MEMORY_LIMIT")
    return need


# --------------------------------------------------------------------------------------------------
# matching
# --------------------------------------------------------------------------------------------------
def _resolve_params(params: SGMParams | None, overrides: dict[str, Any]) -> SGMParams:
    if params is None:
        params = SGMParams()
    elif not isinstance(params, SGMParams):
        raise ValueError(f"`params` must be an SGMParams or None, got {type(params).__name__}")
    return params.replace(**overrides) if overrides else params


def _match(left: Any, right: Any, params: SGMParams, memory_checked: set | None = None,
           workspace: kernels.Workspace | None = None, reserved: int = 0) -> DisparityMap:
    """``reserved``: bytes a busy call of the same StereoMatcher holds; when > 0 the memory is checked
    on every call, with ``reserved`` added (``memory_checked`` does not apply)."""
    t0 = time.perf_counter()
    left_arr, right_arr = _check_pair(left, right, params)
    key = (left_arr.shape, left_arr.dtype)
    if reserved > 0:
        _check_memory(left_arr.shape, left_arr.dtype, params, reserved)
    elif memory_checked is None or key not in memory_checked:
        _check_memory(left_arr.shape, left_arr.dtype, params)
        if memory_checked is not None:
            memory_checked.add(key)
    _check_finite("left", left_arr)
    _check_finite("right", right_arr)
    gray_left, gray_right = _to_gray_uint8(left_arr, right_arr)
    t1 = time.perf_counter()
    features = None if not params.learned else learned.model_for(params).features(  # int8 unit vectors of both
        gray_left, gray_right, normalisation=params.feature_input, threads=params.effective_threads)
    t_features = time.perf_counter()

    reach = column_reach(gray_left.shape[1], params)
    short = short_reach(reach, params)
    # winners lie in the range, subpixel within 0.5 px of one
    bound = max(abs(params.min_disparity), abs(params.min_disparity + params.num_disparities)) + 1.0
    stripe_counts: list[tuple[int, int]] = []
    labelled = None
    independent = params.independent_lr  # checked below, not by the kernels
    if (params.speckle_size > 0 and params.fill_holes and not params.border_check and not independent
            and StripeLabels.fits(bound)):
        # the speckle filter's labels made stripe by stripe as the matcher finishes them (by a worker that would
        # otherwise wait for the last stripes), each stripe's unknown pixels counted and its short-reach border
        # pixels set unknown first (below, the same on the whole map when this does not apply)
        labelled = StripeLabels(gray_left.shape, params.speckle_range, bound, workspace)

        def on_rows(disp: np.ndarray, y0: int, y1: int) -> None:
            band = disp[y0:y1]
            unknown = int(np.count_nonzero(np.isnan(band)))
            cut = int(np.count_nonzero(np.isfinite(band[:, short]))) if short.any() else 0
            if cut:
                band[:, short] = np.nan
            stripe_counts.append((unknown, cut))
            labelled.label(disp, y0, y1)

    disparity, disparity_right, core_timings = kernels.sgm_match(
        gray_left, gray_right, cost="features" if params.learned else params.cost,
        features=features, feature_similarity=params.feature_similarity, min_disparity=params.min_disparity,
        num_disparities=params.num_disparities, block_size=params.block_size, census_window=params.census_window,
        p1=params.effective_p1, p2=params.effective_p2, p1_cross=params.effective_p1_vertical,
        cross_texture=params.p1_vertical_texture, outside_cost=params.outside_cost, paths=params.paths,
        feature_census=params.effective_feature_census,
        adaptive_p2=params.effective_adaptive_p2, weak_texture_gain=params.weak_texture_gain,
        uniqueness=params.uniqueness / 100.0, lr_check=None if independent else params.lr_check,
        subpixel=params.subpixel, threads=params.effective_threads,
        lr_mode="full" if params.lr_mode == "independent" else params.lr_mode,
        return_right=params.right_view and not independent, workspace=workspace,
        scratch_output=params.speckle_size > 0 or params.fill_holes,  # post-processing makes a new map of it
        on_rows=on_rows if labelled is not None else None)
    t2 = time.perf_counter()

    disparity = np.asarray(disparity, dtype=np.float32)
    failed_independent = 0
    if independent:  # the right image's own match, both views' 3x3 median, then the check (docs/matching.md)
        if workspace is not None and workspace.mirror is None:
            workspace.mirror = kernels.Workspace()
        mirror = None if workspace is None else workspace.mirror
        disparity, right_own, failed_independent = independent_check(
            gray_left, gray_right, disparity, params, lambda a, b, p: _match(a, b, p, workspace=mirror),
            params.effective_threads)
        disparity_right = right_own if params.right_view else None
    t_border = time.perf_counter()
    if labelled is not None:
        unknown_matcher = sum(u for u, _ in stripe_counts)
        short_range = sum(c for _, c in stripe_counts)
    else:
        unknown_matcher = int(np.count_nonzero(np.isnan(disparity)))
        short_range = 0
    if short.any() and labelled is None:  # border pixels that could search too little of the range: not a measurement
        short_range = int(np.count_nonzero(np.isfinite(disparity[:, short])))
        disparity = disparity.copy() if not disparity.flags.writeable else disparity
        columns = left_border_columns(short) if params.border_check and params.lr_check is not None else 0
        confirmed = (confirm_left_border(gray_left, gray_right, disparity, columns, params, _match)
                     if columns else None)
        kept = disparity[:, :columns][confirmed] if columns else None
        disparity[:, short] = np.nan
        if columns:  # ... unless the right image's own match says the same (``border_check``)
            disparity[:, :columns][confirmed] = kept
            short_range -= int(confirmed.sum())
    t_border_end = time.perf_counter()
    valid_before = disparity.size - unknown_matcher - short_range
    threads = params.effective_threads
    disparity, filled_mask, valid_after_speckle, filled, measured = _speckle_and_fill(
        disparity, max_size=params.speckle_size, max_diff=params.speckle_range, fill=params.fill_holes,
        threads=threads, workspace=workspace, bound=bound, labelled=labelled)
    if params.median_filter:  # the measured pixels only: the fill above read them as the checks left them
        disparity = median_measured(disparity, filled_mask, threads=threads, workspace=workspace)
        measured = None
    border = reach < params.num_disparities  # the full range does not fit: matched with the range that does
    t3 = time.perf_counter()

    # The kernels mark NaN: pixels with no candidate at all, and those failing uniqueness or the LR check
    # (which they count exactly).
    no_candidate = int((reach == 0).sum()) * disparity.shape[0]  # no disparity of the range fits
    timings = {"prepare": (t1 - t0) * 1e3, **({"features": (t_features - t1) * 1e3} if params.learned else {})}
    timings.update({k: float(v) for k, v in dict(core_timings).items() if not k.startswith("n_")})
    if params.border_check:
        timings["border_check"] = (t_border_end - t_border) * 1e3
    if independent:
        timings["independent_check"] = (t_border - t2) * 1e3
    timings["postprocess"] = (t3 - t2) * 1e3
    timings["total"] = (t3 - t0) * 1e3
    validity = {
        "pixels": int(disparity.size),
        "valid": valid_after_speckle + filled,
        "unknown_matcher": unknown_matcher,
        "no_candidate": no_candidate,
        "failed_lr": int(core_timings["n_failed_lr"]) + failed_independent,
        "failed_uniqueness": int(core_timings["n_failed_uniqueness"]),
        "outside": int(core_timings["n_outside"]),
        "short_range": short_range,
        "speckle_removed": valid_before - valid_after_speckle,
        "filled": filled,
        "border": int(border.sum()) * disparity.shape[0],
        "border_valid": finite_in_columns(disparity, border),
    }
    if disparity_right is not None:
        disparity_right = np.asarray(disparity_right, dtype=np.float32)
    left_copy = handout_allocator(workspace)("left_gray", gray_left.shape, np.uint8)  # for ``confidence``
    np.copyto(left_copy, gray_left)
    if measured is not None:  # the one pass made the measured map beside the filled one
        return DisparityMap._of_one_pass(disparity, filled_mask, measured, valid_after_speckle, filled,
                                         disparity_right=disparity_right, params=params, timings_ms=timings,
                                         validity=validity, left_gray=left_copy)
    return DisparityMap(disparity=disparity, disparity_right=disparity_right, params=params,
                        timings_ms=timings, validity=validity, filled=filled_mask,
                        left_gray=left_copy)


def compute_disparity(left: Any, right: Any, params: SGMParams | None = None, **overrides: Any) -> DisparityMap:
    """Disparity of a rectified stereo pair by semi-global matching (default: census + x-gradient cost, 3 paths,
    left-right check, holes filled into ``DisparityMap.filled_disparity`` and marked in ``DisparityMap.filled``, while
    ``DisparityMap.disparity`` keeps the measured pixels only; see ``SGMParams``).

    Parameters
    ----------
    left, right : (H, W) or (H, W, 3) array
        Rectified images, grey or colour BGR, dtype uint8, uint16, float32 or float64, same
        shape and dtype. Converted once to uint8 grey (see ``to_gray_uint8``).
    params : SGMParams, optional
        Default ``SGMParams()``.
    **overrides
        Fields of ``SGMParams`` to change, e.g. ``num_disparities=128``.

    Returns
    -------
    DisparityMap
        ``disparity`` (H, W) float32 pixels, ``d = x_left - x_right``, NaN where unknown (measured pixels only);
        ``filled_disparity`` the dense map with the holes filled.

    Raises
    ------
    StereoInputError
        Bad images: dtype, shape, different sizes, empty, smaller than the window, NaN/inf,
        or a disparity range wider than the image.
    MemoryBudgetError
        The estimated memory exceeds ``memory_limit``; raised before any large allocation.
    ValueError
        Bad parameters (message names the field).
    """
    return _match(left, right, _resolve_params(params, overrides))


_LOADED: set[SGMParams] = set()  # the settings load_kernels has matched with in this process


def load_kernels(params: SGMParams | None = None, **overrides: Any) -> bool:
    """Load the matcher's compiled kernels now, so that the first frame of a stream takes what the others take.

    The kernels are numba functions kept compiled in numba's on-disk cache. The first call of a process that uses
    them loads that code and numba's own registries: about 0.3 s on a 2-core machine (more after an install, when
    they are compiled once). ``run``, ``guide`` and the ROS 2 node call this before their first frame, so that a live
    camera's first frame is not held up by the loading. It matches a small random pair (64 rows; 64 columns more
    than the range's length or its farther end) with ``params``: the same cost, paths, checks, threads and
    disparities per pixel (the kernels are compiled once per padded range), so the same kernels (and a learned
    cost's network) load.

    Parameters
    ----------
    params : SGMParams, optional
        Default ``SGMParams()``.
    **overrides
        Fields of ``SGMParams`` to change.

    Returns
    -------
    bool
        True when this call matched the pair; False when this process had already loaded the kernels for these
        settings (the call then does nothing).

    >>> _ = load_kernels(num_disparities=16)
    >>> load_kernels(num_disparities=16)  # loaded already: nothing to do
    False
    """
    params = _resolve_params(params, overrides)
    # every setting but the range, which picks the kernels only by the disparities per pixel of their buffers
    # (they are compiled once per padded range: tags.disparity_tag)
    key = params.replace(min_disparity=0, num_disparities=kernels.padded_disparities(params.num_disparities,
                                                                                   params.paths))
    if key in _LOADED:
        return False
    width = max(abs(params.min_disparity), abs(params.max_disparity), params.num_disparities) + 64
    pattern = np.random.default_rng(0).integers(0, 256, (64, width + 4), dtype=np.uint8)
    left, right = np.ascontiguousarray(pattern[:, 4:]), np.ascontiguousarray(pattern[:, :width])  # 4 px apart
    _match(left, right, params)
    _LOADED.add(key)
    return True


class StereoMatcher:
    """Holds parameters for a sequence of frames and reuses what it can between frames of one size.

    Per image size and dtype the memory budget is checked once; the kernels' buffers (row buffers for 3 paths, about
    ``2 * num_disparities * (4 * W + H)`` bytes per thread; 4 or 8 paths also the ``2 * H * W * num_disparities``-byte
    sum volume) are kept and reused, which saves their allocation and page faults on every frame, until the image
    size changes or ``release()``; so are the maps of the last three results: a new result's maps are written into
    those of one that nothing holds any more (never a held one). Safe to share between threads: a call that finds
    the buffers busy allocates its own, after checking that its estimate plus the busy call's fits in the memory
    limit (``MemoryBudgetError`` otherwise).

    >>> rng = np.random.default_rng(2)
    >>> frames = [(np.roll(right, 3, axis=1), right) for right in rng.integers(0, 256, (2, 32, 64), np.uint8)]
    >>> matcher = StereoMatcher(num_disparities=16, subpixel=False)
    >>> [float(np.nanmedian(matcher.compute(left, right).disparity)) for left, right in frames]
    [3.0, 3.0]
    """

    def __init__(self, params: SGMParams | None = None, **overrides: Any) -> None:
        self._params = _resolve_params(params, overrides)
        self._memory_checked: set[tuple[tuple[int, ...], np.dtype]] = set()
        self._workspace: kernels.Workspace | None = None
        self._lock = threading.Lock()
        self._busy_bytes = 0  # estimate of the call holding the lock (the buffers and its temporaries)

    @property
    def params(self) -> SGMParams:
        """The parameters used for every frame."""
        return self._params

    def compute(self, left: Any, right: Any) -> DisparityMap:
        """Disparity of one rectified pair; see ``compute_disparity``."""
        if not self._lock.acquire(blocking=False):  # another thread is using the buffers
            # This call allocates a full set of its own next to the busy one: check both together.
            return _match(left, right, self._params, self._memory_checked, reserved=max(1, self._busy_bytes))
        try:
            self._busy_bytes = self._estimate(left)
            if self._workspace is None:
                self._workspace = kernels.Workspace()
            return _match(left, right, self._params, self._memory_checked, self._workspace)
        finally:
            self._busy_bytes = 0
            self._lock.release()

    def _estimate(self, image: Any) -> int:
        """Bytes a call on ``image`` uses (0 when it is no image: the call itself reports that)."""
        try:
            arr = np.asarray(image)
            return estimate_memory(tuple(arr.shape), self._params, dtype=arr.dtype)
        except (TypeError, ValueError):
            return 0

    def release(self) -> None:
        """Free the buffers kept between frames (the next frame allocates them again)."""
        with self._lock:
            self._workspace = None

    def __repr__(self) -> str:
        return f"StereoMatcher({self._params!r})"
