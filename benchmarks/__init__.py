"""benchmarks: reproducible accuracy and speed reports against OpenCV StereoSGBM."""
