"""--dataset streams: scenes are described up front and read when processed; memory does not grow with them."""

from __future__ import annotations

import logging
import os
import shutil
import subprocess
import sys

from stereo_classic.cli import main


def _dataset(root, oakd, n, *, lonely=False, corrupt=None):
    root.mkdir(parents=True)
    shutil.copy(oakd / "stereodemo_calibration.json", root)
    for i in range(n):
        for side in ("left", "right"):
            target = root / f"s{i:04d}_{side}.png"
            if i == corrupt and side == "right":
                target.write_bytes(b"not a png")
            else:
                target.symlink_to(oakd / f"desk_{side}.png")
    if lonely:
        (root / "lonely_left.png").symlink_to(oakd / "desk_left.png")
    return root


def test_a_dataset_is_described_not_read(tmp_path, shared_data, monkeypatch, caplog):
    from stereo_classic.datasets import discovery
    from stereo_classic.sources import SceneSource

    root = _dataset(tmp_path / "d", shared_data / "oakd", 50, lonely=True)
    reads = []
    real = discovery.load_oakd
    monkeypatch.setattr(discovery, "load_oakd", lambda d, n: reads.append(n) or real(d, n))
    with caplog.at_level(logging.WARNING):
        source = SceneSource.from_folder(root)
    assert len(source) == 50 and reads == ["s0000"]  # one scene read, to check the dataset has a calibration
    assert "lonely_left.png: a left image without a right image (lonely_right.png)" in caplog.text
    refs = list(source.refs(lambda name: name != "s0007"))
    assert [r.name for r in refs] == ["s0007"] and reads == ["s0000"]
    assert refs[0].read().left.shape == (480, 640, 3) and reads == ["s0000", "s0007"]


def test_corrupt_and_uncalibrated_scenes_are_named_and_the_dataset_goes_on(tmp_path, shared_data, capsys):
    root = tmp_path / "data"
    _dataset(root / "a_cal", shared_data / "oakd", 3, corrupt=1)
    plain = root / "b_plain"
    plain.mkdir()
    for side in ("left", "right"):
        (plain / f"pair_{side}.png").symlink_to(shared_data / "oakd" / f"desk_{side}.png")
    argv = ["run", "--dataset", str(root), "--model", "none", "--scale", "0.25", "--save", "json"]
    assert main([*argv, "-o", str(tmp_path / "stop")]) == 1  # default: the corrupt scene stops the run
    assert "s0001_right.png" in capsys.readouterr().err
    assert main([*argv, "-o", str(tmp_path / "skip"), "--on-error", "skip"]) == 1
    err = capsys.readouterr().err
    assert "frame s0001 failed and is skipped" in err and "s0001_right.png" in err
    assert "scene pair" in err and "has no calibration" in err
    assert "2 frame(s)" in err and "1 frame(s) FAILED" in err and "1 scene(s) not measured" in err
    assert len((tmp_path / "skip" / "objects.jsonl").read_text().splitlines()) == 2


# The peak resident memory of the run itself: the kernels are loaded (or, when their numba cache is missing or was
# overwritten by another process, compiled: LLVM alone can take several hundred MB) before the peak is reset.
_PEAK = """
import sys
import numpy as np
import stereo_classic as sc
from stereo_classic.cli import main
pair = np.random.default_rng(0).integers(0, 255, (60, 80), dtype=np.uint8)
sc.compute_disparity(pair, pair.copy(), num_disparities=16, threads=1)
with open("/proc/self/clear_refs", "w") as fh:
    fh.write("5")  # reset VmHWM, the peak resident set
rc = main(sys.argv[1:])
with open("/proc/self/status") as fh:
    print(next(int(line.split()[1]) for line in fh if line.startswith("VmHWM")) // 1024)
sys.exit(rc)
"""


def _peak_mb(root, out):
    argv = ["-q", "run", "--dataset", str(root), "--model", "none", "--scale", "0.25", "--save", "json",
            "--threads", "1", "-o", str(out)]
    done = subprocess.run([sys.executable, "-c", _PEAK, *argv], check=False, capture_output=True, text=True,
                          timeout=600, env={**os.environ, "NUMBA_NUM_THREADS": "1"})
    assert done.returncode in (0, 1), done.stderr  # 1: frames flagged by the pair checks (still written)
    return int(done.stdout.split()[-1])


def test_memory_does_not_grow_with_the_number_of_frames(tmp_path, shared_data):
    # 300 scenes of 640x480: reading them all first (as before) needed ~550 MB of images alone.
    few = _peak_mb(_dataset(tmp_path / "few", shared_data / "oakd", 20), tmp_path / "o_few")
    many = _peak_mb(_dataset(tmp_path / "many", shared_data / "oakd", 300), tmp_path / "o_many")
    assert len((tmp_path / "o_many" / "objects.jsonl").read_text().splitlines()) == 300
    assert many < 400, f"peak RSS {many} MB over 300 frames"
    assert many - few < 40, f"peak RSS {few} MB over 20 frames but {many} MB over 300"
