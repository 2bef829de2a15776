"""Per-pixel confidence of a measured disparity, from what the matcher already has (``DisparityMap.confidence``).

Two questions decide whether a measured disparity can be trusted, and the matcher has an answer to each:

* **Was there anything to match?** Where the left image has weak texture, the matching cost's minimum is mostly
  noise and the disparity comes from the neighbours along the aggregation paths (it is then right on a plane,
  a guess elsewhere). The matcher's own measure of this is the ``TEXTURE_WINDOW`` x ``TEXTURE_WINDOW`` window mean
  of ``|Sobel_x|`` of the left image, weak below ``TEXTURE_REFERENCE`` grey levels (the weak-texture penalties,
  ``SGMParams.weak_texture_gain``). The texture term is that mean over the reference, at most 1. The kernels do not
  keep the cost's uniqueness margin per pixel; the texture is what makes that margin small, and it costs nothing
  while matching.
* **Do both views agree?** ``e = |d(x) - d_right(x - round(d))|``, where the right view's disparity (an integer
  winner) is there (the default "full" left-right check computes it). Up to 0.5 px is the rounding of the right
  view's integer winner alone; the agreement term falls linearly from 1 at 0.5 px to 0 at 0.5 px beyond the
  check's threshold (``lr_check``: pixels past it are unknown already). Without a right view the term is 1.

``confidence = round(255 * texture * agreement)``, at least 1 on a measured pixel; 0 where nothing was measured
(NaN in ``DisparityMap.disparity``: unknown, or filled). A user thresholds it (128: texture at least half the
reference and the views within about 1 px).
"""

from __future__ import annotations

import cv2
import numpy as np

from stereo_classic.matching._kernels.cost import TEXTURE_REFERENCE, TEXTURE_WINDOW

__all__ = ["confidence_map", "texture_strength", "lr_agreement"]


def texture_strength(left_gray: np.ndarray) -> np.ndarray:
    """(H, W) float32 in 0..1: the window mean of ``|Sobel_x|`` over ``TEXTURE_REFERENCE``, at most 1 (the
    matcher's weak-texture measure, ``_kernels.texture.weak_texture_scale``, borders replicated)."""
    if not isinstance(left_gray, np.ndarray) or left_gray.ndim != 2 or left_gray.dtype != np.uint8:
        raise ValueError(f"`left_gray` must be an (H, W) uint8 array, got {type(left_gray).__name__} "
                         f"{getattr(left_gray, 'shape', None)} {getattr(left_gray, 'dtype', None)}")
    grad = np.abs(cv2.Sobel(left_gray, cv2.CV_32F, 1, 0, ksize=3, borderType=cv2.BORDER_REPLICATE))
    mean = cv2.blur(grad, (TEXTURE_WINDOW, TEXTURE_WINDOW), borderType=cv2.BORDER_REPLICATE)
    return np.minimum(mean * np.float32(1.0 / TEXTURE_REFERENCE), np.float32(1.0))


def lr_agreement(disparity: np.ndarray, disparity_right: np.ndarray, lr_check: float | None) -> np.ndarray:
    """(H, W) float32 in 0..1 (NaN where ``disparity`` is): 1 up to 0.5 px of left-right difference (the right
    view's integer rounding), then linearly to 0 at ``lr_check`` + 0.5 px (1.5 px without a check)."""
    h, w = disparity.shape
    limit = 1.0 if lr_check is None else float(lr_check)
    xs = np.arange(w, dtype=np.float32)[None, :]
    with np.errstate(invalid="ignore"):
        target = np.rint(xs - disparity)
    inside = np.isfinite(target) & (target >= 0) & (target <= w - 1)
    cols = np.where(inside, target, 0).astype(np.intp)
    right = np.take_along_axis(disparity_right, cols, axis=1)
    err = np.abs(disparity - right)
    err[~inside] = np.nan
    out = 1.0 - (err - 0.5) / max(limit, 1e-3)
    np.clip(out, 0.0, 1.0, out=out)
    out[np.isfinite(disparity) & ~np.isfinite(err)] = 0.0  # measured, but the right view has nothing there
    return out.astype(np.float32)


def confidence_map(disparity: np.ndarray, disparity_right: np.ndarray | None = None,
                   left_gray: np.ndarray | None = None, *, lr_check: float | None = 1.0) -> np.ndarray:
    """(H, W) uint8 confidence of the measured pixels of ``disparity`` (module docstring): 1..255 where finite,
    0 where NaN. A term whose input is None (no right view, no left image) counts as 1."""
    if not isinstance(disparity, np.ndarray) or disparity.ndim != 2:
        raise ValueError(f"`disparity` must be an (H, W) array, got {type(disparity).__name__} "
                         f"{getattr(disparity, 'shape', None)}")
    measured = np.isfinite(disparity)
    conf = np.ones(disparity.shape, np.float32)
    if left_gray is not None:
        if left_gray.shape != disparity.shape:
            raise ValueError(f"`left_gray` must have the shape of `disparity` {disparity.shape}, got {left_gray.shape}")
        conf *= texture_strength(left_gray)
    if disparity_right is not None:
        if disparity_right.shape != disparity.shape:
            raise ValueError(f"`disparity_right` must have the shape of `disparity` {disparity.shape}, "
                             f"got {disparity_right.shape}")
        conf *= np.nan_to_num(lr_agreement(disparity, disparity_right, lr_check), nan=0.0)
    out = np.rint(conf * 255.0).clip(1, 255).astype(np.uint8)
    out[~measured] = 0
    return out
