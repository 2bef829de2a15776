"""calib.formats.kitti: golden values on the real object calib.txt, raw calib_cam_to_cam.txt, error paths,
plain values."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from calib import CalibrationError, RectifiedRig, StereoRig, load_rig, read_kitti_calib
from calib.formats import KITTI_OBJECT_IMAGE_SIZE, kitti


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


def test_readers_return_plain_values(tmp_path, shared_data):
    path = shared_data / "kitti_object_pair/calib.txt"
    raw = read_kitti_calib(path)
    assert raw["P2"].shape == (12,) and raw["P2"].dtype == np.float64 and raw["P2"][0] == pytest.approx(721.5377)
    rect = kitti.read_rectified(path)
    assert set(rect) == {"focal_px", "cx_left", "cx_right", "cy", "baseline_m", "image_size"}
    assert rect["image_size"] == KITTI_OBJECT_IMAGE_SIZE == (1242, 375)
    assert RectifiedRig(**rect) == RectifiedRig.from_kitti(path)
    cam_to_cam = tmp_path / "calib_cam_to_cam.txt"
    cam_to_cam.write_text(_kitti_raw_text(shared_data))
    values = kitti.read_raw_stereo(cam_to_cam)
    assert set(values) == {"K_left", "dist_left", "K_right", "dist_right", "R", "T", "image_size"}
    assert values["image_size"] == (1392, 512) and values["T"].shape == (3,)
    assert StereoRig(**values) == StereoRig.from_kitti(cam_to_cam)


def test_rig_errors_name_the_file(tmp_path, shared_data):
    path = tmp_path / "calib.txt"
    text = (shared_data / "kitti_object_pair/calib.txt").read_text()
    path.write_text(text.replace("P2: 7.215377000000e+02", "P2: 1.0e-09").replace("P3: 7.215377000000e+02", "P3: 1.0e-09"))
    with pytest.raises(CalibrationError, match="plausible range") as info:
        RectifiedRig.from_kitti(path)
    assert str(info.value).startswith(f"{path}: `focal_px`")
