"""Letterbox an image into a detector's input and map boxes back exactly."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["Preprocessing", "Letterbox", "letterbox", "check_image"]


@dataclass(frozen=True)
class Preprocessing:
    """How a model family wants its input.

    Parameters
    ----------
    rgb : bool
        Swap the BGR image to RGB.
    scale : float
        Multiply pixel values (0-255) by this (1/255 for ultralytics).
    mean, std : tuple of 3 floats or None
        Per-channel ``(x - mean) / std`` after ``scale``, in the channel order fed to the model.
    pad_value : float
        Grey level (0-255) of the letterbox border before scaling.
    centre : bool
        True: image centred in the input (ultralytics, NanoDet); False: top-left (YOLOX).
    keep_ratio : bool
        False: stretch the image to the input size (no border).
    """

    rgb: bool = False
    scale: float = 1.0
    mean: tuple[float, float, float] | None = None
    std: tuple[float, float, float] | None = None
    pad_value: float = 114.0
    centre: bool = True
    keep_ratio: bool = True


@dataclass(frozen=True)
class Letterbox:
    """Where the original image went inside the model input.

    The original pixel edge coordinate ``x`` maps to ``pad_x + x * new_width / width``;
    :meth:`to_original` is the exact inverse.
    """

    width: int
    height: int
    new_width: int
    new_height: int
    pad_x: int
    pad_y: int

    def to_original(self, xyxy: np.ndarray) -> np.ndarray:
        """Boxes (N, 4) in model-input pixels -> original-image pixels, clipped to the image; float32."""
        b = np.asarray(xyxy, dtype=np.float64).reshape(-1, 4)
        sx = self.width / self.new_width
        sy = self.height / self.new_height
        out = np.empty_like(b)
        out[:, 0] = (b[:, 0] - self.pad_x) * sx
        out[:, 2] = (b[:, 2] - self.pad_x) * sx
        out[:, 1] = (b[:, 1] - self.pad_y) * sy
        out[:, 3] = (b[:, 3] - self.pad_y) * sy
        np.clip(out[:, 0::2], 0.0, float(self.width), out=out[:, 0::2])
        np.clip(out[:, 1::2], 0.0, float(self.height), out=out[:, 1::2])
        return out.astype(np.float32)


def check_image(image: object, parameter: str = "image") -> np.ndarray:
    """Check an image and return it as (H, W, 3) BGR uint8 (grey and BGRA are converted)."""
    if not isinstance(image, np.ndarray):
        raise ValueError(f"`{parameter}` must be a numpy array (H, W, 3) BGR uint8 or (H, W) grey uint8, "
                         f"got {type(image).__name__}")
    if image.dtype != np.uint8:
        raise ValueError(f"`{parameter}` must have dtype uint8 (as cv2.imread gives), got {image.dtype}; "
                         "convert 16-bit or float images to 8-bit first")
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if image.ndim == 2:
        if min(image.shape) < 1:
            raise ValueError(f"`{parameter}` is empty, shape {image.shape}")
        return cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_GRAY2BGR)
    if image.ndim != 3 or image.shape[2] not in (3, 4):
        raise ValueError(f"`{parameter}` must have shape (H, W), (H, W, 1), (H, W, 3) or (H, W, 4), got {image.shape}")
    if min(image.shape[:2]) < 1:
        raise ValueError(f"`{parameter}` is empty, shape {image.shape}")
    if image.shape[2] == 4:
        return cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_BGRA2BGR)
    return np.ascontiguousarray(image)  # OpenCV needs positive strides (no copy when already contiguous)


def letterbox(image: np.ndarray, size: tuple[int, int], prep: Preprocessing) -> tuple[np.ndarray, Letterbox]:
    """Resize ``image`` (H, W, 3) uint8 into ``size`` = (width, height) keeping its aspect ratio.

    Returns the padded uint8 image (height, width, 3) and the :class:`Letterbox` for the inverse.
    """
    h, w = image.shape[:2]
    in_w, in_h = size
    if prep.keep_ratio:
        r = min(in_w / w, in_h / h)
        nw = min(in_w, max(1, int(round(w * r))))
        nh = min(in_h, max(1, int(round(h * r))))
    else:
        nw, nh = in_w, in_h
    if prep.centre:
        px, py = (in_w - nw) // 2, (in_h - nh) // 2
    else:
        px, py = 0, 0
    if (nw, nh) != (w, h):
        resized = cv2.resize(image, (nw, nh), interpolation=cv2.INTER_LINEAR)
    else:
        resized = image
    if (nw, nh) == (in_w, in_h):
        out = np.ascontiguousarray(resized)
    else:
        out = np.full((in_h, in_w, 3), int(round(prep.pad_value)), dtype=np.uint8)
        out[py:py + nh, px:px + nw] = resized
    return out, Letterbox(w, h, nw, nh, px, py)
