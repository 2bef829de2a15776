"""``python -m stereo_classic run`` in-process: outputs, errors, config, Ctrl-C, --resume, determinism."""

from __future__ import annotations

import json
import os
import re
import signal
from pathlib import Path

import cv2
import numpy as np
import pytest

from stereo_classic.cli import main
from tests.helpers.scenes import planted_scene

EVERY_KIND = ("boxes.png", "disparity.png", "depth.png", "disparity.pfm", "disparity_kitti.png", "points.ply",
              "objects.json")


def _check_outputs(out: Path, name: str, shape: tuple[int, int], kinds=EVERY_KIND) -> dict:
    from stereo_classic import io

    h, w = shape
    for kind in kinds:
        assert (out / f"{name}_{kind}").is_file(), f"{name}_{kind} missing in {sorted(os.listdir(out))}"
    if "boxes.png" in kinds:
        assert io.read_image(out / f"{name}_boxes.png").shape == (h, w, 3)
    for kind in ("disparity.png", "depth.png"):
        if kind in kinds:
            assert io.read_image(out / f"{name}_{kind}").shape == (h, w, 3)
    pfm = io.read_pfm(out / f"{name}_disparity.pfm")
    assert pfm.shape == (h, w) and pfm.dtype == np.float32 and np.isfinite(pfm).mean() > 0.3
    kitti = io.read_kitti_disparity(out / f"{name}_disparity_kitti.png")
    both = np.isfinite(kitti) & np.isfinite(pfm)
    assert both.mean() > 0.3 and np.abs(kitti[both] - pfm[both]).max() <= 1 / 256 + 1e-6
    if "points.ply" in kinds:
        points, colors = io.read_ply(out / f"{name}_points.ply")
        assert points.shape[1] == 3 and len(points) > 1000 and np.all(np.isfinite(points))
        assert colors is not None and colors.shape == points.shape
    assert not [p for p in os.listdir(out) if p.endswith(".tmp")]
    if "objects.json" in kinds:
        return json.loads((out / f"{name}_objects.json").read_text())
    return {}


def _write_pair(folder: Path, name: str, seed: int = 0, size=(240, 160), z_box=3.0) -> tuple[Path, Path]:
    from stereo_classic import io

    left, right, _, _ = planted_scene(width=size[0], height=size[1], z_box=z_box, z_wall=8.0,
                                      box=(80, 50, 160, 110), seed=seed)
    lp, rp = folder / f"{name}_L.png", folder / f"{name}_R.png"
    io.write_image(lp, left)
    io.write_image(rp, right)
    return lp, rp


def _write_calib(path: Path, size=(240, 160)) -> Path:
    from calib import RectifiedRig

    w, h = size
    RectifiedRig(focal_px=700.0, cx_left=(w - 1) / 2, cx_right=(w - 1) / 2, cy=(h - 1) / 2, baseline_m=0.12,
                 image_size=(w, h)).to_opencv_yaml(path)
    return path


@pytest.fixture()
def pairs(tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    files = [_write_pair(folder, f"f{i}", seed=i, z_box=2.5 + 0.5 * i) for i in range(3)]
    return folder, files, _write_calib(tmp_path / "rig.yaml")


def _base(pairs_fixture, out: Path) -> list[str]:
    folder, _, calib_file = pairs_fixture
    return ["-q", "run", "--left", str(folder / "*_L.png"), "--right", str(folder / "*_R.png"),
            "--calib", str(calib_file), "--model", "none", "--num-disparities", "48", "-o", str(out)]


# --- the demo and the KITTI pair -----------------------------------------------------------------------

def test_demo_prints_the_table_and_writes_every_output(tmp_path, shared_models, monkeypatch, capsys):
    monkeypatch.setenv("STEREO_CLASSIC_MODELS", str(shared_models))
    out = tmp_path / "stereo_out"
    assert main(["run", "-o", str(out), "--ply"]) == 0
    stdout = capsys.readouterr().out
    header, *rows = stdout.splitlines()[:2]
    assert header.split() == ["label", "confidence", "distance", "x", "(m)", "y", "(m)", "z", "(m)", "direction"]
    assert rows[0].split()[:2] == ["motorcycle", "0.89"] and rows[0].split()[3] == "m"
    record = _check_outputs(out, "motorcycle_skimage", (500, 741))
    moto = [o for o in record["objects"] if o["label"] == "motorcycle"]
    assert len(moto) == 1 and moto[0]["status"] == "ok" and 1.5 < moto[0]["distance_m"] < 3.5
    assert record["detector"] == "yolox_nano" and len(moto[0]["xyz_m"]) == 3


def test_demo_offline_without_a_model_still_writes_depth(tmp_path, capsys, monkeypatch):
    # the default model missing (a named one missing is a usage error: tests/stereo_classic/cli/test_exit_codes.py)
    from detectors import ModelNotFoundError
    from stereo_classic.cli import run as run_cli

    def not_found(name):
        raise ModelNotFoundError(f"model file {tmp_path / 'missing.onnx'} does not exist")

    monkeypatch.setattr(run_cli, "resolve_model", not_found)
    out = tmp_path / "o"
    assert main(["run", "-o", str(out), "--scale", "0.5"]) == 0
    captured = capsys.readouterr()
    warning = [line for line in captured.err.splitlines() if "detector" in line]
    assert len(warning) == 1 and "missing.onnx" in warning[0]
    record = _check_outputs(out, "motorcycle_skimage", (250, 370), kinds=EVERY_KIND[:-2] + ("objects.json",))
    assert record["objects"] == [] and record["detector"] is None


def test_kitti_pair_from_files(tmp_path, shared_data, yolox_nano, capsys):
    d = shared_data / "kitti_object_pair"
    out = tmp_path / "k"
    argv = ["run", "--left", str(d / "left.png"), "--right", str(d / "right.png"), "--calib", str(d / "calib.txt"),
            "--model", str(yolox_nano), "--num-disparities", "128", "-o", str(out), "--ply"]
    assert main(argv) == 0
    assert capsys.readouterr().out.count("car ") == 4
    record = _check_outputs(out, "left", (375, 1242))
    cars = [o for o in record["objects"] if o["label"] == "car"]
    assert len(cars) == 4
    # the car cut by the right edge is nearer than 128 disparities reach: marked, with no distance; the others measured
    edge = [c for c in cars if c["box_xyxy"][2] >= 1241.0]
    assert len(edge) == 1 and edge[0]["status"] == "beyond_range" and edge[0]["distance_m"] is None
    assert all(c["status"] == "ok" and 2.0 < c["distance_m"] < 30.0 for c in cars if c not in edge)


# --- determinism, Ctrl-C, --resume ----------------------------------------------------------------------

def test_json_is_byte_identical_across_runs_and_thread_counts(tmp_path, pairs):
    outs = []
    for i, threads in enumerate(("1", "2", "2")):
        out = tmp_path / f"o{i}"
        assert main(_base(pairs, out) + ["--threads", threads, "--seed", "5"]) == 0
        outs.append((out / "objects.jsonl").read_bytes())
    assert outs[0] == outs[1] == outs[2]
    lines = outs[0].decode().splitlines()
    assert [json.loads(line)["frame"] for line in lines] == ["f0_L", "f1_L", "f2_L"]


def test_ctrl_c_leaves_finished_frames_complete_and_resume_finishes(tmp_path, pairs, monkeypatch, capsys):
    from stereo_classic import pipeline

    out = tmp_path / "o"
    calls = {"n": 0}
    real_call = pipeline.Localizer._rectified

    def interrupt_on_second(self, left, right):
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        return real_call(self, left, right)

    monkeypatch.setattr(pipeline.Localizer, "_rectified", interrupt_on_second)
    assert main(_base(pairs, out)) == 130
    assert "interrupted" in capsys.readouterr().err
    _check_outputs(out, "f0_L", (160, 240), kinds=EVERY_KIND[:5])
    assert not list(out.glob("f1_L*")) and not list(out.glob("f2_L*"))
    assert len((out / "objects.jsonl").read_text().splitlines()) == 1
    monkeypatch.setattr(pipeline.Localizer, "_rectified", real_call)

    assert main(_base(pairs, out)[1:] + ["--resume"]) == 0  # without -q: the summary is shown
    assert "1 finished frame(s) skipped" in capsys.readouterr().err
    for name in ("f0_L", "f1_L", "f2_L"):
        _check_outputs(out, name, (160, 240), kinds=EVERY_KIND[:5])
    fresh = tmp_path / "fresh"
    assert main(_base(pairs, fresh)) == 0
    assert (out / "objects.jsonl").read_bytes() == (fresh / "objects.jsonl").read_bytes()


def test_ctrl_c_while_writing_finishes_that_frame_first(tmp_path, pairs, monkeypatch, sigint_delivered):
    from stereo_classic import io

    out = tmp_path / "o"
    real = io.write_pfm
    calls = {"n": 0}

    def pfm_then_sigint(path, array, **kw):
        calls["n"] += 1
        if calls["n"] == 2:
            os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C in the middle of frame 2's files
        return real(path, array, **kw)

    monkeypatch.setattr(io, "write_pfm", pfm_then_sigint)
    assert main(_base(pairs, out)) == 130
    for name in ("f0_L", "f1_L"):
        _check_outputs(out, name, (160, 240), kinds=EVERY_KIND[:5])
    assert not list(out.glob("f2_L*"))
    assert len((out / "objects.jsonl").read_text().splitlines()) == 2


def test_resume_drops_a_torn_jsonl_line(tmp_path, pairs):
    out = tmp_path / "o"
    assert main(_base(pairs, out)) == 0
    full = (out / "objects.jsonl").read_bytes()
    lines = full.decode().splitlines(keepends=True)
    (out / "objects.jsonl").write_text(lines[0] + lines[1][:20])  # frame 1's line torn, frame 2's gone
    assert main(_base(pairs, out) + ["--resume"]) == 0
    assert (out / "objects.jsonl").read_bytes() == full


# --- video and camera -------------------------------------------------------------------------------------

def _write_video(path: Path, n: int) -> None:
    left, right, _, _ = planted_scene(width=240, height=160, z_box=3.0, z_wall=8.0, box=(80, 50, 160, 110))
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 5.0, (480, 160))
    assert writer.isOpened()
    for _ in range(n):
        writer.write(np.hstack([left, right]))
    writer.release()


def test_side_by_side_video(tmp_path, capsys):
    video = tmp_path / "sbs.avi"
    _write_video(video, 3)
    out = tmp_path / "o"
    calib_file = _write_calib(tmp_path / "rig.yaml")
    argv = ["run", "--video", str(video), "--calib", str(calib_file), "--model", "none", "--num-disparities", "48",
            "-o", str(out)]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "3 frame(s)" in err and "frames/s" in err
    rates = [line for line in err.splitlines() if "frames/s" in line]  # one rate, saying what it measures
    assert len(rates) == 1 and "wall clock of the whole frame loop" in rates[0]
    # and the rate after the first frame, whose time holds the one-time loading
    assert re.search(r"; after the first frame \(\d+\.\d\d s, one-time loading included\): \d+\.\d\d frames/s$",
                     rates[0]), rates[0]
    names = [json.loads(line)["frame"] for line in (out / "objects.jsonl").read_text().splitlines()]
    assert names == ["frame_000000", "frame_000001", "frame_000002"]


class _FakeCamera:
    """Delivers two side-by-side frames, then stops (a camera unplugged)."""

    def __init__(self, index):
        left, right, _, _ = planted_scene(width=240, height=160, z_box=3.0, z_wall=8.0, box=(80, 50, 160, 110))
        self.frames = [np.hstack([left, right])] * 2

    def isOpened(self):  # noqa: N802 (OpenCV's name)
        return True

    def read(self):
        return (True, self.frames.pop()) if self.frames else (False, None)

    def get(self, prop):
        return 0.0

    def release(self):
        pass


def test_camera_that_stops_ends_cleanly_with_a_summary(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(cv2, "VideoCapture", _FakeCamera)
    out = tmp_path / "o"
    argv = ["run", "--camera", "0", "--calib", str(_write_calib(tmp_path / "rig.yaml")), "--model", "none",
            "--num-disparities", "48", "-o", str(out)]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "stopped delivering frames after 2 frame(s)" in err and "2 frame(s)" in err
    assert "Traceback" not in err
    assert len((out / "objects.jsonl").read_text().splitlines()) == 2


# --- bad input: one line, the right exit code, nothing written ------------------------------------------

def _bad_cases(tmp_path: Path) -> dict[str, tuple[list[str], int, str]]:
    from stereo_classic import io

    folder = tmp_path / "in"
    folder.mkdir()
    lp, rp = _write_pair(folder, "a")
    small = folder / "small_R.png"
    io.write_image(small, io.read_image(rp)[:, :200])
    broken = folder / "broken_L.png"
    broken.write_bytes(b"\x89PNG\r\n\x1a\n not really")
    calib_ok = _write_calib(tmp_path / "rig.yaml")
    calib_other = _write_calib(tmp_path / "other.yaml", size=(320, 240))
    base = ["run", "--model", "none", "--num-disparities", "48"]
    negative_frames = tmp_path / "frames.toml"
    negative_frames.write_text("max_frames = -2\n")
    return {
        "mismatched sizes": (base + ["--left", str(lp), "--right", str(small), "--calib", str(calib_ok)], 1, "differ"),
        "unreadable file": (base + ["--left", str(broken), "--right", str(rp), "--calib", str(calib_ok)], 1, "broken_L"),
        "missing file": (base + ["--left", str(folder / "nope.png"), "--right", str(rp), "--calib", str(calib_ok)], 1, "nope.png"),
        "calibration size": (base + ["--left", str(lp), "--right", str(rp), "--calib", str(calib_other)], 1, "320x240"),
        "empty glob": (base + ["--left", str(folder / "*.jpg"), "--right", str(folder / "*.jpg"), "--calib", str(calib_ok)], 2, "matches no file"),
        "camera": (base + ["--camera", "57", "--calib", str(calib_ok)], 1, "camera 57"),
        "left without right": (base + ["--left", str(lp), "--calib", str(calib_ok)], 2, "--right"),
        "no calib": (base + ["--left", str(lp), "--right", str(rp)], 2, "--calib"),
        "two inputs": (base + ["--left", str(lp), "--right", str(rp), "--dataset", str(folder)], 2, "choose one input"),
        "bad save": (base + ["--save", "boxes,nonsense"], 2, "nonsense"),
        "bad matcher value": (base + ["--cost", "ssd"], 2, "cost"),
        "bad fusion value": (base + ["--box-shrink", "1.5"], 2, "box_shrink"),
        "bad depth range": (base + ["--depth-range", "5", "1"], 2, "depth_range"),
        "bad confidence": (base + ["--conf", "1.5"], 2, "--conf"),
        "missing config": (base + ["--config", str(tmp_path / "none.toml")], 2, "none.toml"),
        "negative max frames": (base + ["--left", str(lp), "--right", str(rp), "--calib", str(calib_ok),
                                        "--max-frames", "-1"], 2, "--max-frames"),
        "negative max_frames in config": (base + ["--left", str(lp), "--right", str(rp), "--calib", str(calib_ok),
                                                  "--config", str(negative_frames)], 2, "`max_frames`"),
    }


@pytest.mark.parametrize("case", ["mismatched sizes", "unreadable file", "missing file", "calibration size", "empty glob",
                                  "camera", "left without right", "no calib", "two inputs", "bad save",
                                  "bad matcher value", "bad fusion value", "bad depth range", "bad confidence",
                                  "missing config", "negative max frames", "negative max_frames in config"])
def test_bad_input_one_line_right_code_nothing_written(tmp_path, capsys, case):
    argv, code, needle = _bad_cases(tmp_path)[case]
    out = tmp_path / "out"
    assert main(argv + ["-o", str(out)]) == code
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and err[0].startswith("error:") and needle in err[0], err
    assert not out.exists() or not any(out.iterdir())


def test_unknown_class_name_and_corrupt_model(tmp_path, yolox_nano, capsys):
    base = ["run", "--scale", "0.25", "-o", str(tmp_path / "out")]
    assert main(base + ["--model", str(yolox_nano), "--classes", "car,motorbike"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'motorbike'" in err[0]
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"not an onnx file")
    assert main(base + ["--model", str(bad)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and "bad.onnx" in err[0]
    assert not (tmp_path / "out").exists()


def test_verbose_shows_the_traceback(tmp_path, capsys):
    argv, code, _ = _bad_cases(tmp_path)["calibration size"]
    assert main(["-v"] + argv + ["-o", str(tmp_path / "out")]) == code
    assert "Traceback" in capsys.readouterr().err


# --- config ---------------------------------------------------------------------------------------------------

def test_dump_config_round_trips_and_flags_win(tmp_path, capsys):
    assert main(["run", "--dump-config", "--conf", "0.4", "--classes", "car,person", "--num-disparities", "96"]) == 0
    text = capsys.readouterr().out
    assert "conf = 0.4" in text and 'classes = ["car", "person"]' in text and "num_disparities = 96" in text
    cfg = tmp_path / "c.toml"
    cfg.write_text(text.replace("conf = 0.4", "conf = 0.25"))
    assert main(["run", "--config", str(cfg), "--dump-config", "--seed", "9"]) == 0
    again = capsys.readouterr().out
    assert "conf = 0.25" in again and "seed = 9" in again and "num_disparities = 96" in again


@pytest.mark.parametrize("content, needle", [
    ("conf = 'high'", "conf"),
    ("colour = 1", "colour"),
    ("[matcher]\nwindow = 3", "window"),
    ("conf = ", "not valid TOML"),
    ("depth_range = [1]", "depth_range"),
])
def test_bad_config_is_a_usage_error(tmp_path, capsys, content, needle):
    cfg = tmp_path / "c.toml"
    cfg.write_text(content)
    assert main(["run", "--config", str(cfg), "--dump-config"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0] and "c.toml" in err[0]


def test_dataset_folder_with_max_frames_and_scale(tmp_path, shared_data, capsys):
    out = tmp_path / "o"
    argv = ["run", "--dataset", str(shared_data / "oakd"), "--max-frames", "2", "--scale", "0.5", "--model", "none",
            "-o", str(out)]
    assert main(argv) == 0
    records = [json.loads(line) for line in (out / "objects.jsonl").read_text().splitlines()]
    assert len(records) == 2 and all(r["processed_size"] == [320, 240] for r in records)
    assert all(r["image_size"] == [640, 480] for r in records)  # the input size: boxes are in its pixels
    for r in records:
        _check_outputs(out, r["frame"], (240, 320), kinds=EVERY_KIND[:5])


def test_raw_pair_needs_rectify_and_is_rectified(tmp_path, capsys):
    from calib import StereoRig
    from stereo_classic import io

    folder = tmp_path / "in"
    folder.mkdir()
    lp, rp = _write_pair(folder, "raw")
    K = np.array([[700.0, 0, 119.5], [0, 700.0, 79.5], [0, 0, 1]])
    rig = StereoRig(K_left=K, dist_left=np.zeros(5), K_right=K, dist_right=np.zeros(5), R=np.eye(3),
                    T=np.array([-0.12, 0.0, 0.0]), image_size=(240, 160))
    calib_file = tmp_path / "stereo.yaml"
    rig.to_opencv_yaml(calib_file)
    argv = ["run", "--left", str(lp), "--right", str(rp), "--calib", str(calib_file), "--model", "none",
            "--num-disparities", "48", "-o", str(tmp_path / "o")]
    assert main(argv) == 2
    assert "--rectify" in capsys.readouterr().err
    assert main(argv + ["--rectify"]) == 0
    pfm = io.read_pfm(tmp_path / "o" / "raw_L_disparity.pfm")
    assert pfm.shape == (160, 240)
    # The wall at 8 m: f B / Z = 700 * 0.12 / 8 = 10.5 px, unchanged by rectifying an ideal rig.
    assert np.nanmedian(pfm[:, 100:]) == pytest.approx(10.5, abs=0.5)


def test_demo_json_identical_across_thread_counts_with_the_detector(tmp_path, yolox_nano):
    texts = []
    for threads in ("1", "2"):
        out = tmp_path / f"t{threads}"
        argv = ["-q", "run", "--model", str(yolox_nano), "--threads", threads, "--save", "json", "-o", str(out)]
        assert main(argv) == 0
        texts.append((out / "motorcycle_skimage_objects.json").read_bytes())
    assert texts[0] == texts[1]
    assert b'"motorcycle"' in texts[0]


def test_save_selects_the_outputs(tmp_path):
    out = tmp_path / "o"
    assert main(["-q", "run", "--model", "none", "--scale", "0.25", "--save", "pfm,json", "-o", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir() if p.name not in ("run.json", ".stereo_classic.lock")) == [
        "motorcycle_skimage_disparity.pfm", "motorcycle_skimage_objects.json"]


def test_a_failing_write_leaves_no_part_of_that_frame(tmp_path, pairs, monkeypatch, capsys):
    from stereo_classic import io

    out = tmp_path / "o"
    real = io.write_kitti_disparity
    calls = {"n": 0}

    def fail_on_second(path, disparity):
        calls["n"] += 1
        if calls["n"] == 2:
            raise OSError(28, "No space left on device")
        return real(path, disparity)

    monkeypatch.setattr(io, "write_kitti_disparity", fail_on_second)
    assert main(_base(pairs, out)) == 1
    assert "No space left" in capsys.readouterr().err
    _check_outputs(out, "f0_L", (160, 240), kinds=EVERY_KIND[:5])
    assert not list(out.glob("f1_L*")) and not list(out.glob("f2_L*"))
    assert len((out / "objects.jsonl").read_text().splitlines()) == 1


def test_disparities_beyond_the_kitti_png_range_are_stored_as_unknown_there(tmp_path, capsys):
    """A near object at ~300 px: the PFM keeps it, the KITTI PNG marks it unknown and the run says so."""
    from stereo_classic import io
    from tests.helpers.scenes import disparity_of, make_rig

    size = (480, 120)
    rig = make_rig(*size)
    z_box = rig.focal_px * rig.baseline_m / 300.0  # disparity 300 px
    left, right, gt, _ = planted_scene(width=size[0], height=size[1], z_box=z_box, z_wall=z_box * 4,
                                       box=(340, 20, 470, 100), rig=rig)
    assert disparity_of(z_box, rig) == pytest.approx(300, abs=0.5)
    io.write_image(tmp_path / "L.png", left)
    io.write_image(tmp_path / "R.png", right)
    _write_calib(tmp_path / "rig.yaml", size)  # the same focal length and baseline as make_rig
    out = tmp_path / "out"
    code = main(["run", "--left", str(tmp_path / "L.png"), "--right", str(tmp_path / "R.png"), "--calib",
                 str(tmp_path / "rig.yaml"), "--model", "none", "--num-disparities", "320", "-o", str(out)])
    assert code == 0
    pfm = io.read_pfm(out / "L_disparity.pfm")
    kitti = io.read_kitti_disparity(out / "L_disparity_kitti.png")
    far = np.isfinite(pfm) & (pfm > 65535 / 256)
    assert far.sum() > 2000  # the object was matched beyond 256 px
    assert np.isnan(kitti[far]).all()
    near = np.isfinite(pfm) & ~far
    assert np.abs(kitti[near] - pfm[near]).max() <= 1 / 256 + 1e-6
    assert "do not fit a KITTI PNG" in capsys.readouterr().err


def test_dataset_run_keeps_the_buffers_of_one_matcher_only(tmp_path, shared_data, monkeypatch):
    """Every OAK-D scene brings its own rig; the previous scene's matcher must free its buffers."""
    from stereo_classic import pipeline

    created, holding = [], []
    real_init, real_call = pipeline.Localizer.__init__, pipeline.Localizer.__call__

    def tracking_init(self, *a, **kw):
        real_init(self, *a, **kw)
        created.append(self)

    def counting_call(self, left, right):
        result = real_call(self, left, right)
        holding.append(sum(loc.matcher._workspace not in (None, False) for loc in created))
        return result

    def counting_submit(self, left, right):  # the pipelined run: the match is done when submit returns
        future = real_submit(self, left, right)
        holding.append(sum(loc.matcher._workspace not in (None, False) for loc in created))
        return future

    real_submit = pipeline.Localizer.submit
    monkeypatch.setattr(pipeline.Localizer, "__init__", tracking_init)
    monkeypatch.setattr(pipeline.Localizer, "__call__", counting_call)
    monkeypatch.setattr(pipeline.Localizer, "submit", counting_submit)
    argv = ["-q", "run", "--dataset", str(shared_data / "oakd"), "--max-frames", "3", "--scale", "0.25",
            "--model", "none", "--save", "json", "-o", str(tmp_path / "o")]
    assert main(argv) == 0
    assert len(created) == 3 and holding == [1, 1, 1]
    assert all(loc.matcher._workspace is None for loc in created)  # the run frees the last one too


def test_run_takes_every_matcher_option_of_the_disparity_command(tmp_path, pairs, monkeypatch):
    import argparse

    from stereo_classic import pipeline
    from stereo_classic.cli import disparity as cli_disparity
    from stereo_classic.cli import run as cli_run

    def flags(module):
        parser = module.add_parser(argparse.ArgumentParser().add_subparsers())
        return {s for a in parser._actions for s in a.option_strings}

    matcher_flags = flags(cli_disparity) - {"-h", "--help", "-o", "--output", "--png", "--no-png", "--memory-limit"}
    assert matcher_flags <= flags(cli_run), matcher_flags - flags(cli_run)
    seen = []
    real_init = pipeline.Localizer.__init__

    def spy(self, rig, detector=None, params=None, **kw):
        seen.append(params)
        real_init(self, rig, detector, params, **kw)

    monkeypatch.setattr(pipeline.Localizer, "__init__", spy)
    argv = _base(pairs, tmp_path / "o") + [
        "--census-window", "7x5", "--lr-check", "2", "--lr-mode", "opencv", "--speckle-range", "1.5", "--paths", "4",
        "--no-fill-holes", "--adaptive-p2", "--no-subpixel", "--max-frames", "1", "--save", "json"]
    assert main(argv) == 0
    p = seen[0]
    assert (p.census_window, p.lr_check, p.lr_mode, p.speckle_range, p.paths) == ((7, 5), 2.0, "opencv", 1.5, 4)
    assert (p.fill_holes, p.adaptive_p2, p.subpixel, p.num_disparities) == (False, True, False, 48)
    # "off" is a value, not "not given": it must override the default (lr_check 1.0) and a config file
    cfg = tmp_path / "c.toml"
    cfg.write_text("[matcher]\nlr_check = 3\n")
    seen.clear()
    argv = _base(pairs, tmp_path / "o2") + ["--lr-check", "off", "--config", str(cfg), "--max-frames", "1",
                                            "--save", "json"]
    assert main(argv) == 0
    assert seen[0].lr_check is None


def _fixed_box_yolox(path: Path, size=(240, 160), box=(80, 50, 160, 110), label=2) -> Path:
    """A tiny YOLOX-layout ONNX model (built with onnx.helper) whose output is a constant: one box.

    Input (1, 3, H, W) = the image size, so the letterbox is the identity and ``box`` (x0, y0, x1, y1,
    image pixels) comes back as it is, class ``label`` (2 = car), score 0.9.
    """
    import math

    import onnx
    from onnx import TensorProto, helper, numpy_helper

    w, h = size
    strides = (8, 16, 32)
    cells = [math.ceil(h / s) * math.ceil(w / s) for s in strides]
    raw = np.zeros((1, sum(cells), 85), np.float32)
    s = 32
    cx, cy, bw, bh = (box[0] + box[2]) / 2, (box[1] + box[3]) / 2, box[2] - box[0], box[3] - box[1]
    gx, gy = int(cx // s), int(cy // s)
    row = cells[0] + cells[1] + gy * math.ceil(w / s) + gx
    raw[0, row, :5] = (cx / s - gx, cy / s - gy, math.log(bw / s), math.log(bh / s), 0.9)
    raw[0, row, 5 + label] = 1.0
    node = helper.make_node("Constant", [], ["output"], value=numpy_helper.from_array(raw, "output_value"))
    graph = helper.make_graph([node], "fixed_box", [helper.make_tensor_value_info("images", TensorProto.FLOAT,
                                                                                  [1, 3, h, w])],
                              [helper.make_tensor_value_info("output", TensorProto.FLOAT, list(raw.shape))])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    path.write_bytes(model.SerializeToString())
    return path


def test_objects_json_is_byte_identical_across_runs_and_thread_counts_with_objects(tmp_path, pairs):
    """RANSAC draws its hypotheses (a box of 64 x 48 known pixels > 256 iterations): seeded, so the same.

    A narrow band (0.1 px, no growth) makes the result depend on which hypotheses are drawn, so that a
    seed not passed through, or a thread-dependent draw, would show (checked: another seed differs).
    """
    model = _fixed_box_yolox(tmp_path / "fixed_box.onnx")

    def run(name, threads, seed):
        out = tmp_path / name
        argv = _base(pairs, out)
        argv[argv.index("--model") + 1] = str(model)
        assert main(argv + ["--threads", threads, "--seed", seed, "--save", "json", "--tolerance-px", "0.1",
                            "--grow-density", "0"]) == 0
        return (out / "objects.jsonl").read_bytes()

    outs = [run(f"o{i}", threads, "5") for i, threads in enumerate(("1", "2", "2"))]
    assert outs[0] == outs[1] == outs[2]
    assert run("other_seed", "1", "6") != outs[0]
    records = [json.loads(line) for line in outs[0].decode().splitlines()]
    assert [r["frame"] for r in records] == ["f0_L", "f1_L", "f2_L"]
    for r, z_box in zip(records, (2.5, 3.0, 3.5)):
        assert r["detector"] == "fixed_box" and len(r["objects"]) == 1
        car = r["objects"][0]
        assert car["label"] == "car" and car["status"] == "ok"
        assert car["distance_m"] == pytest.approx(z_box, rel=0.05)


def test_no_default_detector_hint_names_the_fetch_command(tmp_path, monkeypatch, capsys):
    from detectors import models

    monkeypatch.delenv("STEREO_CLASSIC_MODELS", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr(models, "packaged_model", lambda name="yolox_nano": None)  # an install without it

    def offline(name, **kwargs):
        raise OSError("network unreachable")

    monkeypatch.setattr(models, "download_model", offline)
    assert main(["run", "-o", str(tmp_path / "o"), "--scale", "0.25", "--save", "json"]) == 0
    captured = capsys.readouterr()
    hint = [line for line in captured.err.splitlines() if "no detector" in line]
    assert len(hint) == 1 and "python -m detectors fetch yolox_nano" in hint[0]
    assert captured.out.strip() == "depth only (no detector)"


def test_kernels_loaded_before_the_first_frame_with_the_runs_parameters(tmp_path, monkeypatch):
    # matching.load_kernels runs before the frame loop (whose clock a camera's first frame is measured by)
    from stereo_classic import checks, pipeline
    from stereo_classic.cli import run as run_cli

    order = []
    real_source = run_cli.run_source
    monkeypatch.setattr(pipeline, "load_kernels", lambda params: order.append(("load", params)))
    # the frame checks' two looks (after a cleared pair and not), whose ranges are their own (compiled per range)
    monkeypatch.setattr(checks, "load_kernels", lambda params: order.append(("look", params)))
    monkeypatch.setattr(run_cli, "run_source", lambda *a, **k: (order.append(("frames", None)),
                                                                real_source(*a, **k))[1])
    assert main(["run", "-o", str(tmp_path / "o"), "--scale", "0.25", "--save", "json", "--model", "none",
                 "--num-disparities", "48", "--paths", "4"]) == 0
    assert [step for step, _ in order] == ["load", "look", "look", "frames"]
    assert order[0][1].num_disparities == 48 and order[0][1].paths == 4
    checker = checks.FrameChecker(order[0][1])
    assert [p for _, p in order[1:3]] == [checker.look_params(True), checker.look_params(False)]
    assert {(p.min_disparity, p.num_disparities, p.cost, p.paths) for _, p in order[1:3]} == {
        (0, 48, "census", 4), (*checker.look_range(), "census", 4)}


def test_kernels_loaded_for_the_range_the_first_scene_is_matched_with(tmp_path, monkeypatch):
    # the demo's range comes with the scene (no --num-disparities): the kernels, compiled per range, are loaded for
    # the settings its frame is matched with, not for the command's default range
    from stereo_classic import pipeline, runner
    from stereo_classic.cli import run as run_cli

    loaded, matched = [], []
    monkeypatch.setattr(pipeline, "load_kernels", loaded.append)
    real = runner.Localizer
    monkeypatch.setattr(runner, "Localizer", lambda rig, det, params, **kw: (matched.append(params),
                                                                             real(rig, det, params, **kw))[1])
    assert main(["run", "-o", str(tmp_path / "o"), "--save", "json", "--model", "none"]) == 0
    assert len(loaded) == 1 and len(matched) == 1
    assert loaded[0] == matched[0]
    assert loaded[0].num_disparities != run_cli.CLI_NUM_DISPARITIES  # the scene's range, not the default
