"""Exit codes that do not lie (issue #15 item 10): a named model that cannot be found is a usage error (2), the
default model missing still falls back to depth only; a file that is not a video fails (1) in one line, without
FFmpeg's own noise on the terminal."""

from __future__ import annotations

import json

import pytest

from detectors import ModelNotFoundError
from stereo_classic.cli import main
from stereo_classic.cli import run as run_cli

OAKD = {"width": 640, "height": 480, "baseline_meters": 0.075, "fx": 451.03, "fy": 451.03,
        "cx0": 299.04, "cx1": 299.04, "cy": 255.17}


@pytest.mark.parametrize("model", ["yolox_nan", "./no/such/model.onnx", "missing.onnx"])
def test_a_named_model_that_is_not_found_is_a_usage_error(tmp_path, capsys, model):
    out = tmp_path / "o"
    assert main(["run", "--model", model, "-o", str(out), "--num-disparities", "64"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --model ") and "--model none" in err and "Traceback" not in err
    assert not out.exists()  # nothing written for a run that did not do what was asked


def test_the_default_model_missing_falls_back_to_depth_only(tmp_path, capsys, monkeypatch):
    def not_found(name):
        raise ModelNotFoundError(f"model {name!r} not found: put it somewhere")

    monkeypatch.setattr(run_cli, "resolve_model", not_found)
    out = tmp_path / "o"
    assert main(["run", "-o", str(out), "--num-disparities", "64", "--save", "json"]) == 0
    assert "no detector, computing depth only" in capsys.readouterr().err


@pytest.mark.parametrize(("name", "content"), [("notes.mp4", b"hello, not a video\n"),
                                                ("noise.avi", bytes(range(256)) * 12)])
def test_a_file_that_is_not_a_video_fails_in_one_line(tmp_path, capfd, name, content):
    video = tmp_path / name
    video.write_bytes(content)
    calib = tmp_path / "calib.json"
    calib.write_text(json.dumps(OAKD))
    out = tmp_path / "o"
    assert main(["run", "--video", str(video), "--calib", str(calib), "--model", "none", "-o", str(out)]) == 1
    err = capfd.readouterr().err  # file descriptor 2: what FFmpeg writes directly lands here too
    assert err.strip().splitlines() == [f"error: cannot open video {video} (not a video OpenCV can decode)"]
    assert not out.exists()


# --- the frame checks on the command line (issue #15 items 1, 2) -------------------------------------------

def test_swapped_pair_exits_1_and_says_so(tmp_path, shared_data, capsys):
    d = shared_data / "kitti_object_pair"
    out = tmp_path / "o"
    argv = ["run", "--left", str(d / "right.png"), "--right", str(d / "left.png"), "--calib", str(d / "calib.txt"),
            "--model", "none", "-o", str(out), "--save", "json"]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "left and right look swapped" in err and "NOT MEASURED" in err
    record = json.loads((out / "right_objects.json").read_text())  # named after the --left image
    assert [w["code"] for w in record["warnings"]] == ["swapped_pair"]


def test_disparity_command_searches_as_many_disparities_as_run():
    from stereo_classic.cli.main import build_parser

    args = build_parser().parse_args(["disparity", "l.png", "r.png", "-o", "d.pfm"])
    assert args.num_disparities == 128
    run_args = build_parser().parse_args(["run"])
    assert run_cli._matcher_params({"matcher": {}, "threads": 0, "scale": 1.0}, None).num_disparities == 128
    assert getattr(run_args, "matcher_num_disparities", None) is None  # run's default comes from the scene or 128


def test_disparity_command_warns_when_the_range_is_too_short(tmp_path, shared_data, capsys):
    d = shared_data / "kitti_object_pair"
    out = tmp_path / "d.pfm"
    assert main(["disparity", str(d / "left.png"), str(d / "right.png"), "-o", str(out), "--num-disparities", "64",
                 "--no-png"]) == 0
    err = capsys.readouterr().err
    assert "sit at the end of the disparity range (63 px)" in err and "--num-disparities" in err


def test_disparity_command_warns_about_a_swapped_pair(tmp_path, capsys):
    import cv2

    from tests.helpers.scenes import make_rig, planted_scene

    left, right, _, _ = planted_scene(width=320, height=200, z_box=2.0, z_wall=8.0, box=(100, 60, 200, 140),
                                      rig=make_rig(320, 200))
    cv2.imwrite(str(tmp_path / "l.png"), left)
    cv2.imwrite(str(tmp_path / "r.png"), right)
    out = tmp_path / "d.pfm"
    assert main(["disparity", str(tmp_path / "r.png"), str(tmp_path / "l.png"), "-o", str(out), "--no-png",
                 "--num-disparities", "64"]) == 0
    assert "left and right look swapped" in capsys.readouterr().err
    assert main(["disparity", str(tmp_path / "l.png"), str(tmp_path / "r.png"), "-o", str(out), "--no-png",
                 "--num-disparities", "64"]) == 0
    assert "warning" not in capsys.readouterr().err
