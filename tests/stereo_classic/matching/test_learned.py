"""Learned matching costs: the feature-network checks, the row cost against the numpy reference, the shipped MC-CNN,
a tiny Siamese network built here giving a known disparity, and the memory estimate."""

from __future__ import annotations

import hashlib

import cv2
import numpy as np
import pytest

from stereo_classic.matching import MemoryBudgetError, SGMParams, compute_disparity, estimate_memory
from stereo_classic.matching import learned
from stereo_classic.matching import reference as ref
from stereo_classic.matching._kernels import core
from stereo_classic.matching.learned import FeatureModelError
from tests.helpers.onnx_features import (
    build_conv_features,
    build_divided_features,
    build_nan_features,
    build_rank5_input,
    build_strided_features,
)


def _texture_pair(shift: int, h: int = 48, w: int = 96, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Smooth random texture; right = left moved by ``shift`` px (d = x_left - x_right = shift everywhere)."""
    rng = np.random.default_rng(seed)
    big = cv2.GaussianBlur(rng.integers(0, 256, (h, w + shift)).astype(np.float32), (0, 0), 1.0)
    big = cv2.normalize(big, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    return np.ascontiguousarray(big[:, :w]), np.ascontiguousarray(big[:, shift:shift + w])


def _random_features(h: int, c: int, w: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    f = rng.standard_normal((h, c, w))
    f /= np.linalg.norm(f, axis=1, keepdims=True)
    return np.ascontiguousarray(np.round(f * 127).astype(np.int8))


# ------------------------------------------------------------------------------------------------ the row cost kernel
@pytest.mark.parametrize("similarity", ["dot", "l1"])
@pytest.mark.parametrize("channels, min_disparity, num_disparities", [(8, 0, 16), (7, -3, 20), (64, 2, 70)])
@pytest.mark.parametrize("census_share, census_window", [(0.0, (9, 7)), (0.5, (9, 7)), (0.3, (5, 5)), (1.0, (7, 7))])
def test_feature_row_cost_equals_the_numpy_reference(similarity, channels, min_disparity, num_disparities,
                                                      census_share, census_window):
    h, w = 5, 90
    left, right = _random_features(h, channels, w, 1), _random_features(h, channels, w, 2)
    right[:, :, :-10] = left[:, :, 10:]  # right(x) = left(x + 10): true matches at d = 10, low costs too
    grey_left = np.random.default_rng(3).integers(0, 256, (h, w)).astype(np.uint8)
    grey_right = np.ascontiguousarray(np.roll(grey_left, -10, axis=1))  # the census codes match at d = 10 too
    from stereo_classic.matching._kernels.features import FEATURE_OUTSIDE

    got = core.cost_volume(grey_left, grey_right, cost="features", min_disparity=min_disparity,
                           num_disparities=num_disparities, p2=300, features=(left, right),
                           feature_similarity=similarity, outside_cost=FEATURE_OUTSIDE, feature_census=census_share,
                           census_window=census_window)
    want = ref.feature_cost_reference(left, right, similarity=similarity, min_disparity=min_disparity,
                                      num_disparities=num_disparities, p2=300, census_share=census_share,
                                      images=(grey_left, grey_right), census_window=census_window)
    np.testing.assert_array_equal(got, want)
    if similarity == "dot" and 0 <= 10 - min_disparity < num_disparities:
        assert (got[:, 20:-20, 10 - min_disparity] <= 1).all()  # identical unit vectors and codes: cost ~0
    if census_share > 0:  # the census term is there: the cost differs from the network's alone
        alone = ref.feature_cost_reference(left, right, similarity=similarity, min_disparity=min_disparity,
                                           num_disparities=num_disparities, p2=300)
        assert (want != alone).mean() > 0.5


@pytest.mark.parametrize("paths", [3, 8])
@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("lr_check, census", [(1.0, 0.0), (None, 0.0), (1.0, 0.5)])
def test_a_match_outside_the_right_image_is_neutral_and_its_winner_unknown(paths, threads, lr_check, census):
    """A learned cost gives the candidates outside the right image ``FEATURE_OUTSIDE`` (not a forbidding cost), the
    sums are the reference's bit for bit, and a pixel whose winner is one of them is unknown (counted apart,
    ``n_outside``), also without an LR check."""
    from stereo_classic.matching._kernels.features import FEATURE_OUTSIDE, FEATURE_SCALE

    h, c, w, shift, D = 9, 16, 44, 12, 16
    left = _random_features(h, c, w, 3)
    right = _random_features(h, c, w, 4)
    right[:, :, :-shift] = left[:, :, shift:]  # true disparity 12: the first 12 columns' match is outside
    grey = np.random.default_rng(5).integers(0, 256, (h, w)).astype(np.uint8)
    grey_right = np.ascontiguousarray(np.roll(grey, -shift, axis=1))  # the census codes agree at d = 12 as well
    kw = dict(cost="features", features=(left, right), min_disparity=0, num_disparities=D, p1=29, p2=304,
              adaptive_p2=True, p1_cross=19, outside_cost=FEATURE_OUTSIDE, feature_census=census)
    C = ref.feature_cost_reference(left, right, num_disparities=D, census_share=census, images=(grey, grey_right))
    assert (C[:, 0, 1:] == FEATURE_OUTSIDE).all() and 0 < FEATURE_OUTSIDE < 2 * FEATURE_SCALE
    S = core.sum_volume(grey, grey_right, path_mask=core.PATH_MASKS[paths], threads=threads, **kw)
    want_S = ref.sum_reference(C, core.PATH_MASKS[paths], 29, 304, image=grey, p1_cross=19)
    np.testing.assert_array_equal(S, want_S)
    d, _, timings = core.sgm_match(grey, grey_right, threads=threads, lr_check=lr_check, paths=paths, **kw)
    want, _ = ref.select_reference(want_S, 0, lr_check=lr_check)
    np.testing.assert_array_equal(d, want)
    outside = np.argmin(want_S, axis=2) > np.arange(w)[None, :]  # first minimum beyond x: outside the image
    assert outside.any() and np.isnan(d[outside]).all()  # the rule is exercised, and its pixels are unknown
    assert np.isfinite(d[:, 2 * shift:]).mean() > 0.9  # inside, the true matches are found
    assert timings["n_outside"] == outside.sum()
    if lr_check is None:
        assert timings["n_failed_lr"] == 0


def test_features_must_be_an_int8_pair_of_the_image_size():
    grey = np.zeros((4, 30), np.uint8)
    f = _random_features(4, 8, 30, 0)
    for bad in (None, (f, f), (f, f[:, :, :20].copy()), (f.astype(np.int16), f.astype(np.int16))):
        with pytest.raises(ValueError, match="`features` must be two distinct C-contiguous int8 arrays"):
            core.cost_volume(grey, grey, cost="features", num_disparities=8, features=bad)


# ------------------------------------------------------------------------------------------------ a network built here
@pytest.mark.parametrize("rank", [2, 3, 4])
def test_a_tiny_siamese_network_finds_the_known_disparity(tmp_path, rank):
    path = build_conv_features(tmp_path / f"conv{rank}.onnx", channels=8, rank=rank)
    model = learned.FeatureModel(path)
    assert (model.channels, model.margin) == (8, 1)
    left, right = _texture_pair(6)
    dmap = compute_disparity(left, right, cost="features", feature_model=str(path), num_disparities=16,
                             subpixel=False, threads=1)
    inner = dmap.measured_disparity[5:-5, 20:-5]
    assert np.nanmedian(inner) == 6.0
    assert np.mean(inner == 6.0) > 0.9
    assert "features" in dmap.timings_ms


def test_l1_similarity_and_the_other_input_normalisations_work_too(tmp_path):
    path = str(build_conv_features(tmp_path / "conv.onnx", channels=8))
    left, right = _texture_pair(5, seed=3)
    for overrides in ({"feature_similarity": "l1"}, {"feature_input": "unit"}, {"feature_input": "raw"}):
        dmap = compute_disparity(left, right, cost="features", feature_model=path, num_disparities=16,
                                 subpixel=False, threads=1, **overrides)
        assert np.nanmedian(dmap.measured_disparity[5:-5, 20:-5]) == 5.0, overrides


# ------------------------------------------------------------------------------------------------ bad networks
def _one_line(exc: pytest.ExceptionInfo) -> str:
    text = str(exc.value)
    assert "\n" not in text and "`feature_model`" in text
    return text


@pytest.mark.parametrize("divisor", ["norm", "constant"])
def test_a_final_division_that_changes_no_direction_is_skipped_with_the_same_features(tmp_path, divisor):
    whole = learned.FeatureModel(build_conv_features(tmp_path / "conv.onnx", rank=4), threads=1)
    divided = learned.FeatureModel(build_divided_features(tmp_path / "div.onnx", divisor=divisor), threads=1)
    assert whole.skipped_division is None  # no division at its end
    assert divided.skipped_division == "conv"
    assert [o.name for o in divided.session.get_outputs()] == ["conv"]
    assert divided.channels == 8 and divided.margin == 1
    left, right = _texture_pair(4)
    for a, b in zip(whole.features(left, right), divided.features(left, right)):  # same weights, same unit vectors
        assert np.abs(a.astype(int) - b.astype(int)).max() <= 1  # float rounding at a tie, at most one step
        assert (a != b).mean() < 1e-3


def test_a_final_division_that_changes_directions_is_kept(tmp_path):
    model = learned.FeatureModel(build_divided_features(tmp_path / "div.onnx", divisor="per_channel"), threads=1)
    assert model.skipped_division is None
    assert [o.name for o in model.session.get_outputs()] == ["features"]


def test_without_final_division_keeps_the_numerator_and_what_it_needs_only(tmp_path):
    onnx = pytest.importorskip("onnx")
    data = build_divided_features(tmp_path / "div.onnx").read_bytes()
    cut, name = learned.without_final_division(data)
    model = onnx.load_from_string(cut)  # the output's rank is unknown (no shape), which ONNX Runtime takes
    assert name == "conv"
    assert [n.op_type for n in model.graph.node] == ["Conv"]
    assert [i.name for i in model.graph.initializer] == ["w"]
    assert [o.name for o in model.graph.output] == ["conv"]
    assert learned.without_final_division(build_conv_features(tmp_path / "c.onnx").read_bytes()) is None
    assert learned.without_final_division(b"") is None


@pytest.mark.parametrize("name", sorted(learned.SHIPPED_MODELS))
def test_the_shipped_networks_run_without_their_final_normalisation(name):
    assert learned.feature_model(name, "cpu", 1).skipped_division is not None


def test_a_file_that_is_not_onnx_is_refused_in_one_line(tmp_path):
    path = tmp_path / "notes.onnx"
    path.write_text("not a model")
    left, right = _texture_pair(3)
    with pytest.raises(FeatureModelError) as exc:
        compute_disparity(left, right, cost="features", feature_model=str(path), num_disparities=16)
    assert "is not a usable ONNX model" in _one_line(exc)


def test_a_missing_file_is_refused(tmp_path):
    with pytest.raises(FeatureModelError, match="no such file"):
        learned.FeatureModel(tmp_path / "absent.onnx")


def test_wrong_input_rank_is_refused(tmp_path):
    with pytest.raises(FeatureModelError) as exc:
        learned.FeatureModel(build_rank5_input(tmp_path / "rank5.onnx"))
    assert "rank 2 (H, W), 3 (1, H, W) or 4 (1, 1, H, W), got rank 5" in _one_line(exc)


def test_output_that_is_not_centred_features_is_refused(tmp_path):
    with pytest.raises(FeatureModelError) as exc:
        learned.FeatureModel(build_strided_features(tmp_path / "strided.onnx"))
    assert "the output must be float32 features (C, H - 2m, W - 2m)" in _one_line(exc)


def test_non_finite_features_are_refused(tmp_path):
    with pytest.raises(FeatureModelError) as exc:
        learned.FeatureModel(build_nan_features(tmp_path / "nan.onnx"))
    assert "not finite" in _one_line(exc)


def test_cuda_is_refused_where_onnxruntime_has_none(tmp_path):
    import onnxruntime as ort

    if "CUDAExecutionProvider" in ort.get_available_providers():
        pytest.skip("this onnxruntime has CUDA")
    path = build_conv_features(tmp_path / "conv.onnx")
    with pytest.raises(FeatureModelError, match="no CUDAExecutionProvider"):
        learned.FeatureModel(path, provider="cuda")
    assert learned.FeatureModel(path, provider="auto").providers == ("CPUExecutionProvider",)


# ------------------------------------------------------------------------------------------------ the shipped MC-CNN
@pytest.mark.parametrize("name", sorted(learned.SHIPPED_MODELS))
def test_shipped_models_are_in_the_package_with_their_sha256_and_licence(name):
    path = learned.shipped_model_path(name)
    assert hashlib.sha256(path.read_bytes()).hexdigest() == learned.SHIPPED_MODELS[name].sha256
    data = path.parent
    assert "Apache License" in (data / "LICENSE_mccnn_Apache-2.0.txt").read_text()
    assert learned.SHIPPED_MODELS[name].sha256 in (data / "PROVENANCE.md").read_text()
    model = learned.feature_model(name, "cpu", 1)
    assert (model.channels, model.margin) == (64, 5)


def test_mccnn_smoke_finds_the_shift_of_a_textured_pair():
    left, right = _texture_pair(9, h=60, w=120, seed=4)
    dmap = compute_disparity(left, right, cost="mccnn", num_disparities=32, subpixel=False, threads=2)
    assert dmap.params.effective_feature_model == "mccnn-fast-dw"
    inner = dmap.measured_disparity[6:-6, 40:-6]
    assert np.nanmedian(inner) == 9.0 and np.mean(inner == 9.0) > 0.9
    assert np.isfinite(dmap.filled_disparity).all() and set(dmap.timings_ms) >= {"features", "cost", "aggregate"}


# ------------------------------------------------------------------------------------------------ memory
def test_estimate_memory_counts_the_features_and_refuses_what_does_not_fit():
    shape = (375, 1242)
    classical = estimate_memory(shape, SGMParams(num_disparities=128, threads=2, cost="census"))
    mccnn = estimate_memory(shape, SGMParams(num_disparities=128, threads=2, cost="mccnn"))
    int8_features = 2 * 64 * shape[0] * shape[1]
    run = learned.onnx_feature_bytes(*shape, 64, 5)
    census_inputs = 2 * 8 * shape[0] * shape[1] + 2 * (shape[0] + 20) * (shape[1] + 20)  # codes + padded images
    assert mccnn - classical >= int8_features + run - census_inputs > 500e6  # ONNX Runtime's run dominates
    # the census term's codes (and the right row's quarters per worker) are counted, and only with it
    alone = estimate_memory(shape, SGMParams(num_disparities=128, threads=2, cost="mccnn", feature_census=0))
    assert mccnn - alone >= census_inputs
    left, right = _texture_pair(3)
    need = estimate_memory(left.shape, SGMParams(num_disparities=16, cost="mccnn"))
    with pytest.raises(MemoryBudgetError, match="GiB"):
        compute_disparity(left, right, cost="mccnn", num_disparities=16, memory_limit=need - 1)


# ------------------------------------------------------------------------------------------------ parameters
def test_learned_parameters_are_checked_and_have_their_penalties():
    params = SGMParams(cost="mccnn")
    assert (params.effective_p1, params.effective_p2) == (29, 304)
    assert params.learned and SGMParams().effective_feature_model is None
    # MC-CNN's P1 / 1.5 on the paths that cross rows; no border-reach rule (the outside candidates are neutral)
    assert (params.effective_p1_vertical, params.effective_border_reach) == (19, 0.0)
    assert (SGMParams().effective_p1_vertical, SGMParams().effective_border_reach) == (28, 0.5)  # classical: as was
    assert params.replace(p1_vertical=25, border_reach=0.3).effective_p1_vertical == 25
    assert params.replace(p1=60, p2=330).effective_p1_vertical == 40
    assert params.replace(border_reach=0.3).effective_border_reach == 0.3
    with pytest.raises(ValueError, match="`border_reach` must be None"):
        SGMParams(border_reach=1.5)
    with pytest.raises(ValueError, match="`feature_model` must be an ONNX feature network for cost 'features'"):
        SGMParams(cost="features")
    with pytest.raises(ValueError, match="`feature_similarity` must be one of"):
        SGMParams(cost="mccnn", feature_similarity="cosine")
    with pytest.raises(ValueError, match="`onnx_provider` must be one of"):
        SGMParams(cost="mccnn", onnx_provider="tpu")
    with pytest.raises(ValueError, match="`p2` too large"):
        SGMParams(cost="mccnn", p2=2000)
    # the census cost's share: 0.5 for the shipped network, none for a given one or a classical cost
    assert (params.effective_feature_census, SGMParams().effective_feature_census) == (0.5, 0.0)
    assert SGMParams(cost="features", feature_model="net.onnx").effective_feature_census == 0.0
    assert SGMParams(cost="features", feature_model="net.onnx", feature_census=0.25).effective_feature_census == 0.25
    assert params.replace(feature_census=0).effective_feature_census == 0.0
    for bad in (-0.1, 1.5, "half", True):
        with pytest.raises(ValueError, match="`feature_census` must be None"):
            SGMParams(cost="mccnn", feature_census=bad)


# feature_census -> family -> the learned cost's dense bad-2 %, measured (docs/matching.md, "Learned costs"). The
# network alone (0): 6.74 / 9.38 before the neutral cost outside the right image, so a margin of 0.3 fails when it is
# undone; the default (None: census in equal parts) 5.81 / 7.79, 0.5 and 1.2 points apart from the network alone.
LEARNED_MEASURED = {None: {"Middlebury-style": 5.81, "driving": 7.79},
                    0.0: {"Middlebury-style": 6.34, "driving": 8.97}}


@pytest.mark.parametrize("census", [None, 0.0])
def test_learned_default_on_the_real_families(shared_data, census):
    import stereo_classic as sc
    from benchmarks.metrics import error_metrics
    from benchmarks.scenes import disparity_range, load_scenes

    measured = LEARNED_MEASURED[census]
    scenes = [s for s in load_scenes(shared_data) if s.gt_disparity is not None and s.family in measured]
    if {s.family for s in scenes} != set(measured):
        pytest.skip(f"the Middlebury-style scenes and driving frames are not all in {shared_data}")
    dense: dict[str, list[float]] = {}
    for scene in scenes:
        params = sc.SGMParams(cost="mccnn", num_disparities=disparity_range(scene), block_size=5, threads=2,
                              feature_census=census)
        dmap = sc.compute_disparity(scene.left, scene.right, params)
        bad2 = error_metrics(dmap.filled_disparity, scene.gt_disparity)["dense"]["bad2"]
        dense.setdefault(scene.family, []).append(bad2)
    for family, want in measured.items():
        assert np.mean(dense[family]) == pytest.approx(want, abs=0.3), family
