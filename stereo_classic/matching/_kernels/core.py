"""The kernels' Python side: stripes, per-thread buffers, and the entry points (the threads: :mod:`.workers`).

``sgm_match`` cuts the image into stripes of about STRIPE_ROWS rows (fixed by the image height) and runs on
each either the one-sweep three-direction kernel of :mod:`.rowpass` (``paths=3``, the default: no sum volume)
or the fused forward and backward passes of :mod:`.aggregate` (4 and 8 paths), the workers (the calling thread
and pool threads) going down runs of stripes (3 paths) or taking them in turn, with buffers kept in a
:class:`Workspace` across calls;
``sum_volume`` and ``cost_volume`` expose intermediate results for the tests against
:mod:`stereo_classic.matching.reference`.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from stereo_classic.matching._kernels.aggregate import (
    _KIND,
    ALL_PATHS,
    FOUR_PATHS,
    PATH_NAMES,
    PATH_STEPS,
    THREE_PATHS,
    PassOutputs,
    PassPlan,
    PassSettings,
    ThreadBuffers,
    check_penalties,
    cost_scale,
    grad_mul,
    sgm_pass,
)
from stereo_classic.matching._kernels.aligned import ALIGN_SLACK, aligned_empty, aligned_zeros
from stereo_classic.matching._kernels.cost import (
    CENSUS,
    SAD,
    CostImages,
    CostSettings,
    RowCostBuffers,
    census_bits,
    census_quarters_rows,
    cost_volume_kernel,
    largest_p2,
    sobel_rows,
)
from stereo_classic.matching._kernels.features import FEATURES, check_features, with_features
from stereo_classic.matching._kernels.handout import HandOut, handout_allocator
from stereo_classic.matching._kernels.rowpass import (RowPassBuffers, StripePlan, path_slots, row_pass_buffers,
                                                     row_pass_bytes, slot_size, three_path_stripe)
from stereo_classic.matching._kernels.tags import disparity_tag
from stereo_classic.matching._kernels.texture import texture_table, weak_texture_rows
from stereo_classic.matching._kernels.workers import run_chained, run_stripes, run_tasks, usable_cpus

__all__ = ["sgm_match", "Workspace", "memory_bytes", "cost_volume", "sum_volume", "check_penalties", "cost_scale",
           "sgm_pass", "PassSettings", "PassPlan", "ThreadBuffers", "PassOutputs",
           "ALL_PATHS", "FOUR_PATHS", "THREE_PATHS", "PATH_NAMES", "PATH_STEPS", "PATH_MASKS",
           "STRIPE_ROWS", "WARMUP_ROWS", "stripes", "usable_cpus", "run_chained", "run_stripes", "run_tasks",
           "scratch_allocator", "workers_for", "DISPARITY_BLOCK", "MIN_DISPARITIES_ONE_SWEEP", "ONE_SWEEP_BLOCK",
           "padded_disparities"]

#: ``paths`` (the number of aggregation directions) -> the direction mask of the passes.
PATH_MASKS = {8: ALL_PATHS, 4: FOUR_PATHS, 3: THREE_PATHS}

# ----------------------------------------------------------------------------------------------
# driver

#: Target stripe height (rows) of the parallel decomposition, and the warm-up rows run above (forward) or
#: below (backward) a stripe by passes that have vertical or diagonal paths. Both depend on nothing but the
#: image height, so every thread count computes exactly the same thing. Measured on the shared scenes
#: (dense bad-2, Middlebury-style / driving): default matcher as one stripe (the exact full passes)
#: 6.8 / 18.9, in stripes of 48 rows with 16 warm-up rows 6.8 / 18.6; census 8 paths, bad-2 with unknown
#: as bad on the six Middlebury-style scenes: 16 warm-up rows are within 0.05 points of the full passes on
#: each, 8 warm-up rows lose up to 0.2 (Tsukuba). The one-sweep kernel (paths=3) with 8 warm-up rows: family means
#: within 0.15, but Cones 8.31 -> 9.00 (`python -m benchmarks --methods sc-default --quick`): kept at 16.
STRIPE_ROWS = 48
WARMUP_ROWS = 16


#: The kernels hold the disparities of a pixel in whole blocks: ``padded_disparities``. The indices past the range hold
#: the invalid cost: they never win and never change a path value in range, so the output is the same bit for bit
#: (tested). The volume kernels (4 and 8 paths) pad to DISPARITY_BLOCK; the one-sweep kernel (paths=3), compiled
#: once per D (``tags``), to ONE_SWEEP_BLOCK, at least MIN_DISPARITIES_ONE_SWEEP (one 512-bit vector).
DISPARITY_BLOCK = 32
ONE_SWEEP_BLOCK = 16
MIN_DISPARITIES_ONE_SWEEP = 32


def padded_disparities(num_disparities: int, paths: int = 3) -> int:
    """The disparities per pixel in the kernels' buffers: ``num_disparities`` rounded up to DISPARITY_BLOCK (paths 3:
    to ONE_SWEEP_BLOCK, at least MIN_DISPARITIES_ONE_SWEEP). The one-sweep kernel with 32 / 16 against the 64 / 32 it
    had (KITTI pair, 2 threads, ms medians of 11 alternations, the same output): 16: 20.7 -> 16.1, 32: 20.6 -> 15.9,
    48: 20.0 -> 16.3, 80: 22.9 -> 20.7, 112: 32.7 -> 24.9 (docs/matching.md, "Disparities in whole vector blocks").

    >>> [padded_disparities(n) for n in (16, 48, 64, 80, 96, 112, 128)]
    [32, 48, 64, 80, 96, 112, 128]
    >>> [padded_disparities(n, paths=8) for n in (16, 48, 64)]
    [32, 64, 64]
    """
    block = ONE_SWEEP_BLOCK if paths == 3 else DISPARITY_BLOCK
    least = MIN_DISPARITIES_ONE_SWEEP if paths == 3 else DISPARITY_BLOCK
    return max(least, -(-int(num_disparities) // block) * block)


def stripes(height: int) -> list[tuple[int, int]]:
    """The row ranges [y0, y1) the passes are split into: about STRIPE_ROWS rows each, evenly sized.

    >>> stripes(100)
    [(0, 50), (50, 100)]
    """
    n = max(1, int(round(height / STRIPE_ROWS)))
    edges = [round(i * height / n) for i in range(n + 1)]
    return [(edges[i], edges[i + 1]) for i in range(n) if edges[i + 1] > edges[i]]


def workers_for(threads: int, n_stripes: int) -> int:
    """How many workers run ``n_stripes`` stripes for ``threads`` threads: never more than stripes, nor than CPUs to
    run them (extra ones only time-slice: on 2 cores 8 workers cost 1.21x the CPU time of 1; same result for any)."""
    return max(1, min(int(threads), n_stripes, usable_cpus()))


def _thread_buffers(H: int, W: int, D: int) -> ThreadBuffers:
    paths, minima = [], []
    for n in (2, W + H + 1, W + 2 * H + 1, W + 2):  # slots of the H, V, A and B directions
        paths.append(path_slots(n, D, D + 2))
        minima.append(np.zeros(n, np.int16))
    return ThreadBuffers(
        *paths, *minima, crow=aligned_empty(W * D, np.int16), sums=aligned_zeros(W * D, np.int16),
        row_min=aligned_zeros(W, np.int16), k_index=np.arange(D, dtype=np.int16),
        right_sums=aligned_empty(W + D - 1, np.int16), right_k=aligned_empty(W + D - 1, np.int16),
        best=np.empty(W, np.int64), counts=np.zeros(3, np.int64),
        claim_cost=np.empty(W, np.int16), claim_k=np.empty(W, np.int16))


def _reset_buffers(b: ThreadBuffers, D: int) -> None:
    E = D + 2
    for P, M in ((b.path_h, b.min_h), (b.path_v, b.min_v), (b.path_a, b.min_a), (b.path_b, b.min_b)):
        P.reshape(-1, E)[:, 1:E - 1] = 0
        M[:] = 0


def _row_cost_buffers(W: int, D: int, kind: int, h: int, channels: int = 0, census: bool = False) -> RowCostBuffers:
    """``census``: ``FEATURES`` with a census term (its codes' quarters, as the census kinds)."""
    grad, feat = kind not in (CENSUS, FEATURES), kind == FEATURES  # feat: right rows and channel sums, float32
    L = 2 * (W + 2 * h + D - 1)  # two reversed right rows
    return RowCostBuffers(
        colsum=aligned_zeros((W + 2 * h) * D if grad else 1, np.int16), hsum=aligned_zeros(D, np.int16),
        rrev=aligned_zeros(4 * (W + D - 1) if kind not in (SAD, FEATURES) or census else 1, np.uint16),
        srev=aligned_zeros(L if grad else 1, np.int16), irev=aligned_zeros(L if kind == SAD else 1, np.int16),
        floor=aligned_zeros(D, np.int16), frev=np.zeros(max(1, channels) * (W + D - 1) if feat else 1, np.float32),
        facc=np.zeros(D if feat else 1, np.float32), tag=disparity_tag(D))


def _set_floor(bufs: RowCostBuffers, settings: CostSettings) -> None:
    """The cost floor of ``bufs``: 0 in the range, the invalid cost on the padding past it."""
    bufs.floor[:settings.num_disparities] = 0
    bufs.floor[settings.num_disparities:] = settings.invalid_cost


def _row_cost_bytes(W: int, D: int, kind: int, h: int, channels: int = 0, census: bool = False) -> int:
    if kind == FEATURES:
        return 4 * max(1, channels) * (W + D - 1) + 4 * D + 2 * D + 10 + (8 * (W + D - 1) if census else 0)
    grad = kind != CENSUS
    L = 2 * (W + 2 * h + D - 1)
    return (2 * (W + 2 * h) * D if grad else 2) + 2 * D + (8 * (W + D - 1) if kind != SAD else 2) + \
        (2 * L if grad else 2) + (2 * L if kind == SAD else 2) + 2 * D


def _reset_row_pass(b: RowPassBuffers, D: int, W: int, n_rows: int) -> None:
    """Zeros (the top path's start) in the slots the first row of a ``three_path_stripe`` call over ``n_rows`` rows
    reads; later rows read what the row before wrote (all ``W + H + 1`` slots: 0.2 ms of CPU a KITTI frame)."""
    b.path_v.reshape(-1, slot_size(D))[n_rows + 1:n_rows + 1 + W, 1:D + 1], b.min_v[n_rows + 1:n_rows + 1 + W] = 0, 0


class Workspace:
    """Buffers (sum volume, row buffers) kept between ``sgm_match`` calls on images of one size, so that repeated calls
    (video frames) skip allocating and page-faulting them, and the results' maps (``handout``). One per caller."""

    def __init__(self) -> None:
        self.S: np.ndarray | None = None
        self.bufs: list[ThreadBuffers] | None = None
        self._key: tuple | None = None
        self._scratch: dict[str, np.ndarray] = {}
        self.handout = HandOut()
        self.mirror: Workspace | None = None  # the mirrored pair's match (lr_mode="independent"), made on first use

    def fits(self, *key) -> bool:
        return self._key == key

    def keep(self, S, bufs, key) -> None:
        self.S, self.bufs, self._key = S, bufs, key

    def scratch(self, name: str, shape: tuple[int, ...], dtype) -> np.ndarray:
        """An array kept under ``name`` for one call's temporaries (contents undefined), made anew when the shape
        or dtype changes (a fresh array of a few MB costs page faults on every call: ``handout``)."""
        arr = self._scratch.get(name)
        if arr is None or arr.shape != tuple(shape) or arr.dtype != np.dtype(dtype):
            arr = aligned_empty(shape, dtype)
            self._scratch[name] = arr
        return arr

    def release(self) -> None:
        """Drop the buffers."""
        self.S = self.bufs = self._key = self.mirror = None
        self._scratch, self.handout = {}, HandOut()

    def arrays(self) -> list[np.ndarray]:
        """Every buffer kept (empty when none)."""
        arrays = list(self._scratch.values())
        if self.S is None:
            return arrays
        arrays.append(self.S)
        for pair in self.bufs:  # (RowCostBuffers, RowPassBuffers or ThreadBuffers) per worker
            for b in pair:
                arrays.extend(a for a in b if isinstance(a, np.ndarray))  # not the disparity tag
        return arrays

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in self.arrays()) + self.handout.free_bytes() + getattr(self.mirror, "nbytes", 0)


def scratch_allocator(workspace: Workspace | None) -> Callable[[str, tuple[int, ...], Any], np.ndarray]:
    """``workspace.scratch``, or a fresh ``aligned_empty`` array for every temporary without a workspace."""
    if workspace is not None:
        return workspace.scratch
    return lambda name, shape, dtype: aligned_empty(shape, dtype)


def memory_bytes(height: int, width: int, num_disparities: int, *, paths: int = 8, lr_check: bool = True,
                 cost: str = "census", block_size: int = 5, threads: int = 2, feature_channels: int = 0,
                 feature_census: bool = False) -> int:
    """Bytes ``sgm_match`` allocates for an image of this size, without the input images.

    4 and 8 paths: the int16 sum volume (2 * H * W * D) dominates; the rest is the two float32 outputs, the
    cost inputs (census codes or prefiltered images) and per-thread row buffers (about
    2 * (D + 2) * (3 W + 3 H) bytes per worker thread, at most one worker per stripe). 3 paths (the one-sweep
    kernel): no volume, W x D row buffers, the costs of WARMUP_ROWS rows and the top path's skewed vectors per
    worker (about 2 * D * (20 W + H) bytes). ``lr_check`` does not change it. D is the padded number
    (``padded_disparities``). ``cost="features"``: int8 features (2 * C * H * W, C = ``feature_channels``), and with
    ``feature_census`` (a census term) the census codes as the census costs have them.
    """
    H, W, D = int(height), int(width), padded_disparities(num_disparities, paths)
    kind = _KIND.get(cost, CENSUS)
    h = block_size // 2 if kind != CENSUS else 0
    E = D + 2
    workers = max(1, min(int(threads), len(stripes(H))))  # one set of row buffers per worker thread
    total = 2 * 4 * H * W  # left and right disparity
    total += 7 * H * W  # the penalty factors (uint8) and the int16 gradient and int32 sums they are made from
    if kind == FEATURES:
        total += 2 * int(feature_channels) * H * W
    if kind != SAD and (kind != FEATURES or feature_census):  # census codes (with a learned cost: its census term),
        total += 2 * 8 * H * W + 2 * (H + 20) * (W + 20)  # four uint16 quarters per pixel, and the padded images
    if kind not in (CENSUS, FEATURES):  # prefiltered images (gradient; and intensity for SAD)
        total += 2 * 2 * H * W * (2 if kind == SAD else 1) + 2 * (H + 2) * (W + 2) * 2
    total += ALIGN_SLACK * 32 * (1 + workers)  # where the arrays start (aligned.py): at most 32 a call and a worker
    if paths == 3:
        cost_state = _row_cost_bytes(W, D, kind, h, feature_channels, feature_census)
        return total + workers * (row_pass_bytes(H, W, D, WARMUP_ROWS) + cost_state)
    total += 2 * (H + workers) * W * D  # sum volume with one scratch row per worker
    slots = 2 + (W + H + 1) + (W + 2 * H + 1) + (W + 2)
    per_thread = 2 * E * slots + 2 * slots  # path vectors + minima
    per_thread += 2 * W * D + 2 * W * D + 2 * W + 2 * D + 2 * 2 * (W + D) + 8 * W  # row costs, row sums and
    # minima, k index, right view, best
    per_thread += _row_cost_bytes(W, D, kind, h, feature_channels, feature_census)  # the cost state
    return total + workers * per_thread


def _placeholder(dtype, ndim: int) -> np.ndarray:
    """A distinct small array for an input the cost does not read (the kernels assume no aliasing)."""
    return np.zeros((1,) * ndim, dtype)


def _prepare_cost(left, right, cost, census_window, threads=1, workspace=None, weak_texture_gain=1.0,
                  features=None, feature_census=False) -> CostImages:
    """The cost's input images of both views: census quarters and / or the x-Sobel channel (with the image itself
    for SAD), made in stripes of rows of both images on ``threads`` workers, into arrays of ``workspace``; and the
    left image's penalty factors (``weak_texture_scale``, by the left view's stripes). ``cost="features"``: ``features``
    is the pair (left, right) of (H, C, W) int8 arrays the row cost reads (``learned.FeatureModel.features``), and
    ``feature_census`` asks for the census codes of its census term."""
    H, W = left.shape
    w, h = census_window
    census = cost in ("census", "census+grad") or (cost == "features" and feature_census)
    sobel = cost in ("sad", "census+grad")

    scratch = scratch_allocator(workspace)

    def padded(side: str, img: np.ndarray, top: int, sides: int) -> np.ndarray:
        # replicated borders (np.pad's "edge"), into the workspace: cv2 takes 0.02 ms where np.pad took 0.15-0.25
        out = scratch(f"{side}_padded_{top}_{sides}", (H + 2 * top, W + 2 * sides), np.uint8)
        return cv2.copyMakeBorder(img, top, top, sides, sides, cv2.BORDER_REPLICATE, dst=out)

    views = []
    for side, img in (("left", left), ("right", right)):
        views.append((
            padded(side, img, h // 2, w // 2) if census else None,
            scratch(side + "_code", (H, 4, W), np.uint16) if census else _placeholder(np.uint16, 3),
            padded(side, img, 1, 1) if sobel or side == "left" else None,  # the left one for the penalty factors too
            scratch(side + "_sobel", (H, W), np.int16) if sobel else _placeholder(np.int16, 2),
            # no intensity term but for SAD: the kernels read no intensity image then
            img.astype(np.int16) if cost == "sad" else _placeholder(np.int16, 2)))

    scale = scratch("penalty_scale", (H, W), np.uint8)
    table = texture_table(weak_texture_gain)  # one entry (16) when the gain is 1 or less: no Sobel made

    def rows(t: int, task) -> None:
        side, (y0, y1) = task
        padded_c, code, padded_s, sob, _ = views[side]
        if census:
            census_quarters_rows(padded_c, w // 2, h // 2, y0, y1, code)
        if sobel:
            sobel_rows(padded_s, y0, y1, sob)
        if side == 0:
            weak_texture_rows(padded_s, y0, y1, table, scale)

    tasks = [(side, band) for side in (0, 1) for band in stripes(H) if census or sobel or side == 0]
    run_tasks(tasks, workers_for(threads, len(tasks)), rows)
    (_, lcode, _, lsob, lint), (_, rcode, _, rsob, rint) = views
    feats = check_features(features, H, W) if cost == "features" else ()  # else the placeholders
    return CostImages(left, lcode, rcode, lsob, lint, rsob, rint, scale, *feats)


def _cost_settings(cost: str, dmin: int, n_disp: int, block_size: int, census_window: tuple[int, int], p2_room: int,
                   outside_cost: int | None, shape: tuple[int, int], features=None, feature_similarity: str = "dot",
                   feature_census: float = 0.0) -> tuple[CostSettings, int]:
    """(settings, C): the row cost's settings (``sgm_match`` and ``cost_volume`` alike) and a learned cost's channel
    count (0 otherwise). SAD scaling and invalid cost leave room for ``p2_room``, the largest P2 at a pixel;
    ``outside_cost`` (None: never wins) scaled like the cost, at most cmax; ``cost="features"``: the checked
    ``features`` of an image of ``shape`` (H, W), their similarity and the census term's share
    (``features.with_features``; its multiplier ``feature_census_mul`` > 0 says the codes are needed)."""
    kind = _KIND[cost]
    shift, cmax = cost_scale(cost, block_size, census_window, p2_room)
    settings = CostSettings(kind=kind, min_disparity=dmin, half_block=block_size // 2 if kind != CENSUS else 0,
                            shift=shift, cmax=cmax, invalid_cost=cmax + 2 * (p2_room >> shift) + 1,
                            num_disparities=n_disp, grad_mul=grad_mul(block_size) if cost == "census+grad" else 0,
                            outside_cost=-1 if outside_cost is None else min(int(outside_cost) >> shift, cmax))
    return with_features(settings, features, feature_similarity, *shape, feature_census, census_bits(census_window))


def _run(left, right, *, cost, min_disparity, num_disparities, block_size, census_window, p1, p2,
         path_mask, adaptive_p2, uniqueness, lr_check, subpixel, threads, select=True, keep_sums=False,
         workspace=None, return_right=False, lr_mode="full", scratch_output=False, weak_texture_gain=1.0,
         features=None, feature_similarity="dot", p1_cross=None, cross_texture=True, outside_cost=None,
         feature_census=0.0, on_rows=None):
    if cost not in _KIND:
        raise ValueError(f"`cost` must be one of {sorted(_KIND)}, got {cost!r}")
    p1_cross = int(p1) if p1_cross is None else int(p1_cross)
    check_penalties(cost, block_size, census_window, int(p1), int(p2), weak_texture_gain, p1_cross)
    kind = _KIND[cost]
    H, W = left.shape
    n_disp = int(num_disparities)
    one_sweep = path_mask == THREE_PATHS  # left, top, right: the one-sweep kernel, no sum volume
    D = padded_disparities(n_disp, 3 if one_sweep else 8)  # per pixel in the buffers: the range, then padding
    dmin = int(min_disparity)
    h = block_size // 2 if kind != CENSUS else 0
    # the SAD cost's scaling and the invalid cost leave room for the largest P2 at a pixel (times the weak-texture
    # factor): the costs are those of cost_volume(p2=p2_top)
    p2_top = largest_p2(p2, weak_texture_gain)
    cost_settings, channels = _cost_settings(cost, dmin, n_disp, block_size, census_window, p2_top, outside_cost,
                                             (H, W), features, feature_similarity, feature_census)
    shift = cost_settings.shift
    p1s, p2s = int(p1) >> shift, int(p2) >> shift
    census_term = cost_settings.feature_census_mul > 0
    timings = {}

    t0 = time.perf_counter()
    images = _prepare_cost(left, right, cost, census_window, threads, workspace, weak_texture_gain, features,
                           census_term)
    t1 = time.perf_counter()
    timings["cost"] = (t1 - t0) * 1e3

    bands = stripes(H)
    n_workers = workers_for(threads, len(bands))
    key = (one_sweep, bool(keep_sums), H, W, D, kind, h, n_workers, channels, census_term)
    if workspace is not None and workspace.fits(*key):
        S, bufs = workspace.S, workspace.bufs
    else:
        if one_sweep:
            S = aligned_empty((H, W, D), np.int16) if keep_sums else np.zeros(1, np.int16)
        else:
            S = aligned_empty((H + n_workers, W, D), np.int16)  # + one scratch row per worker for warm-up rows
        # per worker: the cost state and the kernel's row buffers
        bufs = [(_row_cost_buffers(W, D, kind, h, channels, census_term),
                 row_pass_buffers(H, W, D, WARMUP_ROWS) if one_sweep else _thread_buffers(H, W, D))
                for _ in range(n_workers)]
        if workspace is not None:
            workspace.keep(S, bufs, key)
    for cbufs, _ in bufs:
        _set_floor(cbufs, cost_settings)
    counters = [b[1].counts for b in bufs]  # pixels rejected by uniqueness, by the LR check, won outside
    for c in counters:
        c[:] = 0
    disp = scratch_allocator(workspace if scratch_output else None)("disparity", (H, W), np.float32)
    dispR = handout_allocator(workspace)("disparity_right", (H, W), np.float32)  # returned whenever computed
    lr_thr = -1.0 if lr_check is None else float(lr_check)
    if lr_mode not in ("full", "opencv"):
        raise ValueError(f"`lr_mode` must be 'full' or 'opencv', got {lr_mode!r}")
    lr_claims = lr_check is not None and lr_mode == "opencv"
    right_view = bool(return_right) or (lr_check is not None and not lr_claims)
    settings = PassSettings(p1=p1s, p2=p2s, p1_cross=p1_cross >> shift, cross_texture=bool(cross_texture),
                            adaptive_p2=bool(adaptive_p2), path_mask=int(path_mask),
                            uniqueness=float(uniqueness), lr_threshold=lr_thr, lr_claims=bool(lr_claims),
                            subpixel=bool(subpixel), right_view=bool(right_view))
    out = PassOutputs(sums=S.reshape(-1), disparity=disp, disparity_right=dispR)
    # vertical or diagonal paths in a direction need warm-up rows beyond the stripe (bits 1-3 forward, 5-7 backward)
    warm_f = WARMUP_ROWS if path_mask & 0x0E else 0
    warm_b = WARMUP_ROWS if path_mask & 0xE0 else 0

    def sweep(t: int, i: int, after: bool) -> None:
        # one sweep down [y0 - warm, y1): the top path warms up, rows of [y0, y1) are resolved. A worker that ran
        # the stripe above reads the warm-up rows' costs it made (its last rows) instead of making them again.
        y0, y1 = bands[i]
        a = max(0, y0 - warm_f)
        cbufs, kbufs = bufs[t]
        _reset_row_pass(kbufs, D, W, y1 - a)
        cached = after and y0 - a == WARMUP_ROWS
        tail = WARMUP_ROWS if i + 1 < len(bands) and y1 - y0 >= WARMUP_ROWS else 0
        three_path_stripe(images, cost_settings, settings,
                          StripePlan(y_first=a, n_rows=y1 - a, warmup=y0 - a, keep_sums=bool(keep_sums),
                                     select=bool(select), cached=cached, tail=tail), cbufs, kbufs, out)

    def stripe(t: int, y0: int, y1: int) -> None:
        a = max(0, y0 - warm_f)
        cbufs, kbufs = bufs[t]
        # forward over [y0 - warm, y1) storing the partial sums of [y0, y1), then backward over
        # [y0, y1 + warm) adding its paths and selecting: both only touch the stripe's own rows
        _reset_buffers(kbufs, D)
        sgm_pass(images, cost_settings, settings,
                 PassPlan(y_first=a, n_rows=y1 - a, step=1, accumulate=False, select=False, init_cost=True,
                          keep_sums=bool(keep_sums), warmup=y0 - a, scratch_row=H + t), cbufs, kbufs, out)
        b = min(H, y1 + warm_b)
        _reset_buffers(kbufs, D)
        sgm_pass(images, cost_settings, settings,
                 PassPlan(y_first=b - 1, n_rows=b - y0, step=-1, accumulate=True, select=bool(select),
                          init_cost=True, keep_sums=bool(keep_sums), warmup=b - y1, scratch_row=H + t),
                 cbufs, kbufs, out)

    def rows_done(t: int, i: int) -> None:
        on_rows(disp, *bands[i])

    if one_sweep:
        run_chained(len(bands), n_workers, sweep, follow=rows_done if on_rows is not None and select else None)
    elif on_rows is not None and select:
        run_stripes(bands, n_workers, lambda t, y0, y1: (stripe(t, y0, y1), on_rows(disp, y0, y1)))
    else:
        run_stripes(bands, n_workers, stripe)
    t2 = time.perf_counter()
    timings["aggregate"] = (t2 - t1) * 1e3
    timings["select"] = 0.0  # fused into the second phase of "aggregate"
    timings["n_failed_uniqueness"] = int(sum(int(c[0]) for c in counters))
    timings["n_outside"] = int(sum(int(c[2]) for c in counters))
    timings["n_failed_lr"] = int(sum(int(c[1]) for c in counters))
    return disp, (dispR if right_view else None), (S[:H, :, :n_disp] if S.ndim == 3 else S), timings


_log = logging.getLogger("stereo_classic")
_compile_note_done = False


def _note_first_compile(paths: int = 3) -> None:
    """Say once per process when the kernels are about to be compiled (no numba cache yet)."""
    global _compile_note_done
    if _compile_note_done:
        return
    _compile_note_done = True
    kernel = three_path_stripe if paths == 3 else sgm_pass  # the one this call runs (the default: 3 paths)
    try:  # numba's cache index of that kernel; private attributes, so only a hint
        index = kernel._cache._cache_file._index_path
    except AttributeError:
        return
    if not os.path.exists(index):
        _log.info("compiling the stereo kernels once (see docs/matching.md, \"First call\"); later runs load them from "
                  "numba's cache")


def sgm_match(left: np.ndarray, right: np.ndarray, *, cost: str = "census", min_disparity: int = 0,
              num_disparities: int = 64, block_size: int = 5, census_window: tuple[int, int] = (9, 7),
              p1: int = 20, p2: int = 80, paths: int = 8, adaptive_p2: bool = False,
              uniqueness: float = 0.0, lr_check: float | None = 1.0, subpixel: bool = True,
              threads: int = 2, workspace: Workspace | None = None, return_right: bool = False,
              lr_mode: str = "full", scratch_output: bool = False, weak_texture_gain: float = 1.0,
              features: tuple[np.ndarray, np.ndarray] | None = None, feature_similarity: str = "dot",
              p1_cross: int | None = None, cross_texture: bool = True, outside_cost: int | None = None,
              feature_census: float = 0.0, on_rows: Callable[[np.ndarray, int, int], Any] | None = None
              ) -> tuple[np.ndarray, np.ndarray | None, dict[str, float]]:
    """Semi-global matching of a rectified grey pair (inputs already validated by the caller).

    Parameters
    ----------
    left, right : (H, W) uint8, C-contiguous, same shape.
    cost : "census" (census_window, Hamming distance), "sad" (block_size x block_size SAD on
        the x-Sobel + intensity/4 prefilter) or "census+grad" (census plus the block_size x block_size
        window mean of the x-Sobel difference, no intensity term). Penalties are in the units of the cost: bits for
        census, raw window SAD for "sad" (scaled internally with the cost so the sums fit int16).
    min_disparity, num_disparities : disparity range [min, min + num), d = x_left - x_right.
    p1, p2 : SGM penalties, 0 <= p1 <= p2.
    p1_cross, cross_texture : P1 of the paths that cross rows (None: p1), and whether the weak-texture factor scales it.
    outside_cost : cost of a match outside the right image (a winner there is unknown); None: never wins.
    paths : 8, 4 (left, right, top, bottom) or 3 (left, right, top: OpenCV MODE_SGBM_3WAY's directions).
    adaptive_p2 : P2 / (1 + |I(p) - I(p - r)|), never below P1.
    weak_texture_gain : at most this factor on P1 and P2 at pixels of weak texture (``texture.weak_texture_scale``,
        in sixteenths; 1 = the same penalties everywhere).
    uniqueness : reject when a disparity more than 1 away has sum * (1 - uniqueness) < best sum.
    lr_check : left-right check threshold in pixels; None = off.
    subpixel : parabola fit through the best sum and its two neighbours.
    lr_mode : "full" (default): reject when |d - d_right(x - d)| > lr_check, d_right being the winner-takes-all of
        the right view from the same sums. "opencv": StereoSGBM's collision check (``SGMParams.lr_mode``).
    threads : worker threads, >= 1: the image is cut into stripes of about STRIPE_ROWS rows (fixed by the
        height alone) that the workers take in turn; the result is the same for every thread count. At most
        one worker per stripe and per usable CPU (``usable_cpus``) runs.
    workspace : a ``Workspace`` to keep the big buffers between calls on one image size (None: per call).
    return_right : also return the right-view disparity (computed anyway for the "full" LR check).
    scratch_output : the left disparity may be an array of ``workspace``, overwritten by its next call (for a
        caller that makes a new map of it anyway).
    features, feature_similarity : ``cost="features"``: the int8 unit features of both views, (H, C, W) each
        (``learned.FeatureModel.features``), and "dot" or "l1" (``features.feature_cost_terms``: the cost units).
    feature_census : ``cost="features"``: the share (0 to 1) of the census cost (``census_window``) in the cost;
        0: the learned cost alone (``features.feature_row_cost``).
    on_rows : called as ``on_rows(disparity, y0, y1)`` once for every stripe [y0, y1) of ``stripes(H)`` as soon as
        its rows of the left map are final, by whichever worker is free (``run_chained``'s follow-ups); it may change
        those rows. Its time counts in "aggregate" (the matcher labels the speckle filter's regions there).

    Returns
    -------
    disparity : (H, W) float32, pixels, NaN where unknown.
    disparity_right : (H, W) float32 when computed (return_right, or the "full" LR check), else None: the right view's
        winner-takes-all disparity from the same sums (integer values), NaN where no disparity of
        the range maps inside the left image.
    timings : ms for "cost" (census transform / prefilter), "aggregate" (both passes, per-pixel costs and the fused
        selection), "select" (0: fused); pixel counts "n_failed_uniqueness", "n_failed_lr", "n_outside" (int).
    """
    _note_first_compile(paths)
    for name, img in (("left", left), ("right", right)):
        if not (isinstance(img, np.ndarray) and img.dtype == np.uint8 and img.ndim == 2 and img.size
                and img.flags.c_contiguous):
            got = f"{img.dtype} {img.shape}" if isinstance(img, np.ndarray) else type(img).__name__
            raise ValueError(f"`{name}` must be a non-empty C-contiguous (H, W) uint8 array, got {got}")
    if left.shape != right.shape:
        raise ValueError(f"`left` and `right` must have the same shape, got {left.shape} and {right.shape}")
    if not (isinstance(num_disparities, (int, np.integer)) and num_disparities >= 1):
        raise ValueError(f"`num_disparities` must be a positive integer, got {num_disparities!r}")
    if paths not in PATH_MASKS:
        raise ValueError(f"`paths` must be one of {sorted(PATH_MASKS)}, got {paths}")
    mask = PATH_MASKS[paths]
    disp, dispR, _, timings = _run(left, right, cost=cost, min_disparity=min_disparity,
                                   num_disparities=num_disparities, block_size=block_size,
                                   census_window=census_window, p1=p1, p2=p2, path_mask=mask,
                                   adaptive_p2=adaptive_p2, uniqueness=uniqueness, lr_check=lr_check,
                                   subpixel=subpixel, threads=threads, workspace=workspace,
                                   return_right=return_right, lr_mode=lr_mode,
                                   scratch_output=scratch_output and workspace is not None,
                                   weak_texture_gain=weak_texture_gain, features=features,
                                   feature_similarity=feature_similarity, p1_cross=p1_cross,
                                   cross_texture=cross_texture, outside_cost=outside_cost,
                                   feature_census=feature_census, on_rows=on_rows)
    return disp, dispR, timings


def sum_volume(left: np.ndarray, right: np.ndarray, *, path_mask: int = ALL_PATHS, threads: int = 2,
               **kwargs) -> np.ndarray:
    """Test entry: the (H, W, D) int16 sum over the directions in ``path_mask`` (see PATH_NAMES),
    computed by the same fused passes as ``sgm_match``. Keyword args as ``sgm_match``."""
    kw = dict(cost="census", min_disparity=0, num_disparities=64, block_size=5, census_window=(9, 7),
              p1=20, p2=80, adaptive_p2=False, uniqueness=0.0, lr_check=1.0, subpixel=True)
    kw.update(kwargs)
    _, _, S, _ = _run(left, right, path_mask=path_mask, threads=threads, keep_sums=True, **kw)
    return S


def cost_volume(left: np.ndarray, right: np.ndarray, *, cost: str = "census", min_disparity: int = 0,
                num_disparities: int = 64, block_size: int = 5, census_window: tuple[int, int] = (9, 7),
                p2: int = 80, features=None, feature_similarity: str = "dot", outside_cost=None,
                feature_census: float = 0.0) -> np.ndarray:
    """(H, W, D) int16 matching cost, entry [y, x, k] for disparity min_disparity + k (``outside_cost``: sgm_match's).

    Exactly the costs the passes use (``cost.row_cost``, row by row; SAD scaled by ``cost_scale``, which depends on
    p2);
    disparities whose match falls outside the right image hold the invalid cost
    ``cmax + 2 * p2_scaled + 1`` (learned: ``FEATURE_OUTSIDE``). Not on the fast path (it allocates the full volume).
    """
    if cost not in _KIND:
        raise ValueError(f"`cost` must be one of {sorted(_KIND)}, got {cost!r}")
    kind = _KIND[cost]
    H, W = left.shape
    n_disp = int(num_disparities)
    D = padded_disparities(n_disp)  # as the one-sweep kernel holds them
    settings, channels = _cost_settings(cost, int(min_disparity), n_disp, block_size, census_window, int(p2),
                                        outside_cost, (H, W), features, feature_similarity, feature_census)
    census_term = settings.feature_census_mul > 0
    images = _prepare_cost(left, right, cost, census_window, features=features, feature_census=census_term)
    out = np.empty((H, W, D), np.int16)
    bufs = _row_cost_buffers(W, D, kind, settings.half_block, channels, census_term)
    _set_floor(bufs, settings)
    cost_volume_kernel(images, settings, bufs, out)
    return np.ascontiguousarray(out[:, :, :n_disp])
