"""stereo_classic.pipeline: Localizer, PipelineResult, format_timings."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from stereo_classic.pipeline import STAGES, Localizer, format_timings
from tests.helpers.detectors import FixedBoxes
from tests.helpers.scenes import make_rig, planted_scene


@pytest.fixture(scope="module")
def scene():
    left, right, gt, _ = planted_scene(z_box=3.0, z_wall=8.0, box=(80, 50, 160, 110), seed=1)
    return left, right, gt


def test_localizer_smoke_depth_only(scene):
    left, right, _ = scene
    with Localizer(make_rig(240, 160), None, {"num_disparities": 48}) as loc:
        result = loc(left, right)
    assert result.detections is None and len(result.objects) == 0
    assert result.disparity.disparity.shape == (160, 240)
    assert list(result.timings_ms) == list(STAGES)


def test_localizer_accuracy_reuse_and_concurrency(scene):
    left, right, _ = scene
    det = FixedBoxes([[80, 50, 160, 110], [0, 0, 40, 30]])
    seq = Localizer(make_rig(240, 160), det, {"num_disparities": 48}, concurrent=False)
    con = Localizer(make_rig(240, 160), det, {"num_disparities": 48}, concurrent=True)
    try:
        a, b, c = seq(left, right), con(left, right), con(left, right)
    finally:
        seq.close()
        con.close()
    assert det.calls == 3
    assert a.objects.distance_m[0] == pytest.approx(3.0, rel=0.01)
    assert json.dumps(a.objects.to_json()) == json.dumps(b.objects.to_json()) == json.dumps(c.objects.to_json())
    assert a.objects.labels == ("box", "car")
    np.testing.assert_array_equal(a.disparity.disparity, c.disparity.disparity)


def test_submit_gives_what_a_call_gives_with_the_rest_in_the_worker(scene):
    """Localizer.submit: matched in the caller's thread, detector, fusion and checks in the worker; the result is a
    call's (objects, warnings, disparity), frames submitted back to back included, and a bad pair raises here."""
    import threading

    from stereo_classic.matching import StereoInputError

    left, right, _ = scene
    threads = []

    class Spy(FixedBoxes):
        def detect(self, image):
            threads.append(threading.current_thread().name)
            return super().detect(image)

    det = Spy([[80, 50, 160, 110], [0, 0, 40, 30]])
    with Localizer(make_rig(240, 160), det, {"num_disparities": 48}) as seq:
        a = seq(left, right)
        swapped_a = seq(right, left)
    with Localizer(make_rig(240, 160), det, {"num_disparities": 48}) as loc:
        futures = [loc.submit(left, right), loc.submit(right, left), loc.submit(left, right)]
        b, swapped_b, c = (f.result() for f in futures)
        with pytest.raises(StereoInputError, match="differ in size"):
            loc.submit(left, right[:, :200])
    assert threads[:2] == [threading.current_thread().name] * 2 and all(t.startswith("localizer") for t in threads[2:])
    for x, y in ((a, b), (a, c), (swapped_a, swapped_b)):
        assert json.dumps(x.objects.to_json()) == json.dumps(y.objects.to_json())
        assert [w.to_json() for w in x.warnings] == [w.to_json() for w in y.warnings]
        np.testing.assert_array_equal(x.disparity.disparity, y.disparity.disparity)
    assert list(b.timings_ms) == list(STAGES) == list(b.cpu_ms)


def test_localizer_class_filter(scene):
    left, right, _ = scene
    with Localizer(make_rig(240, 160), FixedBoxes([[80, 50, 160, 110], [0, 0, 40, 30]]), {"num_disparities": 48},
                   classes=["car"]) as loc:
        result = loc(left, right)
    assert result.objects.labels == ("car",) and len(result.detections) == 1


@pytest.mark.parametrize("make, match", [
    (lambda l, r: (l, r[:, :200]), "`left` and `right` images differ in size: 240x160 and 200x160"),
    (lambda l, r: (l[:100], r[:100]), "`rig`: the calibration is for 240x160 images but `left` and `right` are 240x100"),
    (lambda l, r: ("left.png", r), "`left` must be an"),
    (lambda l, r: (l, None), "`right` must be an"),
])
def test_localizer_bad_images(scene, make, match):
    from stereo_classic.matching import StereoInputError

    left, right, _ = scene
    with Localizer(make_rig(240, 160), None, {"num_disparities": 48}) as loc, pytest.raises(StereoInputError, match=match):
        loc(*make(left, right))


@pytest.mark.parametrize("kwargs, match", [
    ({"rig": object()}, "rig"),
    ({"detector": 42}, "detector"),
    ({"params": 3}, "params"),
    ({"params": {"num_disparities": -1}}, "num_disparities"),
    ({"box_shrink": 2.0}, "box_shrink"),
    ({"seed": -1}, "seed"),
])
def test_localizer_bad_arguments(kwargs, match):
    args = {"rig": make_rig(240, 160), "detector": None, "params": None}
    args.update(kwargs)
    rig, det, params = args.pop("rig"), args.pop("detector"), args.pop("params")
    with pytest.raises(ValueError, match=match):
        Localizer(rig, det, params, **args)


def test_localizer_detector_by_path(yolox_nano, shared_data):
    from stereo_classic.datasets import demo_scene

    scene = demo_scene()
    with Localizer(scene.rig, str(yolox_nano), {"num_disparities": 80}, detector_options={"conf_threshold": 0.5}) as loc:
        result = loc(scene.left, scene.right)
    assert "motorcycle" in result.objects.labels
    # the pipeline's detector letterboxes into the smallest rectangle (741x497 -> 416x288), not the 416 square
    assert loc.detector.minimal_padding and loc.detector.input_size_for(741, 497) == (416, 288)


def test_open_detector_minimal_padding_where_the_model_allows():
    """open_detector: minimal padding by default; the square for ``square_input=True``, for an explicit
    ``minimal_padding``, and for a model that runs at its own size only (here one whose outputs are constants)."""
    from detectors import OnnxDetector
    from stereo_classic.pipeline import open_detector
    from tests.helpers.onnx_detectors import constant_detector, shape_echo_detector

    echo = shape_echo_detector(metadata={"imgsz": "[640, 640]"})
    assert open_detector(echo).input_size_for(1242, 375) == (640, 224)
    assert open_detector(echo, square_input=True).input_size_for(1242, 375) == (640, 640)
    assert open_detector(echo, minimal_padding=False).input_size_for(1242, 375) == (640, 640)
    raw = np.zeros((1, 84, 8400), np.float32)
    fixed = open_detector(constant_detector({"output0": raw}, input_shape=(1, 3, 640, 640)))
    assert isinstance(fixed, OnnxDetector) and not fixed.minimal_padding
    assert fixed.input_size_for(1242, 375) == (640, 640)


def test_format_timings():
    text = format_timings([{"disparity": 100.0, "total": 200.0}, {"disparity": 300.0, "total": 300.0, "extra": 1.0}])
    lines = text.splitlines()
    assert lines[0].split() == ["stage", "median", "ms", "mean", "ms"]
    assert lines[1].split() == ["disparity", "200.0", "200.0"]
    assert lines[2].split() == ["total", "250.0", "250.0"]
    assert lines[3].split()[0] == "extra"
    assert lines[-1] == "2 frames, 4.0 frames/s"
    assert format_timings([]) == "no frames"


# --- property test: any pair gives a well-formed result or a ValueError naming what is wrong --------------

from hypothesis import HealthCheck, event, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@st.composite
def _pairs(draw):
    h = draw(st.integers(1, 48))
    w = draw(st.integers(1, 64))
    dtype = draw(st.sampled_from([np.uint8, np.uint16, np.float32]))
    channels = draw(st.sampled_from([None, 3]))
    kind = draw(st.sampled_from(["noise", "const", "black", "nan", "repetitive"]))
    rng = np.random.default_rng(draw(st.integers(0, 1000)))
    shape = (h, w) if channels is None else (h, w, channels)
    if kind == "noise":
        left = rng.uniform(0, 255, shape)
    elif kind == "const":
        left = np.full(shape, 77.0)
    elif kind == "black":
        left = np.zeros(shape)
    elif kind == "repetitive":
        left = np.broadcast_to((np.arange(w) % 4 * 60.0).reshape((1, w) + (1,) * (len(shape) - 2)), shape).copy()
    else:
        left = rng.uniform(0, 255, shape)
        left.reshape(-1)[:: max(1, left.size // 3)] = np.nan
    right = np.roll(left, -draw(st.integers(0, 5)), axis=1)
    boxes = [[draw(st.floats(-10, 70)), draw(st.floats(-10, 50)), 0, 0] for _ in range(draw(st.integers(0, 3)))]
    for b in boxes:
        b[2], b[3] = b[0] + draw(st.floats(0, 60)), b[1] + draw(st.floats(0, 40))
    if dtype != np.float32:
        left, right = np.nan_to_num(left).astype(dtype), np.nan_to_num(right).astype(dtype)
    else:
        left, right = left.astype(np.float32), right.astype(np.float32)
    return left, right, boxes, draw(st.integers(1, 40))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_pairs())
def test_property_localizer_well_formed_or_value_error(case):
    from stereo_classic.fusion import STATUSES

    left, right, boxes, ndisp = case
    h, w = left.shape[:2]
    det = FixedBoxes(boxes) if boxes else None
    try:
        loc = Localizer(make_rig(w, h), det, {"num_disparities": ndisp, "threads": 1})
        result = loc(left, right)
    except ValueError as exc:
        # One line, and either one of the project's error classes or a message naming the parameter in
        # backticks: numpy's or numba's own ValueError from deep inside is a defect, not a clear message.
        from calib import CalibrationError
        from stereo_classic.fusion import FusionInputError
        from stereo_classic.matching import MemoryBudgetError, StereoInputError

        message = str(exc)
        assert message and "\n" not in message
        ours = isinstance(exc, (StereoInputError, MemoryBudgetError, FusionInputError, CalibrationError))
        assert ours or re.search(r"`[A-Za-z_][A-Za-z0-9_]*`", message), f"{type(exc).__name__}: {message}"
        event(type(exc).__name__)
        return
    event("result")
    assert result.disparity.disparity.shape == (h, w)
    assert len(result.objects) == len(boxes)
    for i, status in enumerate(result.objects.status):
        assert status in STATUSES
        if status == "ok":
            assert 0.3 <= result.objects.distance_m[i] <= 80.0
    json.dumps(result.objects.to_json(), allow_nan=False)
