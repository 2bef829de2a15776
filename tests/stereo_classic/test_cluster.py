"""stereo_classic.cluster: frames on a real Dask cluster (a local scheduler and two worker processes).

The proof of issue #14: the output folder of a Dask run equals the serial run's byte for byte, a worker killed
mid-run loses no frame and duplicates none, --resume works across executors, and without Dask installed
``--executor dask`` says in one line what to install.
"""

from __future__ import annotations

import json
import logging
import os
import signal
from pathlib import Path

import distributed
import pytest

from stereo_classic import io
from stereo_classic.cli import main
from stereo_classic.cluster import DaskExecutor
from stereo_classic.matching import SGMParams
from stereo_classic.outputs import FrameWriter
from stereo_classic.runner import run_source
from stereo_classic.sources import PairSource
from tests.helpers.scenes import make_rig, planted_scene


@pytest.fixture(scope="module")
def cluster():
    # The scheduler lives in this process; its log lines about the worker killed on purpose are expected, and
    # its handler may point at a capture stream pytest has closed: keep it quiet for the module.
    dask_log = logging.getLogger("distributed")
    level = dask_log.level
    dask_log.setLevel(logging.CRITICAL)
    try:
        with distributed.LocalCluster(processes=True, n_workers=2, threads_per_worker=1, dashboard_address=":0",
                                      silence_logs=logging.CRITICAL) as local:
            yield local
    finally:
        dask_log.setLevel(level)


def _folder(path: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(path.iterdir()) if p.name != ".stereo_classic.lock"}


def _params(max_disparity):
    return SGMParams(num_disparities=48)


@pytest.fixture(scope="module")
def pairs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("pairs")
    rig = make_rig(240, 160)
    files = []
    for i in range(12):
        left, right, _, _ = planted_scene(rig=rig, seed=i, z_box=2.0 + 0.2 * i)
        lp, rp = tmp / f"f{i:02d}_L.png", tmp / f"f{i:02d}_R.png"
        io.write_image(lp, left)
        io.write_image(rp, right)
        files.append((lp, rp))
    return files, rig


def test_dask_run_equals_the_serial_run_byte_for_byte(tmp_path, cluster, shared_data, capsys):
    models = os.environ.get("STEREO_CLASSIC_MODELS")
    model = "yolox_nano" if models and (Path(models) / "yolox_nano.onnx").is_file() else "none"
    base = ["-q", "run", "--dataset", str(shared_data), "--scale", "0.5", "--model", model]
    assert main([*base, "-o", str(tmp_path / "serial")]) == 0
    assert main([*base, "-o", str(tmp_path / "dask"), "--executor", "dask", "--scheduler",
                 cluster.scheduler_address]) == 0
    serial, dask = _folder(tmp_path / "serial"), _folder(tmp_path / "dask")
    assert len(serial) > 20 and serial.keys() == dask.keys()
    assert [name for name in serial if serial[name] != dask[name]] == []


def test_a_killed_worker_loses_no_frame_and_writes_none_twice(tmp_path, cluster, pairs):
    files, rig = pairs
    out = tmp_path / "o"
    client = distributed.Client(cluster)
    pids = client.run(os.getpid)
    killed = []

    def kill_one(frame, result):
        if not killed and frame.index >= 2:
            victim = min(pids.values())
            os.kill(victim, signal.SIGKILL)
            killed.append(victim)

    with DaskExecutor(cluster.scheduler_address) as executor:
        summary = run_source(PairSource(files), FrameWriter(out, sequence=True), params_for=_params, rig=rig,
                             executor=executor, on_frame=kill_one)
    client.close()
    names = [json.loads(line)["frame"] for line in (out / "objects.jsonl").read_text().splitlines()]
    assert killed and summary.frames == len(files) and not summary.interrupted
    assert names == [f"f{i:02d}_L" for i in range(len(files))]  # each once, in frame order
    serial = tmp_path / "serial"
    run_source(PairSource(files), FrameWriter(serial, sequence=True), params_for=_params, rig=rig)
    assert _folder(out) == _folder(serial)


def test_a_result_lost_after_it_finished_is_computed_again(tmp_path, cluster, pairs, monkeypatch):
    """The race the killed-worker test can hit: a frame finishes, then the worker holding its result dies and the
    scheduler forgets the key, so its future comes back cancelled. Made deterministic here (frame 3's first
    result raises that cancellation): the frame is submitted again, and the folder equals the serial run's."""
    import concurrent.futures

    files, rig = pairs
    real = distributed.Future.result
    lost = []

    def result(self, *args, **kwargs):
        if "stereo-frame-3-" in str(self.key) and not lost:
            lost.append(self.key)
            raise concurrent.futures.CancelledError(f"{self.key} cancelled for reason: already forgotten.")
        return real(self, *args, **kwargs)

    monkeypatch.setattr(distributed.Future, "result", result)
    out, serial = tmp_path / "o", tmp_path / "serial"
    with DaskExecutor(cluster.scheduler_address) as executor:
        summary = run_source(PairSource(files), FrameWriter(out, sequence=True), params_for=_params, rig=rig,
                             executor=executor)
    assert lost and summary.frames == len(files)
    run_source(PairSource(files), FrameWriter(serial, sequence=True), params_for=_params, rig=rig)
    assert _folder(out) == _folder(serial)


def test_a_result_lost_every_time_fails_the_run_and_says_so(tmp_path, cluster, pairs, monkeypatch):
    import concurrent.futures

    files, rig = pairs
    real = distributed.Future.result

    def result(self, *args, **kwargs):
        if "stereo-frame-1-" in str(self.key):
            raise concurrent.futures.CancelledError(f"{self.key} cancelled")
        return real(self, *args, **kwargs)

    monkeypatch.setattr(distributed.Future, "result", result)
    with DaskExecutor(cluster.scheduler_address) as executor, pytest.raises(RuntimeError, match="frame 1: its result"):
        run_source(PairSource(files), FrameWriter(tmp_path / "o", sequence=True), params_for=_params, rig=rig,
                   executor=executor)


def test_resume_across_executors(tmp_path, cluster, pairs):
    files, rig = pairs
    out, serial = tmp_path / "o", tmp_path / "serial"
    run_source(PairSource(files[:5]), FrameWriter(out, sequence=True), params_for=_params, rig=rig)
    with DaskExecutor(cluster.scheduler_address) as executor:
        summary = run_source(PairSource(files), FrameWriter(out, sequence=True, resume=True), params_for=_params,
                             rig=rig, executor=executor)
    assert (summary.frames, summary.skipped) == (len(files) - 5, 5)
    assert set(summary.workers) <= set(cluster.scheduler_info["workers"]) | {"local"}
    run_source(PairSource(files), FrameWriter(serial, sequence=True), params_for=_params, rig=rig)
    assert _folder(out) == _folder(serial)


def test_a_failing_frame_on_a_worker(tmp_path, cluster, pairs):
    files, rig = pairs
    broken = tmp_path / "broken_R.png"
    broken.write_bytes(b"not a png")
    mixed = [*files[:3], (files[3][0], broken), *files[4:6]]
    with DaskExecutor(cluster.scheduler_address) as executor:
        summary = run_source(PairSource(mixed), FrameWriter(tmp_path / "skip", sequence=True), params_for=_params,
                             rig=rig, executor=executor, on_error="skip")
        assert summary.frames == 5 and [name for name, _ in summary.failed] == ["f03_L"]
        with pytest.raises(ValueError, match="broken_R.png"):
            run_source(PairSource(mixed), FrameWriter(tmp_path / "stop", sequence=True), params_for=_params,
                       rig=rig, executor=executor)


def test_ctrl_c_cancels_the_cluster_run_and_leaves_no_partial_frame(tmp_path, cluster, pairs):
    files, rig = pairs
    out = tmp_path / "o"

    def interrupt_after_three(frame, result):
        if frame.index == 2:
            raise KeyboardInterrupt

    with DaskExecutor(cluster.scheduler_address) as executor:
        summary = run_source(PairSource(files), FrameWriter(out, sequence=True), params_for=_params, rig=rig,
                             executor=executor, on_frame=interrupt_after_three)
        assert summary.interrupted and summary.frames == 3
        names = {p.name.split("_")[0] for p in out.iterdir() if p.name != "objects.jsonl"}
        assert names == {"f00", "f01", "f02"} and not [p for p in out.iterdir() if p.name.endswith(".tmp")]
        again = run_source(PairSource(files), FrameWriter(out, sequence=True, resume=True), params_for=_params,
                           rig=rig, executor=executor)
    assert (again.frames, again.skipped) == (len(files) - 3, 3)


def test_importing_distributed_keeps_the_level_the_command_line_set():
    """Issue 34: `run` sets the `distributed` logger to WARNING (unless -v); importing distributed sets its own INFO
    (about 50 lines a run), so the import restores the caller's level. A fresh process: here it is imported."""
    import subprocess
    import sys

    code = ("import logging; logging.getLogger('distributed').setLevel(logging.WARNING); "
            "from stereo_classic.cluster import import_distributed; import_distributed(); "
            "print(logging.getLogger('distributed').level)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          cwd=Path(__file__).resolve().parents[2])
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == str(logging.WARNING)
