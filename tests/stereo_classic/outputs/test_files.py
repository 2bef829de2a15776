"""stereo_classic.outputs.files: what `run` writes, used as a library."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from stereo_classic import io
from stereo_classic.fusion import FusionParams
from stereo_classic.outputs import (
    DEFAULT_SAVE,
    JSONL_NAME,
    SAVE_KINDS,
    FrameWriter,
    JsonlSink,
    box_labels,
    frame_record,
    write_all_or_nothing,
)
from stereo_classic.pipeline import Localizer
from tests.helpers.detectors import FixedBoxes
from tests.helpers.scenes import make_rig, planted_scene


@pytest.fixture(scope="module")
def frame():
    rig = make_rig(240, 160)
    left, right, _, _ = planted_scene(rig=rig, z_box=3.0, z_wall=8.0, box=(80, 50, 160, 110))
    detector = FixedBoxes([(80, 50, 160, 110)], names=("box",), confidence=0.9)
    with Localizer(rig, detector, {"num_disparities": 48}) as loc:
        result = loc(left, right)
    return rig, result


def test_writer_writes_every_kind_and_the_record_names_the_settings(tmp_path, frame):
    rig, result = frame
    fusion = FusionParams(box_shrink=0.25)
    record = frame_record("f", 0, result, rig, detector="stub", fusion=fusion, seed=3)
    assert record["settings"]["box_shrink"] == 0.25 and record["settings"]["seed"] == 3
    assert record["settings"]["depth_range"] == [0.3, 80.0]
    assert "threads" not in record["settings"]["matcher"] and "max_samples" not in record["settings"]
    writer = FrameWriter(tmp_path, save=tuple(SAVE_KINDS), depth_range=fusion.depth_range)
    written = writer.write("f", result, rig, record)
    assert sorted(p.name for p in written) == sorted(SAVE_KINDS[k].format(name="f") for k in SAVE_KINDS)
    assert sorted(written) == sorted(writer.expected_files("f"))
    np.testing.assert_array_equal(io.read_pfm(tmp_path / "f_disparity.pfm"), result.disparity.disparity)
    saved = json.loads((tmp_path / "f_objects.json").read_text())
    assert saved == json.loads(json.dumps(record))
    assert saved["objects"][0]["distance_m"] == pytest.approx(3.0, rel=0.02)
    assert io.read_ply(tmp_path / "f_points.ply").points.shape[1] == 3


def test_disparity_files_hold_measured_pixels_only_and_the_filled_map_only_when_asked(tmp_path, frame):
    """Issue 31: the PFM and the KITTI PNG read back have no value where the map has none (NaN / 0 there, the
    filled pixels included); ``NAME_disparity_filled.pfm`` is written only when ``dense`` is named."""
    rig, result = frame
    dmap = result.disparity
    assert dmap.filled is not None and dmap.filled.any()  # the case: the matcher filled holes
    FrameWriter(tmp_path).write("f", result, rig, {"frame": "f"})
    assert not (tmp_path / "f_disparity_filled.pfm").exists()
    unknown = ~np.isfinite(dmap.disparity)
    assert unknown[dmap.filled].all()
    pfm = io.read_pfm(tmp_path / "f_disparity.pfm")
    assert np.isnan(pfm[unknown]).all() and np.isfinite(pfm[~unknown]).all()
    kitti = io.read_kitti_disparity(tmp_path / "f_disparity_kitti.png")
    assert np.isnan(kitti[unknown]).all() and np.isfinite(kitti[~unknown]).all()
    raw = cv2.imread(str(tmp_path / "f_disparity_kitti.png"), cv2.IMREAD_UNCHANGED)
    assert raw.dtype == np.uint16 and (raw[unknown] == 0).all()
    dense = tmp_path / "dense"
    FrameWriter(dense, save=("pfm", "dense", "confidence")).write("f", result, rig, {"frame": "f"})
    conf = cv2.imread(str(dense / "f_confidence.png"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(conf, dmap.confidence)
    assert (conf[unknown] == 0).all() and (conf[~unknown] > 0).all()
    filled = io.read_pfm(dense / "f_disparity_filled.pfm")
    np.testing.assert_array_equal(filled, dmap.filled_disparity)
    assert np.isfinite(filled[dmap.filled]).all()


def test_sequence_appends_jsonl_and_resume_knows_finished_frames(tmp_path, frame):
    rig, result = frame
    writer = FrameWriter(tmp_path, save=("pfm", "json"), sequence=True)
    assert [p.name for p in writer.expected_files("a")] == ["a_disparity.pfm"]
    for name in ("a", "b"):
        writer.write(name, result, rig, {"frame": name, "index": 0})
    lines = (tmp_path / JSONL_NAME).read_text().splitlines()
    assert [json.loads(line)["frame"] for line in lines] == ["a", "b"]
    (tmp_path / JSONL_NAME).write_text("\n".join(lines) + "\n{\"frame\": \"c\", tor")  # a torn last line
    resumed = FrameWriter(tmp_path, save=("pfm", "json"), sequence=True, resume=True)
    assert resumed.finished("a") and resumed.finished("b") and not resumed.finished("c")
    (tmp_path / "b_disparity.pfm").unlink()
    assert not resumed.finished("b")
    assert not FrameWriter(tmp_path, save=("pfm", "json"), sequence=True).finished("a")  # no resume: never


def test_a_failing_file_removes_the_frames_other_files(tmp_path, frame, monkeypatch):
    rig, result = frame

    def full_disk(path, disparity):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(io, "write_kitti_disparity", full_disk)
    with pytest.raises(OSError, match="No space"):
        FrameWriter(tmp_path).write("f", result, rig, {"frame": "f"})
    assert list(tmp_path.iterdir()) == []


def test_write_all_or_nothing_keeps_nothing_of_a_failed_group(tmp_path):
    def ok(path):
        path.write_text("x")

    def boom(path):
        raise KeyboardInterrupt

    assert write_all_or_nothing([(tmp_path / "a", ok), (tmp_path / "b", ok)]) == [tmp_path / "a", tmp_path / "b"]
    with pytest.raises(KeyboardInterrupt):
        write_all_or_nothing([(tmp_path / "c", ok), (tmp_path / "d", boom)])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "b"]


def test_bad_save_kind_names_the_parameter(tmp_path):
    with pytest.raises(ValueError, match="`save`.*'png'"):
        FrameWriter(tmp_path, save=("png",))
    assert set(DEFAULT_SAVE) == set(SAVE_KINDS) - {"ply", "dense", "confidence"}  # only when named


def test_record_is_json_without_nan_and_labels_say_unknown(frame):
    rig, result = frame
    objs = result.objects
    assert box_labels(objs)[0].startswith("box ") and box_labels(objs)[0].endswith(" m")
    unknown = type(objs)(**{**objs.__dict__, "status": ("no_consensus",),
                            "distance_m": np.array([np.nan])})
    assert box_labels(unknown) == ["box ?"]
    json.dumps(frame_record("f", 0, result, rig, detector=None, fusion=FusionParams(), seed=0), allow_nan=False)


def test_jsonl_sink_without_resume_starts_afresh(tmp_path):
    path = tmp_path / JSONL_NAME
    path.write_text('{"frame": "old"}\n')
    sink = JsonlSink(path)
    assert sink.done == set()
    sink.append({"frame": "new"})
    assert path.read_text() == '{"frame":"new"}\n'


def test_record_names_the_source_files_and_gives_boxes_in_input_pixels(frame):
    rig, result = frame
    plain = frame_record("f", 0, result, rig, detector="stub", fusion=FusionParams(), seed=0,
                         source={"left": "in/é L.png", "right": "in/é R.png"})
    assert plain["source"] == {"left": "in/é L.png", "right": "in/é R.png"}
    assert plain["image_size"] == plain["processed_size"] == [240, 160]
    assert plain["boxes_in"] == "input image pixels (image_size)"
    # the same result reported for input images twice as large (as --scale 0.5 makes it)
    scaled = frame_record("f", 0, result, rig, detector="stub", fusion=FusionParams(), seed=0, original_size=(480, 320))
    assert scaled["image_size"] == [480, 320] and scaled["processed_size"] == [240, 160] and scaled["source"] is None
    box = np.array(plain["objects"][0]["box_xyxy"])
    np.testing.assert_allclose(scaled["objects"][0]["box_xyxy"], box * 2, atol=0.011)
    assert scaled["objects"][0]["distance_m"] == plain["objects"][0]["distance_m"]
