"""Post-processing of float32 disparity maps (NaN = unknown): speckle filter and optional hole filling.

Both functions take and return ``(H, W) float32`` disparity in pixels with NaN where unknown, and
never modify their input.

>>> import numpy as np
>>> d = np.full((20, 20), 10.0, np.float32); d[5, 5] = 30.0
>>> int(np.isnan(filter_speckles(d, max_size=4, max_diff=1.0)).sum())
1
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numba import njit

from stereo_classic.matching._kernels import core as _kernels
from stereo_classic.matching._kernels import speckle as _speckle
from stereo_classic.matching._kernels.core import Workspace
from stereo_classic.matching._kernels.handout import handout_allocator

__all__ = ["filter_speckles", "fill_holes", "fill_holes_marked", "median_measured"]

# Largest |scaled disparity| we put into int16 (leaves room below the sentinel).
_I16_LIMIT = 32000.0
# Region labels are int32 pixel indices.
_MAX_LABELS = 2**31 - 1


def _check_disparity(disparity: np.ndarray, name: str = "disparity") -> np.ndarray:
    arr = np.asarray(disparity)
    if arr.ndim != 2 or arr.dtype != np.float32:
        raise ValueError(f"`{name}` must be a (H, W) float32 array, got shape {arr.shape} dtype {arr.dtype}")
    return arr


def filter_speckles(disparity: np.ndarray, *, max_size: int, max_diff: float, threads: int = 1) -> np.ndarray:
    """Set small connected regions of similar disparity unknown (NaN).

    The regions are those of ``cv2.filterSpeckles`` on a scaled int16 copy (scale 16, i.e. 1/16 px resolution,
    or less where the disparity magnitude needs it): 4-connected pixels whose scaled values differ by at most
    ``max_diff`` scaled. They are found in stripes of rows on ``threads`` threads and joined across the stripes'
    borders (:mod:`stereo_classic.matching._kernels.speckle`): the same map as OpenCV's for any thread count.

    Parameters
    ----------
    disparity : (H, W) float32
        Pixels, NaN where unknown.
    max_size : int
        Regions of at most this many pixels are removed; 0 returns a copy unchanged.
    max_diff : float
        Largest disparity difference, pixels, between 4-neighbours of one region.
    threads : int
        Worker threads (at most one per stripe of about 48 rows and per CPU the process may use).

    Returns
    -------
    (H, W) float32
        A new map; removed pixels are NaN, as are values that were not finite (unless ``max_size`` is 0).
    """
    return _filter_speckles_counted(disparity, max_size=max_size, max_diff=max_diff, threads=threads)[0]


def _check_threads(threads: int) -> None:
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
        raise ValueError(f"`threads` must be a positive integer, got {threads!r}")


def _check_speckle_args(disparity: np.ndarray, max_size: int, max_diff: float, threads: int) -> np.ndarray:
    disp = _check_disparity(disparity)
    if isinstance(max_size, bool) or not isinstance(max_size, (int, np.integer)) or max_size < 0:
        raise ValueError(f"`max_size` must be a non-negative integer, got {max_size!r}")
    if not np.isfinite(max_diff) or max_diff < 0:
        raise ValueError(f"`max_diff` must be a non-negative number of pixels, got {max_diff!r}")
    _check_threads(threads)
    if disp.size >= _MAX_LABELS:
        raise ValueError(f"`disparity` has {disp.size} pixels; the speckle filter labels at most {_MAX_LABELS - 1} "
                         "(int32 region labels): filter it in parts")
    return np.ascontiguousarray(disp)


def finite_in_columns(disparity: np.ndarray, columns: np.ndarray) -> int:
    """How many pixels of ``disparity`` (H, W) are finite in the columns where ``columns`` (W,) bool is true: by
    its runs of columns, slices of the map (no copy of the columns)."""
    edges = np.flatnonzero(np.diff(np.concatenate(([0], columns.astype(np.int8), [0]))))
    return sum(int(np.count_nonzero(np.isfinite(disparity[:, a:b]))) for a, b in zip(edges[::2], edges[1::2]))


def _speckle_scale(lo: float, hi: float, max_diff: float) -> tuple[np.float32, int]:
    """(scale, scaled max_diff) of the speckle filter's int16 copy of a map whose finite values lie in [lo, hi]."""
    magnitude = max(abs(float(lo)), abs(float(hi)))
    scale = np.float32(16.0 if magnitude * 16.0 <= _I16_LIMIT else _I16_LIMIT / magnitude)
    return scale, int(round(max_diff * float(scale)))


def _label_regions(disp: np.ndarray, lo: float, hi: float, max_diff: float, n_workers: int, empty
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The speckle filter's regions of ``disp`` (finite values in [lo, hi]): labels, union-find parents and
    sizes, labelled stripe by stripe on ``n_workers`` workers and joined across the stripes' borders."""
    labelled = StripeLabels.of_range(disp.shape, lo, hi, max_diff, empty)
    _kernels.run_stripes(_kernels.stripes(disp.shape[0]), n_workers,
                         lambda t, y0, y1: labelled.label(disp, y0, y1))
    return labelled.joined(disp)


class StripeLabels:
    """The speckle filter's regions labelled stripe by stripe (``label``) and joined across the stripes (``joined``):
    by ``_label_regions`` on a finished map, and by the matcher while it makes the map (``label`` is its
    ``sgm_match(on_rows=...)``), for ``_speckle_fill_counted(..., labelled=...)``. The matcher's are made for maps
    whose values lie within ``bound`` pixels of 0 with ``bound * 16 <= _I16_LIMIT`` (``fits``): the scale is then 16
    whatever the values are, that of the finished map's labels (tested)."""

    def __init__(self, shape: tuple[int, int], max_diff: float, bound: float, workspace: Workspace | None = None):
        if not self.fits(bound):
            raise ValueError(f"`bound` must be between 0 and {_I16_LIMIT / 16.0:g} pixels, got {bound!r}")
        self._start(shape, _speckle_scale(-bound, bound, max_diff), _kernels.scratch_allocator(workspace))
        self.bound: float | None = float(bound)

    @classmethod
    def of_range(cls, shape: tuple[int, int], lo: float, hi: float, max_diff: float, empty) -> StripeLabels:
        """Labels of a map whose finite values lie in [lo, hi] (its scale; no bound), arrays from ``empty``."""
        labelled = cls.__new__(cls)
        labelled._start(shape, _speckle_scale(lo, hi, max_diff), empty)
        labelled.bound = None
        return labelled

    def _start(self, shape: tuple[int, int], scaling: tuple[np.float32, int], empty) -> None:
        self.shape = tuple(shape)
        self.scale, self.max_diff_scaled = scaling
        size = self.shape[0] * self.shape[1]  # the scaled copy, labels, union-find parents, sizes
        self.arrays = (empty("speckle_scaled", self.shape, np.int16), empty("speckle_labels", self.shape, np.int32),
                       empty("speckle_parent", (size,), np.int32), empty("speckle_sizes", (size,), np.int32))
        self.disparity: np.ndarray | None = None
        self._done = np.zeros(self.shape[0], np.bool_)

    @staticmethod
    def fits(bound: float) -> bool:
        return 0 <= bound and bound * 16.0 <= _I16_LIMIT

    def label(self, disparity: np.ndarray, y0: int, y1: int) -> None:
        """Label rows [y0, y1) of ``disparity`` (one stripe of ``core.stripes``; every call of one instance on the
        same map)."""
        if self.disparity is None:
            self.disparity = disparity
        if disparity is not self.disparity or disparity.shape != self.shape:
            raise ValueError("`disparity` must be the one map the labels are made of")
        _speckle.label_stripe(disparity, self.scale, self.max_diff_scaled, y0, y1, *self.arrays)
        self._done[y0:y1] = True

    def joined(self, disparity: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(labels, parents, sizes) of ``disparity`` once every stripe is labelled, joined across the stripes."""
        if disparity is not self.disparity or not self._done.all():
            raise ValueError("the labels are not those of `disparity`: a stripe was not labelled, or another map")
        bands = _kernels.stripes(self.shape[0])
        scaled, labels, parent, sizes = self.arrays
        _speckle.join_stripes(np.array([y0 for y0, _ in bands[1:]], np.int64), self.max_diff_scaled, scaled, labels,
                              parent, sizes)
        return labels, parent, sizes


def _filter_speckles_counted(disparity: np.ndarray, *, max_size: int, max_diff: float, threads: int = 1,
                             workspace: Workspace | None = None) -> tuple[np.ndarray, int]:
    """``filter_speckles``, and how many pixels of its result are known. ``workspace`` keeps the temporaries
    between calls."""
    disp = _check_speckle_args(disparity, max_size, max_diff, threads)
    lo, hi, n_valid = _finite_range(disp)
    if max_size == 0 or n_valid == 0:
        return disp.copy(), n_valid
    bands = _kernels.stripes(disp.shape[0])
    n_workers = _kernels.workers_for(threads, len(bands))
    empty = _kernels.scratch_allocator(workspace)
    labels, parent, sizes = _label_regions(disp, lo, hi, max_diff, n_workers, empty)
    out = np.empty_like(disp)
    kept = _kernels.run_stripes(bands, n_workers, lambda t, y0, y1: _speckle.apply_stripe(
        disp, int(max_size), y0, y1, labels, parent, sizes, out))
    return out, int(sum(kept))


def _speckle_fill_counted(disparity: np.ndarray, *, max_size: int, max_diff: float, threads: int = 1,
                          workspace: Workspace | None = None, bound: float | None = None,
                          labelled: StripeLabels | None = None
                          ) -> tuple[np.ndarray, np.ndarray, int, int, np.ndarray | None]:
    """``fill_holes_marked(filter_speckles(disparity, ...))`` in one pass after the labelling
    (``_speckle.apply_and_fill_stripe``: the filtered map, the row fill and the median are never stored whole),
    and how many pixels the filter kept and the fill filled: ``(out, holes, kept, filled, measured)``, ``measured``
    the filtered map (``out`` with NaN where ``holes``; None where ``max_size`` is 0 or nothing is known). The same
    numbers as the two steps one after the other (tested), for any thread count. ``bound``: the largest magnitude the
    map's values can have (the matcher's from its range); when it keeps the filter's scale at 16, the serial
    scan of the map for its range is skipped (the scale is 16 either way). Without the scan a map whose every
    value is infinite comes out NaN where the two steps return it as given: the matcher's unknown pixels are NaN,
    never infinite. ``labelled``: the regions of ``disparity`` made while it was matched, with ``bound`` (``max_diff``
    the same)."""
    disp = _check_speckle_args(disparity, max_size, max_diff, threads)
    if labelled is not None and (disp is not labelled.disparity or bound != labelled.bound or max_size == 0):
        raise ValueError("`labelled` must hold the labels of `disparity` made with the same `bound`, and "
                         "`max_size` > 0")
    if bound is not None and max_size > 0 and StripeLabels.fits(bound):
        lo, hi, n_valid = -float(bound), float(bound), -1  # n_valid unknown: a map without any is fine below
    else:
        lo, hi, n_valid = _finite_range(disp)
    if max_size == 0 or n_valid == 0:
        filtered, kept = _filter_speckles_counted(disp, max_size=max_size, max_diff=max_diff, threads=threads)
        out, holes, filled = _fill_holes_counted(filtered, threads=threads, n_valid=kept, workspace=workspace)
        return out, holes, kept, filled, None
    bands = _kernels.stripes(disp.shape[0])
    n_workers = _kernels.workers_for(threads, len(bands))
    empty = _kernels.scratch_allocator(workspace)
    if labelled is not None:
        labels, parent, sizes = labelled.joined(disp)
    else:
        labels, parent, sizes = _label_regions(disp, lo, hi, max_diff, n_workers, empty)
    W = disp.shape[1]
    scratch = [(empty(f"fill_rows_{t}", (3, W), np.float32), empty(f"fill_kept_{t}", (3, W), np.uint8),
                empty(f"fill_columns_{t}", (3, W + 2), np.float32)) for t in range(n_workers)]
    handout = handout_allocator(workspace)  # the result's maps: those of an earlier result nothing holds, or new
    out, holes, measured = (handout(name, disp.shape, dtype) for name, dtype in (
        ("filled_disparity", disp.dtype), ("filled", np.bool_), ("disparity", disp.dtype)))
    counts = _kernels.run_stripes(bands, n_workers, lambda t, y0, y1: _speckle.apply_and_fill_stripe(
        disp, int(max_size), y0, y1, labels, parent, sizes, out, holes, measured, *scratch[t]))
    return out, holes, int(sum(c[0] for c in counts)), int(sum(c[1] for c in counts)), measured


def _speckle_and_fill(disparity: np.ndarray, *, max_size: int, max_diff: float, fill: bool, threads: int = 1,
                      workspace: Workspace | None = None, bound: float | None = None,
                      labelled: StripeLabels | None = None
                      ) -> tuple[np.ndarray, np.ndarray | None, int, int, np.ndarray | None]:
    """The matcher's post-processing: the speckle filter (``max_size`` > 0) and the hole fill (``fill``), in one
    pass when both are on (``bound``, ``labelled`` as for ``_speckle_fill_counted``; only there). Returns (map,
    filled-pixel mask or None without the fill, pixels known after the filter, pixels filled, the map with NaN
    where filled when the one pass made it, else None)."""
    if max_size > 0 and fill:
        return _speckle_fill_counted(disparity, max_size=max_size, max_diff=max_diff, threads=threads,
                                     workspace=workspace, bound=bound, labelled=labelled)
    if labelled is not None:
        raise ValueError("`labelled` needs both the speckle filter (`max_size` > 0) and the fill (`fill`)")
    if max_size > 0:
        disparity, known = _filter_speckles_counted(disparity, max_size=max_size, max_diff=max_diff, threads=threads,
                                                    workspace=workspace)
    else:
        known = int(np.count_nonzero(np.isfinite(disparity)))
    if not fill:
        return disparity, None, known, 0, None
    out, holes, filled = _fill_holes_counted(disparity, threads=threads, n_valid=known, workspace=workspace)
    return out, holes, known, filled, None


def _finite_range(disp: np.ndarray) -> tuple[float, float, int]:
    """(smallest, largest, count) of the finite values of ``disp`` (NumPy's NaN-skipping reductions: as fast as a
    numba loop here, without its two seconds of compilation on the first call)."""
    flat = disp.ravel()
    if flat.size == 0:
        return 0.0, 0.0, 0
    lo, hi = float(np.fmin.reduce(flat)), float(np.fmax.reduce(flat))
    if math.isinf(lo) or math.isinf(hi):  # infinities too: only then a mask
        finite = flat[np.isfinite(flat)]
        return (float(finite.min()), float(finite.max()), finite.size) if finite.size else (0.0, 0.0, 0)
    if math.isnan(lo):  # every value NaN
        return 0.0, 0.0, 0
    return lo, hi, flat.size - int(np.count_nonzero(np.isnan(flat)))


def speckle_bytes(height: int, width: int) -> int:
    """Bytes ``filter_speckles`` allocates for a (height, width) map: the result, the scaled int16 copy, the
    labels and the union-find's parents and sizes."""
    return (4 + 2 + 4 + 4 + 4) * height * width


def speckle_fill_bytes(height: int, width: int) -> int:
    """Bytes the speckle filter and the hole fill allocate at most when run together (``_speckle_fill_counted``):
    the filter's (``speckle_bytes``), the filled-pixel mask and the measured map; the fill's rows are per worker (3
    rows)."""
    return speckle_bytes(height, width) + 5 * height * width


def fill_bytes(height: int, width: int) -> int:
    """Bytes ``fill_holes_marked`` allocates at most for a (height, width) map: the row fill, its still-unknown
    mask, the median, the result and its mask (14 bytes a pixel), and where rows without any known pixel need
    the masked path, its masks and a copy (12 more)."""
    return (14 + 12) * height * width


@njit(cache=True, nogil=True)
def _background_fill(disp, y0, y1, filled, still_unknown):  # pragma: no cover - numba
    """Rows [y0, y1): each unknown (not finite) pixel takes the smaller of the nearest known values to its left and
    right (the one that exists); rows without any known pixel get 0 and ``still_unknown``. Returns how many
    pixels are ``still_unknown``."""
    width = disp.shape[1]
    inf = np.float32(np.inf)
    zero = np.float32(0.0)
    n_unknown = 0
    for y in range(y0, y1):
        last = inf
        for x in range(width):  # left neighbour
            v = disp[y, x]
            if v - v == zero:  # finite
                last = v
                filled[y, x] = v
            else:
                filled[y, x] = last
        nxt = inf
        for x in range(width - 1, -1, -1):  # right neighbour, the smaller of the two
            v = disp[y, x]
            if v - v == zero:
                nxt = v
            else:
                b = filled[y, x]
                b = nxt if nxt < b else b
                unknown = b == inf
                still_unknown[y, x] = unknown
                filled[y, x] = zero if unknown else b
                n_unknown += unknown
                continue
            still_unknown[y, x] = False
    return n_unknown


@njit(cache=True, nogil=True)
def _take_median(disp, median, y0, y1, out, holes):  # pragma: no cover - numba
    """Rows [y0, y1): ``out`` = disp where finite, else the median; ``holes`` = not finite. Returns the holes."""
    width = disp.shape[1]
    zero = np.float32(0.0)
    n = 0
    for y in range(y0, y1):
        for x in range(width):
            v = disp[y, x]
            known = v - v == zero
            out[y, x] = v if known else median[y, x]
            holes[y, x] = not known
            n += not known
    return n


def fill_holes(disparity: np.ndarray, *, threads: int = 1) -> np.ndarray:
    """Fill unknown pixels from the background side of their row, then smooth the filled pixels.

    Each unknown pixel takes the smaller (farther, background) of the nearest known disparities to
    its left and right in the same row (or the one that exists). The filled pixels then take the
    3x3 median of the filled map; known pixels keep their value. Rows with no known pixel stay NaN.
    This is for users who need a dense map: the filled values are guesses, not measurements.

    Parameters
    ----------
    disparity : (H, W) float32
        Pixels, NaN where unknown.
    threads : int
        Worker threads for the row fill (the same map for any count).

    Returns
    -------
    (H, W) float32
        A new map.
    """
    return fill_holes_marked(disparity, threads=threads)[0]


def fill_holes_marked(disparity: np.ndarray, *, threads: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``fill_holes``, and the (H, W) bool mask of the pixels it filled (unknown before, known after)."""
    out, holes, _ = _fill_holes_counted(disparity, threads=threads)
    return out, holes


def _fill_holes_counted(disparity: np.ndarray, *, threads: int = 1, n_valid: int | None = None,
                        workspace: Workspace | None = None) -> tuple[np.ndarray, np.ndarray, int]:
    """``fill_holes_marked`` on ``threads`` threads (the same result for any count), and how many pixels it
    filled. ``n_valid``: the number of finite pixels, when the caller knows it; ``workspace`` keeps the
    temporaries between calls."""
    disp = np.ascontiguousarray(_check_disparity(disparity))
    _check_threads(threads)
    if n_valid is None:
        n_valid = _finite_range(disp)[2]
    if n_valid in (0, disp.size):
        return disp.copy(), np.zeros(disp.shape, np.bool_), 0
    bands = _kernels.stripes(disp.shape[0])
    n_workers = _kernels.workers_for(threads, len(bands))
    empty = _kernels.scratch_allocator(workspace)
    filled = empty("fill_filled", disp.shape, np.float32)
    still_unknown = empty("fill_still_unknown", disp.shape, np.bool_)
    n_unknown = sum(_kernels.run_stripes(bands, n_workers, lambda t, y0, y1: _background_fill(
        disp, y0, y1, filled, still_unknown)))
    median = cv2.medianBlur(filled, 3, dst=empty("fill_median", disp.shape, np.float32))
    if n_unknown == 0:  # every row has a known pixel: every hole takes the median of the filled map
        out = np.empty_like(disp)
        holes = np.empty(disp.shape, np.bool_)
        n_holes = sum(_kernels.run_stripes(bands, n_workers, lambda t, y0, y1: _take_median(
            disp, median, y0, y1, out, holes)))
        return out, holes, int(n_holes)
    valid = np.isfinite(disp)
    holes = ~valid & ~still_unknown
    out = disp.copy()
    out[holes] = filled[holes]
    # the median must not see the placeholder of rows without any known pixel
    near_empty = cv2.dilate(still_unknown.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    smoothed = holes & ~near_empty
    out[smoothed] = median[smoothed]
    out[still_unknown] = np.nan
    return out, holes, int(np.count_nonzero(holes))


# ----------------------------------------------------------------------------------------------
# the 3x3 median of the measured pixels


@njit(cache=True, nogil=True, inline="always")
def _cx(a, b):  # pragma: no cover - numba
    """(smaller, larger): a compare-exchange of the sorting network (+inf stands for "not measured")."""
    return (a, b) if a < b else (b, a)


@njit(cache=True, nogil=True)
def _pad_measured(disp, holes, y0, y1, pad):  # pragma: no cover - numba
    """Rows ``y0 .. y1 - 1`` of ``pad`` ((H + 2, W + 2), its border +inf): each measured pixel's value (finite and
    not a filled hole), +inf elsewhere."""
    W = disp.shape[1]
    inf = np.float32(np.inf)
    for y in range(y0, y1):
        for x in range(W):
            v = disp[y, x]
            pad[y + 1, x + 1] = v if (v == v) and not holes[y, x] else inf


@njit(cache=True, nogil=True)
def _median_rows(disp, pad, y0, y1, out):  # pragma: no cover - numba
    """Rows ``y0 .. y1 - 1`` of ``out``: each measured pixel (finite in ``pad``) the lower median of the measured
    values of its 3x3 neighbourhood, itself included (the ``(n - 1) // 2``-th smallest of the n); every other
    pixel ``disp``'s value. The 9 values go through a 25-comparator sorting network (+inf sorts last), one pixel
    per vector lane."""
    W = disp.shape[1]
    inf = np.float32(np.inf)
    for y in range(y0, y1):
        for x in range(W):
            v0 = pad[y, x]
            v1 = pad[y, x + 1]
            v2 = pad[y, x + 2]
            v3 = pad[y + 1, x]
            v4 = pad[y + 1, x + 1]
            v5 = pad[y + 1, x + 2]
            v6 = pad[y + 2, x]
            v7 = pad[y + 2, x + 1]
            v8 = pad[y + 2, x + 2]
            centre = v4
            n = ((v0 < inf) + (v1 < inf) + (v2 < inf) + (v3 < inf) + (v4 < inf) + (v5 < inf) + (v6 < inf)
                 + (v7 < inf) + (v8 < inf))
            v0, v1 = _cx(v0, v1)
            v3, v4 = _cx(v3, v4)
            v6, v7 = _cx(v6, v7)
            v1, v2 = _cx(v1, v2)
            v4, v5 = _cx(v4, v5)
            v7, v8 = _cx(v7, v8)
            v0, v1 = _cx(v0, v1)
            v3, v4 = _cx(v3, v4)
            v6, v7 = _cx(v6, v7)
            v0, v3 = _cx(v0, v3)
            v3, v6 = _cx(v3, v6)
            v0, v3 = _cx(v0, v3)
            v1, v4 = _cx(v1, v4)
            v4, v7 = _cx(v4, v7)
            v1, v4 = _cx(v1, v4)
            v2, v5 = _cx(v2, v5)
            v5, v8 = _cx(v5, v8)
            v2, v5 = _cx(v2, v5)
            v1, v3 = _cx(v1, v3)
            v5, v7 = _cx(v5, v7)
            v2, v6 = _cx(v2, v6)
            v4, v6 = _cx(v4, v6)
            v2, v4 = _cx(v2, v4)
            v2, v3 = _cx(v2, v3)
            v5, v6 = _cx(v5, v6)
            k = (n - 1) >> 1
            m = v0 if k == 0 else (v1 if k == 1 else (v2 if k == 2 else (v3 if k == 3 else v4)))
            out[y, x] = m if centre < inf else disp[y, x]


def median_measured(disparity: np.ndarray, holes: np.ndarray | None = None, *, threads: int = 1,
                    workspace: Workspace | None = None) -> np.ndarray:
    """Each measured pixel replaced by the lower median of the measured pixels of its 3x3 neighbourhood.

    Hirschmuller's semi-global matching filters its disparity with a 3x3 median (CVPR 2005, PAMI 2008; so do
    libSGM and Pandora): an isolated wrong winner among agreeing neighbours is outvoted, and the subpixel steps of
    a slanted surface are smoothed. Here it reads the *measured* pixels only: an unknown pixel stays unknown (and a
    hole the fill made, marked in ``holes``, keeps its value and is not read), so no measurement is invented or
    lost; with an even number n of measured neighbours it takes the lower of the two middle values (the
    ``(n - 1) // 2``-th smallest), a value that was measured. Stripes of rows on ``threads`` threads, the same map
    for any count.

    Parameters
    ----------
    disparity : (H, W) float32
        Pixels, NaN where unknown (and, with ``holes``, the fill's values there).
    holes : (H, W) bool, optional
        Pixels that are not measurements (filled holes): neither changed nor read.
    threads : int
        Worker threads.

    Returns
    -------
    (H, W) float32
        A new map.

    >>> d = np.full((5, 5), 10.0, np.float32); d[2, 2] = 30.0; d[0, 0] = np.nan
    >>> m = median_measured(d)
    >>> float(m[2, 2]), bool(np.isnan(m[0, 0]))
    (10.0, True)
    """
    disp = np.ascontiguousarray(_check_disparity(disparity))
    _check_threads(threads)
    H, W = disp.shape
    if holes is None:
        holes = np.zeros((H, W), np.bool_)
    elif holes.shape != disp.shape or holes.dtype != np.bool_:
        raise ValueError(f"`holes` must be a (H, W) bool array like `disparity` ({H} x {W}), got shape "
                         f"{holes.shape} dtype {holes.dtype}")
    empty = _kernels.scratch_allocator(workspace)
    pad = empty("median_pad", (H + 2, W + 2), np.float32)
    pad[0, :] = pad[-1, :] = pad[:, 0] = pad[:, -1] = np.inf
    out = handout_allocator(workspace)("median_disparity", disp.shape, disp.dtype)  # a result's map
    bands = _kernels.stripes(H)
    n_workers = _kernels.workers_for(threads, len(bands))
    _kernels.run_stripes(bands, n_workers, lambda t, y0, y1: _pad_measured(disp, holes, y0, y1, pad))
    _kernels.run_stripes(bands, n_workers, lambda t, y0, y1: _median_rows(disp, pad, y0, y1, out))
    return out


def median_bytes(height: int, width: int) -> int:
    """Bytes ``median_measured`` allocates: the padded copy and the output (and a holes mask when none is given)."""
    return 4 * (height + 2) * (width + 2) + 4 * height * width + height * width
