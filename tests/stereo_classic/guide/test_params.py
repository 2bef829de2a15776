"""GuideParams: defaults, checks naming the parameter, replace."""

from __future__ import annotations

import pytest

from stereo_classic.guide import GuideInputError, GuideParams


def test_defaults():
    p = GuideParams()
    assert (p.head_height, p.corridor_width, p.step_height, p.camera_height, p.camera_pitch) == (2.0, 1.0, 0.15,
                                                                                                  None, None)
    assert p.to_dict()["units"] == "metres"


@pytest.mark.parametrize("kwargs, name", [
    ({"camera_height": 40.0}, "camera_height"),          # an absurd mounting height
    ({"camera_height": 0.0}, "camera_height"),
    ({"camera_height": float("nan")}, "camera_height"),
    ({"camera_pitch": 95.0}, "camera_pitch"),
    ({"head_height": -1.0}, "head_height"),
    ({"min_height": 2.5}, "min_height"),
    ({"danger_distance": 3.0}, "danger_distance"),
    ({"look_ahead": 100.0}, "look_ahead"),
    ({"units": "yards"}, "units"),
    ({"directions": "compass"}, "directions"),
    ({"sectors": 0}, "sectors"),
    ({"corridor_width": "wide"}, "corridor_width"),
])
def test_bad_values_name_the_parameter(kwargs, name):
    with pytest.raises(GuideInputError, match=f"`{name}`"):
        GuideParams(**kwargs)


def test_replace_checks_again_and_names_unknown_fields():
    assert GuideParams().replace(camera_height=1.5).camera_height == 1.5
    with pytest.raises(GuideInputError, match="unknown guide parameter"):
        GuideParams().replace(height=1.5)
    with pytest.raises(GuideInputError, match="camera_height"):
        GuideParams().replace(camera_height=12)
