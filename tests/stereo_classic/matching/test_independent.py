"""The left-right check against the right image's own match (``SGMParams.lr_mode="independent"``,
``stereo_classic.matching.border.independent_check``)."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_classic.matching import LR_MODES, SGMParams, compute_disparity, estimate_memory
from stereo_classic.matching.border import independent_check, mirrored_params
from stereo_classic.matching.postprocess import median_measured


def _occluding_pair(h: int = 48, w: int = 160, seed: int = 0):
    """A textured background at d = 4 and a textured square in front of it at d = 14 (columns 60-99 of the left
    image): the 10 columns left of the square in the left image (50-59) show background the right camera does not
    see. Returns (left, right, true disparity of the left image)."""
    rng = np.random.default_rng(seed)

    def texture(shape):  # 2 px blobs, so that the census windows see structure and not noise alone
        t = rng.integers(0, 256, ((shape[0] + 1) // 2, (shape[1] + 1) // 2), dtype=np.uint8)
        return np.repeat(np.repeat(t, 2, 0), 2, 1)[: shape[0], : shape[1]]

    back = texture((h, w + 32))
    front = texture((h, 40))
    left = back[:, 4:4 + w].copy()  # left pixel x sees the background's x + 4, the right pixel x its x + 8 ...
    right = back[:, 8:8 + w].copy()  # ... so the background's d = x_left - x_right = 4
    left[8:40, 60:100] = front[8:40]
    right[8:40, 46:86] = front[8:40]  # the square at d = 14
    truth = np.full((h, w), 4.0, np.float32)
    truth[8:40, 60:100] = 14.0
    return np.ascontiguousarray(left), np.ascontiguousarray(right), truth


def test_the_mode_is_one_of_the_lr_modes_and_sets_the_border_rule():
    assert "independent" in LR_MODES
    p = SGMParams(lr_mode="Independent")
    assert p.lr_mode == "independent" and p.effective_border_reach == 0.0 and p.independent_lr
    assert not SGMParams(lr_mode="independent", lr_check=None).independent_lr and not SGMParams().independent_lr
    assert SGMParams(lr_mode="independent", border_reach=0.5).effective_border_reach == 0.5  # as given
    assert SGMParams(lr_mode="independent", lr_check=None).effective_border_reach == 0.5  # no check: the default
    assert SGMParams().effective_border_reach == 0.5
    with pytest.raises(ValueError, match="lr_mode.*independent"):
        SGMParams(lr_mode="mirrored")


def test_without_a_check_the_mode_does_nothing():
    """``lr_check=None`` turns every check off, this one too: the same map as the other modes without a check."""
    left, right, _ = _occluding_pair()
    plain = compute_disparity(left, right, num_disparities=32, lr_check=None, threads=1)
    indep = compute_disparity(left, right, num_disparities=32, lr_check=None, lr_mode="independent", threads=1)
    np.testing.assert_array_equal(plain.filled_disparity, indep.filled_disparity)
    assert "independent_check" not in indep.timings_ms


def test_mirrored_params_leave_every_winner_a_measurement():
    p = mirrored_params(SGMParams(lr_mode="independent", median_filter=True, border_check=True, right_view=True))
    assert p.lr_check is None and p.lr_mode == "full" and p.border_reach == 0.0 and p.speckle_size == 0
    assert not (p.fill_holes or p.median_filter or p.border_check or p.right_view)


def test_the_check_is_the_mirrored_match_after_both_medians():
    """Without speckle filter and fill, the measured map is the left winners (no check of the kernels) after the 3x3
    median, NaN where the right image's own match (mirrored pair, its 3x3 median) at x - rint(d) disagrees by more
    than lr_check: bit for bit the numpy composition."""
    left, right, _ = _occluding_pair()
    params = SGMParams(num_disparities=32, lr_mode="independent", speckle_size=0, fill_holes=False, threads=1,
                       right_view=True)
    got = compute_disparity(left, right, params)

    winners = compute_disparity(left, right, params.replace(lr_check=None, lr_mode="full", border_reach=0.0,
                                                           right_view=False)).disparity
    mirrored = compute_disparity(right[:, ::-1].copy(), left[:, ::-1].copy(), mirrored_params(params)).disparity
    right_view = median_measured(np.ascontiguousarray(mirrored[:, ::-1]))
    expected = median_measured(winners)
    H, W = expected.shape
    failed = 0
    for y in range(H):
        for x in range(W):
            d = expected[y, x]
            if np.isnan(d):
                continue
            xr = int(np.rint(float(x) - float(d)))  # in float64, half to even
            if not (0 <= xr < W and abs(right_view[y, xr] - d) <= params.lr_check):  # NaN compares False
                expected[y, x] = np.nan
                failed += 1
    np.testing.assert_array_equal(got.disparity, expected)
    np.testing.assert_array_equal(got.disparity_right, right_view)
    assert got.validity["failed_lr"] == failed > 0
    assert got.timings_ms["independent_check"] > 0


def test_the_pixels_only_the_left_camera_sees_are_removed_and_the_border_is_measured():
    """The background band left of the square (columns 50-59 of its rows) has no match in the right image: the check
    removes it (2 % of it left; the kernels' own check: 6 %). The left border, which ``border_reach`` leaves unknown
    with the own check, is checked like any other place: measured where its match is inside the right image (87 % of
    the first 32 columns against 53 %), and overall more pixels are measured and fewer are wrong."""
    left, right, truth = _occluding_pair()
    params = SGMParams(num_disparities=32, subpixel=False, threads=1, speckle_size=0, fill_holes=False)
    own = compute_disparity(left, right, params).disparity
    indep = compute_disparity(left, right, params, lr_mode="independent").disparity
    assert np.isfinite(indep[10:38, 50:60]).mean() < 0.05
    assert np.isfinite(indep[:, :32]).mean() > 0.8 > 0.6 > np.isfinite(own[:, :32]).mean()

    def wrong(d):
        ok = np.isfinite(d)
        return np.mean(np.abs(d[ok] - truth[ok]) > 1)

    assert np.isfinite(indep).mean() > np.isfinite(own).mean() + 0.05 and wrong(indep) <= wrong(own) < 0.01


def test_any_thread_count_gives_the_same_map():
    left, right, _ = _occluding_pair(w=200)
    a = compute_disparity(left, right, num_disparities=32, lr_mode="independent", threads=1)
    b = compute_disparity(left, right, num_disparities=32, lr_mode="independent", threads=2)
    np.testing.assert_array_equal(a.filled_disparity, b.filled_disparity)
    np.testing.assert_array_equal(a.filled, b.filled)


def test_a_matcher_keeps_the_mirrored_match_buffers_and_repeats_itself():
    from stereo_classic.matching import StereoMatcher

    left, right, _ = _occluding_pair()
    matcher = StereoMatcher(SGMParams(num_disparities=32, lr_mode="independent", threads=2))
    a = matcher.compute(left, right)
    mirror = matcher._workspace.mirror
    assert mirror is not None and mirror.nbytes > 0 and matcher._workspace.nbytes > mirror.nbytes
    b = matcher.compute(left, right)
    assert matcher._workspace.mirror is mirror
    np.testing.assert_array_equal(a.filled_disparity, b.filled_disparity)
    np.testing.assert_array_equal(a.disparity, compute_disparity(left, right, matcher.params).disparity)


def test_the_check_rounds_the_match_half_to_even_in_float64():
    """A pixel whose match x - d falls exactly half-way between two right pixels is compared with the even one."""
    from stereo_classic.matching.border import _reject_disagreeing

    d = np.full((1, 8), np.nan, np.float32)
    d[0, 5] = 2.5  # x - d = 2.5 -> right pixel 2
    d[0, 6] = 2.5  # 3.5 -> 4
    right_view = np.array([[0, 0, 2.5, 9, 9, 0, 0, 0]], np.float32)
    xs = np.array([5, 6])  # the finite pixels, and numpy's reading of the rule: int64 - float32 in float64, rint
    xr = np.rint(xs - d[0, xs]).astype(np.int64)
    agree = np.abs(right_view[0, xr] - d[0, xs]) <= 1.0
    checked = d.copy()
    assert _reject_disagreeing(checked, right_view, 1.0) == 1 == int((~agree).sum())
    assert checked[0, 5] == 2.5 and np.isnan(checked[0, 6])


def test_validity_adds_up_and_the_right_view_is_only_returned_when_asked():
    left, right, _ = _occluding_pair()
    d = compute_disparity(left, right, num_disparities=32, lr_mode="independent", threads=1)
    v = d.validity
    assert v["unknown_matcher"] + v["short_range"] + v["speckle_removed"] + v["valid"] - v["filled"] == left.size
    assert v["failed_lr"] <= v["unknown_matcher"] and v["short_range"] == 0
    assert d.disparity_right is None


def test_independent_check_calls_the_matcher_once_on_the_mirrored_pair():
    left, right, _ = _occluding_pair()
    params = SGMParams(num_disparities=32, lr_mode="independent", threads=1)
    seen = []

    def match(a, b, p):
        seen.append((a.copy(), b.copy(), p))
        return compute_disparity(a, b, p)

    winners = compute_disparity(left, right, mirrored_params(params)).disparity
    checked, right_view, failed = independent_check(left, right, winners, params, match)
    (a, b, p), = seen
    np.testing.assert_array_equal(a, right[:, ::-1])
    np.testing.assert_array_equal(b, left[:, ::-1])
    assert p == mirrored_params(params)
    assert checked.shape == right_view.shape == left.shape and checked.dtype == np.float32
    assert failed == int(np.isfinite(winners).sum() - np.isfinite(checked).sum()) > 0


def test_memory_counts_the_second_match():
    params = SGMParams(num_disparities=64)
    indep = params.replace(lr_mode="independent")
    second = estimate_memory((480, 640), mirrored_params(indep))  # the mirrored pair's match
    assert estimate_memory((480, 640), indep) > estimate_memory((480, 640), params) + second
    assert estimate_memory((480, 640), params.replace(lr_mode="independent", lr_check=None)) == estimate_memory(
        (480, 640), params.replace(lr_check=None))


@pytest.mark.parametrize("name", ["Adirondack"])
def test_real_scene_is_more_often_right(shared_data, name):
    """Adirondack, where the default lost most to Pandora (docs/matching.md): dense bad-2 7.55 -> 5.82 % with the
    independent check (at the benchmark's range and block size)."""
    from benchmarks.metrics import error_metrics
    from benchmarks.scenes import disparity_range, load_scenes

    scenes = [s for s in load_scenes(shared_data) if s.name == name and s.gt_disparity is not None]
    if not scenes:
        pytest.skip(f"{name} is not in {shared_data}")
    scene = scenes[0]
    params = SGMParams(num_disparities=disparity_range(scene), block_size=5, threads=2)

    def bad2(p):
        out = compute_disparity(scene.left, scene.right, p).filled_disparity
        return error_metrics(out, scene.gt_disparity)["dense"]["bad2"]

    assert bad2(params.replace(lr_mode="independent")) < bad2(params) - 1.0
