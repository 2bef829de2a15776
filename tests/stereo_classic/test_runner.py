"""stereo_classic.runner: the pipeline over a source into a folder, as a library (what `run` does)."""

from __future__ import annotations

import json

import pytest

from stereo_classic import io, pipeline
from stereo_classic.cli import main
from stereo_classic.matching import SGMParams
from stereo_classic.outputs import FrameWriter
from stereo_classic.runner import RunSummary, run_source, scale_pair
from stereo_classic.sources import PairSource
from tests.helpers.scenes import make_rig, planted_scene
from tests.helpers.detectors import FixedBoxes


@pytest.fixture()
def pairs(tmp_path):
    rig = make_rig(240, 160)
    files = []
    for i in range(2):
        left, right, _, _ = planted_scene(rig=rig, seed=i, z_box=2.5 + 0.5 * i)
        lp, rp = tmp_path / f"f{i}_L.png", tmp_path / f"f{i}_R.png"
        io.write_image(lp, left)
        io.write_image(rp, right)
        files.append((lp, rp))
    return files, rig


def _params(max_disparity):
    return SGMParams(num_disparities=48)


def test_library_run_writes_what_the_command_writes(tmp_path, pairs):
    files, rig = pairs
    out_lib = tmp_path / "lib"
    summary = run_source(PairSource(files), FrameWriter(out_lib, sequence=True), params_for=_params, rig=rig)
    assert (summary.frames, summary.skipped, summary.interrupted) == (2, 0, False)
    assert len(summary.timings_ms) == 2
    calib_file = tmp_path / "rig.yaml"
    rig.to_opencv_yaml(calib_file)
    out_cli = tmp_path / "cli"
    argv = ["-q", "run", "--left", *[str(p[0]) for p in files], "--right", *[str(p[1]) for p in files],
            "--calib", str(calib_file), "--model", "none", "--num-disparities", "48", "-o", str(out_cli)]
    assert main(argv) == 0
    run_files = ("run.json", ".stereo_classic.lock")  # the command's record of the run (OutputFolder)
    assert sorted(p.name for p in out_lib.iterdir()) == sorted(
        p.name for p in out_cli.iterdir() if p.name not in run_files)
    for name in ("f0_L_disparity.pfm", "f1_L_disparity_kitti.png", "f0_L_depth.png"):
        assert (out_lib / name).read_bytes() == (out_cli / name).read_bytes()
    lib_lines = [json.loads(line) for line in (out_lib / "objects.jsonl").read_text().splitlines()]
    cli_lines = [json.loads(line) for line in (out_cli / "objects.jsonl").read_text().splitlines()]
    assert lib_lines == cli_lines


def test_resume_skips_finished_frames_and_ctrl_c_is_a_summary(tmp_path, pairs, monkeypatch):
    files, rig = pairs
    out = tmp_path / "o"
    real_call = pipeline.Localizer._rectified
    calls = {"n": 0}

    def interrupt_on_second(self, left, right):
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        return real_call(self, left, right)

    monkeypatch.setattr(pipeline.Localizer, "_rectified", interrupt_on_second)
    first = run_source(PairSource(files), FrameWriter(out, sequence=True), params_for=_params, rig=rig)
    assert (first.frames, first.interrupted) == (1, True)
    assert not list(out.glob("f1_L*"))
    monkeypatch.setattr(pipeline.Localizer, "_rectified", real_call)
    again = run_source(PairSource(files), FrameWriter(out, sequence=True, resume=True), params_for=_params, rig=rig)
    assert (again.frames, again.skipped, again.interrupted) == (1, 1, False)
    assert len((out / "objects.jsonl").read_text().splitlines()) == 2


def test_scale_and_errors(tmp_path, pairs):
    files, rig = pairs
    seen = []
    summary = run_source(PairSource(files[:1]), FrameWriter(tmp_path, save=("pfm",)), params_for=_params, rig=rig,
                         scale=0.5, on_frame=lambda frame, result: seen.append(result.disparity.disparity.shape))
    assert summary == RunSummary(frames=1, objects=0, skipped=0, interrupted=False, timings_ms=summary.timings_ms,
                                 first_written=summary.first_written)
    assert summary.first_written is not None
    assert seen == [(80, 120)]
    with pytest.raises(ValueError, match="no calibration"):
        run_source(PairSource(files[:1]), FrameWriter(tmp_path / "x"), params_for=_params)
    left = io.read_image(files[0][0])
    with pytest.raises(ValueError, match="calibration is for 240x160"):
        scale_pair(left[:100], left[:100], rig, (120, 80))


def test_records_name_the_source_files_and_scaled_runs_report_input_pixels(tmp_path, pairs):
    from tests.helpers.detectors import FixedBoxes

    files, rig = pairs
    detector = FixedBoxes([(20, 15, 60, 45)], names=("box",), confidence=0.9)
    records = {}
    for scale in (1.0, 0.5):
        out = tmp_path / f"s{scale}"
        run_source(PairSource(files[:1]), FrameWriter(out, save=("json",)), params_for=_params, rig=rig,
                   detector=detector, detector_name="fixed", scale=scale)
        records[scale] = json.loads((out / "f0_L_objects.json").read_text())
    full, half = records[1.0], records[0.5]
    assert full["source"] == half["source"] == {"left": str(files[0][0]), "right": str(files[0][1])}
    assert full["image_size"] == half["image_size"] == [240, 160] and half["processed_size"] == [120, 80]
    # FixedBoxes returns the same pixel box for any image: at half size it covers twice the input pixels
    assert full["objects"][0]["box_xyxy"] == [20.0, 15.0, 60.0, 45.0]
    assert half["objects"][0]["box_xyxy"] == [40.0, 30.0, 120.0, 90.0]


# --------------------------------------------------------------------------------------------------
# overlap: frame N is written while frame N + 1 is matched
# --------------------------------------------------------------------------------------------------
class _Processor:
    def __init__(self, started_writing, fail_at=None):
        self.started_writing, self.fail_at, self.seen_write_while_processing = started_writing, fail_at, []

    def process_ref(self, ref):
        if ref > 0:  # frame ref is processed while frame ref - 1 is being written
            self.seen_write_while_processing.append(self.started_writing[ref - 1].wait(timeout=30))
        return ref


def test_frames_are_written_while_the_next_is_processed_in_order():
    import threading

    from stereo_classic.runner import _run_overlapped

    started = [threading.Event() for _ in range(4)]
    release = [threading.Event() for _ in range(4)]
    written = []
    proc = _Processor(started)

    def take(out):
        started[out].set()
        if out < 3:
            # the write of frame `out` only finishes once frame out + 1 has been processed: proves the overlap
            release[out].wait(timeout=30)
        written.append(out)

    def process_ref(ref):
        out = proc.process_ref(ref)
        if ref > 0:
            release[ref - 1].set()
        return out

    proc_wrapper = type("P", (), {"process_ref": staticmethod(process_ref)})()
    _run_overlapped(iter(range(4)), proc_wrapper, take)
    assert written == [0, 1, 2, 3]
    assert proc.seen_write_while_processing == [True, True, True]


def test_a_failing_write_stops_the_run_with_its_error():
    from stereo_classic.runner import _run_overlapped

    def take(out):
        if out == 1:
            raise OSError("disk full")

    proc = type("P", (), {"process_ref": staticmethod(lambda ref: ref)})()
    with pytest.raises(OSError, match="disk full"):
        _run_overlapped(iter(range(5)), proc, take)


def test_reading_ahead_writes_the_same_bytes_and_reads_in_its_own_thread(tmp_path, pairs, monkeypatch):
    """The next frame is read in the reader thread while one is processed; the folder is the same byte for byte as
    reading each frame when processed, and a frame that cannot be read is still that frame's failure."""
    import threading

    from stereo_classic import sources

    files, rig = pairs
    bad = (tmp_path / "c_L.png", tmp_path / "c_R.png")
    bad[0].write_bytes(files[0][0].read_bytes())
    bad[1].write_bytes(b"not a png")
    last = (tmp_path / "d_L.png", tmp_path / "d_R.png")
    for src, dst in zip(files[0], last):
        dst.write_bytes(src.read_bytes())
    files = files + [bad, last]
    readers = []
    real = sources._read_pair
    monkeypatch.setattr(sources, "_read_pair",
                        lambda *a: readers.append(threading.current_thread().name) or real(*a))
    outs = {}
    for ahead, pipelined in ((False, False), (True, False), (False, True), (True, True)):
        readers.clear()
        out = tmp_path / f"ahead_{ahead}_{pipelined}"
        summary = run_source(PairSource(files), FrameWriter(out, sequence=True, save=("json", "pfm")),
                             params_for=_params, rig=rig, detector=FixedBoxes([[20, 15, 60, 45]]),
                             detector_name="fixed", on_error="skip", read_ahead=ahead, pipeline=pipelined)
        assert (summary.frames, [name for name, _ in summary.failed]) == (3, ["c_L"])
        assert all(n.startswith("stereo-reader") == ahead for n in readers) and len(readers) == 4
        outs[ahead, pipelined] = {p.name: p.read_bytes() for p in sorted(out.iterdir())}
    assert len(set(map(str, outs.values()))) == 1 and len(outs[True, True]) > 3
    assert b'"box_xyxy"' in outs[True, True]["objects.jsonl"]  # the detector's objects are in it


def test_pipelined_run_hands_on_the_frame_before_a_failure_or_ctrl_c(tmp_path, pairs, monkeypatch):
    """A frame that fails to start (on_error stop), or Ctrl-C while it starts, comes after the frame before it is
    written: the folder holds what processing in turn leaves."""
    from stereo_classic import pipeline

    files, rig = pairs
    real = pipeline.Localizer._rectified
    for what in (ValueError, KeyboardInterrupt):
        calls = {"n": 0}

        def fail_on_third(self, left, right, what=what, calls=calls):
            calls["n"] += 1
            if calls["n"] == 3:
                raise what("third frame")
            return real(self, left, right)

        monkeypatch.setattr(pipeline.Localizer, "_rectified", fail_on_third)
        out = tmp_path / what.__name__
        if what is ValueError:
            with pytest.raises(ValueError, match="third frame"):
                run_source(PairSource(files * 2), FrameWriter(out, sequence=True), params_for=_params, rig=rig)
        else:
            summary = run_source(PairSource(files * 2), FrameWriter(out, sequence=True), params_for=_params,
                                 rig=rig)
            assert summary.interrupted and summary.frames == 2
        lines = (out / "objects.jsonl").read_text().splitlines()
        assert [json.loads(line)["index"] for line in lines] == [0, 1]


def test_read_ahead_on_the_command_line_writes_the_same_files(tmp_path, pairs):
    files, rig = pairs
    calib_file = tmp_path / "rig.yaml"
    rig.to_opencv_yaml(calib_file)
    outs = {}
    for flag in ("--read-ahead", "--no-read-ahead", "--no-pipeline"):
        out = tmp_path / flag
        argv = ["-q", "run", "--left", *[str(p[0]) for p in files], "--right", *[str(p[1]) for p in files],
                "--calib", str(calib_file), "--model", "none", "--num-disparities", "48", flag, "-o", str(out)]
        assert main(argv) == 0
        outs[flag] = {p.name: p.read_bytes() for p in sorted(out.iterdir()) if p.name != ".stereo_classic.lock"}
    assert outs["--read-ahead"] == outs["--no-read-ahead"] == outs["--no-pipeline"]
    assert "objects.jsonl" in outs["--read-ahead"]
