"""stereo_classic: classical stereo matching (numba SGM), file I/O, datasets, and object localisation.

Each block below belongs to one module; the public names are listed in ``__all__``.
"""

__version__ = "0.1.0"

__all__: list[str] = ["__version__"]

# --- io (file I/O, datasets, visualisation) ---
from stereo_classic.datasets import Scene, demo_scene, iter_scenes, load_scene  # noqa: E402
from stereo_classic.io import (  # noqa: E402
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
from stereo_classic.visualize import colorize, draw_boxes  # noqa: E402

__all__ += [
    "FileFormatError", "atomic_write", "read_image", "write_image", "read_pfm", "write_pfm",
    "read_kitti_disparity", "write_kitti_disparity", "read_scaled_disparity", "read_ply", "write_ply",
    "Scene", "load_scene", "iter_scenes", "demo_scene", "colorize", "draw_boxes",
]  # fmt: skip

# --- detectors (ONNX object detectors; the package itself is the leaf `detectors`) ---
from detectors import (  # noqa: E402
    COCO_CLASSES,
    Detections,
    ModelError,
    ModelNotFoundError,
    OnnxDetector,
    resolve_model,
)

__all__ += ["COCO_CLASSES", "Detections", "ModelError", "ModelNotFoundError", "OnnxDetector", "resolve_model"]

# --- sgm-api (stereo matcher: parameters, compute_disparity, DisparityMap, post-processing) ---
from stereo_classic.matcher import (  # noqa: E402
    DisparityMap,
    MemoryBudgetError,
    StereoInputError,
    StereoMatcher,
    compute_disparity,
    estimate_memory,
)
from stereo_classic.params import SGMParams  # noqa: E402
from stereo_classic.postprocess import fill_holes, filter_speckles  # noqa: E402

__all__ += [
    "SGMParams", "compute_disparity", "StereoMatcher", "DisparityMap", "estimate_memory", "MemoryBudgetError",
    "StereoInputError", "filter_speckles", "fill_holes",
]  # fmt: skip

# --- fusion (per-object distance, the whole pipeline, CLI run helpers) ---
from stereo_classic.fusion import (  # noqa: E402
    FusionInputError,
    LocalizedObjects,
    direction_phrase,
    localize,
    sparse_depth_reference,
)
from stereo_classic.pipeline import Localizer, PipelineResult, format_timings  # noqa: E402

__all__ += [
    "localize", "LocalizedObjects", "FusionInputError", "direction_phrase", "sparse_depth_reference",
    "Localizer", "PipelineResult", "format_timings",
]  # fmt: skip
