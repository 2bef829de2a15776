"""SGMParams (stereo_classic.matching.params): checks, derived values, memory limit, command-line metadata."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stereo_classic.matching.params import (
    MEMORY_LIMIT_ENV,
    SGMParams,
    default_memory_limit,
    parse_bytes,
    parse_census_window,
    parse_lr_check,
)


# --------------------------------------------------------------------------------------------------
# SGMParams
# --------------------------------------------------------------------------------------------------
class TestParams:
    def test_defaults_and_effective_penalties(self):
        p = SGMParams()
        assert (p.cost, p.num_disparities, p.block_size, p.paths) == ("census+grad", 64, 5, 3)
        assert (p.lr_check, p.fill_holes) == (1.0, True)
        assert (p.effective_p1, p.effective_p2) == (28, 112)
        assert (p.replace(cost="census").effective_p1, p.replace(cost="census").effective_p2) == (20, 80)
        sad = p.replace(cost="sad", block_size=3)
        assert (sad.effective_p1, sad.effective_p2) == (8 * 9, 32 * 9)
        assert p.replace(p1=3, p2=30).effective_p2 == 30
        assert p.max_disparity == 63
        assert SGMParams(min_disparity=-10, num_disparities=20).max_disparity == 9

    def test_frozen_replace_to_dict(self):
        p = SGMParams(num_disparities=100)  # any positive count, not only multiples of 16
        with pytest.raises(dataclasses.FrozenInstanceError):
            p.num_disparities = 3  # type: ignore[misc]
        q = p.replace(uniqueness=10)
        assert q.uniqueness == 10.0 and p.uniqueness == 0.0
        d = q.to_dict()
        assert d["num_disparities"] == 100 and d["census_window"] == [9, 7]
        assert SGMParams(**{**d, "census_window": tuple(d["census_window"])}) == q
        with pytest.raises(ValueError, match="unknown SGM parameter.*'num_disp'"):
            p.replace(num_disp=3)

    def test_normalises_numpy_scalars(self):
        p = SGMParams(num_disparities=np.int64(32), uniqueness=np.float32(5), census_window=[7, 7])
        assert type(p.num_disparities) is int and p.census_window == (7, 7) and p.uniqueness == 5.0

    @pytest.mark.parametrize("field, value", [
        ("min_disparity", 1.5), ("min_disparity", "0"), ("min_disparity", 10**6),
        ("num_disparities", 0), ("num_disparities", -16), ("num_disparities", 16.0), ("num_disparities", True),
        ("num_disparities", 10**6),
        ("block_size", 4), ("block_size", 0), ("block_size", 23), ("block_size", 5.0),
        ("p1", -1), ("p1", 2.5), ("p2", 10**6), ("p1_vertical", -1), ("p1_vertical", 3.5), ("p1_vertical", 112),
        ("p1_vertical_texture", 0), ("outside_match", "free"), ("outside_match", None),
        ("cost", "ssd"), ("cost", None),
        ("census_window", (9, 9)), ("census_window", (8, 7)), ("census_window", 9), ("census_window", (9, 7, 1)),
        ("adaptive_p2", 1), ("subpixel", "yes"), ("fill_holes", None),
        ("weak_texture_gain", 0.5), ("weak_texture_gain", 9), ("weak_texture_gain", "2"),
        ("weak_texture_gain", float("nan")), ("weak_texture_gain", None),
        ("uniqueness", -1), ("uniqueness", 101), ("uniqueness", float("nan")),
        ("lr_check", -1), ("lr_check", float("inf")), ("lr_check", "1"), ("lr_mode", "strict"), ("lr_mode", None),
        ("right_view", 1),
        ("speckle_size", -1), ("speckle_size", 2.5), ("speckle_range", -0.5), ("speckle_range", float("nan")),
        ("paths", 16), ("paths", 2), ("threads", 0), ("threads", 1.5),
        ("memory_limit", 0), ("memory_limit", -5), ("memory_limit", 1.5e9),
    ])
    def test_bad_field_names_field(self, field, value):
        with pytest.raises(ValueError, match=f"`{field}`"):
            SGMParams(**{field: value})

    def test_weak_texture_gain_bounds_p2(self):
        assert SGMParams(weak_texture_gain=1).weak_texture_gain == 1.0  # off; normalised to float
        SGMParams(cost="census", p2=336)  # 336 * 4 at a weak-texture pixel: the int16 sums' limit
        with pytest.raises(ValueError, match="weak_texture_gain"):
            SGMParams(cost="census", p2=337)
        assert SGMParams(cost="census", p2=1343, weak_texture_gain=1).p2 == 1343  # without the factor

    def test_p1_vertical_defaults_to_p1_and_the_old_rule(self):
        p = SGMParams()
        assert (p.effective_p1_vertical, p.p1_vertical_texture) == (p.effective_p1, True)
        assert SGMParams(p1=10, p2=50).effective_p1_vertical == 10
        assert SGMParams(p1_vertical=40).effective_p1_vertical == 40

    @pytest.mark.parametrize("kwargs", [dict(p1=80, p2=80), dict(p1=120), dict(cost="sad", p2=10)])
    def test_p2_must_exceed_p1(self, kwargs):
        with pytest.raises(ValueError, match="`p2` must be larger than `p1`"):
            SGMParams(**kwargs)

    def test_memory_limit_from_env(self, monkeypatch):
        monkeypatch.setenv(MEMORY_LIMIT_ENV, "2G")
        assert SGMParams().effective_memory_limit == 2 * 1024**3
        assert SGMParams(memory_limit=1234).effective_memory_limit == 1234
        monkeypatch.setenv(MEMORY_LIMIT_ENV, "lots")
        with pytest.raises(ValueError, match=MEMORY_LIMIT_ENV):
            default_memory_limit()
        monkeypatch.delenv(MEMORY_LIMIT_ENV)
        assert default_memory_limit() > 100 * 1024**2  # half of this machine's RAM

    @pytest.mark.parametrize("text, expected",
                             [("4096", 4096), ("1k", 1024), ("1.5 GiB", 3 * 2**29), ("2MB", 2 * 2**20)])
    def test_parse_bytes(self, text, expected):
        assert parse_bytes(text) == expected

    @pytest.mark.parametrize("text", ["", "-1G", "0", "1X", "G", "nan"])
    def test_parse_bytes_rejects(self, text):
        with pytest.raises(ValueError, match="byte count"):
            parse_bytes(text)



# --------------------------------------------------------------------------------------------------
# command-line metadata (the CLI flags and the config file are generated from it)
# --------------------------------------------------------------------------------------------------
_FLAG_FIELDS = {"min_disparity", "num_disparities", "cost", "block_size", "census_window", "p1", "p2", "uniqueness",
                "lr_check", "lr_mode", "speckle_size", "speckle_range", "paths", "adaptive_p2", "subpixel",
                "fill_holes", "median_filter", "border_reach", "border_check", "outside_match", "weak_texture_gain", "p1_vertical",
                "p1_vertical_texture",
                "feature_model", "feature_input", "feature_similarity", "feature_census", "onnx_provider"}


class TestCliMetadata:
    def test_every_flag_field_has_help_and_no_other_field_does(self):
        fields = {f.name: f for f in dataclasses.fields(SGMParams)}
        assert {name for name, f in fields.items() if "help" in f.metadata} == _FLAG_FIELDS
        for name, f in fields.items():
            meta = f.metadata
            assert set(meta) <= {"help", "metavar", "choices", "parse"}, name
            if "help" not in meta:
                assert not meta, name  # right_view, threads, memory_limit: library-only fields
                continue
            assert isinstance(meta["help"], str) and meta["help"].strip(), name
            assert isinstance(meta.get("metavar", ""), str), name
            if "choices" in meta:
                assert isinstance(meta["choices"], tuple) and f.default in meta["choices"], name
                for choice in meta["choices"]:
                    SGMParams(**{name: choice})  # every choice is a valid value
            if "parse" in meta:
                assert callable(meta["parse"]), name

    def test_metadata_values(self):
        meta = {f.name: f.metadata for f in dataclasses.fields(SGMParams)}
        assert meta["lr_mode"]["choices"] == ("full", "opencv", "independent") and meta["paths"]["choices"] == (3, 4, 8)
        assert meta["census_window"]["parse"] is parse_census_window and meta["lr_check"]["parse"] is parse_lr_check
        assert meta["census_window"]["metavar"] == "WxH" and meta["lr_check"]["metavar"] == "PX|off"
        assert meta["subpixel"]["help"] == "integer disparities only"  # the help of --no-subpixel

    @pytest.mark.parametrize("text, expected", [("9x7", (9, 7)), ("9,7", (9, 7)), ("5X5", (5, 5)), (" 3x3", (3, 3))])
    def test_parse_census_window(self, text, expected):
        assert parse_census_window(text) == expected
        assert SGMParams(census_window=parse_census_window(text)).census_window == expected

    @pytest.mark.parametrize("text", ["abc", "9", "9x7x1", "9xa", "", "x"])
    def test_parse_census_window_rejects(self, text):
        with pytest.raises(ValueError, match=re.escape(f"expected WIDTHxHEIGHT such as 9x7, got {text!r}")):
            parse_census_window(text)

    @pytest.mark.parametrize("text, expected", [("off", None), ("None", None), ("no", None), ("1.5", 1.5), ("0", 0.0),
                                                ("2", 2.0)])
    def test_parse_lr_check(self, text, expected):
        assert parse_lr_check(text) == expected
        assert SGMParams(lr_check=parse_lr_check(text)).lr_check == expected

    @pytest.mark.parametrize("text", ["abc", "", "1 px", "offf"])
    def test_parse_lr_check_rejects(self, text):
        with pytest.raises(ValueError, match=re.escape(f"expected a number of pixels or 'off', got {text!r}")):
            parse_lr_check(text)

    @pytest.mark.parametrize("name, value", [("census_window", (7, 5)), ("lr_check", 1.5), ("lr_check", None)])
    def test_parse_round_trips_the_written_value(self, name, value):
        parse = next(f for f in dataclasses.fields(SGMParams) if f.name == name).metadata["parse"]
        text = "off" if value is None else ("x".join(map(str, value)) if isinstance(value, tuple) else str(value))
        assert parse(text) == value


_ANY = st.one_of(st.none(), st.booleans(), st.integers(-10**7, 10**7), st.floats(allow_nan=True),
                 st.text(max_size=3), st.tuples(st.integers(-3, 11), st.integers(-3, 11)))


@settings(max_examples=450, deadline=None)
@given(field=st.sampled_from([f.name for f in dataclasses.fields(SGMParams)]), value=_ANY)
def test_property_params_value_or_named_error(field, value):
    try:
        p = SGMParams(**{field: value})
    except ValueError as exc:
        assert f"`{field}`" in str(exc) or "`p2`" in str(exc), str(exc)
        return
    assert p.effective_p2 > p.effective_p1 >= 0
    assert SGMParams(**{**p.to_dict(), "census_window": p.census_window}) == p
