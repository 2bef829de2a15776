"""ROS parameters generated from SGMParams, FusionParams and GuideParams: every CLI option, the same parsers."""

from __future__ import annotations

import pytest

from stereo_classic.cli.options import option_fields
from stereo_classic.fusion import FusionParams
from stereo_classic.guide import GuideParams
from stereo_classic.matching import SGMParams
from stereo_classic.ros.parameters import dataclass_values, parameter_table


@pytest.mark.parametrize("cls, prefix", [(SGMParams, "matcher"), (FusionParams, "fusion"), (GuideParams, "guide")])
def test_every_option_field_is_a_parameter_with_a_ros_type(cls, prefix):
    table = parameter_table(cls, prefix)
    assert [p.field for p in table] == [f.name for f in option_fields(cls)]
    for p in table:
        assert isinstance(p.default, (bool, int, float, str, list)) and p.description
    defaults = {p.name: p.default for p in table}
    assert dataclass_values(cls, prefix, defaults) == {}  # the defaults give the dataclass's own defaults
    cls(**dataclass_values(cls, prefix, defaults))


def test_values_are_read_as_the_flags_read_them():
    values = {"matcher.census_window": "9x7", "matcher.lr_check": "off", "matcher.num_disparities": 96,
              "matcher.p1": ""}
    got = dataclass_values(SGMParams, "matcher", values)
    assert got == {"census_window": (9, 7), "lr_check": None, "num_disparities": 96}
    SGMParams(**got)
    assert dataclass_values(FusionParams, "fusion", {"fusion.depth_range": [0.5, 40.0]}) == {
        "depth_range": (0.5, 40.0)}
    with pytest.raises(ValueError, match="parameter matcher.census_window"):
        dataclass_values(SGMParams, "matcher", {"matcher.census_window": "big"})


def test_command_defaults_replace_the_dataclass_default():
    table = {p.name: p for p in parameter_table(SGMParams, "matcher", {"num_disparities": 128})}
    assert table["matcher.num_disparities"].default == 128
    assert dataclass_values(SGMParams, "matcher", {"matcher.num_disparities": 128}, {"num_disparities": 128}) == {
        "num_disparities": 128}
