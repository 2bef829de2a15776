"""calib.formats.middlebury: golden values on the real Motorcycle calib.txt, millimetres to metres, scaling to
the image size, error paths, hostile values (hypothesis), plain values."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib import CalibrationError, RectifiedRig, load_rig, read_middlebury_calib
from calib.formats import middlebury


def test_middlebury_motorcycle(shared_data):
    rig = RectifiedRig.from_middlebury(shared_data / "middlebury2014/trainingQ/Motorcycle/calib.txt")
    assert rig.focal_px == pytest.approx(999.421)
    assert rig.baseline_m == pytest.approx(0.193001)  # 193.001 mm in the file
    assert rig.doffs == pytest.approx(32.778)
    assert rig.cx_left == pytest.approx(294.182) and rig.cy == pytest.approx(252.932)
    assert rig.image_size == (741, 497)
    raw = read_middlebury_calib(shared_data / "middlebury2014/trainingQ/Motorcycle/calib.txt")
    assert raw["ndisp"] == 70 and raw["baseline"] == pytest.approx(193.001)
    assert load_rig(shared_data / "middlebury2014/trainingQ/Motorcycle/calib.txt") == rig


def test_middlebury_depth_of_a_ground_truth_disparity(shared_data):
    rig = RectifiedRig.from_middlebury(shared_data / "middlebury2014/trainingQ/Motorcycle/calib.txt")
    # Z = baseline * f / (d + doffs): d = 40 px -> 0.193001 * 999.421 / 72.778
    assert float(rig.depth(np.array([40.0]))[0]) == pytest.approx(0.193001 * 999.421 / 72.778, rel=1e-6)


MOTO = "cam0=[999.421 0 294.182; 0 999.421 252.932; 0 0 1]\ncam1=[999.421 0 326.96; 0 999.421 252.932; 0 0 1]\n" \
       "doffs=32.778\nbaseline=193.001\nwidth=741\nheight=497\nndisp=70\n"


@pytest.mark.parametrize(
    "text, match",
    [
        (MOTO.replace("baseline=193.001\n", ""), "missing key `baseline`"),
        (MOTO.replace("cam1=", "camX="), "missing key `cam1`"),
        (MOTO.replace("width=741\n", ""), "missing key `width`"),
        (MOTO.replace("baseline=193.001", "baseline=abc"), "key `baseline` must hold numbers"),
        (MOTO.replace("baseline=193.001", "baseline=-5"), "key `baseline` must be a positive"),
        (MOTO.replace("0 0 1]\ncam1", "0 1]\ncam1"), "key `cam0` must be a 3x3"),
        (MOTO.replace("999.421 0 294.182", "999.421 0 x"), "key `cam0` must hold numbers"),
        (MOTO.replace("999.421 0 294.182", "nan 0 294.182"), "key `cam0` must be finite"),
        (MOTO.replace("999.421 0 294.182", "-999.421 0 294.182"), "focal_px"),
        (MOTO.replace("width=741", "width=741.5"), "width"),
        ("just some words\n", "line 1 is not `key=value`"),
    ],
)
def test_middlebury_errors(tmp_path, text, match):
    path = tmp_path / "calib.txt"
    path.write_text(text)
    with pytest.raises(CalibrationError, match=match) as info:
        RectifiedRig.from_middlebury(path)
    assert str(path) in str(info.value)


num = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=32), st.integers(-10**6, 10**6))


@settings(max_examples=180, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(f=num, cx=num, baseline=num, doffs=num, width=num)
def test_property_middlebury_values_valid_or_named_error(tmp_path, f, cx, baseline, doffs, width):
    path = tmp_path / "calib.txt"
    path.write_text(f"cam0=[{f} 0 {cx}; 0 {f} 200; 0 0 1]\ncam1=[{f} 0 {cx}; 0 {f} 200; 0 0 1]\n"
                    f"doffs={doffs}\nbaseline={baseline}\nwidth={width}\nheight=400\n")
    try:
        rig = RectifiedRig.from_middlebury(path)
    except CalibrationError as exc:
        assert str(path) in str(exc)
    else:
        assert rig.focal_px > 0 and rig.baseline_m > 0 and np.isfinite(rig.doffs) and rig.image_size[0] > 0
        assert rig.baseline_m == pytest.approx(float(baseline) / 1000.0)


# ------------------------------------------------------------------------- Middlebury size vs image_size
def test_middlebury_full_size_calib_beside_quarter_size_images_is_scaled(tmp_path, caplog):
    full = MOTO.replace("999.421 0 294.182", "3997.684 0 1176.728").replace("999.421 252.932", "3997.684 1011.728") \
               .replace("999.421 0 326.96", "3997.684 0 1307.84").replace("doffs=32.778", "doffs=131.112") \
               .replace("width=741", "width=2964").replace("height=497", "height=1988")
    path = tmp_path / "calib.txt"
    path.write_text(full)
    with caplog.at_level(logging.INFO, logger="calib"):
        rig = RectifiedRig.from_middlebury(path, image_size=(741, 497))
    assert rig.image_size == (741, 497)
    assert rig.focal_px == pytest.approx(3997.684 / 4)
    assert rig.cx_left == pytest.approx((1176.728 + 0.5) / 4 - 0.5)
    assert rig.doffs == pytest.approx(131.112 / 4)
    assert rig.baseline_m == pytest.approx(0.193001)
    assert "2964x1988" in caplog.text and "741x497" in caplog.text
    # same size: unchanged
    same = tmp_path / "same.txt"
    same.write_text(MOTO)
    assert RectifiedRig.from_middlebury(same, image_size=(741, 497)).focal_px == pytest.approx(999.421)


def test_middlebury_calib_of_another_aspect_ratio_is_refused(tmp_path):
    path = tmp_path / "calib.txt"
    path.write_text(MOTO)
    with pytest.raises(CalibrationError, match="741x497") as info:
        RectifiedRig.from_middlebury(path, image_size=(741, 300))
    assert "741x300" in str(info.value) and str(path) in str(info.value)


def test_readers_return_plain_values(tmp_path):
    path = tmp_path / "calib.txt"
    path.write_text(MOTO)
    raw = read_middlebury_calib(path)
    assert raw["cam0"].shape == (3, 3) and raw["baseline"] == 193.001 and raw["width"] == 741.0
    values = middlebury.read_rectified(path)
    assert values == {"focal_px": 999.421, "cx_left": 294.182, "cx_right": 294.182 + 32.778, "cy": 252.932,
                      "baseline_m": 193.001 / 1000.0, "image_size": (741, 497)}
    assert RectifiedRig(**values) == RectifiedRig.from_middlebury(path)
