"""The uncertainty of an object's disparity, and a second estimate of it from where the object meets the ground.

**Uncertainty.** The disparity of a consistent set is known to ``sigma_d**2 = SUBPIXEL_SIGMA_PX**2 + s**2 / n``:
``s`` the robust spread of its ``n`` values (1.4826 x their median absolute deviation) over ``sqrt(n)``, the
random part, and ``SUBPIXEL_SIGMA_PX`` the part that does not average away over the pixels of one surface: the
parabola subpixel fit pulls the disparities of a surface towards whole pixels by the same amount at every pixel
of that surface (pixel locking, up to about a quarter pixel on census-type costs), and a box holds one or two
surfaces. In depth, ``Z = f B / (d + doffs)``, so ``sigma_Z = Z**2 / (f B) * sigma_d``: 1 px at 13 px is 8 %.

**Ground contact.** A person or a car stands on the ground; the bottom of its box is where it meets the road, and
the road just below the box has a disparity that grows row by row (``dd/dv = B / h`` for a camera ``h`` above a
level road: 0.33 px per row on the driving rigs). A straight line through the road's disparities in a strip
below the box (the middle half of the box's width, a quarter of its height deep, at least
``CONTACT_MIN_ROWS`` rows), extrapolated to the box's bottom row, is the disparity where the object stands: an
estimate that uses none of the box's own pixels. It exists only where the strip is a ground (the line rises
downwards by more than three standard errors: a vertical surface, a nearer car hiding the object's foot, has no
slope); its uncertainty is the fit's and the box's bottom edge's (``BOX_EDGE_SIGMA`` of the box height times the
slope: a detector's box is looser than the object, by up to a tenth of its size at an edge; the KITTI frame's
detections match its labelled boxes at IoU 0.57 to 0.91, and a margin of 10 % on every side is IoU 0.69).
With a loose box the contact lies below the object's foot and reads nearer, so the estimate is a check of gross
errors (a car at 35 m, 40 px tall, read beyond about 47 m), not a second distance to average in.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["GROUND_CLASSES", "SUBPIXEL_SIGMA_PX", "BOX_EDGE_SIGMA", "AGREEMENT_SIGMAS", "CONTACT_MIN_ROWS",
           "disparity_sigma", "ground_contact"]

#: Labels (COCO names) of objects that stand on the ground and whose box bottom is their foot: persons and road
#: vehicles. Not furniture: indoors the strip below a chair is often a hand or a knee in front of it (the OAK-D
#: ``pov_hands`` frame), a surface that also rises downwards.
GROUND_CLASSES = frozenset({"person", "bicycle", "car", "motorcycle", "bus", "truck"})
#: The part of a surface's disparity error that is the same at each of its pixels (pixel locking), pixels.
SUBPIXEL_SIGMA_PX = 0.25
#: One standard uncertainty of a detector box's bottom edge, as a fraction of the box height (module docstring).
BOX_EDGE_SIGMA = 0.1
#: Two estimates disagree when they differ by more than this many combined standard uncertainties.
AGREEMENT_SIGMAS = 3.0
#: The fewest rows of road below a box for a contact estimate.
CONTACT_MIN_ROWS = 4


def disparity_sigma(values: np.ndarray) -> float:
    """One standard uncertainty (pixels) of the disparity of a set of ``values`` (pixels): module docstring."""
    values = np.asarray(values, dtype=np.float64)
    if values.size == 0:
        return math.nan
    spread = 1.4826 * float(np.median(np.abs(values - np.median(values))))
    return math.sqrt(SUBPIXEL_SIGMA_PX ** 2 + spread ** 2 / values.size)


def ground_contact(disp: np.ndarray, box: np.ndarray, min_pixels: int) -> tuple[float, float] | None:
    """``(disparity, sigma)`` in pixels where the box's bottom meets the ground (module docstring), or None
    where the strip below the box is not a ground or holds fewer than ``min_pixels`` measured values."""
    height, width = disp.shape
    x0, y0, x1, y1 = (float(v) for v in box)
    box_h, box_w = y1 - y0, x1 - x0
    if box_h <= 0 or box_w <= 0:
        return None
    r0 = int(math.ceil(y1))
    r1 = min(height, r0 + max(CONTACT_MIN_ROWS, int(math.ceil(0.25 * box_h))))
    c0, c1 = max(0, int(math.floor(x0 + box_w / 4))), min(width, int(math.ceil(x1 - box_w / 4)))
    if r1 - r0 < CONTACT_MIN_ROWS or c1 <= c0:
        return None
    strip = np.asarray(disp[r0:r1, c0:c1], dtype=np.float64)
    rows, _ = np.nonzero(np.isfinite(strip))
    if rows.size < max(min_pixels, 3):
        return None
    d = strip[np.isfinite(strip)]
    v = rows + r0 - (y1 - 0.5)  # rows below the box's last row (its bottom edge's pixel centre)
    keep = np.ones(d.size, bool)
    for _ in range(2):  # least squares, then again without the values beyond 3 robust deviations
        a = np.stack([np.ones(int(keep.sum())), v[keep]], axis=1)
        coef, *_ = np.linalg.lstsq(a, d[keep], rcond=None)
        res = d - (coef[0] + coef[1] * v)
        scale = 1.4826 * float(np.median(np.abs(res[keep]))) + 1e-6
        keep = np.abs(res) <= 3.0 * scale
        if int(keep.sum()) < max(min_pixels, 3):
            return None
    a = np.stack([np.ones(int(keep.sum())), v[keep]], axis=1)
    coef, *_ = np.linalg.lstsq(a, d[keep], rcond=None)
    res = d[keep] - a @ coef
    dof = max(1, int(keep.sum()) - 2)
    cov = np.linalg.pinv(a.T @ a) * float(res @ res) / dof
    alpha, slope = float(coef[0]), float(coef[1])
    se_alpha, se_slope = math.sqrt(max(cov[0, 0], 0.0)), math.sqrt(max(cov[1, 1], 0.0))
    if not (slope > 0 and slope > AGREEMENT_SIGMAS * se_slope and alpha > 0):
        return None  # no ground below the box (a vertical surface, or nothing rising downwards)
    sigma = math.sqrt(se_alpha ** 2 + (slope * BOX_EDGE_SIGMA * box_h) ** 2 + SUBPIXEL_SIGMA_PX ** 2)
    return alpha, sigma
