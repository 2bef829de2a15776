"""calib readers and writers: golden values on the real files, round trips, every reader's error paths,
hostile files (hypothesis)."""

from __future__ import annotations

import json
import logging
import os

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib import CalibrationError, RectifiedRig, StereoRig, load_rig, read_middlebury_calib

K1 = np.array([[700.5, 0.0, 320.25], [0.0, 701.0, 239.75], [0.0, 0.0, 1.0]])
K2 = np.array([[698.0, 0.1, 322.0], [0.0, 699.5, 241.0], [0.0, 0.0, 1.0]])
D1 = np.array([-0.11, 0.021, 0.0011, -0.0007, 0.003])
D2 = np.array([-0.1, 0.018, -0.0003, 0.0009, 0.0])
R = cv2.Rodrigues(np.array([0.003, -0.012, 0.0017]))[0]
T = np.array([-0.1203, 0.0011, -0.0004])
RIG = StereoRig(K1, D1, K2, D2, R, T, (640, 480))


# --------------------------------------------------------------------------- golden values on the real files
def test_middlebury_motorcycle(shared_data):
    rig = RectifiedRig.from_middlebury(shared_data / "middlebury2014/trainingQ/Motorcycle/calib.txt")
    assert rig.focal_px == pytest.approx(999.421)
    assert rig.baseline_m == pytest.approx(0.193001)  # 193.001 mm in the file
    assert rig.doffs == pytest.approx(32.778)
    assert rig.cx_left == pytest.approx(294.182) and rig.cy == pytest.approx(252.932)
    assert rig.image_size == (741, 497)
    raw = read_middlebury_calib(shared_data / "middlebury2014/trainingQ/Motorcycle/calib.txt")
    assert raw["ndisp"] == 70 and raw["baseline"] == pytest.approx(193.001)
    assert load_rig(shared_data / "middlebury2014/trainingQ/Motorcycle/calib.txt") == rig


def test_middlebury_depth_of_a_ground_truth_disparity(shared_data):
    rig = RectifiedRig.from_middlebury(shared_data / "middlebury2014/trainingQ/Motorcycle/calib.txt")
    # Z = baseline * f / (d + doffs): d = 40 px -> 0.193001 * 999.421 / 72.778
    assert float(rig.depth(np.array([40.0]))[0]) == pytest.approx(0.193001 * 999.421 / 72.778, rel=1e-6)


def test_kitti_object_pair(shared_data):
    path = shared_data / "kitti_object_pair/calib.txt"
    rig = RectifiedRig.from_kitti(path)
    assert rig.focal_px == pytest.approx(721.5377)
    assert rig.baseline_m == pytest.approx((44.85728 + 339.5242) / 721.5377, rel=1e-9)
    assert rig.baseline_m == pytest.approx(0.533, abs=0.001)
    assert rig.doffs == pytest.approx(0.0)
    assert rig.image_size == (1242, 375)
    left = cv2.imread(str(shared_data / "kitti_object_pair/left.png"))
    sized = RectifiedRig.from_kitti(path, image_size=(left.shape[1], left.shape[0]))
    assert sized.image_size == (left.shape[1], left.shape[0])
    assert load_rig(path) == rig
    # grey cameras P0/P1 give the same focal length and a baseline of 387.5744 / 721.5377 m
    grey = RectifiedRig.from_kitti(path, left=0, right=1)
    assert grey.baseline_m == pytest.approx(387.5744 / 721.5377)
    with pytest.raises(CalibrationError, match="right camera"):
        RectifiedRig.from_kitti(path, left=3, right=2)
    with pytest.raises(CalibrationError, match="`left`"):
        RectifiedRig.from_kitti(path, left=4)
    with pytest.raises(CalibrationError, match="different"):
        RectifiedRig.from_kitti(path, left=2, right=2)
    with pytest.raises(CalibrationError, match="RectifiedRig.from_kitti"):
        StereoRig.from_kitti(path)


def test_kitti_lidar_depth_to_disparity_and_back(shared_data):
    path = shared_data / "kitti_object_pair/lidar_depth_left.npy"
    if not path.is_file():
        pytest.skip(f"{path} not present")
    rig = RectifiedRig.from_kitti(shared_data / "kitti_object_pair/calib.txt")
    depth = np.load(path).astype(np.float32)
    depth[depth <= 0] = np.nan
    disp = rig.disparity(depth)
    valid = np.isfinite(depth)
    assert valid.sum() > 1000
    assert np.isfinite(disp[valid]).all() and np.isnan(disp[~valid]).all()
    np.testing.assert_allclose(rig.depth(disp)[valid], depth[valid], rtol=1e-5)
    y, x = np.argwhere(valid)[0]
    assert disp[y, x] == pytest.approx(721.5377 * rig.baseline_m / depth[y, x], rel=1e-5)


def test_oakd_json(shared_data):
    rig = RectifiedRig.from_oakd_json(shared_data / "oakd/stereodemo_calibration.json")
    assert rig.baseline_m == pytest.approx(0.075)
    assert rig.focal_px == pytest.approx(451.0344543457031)
    assert rig.image_size == (640, 480) and rig.doffs == 0.0
    assert load_rig(shared_data / "oakd/stereodemo_calibration.json") == rig


# --------------------------------------------------------------------------- OpenCV YAML / XML
@pytest.mark.parametrize("name", ["rig.yaml", "rig.yml", "rig.xml"])
def test_opencv_round_trip_is_exact(tmp_path, name):
    path = tmp_path / name
    RIG.to_opencv_yaml(path)
    back = StereoRig.from_opencv_yaml(path)
    assert back == RIG
    assert load_rig(path) == RIG
    # the file also carries the rectification for other tools
    rect = RectifiedRig.from_opencv_yaml(path)
    ref = RIG.rectify()
    assert rect.focal_px == pytest.approx(ref.focal_px) and rect.baseline_m == pytest.approx(ref.baseline_m)
    assert list(tmp_path.iterdir()) == [path]  # no temp files left behind


def test_rectified_with_maps_from_the_file(tmp_path):
    path = tmp_path / "rig.yaml"
    RIG.to_opencv_yaml(path)
    from_file = RectifiedRig.from_opencv_yaml(path, maps=True)
    ref = RIG.rectify(alpha=0.0)
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


def _opencv_text(header: str) -> str:
    def mat(name, m):
        m = np.atleast_2d(m)
        data = ", ".join(repr(float(v)) for v in m.ravel())
        return f"{name}: !!opencv-matrix\n   rows: {m.shape[0]}\n   cols: {m.shape[1]}\n   dt: d\n   data: [ {data} ]\n"

    return (f"{header}\n---\nimage_width: 640\nimage_height: 480\n" + mat("K1", K1) + mat("D1", D1) + mat("K2", K2)
            + mat("D2", D2) + mat("R", R) + mat("T", T.reshape(3, 1)))


@pytest.mark.parametrize("header", ["%YAML:1.0", "%YAML 1.2", "%YAML 1.1"])
def test_both_yaml_headers(tmp_path, header):
    path = tmp_path / "stereo.yml"
    path.write_text(_opencv_text(header))
    assert StereoRig.from_opencv_yaml(path) == RIG


def test_header_variants_tried_when_cv2_refuses_one():
    from calib.formats import _storage_variants

    body = "K1: 1\n"
    for header in ("%YAML:1.0\n", "%YAML 1.2\n", ""):
        variants = _storage_variants(header + body)
        assert variants[0] == header + body  # as written first
        assert {"%YAML:1.0\n" + body, "%YAML 1.2\n" + body, body} <= set(variants)
    assert _storage_variants("<?xml version=\"1.0\"?>\n<opencv_storage/>") == ["<?xml version=\"1.0\"?>\n<opencv_storage/>"]


def test_opencv_sample_names_and_image_size_argument(tmp_path):
    # OpenCV's stereo_calib sample writes M1/M2 and no image size
    text = _opencv_text("%YAML:1.0").replace("K1:", "M1:").replace("K2:", "M2:")
    text = text.replace("image_width: 640\nimage_height: 480\n", "")
    path = tmp_path / "intrinsics.yml"
    path.write_text(text)
    with pytest.raises(CalibrationError, match=r"image_width.*image_size=\(width, height\)"):
        StereoRig.from_opencv_yaml(path)
    assert StereoRig.from_opencv_yaml(path, image_size=(640, 480)) == RIG


def test_writer_is_atomic_and_checks(tmp_path):
    path = tmp_path / "rig.yaml"
    path.write_text("old")
    RIG.to_opencv_yaml(path)
    assert StereoRig.from_opencv_yaml(path) == RIG
    with pytest.raises(FileNotFoundError, match="folder"):
        RIG.to_opencv_yaml(tmp_path / "missing" / "rig.yaml")
    with pytest.raises(CalibrationError, match="directory"):
        RIG.to_opencv_yaml(tmp_path)


@pytest.mark.parametrize("umask", [0o022, 0o002, 0o077])
def test_written_files_follow_the_umask(tmp_path, umask):
    old = os.umask(umask)
    try:
        RIG.to_opencv_yaml(tmp_path / "rig.yaml")
        RIG.rectify().to_opencv_yaml(tmp_path / "rect.yaml")
    finally:
        os.umask(old)
    for name in ("rig.yaml", "rect.yaml"):
        assert (tmp_path / name).stat().st_mode & 0o777 == 0o666 & ~umask  # like io.atomic_write, not 0o600
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rect.yaml", "rig.yaml"]  # no temporary left


def test_failed_write_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    path = tmp_path / "rig.yaml"
    path.write_text("old")

    def boom(fd):
        raise OSError("disk full")

    monkeypatch.setattr(os, "fsync", boom)
    with pytest.raises(OSError, match="disk full"):
        RIG.to_opencv_yaml(path)
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["rig.yaml"]


# --------------------------------------------------------------------------- ROS camera_info
def _ros_text(name, k, d, r, p, width=640, height=480, header=""):
    def block(key, rows, cols, values):
        data = ", ".join(repr(float(v)) for v in np.ravel(values))
        return f"{key}:\n  rows: {rows}\n  cols: {cols}\n  data: [{data}]\n"

    return (header + f"image_width: {width}\nimage_height: {height}\ncamera_name: {name}\n" + block("camera_matrix", 3, 3, k)
            + "distortion_model: plumb_bob\n" + block("distortion_coefficients", 1, len(d), d)
            + block("rectification_matrix", 3, 3, r) + block("projection_matrix", 3, 4, p))


def _ros_pair(tmp_path, rig=RIG, header=""):
    rect = rig.rectification(alpha=0.0)
    left, right = tmp_path / "left.yaml", tmp_path / "right.yaml"
    left.write_text(_ros_text("left", rig.K_left, rig.dist_left, rect["R1"], rect["P1"], header=header))
    right.write_text(_ros_text("right", rig.K_right, rig.dist_right, rect["R2"], rect["P2"], header=header))
    return left, right


@pytest.mark.parametrize("header", ["", "%YAML:1.0\n---\n"])
def test_ros_pair_recovers_the_rig(tmp_path, header):
    left, right = _ros_pair(tmp_path, header=header)
    rig = StereoRig.from_ros(left, right)
    assert rig.isclose(RIG, rtol=1e-9, atol=1e-12)
    with pytest.raises(CalibrationError, match="one camera"):
        load_rig(left)


def test_ros_errors(tmp_path):
    left, right = _ros_pair(tmp_path)
    with pytest.raises(CalibrationError, match="no baseline"):
        StereoRig.from_ros(left, left)
    bad = tmp_path / "fisheye.yaml"
    bad.write_text(left.read_text().replace("plumb_bob", "equidistant"))
    with pytest.raises(CalibrationError, match="distortion_model"):
        StereoRig.from_ros(bad, right)
    small = tmp_path / "small.yaml"
    small.write_text(left.read_text().replace("image_width: 640", "image_width: 320"))
    with pytest.raises(CalibrationError, match="different image sizes"):
        StereoRig.from_ros(small, right)
    with pytest.raises(FileNotFoundError, match="nothere"):
        StereoRig.from_ros(tmp_path / "nothere.yaml", right)


# --------------------------------------------------------------------------- KITTI raw calib_cam_to_cam.txt
def _kitti_raw_text(shared_data) -> str:
    """A calib_cam_to_cam.txt in the KITTI raw layout, its P_rect_02/03 copied from the real object calib.txt."""
    obj = {}
    for line in (shared_data / "kitti_object_pair/calib.txt").read_text().splitlines():
        if ":" in line:
            key, rest = line.split(":", 1)
            obj[key] = rest.strip()
    rot3 = cv2.Rodrigues(np.array([0.0018, -0.0243, -0.0170]))[0]
    rot2 = cv2.Rodrigues(np.array([0.0034, -0.0046, 0.0053]))[0]

    def row(a):
        return " ".join(f"{v:.12e}" for v in np.ravel(a))

    lines = ["calib_time: 09-Jan-2012 13:57:47", "corner_dist: 9.950000e-02"]
    for i, (k, d, r, t) in {
        2: ([[959.791, 0, 696.0217], [0, 956.9251, 224.1806], [0, 0, 1]], [-0.3691, 0.1969, 0.00135, 0.00057, -0.0677], rot2,
            [0.05956621, 0.0002900141, 0.002577209]),
        3: ([[903.7596, 0, 695.7519], [0, 901.9653, 224.2509], [0, 0, 1]], [-0.3640, 0.1789, 0.0006, -0.0004, -0.0538], rot3,
            [-0.473105, 0.00555147, -0.005250882]),
    }.items():
        lines += [f"S_0{i}: 1.392000e+03 5.120000e+02", f"K_0{i}: {row(k)}", f"D_0{i}: {row(d)}", f"R_0{i}: {row(r)}",
                  f"T_0{i}: {row(t)}", f"S_rect_0{i}: 1.242000e+03 3.750000e+02", f"R_rect_0{i}: {obj['R0_rect']}",
                  f"P_rect_0{i}: {obj[f'P{i}']}"]
    return "\n".join(lines) + "\n"


def test_kitti_raw_cam_to_cam(tmp_path, shared_data):
    path = tmp_path / "calib_cam_to_cam.txt"
    path.write_text(_kitti_raw_text(shared_data))
    rect = RectifiedRig.from_kitti(path)
    assert rect.focal_px == pytest.approx(721.5377) and rect.baseline_m == pytest.approx(0.5327, abs=2e-4)
    assert rect.image_size == (1242, 375)  # from S_rect_02
    assert load_rig(path) == rect
    raw = StereoRig.from_kitti(path)
    assert raw.image_size == (1392, 512)
    # relative pose: X3 = R3 R2^T (X2 - T2) + T3
    t2, t3 = np.array([0.05956621, 0.0002900141, 0.002577209]), np.array([-0.473105, 0.00555147, -0.005250882])
    r2 = cv2.Rodrigues(np.array([0.0034, -0.0046, 0.0053]))[0]
    r3 = cv2.Rodrigues(np.array([0.0018, -0.0243, -0.0170]))[0]
    rel = r3 @ r2.T
    np.testing.assert_allclose(raw.R, rel, atol=1e-9)
    np.testing.assert_allclose(raw.T, t3 - rel @ t2, atol=1e-9)
    assert raw.baseline_m == pytest.approx(0.533, abs=0.003)
    assert raw.rectify().baseline_m == pytest.approx(raw.baseline_m, rel=1e-9)


def test_kitti_raw_missing_key(tmp_path, shared_data):
    path = tmp_path / "calib_cam_to_cam.txt"
    path.write_text("\n".join(l for l in _kitti_raw_text(shared_data).splitlines() if not l.startswith("D_03")))
    with pytest.raises(CalibrationError, match=r"calib_cam_to_cam.txt: missing key `D_03`"):
        StereoRig.from_kitti(path)


# --------------------------------------------------------------------------- every reader's error paths
READERS = {
    "middlebury": (RectifiedRig.from_middlebury, "calib.txt"),
    "kitti": (RectifiedRig.from_kitti, "calib.txt"),
    "kitti_raw": (StereoRig.from_kitti, "calib_cam_to_cam.txt"),
    "oakd": (RectifiedRig.from_oakd_json, "calib.json"),
    "opencv": (StereoRig.from_opencv_yaml, "rig.yaml"),
    "opencv_rect": (RectifiedRig.from_opencv_yaml, "rig.yaml"),
    "ros": (lambda p: StereoRig.from_ros(p, p), "left.yaml"),
    "load_rig": (load_rig, "rig.yaml"),
}


@pytest.mark.parametrize("reader", READERS)
def test_missing_file(tmp_path, reader):
    func, name = READERS[reader]
    with pytest.raises(FileNotFoundError, match=name):
        func(tmp_path / name)


@pytest.mark.parametrize("reader", READERS)
@pytest.mark.parametrize("content", ["", "   \n\n"])
def test_empty_file(tmp_path, reader, content):
    func, name = READERS[reader]
    (tmp_path / name).write_text(content)
    with pytest.raises(CalibrationError, match=rf"{name}.* empty"):
        func(tmp_path / name)


@pytest.mark.parametrize("reader", READERS)
def test_binary_garbage(tmp_path, reader):
    func, name = READERS[reader]
    (tmp_path / name).write_bytes(bytes(range(256)) * 4)
    with pytest.raises(CalibrationError, match=name):
        func(tmp_path / name)


def test_directory_instead_of_file(tmp_path):
    with pytest.raises(CalibrationError, match="not a regular file"):
        load_rig(tmp_path)


MOTO = "cam0=[999.421 0 294.182; 0 999.421 252.932; 0 0 1]\ncam1=[999.421 0 326.96; 0 999.421 252.932; 0 0 1]\n" \
       "doffs=32.778\nbaseline=193.001\nwidth=741\nheight=497\nndisp=70\n"


@pytest.mark.parametrize(
    "text, match",
    [
        (MOTO.replace("baseline=193.001\n", ""), "missing key `baseline`"),
        (MOTO.replace("cam1=", "camX="), "missing key `cam1`"),
        (MOTO.replace("width=741\n", ""), "missing key `width`"),
        (MOTO.replace("baseline=193.001", "baseline=abc"), "key `baseline` must hold numbers"),
        (MOTO.replace("baseline=193.001", "baseline=-5"), "key `baseline` must be a positive"),
        (MOTO.replace("0 0 1]\ncam1", "0 1]\ncam1"), "key `cam0` must be a 3x3"),
        (MOTO.replace("999.421 0 294.182", "999.421 0 x"), "key `cam0` must hold numbers"),
        (MOTO.replace("999.421 0 294.182", "nan 0 294.182"), "key `cam0` must be finite"),
        (MOTO.replace("999.421 0 294.182", "-999.421 0 294.182"), "focal_px"),
        (MOTO.replace("width=741", "width=741.5"), "width"),
        ("just some words\n", "line 1 is not `key=value`"),
    ],
)
def test_middlebury_errors(tmp_path, text, match):
    path = tmp_path / "calib.txt"
    path.write_text(text)
    with pytest.raises(CalibrationError, match=match) as info:
        RectifiedRig.from_middlebury(path)
    assert str(path) in str(info.value)


def _kitti_obj(shared_data):
    return (shared_data / "kitti_object_pair/calib.txt").read_text()


@pytest.mark.parametrize(
    "edit, match",
    [
        (lambda t: "\n".join(l for l in t.splitlines() if not l.startswith("P3:")), "missing key `P3`"),
        (lambda t: t.replace("P2: 7.215377000000e+02", "P2: abc"), "key `P2` must hold numbers"),
        (lambda t: t.replace("P2: 7.215377000000e+02 ", "P2: "), r"key `P2` must hold 12 numbers"),
        (lambda t: t.replace("P2: 7.215377000000e+02", "P2: nan"), "key `P2` must be finite"),
        (lambda t: t.replace("P3: 7.215377000000e+02", "P3: 7.0e+02"), "different focal lengths"),
        (lambda t: "this is not a calib file\n", "line 1 is not `key: values`"),
    ],
)
def test_kitti_errors(tmp_path, shared_data, edit, match):
    path = tmp_path / "calib.txt"
    path.write_text(edit(_kitti_obj(shared_data)))
    with pytest.raises(CalibrationError, match=match) as info:
        RectifiedRig.from_kitti(path)
    assert str(path) in str(info.value)


OAKD = {"width": 640, "height": 480, "baseline_meters": 0.075, "fx": 451.03, "fy": 451.03, "cx0": 299.0, "cx1": 299.0, "cy": 255.1}


@pytest.mark.parametrize(
    "change, match",
    [
        ({"fx": None}, "missing key `fx`"),
        ({"baseline_meters": None}, "missing key `baseline_meters`"),
        ({"fx": "451"}, "key `fx` must be a finite number"),
        ({"cx0": True}, "key `cx0` must be a finite number"),
        ({"baseline_meters": -0.075}, "baseline_m"),
        ({"width": 640.5}, "width"),
        ({"cy": [1, 2]}, "key `cy`"),
    ],
)
def test_oakd_errors(tmp_path, change, match):
    data = {k: v for k, v in (OAKD | change).items() if v is not None}
    path = tmp_path / "calib.json"
    path.write_text(json.dumps(data))
    with pytest.raises(CalibrationError, match=match) as info:
        RectifiedRig.from_oakd_json(path)
    assert str(path) in str(info.value)


def test_oakd_not_json(tmp_path):
    path = tmp_path / "calib.json"
    path.write_text("{not json")
    with pytest.raises(CalibrationError, match="not valid JSON"):
        RectifiedRig.from_oakd_json(path)
    path.write_text("[1, 2]")
    with pytest.raises(CalibrationError, match="JSON object"):
        RectifiedRig.from_oakd_json(path)


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
def test_opencv_errors(tmp_path, edit, match):
    path = tmp_path / "rig.yaml"
    path.write_text(edit(_opencv_text("%YAML:1.0")))
    if match is None:
        assert StereoRig.from_opencv_yaml(path) == RIG
        return
    with pytest.raises(CalibrationError, match=match) as info:
        load_rig(path)
    assert str(path) in str(info.value)


def test_opencv_rectified_errors(tmp_path):
    path = tmp_path / "rig.yaml"
    path.write_text(_opencv_text("%YAML:1.0"))
    with pytest.raises(CalibrationError, match="missing key `P1`/`P2`"):
        RectifiedRig.from_opencv_yaml(path)
    rect = RectifiedRig(focal_px=650.0, cx_left=300.0, cx_right=300.0, cy=200.0, baseline_m=0.09, image_size=(600, 400))
    rect.to_opencv_yaml(path)
    path.write_text(path.read_text().replace("-58.5", "58.5"))
    with pytest.raises(CalibrationError, match="baseline"):
        RectifiedRig.from_opencv_yaml(path)


# --------------------------------------------------------------------------- hostile files (hypothesis)
@settings(max_examples=180, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(max_size=300), which=st.sampled_from(sorted(READERS)))
def test_property_random_bytes_give_a_clear_error(tmp_path, data, which):
    func, name = READERS[which]
    path = tmp_path / name
    path.write_bytes(data)
    try:
        rig = func(path)
    except CalibrationError as exc:
        assert str(tmp_path) in str(exc) or name in str(exc)
    else:  # random bytes that parse must still give a well-formed rig
        assert isinstance(rig, (StereoRig, RectifiedRig))
        if isinstance(rig, RectifiedRig):
            assert rig.focal_px > 0 and rig.baseline_m > 0
            assert np.isfinite([rig.focal_px, rig.cx_left, rig.cx_right, rig.cy, rig.baseline_m]).all()
        else:
            assert all(np.isfinite(m).all() for m in (rig.K_left, rig.K_right, rig.R, rig.T, rig.dist_left, rig.dist_right))
        assert len(rig.image_size) == 2 and min(rig.image_size) > 0


@settings(max_examples=180, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cut=st.integers(0, 2000), junk=st.sampled_from(["", "x", ": [", "\x00", "nan", "]]]", "- - -"]))
def test_property_truncated_or_damaged_files(tmp_path, cut, junk):
    text = _opencv_text("%YAML:1.0")
    path = tmp_path / "rig.yaml"
    path.write_text(text[: cut % (len(text) + 1)] + junk)
    try:
        rig = load_rig(path)
    except CalibrationError as exc:
        assert str(path) in str(exc)
    else:
        assert rig == RIG  # a cut in the trailing whitespace still reads the full rig


num = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=32), st.integers(-10**6, 10**6))


@settings(max_examples=180, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(f=num, cx=num, baseline=num, doffs=num, width=num)
def test_property_middlebury_values_valid_or_named_error(tmp_path, f, cx, baseline, doffs, width):
    path = tmp_path / "calib.txt"
    path.write_text(f"cam0=[{f} 0 {cx}; 0 {f} 200; 0 0 1]\ncam1=[{f} 0 {cx}; 0 {f} 200; 0 0 1]\n"
                    f"doffs={doffs}\nbaseline={baseline}\nwidth={width}\nheight=400\n")
    try:
        rig = RectifiedRig.from_middlebury(path)
    except CalibrationError as exc:
        assert str(path) in str(exc)
    else:
        assert rig.focal_px > 0 and rig.baseline_m > 0 and np.isfinite(rig.doffs) and rig.image_size[0] > 0
        assert rig.baseline_m == pytest.approx(float(baseline) / 1000.0)


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(fx=num, cx0=num, baseline=num, width=num)
def test_property_oakd_values_valid_or_named_error(tmp_path, fx, cx0, baseline, width):
    path = tmp_path / "calib.json"
    data = OAKD | {"fx": fx, "cx0": cx0, "baseline_meters": baseline, "width": width}
    path.write_text(json.dumps(data))  # NaN/inf become the non-standard NaN/Infinity tokens json accepts
    try:
        rig = RectifiedRig.from_oakd_json(path)
    except CalibrationError as exc:
        assert str(path) in str(exc)
    else:
        assert rig.focal_px > 0 and rig.baseline_m > 0 and np.isfinite([rig.cx_left, rig.doffs]).all()


# ------------------------------------------------------------------------- Middlebury size vs image_size
def test_middlebury_full_size_calib_beside_quarter_size_images_is_scaled(tmp_path, caplog):
    full = MOTO.replace("999.421 0 294.182", "3997.684 0 1176.728").replace("999.421 252.932", "3997.684 1011.728") \
               .replace("999.421 0 326.96", "3997.684 0 1307.84").replace("doffs=32.778", "doffs=131.112") \
               .replace("width=741", "width=2964").replace("height=497", "height=1988")
    path = tmp_path / "calib.txt"
    path.write_text(full)
    with caplog.at_level(logging.INFO, logger="calib"):
        rig = RectifiedRig.from_middlebury(path, image_size=(741, 497))
    assert rig.image_size == (741, 497)
    assert rig.focal_px == pytest.approx(3997.684 / 4)
    assert rig.cx_left == pytest.approx((1176.728 + 0.5) / 4 - 0.5)
    assert rig.doffs == pytest.approx(131.112 / 4)
    assert rig.baseline_m == pytest.approx(0.193001)
    assert "2964x1988" in caplog.text and "741x497" in caplog.text
    # same size: unchanged
    same = tmp_path / "same.txt"
    same.write_text(MOTO)
    assert RectifiedRig.from_middlebury(same, image_size=(741, 497)).focal_px == pytest.approx(999.421)


def test_middlebury_calib_of_another_aspect_ratio_is_refused(tmp_path):
    path = tmp_path / "calib.txt"
    path.write_text(MOTO)
    with pytest.raises(CalibrationError, match="741x497") as info:
        RectifiedRig.from_middlebury(path, image_size=(741, 300))
    assert "741x300" in str(info.value) and str(path) in str(info.value)
