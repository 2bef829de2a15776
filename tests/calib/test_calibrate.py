"""calib.calibrate_stereo on synthetic views rendered from a known virtual rig; board detection; the
``calibrate`` CLI."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib import CalibrationError, CharucoBoard, CheckerBoard, StereoRig, calibrate_stereo, detect_board
from calib.calibrate import _load
from calib.synthetic import render_stereo_views

TRUE_RIG = StereoRig(
    K_left=[[620.0, 0, 318.0], [0, 622.0, 243.0], [0, 0, 1]],
    dist_left=[-0.12, 0.05, 0.0008, -0.0006, 0.0],
    K_right=[[615.0, 0, 325.0], [0, 616.0, 238.0], [0, 0, 1]],
    dist_right=[-0.10, 0.03, -0.0005, 0.0004, 0.0],
    R=cv2.Rodrigues(np.array([0.01, -0.02, 0.005]))[0],
    T=[-0.12, 0.002, -0.001],
    image_size=(640, 480),
)
CHECKER = CheckerBoard(9, 6, 0.03)
CHARUCO = CharucoBoard(8, 6, 0.035, 0.026, dictionary="DICT_5X5_100")


@pytest.fixture(scope="module")
def checker_views():
    return render_stereo_views(TRUE_RIG, CHECKER, 12, rng=1)


@pytest.fixture(scope="module")
def charuco_views():
    return render_stereo_views(TRUE_RIG, CHARUCO, 10, rng=2)


@pytest.fixture(scope="module")
def checker_result(checker_views):
    blank = np.full((480, 640), 110, np.uint8)
    left = list(checker_views.left) + [blank, checker_views.left[0]]
    right = list(checker_views.right) + [blank, blank]
    return calibrate_stereo(left, right, board=CHECKER)


def _assert_close_to_truth(rig, report, max_angle_deg=0.1):
    assert abs(rig.baseline_m / TRUE_RIG.baseline_m - 1.0) < 0.005  # within 0.5 %
    assert report.rms_px < 0.3
    np.testing.assert_allclose(np.diag(rig.K_left)[:2], np.diag(TRUE_RIG.K_left)[:2], rtol=0.01)
    np.testing.assert_allclose(np.diag(rig.K_right)[:2], np.diag(TRUE_RIG.K_right)[:2], rtol=0.01)
    np.testing.assert_allclose(rig.T, TRUE_RIG.T, atol=0.002)
    angle = np.linalg.norm(cv2.Rodrigues(rig.R @ TRUE_RIG.R.T)[0])
    assert np.degrees(angle) < max_angle_deg
    assert report.vertical_residual_px < 0.3


class TestCalibrateStereo:
    def test_checkerboard_recovers_the_rig(self, checker_result):
        rig, report = checker_result
        _assert_close_to_truth(rig, report)
        assert rig.image_size == (640, 480)
        assert report.per_view_rms_px.shape == (12, 2) and (report.per_view_rms_px < 0.3).all()
        assert len(report.used_views) == 12

    def test_views_without_the_board_are_listed(self, checker_result):
        _, report = checker_result
        rejected = dict(report.rejected_views)
        assert rejected == {"view 12": "board not found in both images", "view 13": "board not found in the right image"}
        text = report.summary()
        assert "rejected view 13" in text and "RMS reprojection error" in text
        assert report.to_dict()["rejected_views"] == rejected

    def test_charuco_recovers_the_rig(self, charuco_views):
        rig, report = calibrate_stereo(charuco_views.left, charuco_views.right, board=CHARUCO)
        _assert_close_to_truth(rig, report, max_angle_deg=0.25)  # ChArUco corners are a little less precise

    def test_too_few_views_is_an_error_listing_the_rejected(self, checker_views):
        blank = np.full((480, 640), 110, np.uint8)
        with pytest.raises(CalibrationError, match=r"only 2 of 4 views are usable.*view 2: board not found"):
            calibrate_stereo(checker_views.left[:2] + [blank, blank], checker_views.right[:2] + [blank, blank],
                             board=CHECKER, min_views=3)

    def test_paths_and_names(self, tmp_path, checker_views):
        lefts, rights = [], []
        for i in range(6):
            lefts.append(tmp_path / f"left_{i:02d}.png")
            rights.append(tmp_path / f"right_{i:02d}.png")
            cv2.imwrite(str(lefts[-1]), checker_views.left[i])
            cv2.imwrite(str(rights[-1]), checker_views.right[i])
        rig, report = calibrate_stereo(lefts, rights, board=CHECKER, fix_k3=True)
        assert report.used_views[0] == "left_00.png"
        assert abs(rig.baseline_m / TRUE_RIG.baseline_m - 1.0) < 0.01
        assert rig.dist_left[4] == 0.0  # fix_k3

    @pytest.mark.parametrize(
        "kwargs, match",
        [
            ({"board": "9x6"}, "board"),
            ({"min_views": 2}, "min_views"),
            ({"min_views": True}, "min_views"),
            ({"names": ["a"]}, "names"),
        ],
    )
    def test_argument_errors(self, checker_views, kwargs, match):
        args = {"board": CHECKER} | kwargs
        with pytest.raises(CalibrationError, match=match):
            calibrate_stereo(checker_views.left[:3], checker_views.right[:3], **args)

    def test_input_errors(self, tmp_path, checker_views):
        left, right = checker_views.left, checker_views.right
        with pytest.raises(CalibrationError, match="3 items but `right_images` has 2"):
            calibrate_stereo(left[:3], right[:2], board=CHECKER)
        with pytest.raises(CalibrationError, match="empty"):
            calibrate_stereo([], [], board=CHECKER)
        with pytest.raises(CalibrationError, match="sequences"):
            calibrate_stereo(left[0], right[0], board=CHECKER)
        with pytest.raises(CalibrationError, match=r"320x240, earlier images are 640x480"):
            calibrate_stereo([left[0], left[1][:240, :320]], [right[0], right[1][:240, :320]], board=CHECKER)
        with pytest.raises(FileNotFoundError, match="nope.png"):
            calibrate_stereo([tmp_path / "nope.png"], [tmp_path / "nope.png"], board=CHECKER)
        (tmp_path / "bad.png").write_bytes(b"not an image")
        with pytest.raises(CalibrationError, match="bad.png could not be decoded"):
            calibrate_stereo([tmp_path / "bad.png"], [tmp_path / "bad.png"], board=CHECKER)
        with pytest.raises(CalibrationError, match="uint8"):
            calibrate_stereo([left[0].astype(np.float32)], [right[0]], board=CHECKER)


class TestBoards:
    @pytest.mark.parametrize("board", [CHECKER, CHARUCO], ids=["checker", "charuco"])
    def test_detection_is_subpixel_accurate(self, board, checker_views, charuco_views):
        views = checker_views if board is CHECKER else charuco_views
        rvec, tvec = views.poses[0]
        ids, obj, img = detect_board(views.left[0], board)
        truth = cv2.projectPoints(obj.astype(np.float64), rvec, tvec, TRUE_RIG.K_left, TRUE_RIG.dist_left)[0].reshape(-1, 2)
        err = np.linalg.norm(img - truth, axis=1)
        assert img.dtype == np.float32 and obj.shape == (len(ids), 3) and img.shape == (len(ids), 2)
        assert np.median(err) < 0.1 and err.max() < 0.4

    def test_not_found_is_none(self):
        assert detect_board(np.full((100, 100), 128, np.uint8), CHECKER) is None
        assert detect_board(np.full((100, 100, 3), 128, np.uint8), CHARUCO) is None

    @pytest.mark.parametrize(
        "make, match",
        [
            (lambda: CheckerBoard(1, 6, 0.03), "cols"),
            (lambda: CheckerBoard(6, 6, 0.03), "must differ"),
            (lambda: CheckerBoard(9, 6, 0.0), "square_m"),
            (lambda: CheckerBoard(9, 6, float("nan")), "square_m"),
            (lambda: CheckerBoard(9.0, 6, 0.03), "cols"),
            (lambda: CharucoBoard(8, 6, 0.03, 0.04), "marker_m"),
            (lambda: CharucoBoard(8, 6, 0.03, 0.02, dictionary="DICT_NOPE"), "dictionary"),
            (lambda: CharucoBoard(20, 20, 0.03, 0.02, dictionary="DICT_4X4_50"), "has 50 markers"),
        ],
    )
    def test_board_errors(self, make, match):
        with pytest.raises(CalibrationError, match=match):
            make()

    def test_detect_board_bad_image(self):
        with pytest.raises(CalibrationError, match="uint8"):
            detect_board(np.zeros((50, 50), np.float64), CHECKER)
        with pytest.raises(CalibrationError, match="shape"):
            detect_board(np.zeros((4, 50), np.uint8), CHECKER)


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**16), n=st.integers(1, 4), h=st.integers(8, 60), w=st.integers(8, 60))
def test_property_junk_images_give_a_clear_error(seed, n, h, w):
    rng = np.random.default_rng(seed)
    imgs = [rng.integers(0, 256, (h, w), dtype=np.uint8) for _ in range(n)]
    with pytest.raises(CalibrationError, match="views are usable"):
        calibrate_stereo(imgs, imgs, board=CHECKER, min_views=3)


# --------------------------------------------------------------------------- CLI
@pytest.fixture(scope="module")
def view_folder(tmp_path_factory, checker_views):
    folder = tmp_path_factory.mktemp("views")
    for i, (left, right) in enumerate(zip(checker_views.left, checker_views.right)):
        cv2.imwrite(str(folder / f"left{i:02d}.png"), left)
        cv2.imwrite(str(folder / f"right{i:02d}.png"), right)
    return folder


def test_cli_calibrate_folder(view_folder, tmp_path, capsys):
    from stereo_classic.cli import main

    out = tmp_path / "rig.yaml"
    code = main(["calibrate", "--folder", str(view_folder), "--board-size", "9x6", "--square", "0.03", "-o", str(out)])
    assert code == 0
    rig = StereoRig.from_opencv_yaml(out)
    assert abs(rig.baseline_m / TRUE_RIG.baseline_m - 1.0) < 0.005
    printed = capsys.readouterr().out
    assert "RMS reprojection error" in printed and "baseline: 0.12" in printed and str(out) in printed


def test_cli_calibrate_globs(view_folder, tmp_path):
    from stereo_classic.cli import main

    out = tmp_path / "rig.xml"
    code = main(["-q", "calibrate", "--left", str(view_folder / "left*.png"), "--right", str(view_folder / "right*.png"),
                 "--board-size", "9x6", "--square", "0.03", "--fix-k3", "-o", str(out)])
    assert code == 0 and out.is_file()


def test_cli_calibrate_charuco(charuco_views, tmp_path):
    from stereo_classic.cli import main

    for i, (left, right) in enumerate(zip(charuco_views.left, charuco_views.right)):
        cv2.imwrite(str(tmp_path / f"left_{i}.png"), left)
        cv2.imwrite(str(tmp_path / f"right_{i}.png"), right)
    out = tmp_path / "out" / "rig.yaml"
    out.parent.mkdir()
    code = main(["calibrate", "--folder", str(tmp_path), "--board", "charuco", "--board-size", "8x6", "--square", "0.035",
                 "--marker", "0.026", "--dictionary", "DICT_5X5_100", "-o", str(out)])
    assert code == 0
    assert abs(StereoRig.from_opencv_yaml(out).baseline_m / TRUE_RIG.baseline_m - 1.0) < 0.005


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--board-size", "9x6", "--square", "0.03"], "--folder DIR"),
        (["--folder", "FOLDER", "--left", "x*", "--board-size", "9x6", "--square", "0.03"], "not both"),
        (["--left", "nothing*.png", "--right", "nothing*.png", "--board-size", "9x6", "--square", "0.03"], "matches no files"),
        (["--folder", "FOLDER", "--board-size", "6x6", "--square", "0.03"], "must differ"),
        (["--folder", "FOLDER", "--board", "charuco", "--board-size", "8x6", "--square", "0.03"], "--marker"),
        (["--folder", "FOLDER", "--board-size", "9x6", "--square", "0.03", "--min-views", "2"], "--min-views"),
        (["--folder", "MISSING", "--board-size", "9x6", "--square", "0.03"], "not a folder"),
    ],
)
def test_cli_usage_errors(view_folder, tmp_path, capsys, argv, message):
    from stereo_classic.cli import main

    argv = [a.replace("FOLDER", str(view_folder)).replace("MISSING", str(tmp_path / "missing")) for a in argv]
    code = main(["calibrate", *argv, "-o", str(tmp_path / "rig.yaml")])
    assert code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "rig.yaml").exists()


@pytest.mark.parametrize("argv", [["--board-size", "9by6"], ["--square", "-1"], ["--square", "abc"]])
def test_cli_argparse_errors(view_folder, tmp_path, argv):
    from stereo_classic.cli import main

    base = {"--board-size": "9x6", "--square": "0.03"}
    base[argv[0]] = argv[1]
    args = ["calibrate", "--folder", str(view_folder), "-o", str(tmp_path / "rig.yaml")]
    for k, v in base.items():
        args += [k, v]
    assert main(args) == 2


def test_cli_too_few_views_is_a_runtime_error(tmp_path, capsys):
    from stereo_classic.cli import main

    blank = np.full((60, 80), 128, np.uint8)
    for i in range(3):
        cv2.imwrite(str(tmp_path / f"left{i}.png"), blank)
        cv2.imwrite(str(tmp_path / f"right{i}.png"), blank)
    code = main(["calibrate", "--folder", str(tmp_path), "--board-size", "9x6", "--square", "0.03", "-o", str(tmp_path / "r.yaml")])
    assert code == 1
    assert "views are usable" in capsys.readouterr().err
    assert not (tmp_path / "r.yaml").exists()


def test_calibration_images_are_read_on_any_path(tmp_path, monkeypatch):
    img = np.arange(6 * 9, dtype=np.uint8).reshape(6, 9)
    path = tmp_path / "vue_gauche_é.png"
    path.write_bytes(cv2.imencode(".png", img)[1].tobytes())
    monkeypatch.setattr(cv2, "imread", lambda *a, **k: None)  # what it does on a non-ASCII path on Windows
    np.testing.assert_array_equal(_load(path, "left_images[0]"), img)
