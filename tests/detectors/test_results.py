"""Detections: construction checks, filtering, export."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from detectors import COCO_CATEGORY_IDS, COCO_CLASSES, Detections


def _dets() -> Detections:
    return Detections(
        np.array([[10, 20, 50, 80], [0, 0, 5, 5], [100.5, 200.25, 300.75, 400]], np.float64),
        np.array([0.9, 0.2, 0.55]),
        np.array([2, 0, 79]),
    )


class TestConstruction:
    def test_smoke_dtypes_and_copy(self):
        xyxy = np.array([[1, 2, 3, 4]], np.int32)
        d = Detections(xyxy, [0.5], [3])
        assert d.xyxy.dtype == np.float32 and d.confidence.dtype == np.float32 and d.class_id.dtype == np.int64
        assert d.xyxy.shape == (1, 4) and len(d) == 1
        xyxy[0, 0] = 99
        assert d.xyxy[0, 0] == 1  # copied
        with pytest.raises(ValueError):
            d.xyxy[0, 0] = 5  # read-only
        assert d.class_names == COCO_CLASSES

    def test_empty(self):
        e = Detections.empty()
        assert len(e) == 0 and e.xyxy.shape == (0, 4) and e.labels == [] and e.to_json() == []
        assert Detections.empty(("a", "b")).class_names == ("a", "b")
        assert len(Detections([], [], [])) == 0

    @pytest.mark.parametrize(
        ("kwargs", "match"),
        [
            ({"xyxy": np.zeros((2, 3))}, r"`xyxy` must have shape \(N, 4\)"),
            ({"xyxy": np.zeros(4)}, r"`xyxy` must have shape \(N, 4\)"),
            ({"confidence": np.ones(3)}, r"`confidence` must have shape \(2,\)"),
            ({"class_id": np.zeros((2, 1), int)}, r"`class_id` must have shape \(2,\)"),
            ({"class_id": np.array([0.0, 1.0])}, r"`class_id` must be an integer array"),
            ({"xyxy": np.array([[0, 0, 1, 1], [0, 0, np.nan, 1]])}, r"`xyxy` must be finite"),
            ({"xyxy": np.array([[0, 0, 1, 1], [0, 0, np.inf, 1]])}, r"`xyxy` must be finite"),
            ({"xyxy": np.array([[0, 0, 1, 1], [0, 0, 1e300, 1]])}, r"`xyxy` must be finite"),
            ({"xyxy": np.array([[0, 0, 1, 1], [5, 0, 1, 1]])}, r"x1 <= x2 and y1 <= y2, got row 1"),
            ({"xyxy": np.array([[0, 3, 1, 1], [0, 0, 1, 1]])}, r"x1 <= x2 and y1 <= y2, got row 0"),
            ({"confidence": np.array([0.5, 1.5])}, r"`confidence` must lie in \[0, 1\], got 1.5"),
            ({"confidence": np.array([0.5, np.nan])}, r"`confidence` must lie in \[0, 1\]"),
            ({"confidence": np.array([-0.1, 0.5])}, r"`confidence` must lie in \[0, 1\]"),
            ({"class_id": np.array([0, 80])}, r"`class_id` must lie in \[0, 79\].*got 80"),
            ({"class_id": np.array([-1, 0])}, r"`class_id` must lie in \[0, 79\].*got -1"),
            ({"class_names": ()}, r"`class_names` must hold at least one"),
            ({"class_names": ("a", 3)}, r"`class_names`\[1\] must be a non-empty string"),
            ({"class_names": "person"}, r"`class_names` must be a sequence"),
            ({"xyxy": [[0, 0, 1, 1], [0, 0, 1]]}, r"`xyxy` must be array-like"),
            ({"xyxy": np.array([["a", "b", "c", "d"]] * 2)}, r"`xyxy` must be a real-valued array"),
        ],
    )
    def test_errors_name_the_parameter(self, kwargs, match):
        args = {"xyxy": np.array([[0, 0, 1, 1], [2, 2, 3, 3]], np.float32), "confidence": np.array([0.5, 0.6]),
                "class_id": np.array([0, 1]), "class_names": COCO_CLASSES}
        args.update(kwargs)
        with pytest.raises(ValueError, match=match):
            Detections(**args)

    def test_frozen(self):
        d = _dets()
        with pytest.raises(AttributeError):
            d.xyxy = np.zeros((0, 4))  # type: ignore[misc]


class TestFiltering:
    def test_mask(self):
        d = _dets()
        hi = d[d.confidence > 0.5]
        assert hi.labels == ["car", "toothbrush"]
        np.testing.assert_array_equal(hi.xyxy, np.array([[10, 20, 50, 80], [100.5, 200.25, 300.75, 400]], np.float32))
        assert len(d[np.zeros(3, bool)]) == 0

    def test_index_slice_int(self):
        d = _dets()
        assert d[[2, 0]].labels == ["toothbrush", "car"]
        assert d[1:].labels == ["person", "toothbrush"]
        assert d[-1].labels == ["toothbrush"] and len(d[0]) == 1
        assert len(d[np.array([], int)]) == 0

    def test_index_errors(self):
        d = _dets()
        with pytest.raises(IndexError, match="boolean mask must have shape"):
            d[np.ones(2, bool)]
        with pytest.raises(IndexError, match="out of range"):
            d[3]
        with pytest.raises(IndexError, match="index must be"):
            d[np.array([0.5])]

    def test_only(self):
        d = _dets()
        assert d.only("car").labels == ["car"]
        assert d.only("person", "toothbrush").labels == ["person", "toothbrush"]
        assert len(d.only("dog")) == 0
        with pytest.raises(ValueError, match=r"unknown class name 'cars'; valid names: person, bicycle, car"):
            d.only("cars")
        with pytest.raises(ValueError, match="at least one class name"):
            d.only()

    def test_labels_custom_names(self):
        d = Detections([[0, 0, 1, 1]], [0.5], [1], ("cone", "buoy"))
        assert d.labels == ["buoy"] and d.only("buoy").labels == ["buoy"]


class TestExport:
    def test_to_coco_ids_and_xywh(self):
        out = _dets().to_coco(image_id=7)
        assert [o["category_id"] for o in out] == [3, 1, 90]  # car -> 3, person -> 1, toothbrush -> 90
        assert out[0]["bbox"] == [10.0, 20.0, 40.0, 60.0] and out[0]["image_id"] == 7
        assert out[2]["bbox"] == [100.5, 200.25, 200.25, 199.75]
        assert abs(out[0]["score"] - 0.9) < 1e-6
        for o in out:
            assert all(type(v) is float for v in o["bbox"]) and type(o["score"]) is float
        assert json.loads(json.dumps(out)) == out

    def test_coco_mapping_table(self):
        assert len(COCO_CATEGORY_IDS) == 80 and len(set(COCO_CATEGORY_IDS)) == 80
        assert COCO_CATEGORY_IDS[COCO_CLASSES.index("dining table")] == 67
        assert COCO_CATEGORY_IDS[COCO_CLASSES.index("tv")] == 72
        assert COCO_CATEGORY_IDS[COCO_CLASSES.index("book")] == 84
        assert sorted(COCO_CATEGORY_IDS) == list(COCO_CATEGORY_IDS)

    def test_to_coco_custom_names_and_errors(self):
        d = Detections([[0, 0, 1, 1]], [0.5], [1], ("cone", "buoy"))
        assert d.to_coco(0)[0]["category_id"] == 2
        with pytest.raises(ValueError, match="`image_id` must be an int"):
            d.to_coco("a")  # type: ignore[arg-type]

    def test_to_json_real_numbers(self):
        out = _dets().to_json()
        assert json.loads(json.dumps(out)) == out
        assert out[0]["class_name"] == "car" and out[0]["class_id"] == 2
        assert out[2]["xyxy"] == [100.5, 200.25, 300.75, 400.0]
        assert all(type(v) is float for v in out[0]["xyxy"]) and type(out[0]["confidence"]) is float
        assert type(out[0]["class_id"]) is int


_floats = st.floats(allow_nan=True, allow_infinity=True, width=64)


@settings(max_examples=360, deadline=None)
@given(
    n=st.integers(0, 6),
    data=st.data(),
)
def test_property_construction_valid_or_named_error(n, data):
    xyxy = data.draw(hnp.arrays(np.float64, (n, 4), elements=_floats))
    conf = data.draw(hnp.arrays(np.float64, (n,), elements=_floats))
    cid = data.draw(hnp.arrays(np.int64, (n,), elements=st.integers(-2, 82)))
    try:
        d = Detections(xyxy, conf, cid)
    except ValueError as exc:
        assert any(p in str(exc) for p in ("`xyxy`", "`confidence`", "`class_id`"))
        return
    assert len(d) == n
    assert np.all(np.isfinite(d.xyxy)) and np.all(d.xyxy[:, 2] >= d.xyxy[:, 0]) and np.all(d.xyxy[:, 3] >= d.xyxy[:, 1])
    assert np.all((d.confidence >= 0) & (d.confidence <= 1)) and np.all((d.class_id >= 0) & (d.class_id < 80))
    assert len(d[d.confidence > 0.5]) == int(np.sum(d.confidence > 0.5))
    assert len(json.loads(json.dumps(d.to_coco(1)))) == n
