"""Tests for stereo_classic.fusion.params: FusionParams (the one home of the fusion defaults) and as_generator."""

from __future__ import annotations

import dataclasses
import inspect
import json
import math

import numpy as np
import pytest

from stereo_classic.fusion import FusionInputError, FusionParams, as_generator, localize
from stereo_classic.pipeline import Localizer
from tests.helpers.scenes import make_rig, planted_scene

_DEFAULTS = dict(method="ransac", box_shrink=0.2, depth_range=(0.3, 80.0), min_pixels=20, tolerance_px=1.0,
                 near_support=0.5, centre_sigma=0.25, grow_density=0.1, max_clusters=3, max_iterations=256,
                 max_samples=10000, occluder_ratio=1.5, occluder_offset=0.25, ground_contact=True)
#: The fields that are `run` flags today, with their argparse metavar.
_FLAGS = {"method": None, "box_shrink": "F", "depth_range": ("NEAR", "FAR"), "min_pixels": "N",
          "tolerance_px": "PX", "near_support": "F", "centre_sigma": "F", "grow_density": "F",
          "occluder_ratio": "R", "occluder_offset": "F", "ground_contact": None}


# --- smoke / defaults --------------------------------------------------------------------------------

def test_defaults_are_the_documented_ones():
    assert dataclasses.asdict(FusionParams()) == _DEFAULTS
    assert [f.name for f in dataclasses.fields(FusionParams)] == list(_DEFAULTS)


def test_defaults_equal_localize_behaviour():
    """localize without options, with FusionParams() and with every default spelled out give the same result."""
    rng = np.random.default_rng(1)
    _, _, gt, rig = planted_scene(z_box=3.0, z_wall=8.0)
    d = gt + rng.normal(0, 0.25, gt.shape).astype(np.float32)
    boxes = np.array([[80, 50, 160, 110], [0, 0, 240, 160]], np.float32)  # the second: > max_samples pixels
    plain = localize(boxes, d, rig, rng=3)
    for other in (localize(boxes, d, rig, FusionParams(), rng=3), localize(boxes, d, rig, rng=3, **_DEFAULTS)):
        assert json.dumps(other.to_json()) == json.dumps(plain.to_json())
        np.testing.assert_array_equal(other.xyz, plain.xyz)
    assert plain.status == ("ok", "ok")


def test_localize_takes_params_and_overrides():
    rig = make_rig(40, 20, focal_px=500.0, baseline_m=0.1)
    d = np.full((20, 40), 10.0, np.float32)
    d[:, 30:] = 25.0  # the near set has a third of the far set's support
    box = np.array([[0, 0, 40, 20]])
    strict = FusionParams(box_shrink=0.0, near_support=1.0, centre_sigma=0)
    assert localize(box, d, rig, strict).distance_m[0] == pytest.approx(5.0)
    # overrides win (the near set at the box's right edge is no occluder with occluder_offset=0.5)
    assert localize(box, d, rig, strict, near_support=0.3, occluder_offset=0.5).distance_m[0] == pytest.approx(2.0)
    assert localize(box, d, rig, strict, method="median").method == "median"


# --- normalisation / shapes and types ------------------------------------------------------------------

def test_fields_are_normalised():
    p = FusionParams(box_shrink=0, depth_range=[1, 20], tolerance_px=np.float32(0.5), max_iterations=np.int64(8),
                     min_pixels=np.int32(5), near_support=1, centre_sigma=0, grow_density=np.float64(0.2))
    assert p.depth_range == (1.0, 20.0) and isinstance(p.depth_range, tuple)
    for name in ("box_shrink", "tolerance_px", "near_support", "centre_sigma", "grow_density"):
        assert type(getattr(p, name)) is float, name
    for name in ("min_pixels", "max_clusters", "max_iterations", "max_samples"):
        assert type(getattr(p, name)) is int, name
    assert all(type(v) is float for v in p.depth_range)
    assert p == FusionParams(box_shrink=0.0, depth_range=(1.0, 20.0), tolerance_px=0.5, max_iterations=8,
                             min_pixels=5, near_support=1.0, centre_sigma=0.0, grow_density=0.2)


def test_frozen_and_hashable():
    p = FusionParams()
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.box_shrink = 0.5  # type: ignore[misc]
    assert hash(p) == hash(FusionParams()) and p == FusionParams()


def test_replace_checks_again_and_names_unknown_fields():
    p = FusionParams()
    q = p.replace(method="median", depth_range=[1, 2])
    assert q.method == "median" and q.depth_range == (1.0, 2.0) and p.method == "ransac"
    assert p.replace() == p
    with pytest.raises(FusionInputError, match="`box_shrink`"):
        p.replace(box_shrink=2.0)
    with pytest.raises(FusionInputError, match="'bogus'.*'seed'.*expected some of: method, box_shrink") as err:
        p.replace(seed=1, bogus=2)
    assert "max_samples" in str(err.value)


def test_to_dict_is_json_friendly_and_round_trips():
    p = FusionParams(depth_range=(1, 30), method="median")
    out = p.to_dict()
    assert out["depth_range"] == [1.0, 30.0] and out["method"] == "median"
    assert json.loads(json.dumps(out)) == out
    assert FusionParams(**out) == p


def test_cli_metadata_for_the_run_flags():
    fields = {f.name: f for f in dataclasses.fields(FusionParams)}
    for name, metavar in _FLAGS.items():
        meta = fields[name].metadata
        assert meta["help"] and "default" not in meta["help"], name
        assert meta["metavar"] == metavar, name
    assert fields["method"].metadata["choices"] == ("ransac", "median")
    assert fields["depth_range"].metadata["nargs"] == 2
    for name in ("max_clusters", "max_iterations", "max_samples"):
        assert "help" not in fields[name].metadata


# --- error paths -------------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, needle", [
    ({"method": "mean"}, "`method`"),
    ({"method": None}, "`method`"),
    ({"box_shrink": 1.0}, "`box_shrink`"),
    ({"box_shrink": -0.1}, "`box_shrink`"),
    ({"box_shrink": "x"}, "`box_shrink`"),
    ({"box_shrink": None}, "`box_shrink`"),
    ({"depth_range": (5, 1)}, "`depth_range`"),
    ({"depth_range": (0.0, math.inf)}, "`depth_range`"),
    ({"depth_range": (-1.0, 5.0)}, "`depth_range`"),
    ({"depth_range": 3}, "`depth_range`"),
    ({"depth_range": (1, 2, 3)}, "`depth_range`"),
    ({"min_pixels": 0}, "`min_pixels`"),
    ({"min_pixels": 2.5}, "`min_pixels`"),
    ({"min_pixels": True}, "`min_pixels`"),
    ({"tolerance_px": 0}, "`tolerance_px`"),
    ({"tolerance_px": math.nan}, "`tolerance_px`"),
    ({"tolerance_px": "x"}, "`tolerance_px`"),
    ({"near_support": 0}, "`near_support`"),
    ({"near_support": 1.5}, "`near_support`"),
    ({"centre_sigma": -1}, "`centre_sigma`"),
    ({"centre_sigma": math.inf}, "`centre_sigma`"),
    ({"grow_density": 2}, "`grow_density`"),
    ({"grow_density": -0.1}, "`grow_density`"),
    ({"max_clusters": 0}, "`max_clusters`"),
    ({"max_iterations": -3}, "`max_iterations`"),
    ({"max_samples": 1.5}, "`max_samples`"),
])
def test_every_bad_value_names_its_field(kwargs, needle):
    with pytest.raises(FusionInputError, match=needle):
        FusionParams(**kwargs)
    with pytest.raises(FusionInputError, match=needle):  # localize checks through FusionParams
        localize(np.zeros((0, 4)), np.zeros((2, 2), np.float32), make_rig(2, 2), **kwargs)
    with pytest.raises(FusionInputError, match=needle):
        FusionParams().replace(**kwargs)


def test_messages_say_expected_and_got():
    with pytest.raises(FusionInputError, match=r"^`box_shrink` must be in \[0, 1\), got 1.0$"):
        FusionParams(box_shrink=1)
    with pytest.raises(FusionInputError, match=r"^`max_samples` must be an int >= 1, got 1.5$"):
        FusionParams(max_samples=1.5)
    with pytest.raises(FusionInputError, match=r"^`depth_range` must satisfy 0 <= near < far \(finite metres\), "
                                               r"got \(5, 1\)$"):
        FusionParams(depth_range=(5, 1))


def test_localize_rejects_unknown_keywords_and_bad_params():
    args = (np.zeros((0, 4)), np.zeros((2, 2), np.float32), make_rig(2, 2))
    with pytest.raises(FusionInputError, match="'shrink'"):
        localize(*args, shrink=0.1)
    with pytest.raises(FusionInputError, match="`params` must be a FusionParams"):
        localize(*args, {"box_shrink": 0.1})
    assert isinstance(FusionInputError("x"), ValueError)


def test_localizer_checks_its_fusion_options_when_built():
    """The pipeline checks the fusion options before the first frame (not with a dummy localize call)."""
    with pytest.raises(FusionInputError, match="`box_shrink`"):
        Localizer(make_rig(8, 8), None, {"num_disparities": 16}, box_shrink=1.5)
    with pytest.raises(FusionInputError, match="`method`"):
        Localizer(make_rig(8, 8), None, {"num_disparities": 16}, method="mean")
    Localizer(make_rig(8, 8), None, {"num_disparities": 16}, box_shrink=0.3).close()


def test_localize_signature_has_the_params_and_the_seed():
    sig = inspect.signature(localize)
    assert list(sig.parameters)[:4] == ["detections", "disparity_map", "rig", "params"]
    assert sig.parameters["rng"].kind is inspect.Parameter.KEYWORD_ONLY and sig.parameters["rng"].default is None


# --- as_generator: the one check of the seed ---------------------------------------------------------

def test_as_generator():
    gen = np.random.default_rng(4)
    assert as_generator(gen) is gen
    assert as_generator(None).integers(1 << 30) == np.random.default_rng(0).integers(1 << 30)
    assert as_generator(7).integers(1 << 30) == np.random.default_rng(7).integers(1 << 30)
    assert as_generator(np.int64(7)).integers(1 << 30) == np.random.default_rng(7).integers(1 << 30)


@pytest.mark.parametrize("rng", [-1, True, "seed", 1.5, np.random.RandomState(0)])
def test_as_generator_names_rng(rng):
    with pytest.raises(FusionInputError, match="^`rng` must be None, a non-negative int seed or a numpy Generator"):
        as_generator(rng)
