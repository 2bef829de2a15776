"""The offline demo scene: Middlebury 2014 Motorcycle as scikit-image ships it.

Example
-------
>>> from stereo_classic.datasets import demo_scene
>>> scene = demo_scene()
>>> scene.left.shape, scene.gt_disparity.dtype, round(scene.rig.baseline_m, 6)
((500, 741, 3), dtype('float32'), 0.193001)
"""

from __future__ import annotations

import cv2
import numpy as np

from calib import RectifiedRig
from stereo_classic.datasets.scene import Scene, _range_from_gt

__all__ = ["DEMO_BASELINE_M", "DEMO_CX_LEFT_PX", "DEMO_CY_PX", "DEMO_DOFFS_PX", "DEMO_FOCAL_PX", "demo_scene"]

#: Rig of ``skimage.data.stereo_motorcycle`` (Middlebury 2014 Motorcycle at 741 x 500).
DEMO_FOCAL_PX = 994.978
DEMO_BASELINE_M = 0.193001
DEMO_DOFFS_PX = 31.086
DEMO_CX_LEFT_PX = 311.193
DEMO_CY_PX = 254.877


def demo_scene() -> Scene:
    """The Middlebury Motorcycle pair that ships with scikit-image (works offline).

    ``skimage.data.stereo_motorcycle()`` returns RGB images and a disparity with ``inf`` for unknown;
    here they become BGR and NaN. Rig as ``stereo_motorcycle.__doc__`` gives it: f = 994.978 px,
    baseline 0.193001 m, principal point x 311.193 px, y 254.877 px, dx (doffs) 31.086 px, so
    ``cx_left = 311.193``, ``cx_right = cx_left + doffs``, ``cy = 254.877``.
    """
    from skimage import data

    rgb_left, rgb_right, disp = data.stereo_motorcycle()
    left = np.ascontiguousarray(cv2.cvtColor(rgb_left, cv2.COLOR_RGB2BGR))
    right = np.ascontiguousarray(cv2.cvtColor(rgb_right, cv2.COLOR_RGB2BGR))
    gt = np.where(np.isfinite(disp), disp, np.nan).astype(np.float32)
    h, w = gt.shape
    rig = RectifiedRig(
        focal_px=DEMO_FOCAL_PX,
        cx_left=DEMO_CX_LEFT_PX,
        cx_right=DEMO_CX_LEFT_PX + DEMO_DOFFS_PX,
        cy=DEMO_CY_PX,
        baseline_m=DEMO_BASELINE_M,
        image_size=(w, h),
    )
    return Scene("motorcycle_skimage", left, right, gt, None, rig, None, _range_from_gt(gt), None, "demo", None)
