"""ROS 2 for the pipeline: rosbag2 (MCAP) recordings as input and output, and a live node.

* :mod:`stereo_classic.ros.images`: ``sensor_msgs/Image`` / ``CompressedImage`` to arrays, ``CameraInfo`` to a rig
  (plain values and numpy; no ROS needed).
* :mod:`stereo_classic.ros.bag`: :class:`~stereo_classic.ros.bag.BagSource`, the frames of a recording, paired by
  header stamp and read one at a time (the ``bag`` extra: ``mcap``, ``mcap-ros2-support``).
* :mod:`stereo_classic.ros.results`: the results of a frame as ROS 2 messages (``stereo_msgs/DisparityImage``,
  ``visualization_msgs/MarkerArray``, JSON on ``std_msgs/String``), as plain dicts.
* :mod:`stereo_classic.ros.node`: ``python -m stereo_classic ros``, the live node (the ``ros`` extra: ``rclpy`` and
  the message packages, from the wheels or a system ROS 2 installation).

Nothing here is imported by the rest of the package unless asked for; each optional dependency is imported when
used, and a missing one is named in one line (:class:`MissingDependencyError`).
"""

from __future__ import annotations

import importlib
from types import ModuleType

__all__ = ["MissingDependencyError", "require"]

#: What to install for each optional module: the extra, and the packages.
_INSTALL = {
    "mcap": 'the bag extra: pip install "stereo-classic[bag]" (mcap, mcap-ros2-support)',
    "mcap_ros2": 'the bag extra: pip install "stereo-classic[bag]" (mcap, mcap-ros2-support)',
    "rclpy": 'the ros extra: pip install "stereo-classic[ros]" (ros-rclpy and the message wheels), '
             "or source a ROS 2 installation (source /opt/ros/<distro>/setup.bash)",
}
for _msgs in ("sensor_msgs", "stereo_msgs", "visualization_msgs", "std_msgs", "geometry_msgs"):
    _INSTALL[_msgs] = _INSTALL["rclpy"]


class MissingDependencyError(ImportError):
    """An optional dependency that is not installed; the message says what to install."""


def require(module: str, what: str) -> ModuleType:
    """Import ``module`` (dotted), or raise :class:`MissingDependencyError` naming ``what`` needs it and how to
    install it.

    >>> require("json", "a test").__name__
    'json'
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        top = module.split(".")[0]
        hint = _INSTALL.get(top, f"pip install {top}")
        raise MissingDependencyError(f"{what} needs the Python module {module} ({exc}); install {hint}") from None
