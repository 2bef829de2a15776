"""Readers and writers of calibration files, one module per format, returning plain values.

- :mod:`~calib.formats.opencv`: OpenCV FileStorage YAML/XML (read and write)
- :mod:`~calib.formats.kitti`: KITTI object ``calib.txt`` and raw ``calib_cam_to_cam.txt``
- :mod:`~calib.formats.middlebury`: Middlebury ``calib.txt`` (baseline in millimetres)
- :mod:`~calib.formats.ros`: ROS ``camera_info`` YAML
- :mod:`~calib.formats.oakd`: the stereodemo / OAK-D JSON
- :mod:`~calib.formats.sniff`: which of them a file holds

Readers return dicts of numpy arrays, floats and ``(width, height)`` tuples (named as the arguments of
``StereoRig`` / ``RectifiedRig`` where they describe a rig), never rig objects: the rigs build themselves from
them (``StereoRig.from_opencv_yaml``, ``RectifiedRig.from_middlebury``, ...) and :func:`calib.load_rig` picks
the format. Every reader raises ``FileNotFoundError`` for a missing file and :class:`calib.CalibrationError`
(a ``ValueError``) naming the file and the key for anything else. Unit conversions (Middlebury's millimetres)
happen here and nowhere else. This package imports neither ``calib.rig`` nor ``calib.rectified``.
"""

from __future__ import annotations

from calib.formats import kitti, middlebury, oakd, opencv, ros, sniff
from calib.formats.kitti import KITTI_OBJECT_IMAGE_SIZE, read_kitti_calib
from calib.formats.middlebury import read_middlebury_calib
from calib.formats.oakd import read_oakd_calib
from calib.formats.ros import read_ros_camera_info
from calib.formats.sniff import sniff_format

__all__ = [
    "KITTI_OBJECT_IMAGE_SIZE",
    "kitti",
    "middlebury",
    "oakd",
    "opencv",
    "read_kitti_calib",
    "read_middlebury_calib",
    "read_oakd_calib",
    "read_ros_camera_info",
    "ros",
    "sniff",
    "sniff_format",
]
