"""calib: the stereo rig (intrinsics, distortion, R/T), rectification, calibration file formats.

A leaf package: it imports neither ``stereo_classic`` nor ``detectors``.

- :class:`StereoRig`: raw cameras (K, distortion, R, T, image size) -> :meth:`StereoRig.rectify`
- :class:`RectifiedRig`: rectified geometry (focal, principal points, baseline) -> depth and 3D points
- :mod:`calib.formats`: readers/writers of OpenCV YAML/XML, KITTI, Middlebury, ROS camera_info, OAK-D JSON
  (plain values; the rigs' ``from_*`` constructors use them); :func:`load_rig` sniffs the format
- :func:`calibrate_stereo`: checkerboard or ChArUco image pairs -> (StereoRig, CalibrationReport)
"""

from __future__ import annotations

from calib.boards import CharucoBoard, CheckerBoard, detect_board
from calib.calibrate import CalibrationReport, calibrate_stereo
from calib.errors import CalibrationError
from calib.features import vertical_offset
from calib.formats import read_kitti_calib, read_middlebury_calib, read_oakd_calib
from calib.geometry import depth_from_disparity, disparity_from_depth, points_from_disparity, points_from_pixels
from calib.load import load_rig
from calib.rectified import RectificationWarning, RectifiedRig
from calib.rig import StereoRig

__all__ = [
    "CalibrationError",
    "CalibrationReport",
    "CharucoBoard",
    "CheckerBoard",
    "RectificationWarning",
    "RectifiedRig",
    "StereoRig",
    "calibrate_stereo",
    "depth_from_disparity",
    "detect_board",
    "disparity_from_depth",
    "load_rig",
    "points_from_disparity",
    "points_from_pixels",
    "read_kitti_calib",
    "read_middlebury_calib",
    "read_oakd_calib",
    "vertical_offset",
]
