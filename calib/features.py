"""Residual vertical offset of a (supposedly) rectified pair, measured by feature matching."""

from __future__ import annotations

import logging

import cv2
import numpy as np

__all__ = ["vertical_offset", "match_features"]

log = logging.getLogger(__name__)

_MIN_MATCHES = 8


def _to_gray_u8(name: str, image: np.ndarray) -> np.ndarray:
    image = np.asarray(image)
    if image.ndim == 3 and image.shape[2] in (3, 4):
        image = cv2.cvtColor(image[..., :3], cv2.COLOR_BGR2GRAY) if image.dtype == np.uint8 else image[..., :3].mean(axis=2)
    elif image.ndim == 3 and image.shape[2] == 1:
        image = image[..., 0]
    if image.ndim != 2 or image.size == 0:
        raise ValueError(f"`{name}` must be a non-empty (H, W) or (H, W, 3) image, got shape {np.shape(image)}")
    if image.dtype != np.uint8:
        if not np.issubdtype(image.dtype, np.number) or image.dtype == np.bool_:
            raise ValueError(f"`{name}` must hold numbers, got dtype {image.dtype}")
        finite = np.isfinite(image)
        if not finite.any():
            raise ValueError(f"`{name}` has no finite pixel")
        lo, hi = float(np.min(image[finite])), float(np.max(image[finite]))
        scaled = (np.where(finite, image, lo) - lo) * (255.0 / (hi - lo) if hi > lo else 0.0)
        image = np.clip(scaled, 0, 255).astype(np.uint8)
    return np.ascontiguousarray(image)


def match_features(left: np.ndarray, right: np.ndarray, *, max_features: int = 3000,
                   ratio: float = 0.75) -> tuple[np.ndarray, np.ndarray]:
    """Matched ORB keypoints of two images (Lowe ratio test, then mutual best match).

    Returns
    -------
    pts_left, pts_right : (N, 2) float64, pixels (x, y); N may be 0.
    """
    if not (isinstance(max_features, int) and max_features > 0):
        raise ValueError(f"`max_features` must be a positive int, got {max_features!r}")
    if not 0.0 < ratio <= 1.0:
        raise ValueError(f"`ratio` must be in (0, 1], got {ratio!r}")
    gl, gr = _to_gray_u8("left", left), _to_gray_u8("right", right)
    orb = cv2.ORB_create(nfeatures=max_features)
    kl, dl = orb.detectAndCompute(gl, None)
    kr, dr = orb.detectAndCompute(gr, None)
    if dl is None or dr is None or len(kl) < 2 or len(kr) < 2:
        return np.empty((0, 2)), np.empty((0, 2))
    matcher = cv2.BFMatcher(cv2.NORM_HAMMING)
    forward = matcher.knnMatch(dl, dr, k=2)
    backward = {m[0].queryIdx: m[0].trainIdx for m in matcher.knnMatch(dr, dl, k=1) if m}
    pairs = []
    for m in forward:
        if len(m) < 2:
            continue
        best, second = m
        if best.distance < ratio * second.distance and backward.get(best.trainIdx) == best.queryIdx:
            pairs.append((best.queryIdx, best.trainIdx))
    if not pairs:
        return np.empty((0, 2)), np.empty((0, 2))
    idx = np.asarray(pairs)
    pl = np.asarray([kl[i].pt for i in idx[:, 0]], dtype=np.float64)
    pr = np.asarray([kr[i].pt for i in idx[:, 1]], dtype=np.float64)
    return pl, pr


def vertical_offset(left: np.ndarray, right: np.ndarray, *, max_features: int = 3000) -> float:
    """Median ``|y_left - y_right|`` in pixels over matched ORB features of a rectified pair.

    A well rectified pair gives well under 1 px (Middlebury Motorcycle: about 0.3 px). Matches whose vertical
    offset exceeds 5 % of the image height are treated as mismatches and left out.

    Parameters
    ----------
    left, right : (H, W) or (H, W, 3) images (uint8 BGR, or any real dtype: rescaled to 0-255)

    Returns
    -------
    float
        Median absolute vertical offset in pixels, or NaN when fewer than 8 features match (a soft failure:
        too little texture to tell).
    """
    pl, pr = match_features(left, right, max_features=max_features)
    if len(pl) < _MIN_MATCHES:
        log.debug("vertical_offset: only %d matches, cannot measure", len(pl))
        return float("nan")
    dy = np.abs(pl[:, 1] - pr[:, 1])
    height = np.shape(left)[0]
    dy = dy[dy <= max(3.0, 0.05 * height)]
    if len(dy) < _MIN_MATCHES:
        return float("nan")
    return float(np.median(dy))
