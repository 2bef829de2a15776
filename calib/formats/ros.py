"""ROS ``camera_info`` YAML files: one per camera; a left/right pair gives the raw stereo calibration.

Read with ``cv2.FileStorage`` (it copes with that simple format, with or without a ``%YAML`` header), so
PyYAML is not needed. Readers return plain values; ``StereoRig.from_ros`` builds the rig.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from calib.errors import CalibrationError
from calib.formats._common import PathLike
from calib.formats.opencv import OpenCVStorage

__all__ = ["read_ros_camera_info", "read_stereo_pair"]


def read_ros_camera_info(path: PathLike) -> dict[str, Any]:
    """One ROS ``camera_info`` YAML.

    Returns
    -------
    dict
        ``K`` (3, 3) float64, ``D`` (k,) float64, ``R`` (3, 3) float64 (identity when absent), ``P`` (3, 4)
        float64, ``image_size`` (width, height), ``distortion_model`` str, ``camera_name`` str, ``path`` Path.
    """
    st = OpenCVStorage(path, "ROS camera_info")
    model = st.string("distortion_model") if st.has("distortion_model") else "plumb_bob"
    if model not in ("plumb_bob", "rational_polynomial"):
        raise CalibrationError(f"{st.path}: key `distortion_model` is {model!r}; only plumb_bob and rational_polynomial are supported")
    out: dict[str, Any] = {
        "K": st.matrix("camera_matrix", (3, 3)),
        "D": st.vector("distortion_coefficients"),
        "R": st.matrix("rectification_matrix", (3, 3)) if st.has("rectification_matrix") else np.eye(3),
        "P": st.matrix("projection_matrix", (3, 4)),
        "image_size": st.image_size(None),
        "distortion_model": model,
        "camera_name": st.string("camera_name") if st.has("camera_name") else "",
        "path": st.path,
    }
    return out


def read_stereo_pair(left_yaml: PathLike, right_yaml: PathLike) -> dict[str, Any]:
    """The raw stereo calibration of the left and right ROS ``camera_info`` files of a stereo camera.

    ROS stores the stereo extrinsics as rectification rotations ``R`` and the right projection
    ``P[0, 3] = -fx' * baseline``; the relative pose is ``R = R_right^T R_left``, ``T = R_right^T t``.

    Returns
    -------
    dict
        ``K_left``, ``dist_left``, ``K_right``, ``dist_right``, ``R`` (float64), ``T`` (3,) float64 metres,
        ``image_size``: the arguments of ``StereoRig``.
    """
    left, right = read_ros_camera_info(left_yaml), read_ros_camera_info(right_yaml)
    if left["image_size"] != right["image_size"]:
        raise CalibrationError(f"{left['path']} and {right['path']} have different image sizes {left['image_size']} and {right['image_size']}")
    t_rect = np.linalg.solve(right["P"][:, :3], right["P"][:, 3]) - np.linalg.solve(left["P"][:, :3], left["P"][:, 3])
    if not np.linalg.norm(t_rect) > 0:
        raise CalibrationError(
            f"{right['path']}: key `projection_matrix` has no baseline (P[0,3] = 0): give the right camera's camera_info"
        )
    r_rel = right["R"].T @ left["R"]
    t_rel = right["R"].T @ t_rect
    return {"K_left": left["K"], "dist_left": left["D"], "K_right": right["K"], "dist_right": right["D"], "R": r_rel,
            "T": t_rel, "image_size": left["image_size"]}
