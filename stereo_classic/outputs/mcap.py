"""``run --save mcap``: the results of a run as one ROS 2 recording, ``results.mcap`` beside the other outputs.

Per frame, stamped like its input (a recording's header stamps; other inputs: frame index x 0.1 s), on these
topics (messages built by :mod:`stereo_classic.ros.results`; the schemas are the ROS 2 message definitions as text,
so writing needs ``mcap`` and ``mcap-ros2-support`` (the ``bag`` extra), not ROS):

* ``/stereo_classic/disparity``: ``stereo_msgs/DisparityImage`` of the measured disparity;
* ``/stereo_classic/objects/markers``: ``visualization_msgs/MarkerArray``, the 3D boxes and labels;
* ``/stereo_classic/objects``: ``std_msgs/String``, the frame's JSON record (as ``objects.jsonl`` holds it);
* ``/stereo_classic/guide/events``: ``std_msgs/String``, one JSON guide event per message (``guide --save mcap``).

The file is written as ``.results.mcap.<hex>.tmp`` and renamed when the run ends, finished or interrupted, so the
file under its name is always a complete MCAP of every frame written (in frame order). :class:`McapFrameWriter`
adds it to a :class:`~stereo_classic.outputs.FrameWriter`.
"""

from __future__ import annotations

import os
import secrets
from pathlib import Path
from typing import Any

from stereo_classic.ros import require
from stereo_classic.ros.msgdefs import MSGDEFS
from stereo_classic.ros.results import DEFAULT_FRAME_ID, disparity_image, header, json_string, object_markers

__all__ = ["MCAP_NAME", "McapFrameWriter", "McapSink", "TOPICS", "frame_stamp_ns"]

#: The file ``--save mcap`` writes in the output folder.
MCAP_NAME = "results.mcap"
#: Topic -> message type of what is written.
TOPICS: dict[str, str] = {
    "/stereo_classic/disparity": "stereo_msgs/msg/DisparityImage",
    "/stereo_classic/objects/markers": "visualization_msgs/msg/MarkerArray",
    "/stereo_classic/objects": "std_msgs/msg/String",
    "/stereo_classic/guide/events": "std_msgs/msg/String",
}
_FRAME_PERIOD_NS = 100_000_000


def frame_stamp_ns(record: dict[str, Any]) -> int:
    """The stamp of a frame's results: its input's header stamp (``source["stamp"]``, ``SEC.NANOSEC``), else the
    frame index x 0.1 s.

    >>> frame_stamp_ns({"index": 3, "source": {"stamp": "12.000000005"}}), frame_stamp_ns({"index": 3})
    (12000000005, 300000000)
    """
    stamp = (record.get("source") or {}).get("stamp")
    if isinstance(stamp, str) and "." in stamp:
        sec, nsec = stamp.split(".")
        return int(sec) * 1_000_000_000 + int(nsec)
    return int(record.get("index", 0)) * _FRAME_PERIOD_NS


class McapSink:
    """One MCAP file of results, written frame after frame, renamed into place by :meth:`close`.

    Raises
    ------
    MissingDependencyError
        ``mcap-ros2-support`` is not installed (the message says to install the ``bag`` extra).
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        writer_mod = require("mcap_ros2.writer", "--save mcap (writing an MCAP recording)")
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = self.path.with_name(f".{self.path.name}.{secrets.token_hex(4)}.tmp")
        self._file = open(self._tmp, "wb")
        self._writer = writer_mod.Writer(self._file)
        self._schemas: dict[str, Any] = {}
        self.frames = 0
        self._last = -1

    def _write(self, topic: str, message: dict[str, Any], stamp_ns: int) -> None:
        kind = TOPICS[topic]
        if kind not in self._schemas:
            self._schemas[kind] = self._writer.register_msgdef(kind, MSGDEFS[kind])
        self._writer.write_message(topic, self._schemas[kind], message, log_time=stamp_ns, publish_time=stamp_ns)

    def write_frame(self, result: Any, rig: Any, record: dict[str, Any], *, frame_id: str | None = None) -> None:
        """The disparity, markers and record of one frame (``result``: a PipelineResult; ``rig``: the rig of the
        images matched)."""
        stamp = max(frame_stamp_ns(record), self._last)  # log times never go back (frames are written in order)
        hdr = header(stamp, frame_id or (record.get("source") or {}).get("frame_id") or DEFAULT_FRAME_ID)
        self._write("/stereo_classic/disparity",
                    disparity_image(result.disparity.measured_disparity, rig, result.disparity.params, hdr), stamp)
        self._write("/stereo_classic/objects/markers", object_markers(result.objects, rig, hdr), stamp)
        self._write("/stereo_classic/objects", json_string(record), stamp)
        self._last = stamp
        self.frames += 1

    def write_events(self, events: list[dict[str, Any]], stamp_ns: int) -> None:
        """Guide events (their ``to_dict()``), one String each."""
        for event in events:
            self._write("/stereo_classic/guide/events", json_string(event), max(stamp_ns, self._last))

    def close(self) -> None:
        """Finish the file (summary and index) and rename it into place."""
        if self._file.closed:
            return
        try:
            self._writer.finish()
        finally:
            self._file.close()
        os.replace(self._tmp, self.path)


class McapFrameWriter:
    """A :class:`~stereo_classic.outputs.FrameWriter` that also appends each frame to a :class:`McapSink`
    (after the frame's files, so the recording holds the frames the folder holds, in order)."""

    def __init__(self, writer: Any, path: str | os.PathLike[str]) -> None:
        self.writer = writer
        self.sink = McapSink(path)

    def __getattr__(self, name: str) -> Any:  # finished, expected_files, kinds, ...: the folder writer's
        return getattr(self.writer, name)

    def write(self, name: str, result: Any, rig: Any, record: dict[str, Any]) -> list[Path]:
        written = self.writer.write(name, result, rig, record)
        self.sink.write_frame(result, rig, record)
        return written

    def close(self) -> None:
        self.sink.close()
