"""ROS 2 camera messages to arrays and rigs, and stamps: plain values, no ROS needed.

A message is anything with the message's fields as attributes (a decoded MCAP message, an ``rclpy`` message):

* :func:`image_from_msg`: ``sensor_msgs/Image`` (mono8, bgr8, rgb8, bgra8, rgba8, mono16 refused, bayer_*8,
  yuv422) or ``sensor_msgs/CompressedImage`` (any format OpenCV decodes) -> (H, W) or (H, W, 3) uint8.
* :func:`camera_info_values` -> K, D, R, P, size; :func:`rig_from_camera_info`: the left and right ``CameraInfo``
  -> a :class:`calib.RectifiedRig` (images already rectified: the P matrices; the baseline from the right camera's
  ``P[0,3] = -fx * B``) or, for raw images, a :class:`calib.StereoRig` to rectify.
* :func:`stamp_ns`, :func:`stamp_name`: a header stamp as nanoseconds and as a frame name.

Examples
--------
>>> from types import SimpleNamespace as M
>>> msg = M(encoding="rgb8", height=1, width=2, step=6, is_bigendian=0, data=bytes([1, 2, 3, 4, 5, 6]))
>>> image_from_msg(msg, "left").tolist()
[[[3, 2, 1], [6, 5, 4]]]
>>> stamp_name(M(sec=12, nanosec=5))
'12.000000005'
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

import calib

__all__ = ["ImageMessageError", "camera_info_values", "image_from_msg", "rig_from_camera_info", "stamp_name",
           "stamp_ns", "ENCODINGS"]


class ImageMessageError(ValueError):
    """An image or CameraInfo message that cannot be used (encoding, size, calibration); the message says which."""


#: ROS encodings read, with the OpenCV conversion to BGR (None: kept as it is). ROS names Bayer patterns by the
#: first row's colours, OpenCV by the second row's: ``bayer_rggb8`` is OpenCV's ``BayerBG`` (as ``cv_bridge``).
ENCODINGS: dict[str, tuple[int, int | None]] = {
    "mono8": (1, None),
    "8UC1": (1, None),
    "bgr8": (3, None),
    "8UC3": (3, None),
    "rgb8": (3, cv2.COLOR_RGB2BGR),
    "bgra8": (4, cv2.COLOR_BGRA2BGR),
    "rgba8": (4, cv2.COLOR_RGBA2BGR),
    "bayer_rggb8": (1, cv2.COLOR_BayerBG2BGR),
    "bayer_bggr8": (1, cv2.COLOR_BayerRG2BGR),
    "bayer_gbrg8": (1, cv2.COLOR_BayerGR2BGR),
    "bayer_grbg8": (1, cv2.COLOR_BayerGB2BGR),
    "yuv422": (2, cv2.COLOR_YUV2BGR_UYVY),
    "uyvy": (2, cv2.COLOR_YUV2BGR_UYVY),
    "yuv422_yuy2": (2, cv2.COLOR_YUV2BGR_YUY2),
    "yuyv": (2, cv2.COLOR_YUV2BGR_YUY2),
}


def stamp_ns(stamp: Any) -> int:
    """A ``builtin_interfaces/Time`` (``sec``, ``nanosec``) as integer nanoseconds."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def stamp_name(stamp: Any) -> str:
    """A stamp as a frame name, ``SEC.NANOSEC`` (nine digits: names sort in time order within a second's digits)."""
    return f"{int(stamp.sec)}.{int(stamp.nanosec):09d}"


def image_from_msg(msg: Any, what: str) -> np.ndarray:
    """The pixels of a ``sensor_msgs/Image`` or ``sensor_msgs/CompressedImage`` as uint8, BGR or grey.

    Parameters
    ----------
    msg : Image or CompressedImage message (``format`` marks a CompressedImage)
    what : str
        Named in errors (e.g. ``"/left/image_rect at 12.000000005"``).

    Returns
    -------
    (H, W) uint8 (mono8, a grey compressed image) or (H, W, 3) uint8 BGR.

    Raises
    ------
    ImageMessageError
        An encoding this cannot convert (the message lists those it can), data shorter than ``step * height``,
        or compressed data OpenCV cannot decode.
    """
    data = np.frombuffer(bytes(msg.data), dtype=np.uint8)
    if hasattr(msg, "format") and not hasattr(msg, "encoding"):
        image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
        if image is None:
            raise ImageMessageError(f"{what}: CompressedImage (format {msg.format!r}) cannot be decoded by OpenCV")
        if image.dtype != np.uint8:
            raise ImageMessageError(f"{what}: CompressedImage (format {msg.format!r}) holds {image.dtype} pixels; "
                                    "8-bit images are expected")
        if image.ndim == 3 and image.shape[2] == 4:
            image = cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
        return image
    encoding = str(msg.encoding)
    if encoding not in ENCODINGS:
        raise ImageMessageError(f"{what}: image encoding {encoding!r} cannot be converted; expected one of "
                                f"{', '.join(ENCODINGS)}")
    channels, code = ENCODINGS[encoding]
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    if height <= 0 or width <= 0 or step < width * channels:
        raise ImageMessageError(f"{what}: image of {width}x{height} with step {step} is not a valid {encoding} image "
                                f"(step must be >= width x {channels})")
    if data.size < step * height:
        raise ImageMessageError(f"{what}: image data holds {data.size} bytes, {encoding} {width}x{height} with step "
                                f"{step} needs {step * height}")
    rows = data[: step * height].reshape(height, step)[:, : width * channels]
    image = rows.reshape(height, width, channels) if channels > 1 else rows
    if code is not None:
        image = cv2.cvtColor(image, code)
    return np.ascontiguousarray(image)


def camera_info_values(msg: Any) -> dict[str, Any]:
    """The calibration of a ``sensor_msgs/CameraInfo``: ``K`` (3, 3), ``D`` (k,), ``R`` (3, 3), ``P`` (3, 4) float64,
    ``image_size`` (width, height), ``distortion_model``."""
    return {"K": np.asarray(msg.k, dtype=np.float64).reshape(3, 3),
            "D": np.asarray(msg.d, dtype=np.float64).reshape(-1),
            "R": np.asarray(msg.r, dtype=np.float64).reshape(3, 3),
            "P": np.asarray(msg.p, dtype=np.float64).reshape(3, 4),
            "image_size": (int(msg.width), int(msg.height)),
            "distortion_model": str(msg.distortion_model)}


def rig_from_camera_info(left: Any, right: Any, *, rectify: bool, what: str = "CameraInfo"
                         ) -> calib.RectifiedRig | calib.StereoRig:
    """The rig of a stereo pair from its two ``CameraInfo`` messages.

    ``rectify=False``: the images are rectified (``image_rect``), their geometry is the P matrices: focal
    ``P[0,0]``, principal points ``P[0,2]``, ``P[1,2]``, baseline ``-P_right[0,3] / P_right[0,0]`` metres.
    ``rectify=True``: the images are raw; K, D and the rectification rotations R with the right P give the
    cameras' relative pose (as :func:`calib.formats.ros.read_stereo_pair`), returned as a
    :class:`calib.StereoRig` to rectify.

    Raises
    ------
    ImageMessageError
        Sizes that differ, no baseline (a right ``P[0,3]`` of 0: the left camera's info given twice?), focal
        lengths that differ between the two P, or values the rig refuses (named).
    """
    lv, rv = camera_info_values(left), camera_info_values(right)
    if lv["image_size"] != rv["image_size"]:
        raise ImageMessageError(f"{what}: the left and right CameraInfo give different image sizes "
                                f"{lv['image_size']} and {rv['image_size']}")
    pl, pr = lv["P"], rv["P"]
    if not pr[0, 3] < 0 or not pr[0, 0] > 0:
        raise ImageMessageError(f"{what}: the right CameraInfo's P[0,3] is {pr[0, 3]:g}; a right camera's P holds "
                                "-fx * baseline (< 0). Is it the left camera's info, or are the topics swapped?")
    try:
        if not rectify:
            if abs(pl[0, 0] - pr[0, 0]) > 1e-6 * pl[0, 0] or abs(pl[1, 2] - pr[1, 2]) > 1e-3:
                raise ImageMessageError(f"{what}: the left and right P differ in focal length or cy "
                                        f"({pl[0, 0]:g}/{pr[0, 0]:g}, {pl[1, 2]:g}/{pr[1, 2]:g}): not a rectified "
                                        "pair (raw images? add --rectify)")
            return calib.RectifiedRig(focal_px=float(pl[0, 0]), cx_left=float(pl[0, 2]), cx_right=float(pr[0, 2]),
                                      cy=float(pl[1, 2]), baseline_m=float(-pr[0, 3] / pr[0, 0]),
                                      image_size=lv["image_size"])
        t_rect = np.linalg.solve(pr[:, :3], pr[:, 3]) - np.linalg.solve(pl[:, :3], pl[:, 3])
        return calib.StereoRig(K_left=lv["K"], dist_left=lv["D"], K_right=rv["K"], dist_right=rv["D"],
                               R=rv["R"].T @ lv["R"], T=rv["R"].T @ t_rect, image_size=lv["image_size"])
    except calib.CalibrationError as exc:
        raise ImageMessageError(f"{what}: {exc}") from None
