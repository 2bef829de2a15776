"""calib.formats.oakd: golden values on the real stereodemo JSON, error paths, hostile values (hypothesis),
plain values."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib import CalibrationError, RectifiedRig, load_rig, read_oakd_calib
from calib.formats import oakd


def test_oakd_json(shared_data):
    rig = RectifiedRig.from_oakd_json(shared_data / "oakd/stereodemo_calibration.json")
    assert rig.baseline_m == pytest.approx(0.075)
    assert rig.focal_px == pytest.approx(451.0344543457031)
    assert rig.image_size == (640, 480) and rig.doffs == 0.0
    assert load_rig(shared_data / "oakd/stereodemo_calibration.json") == rig


OAKD = {"width": 640, "height": 480, "baseline_meters": 0.075, "fx": 451.03, "fy": 451.03, "cx0": 299.0, "cx1": 299.0, "cy": 255.1}


@pytest.mark.parametrize(
    "change, match",
    [
        ({"fx": None}, "missing key `fx`"),
        ({"baseline_meters": None}, "missing key `baseline_meters`"),
        ({"fx": "451"}, "key `fx` must be a finite number"),
        ({"cx0": True}, "key `cx0` must be a finite number"),
        ({"baseline_meters": -0.075}, "baseline_m"),
        ({"width": 640.5}, "width"),
        ({"cy": [1, 2]}, "key `cy`"),
    ],
)
def test_oakd_errors(tmp_path, change, match):
    data = {k: v for k, v in (OAKD | change).items() if v is not None}
    path = tmp_path / "calib.json"
    path.write_text(json.dumps(data))
    with pytest.raises(CalibrationError, match=match) as info:
        RectifiedRig.from_oakd_json(path)
    assert str(path) in str(info.value)


def test_oakd_not_json(tmp_path):
    path = tmp_path / "calib.json"
    path.write_text("{not json")
    with pytest.raises(CalibrationError, match="not valid JSON"):
        RectifiedRig.from_oakd_json(path)
    path.write_text("[1, 2]")
    with pytest.raises(CalibrationError, match="JSON object"):
        RectifiedRig.from_oakd_json(path)


num = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=32), st.integers(-10**6, 10**6))


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(fx=num, cx0=num, baseline=num, width=num)
def test_property_oakd_values_valid_or_named_error(tmp_path, fx, cx0, baseline, width):
    path = tmp_path / "calib.json"
    data = OAKD | {"fx": fx, "cx0": cx0, "baseline_meters": baseline, "width": width}
    path.write_text(json.dumps(data))  # NaN/inf become the non-standard NaN/Infinity tokens json accepts
    try:
        rig = RectifiedRig.from_oakd_json(path)
    except CalibrationError as exc:
        assert str(path) in str(exc)
    else:
        assert rig.focal_px > 0 and rig.baseline_m > 0 and np.isfinite([rig.cx_left, rig.doffs]).all()


def test_readers_return_plain_values(tmp_path):
    path = tmp_path / "calib.json"
    path.write_text(json.dumps(OAKD | {"depth_range": [0.3, 12]}))
    raw = read_oakd_calib(path)
    assert raw["depth_range"] == (0.3, 12.0) and raw["fy"] == 451.03
    values = oakd.read_rectified(path)
    assert values == {"focal_px": 451.03, "cx_left": 299.0, "cx_right": 299.0, "cy": 255.1, "baseline_m": 0.075,
                      "image_size": (640, 480)}
    assert RectifiedRig(**values) == RectifiedRig.from_oakd_json(path)
    path.write_text(json.dumps(OAKD | {"depth_range": [5, 1]}))
    with pytest.raises(CalibrationError, match="depth_range"):
        read_oakd_calib(path)
