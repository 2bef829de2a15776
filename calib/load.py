"""load_rig: any supported calibration file -> the rig it describes, the format recognised by content."""

from __future__ import annotations

from pathlib import Path

from calib.formats._common import PathLike
from calib.formats.sniff import sniff_format
from calib.rectified import RectifiedRig
from calib.rig import StereoRig

__all__ = ["load_rig"]


def load_rig(path: PathLike, *, image_size: tuple[int, int] | None = None) -> StereoRig | RectifiedRig:
    """Read any supported calibration file, recognised by its content.

    - ``.json`` with ``fx``/``cx0``/``cx1``: OAK-D / stereodemo -> :class:`RectifiedRig`
    - text with ``cam0=``: Middlebury ``calib.txt`` -> :class:`RectifiedRig`
    - text with ``P2:`` or ``P_rect_02:``: KITTI -> :class:`RectifiedRig` (left P2, right P3)
    - OpenCV YAML/XML with ``K1``/``M1``: -> :class:`StereoRig`; with only ``P1``/``P2`` or ``Q``: -> :class:`RectifiedRig`

    A single ROS ``camera_info`` file is refused (it describes one camera): use ``StereoRig.from_ros(left, right)``.

    Parameters
    ----------
    path : str or os.PathLike
        The calibration file.
    image_size : (width, height) or None
        Size of the images, for the formats that may lack it (OpenCV, KITTI) or describe another
        resolution (Middlebury); ignored for OAK-D JSON.

    Returns
    -------
    StereoRig or RectifiedRig

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    CalibrationError
        Unrecognised or invalid file; the message names the file and the key.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = Path(tmp) / "calib.txt"
    ...     _ = path.write_text("cam0=[700 0 320; 0 700 240; 0 0 1]\\ncam1=[700 0 330; 0 700 240; 0 0 1]\\n"
    ...                         "doffs=10\\nbaseline=100\\nwidth=640\\nheight=480\\n")
    ...     rig = load_rig(path)
    >>> rig.baseline_m, rig.doffs
    (0.1, 10.0)
    """
    kind = sniff_format(path)
    p = Path(path)
    if kind == "oakd":
        return RectifiedRig.from_oakd_json(p)
    if kind == "middlebury":
        return RectifiedRig.from_middlebury(p, image_size=image_size)
    if kind == "kitti":
        return RectifiedRig.from_kitti(p, image_size=image_size)
    if kind == "opencv_stereo":
        return StereoRig.from_opencv_yaml(p, image_size=image_size)
    return RectifiedRig.from_opencv_yaml(p, image_size=image_size)
