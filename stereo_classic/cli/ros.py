"""``python -m stereo_classic ros``: the pipeline as a live ROS 2 node (:mod:`stereo_classic.ros.node`).

The detector options are flags, as for ``run``; the matcher, fusion and guide settings are ROS parameters generated
from ``SGMParams``, ``FusionParams`` and ``GuideParams`` (``-p matcher.num_disparities:=96``); everything after
``--ros-args`` goes to ROS (remapping, parameters, a parameter file). See docs/ros.md.
"""

from __future__ import annotations

import argparse
import dataclasses
from typing import Any

from stereo_classic.cli.errors import UsageError
from stereo_classic.cli.run import SQUARE_INPUT_HELP

__all__ = ["add_parser", "func"]


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Register the ``ros`` sub-command."""
    p = subparsers.add_parser(
        "ros", help="run as a ROS 2 node: stereo images in, disparity, 3D boxes and objects out (docs/ros.md)",
        description="A live ROS 2 node (the ros extra, or a sourced ROS 2): subscribes to left/image_rect, "
                    "left/camera_info, right/image_rect, right/camera_info; publishes disparity, objects/markers, "
                    "objects and guide/events. Matcher, fusion and guide settings are ROS parameters "
                    "(--ros-args -p matcher.num_disparities:=96).")
    det = p.add_argument_group("detector")
    det.add_argument("--model", default="yolox_nano", metavar="NAME|PATH",
                     help="ONNX detector name or path, or 'none' (default: yolox_nano)")
    det.add_argument("--conf", type=float, default=0.3, help="confidence threshold (default 0.3)")
    det.add_argument("--iou", type=float, default=0.45, help="NMS IoU threshold (default 0.45)")
    det.add_argument("--classes", default="", metavar="LIST", help="comma-separated class names to keep")
    det.add_argument("--square-input", action="store_true", help=SQUARE_INPUT_HELP)
    node = p.add_argument_group("node")
    node.add_argument("--guide", action="store_true", help="also run the guide and publish guide/events")
    node.add_argument("--threads", type=int, default=0, metavar="N", help="matcher and detector threads (0 = all)")
    node.add_argument("--name", default="stereo_classic", help="node name (default stereo_classic)")
    node.add_argument("--ros-args", dest="ros_args", nargs=argparse.REMAINDER, default=[],
                      help="the rest goes to ROS: -r FROM:=TO remaps, -p NAME:=VALUE sets a parameter")
    p.set_defaults(func=func)
    return p


def func(args: argparse.Namespace) -> int:
    from stereo_classic.cli import run as run_command
    from stereo_classic.pipeline import Localizer
    from stereo_classic.ros import MissingDependencyError

    cfg = {"model": args.model, "conf": args.conf, "iou": args.iou, "threads": args.threads,
           "classes": [c.strip() for c in args.classes.split(",") if c.strip()],
           "square_input": args.square_input}
    for key in ("conf", "iou"):
        if not 0.0 <= cfg[key] <= 1.0:
            raise UsageError(f"--{key} must be between 0 and 1, got {cfg[key]}")
    if args.threads < 0:
        raise UsageError(f"--threads must be >= 1 (0 = all), got {args.threads}")
    try:
        from stereo_classic.ros.node import _ros, run_node

        _ros()  # rclpy and the messages, before the detector is opened
    except MissingDependencyError as exc:
        raise UsageError(str(exc)) from None
    detector, detector_name = run_command._open_detector(cfg)

    def make_localizer(rig: Any, matcher: dict[str, Any], fusion: Any, seed: int) -> Localizer:
        from stereo_classic.matching import SGMParams

        params = SGMParams(**matcher)
        if args.threads:
            params = dataclasses.replace(params, threads=args.threads)
        return Localizer(rig, detector, params, fusion=fusion, seed=seed, classes=cfg["classes"] or None)

    ros_args = list(args.ros_args or [])
    return run_node(make_localizer, ros_args=["--ros-args", *ros_args] if ros_args else [], guide=args.guide,
                    node_name=args.name, detector_name=detector_name)
