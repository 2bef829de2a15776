"""Frames of a rosbag2 (MCAP) recording: ``run --bag FILE.mcap --left-topic T --right-topic T``.

:class:`BagSource` is a source like those of :mod:`stereo_classic.sources`. Opening it reads the file's summary
(topics, counts) and then the header stamps of the two image topics (the stamp is read from the first bytes of each
serialized message; no image is decoded), pairs left and right by stamp (equal, or the nearest within
``tolerance_s``; a message left without a partner is counted and named, never matched to a far one) and checks the
first pair against the calibration. Each frame is then read when it is processed, from the file's chunk index
(``load()`` opens the file, seeks to the two messages and decodes them), so memory does not depend on the length of
the recording, and the description is picklable for a Dask worker. Frame names are the left stamps
(``SEC.NANOSEC``); the record's ``source`` holds the bag, the topics, the stamp and ``time_s`` since the first pair.

The calibration comes from the ``CameraInfo`` topics beside the image topics (``/left/image_rect`` ->
``/left/camera_info``) unless ``--calib`` is given; see :func:`stereo_classic.ros.images.rig_from_camera_info`.
"""

from __future__ import annotations

import bisect
import logging
import os
import struct
from collections.abc import Callable, Iterator
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

import calib
from stereo_classic.ros import require
from stereo_classic.ros.images import ImageMessageError, image_from_msg, rig_from_camera_info, stamp_ns
from stereo_classic.sources import Frame, FrameRef, SourceError, _safe_name, _unique

__all__ = ["BagError", "BagSource", "IMAGE_TYPES", "pair_stamps", "info_topic_for"]

log = logging.getLogger("stereo_classic.run")

#: The image message types read (rosbag2 schema names).
IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"


class BagError(SourceError):
    """A recording that cannot be used as asked (a missing topic, no calibration, not MCAP); one clear line."""


def info_topic_for(image_topic: str) -> str:
    """The ``CameraInfo`` topic beside an image topic (ROS: the same namespace).

    >>> info_topic_for("/stereo/left/image_rect_color"), info_topic_for("left/image_rect/compressed")
    ('/stereo/left/camera_info', 'left/camera_info')
    """
    parts = image_topic.rstrip("/").split("/")
    if parts and parts[-1] in ("compressed", "compressedDepth", "theora") and len(parts) > 1:
        parts = parts[:-1]
    return "/".join(parts[:-1] + ["camera_info"])


def _cdr_stamp(data: bytes) -> int:
    """The header stamp (ns) of a serialized message that starts with a ``std_msgs/Header`` (Image, CameraInfo):
    4 bytes of CDR encapsulation (byte 1: 1 = little endian), then ``int32 sec``, ``uint32 nanosec``."""
    if len(data) < 12:
        raise BagError("a message too short to hold a header")
    sec, nsec = struct.unpack_from("<iI" if data[1] & 1 else ">iI", data, 4)
    return sec * 1_000_000_000 + nsec


def pair_stamps(left: list[int], right: list[int], tolerance_ns: int) -> tuple[list[tuple[int, int]], list[int],
                                                                                list[int]]:
    """Pair two sorted stamp lists: equal stamps, or (``tolerance_ns`` > 0) the mutually nearest within it.

    Returns (pairs of indices, unpaired left indices, unpaired right indices).

    >>> pair_stamps([0, 100, 200, 300], [0, 101, 250], 0)
    ([(0, 0)], [1, 2, 3], [1, 2])
    >>> pair_stamps([0, 100, 200, 300], [0, 101, 250], 10)
    ([(0, 0), (1, 1)], [2, 3], [2])
    """
    pairs: list[tuple[int, int]] = []
    lonely_left: list[int] = []
    lonely_right: list[int] = []
    i = j = 0
    while i < len(left) and j < len(right):
        d = right[j] - left[i]
        if abs(d) <= tolerance_ns:
            if i + 1 < len(left) and abs(right[j] - left[i + 1]) < abs(d):
                lonely_left.append(i)
                i += 1
            elif j + 1 < len(right) and abs(right[j + 1] - left[i]) < abs(d):
                lonely_right.append(j)
                j += 1
            else:
                pairs.append((i, j))
                i += 1
                j += 1
        elif d < 0:
            lonely_right.append(j)
            j += 1
        else:
            lonely_left.append(i)
            i += 1
    lonely_left.extend(range(i, len(left)))
    lonely_right.extend(range(j, len(right)))
    return pairs, lonely_left, lonely_right


def _open(path: str) -> tuple[Any, Any]:
    """(file, mcap reader with the ROS 2 decoder) of ``path``."""
    reader_mod = require("mcap.reader", "--bag (reading an MCAP recording)")
    decoder = require("mcap_ros2.decoder", "--bag (reading an MCAP recording)")
    f = open(path, "rb")
    try:
        reader = reader_mod.make_reader(f, decoder_factories=[decoder.DecoderFactory()])
        reader.get_header()
    except Exception as exc:  # mcap's own errors: not an MCAP file, a truncated one
        f.close()
        raise BagError(f"--bag {path}: not a readable MCAP file ({type(exc).__name__}: {exc})") from None
    return f, reader


def _find(reader: Any, topic: str, log_time: int, stamp: int) -> Any:
    """The decoded message of ``topic`` logged at ``log_time`` with header stamp ``stamp``."""
    for _, _, message, decoded in reader.iter_decoded_messages(topics=[topic], starting_at=log_time,
                                                               ending_at=log_time):
        if _cdr_stamp(message.data) == stamp:
            return decoded
    raise BagError(f"{topic}: the message stamped {stamp / 1e9:.9f} s is no longer in the file")


def _load_pair(path: str, left_topic: str, right_topic: str, left_at: tuple[int, int], right_at: tuple[int, int],
               size: tuple[int, int] | None) -> tuple[np.ndarray, np.ndarray, None, None]:
    """Read and convert one pair (picklable with ``functools.partial``: what travels to a Dask worker)."""
    f, reader = _open(path)
    with f:
        lmsg = _find(reader, left_topic, *left_at)
        rmsg = _find(reader, right_topic, *right_at)
    when = f" at {left_at[1] // 1_000_000_000}.{left_at[1] % 1_000_000_000:09d}"
    left = image_from_msg(lmsg, left_topic + when)
    right = image_from_msg(rmsg, right_topic + when)
    if left.shape[:2] != right.shape[:2]:
        raise ImageMessageError(f"{left_topic} and {right_topic}{when}: the left image is {left.shape[1]}x"
                                f"{left.shape[0]}, the right one {right.shape[1]}x{right.shape[0]}; a stereo pair "
                                "needs equal sizes")
    if size is not None and (left.shape[1], left.shape[0]) != tuple(size):
        raise ImageMessageError(f"{left_topic}{when}: the images are {left.shape[1]}x{left.shape[0]} but the "
                                f"CameraInfo says {size[0]}x{size[1]}")
    return left, right, None, None


class BagSource:
    """The stereo pairs of an MCAP recording, paired by header stamp and read one at a time.

    Parameters
    ----------
    path : path of a ``.mcap`` file (a rosbag2 folder: its ``.mcap`` file)
    left_topic, right_topic : str
        ``sensor_msgs/Image`` or ``sensor_msgs/CompressedImage`` topics.
    tolerance_s : float
        0: only equal stamps pair; > 0: the nearest stamps within it pair (mutually nearest).
    rig : calib.RectifiedRig or None
        The calibration (``--calib``); None: from the ``CameraInfo`` topics (``left_info``, ``right_info``, by
        default beside the image topics).
    rectify : bool
        The images are raw: rectify them with the CameraInfo's K, D, R (``--rectify``).
    max_frames : int or None
        Keep the first pairs only.

    Attributes
    ----------
    rig : calib.RectifiedRig
    unpaired : dict topic -> list of stamp names, the messages left without a partner.

    Raises
    ------
    BagError
        Not MCAP, a topic missing (the message lists the file's topics and types), a topic of another type, no pair,
        no CameraInfo and no ``rig``.
    ImageMessageError
        The first pair cannot be converted, its sizes differ, or the CameraInfo contradicts them.
    """

    def __init__(self, path: str | os.PathLike[str], left_topic: str, right_topic: str, *, tolerance_s: float = 0.0,
                 rig: calib.RectifiedRig | calib.StereoRig | None = None, rectify: bool = False,
                 left_info: str | None = None, right_info: str | None = None,
                 max_frames: int | None = None) -> None:
        p = Path(path)
        if p.is_dir():  # a rosbag2 folder: metadata.yaml + one .mcap
            found = sorted(p.glob("*.mcap"))
            if len(found) != 1:
                raise BagError(f"--bag {p} is a folder with {len(found)} .mcap files; name the .mcap file")
            p = found[0]
        if not p.is_file():
            raise FileNotFoundError(f"--bag: recording not found: {p}")
        if not (tolerance_s >= 0.0 and np.isfinite(tolerance_s)):
            raise BagError(f"--stamp-tolerance must be >= 0 seconds, got {tolerance_s}")
        self.path = str(p)
        self.left_topic, self.right_topic = left_topic, right_topic
        f, reader = _open(self.path)
        with f:
            types = self._topics(reader)
            for option, topic in (("--left-topic", left_topic), ("--right-topic", right_topic)):
                if topic not in types:
                    raise BagError(f"{option} {topic}: no such topic in {p.name}; its topics: " + ", ".join(
                        f"{t} ({s})" for t, s in sorted(types.items())))
                if types[topic] not in IMAGE_TYPES:
                    raise BagError(f"{option} {topic} holds {types[topic]}, expected sensor_msgs/msg/Image or "
                                   "CompressedImage")
            self.frame_id = ""
            for _, _, _, decoded in reader.iter_decoded_messages(topics=[left_topic]):
                self.frame_id = str(decoded.header.frame_id)  # the results are stamped in the input's frame
                break
            stamps: dict[str, list[tuple[int, int]]] = {left_topic: [], right_topic: []}
            for _, channel, message in reader.iter_messages(topics=[left_topic, right_topic]):
                stamps[channel.topic].append((_cdr_stamp(message.data), message.log_time))
            for side in stamps.values():
                side.sort()
            ls, rs = stamps[left_topic], stamps[right_topic]
            pairs, lonely_l, lonely_r = pair_stamps([s for s, _ in ls], [s for s, _ in rs],
                                                    int(round(tolerance_s * 1e9)))
            self.unpaired = {left_topic: [_name(ls[i][0]) for i in lonely_l],
                             right_topic: [_name(rs[j][0]) for j in lonely_r]}
            if not pairs:
                raise BagError(f"{p.name}: no left message of {left_topic} ({len(ls)}) has a right message of "
                               f"{right_topic} ({len(rs)}) with the same stamp"
                               + (f" within {tolerance_s:g} s" if tolerance_s else " (--stamp-tolerance S pairs "
                                                                                    "the nearest within S)"))
            if max_frames:
                pairs = pairs[:max_frames]
            self._pairs = [(ls[i][::-1], rs[j][::-1]) for i, j in pairs]  # ((log_time, stamp), (log_time, stamp))
            self._t0 = self._pairs[0][0][1]
            self.rig, self.info_size = self._rig(reader, types, rig, rectify, left_info, right_info)
        self._names = _unique([_safe_name(_name(lp[1])) for lp, _ in self._pairs])
        left, right, _, _ = self._load(0)  # the first pair: a bad encoding or size fails before any work
        size = (left.shape[1], left.shape[0])
        if self.info_size is None:
            rig_size = tuple(self.rig.raw_image_size if getattr(self.rig, "has_maps", False) else
                             self.rig.image_size)
            if size != rig_size:
                raise ImageMessageError(f"{left_topic}: the images are {size[0]}x{size[1]} but --calib is for "
                                        f"{rig_size[0]}x{rig_size[1]}")
        n_lonely = sum(len(v) for v in self.unpaired.values())
        if n_lonely:
            log.warning("%s: %d message(s) without a partner within %g s, not used: %s", p.name, n_lonely,
                        tolerance_s, self.unpaired_text())

    @staticmethod
    def _topics(reader: Any) -> dict[str, str]:
        summary = reader.get_summary()
        if summary is None:  # an unindexed file: scan it once for its channels
            out = {}
            for schema, channel, _ in reader.iter_messages():
                out.setdefault(channel.topic, schema.name if schema else "?")
            return out
        return {c.topic: (summary.schemas[c.schema_id].name if c.schema_id in summary.schemas else "?")
                for c in summary.channels.values()}

    def _rig(self, reader: Any, types: dict[str, str], rig: Any, rectify: bool, left_info: str | None,
             right_info: str | None) -> tuple[calib.RectifiedRig, tuple[int, int] | None]:
        if rig is not None:
            return rig, None
        infos = [left_info or info_topic_for(self.left_topic), right_info or info_topic_for(self.right_topic)]
        missing = [t for t in infos if types.get(t) != CAMERA_INFO]
        if missing:
            found = [t for t, s in sorted(types.items()) if s == CAMERA_INFO]
            raise BagError(f"{Path(self.path).name} has no CameraInfo on {' and '.join(missing)} and no --calib was "
                           f"given; CameraInfo topics in the file: {', '.join(found) or 'none'} (--left-info-topic/"
                           "--right-info-topic name others, --calib FILE gives the calibration)")
        first: dict[str, Any] = {}
        for _, channel, _, decoded in reader.iter_decoded_messages(topics=infos):
            first.setdefault(channel.topic, decoded)
            if len(first) == 2:
                break
        built = rig_from_camera_info(first[infos[0]], first[infos[1]], rectify=rectify,
                                     what=f"{infos[0]} / {infos[1]}")
        if isinstance(built, calib.StereoRig):
            built = built.rectify()
        return built, (int(first[infos[0]].width), int(first[infos[0]].height))

    def _load(self, i: int) -> tuple[np.ndarray, np.ndarray, None, None]:
        (l_at, r_at) = self._pairs[i]
        return _load_pair(self.path, self.left_topic, self.right_topic, l_at, r_at, self.info_size)

    def __len__(self) -> int:
        return len(self._pairs)

    @property
    def names(self) -> list[str]:
        return list(self._names)

    def unpaired_text(self, limit: int = 5) -> str:
        """The messages without a partner, per topic: ``/left/image_rect: 3 (12.000000000, ...)``."""
        parts = []
        for topic, names in self.unpaired.items():
            if names:
                shown = ", ".join(names[:limit]) + (", ..." if len(names) > limit else "")
                parts.append(f"{topic}: {len(names)} ({shown})")
        return "; ".join(parts)

    def time_s(self, index: int) -> float:
        """Seconds from the first pair's left stamp to pair ``index``'s."""
        return (self._pairs[index][0][1] - self._t0) / 1e9

    def refs(self, skip: Callable[[str], bool] = lambda name: False) -> Iterator[FrameRef]:
        """The pairs not skipped, described (file, topics, log times, stamps), not read."""
        for i, ((l_at, r_at), name) in enumerate(zip(self._pairs, self._names)):
            if skip(name):
                continue
            stamp = _name(l_at[1])
            yield FrameRef(i, name, f"{self.path} {self.left_topic} + {self.right_topic} at {stamp}",
                           partial(_load_pair, self.path, self.left_topic, self.right_topic, l_at, r_at,
                                   self.info_size),
                           {"bag": self.path, "left_topic": self.left_topic, "right_topic": self.right_topic,
                            "stamp": stamp, "right_stamp": _name(r_at[1]), "time_s": round(self.time_s(i), 9),
                            "frame_id": self.frame_id})

    def frames(self, skip: Callable[[str], bool] = lambda name: False) -> Iterator[Frame]:
        for ref in self.refs(skip):
            yield ref.read()

    def close(self) -> None:
        pass


def _name(ns: int) -> str:
    return f"{ns // 1_000_000_000}.{ns % 1_000_000_000:09d}"
