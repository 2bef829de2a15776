"""The stereo matcher: rectified pair -> disparity map, by semi-global matching (numba kernels).

Modules, in the order the data flows:

* ``params``: ``SGMParams``, every setting of the matcher in one frozen, self-checking dataclass
  (with the command-line help of each field).
* ``matcher``: ``compute_disparity`` / ``StereoMatcher`` (input checks, grey conversion, memory
  budget, the kernels, post-processing) and the result object ``DisparityMap``.
* ``learned``: learned matching costs, a Siamese feature network (ONNX; MC-CNN fast shipped in ``data/``) whose
  int8 features the kernels compare a row at a time (``cost="mccnn"`` / ``"features"``).
* ``postprocess``: ``filter_speckles`` and ``fill_holes`` on float32 disparity maps.
* ``_kernels``: the numba kernels (``core``: the fused passes; ``cost``: census, SAD and the gradient term;
  ``intrinsics``: int16 arithmetic as LLVM operations); ``reference``: their slow numpy reference.

>>> import numpy as np
>>> from stereo_classic.matching import SGMParams, compute_disparity
>>> right = np.random.default_rng(1).integers(0, 256, (32, 64), dtype=np.uint8)
>>> dmap = compute_disparity(np.roll(right, 4, axis=1), right, SGMParams(num_disparities=8))
>>> dmap.disparity.shape, dmap.disparity.dtype.name
((32, 64), 'float32')
"""

from __future__ import annotations

from stereo_classic.matching.matcher import (
    SUPPORTED_DTYPES,
    DisparityMap,
    MemoryBudgetError,
    StereoInputError,
    StereoMatcher,
    compute_disparity,
    estimate_memory,
    load_kernels,
    to_gray_uint8,
)
from stereo_classic.matching.learned import FeatureModelError
from stereo_classic.matching.params import (
    COSTS,
    FEATURE_SIMILARITIES,
    LEARNED_COSTS,
    LR_MODES,
    MAX_BLOCK_SIZE,
    MAX_NUM_DISPARITIES,
    MAX_PENALTY,
    MEMORY_LIMIT_ENV,
    SGMParams,
    default_memory_limit,
    parse_bytes,
    parse_census_window,
    parse_lr_check,
)
from stereo_classic.matching.postprocess import fill_holes, filter_speckles

__all__ = [
    # parameters
    "SGMParams",
    "parse_bytes",
    "parse_census_window",
    "parse_lr_check",
    "default_memory_limit",
    "MEMORY_LIMIT_ENV",
    "COSTS",
    "LEARNED_COSTS",
    "FEATURE_SIMILARITIES",
    "FeatureModelError",
    "LR_MODES",
    "MAX_BLOCK_SIZE",
    "MAX_NUM_DISPARITIES",
    "MAX_PENALTY",
    # matching
    "compute_disparity",
    "StereoMatcher",
    "DisparityMap",
    "estimate_memory",
    "load_kernels",
    "to_gray_uint8",
    "StereoInputError",
    "MemoryBudgetError",
    "SUPPORTED_DTYPES",
    # post-processing
    "filter_speckles",
    "fill_holes",
]
