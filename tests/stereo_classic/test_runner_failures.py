"""stereo_classic.runner when things go wrong: corrupt frames (--on-error), Ctrl-C during a write, SIGTERM."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from stereo_classic import io
from stereo_classic.cli import main
from stereo_classic.matching import SGMParams
from stereo_classic.outputs import FrameWriter
from stereo_classic.runner import run_source
from stereo_classic.sources import PairSource
from tests.helpers.scenes import make_rig, planted_scene


def _params(max_disparity):
    return SGMParams(num_disparities=48)


@pytest.fixture()
def pairs(tmp_path):
    rig = make_rig(240, 160)
    files = []
    for i in range(4):
        left, right, _, _ = planted_scene(rig=rig, seed=i, z_box=2.5 + 0.3 * i)
        lp, rp = tmp_path / f"f{i}_L.png", tmp_path / f"f{i}_R.png"
        io.write_image(lp, left)
        io.write_image(rp, right)
        files.append((lp, rp))
    calib = tmp_path / "rig.yaml"
    rig.to_opencv_yaml(calib)
    return files, rig, calib


def _lines(out):
    return [json.loads(line)["frame"] for line in (out / "objects.jsonl").read_text().splitlines()]


def test_on_error_skip_records_the_corrupt_frame_and_goes_on(tmp_path, pairs):
    files, rig, _ = pairs
    files[1][1].write_bytes(b"not a png")
    out = tmp_path / "o"
    summary = run_source(PairSource(files), FrameWriter(out, sequence=True), params_for=_params, rig=rig,
                         on_error="skip")
    assert summary.frames == 3 and [name for name, _ in summary.failed] == ["f1_L"]
    assert "f1_R.png" in summary.failed[0][1]
    assert _lines(out) == ["f0_L", "f2_L", "f3_L"] and not list(out.glob("f1_L*"))
    with pytest.raises(ValueError, match="f1_R.png"):  # the default: stop, with the file named
        run_source(PairSource(files), FrameWriter(tmp_path / "s", sequence=True), params_for=_params, rig=rig)
    with pytest.raises(ValueError, match="`on_error` must be one of stop, skip"):
        run_source(PairSource(files), FrameWriter(tmp_path / "x"), params_for=_params, rig=rig, on_error="ignore")


def test_on_error_skip_on_the_command_line_names_the_frame_and_exits_1(tmp_path, pairs, capsys):
    files, _, calib = pairs
    files[2][0].write_bytes(b"")
    argv = ["run", "--left", *[str(p[0]) for p in files], "--right", *[str(p[1]) for p in files],
            "--calib", str(calib), "--model", "none", "--num-disparities", "48", "-o", str(tmp_path / "o")]
    assert main([*argv, "--on-error", "skip"]) == 1
    err = capsys.readouterr().err
    assert "1 frame(s) FAILED and skipped (--on-error skip): f2_L" in err and "3 frame(s)" in err
    assert _lines(tmp_path / "o") == ["f0_L", "f1_L", "f3_L"]


def test_ctrl_c_during_a_write_counts_the_written_frame(tmp_path, pairs, monkeypatch):
    files, rig, _ = pairs
    out = tmp_path / "o"
    writer = FrameWriter(out, sequence=True)
    real_write = writer.write

    def write_then_ctrl_c(name, *args):
        written = real_write(name, *args)
        if name == "f1_L":
            os.kill(os.getpid(), signal.SIGINT)  # held until the frame is complete
        return written

    monkeypatch.setattr(writer, "write", write_then_ctrl_c)
    summary = run_source(PairSource(files), writer, params_for=_params, rig=rig)
    assert summary.interrupted and summary.signal == "SIGINT"
    assert summary.frames == len(_lines(out)) == 2


_SCRIPT = """
import sys
from stereo_classic.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_sigterm_is_handled_like_ctrl_c(tmp_path, pairs):
    files, _, calib = pairs
    many = [files[i % len(files)] for i in range(40)]  # the same pairs under 40 names: long enough to stop
    for i, (lp, rp) in enumerate(many):
        (tmp_path / f"g{i:02d}_L.png").symlink_to(lp)
        (tmp_path / f"g{i:02d}_R.png").symlink_to(rp)
    out = tmp_path / "o"
    argv = ["run", "--left", str(tmp_path / "g*_L.png"), "--right", str(tmp_path / "g*_R.png"), "--calib",
            str(calib), "--model", "none", "--num-disparities", "48", "-o", str(out)]
    proc = subprocess.Popen([sys.executable, "-c", _SCRIPT, *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env={**os.environ, "NUMBA_NUM_THREADS": "1"})
    jsonl = out / "objects.jsonl"
    deadline = time.monotonic() + 120  # a bound on waiting, not a timed assertion
    while time.monotonic() < deadline and proc.poll() is None:
        if jsonl.is_file() and len(jsonl.read_text().splitlines()) >= 2:
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    if proc.returncode == 0:
        pytest.skip("the run finished before SIGTERM arrived")
    assert proc.returncode == 143, err
    written = len(_lines(out))
    assert f"terminated (SIGTERM): {written} frame(s)" in err
    assert not [p.name for p in out.iterdir() if p.name.endswith(".tmp")]
    assert main(["-q", "run", *argv[1:], "--resume"]) == 0
    assert sorted(_lines(out)) == [f"g{i:02d}_L" for i in range(40)]
