"""``python -m stereo_classic ros``: the pipeline as a live ROS 2 node.

Subscribes to ``left/image_rect``, ``left/camera_info``, ``right/image_rect``, ``right/camera_info``
(``sensor_msgs/Image``; remap with ``--ros-args -r left/image_rect:=/my/left``), pairs left and right by
approximate time (stamps within ``sync.slop`` seconds), runs :class:`stereo_classic.pipeline.Localizer` (and, with
``--guide``, :class:`stereo_classic.guide.Guide`) and publishes ``disparity`` (``stereo_msgs/DisparityImage``),
``objects/markers`` (``visualization_msgs/MarkerArray``), ``objects`` (the frame's record as JSON on
``std_msgs/String``) and ``guide/events`` (one JSON event per message), stamped like the input pair.

Processing runs in its own thread; the subscriptions only keep the newest pair, so a frame that arrives while the
previous one is processed replaces any pair still waiting (dropped, counted): the node always works on the latest
images, never on a queue. It logs its rate every ``report_period`` seconds and stops cleanly on Ctrl-C or SIGTERM.

rclpy and the message packages are imported here, when the node starts: from the ``ros`` extra's wheels or from a
sourced ROS 2 installation; a missing one is named in one line.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Any

import numpy as np

from stereo_classic.ros import require
from stereo_classic.ros.images import image_from_msg, rig_from_camera_info, stamp_name, stamp_ns
from stereo_classic.ros.parameters import dataclass_values, parameter_table
from stereo_classic.ros.results import disparity_image, fill, header, json_string, object_markers

__all__ = ["StereoNode", "run_node"]

_WHAT = "python -m stereo_classic ros"


def _ros() -> dict[str, Any]:
    """The ROS modules the node needs (imported now; a missing one named in one line)."""
    return {"rclpy": require("rclpy", _WHAT), "executors": require("rclpy.executors", _WHAT),
            "qos": require("rclpy.qos", _WHAT), "sensor_msgs": require("sensor_msgs.msg", _WHAT),
            "stereo_msgs": require("stereo_msgs.msg", _WHAT),
            "visualization_msgs": require("visualization_msgs.msg", _WHAT), "std_msgs": require("std_msgs.msg", _WHAT)}


class StereoNode:
    """The node's logic around an ``rclpy`` node (created by :func:`run_node`).

    Parameters
    ----------
    node : rclpy.node.Node
    make_localizer : callable
        ``make_localizer(rig, matcher_values) -> Localizer`` (the detector, fusion and seed bound by the caller).
    guide_params : GuideParams or None
        Run the guide and publish its events.
    """

    def __init__(self, node: Any, ros: dict[str, Any], make_localizer: Any, *, guide: bool = False,
                 detector_name: str | None = None) -> None:
        from stereo_classic.fusion import FusionParams
        from stereo_classic.guide import GuideParams
        from stereo_classic.cli.options import CLI_NUM_DISPARITIES
        from stereo_classic.matching import SGMParams

        matcher_defaults = {"num_disparities": CLI_NUM_DISPARITIES}
        self.detector_name = detector_name

        self.node, self.ros, self.make_localizer = node, ros, make_localizer
        self.tables = {"matcher": SGMParams, "fusion": FusionParams, "guide": GuideParams}
        tables = {prefix: parameter_table(cls, prefix, matcher_defaults if prefix == "matcher" else None)
                  for prefix, cls in self.tables.items()}
        for table in tables.values():
            for p in table:
                node.declare_parameter(p.name, p.default, _descriptor(p.description))
        node.declare_parameter("sync.slop", 0.01)
        node.declare_parameter("seed", 0)
        node.declare_parameter("report_period", 10.0)
        node.declare_parameter("frame_id", "")
        values = {p.name: node.get_parameter(p.name).value for table in tables.values() for p in table}
        self.matcher = dataclass_values(SGMParams, "matcher", values, matcher_defaults)
        self.fusion = FusionParams(**dataclass_values(FusionParams, "fusion", values))
        self.guide_params = GuideParams(**dataclass_values(GuideParams, "guide", values)) if guide else None
        self.slop_ns = int(float(node.get_parameter("sync.slop").value) * 1e9)
        self.seed = int(node.get_parameter("seed").value)
        self.frame_id = str(node.get_parameter("frame_id").value)
        node.declare_parameter("image_qos", "reliable", _descriptor(
            "reliability of the image and camera_info subscriptions: reliable (as stereo_image_proc publishes; a "
            "best-effort publisher is then not heard) or best_effort (takes both, but large images lose fragments)"))
        choice = str(node.get_parameter("image_qos").value)
        qos = ros["qos"]
        if choice not in ("reliable", "best_effort"):
            raise ValueError(f"parameter image_qos must be reliable or best_effort, got {choice!r}")
        sensor = qos.QoSProfile(depth=2, history=qos.HistoryPolicy.KEEP_LAST,  # the newest only: no queue
                                reliability=qos.ReliabilityPolicy.RELIABLE if choice == "reliable"
                                else qos.ReliabilityPolicy.BEST_EFFORT)
        msgs = ros["sensor_msgs"]
        self._lock = threading.Condition()
        self._latest: dict[str, Any] = {}
        self._recent: dict[str, list[Any]] = {"left": [], "right": []}
        self._pending: tuple[Any, Any] | None = None
        self._stop = False
        self.received = self.processed = self.dropped = 0
        for side in ("left", "right"):
            node.create_subscription(msgs.Image, f"{side}/image_rect",
                                     (lambda s: lambda m: self._on_image(s, m))(side), sensor)
            node.create_subscription(msgs.CameraInfo, f"{side}/camera_info",
                                     (lambda s: lambda m: self._on_info(s, m))(side), sensor)
        reliable = 10
        self.pub_disparity = node.create_publisher(ros["stereo_msgs"].DisparityImage, "disparity", reliable)
        self.pub_markers = node.create_publisher(ros["visualization_msgs"].MarkerArray, "objects/markers", reliable)
        self.pub_objects = node.create_publisher(ros["std_msgs"].String, "objects", reliable)
        self.pub_events = node.create_publisher(ros["std_msgs"].String, "guide/events", reliable)
        self._guide = None
        self._current: list[Any] = []  # [camera infos key, rig, localizer]
        self._worker = threading.Thread(target=self._work, name="stereo-classic-node", daemon=True)
        self._t_report = time.monotonic()
        self._n_report = 0
        period = float(node.get_parameter("report_period").value)
        if period > 0:
            node.create_timer(period, self._report)

    # ----------------------------------------------------------------- callbacks: keep the newest pair
    def _on_info(self, side: str, msg: Any) -> None:
        with self._lock:
            self._latest[f"{side}_info"] = msg

    def _on_image(self, side: str, msg: Any) -> None:
        other = "right" if side == "left" else "left"
        t = stamp_ns(msg.header.stamp)
        with self._lock:
            self.received += 1
            recent = self._recent[side]
            recent.append(msg)
            del recent[:-4]
            best = None
            for cand in self._recent[other]:
                d = abs(stamp_ns(cand.header.stamp) - t)
                if d <= self.slop_ns and (best is None or d < best[0]):
                    best = (d, cand)
            if best is None:
                return
            pair = (msg, best[1]) if side == "left" else (best[1], msg)
            self._recent[side].remove(msg)
            self._recent[other].remove(best[1])
            if self._pending is not None:
                self.dropped += 1  # a newer pair replaces one that was still waiting
            self._pending = pair
            self._lock.notify()

    # ----------------------------------------------------------------- the worker
    def start(self) -> None:
        """Load the matcher's compiled code (so that the first pair does not wait for it) and start the worker."""
        from stereo_classic.matching import SGMParams
        from stereo_classic.pipeline import load_frame_kernels

        try:
            load_frame_kernels(SGMParams(**self.matcher))
        except ValueError:  # a parameter the matcher refuses: each pair's error says which, as before
            pass
        self._worker.start()

    def stop(self) -> None:
        with self._lock:
            self._stop = True
            self._lock.notify()
        if self._worker.is_alive():
            self._worker.join(timeout=30)
        if self._current:
            self._current[-1].close()

    def _work(self) -> None:
        while True:
            with self._lock:
                while self._pending is None and not self._stop:
                    self._lock.wait()
                if self._stop:
                    return
                pair, self._pending = self._pending, None
                infos = (self._latest.get("left_info"), self._latest.get("right_info"))
            try:
                self._process(pair, infos)
            except Exception as exc:  # one bad frame must not end a robot's node: say it, go on
                self.node.get_logger().error(f"frame {stamp_name(pair[0].header.stamp)}: {exc}")

    def _localizer(self, infos: tuple[Any, Any]) -> tuple[Any, Any]:
        key = tuple(tuple(np.asarray(i.p, dtype=float)) + (int(i.width), int(i.height)) for i in infos)
        if not self._current or self._current[0] != key:
            if self._current:
                self._current[-1].close()
            rig = rig_from_camera_info(infos[0], infos[1], rectify=False, what="left/camera_info / right/camera_info")
            self._current[:] = [key, rig, self.make_localizer(rig, self.matcher, self.fusion, self.seed)]
            if self.guide_params is not None:
                from stereo_classic.guide import Guide

                self._guide = Guide(self.guide_params)
        return self._current[1], self._current[2]

    def _process(self, pair: tuple[Any, Any], infos: tuple[Any, Any]) -> None:
        from stereo_classic.outputs import frame_record

        if infos[0] is None or infos[1] is None:
            raise ValueError("no CameraInfo received yet on left/camera_info and right/camera_info")
        lmsg, rmsg = pair
        name = stamp_name(lmsg.header.stamp)
        left = image_from_msg(lmsg, f"left/image_rect at {name}")
        right = image_from_msg(rmsg, f"right/image_rect at {name}")
        rig, loc = self._localizer(infos)
        if (left.shape[1], left.shape[0]) != tuple(rig.image_size) or left.shape[:2] != right.shape[:2]:
            raise ValueError(f"images of {left.shape[1]}x{left.shape[0]} and {right.shape[1]}x{right.shape[0]} "
                             f"with a CameraInfo of {rig.image_size[0]}x{rig.image_size[1]}")
        result = loc(left, right)
        t = stamp_ns(lmsg.header.stamp)
        hdr = header(t, self.frame_id or lmsg.header.frame_id)
        ros = self.ros
        self.pub_disparity.publish(fill(ros["stereo_msgs"].DisparityImage(), disparity_image(
            result.disparity.measured_disparity, rig, result.disparity.params, hdr)))
        self.pub_markers.publish(fill(ros["visualization_msgs"].MarkerArray(), object_markers(result.objects, rig,
                                                                                               hdr)))
        record = frame_record(name, self.processed, result, rig, detector=self.detector_name, fusion=self.fusion, seed=self.seed,
                              source={"stamp": name, "frame_id": hdr["frame_id"]})
        self.pub_objects.publish(fill(ros["std_msgs"].String(), json_string(record)))
        if self._guide is not None:
            frame = self._guide.update(result, rig, t / 1e9, frame=name)
            for event in frame.events:
                self.pub_events.publish(fill(ros["std_msgs"].String(), json_string(event.to_dict())))
        with self._lock:
            self.processed += 1

    def _report(self) -> None:
        now = time.monotonic()
        with self._lock:
            n, dropped, received = self.processed, self.dropped, self.received
        rate = (n - self._n_report) / max(now - self._t_report, 1e-9)
        self._t_report, self._n_report = now, n
        self.node.get_logger().info(f"{rate:.2f} frames/s; {n} processed, {dropped} stale pair(s) dropped, "
                                    f"{received} image(s) received")


def _descriptor(text: str) -> Any:
    from rcl_interfaces.msg import ParameterDescriptor

    return ParameterDescriptor(description=text)


def run_node(make_localizer: Any, *, ros_args: list[str], guide: bool = False, node_name: str = "stereo_classic",
             detector_name: str | None = None) -> int:
    """Start rclpy, spin the node until Ctrl-C or SIGTERM (or a ROS shutdown), stop it cleanly; returns 0."""
    ros = _ros()
    rclpy = ros["rclpy"]
    rclpy.init(args=["stereo_classic", *ros_args])  # installs rclpy's SIGINT and SIGTERM handlers
    node = rclpy.create_node(node_name)
    stereo = StereoNode(node, ros, make_localizer, guide=guide, detector_name=detector_name)
    stereo.start()
    node.get_logger().info("waiting for left/image_rect, right/image_rect and their camera_info")
    executor = ros["executors"].SingleThreadedExecutor()
    started = time.monotonic()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ros["executors"].ExternalShutdownException):
        pass
    except RuntimeError:  # rclpy's RCLError is one
        if rclpy.ok():
            raise
        # a signal's handler shut the context down while the executor was making its wait set ("failed to
        # initialize wait set: the given context is not valid", rclpy's known race, ros2/rclpy#968): the stop asked for
    finally:
        stereo.stop()  # rclpy's context may be shut down already (a signal): say it on this package's log
        seconds = time.monotonic() - started
        logging.getLogger("stereo_classic.ros").info(
            "stopped: %d frame(s) processed in %.1f s (%.2f frames/s), %d stale pair(s) dropped", stereo.processed,
            seconds, stereo.processed / max(seconds, 1e-9), stereo.dropped)
        executor.shutdown()
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0
