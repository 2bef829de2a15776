"""calib: the stereo rig (intrinsics, distortion, R/T), rectification, calibration file formats."""

__all__: list[str] = []
