"""calib.formats.opencv: OpenCV FileStorage YAML/XML round trips, header spellings, atomic writes, error paths,
damaged files (hypothesis); the plain values the readers return."""

from __future__ import annotations

import os

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib import CalibrationError, RectifiedRig, StereoRig, load_rig
from calib.formats import opencv
from calib.formats.opencv import _storage_variants


# --------------------------------------------------------------------------- OpenCV YAML / XML
@pytest.mark.parametrize("name", ["rig.yaml", "rig.yml", "rig.xml"])
def test_opencv_round_trip_is_exact(tmp_path, name, stereo_rig):
    path = tmp_path / name
    stereo_rig.to_opencv_yaml(path)
    back = StereoRig.from_opencv_yaml(path)
    assert back == stereo_rig
    assert load_rig(path) == stereo_rig
    # the file also carries the rectification for other tools
    rect = RectifiedRig.from_opencv_yaml(path)
    ref = stereo_rig.rectify()
    assert rect.focal_px == pytest.approx(ref.focal_px) and rect.baseline_m == pytest.approx(ref.baseline_m)
    assert list(tmp_path.iterdir()) == [path]  # no temp files left behind


def test_rectified_with_maps_from_the_file(tmp_path, stereo_rig):
    path = tmp_path / "rig.yaml"
    stereo_rig.to_opencv_yaml(path)
    from_file = RectifiedRig.from_opencv_yaml(path, maps=True)
    ref = stereo_rig.rectify(alpha=0.0)
    assert from_file.has_maps and from_file.raw_image_size == (640, 480)
    np.testing.assert_array_equal(from_file.maps_left[0], ref.maps_left[0])
    np.testing.assert_array_equal(from_file.maps_right[1], ref.maps_right[1])
    raw = np.random.default_rng(0).integers(0, 256, (480, 640), dtype=np.uint8)
    np.testing.assert_array_equal(from_file.rectify_pair(raw, raw, check_offset=False)[0],
                                  ref.rectify_pair(raw, raw, check_offset=False)[0])
    path.write_text(path.read_text().replace("R1:", "RR1:"))
    with pytest.raises(CalibrationError, match="missing key `R1`"):
        RectifiedRig.from_opencv_yaml(path, maps=True)


def test_rectified_round_trip(tmp_path, shared_data):
    rig = RectifiedRig.from_middlebury(shared_data / "middlebury2014/trainingQ/Motorcycle/calib.txt")
    rig.to_opencv_yaml(tmp_path / "rect.yaml")
    back = RectifiedRig.from_opencv_yaml(tmp_path / "rect.yaml")
    assert back.image_size == rig.image_size
    for name in ("focal_px", "cx_left", "cx_right", "cy", "baseline_m"):
        assert getattr(back, name) == pytest.approx(getattr(rig, name), rel=1e-12)
    assert load_rig(tmp_path / "rect.yaml") == back


def test_rectified_from_q_only(tmp_path):
    rig = RectifiedRig(focal_px=650.0, cx_left=300.0, cx_right=310.0, cy=200.0, baseline_m=0.09, image_size=(600, 400))
    fs = cv2.FileStorage(str(tmp_path / "q.yaml"), cv2.FILE_STORAGE_WRITE)
    fs.write("Q", rig.Q)
    fs.write("image_width", 600)
    fs.write("image_height", 400)
    fs.release()
    back = RectifiedRig.from_opencv_yaml(tmp_path / "q.yaml")
    assert back.doffs == pytest.approx(10.0) and back.baseline_m == pytest.approx(0.09)


def _opencv_text(rig: StereoRig, header: str) -> str:
    def mat(name, m):
        m = np.atleast_2d(m)
        data = ", ".join(repr(float(v)) for v in m.ravel())
        return f"{name}: !!opencv-matrix\n   rows: {m.shape[0]}\n   cols: {m.shape[1]}\n   dt: d\n   data: [ {data} ]\n"

    return (f"{header}\n---\nimage_width: 640\nimage_height: 480\n" + mat("K1", rig.K_left) + mat("D1", rig.dist_left)
            + mat("K2", rig.K_right) + mat("D2", rig.dist_right) + mat("R", rig.R) + mat("T", rig.T.reshape(3, 1)))


@pytest.mark.parametrize("header", ["%YAML:1.0", "%YAML 1.2", "%YAML 1.1"])
def test_both_yaml_headers(tmp_path, header, stereo_rig):
    path = tmp_path / "stereo.yml"
    path.write_text(_opencv_text(stereo_rig, header))
    assert StereoRig.from_opencv_yaml(path) == stereo_rig


def test_header_variants_tried_when_cv2_refuses_one():
    body = "K1: 1\n"
    for header in ("%YAML:1.0\n", "%YAML 1.2\n", ""):
        variants = _storage_variants(header + body)
        assert variants[0] == header + body  # as written first
        assert {"%YAML:1.0\n" + body, "%YAML 1.2\n" + body, body} <= set(variants)
    assert _storage_variants("<?xml version=\"1.0\"?>\n<opencv_storage/>") == ["<?xml version=\"1.0\"?>\n<opencv_storage/>"]


def test_opencv_sample_names_and_image_size_argument(tmp_path, stereo_rig):
    # OpenCV's stereo_calib sample writes M1/M2 and no image size
    text = _opencv_text(stereo_rig, "%YAML:1.0").replace("K1:", "M1:").replace("K2:", "M2:")
    text = text.replace("image_width: 640\nimage_height: 480\n", "")
    path = tmp_path / "intrinsics.yml"
    path.write_text(text)
    with pytest.raises(CalibrationError, match=r"image_width.*image_size=\(width, height\)"):
        StereoRig.from_opencv_yaml(path)
    assert StereoRig.from_opencv_yaml(path, image_size=(640, 480)) == stereo_rig


def test_writer_is_atomic_and_checks(tmp_path, stereo_rig):
    path = tmp_path / "rig.yaml"
    path.write_text("old")
    stereo_rig.to_opencv_yaml(path)
    assert StereoRig.from_opencv_yaml(path) == stereo_rig
    with pytest.raises(FileNotFoundError, match="folder"):
        stereo_rig.to_opencv_yaml(tmp_path / "missing" / "rig.yaml")
    with pytest.raises(CalibrationError, match="directory"):
        stereo_rig.to_opencv_yaml(tmp_path)


@pytest.mark.parametrize("umask", [0o022, 0o002, 0o077])
def test_written_files_follow_the_umask(tmp_path, umask, stereo_rig):
    old = os.umask(umask)
    try:
        stereo_rig.to_opencv_yaml(tmp_path / "rig.yaml")
        stereo_rig.rectify().to_opencv_yaml(tmp_path / "rect.yaml")
    finally:
        os.umask(old)
    for name in ("rig.yaml", "rect.yaml"):
        assert (tmp_path / name).stat().st_mode & 0o777 == 0o666 & ~umask  # like io.atomic_write, not 0o600
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rect.yaml", "rig.yaml"]  # no temporary left


def test_failed_write_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch, stereo_rig):
    path = tmp_path / "rig.yaml"
    path.write_text("old")

    def boom(fd):
        raise OSError("disk full")

    monkeypatch.setattr(os, "fsync", boom)
    with pytest.raises(OSError, match="disk full"):
        stereo_rig.to_opencv_yaml(path)
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["rig.yaml"]


@pytest.mark.parametrize(
    "edit, match",
    [
        (lambda t: t.replace("K2:", "Kx:"), "missing key `K2`"),
        (lambda t: t.replace("\nT:", "\nTT:"), "missing key `T`"),
        (lambda t: t.replace("   data: [ 700.5", "   data: [ abc"), "key `K1`"),
        (lambda t: t.replace("rows: 3\n   cols: 3\n   dt: d\n   data: [ 700.5", "rows: 1\n   cols: 9\n   dt: d\n   data: [ 700.5"),
         r"key `K1` must have shape \(3, 3\)"),
        (lambda t: t.replace("rows: 3\n   cols: 1", "rows: 1\n   cols: 3"), None),  # a row vector T is fine
        (lambda t: t.replace("   data: [ 700.5", "   data: [ .nan"), "key `K1` must be finite"),
        (lambda t: t.replace("image_width: 640", "image_width: 640.5"), "image_width"),
        (lambda t: t.replace("image_width: 640", "image_width: wide"), "key `image_width` must be a number"),
        (lambda t: t.replace("K1: !!opencv-matrix", "K1: hello\nK1x: !!opencv-matrix"), "key `K1` must be a matrix of numbers"),
        (lambda t: "%YAML:1.0\n---\nfoo: 1\n", "unrecognised calibration file"),
        (lambda t: "%YAML:1.0\n---\n[1, 2, 3\n", "not a readable OpenCV FileStorage"),
    ],
)
def test_opencv_errors(tmp_path, edit, match, stereo_rig):
    path = tmp_path / "rig.yaml"
    path.write_text(edit(_opencv_text(stereo_rig, "%YAML:1.0")))
    if match is None:
        assert StereoRig.from_opencv_yaml(path) == stereo_rig
        return
    with pytest.raises(CalibrationError, match=match) as info:
        load_rig(path)
    assert str(path) in str(info.value)


def test_opencv_rectified_errors(tmp_path, stereo_rig):
    path = tmp_path / "rig.yaml"
    path.write_text(_opencv_text(stereo_rig, "%YAML:1.0"))
    with pytest.raises(CalibrationError, match="missing key `P1`/`P2`"):
        RectifiedRig.from_opencv_yaml(path)
    rect = RectifiedRig(focal_px=650.0, cx_left=300.0, cx_right=300.0, cy=200.0, baseline_m=0.09, image_size=(600, 400))
    rect.to_opencv_yaml(path)
    path.write_text(path.read_text().replace("-58.5", "58.5"))
    with pytest.raises(CalibrationError, match="baseline"):
        RectifiedRig.from_opencv_yaml(path)


@settings(max_examples=180, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cut=st.integers(0, 2000), junk=st.sampled_from(["", "x", ": [", "\x00", "nan", "]]]", "- - -"]))
def test_property_truncated_or_damaged_files(tmp_path, cut, junk, stereo_rig):
    text = _opencv_text(stereo_rig, "%YAML:1.0")
    path = tmp_path / "rig.yaml"
    path.write_text(text[: cut % (len(text) + 1)] + junk)
    try:
        rig = load_rig(path)
    except CalibrationError as exc:
        assert str(path) in str(exc)
    else:
        assert rig == stereo_rig  # a cut in the trailing whitespace still reads the full rig


# --------------------------------------------------------------------------- plain values
def test_readers_return_plain_values(tmp_path, stereo_rig):
    path = tmp_path / "rig.yaml"
    stereo_rig.to_opencv_yaml(path)
    values = opencv.read_stereo(path)
    assert set(values) == {"K_left", "dist_left", "K_right", "dist_right", "R", "T", "image_size"}
    assert values["image_size"] == (640, 480)
    for name in ("K_left", "dist_left", "K_right", "dist_right", "R", "T"):
        assert type(values[name]) is np.ndarray and values[name].dtype == np.float64
        np.testing.assert_array_equal(values[name], getattr(stereo_rig, name))
    assert values["T"].shape == (3,) and values["dist_left"].shape == (5,)
    rect = opencv.read_rectified(path)
    assert set(rect) == {"focal_px", "cx_left", "cx_right", "cy", "baseline_m", "image_size"}
    assert all(type(rect[k]) is float for k in ("focal_px", "cx_left", "cx_right", "cy", "baseline_m"))
    assert rect == opencv.read_projections(path)
    assert RectifiedRig(**rect) == RectifiedRig.from_opencv_yaml(path)
    maps = opencv.read_rectify_maps(path, image_size=(640, 480))
    assert set(maps) == {"maps_left", "maps_right", "raw_image_size"} and maps["raw_image_size"] == (640, 480)
    assert maps["maps_left"][0].shape == (480, 640, 2) and maps["maps_left"][0].dtype == np.int16
    assert opencv.read_keys(path)[:4] == ("image_width", "image_height", "K1", "D1")


def test_writers_take_plain_values(tmp_path, stereo_rig):
    path = tmp_path / "plain.yaml"
    opencv.write_stereo(path, K_left=stereo_rig.K_left, dist_left=stereo_rig.dist_left, K_right=stereo_rig.K_right,
                        dist_right=stereo_rig.dist_right, R=stereo_rig.R, T=stereo_rig.T, image_size=(640, 480))
    assert "R1" not in opencv.read_keys(path)  # no rectification given, none written
    assert StereoRig.from_opencv_yaml(path) == stereo_rig
    rect = stereo_rig.rectify()
    opencv.write_rectified(tmp_path / "rect.xml", P_left=rect.P_left, P_right=rect.P_right, Q=rect.Q, image_size=rect.image_size)
    assert RectifiedRig.from_opencv_yaml(tmp_path / "rect.xml") == rect.without_maps()


def test_a_rig_opencv_cannot_rectify_is_still_written(tmp_path, stereo_rig, monkeypatch, caplog):
    def refuse(*args, **kwargs):
        raise cv2.error("stereoRectify refused")

    monkeypatch.setattr(cv2, "stereoRectify", refuse)
    path = tmp_path / "rig.yaml"
    stereo_rig.to_opencv_yaml(path)
    assert "could not compute R1 R2 P1 P2 Q" in caplog.text
    assert "P1" not in opencv.read_keys(path)
    assert StereoRig.from_opencv_yaml(path) == stereo_rig
