"""stereo_classic: from a calibrated stereo pair to objects with a distance, on a CPU.

The packages follow the data flow (the rig comes from :mod:`calib`, detections from :mod:`detectors`):

- :mod:`~stereo_classic.io`, :mod:`~stereo_classic.datasets`: stereo pairs, ground truth and files in
- :mod:`~stereo_classic.matching`: ``SGMParams`` -> :func:`compute_disparity` -> ``DisparityMap``
- :mod:`~stereo_classic.fusion`: detections + disparity + rig -> ``LocalizedObjects`` (``FusionParams``)
- :mod:`~stereo_classic.pipeline`: :class:`Localizer`, the whole per-frame pipeline
- :mod:`~stereo_classic.outputs`: pictures and every file ``run`` writes
- :mod:`~stereo_classic.sources`, :mod:`~stereo_classic.runner`: frames in, the pipeline over them into a folder
- :mod:`~stereo_classic.cli`: the command line, a thin layer over the above

The names below are the ones most programs need.
"""

__version__ = "0.1.0"

# --- pairs, ground truth and files in
from stereo_classic.datasets import Scene, demo_scene, iter_scenes, load_scene
from stereo_classic.io import (
    FileFormatError,
    atomic_write,
    read_image,
    read_kitti_disparity,
    read_pfm,
    read_ply,
    read_scaled_disparity,
    write_image,
    write_kitti_disparity,
    write_pfm,
    write_ply,
)

# --- disparity
from stereo_classic.matching import (
    DisparityMap,
    MemoryBudgetError,
    SGMParams,
    StereoInputError,
    StereoMatcher,
    compute_disparity,
    estimate_memory,
    fill_holes,
    filter_speckles,
)

# --- detections (the package itself is the leaf `detectors`)
from detectors import COCO_CLASSES, Detections, ModelError, ModelNotFoundError, OnnxDetector, resolve_model

# --- one distance per object
from stereo_classic.fusion import (
    FusionInputError,
    FusionParams,
    LocalizedObjects,
    direction_phrase,
    localize,
    sparse_depth_reference,
)

# --- the whole pipeline, and what it writes
from stereo_classic.pipeline import Localizer, PipelineResult, format_timings
from stereo_classic.outputs import FrameWriter, colorize, draw_boxes

__all__ = [
    "__version__",
    # pairs, ground truth and files
    "Scene", "load_scene", "iter_scenes", "demo_scene",
    "FileFormatError", "atomic_write", "read_image", "write_image", "read_pfm", "write_pfm",
    "read_kitti_disparity", "write_kitti_disparity", "read_scaled_disparity", "read_ply", "write_ply",
    # disparity
    "SGMParams", "compute_disparity", "StereoMatcher", "DisparityMap", "estimate_memory", "MemoryBudgetError",
    "StereoInputError", "filter_speckles", "fill_holes",
    # detections
    "COCO_CLASSES", "Detections", "ModelError", "ModelNotFoundError", "OnnxDetector", "resolve_model",
    # distance per object
    "FusionParams", "localize", "LocalizedObjects", "FusionInputError", "direction_phrase", "sparse_depth_reference",
    # pipeline and outputs
    "Localizer", "PipelineResult", "format_timings", "FrameWriter", "colorize", "draw_boxes",
]  # fmt: skip
