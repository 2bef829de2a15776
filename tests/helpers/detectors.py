"""A detector stand-in for the pipeline tests (test helper, no API)."""

from __future__ import annotations

import numpy as np

from detectors import Detections


class FixedBoxes:
    """Reports the same boxes for every image and counts its calls.

    Box ``i`` gets class ``names[i % len(names)]`` and the given confidence.
    """

    def __init__(self, boxes, names=("box", "car"), confidence=0.8):
        n = len(boxes)
        self.dets = Detections(xyxy=np.array(boxes, np.float32).reshape(n, 4),
                               confidence=np.full(n, confidence, np.float32),
                               class_id=np.arange(n) % len(names), class_names=tuple(names))
        self.calls = 0

    def detect(self, image):
        self.calls += 1
        return self.dets
