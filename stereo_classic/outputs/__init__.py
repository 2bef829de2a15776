"""What the pipeline hands to people and files: pictures, and every file ``run`` writes.

- :mod:`~stereo_classic.outputs.visualize`: :func:`colorize` (disparity/depth to colour), :func:`draw_boxes`
- :mod:`~stereo_classic.outputs.files`: :class:`FrameWriter` (one frame's files, all or nothing),
  :class:`JsonlSink` (``objects.jsonl``), :func:`frame_record` (the JSON record of a frame), :data:`SAVE_KINDS`
"""

from stereo_classic.outputs.files import (
    DEFAULT_SAVE,
    JSONL_NAME,
    SAVE_KINDS,
    FrameWriter,
    JsonlSink,
    box_labels,
    frame_record,
    write_all_or_nothing,
)
from stereo_classic.outputs.folder import (
    FolderBusyError,
    OutputFolder,
    SettingsMismatchError,
)
from stereo_classic.outputs.visualize import PALETTE, colorize, draw_boxes

__all__ = [
    "DEFAULT_SAVE",
    "JSONL_NAME",
    "PALETTE",
    "SAVE_KINDS",
    "FolderBusyError",
    "FrameWriter",
    "JsonlSink",
    "OutputFolder",
    "SettingsMismatchError",
    "box_labels",
    "colorize",
    "draw_boxes",
    "frame_record",
    "write_all_or_nothing",
]
