"""The input options shared by the commands that run over frames (``run``, and those built on it).

One kind of input per call: ``--left/--right`` pairs (files or globs, paired in order) with ``--calib``, a
``--dataset`` folder, a side-by-side ``--video`` or ``--camera`` with ``--calib``, a rosbag2 ``--bag`` (MCAP) with
``--left-topic``/``--right-topic`` (calibration from its CameraInfo or ``--calib``), or none (the built-in demo).
:func:`add_input_options` registers them on a parser; :func:`open_source` turns the parsed options into a
:mod:`stereo_classic.sources` source and, where the input does not carry its own, the rectified rig.
"""

from __future__ import annotations

import argparse
from typing import Any

import calib
from stereo_classic import sources
from stereo_classic.cli.errors import UsageError

__all__ = ["Source", "add_input_options", "load_rig", "open_source"]

Source = sources.PairSource | sources.SceneSource | sources.SideBySideSource  # or a stereo_classic.ros.bag.BagSource


def add_input_options(parser: Any) -> None:
    """Register the input group (``--left``, ``--right``, ``--calib``, ``--rectify``, ``--dataset``, ``--video``,
    ``--camera``, ``--max-frames``, ``--scale``) on ``parser``."""
    src = parser.add_argument_group("input (one kind; none = the demo scene)")
    src.add_argument("--left", nargs="+", metavar="PATH",
                     help="left image(s) or glob pattern(s), paired in order with --right")
    src.add_argument("--right", nargs="+", metavar="PATH", help="right image(s) or glob pattern(s)")
    src.add_argument("--calib", metavar="FILE", help="calibration (OpenCV YAML/XML, KITTI, Middlebury calib.txt, ...)")
    src.add_argument("--rectify", action="store_true", help="the images are raw: rectify them with --calib")
    src.add_argument("--dataset", metavar="DIR", help="a dataset folder (Middlebury, KITTI, ...): every scene below it")
    src.add_argument("--video", metavar="FILE",
                     help="a side-by-side stereo video (left half = left image); needs --calib")
    src.add_argument("--camera", type=int, metavar="N", help="live side-by-side stereo camera N; needs --calib")
    bag = parser.add_argument_group("rosbag2 (MCAP) input: the bag extra, docs/ros.md")
    bag.add_argument("--bag", metavar="FILE.mcap", help="a rosbag2 recording in MCAP; needs --left-topic and "
                     "--right-topic; calibration from its CameraInfo topics unless --calib is given")
    bag.add_argument("--left-topic", metavar="TOPIC", help="left sensor_msgs/Image or CompressedImage topic")
    bag.add_argument("--right-topic", metavar="TOPIC", help="right sensor_msgs/Image or CompressedImage topic")
    bag.add_argument("--left-info-topic", metavar="TOPIC",
                     help="left CameraInfo topic (default: camera_info beside --left-topic)")
    bag.add_argument("--right-info-topic", metavar="TOPIC",
                     help="right CameraInfo topic (default: camera_info beside --right-topic)")
    bag.add_argument("--stamp-tolerance", type=float, metavar="S",
                     help="pair left and right stamps within S seconds (default 0: equal stamps only)")
    src.add_argument("--max-frames", type=int, default=None, metavar="N", help="stop after N frames (0 = all)")
    src.add_argument("--scale", type=float, default=None, metavar="F",
                     help="resize the images by F (e.g. 0.5) before matching")


def load_rig(path: str, rectify: bool) -> calib.RectifiedRig:
    """The rectified rig of ``--calib path``; a raw calibration needs ``rectify`` (``--rectify``)."""
    rig = calib.load_rig(path)
    if isinstance(rig, calib.StereoRig):  # raw cameras
        if not rectify:
            raise UsageError(f"--calib {path} holds a raw (unrectified) calibration; add --rectify to rectify "
                             "the images with it")
        rig = rig.rectify()
    elif rectify and not rig.has_maps:
        raise UsageError(f"--rectify: {path} describes an already rectified pair (no distortion or rotation to undo)")
    return rig


def open_source(args: argparse.Namespace, max_frames: int | None = None) -> tuple[Source, calib.RectifiedRig | None]:
    """The source and (for pairs, videos and cameras) the rig that the input options of ``args`` name.

    Scenes of ``--dataset`` and the demo carry their own rig (``None`` is returned). ``max_frames`` (None = all)
    stops reading. Wrong combinations raise :class:`UsageError` naming the options.
    """
    kinds = [k for k in ("left", "dataset", "video", "camera", "bag") if getattr(args, k, None) is not None]
    if args.right is not None and args.left is None:
        raise UsageError("--right needs --left")
    if len(kinds) > 1:
        raise UsageError(f"choose one input: --{kinds[0]} and --{kinds[1]} were both given")
    kind = kinds[0] if kinds else "demo"
    topics = [f"--{k.replace('_', '-')}" for k in ("left_topic", "right_topic", "left_info_topic", "right_info_topic",
                                                   "stamp_tolerance") if getattr(args, k, None) is not None]
    if kind == "bag":
        return _open_bag(args, max_frames)
    if topics:
        raise UsageError(f"{topics[0]} goes with --bag")
    if kind in ("left", "video", "camera") and not args.calib:
        raise UsageError(f"--{kind} needs --calib (the stereo calibration)")
    if kind in ("demo", "dataset") and (args.calib or args.rectify):
        raise UsageError("--calib/--rectify go with --left/--right, --video or --camera (scenes carry their own)")
    try:
        if kind == "left":
            if args.right is None:
                raise UsageError("--left needs --right")
            pairs = sources.expand_pairs(args.left, args.right)
            if max_frames:
                pairs = pairs[:max_frames]
            rig = load_rig(args.calib, args.rectify)
            return sources.PairSource(pairs), rig
        if kind in ("video", "camera"):
            rig = load_rig(args.calib, args.rectify)
            target = args.video if kind == "video" else args.camera
            return sources.SideBySideSource(target, max_frames=max_frames), rig
        if kind == "dataset":
            src = sources.SceneSource.from_folder(args.dataset)
        else:
            src = sources.SceneSource.demo()
    except sources.SourceError as exc:
        if "matches no file" in str(exc) or "paired in order" in str(exc):
            raise UsageError(str(exc)) from None
        raise
    if max_frames:
        src.scenes = src.scenes[:max_frames]  # descriptions: the scenes past it are never read
    return src, None


def _open_bag(args: argparse.Namespace, max_frames: int | None) -> tuple[Source, calib.RectifiedRig | None]:
    """A :class:`stereo_classic.ros.bag.BagSource` (the calibration from ``--calib`` or the bag's CameraInfo)."""
    from stereo_classic.ros import MissingDependencyError

    for option in ("left_topic", "right_topic"):
        if not getattr(args, option, None):
            raise UsageError(f"--bag needs --{option.replace('_', '-')} (the sensor_msgs/Image topic of that camera)")
    rig = load_rig(args.calib, args.rectify) if args.calib else None
    try:
        from stereo_classic.ros.bag import BagSource

        source = BagSource(args.bag, args.left_topic, args.right_topic, tolerance_s=args.stamp_tolerance or 0.0,
                           rig=rig, rectify=bool(args.rectify), left_info=args.left_info_topic,
                           right_info=args.right_info_topic, max_frames=max_frames)
    except MissingDependencyError as exc:
        raise UsageError(str(exc)) from None
    return source, source.rig
