"""``python -m stereo_classic guide`` in-process on a rendered walk: events.jsonl, pictures, speech, bad input."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from stereo_classic import sources
from stereo_classic.cli import main
from stereo_classic.guide import speech
from tests.helpers import walk_scenes as ws

BASE = ["--model", "none", "--num-disparities", "64"]


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    """Six frames of a box coming at 1 m/s (PNG pairs) and the rig as OpenCV YAML."""
    root = tmp_path_factory.mktemp("walk")
    frames, rig = ws.approach(n=6)
    for i, (left, right, _, _) in enumerate(frames):
        cv2.imwrite(str(root / f"l_{i:02d}.png"), left)
        cv2.imwrite(str(root / f"r_{i:02d}.png"), right)
    rig.to_opencv_yaml(root / "rig.yaml")
    return root


def _args(walk, out, *more):
    return ["guide", "--left", str(walk / "l_*.png"), "--right", str(walk / "r_*.png"), "--calib",
            str(walk / "rig.yaml"), "-o", str(out), *BASE, *more]


def _lines(out):
    return [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]


def test_events_pictures_and_haptics(walk, tmp_path, capsys):
    out = tmp_path / "g"
    assert main(_args(walk, out, "--fps", "10", "--save", "overlay,birdseye")) == 0
    lines = _lines(out)
    haptics = [r for r in lines if r["kind"] == "haptics"]
    events = [r for r in lines if r["kind"] != "haptics"]
    assert len(haptics) == 6 and all(len(r["intensity"]) == 5 for r in haptics)
    assert haptics[-1]["ground"]["height_m"] == pytest.approx(1.2, abs=0.05)
    first = events[0]
    assert set(first) >= {"frame", "time_s", "kind", "label", "track_id", "distance_m", "nearest_m", "clock",
                          "bearing_deg", "approach_mps", "ttc_s", "priority", "text"}
    assert (first["kind"], first["clock"], first["track_id"]) == ("obstacle", 12, 1)
    assert first["nearest_m"] == pytest.approx(3.0, rel=0.1)
    assert "obstacle, 12 o'clock" in capsys.readouterr().out
    pictures = sorted(p.name for p in out.glob("*.png"))
    assert len(pictures) == 12 and pictures[0] == "l_00_birdseye.png"
    assert cv2.imread(str(out / "l_05_overlay.png")).shape == (240, 320, 3)


def test_feet_and_words(walk, tmp_path):
    out = tmp_path / "g"
    assert main(_args(walk, out, "--units", "feet", "--directions", "leftright", "--max-frames", "2")) == 0
    texts = [r["text"] for r in _lines(out) if r["kind"] != "haptics"]
    assert texts[0] == "obstacle, ahead, 10 feet"


def test_speak_to_writes_a_wav_per_message(walk, tmp_path, monkeypatch):
    class Engine:
        name = "stand-in"

        def say(self, text, *, interrupt):
            pass

        def to_wav(self, text, path):
            path.write_bytes(b"RIFF")

        def close(self):
            pass

    monkeypatch.setattr(speech, "find_engine", lambda: Engine())
    out = tmp_path / "g"
    assert main(_args(walk, out, "--speak-to", str(tmp_path / "wav"), "--camera-height", "1.2",
                      "--camera-pitch", "10")) == 0
    events = [r for r in _lines(out) if r["kind"] != "haptics"]
    assert len(list((tmp_path / "wav").glob("*.wav"))) == len(events) >= 1


def test_no_speech_engine_is_one_line_and_not_a_failure(walk, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(speech, "find_engine", lambda: None)
    assert main(_args(walk, tmp_path / "g", "--speak", "--max-frames", "2")) == 0
    assert [line for line in capsys.readouterr().err.splitlines() if "text-to-speech" in line] == [speech.INSTALL_HINT]


@pytest.mark.parametrize("more, message", [
    (["--camera-height", "40"], "--camera-height must be between"),
    (["--fps", "0"], "--fps must be"),
    (["--save", "boxes"], "--save: unknown picture 'boxes'"),
    (["--corridor-width", "-1"], "--corridor-width must be > 0"),
])
def test_bad_options_are_usage_errors(walk, tmp_path, capsys, more, message):
    assert main(_args(walk, tmp_path / "g", *more)) == 2
    assert message in capsys.readouterr().err


def test_missing_calibration_and_mixed_sizes(walk, tmp_path, capsys):
    assert main(["guide", "--left", str(walk / "l_00.png"), "--right", str(walk / "r_00.png"), *BASE]) == 2
    assert "--left needs --calib" in capsys.readouterr().err
    small = tmp_path / "small"
    small.mkdir()
    for i in range(2):
        for side in "lr":
            img = cv2.imread(str(walk / f"{side}_{i:02d}.png"))
            cv2.imwrite(str(small / f"{side}_{i:02d}.png"), img if i == 0 else cv2.resize(img, (160, 120)))
    out = tmp_path / "g"
    code = main(["guide", "--left", str(small / "l_*.png"), "--right", str(small / "r_*.png"), "--calib",
                 str(walk / "rig.yaml"), "-o", str(out), *BASE])
    err = capsys.readouterr().err
    assert code == 1 and "frame l_01" in err and "320x240" in err
    assert [r["frame"] for r in _lines(out) if r["kind"] == "haptics"] == ["l_00"]   # the first frame is whole


def test_a_camera_that_stops_ends_with_an_error(walk, tmp_path, monkeypatch, capsys):
    pair = np.hstack([cv2.imread(str(walk / "l_00.png")), cv2.imread(str(walk / "r_00.png"))])

    class Capture:
        def __init__(self, index):
            self.left = 3

        def isOpened(self):
            return True

        def read(self):
            self.left -= 1
            return (True, pair.copy()) if self.left >= 0 else (False, None)

        def get(self, prop):
            return 0.0

        def release(self):
            pass

    monkeypatch.setattr(sources.cv2, "VideoCapture", Capture)
    out = tmp_path / "g"
    code = main(["guide", "--camera", "0", "--calib", str(walk / "rig.yaml"), "-o", str(out), *BASE])
    assert code == 1 and "stopped delivering frames after 3 frame(s)" in capsys.readouterr().err
    assert len([r for r in _lines(out) if r["kind"] == "haptics"]) == 3


def test_config_file_options(walk, tmp_path):
    config = tmp_path / "guide.toml"
    config.write_text('model = "none"\nmax_frames = 2\n\n[matcher]\nnum_disparities = 64\n')
    out = tmp_path / "g"
    code = main(["guide", "--left", str(walk / "l_*.png"), "--right", str(walk / "r_*.png"), "--calib",
                 str(walk / "rig.yaml"), "-o", str(out), "--config", str(config)])
    assert code == 0 and len([r for r in _lines(out) if r["kind"] == "haptics"]) == 2


def test_vertical_lines_in_the_events(tmp_path):
    """Stairs up seen from their bottom (rendered): the haptics line says which way is up (the camera looks up
    25 degrees) and that there is no ground; ``--no-vertical-lines`` turns the measurement off."""
    left, right, _, rig = ws.render(ws.stairs_up(0.8), supersample=1, cam_height=1.5, pitch_deg=-25.0)
    for side, img in (("l", left), ("r", right)):
        for i in range(2):
            cv2.imwrite(str(tmp_path / f"{side}_{i:02d}.png"), img)
    rig.to_opencv_yaml(tmp_path / "rig.yaml")
    args = ["guide", "--left", str(tmp_path / "l_*.png"), "--right", str(tmp_path / "r_*.png"), "--calib",
            str(tmp_path / "rig.yaml"), *BASE]
    assert main([*args, "-o", str(tmp_path / "on")]) == 0
    haptics = [r for r in _lines(tmp_path / "on") if r["kind"] == "haptics"]
    assert [r["ground"] for r in haptics] == [None, None]
    assert all(r["gravity"]["pitch_deg"] == pytest.approx(-25.0, abs=1.5) for r in haptics)
    assert any("looks up" in n for n in haptics[0]["notes"])
    assert main([*args, "-o", str(tmp_path / "off"), "--no-vertical-lines"]) == 0
    assert all(r["gravity"] is None for r in _lines(tmp_path / "off") if r["kind"] == "haptics")


def test_pipelined_and_in_turn_give_the_same_events_and_pictures(walk, tmp_path, capsys):
    """--pipeline (the default: frame N guided once N + 1 is matched) and --no-pipeline: the same bytes, and the
    run ends with its wall-clock frames/s."""
    outs = {}
    for flag in ("--pipeline", "--no-pipeline"):
        out = tmp_path / flag
        assert main(_args(walk, out, "--fps", "10", "--save", "overlay,birdseye", flag)) == 0
        err = capsys.readouterr().err
        assert "6 frame(s) in" in err and "frames/s (wall clock of the whole frame loop" in err
        assert "; after the first frame (" in err  # the rate without the one-time loading of the first frame
        outs[flag] = {p.name: p.read_bytes() for p in sorted(out.iterdir())}
    assert outs["--pipeline"] == outs["--no-pipeline"] and len(outs["--pipeline"]) == 13


def test_kernels_loaded_before_the_first_frame(walk, tmp_path, monkeypatch):
    from stereo_classic.cli import guide as guide_cli
    from stereo_classic.pipeline import Localizer

    loaded = []

    def localizer(*args, **kwargs):
        assert loaded, "a frame began before the kernels were loaded"
        return Localizer(*args, **kwargs)

    from stereo_classic import checks, pipeline

    monkeypatch.setattr(pipeline, "load_kernels", lambda params: loaded.append(params))
    monkeypatch.setattr(checks, "load_kernels", lambda params: loaded.append(params))  # the checks' two looks
    monkeypatch.setattr(guide_cli, "Localizer", localizer)
    assert main(_args(walk, tmp_path / "g")) == 0
    checker = checks.FrameChecker(loaded[0])
    assert loaded == [loaded[0], checker.look_params(True), checker.look_params(False)]
    assert loaded[0].num_disparities == 64
