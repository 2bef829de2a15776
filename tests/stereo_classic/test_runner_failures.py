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


def test_ctrl_c_during_a_write_counts_the_written_frame(tmp_path, pairs, monkeypatch, sigint_delivered):
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


def test_a_ctrl_c_discarded_where_it_was_raised_still_ends_the_run(tmp_path, pairs, monkeypatch, sigint_delivered):
    # A KeyboardInterrupt is raised wherever the main thread is; inside a finalizer (__del__, a file closed by the
    # garbage collector) Python discards it. The run remembers the signal and ends at the next frame boundary.
    from stereo_classic import pipeline

    files, rig, _ = pairs
    out = tmp_path / "o"
    real_call = pipeline.Localizer._rectified
    seen = {"n": 0, "discarded": False}

    def discard_on_second(self, left, right):
        seen["n"] += 1
        if seen["n"] == 2:
            try:  # what a finalizer does to an exception raised in it
                os.kill(os.getpid(), signal.SIGINT)
                for _ in range(10**7):  # the handler runs at the next check of the loop (bounded, never reached)
                    pass
            except KeyboardInterrupt:
                seen["discarded"] = True
        return real_call(self, left, right)

    monkeypatch.setattr(pipeline.Localizer, "_rectified", discard_on_second)
    summary = run_source(PairSource(files), FrameWriter(out, sequence=True), params_for=_params, rig=rig)
    assert seen["discarded"]
    assert summary.interrupted and summary.signal == "SIGINT"
    assert summary.frames == 1 and _lines(out) == ["f0_L"] and not list(out.glob("f1_L*"))


def test_a_run_leaves_an_applications_sigint_handler_alone_and_restores_sigterm(tmp_path, pairs, monkeypatch):
    from stereo_classic import pipeline

    files, rig, _ = pairs
    calls = []

    def mine(signum, frame):
        calls.append(signum)

    previous = signal.signal(signal.SIGINT, mine)
    term_before = signal.getsignal(signal.SIGTERM)
    real_call = pipeline.Localizer._rectified
    during = []

    def look(self, left, right):
        during.append((signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)))
        return real_call(self, left, right)

    monkeypatch.setattr(pipeline.Localizer, "_rectified", look)
    try:
        summary = run_source(PairSource(files[:2]), FrameWriter(tmp_path / "o", sequence=True), params_for=_params,
                             rig=rig)
        assert summary.frames == 2 and not summary.interrupted
        assert all(i is mine for i, _ in during) and all(t is not term_before for _, t in during)
        assert signal.getsignal(signal.SIGINT) is mine and signal.getsignal(signal.SIGTERM) is term_before
    finally:
        signal.signal(signal.SIGINT, previous)


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
