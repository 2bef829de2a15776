"""stereo_classic.outputs.visualize: colorize and draw_boxes."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from stereo_classic.outputs.visualize import PALETTE, colorize, draw_boxes


def _turbo(index: int) -> list[int]:
    return cv2.applyColorMap(np.array([[index]], np.uint8), cv2.COLORMAP_TURBO)[0, 0].tolist()


def test_colorize_ramp_ends_and_invalid() -> None:
    v = np.array([[0.0, 5.0, 10.0, np.nan, np.inf, -np.inf]], np.float32)
    out = colorize(v, vmin=0, vmax=10)
    assert out.shape == (1, 6, 3) and out.dtype == np.uint8
    assert out[0, 0].tolist() == _turbo(0) and out[0, 2].tolist() == _turbo(255)
    assert out[0, 1].tolist() in (_turbo(127), _turbo(128))
    assert out[0, 3:].tolist() == [[0, 0, 0]] * 3
    out = colorize(v, vmin=0, vmax=10, invalid_color=(255, 0, 255))
    assert out[0, 3].tolist() == [255, 0, 255]


def test_colorize_clips_outside_limits() -> None:
    out = colorize(np.array([[-5.0, 50.0]]), vmin=0, vmax=10)
    assert out[0, 0].tolist() == _turbo(0) and out[0, 1].tolist() == _turbo(255)


def test_colorize_robust_percentiles_ignore_outliers() -> None:
    rng = np.random.default_rng(0)
    v = rng.uniform(10, 20, (100, 100))
    v[0, 0] = 1e6  # a single wild value must not wash out the picture
    out = colorize(v)
    colours = {tuple(c) for c in out.reshape(-1, 3)[1:]}
    assert len(colours) > 100  # the ramp is used, not one colour
    same = colorize(v, vmin=float(np.percentile(v, 1)), vmax=float(np.percentile(v, 99)))
    np.testing.assert_array_equal(out, same)


def test_colorize_constant_and_all_invalid() -> None:
    out = colorize(np.full((3, 4), 7.0))
    assert (out == out[0, 0]).all() and out[0, 0].tolist() == _turbo(128)
    assert (colorize(np.full((2, 2), np.nan)) == 0).all()
    assert colorize(np.arange(6, dtype=np.uint16).reshape(2, 3)).shape == (2, 3, 3)


@pytest.mark.parametrize(
    ("values", "kwargs", "exc", "match"),
    [
        (np.zeros((2, 2, 2)), {}, ValueError, "values"),
        (np.zeros((0, 3)), {}, ValueError, "values"),
        (np.zeros((2, 2), bool), {}, ValueError, "dtype"),
        ([[1.0]], {}, TypeError, "values"),
        (np.zeros((2, 2)), {"vmin": 2, "vmax": 1}, ValueError, "vmin"),
        (np.zeros((2, 2)), {"vmin": float("nan")}, ValueError, "vmin"),
        (np.zeros((2, 2)), {"vmax": "1"}, TypeError, "vmax"),
        (np.zeros((2, 2)), {"invalid_color": (0, 0)}, ValueError, "invalid_color"),
        (np.zeros((2, 2)), {"invalid_color": (0, 0, 300)}, ValueError, "invalid_color"),
    ],
)
def test_colorize_errors(values: object, kwargs: dict, exc: type, match: str) -> None:
    with pytest.raises(exc, match=match):
        colorize(values, **kwargs)  # type: ignore[arg-type]


@settings(max_examples=180, deadline=None)
@given(
    v=hnp.arrays(
        st.sampled_from([np.float32, np.float64, np.int16]),
        st.tuples(st.integers(1, 12), st.integers(1, 12)),
    ),
    lo=st.one_of(st.none(), st.floats(-1e6, 1e6)),
    hi=st.one_of(st.none(), st.floats(-1e6, 1e6)),
)
def test_colorize_property(v: np.ndarray, lo: float | None, hi: float | None) -> None:
    if lo is not None and hi is not None and lo > hi:
        with pytest.raises(ValueError, match="vmin"):
            colorize(v, vmin=lo, vmax=hi)
        return
    out = colorize(v, vmin=lo, vmax=hi)
    assert out.shape == v.shape + (3,) and out.dtype == np.uint8
    bad = ~np.isfinite(v.astype(np.float64))
    assert (out[bad] == 0).all()


def test_draw_boxes_draws_on_a_copy_with_label_background() -> None:
    img = np.full((120, 200, 3), 255, np.uint8)
    out = draw_boxes(img, [[40, 50, 120, 110]], ["car 12.4 m"], colors=(0, 0, 255))
    assert (img == 255).all()  # input untouched
    assert out.shape == img.shape and out.dtype == np.uint8
    assert out[80, 40].tolist() == [0, 0, 255]  # left edge of the box
    label_area = out[30:48, 42:100]
    red = np.all(label_area == [0, 0, 255], axis=-1).mean()
    white_text = np.all(label_area > 200, axis=-1).mean()
    assert red > 0.5 and white_text > 0.02  # filled background, readable white text on red
    assert (out[60:100, 60:100] == 255).all()  # inside of the box is left alone


def test_draw_boxes_label_inside_when_no_room_and_grey_input() -> None:
    grey = np.zeros((60, 80), np.uint8)
    out = draw_boxes(grey, np.array([[0, 0, 79, 59]], np.float32), ["person 2.4 m"], colors=[(0, 255, 255)])
    assert out.shape == (60, 80, 3)
    assert np.all(out[2:12, 5:40] == [0, 255, 255], axis=-1).mean() > 0.3  # label drawn inside at the top
    assert np.all(out[2:12, 5:40] < 60, axis=-1).any()  # dark text on the bright yellow background


def test_draw_boxes_defaults_and_clipping() -> None:
    img = np.zeros((50, 50, 3), np.uint8)
    out = draw_boxes(img, [[-10, -10, 100, 100], [5, 5, 20, 20]])
    assert out[25, 0].tolist() == list(PALETTE[0])
    assert out[12, 5].tolist() == list(PALETTE[1])
    np.testing.assert_array_equal(draw_boxes(img, np.zeros((0, 4))), img)


@pytest.mark.parametrize(
    ("image", "boxes", "labels", "kwargs", "exc", "match"),
    [
        (np.zeros((5, 5, 3), np.float32), [[0, 0, 1, 1]], None, {}, ValueError, "uint8"),
        (np.zeros((5, 5, 4), np.uint8), [[0, 0, 1, 1]], None, {}, ValueError, "shape"),
        ("img", [[0, 0, 1, 1]], None, {}, TypeError, "image"),
        (np.zeros((5, 5, 3), np.uint8), [[0, 0, 1]], None, {}, ValueError, "xyxy"),
        (np.zeros((5, 5, 3), np.uint8), [[0, 0, np.nan, 1]], None, {}, ValueError, "finite"),
        (np.zeros((5, 5, 3), np.uint8), [[3, 0, 1, 1]], None, {}, ValueError, "x1 <= x2"),
        (np.zeros((5, 5, 3), np.uint8), [[0, 0, 1, 1]], ["a", "b"], {}, ValueError, "labels"),
        (np.zeros((5, 5, 3), np.uint8), [[0, 0, 1, 1]], "car", {}, TypeError, "labels"),
        (np.zeros((5, 5, 3), np.uint8), [[0, 0, 1, 1]], None, {"colors": [(1, 2, 3), (4, 5, 6)]}, ValueError, "colors"),
        (np.zeros((5, 5, 3), np.uint8), [[0, 0, 1, 1]], None, {"colors": (1, 2, 999)}, ValueError, "colors"),
        (np.zeros((5, 5, 3), np.uint8), [[0, 0, 1, 1]], None, {"thickness": 0}, ValueError, "thickness"),
        (np.zeros((5, 5, 3), np.uint8), [[0, 0, 1, 1]], None, {"font_scale": -1}, ValueError, "font_scale"),
        (np.zeros((5, 5, 3), np.uint8), [[0, 0, 1, 1]], None, {"thickness": 10**6}, ValueError, r"`thickness` must be an int in \[1, 64\]"),
        (np.zeros((5, 5, 3), np.uint8), [[0, 0, 1, 1]], None, {"thickness": 2.5}, ValueError, "`thickness` must be an int"),
        (np.zeros((5, 5, 3), np.uint8), [[0, 0, 1, 1]], None, {"thickness": True}, ValueError, "`thickness` must be an int"),
        (np.zeros((5, 5, 3), np.uint8), [[0, 0, 1, 1]], ["a"], {"font_scale": 1e9}, ValueError, "`font_scale` must be a positive finite"),
        (np.zeros((5, 5, 3), np.uint8), [[0, 0, 1, 1]], ["a"], {"font_scale": float("inf")}, ValueError, "`font_scale` must be a positive finite"),
        (np.zeros((5, 5, 3), np.uint8), [[0, 0, 1, 1]], ["a"], {"font_scale": "1"}, ValueError, "`font_scale` must be a positive finite"),
    ],
)
def test_draw_boxes_errors(image, boxes, labels, kwargs, exc, match) -> None:  # noqa: ANN001
    with pytest.raises(exc, match=match):
        draw_boxes(image, boxes, labels, **kwargs)


def _label_rects(boxes, labels, size):
    from stereo_classic.outputs.visualize import place_labels
    w, h = size
    scale, thick = max(0.4, min(h, w) / 800.0), 1
    sizes = []
    for t in labels:
        (tw, th), base = cv2.getTextSize(t, cv2.FONT_HERSHEY_SIMPLEX, scale, thick)
        sizes.append((tw + 4, th + base + 4))
    return [(x, y, lw, lh) for (x, y), (lw, lh) in zip(place_labels(boxes, sizes, (w, h)), sizes)]


@pytest.mark.parametrize("boxes", [
    [(100, 100, 300, 250)] * 4,                                  # the same box four times
    [(100, 100, 300, 250), (110, 105, 290, 240), (120, 0, 200, 90)],  # nested, and one at the top edge
    [(5, 5, 60, 60), (10, 8, 70, 70), (15, 12, 80, 80), (20, 2, 90, 50), (0, 0, 639, 479)],
])
def test_labels_never_cover_each_other(boxes) -> None:
    labels = [f"object {i} {2.0 + i:.1f} m" for i in range(len(boxes))]
    rects = _label_rects(boxes, labels, (640, 480))
    for i, a in enumerate(rects):
        assert 0 <= a[0] and a[0] + a[2] <= 640 and 0 <= a[1] and a[1] + a[3] <= 480
        for b in rects[i + 1:]:
            assert not (a[0] < b[0] + b[2] and b[0] < a[0] + a[2] and a[1] < b[1] + b[3] and b[1] < a[1] + a[3]), (a, b)


def test_overlapping_boxes_show_every_label() -> None:
    boxes = [(100, 100, 300, 250)] * 3
    colors = [(0, 0, 255), (0, 255, 0), (255, 0, 0)]
    out = draw_boxes(np.zeros((480, 640, 3), np.uint8), boxes, ["a 1.0 m", "b 2.0 m", "c 3.0 m"], colors=colors)
    for (x, y, lw, lh), color in zip(_label_rects(boxes, ["a 1.0 m", "b 2.0 m", "c 3.0 m"], (640, 480)), colors):
        patch = out[y:y + lh, x:x + lw].reshape(-1, 3)
        assert (patch == color).all(axis=1).mean() > 0.5  # each label's own background is visible
