"""``python -m stereo_classic disparity``: files written, options passed through, usage errors."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from stereo_classic.cli import disparity as disparity_command
from stereo_classic.cli import main


@pytest.fixture
def pair_files(tmp_path):
    rng = np.random.default_rng(7)
    right = rng.integers(0, 256, (40, 90, 3), dtype=np.uint8)
    left = np.roll(right, 6, axis=1)
    lp, rp = tmp_path / "left.png", tmp_path / "right.png"
    cv2.imwrite(str(lp), left)
    cv2.imwrite(str(rp), right)
    return lp, rp


def _read_pfm(path):
    from stereo_classic.io import read_pfm

    return read_pfm(path)


def test_writes_pfm_and_png(pair_files, tmp_path, capsys):
    lp, rp = pair_files
    out = tmp_path / "out.pfm"
    assert main(["disparity", str(lp), str(rp), "-o", str(out), "--num-disparities", "16"]) == 0
    disp = _read_pfm(out)
    assert disp.shape == (40, 90) and disp.dtype == np.float32
    inner = disp[6:-6, 22:-6]
    assert np.nanmedian(np.abs(inner - 6.0)) < 0.05
    png = cv2.imread(str(tmp_path / "out.png"))
    assert png.shape == (40, 90, 3)
    captured = capsys.readouterr()
    assert captured.out.startswith("valid pixels") and len(captured.out.splitlines()) == 1  # the data on stdout
    assert "total" in captured.err and "prepare" in captured.err  # the timing table with the logs


def test_options_reach_the_matcher(pair_files, tmp_path, monkeypatch):
    seen = {}
    real = disparity_command.compute_disparity

    def spy(left, right, params=None, **kw):
        seen["params"] = params
        return real(left, right, params, **kw)

    monkeypatch.setattr(disparity_command, "compute_disparity", spy)
    lp, rp = pair_files
    out = tmp_path / "o.pfm"
    args = ["disparity", str(lp), str(rp), "-o", str(out), "--num-disparities", "20", "--min-disparity", "-2",
            "--cost", "sad", "--block-size", "3", "--p1", "10", "--p2", "90", "--uniqueness", "5",
            "--speckle-size", "0", "--speckle-range", "1.5", "--lr-check", "2", "--lr-mode", "opencv", "--paths", "4",
            "--census-window", "7x5", "--no-subpixel", "--no-fill-holes", "--memory-limit", "1G", "--threads", "1",
            "--no-png"]
    assert main(args) == 0
    p = seen["params"]
    assert (p.num_disparities, p.min_disparity, p.cost, p.block_size, p.p1, p.p2) == (20, -2, "sad", 3, 10, 90)
    assert (p.uniqueness, p.speckle_size, p.speckle_range, p.lr_check, p.paths) == (5.0, 0, 1.5, 2.0, 4)
    assert (p.census_window, p.subpixel, p.fill_holes, p.memory_limit, p.threads) == ((7, 5), False, False, 2**30, 1)
    assert p.lr_mode == "opencv"
    assert out.exists() and not (tmp_path / "o.png").exists()


@pytest.mark.parametrize("extra, message", [
    (["--num-disparities", "0"], "--num-disparities must be a positive integer"),
    (["--block-size", "4"], "--block-size must be an odd integer"),
    (["--p1", "50", "--p2", "40"], "--p2 must be larger than --p1"),
    (["--memory-limit", "lots"], "--memory-limit"),
    (["--census-window", "9x9"], "--census-window"),
    (["--png", "x.jpg"], "--png must name a .png file"),
    (["--png", "x.png", "--no-png"], "contradict"),
])
def test_usage_errors_exit_2(pair_files, tmp_path, capsys, extra, message):
    lp, rp = pair_files
    out = tmp_path / "out.pfm"
    assert main(["disparity", str(lp), str(rp), "-o", str(out), *extra]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("argv", [
    ["disparity", "L", "R"],  # -o missing: argparse
    ["disparity", "L", "R", "-o", "o.pfm", "--lr-check", "maybe"],
    ["disparity", "L", "R", "-o", "o.pfm", "--census-window", "9"],
    ["disparity", "L", "R", "-o", "o.pfm", "--paths", "5"],
])
def test_argparse_errors_exit_2(argv):
    assert main(argv) == 2


def test_output_must_be_pfm_and_folder_must_exist(pair_files, tmp_path, capsys):
    lp, rp = pair_files
    assert main(["disparity", str(lp), str(rp), "-o", str(tmp_path / "out.png")]) == 2
    assert ".pfm" in capsys.readouterr().err
    assert main(["disparity", str(lp), str(rp), "-o", str(tmp_path / "nowhere" / "out.pfm")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_missing_folder_with_no_png_is_a_usage_error_before_matching(pair_files, tmp_path, capsys, monkeypatch):
    def must_not_match(*a, **kw):
        raise AssertionError("matched before checking the output folder")

    monkeypatch.setattr(disparity_command, "compute_disparity", must_not_match)
    lp, rp = pair_files
    assert main(["disparity", str(lp), str(rp), "-o", str(tmp_path / "nowhere" / "out.pfm"), "--no-png"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "does not exist" in err[0] and "-o/--output" in err[0]


def test_a_failing_png_leaves_no_lone_pfm(pair_files, tmp_path, capsys, monkeypatch):
    from stereo_classic import io

    def full_disk(path, image, **kw):
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(io, "write_image", full_disk)
    lp, rp = pair_files
    out = tmp_path / "res" / "out.pfm"
    out.parent.mkdir()
    assert main(["disparity", str(lp), str(rp), "-o", str(out), "--num-disparities", "16"]) == 1
    assert "No space left" in capsys.readouterr().err
    assert list(out.parent.iterdir()) == []


def test_runtime_failures_exit_1_and_write_nothing(pair_files, tmp_path, capsys):
    lp, rp = pair_files
    out = tmp_path / "out.pfm"
    assert main(["disparity", str(lp), str(tmp_path / "missing.png"), "-o", str(out)]) == 1
    assert "missing.png" in capsys.readouterr().err
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), np.zeros((40, 60, 3), np.uint8))
    assert main(["disparity", str(lp), str(small), "-o", str(out), "--num-disparities", "16"]) == 1
    assert "same shape" in capsys.readouterr().err
    assert main(["disparity", str(lp), str(rp), "-o", str(out), "--num-disparities", "16",
                 "--memory-limit", "1000"]) == 1
    assert "GiB" in capsys.readouterr().err
    assert not out.exists() and not (tmp_path / "out.png").exists()


def test_sixteen_bit_grey_pngs(tmp_path):
    rng = np.random.default_rng(3)
    right = (rng.integers(0, 4096, (40, 90)) * 16).astype(np.uint16)  # 12-bit data in a 16-bit container
    left = np.roll(right, 4, axis=1)
    lp, rp, out = tmp_path / "l16.png", tmp_path / "r16.png", tmp_path / "d.pfm"
    cv2.imwrite(str(lp), left)
    cv2.imwrite(str(rp), right)
    assert cv2.imread(str(lp), cv2.IMREAD_UNCHANGED).dtype == np.uint16
    assert main(["disparity", str(lp), str(rp), "-o", str(out), "--num-disparities", "16", "--no-subpixel"]) == 0
    disp = _read_pfm(out)
    assert np.nanmedian(disp[6:-6, 22:-6]) == 4.0
