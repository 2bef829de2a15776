"""Which calibration format a file holds, recognised by its content (not its name)."""

from __future__ import annotations

import re
from typing import Literal

from calib.errors import CalibrationError
from calib.formats._common import PathLike, read_text
from calib.formats.opencv import read_keys

__all__ = ["FormatName", "sniff_format"]

_EXPECTED = "expected OpenCV YAML/XML with K1/D1/K2/D2/R/T or P1/P2/Q, KITTI, Middlebury calib.txt or OAK-D JSON"
# a YAML mapping key at the start of a line ("K1: !!opencv-matrix", "image_width: 640")
_YAML_KEY_RE = re.compile(r"^[A-Za-z_][\w.-]*\s*:(\s|$)", re.MULTILINE)

#: What :func:`sniff_format` answers.
FormatName = Literal["oakd", "middlebury", "kitti", "opencv_stereo", "opencv_rectified"]


def sniff_format(path: PathLike) -> FormatName:
    """The format of a calibration file.

    - ``"oakd"``: JSON (the text starts with ``{``), the stereodemo / OAK-D layout
    - ``"middlebury"``: text with a ``cam0=`` line
    - ``"kitti"``: text (not YAML/XML) with a ``P2:`` or ``P_rect_02:`` line of numbers
    - ``"opencv_stereo"``: OpenCV YAML/XML with ``K1``/``M1`` (raw cameras)
    - ``"opencv_rectified"``: OpenCV YAML/XML with ``P1`` and ``P2``, or ``Q``

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    CalibrationError
        A single ROS ``camera_info`` file (it describes one camera), or no format recognised (the message
        lists the keys found).
    """
    p, text = read_text(path, "calibration")
    head = text.lstrip()
    if head.startswith("{"):
        return "oakd"
    if re.search(r"^\s*cam0\s*=", text, re.MULTILINE):
        return "middlebury"
    if not head.startswith(("%YAML", "<")) and re.search(r"^(P_rect_0\d|P\d):[ \t]*[-+.\d]", text, re.MULTILINE):
        return "kitti"
    if not head.startswith(("%YAML", "<", "---")) and not _YAML_KEY_RE.search(text):
        first = head.splitlines()[0][:60] if head else ""
        raise CalibrationError(
            f"{p}: not a calibration file: {_EXPECTED}; its first line is {first!r}")
    keys = read_keys(p)
    if any(k in keys for k in ("K1", "M1", "cameraMatrix1", "camera_matrix_left")):
        return "opencv_stereo"
    if "P1" in keys and "P2" in keys or "Q" in keys:
        return "opencv_rectified"
    if "camera_matrix" in keys:
        raise CalibrationError(f"{p}: a ROS camera_info file describes one camera: use StereoRig.from_ros(left_yaml, right_yaml)")
    raise CalibrationError(f"{p}: unrecognised calibration file ({_EXPECTED}); keys found: {', '.join(keys[:10])}")
