"""Write small rosbag2 (MCAP) recordings for the tests: a stereo pair repeated at stamps, with CameraInfo."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np

from stereo_classic.ros.msgdefs import MSGDEFS

LEFT, RIGHT = "/stereo/left/image_rect", "/stereo/right/image_rect"
LEFT_INFO, RIGHT_INFO = "/stereo/left/camera_info", "/stereo/right/camera_info"


def header(ns: int, frame_id: str = "left_camera") -> dict[str, Any]:
    return {"stamp": {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}, "frame_id": frame_id}


def image_msg(image: np.ndarray, ns: int, encoding: str = "bgr8") -> dict[str, Any]:
    if encoding == "rgb8":
        image = cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
    elif encoding == "mono8" and image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    image = np.ascontiguousarray(image)
    h, w = image.shape[:2]
    return {"header": header(ns), "height": h, "width": w, "encoding": encoding, "is_bigendian": 0,
            "step": image.strides[0], "data": image.tobytes()}


def compressed_msg(image: np.ndarray, ns: int) -> dict[str, Any]:
    ok, data = cv2.imencode(".png", image)
    assert ok
    return {"header": header(ns), "format": "png", "data": data.tobytes()}


def info_msg(P: np.ndarray, size: tuple[int, int], ns: int) -> dict[str, Any]:
    K = P[:, :3]
    return {"header": header(ns), "height": size[1], "width": size[0], "distortion_model": "plumb_bob",
            "d": [0.0] * 5, "k": [float(v) for v in K.ravel()], "r": [float(v) for v in np.eye(3).ravel()],
            "p": [float(v) for v in P.ravel()], "binning_x": 0, "binning_y": 0,
            "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0, "do_rectify": False}}


def write_bag(path: Path, messages: list[tuple[str, str, dict[str, Any], int]]) -> Path:
    """``messages``: (topic, type, message dict, log time ns), written in the order given."""
    from mcap_ros2.writer import Writer

    with open(path, "wb") as f:
        writer = Writer(f)
        schemas: dict[str, Any] = {}
        for topic, kind, msg, log_time in messages:
            if kind not in schemas:
                schemas[kind] = writer.register_msgdef(kind, MSGDEFS[kind])
            writer.write_message(topic, schemas[kind], msg, log_time=log_time, publish_time=log_time)
        writer.finish()
    return path


def stereo_bag(path: Path, left: np.ndarray, right: np.ndarray, rig: Any, stamps: list[int], *,
               compressed: bool = False, camera_info: bool = True, extra: list | None = None,
               left_encoding: str = "bgr8") -> Path:
    """A bag of the pair at each stamp (left, right, and the two CameraInfo), plus ``extra`` messages."""
    kind = "sensor_msgs/msg/CompressedImage" if compressed else "sensor_msgs/msg/Image"
    suffix = "/compressed" if compressed else ""
    size = (left.shape[1], left.shape[0])
    msgs: list[tuple[str, str, dict[str, Any], int]] = []
    for ns in stamps:
        if camera_info:
            msgs.append((LEFT_INFO, "sensor_msgs/msg/CameraInfo", info_msg(rig.P_left, size, ns), ns))
            msgs.append((RIGHT_INFO, "sensor_msgs/msg/CameraInfo", info_msg(rig.P_right, size, ns), ns))
        lm = compressed_msg(left, ns) if compressed else image_msg(left, ns, left_encoding)
        rm = compressed_msg(right, ns) if compressed else image_msg(right, ns)
        msgs.append((LEFT + suffix, kind, lm, ns + 1000))
        msgs.append((RIGHT + suffix, kind, rm, ns + 2000))
    msgs.extend(extra or [])
    msgs.sort(key=lambda m: m[3])
    return write_bag(path, msgs)
