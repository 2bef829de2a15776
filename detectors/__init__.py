"""detectors: exported ONNX object detectors run with onnxruntime.

``OnnxDetector(model).detect(bgr_image) -> Detections`` with boxes in original-image pixels.
Leaf package: imports neither ``stereo_classic`` nor ``calib``.
"""

from detectors.classes import COCO_CATEGORY_IDS, COCO_CLASSES
from detectors.decoders import FAMILIES
from detectors.errors import InputSizeError, ModelError, ModelNotFoundError
from detectors.letterbox import Letterbox, Preprocessing
from detectors.models import KNOWN_MODELS, PACKAGED_MODELS, cache_dir, download_model, resolve_model
from detectors.nms import box_iou, nms
from detectors.onnx_detector import OnnxDetector
from detectors.results import Detections

__all__ = [
    "COCO_CATEGORY_IDS",
    "COCO_CLASSES",
    "Detections",
    "FAMILIES",
    "InputSizeError",
    "KNOWN_MODELS",
    "Letterbox",
    "ModelError",
    "ModelNotFoundError",
    "OnnxDetector",
    "PACKAGED_MODELS",
    "Preprocessing",
    "box_iou",
    "cache_dir",
    "download_model",
    "nms",
    "resolve_model",
]
