"""Speed probe of the SGM kernels against OpenCV StereoSGBM, side by side, interleaved.

    python -m benchmarks.sgm_speed [--data ../shared/data] [--repeat 15] [--disparities 128]
                                   [--threads 2] [--cost census] [--paths 8] [--no-opencv]
                                   [--gap-ms 50] [--lr-mode full|opencv]

Loads the KITTI pair (1242 x 375), greyscale, times every method once per repetition in a rotating
order (so drift of a shared machine hits all alike), the first call apart (numba compile or cache
load), and prints median/min ms, M disparity-estimates/s, ratios to each OpenCV mode, the kernel's
per-stage ms and the peak memory it allocated (tracemalloc, numpy buffers) against 3 x W x H x D.
Both sides use 2 threads, block 5 (OpenCV P1 8*25, P2 32*25) and a 1 px LR check.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import tracemalloc
from pathlib import Path

import cv2
import numpy as np

__all__ = ["load_kitti_grey", "opencv_runner", "sgm_runner", "run", "main"]

REPO = Path(__file__).resolve().parents[1]


def load_kitti_grey(data: Path) -> tuple[np.ndarray, np.ndarray]:
    folder = data / "kitti_object_pair"
    left = cv2.imread(str(folder / "left.png"), cv2.IMREAD_GRAYSCALE)
    right = cv2.imread(str(folder / "right.png"), cv2.IMREAD_GRAYSCALE)
    if left is None or right is None:
        raise FileNotFoundError(f"KITTI pair not found in {folder}")
    return np.ascontiguousarray(left), np.ascontiguousarray(right)


def opencv_runner(mode: int, num_disparities: int, block_size: int = 5):
    cn = 1
    matcher = cv2.StereoSGBM_create(
        minDisparity=0, numDisparities=num_disparities, blockSize=block_size,
        P1=8 * cn * block_size * block_size, P2=32 * cn * block_size * block_size,
        disp12MaxDiff=1, uniquenessRatio=0, speckleWindowSize=0, speckleRange=0, mode=mode)

    def run(left, right):
        return matcher.compute(left, right)

    return run


def sgm_runner(num_disparities: int, threads: int, cost: str, paths: int, workspace: bool = True, **kw):
    from stereo_classic.matching._kernels.core import Workspace, sgm_match

    stages: list[dict[str, float]] = []
    # buffers kept between calls, like the buffer inside a reused OpenCV StereoSGBM object
    workspace = Workspace() if workspace else None

    def run(left, right):
        d, _, t = sgm_match(left, right, cost=cost, num_disparities=num_disparities, threads=threads,
                            paths=paths, workspace=workspace, **kw)
        stages.append(t)
        return d

    run.stages = stages
    return run


def _peak_bytes(fn, left, right) -> int:
    tracemalloc.start()
    tracemalloc.reset_peak()
    fn(left, right)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak


def run(data: Path, *, repeat: int = 15, num_disparities: int = 128, threads: int = 2, cost: str = "census",
        paths: int = 8, opencv: bool = True, gap_ms: float = 50.0, lr_mode: str = "full",
        out=sys.stdout) -> dict[str, list[float]]:
    cv2.setNumThreads(threads)
    left, right = load_kitti_grey(data)
    H, W = left.shape
    D = num_disparities
    runners = {}
    t0 = time.perf_counter()
    sgm = sgm_runner(D, threads, cost, paths, lr_mode=lr_mode)
    sgm(left, right)
    first = (time.perf_counter() - t0) * 1e3
    sgm.stages.clear()
    runners[f"sgm {cost} {paths}p" + (" lrcv" if lr_mode == "opencv" else "")] = sgm
    if opencv:
        runners["cv HH"] = opencv_runner(cv2.STEREO_SGBM_MODE_HH, D)
        runners["cv SGBM"] = opencv_runner(cv2.STEREO_SGBM_MODE_SGBM, D)
        runners["cv 3WAY"] = opencv_runner(cv2.STEREO_SGBM_MODE_SGBM_3WAY, D)
        for fn in list(runners.values())[1:]:
            fn(left, right)
    names = list(runners)
    times: dict[str, list[float]] = {n: [] for n in names}
    for i in range(repeat):
        order = names[i % len(names):] + names[:i % len(names)]
        for n in order:
            # OpenCV's worker threads spin for a while after each call; without a pause they steal a
            # core from whichever method runs next (measured: sgm median 109 ms right after OpenCV
            # calls, 73 ms on its own). The pause applies to every method alike.
            time.sleep(gap_ms / 1e3)
            t = time.perf_counter()
            runners[n](left, right)
            times[n].append((time.perf_counter() - t) * 1e3)
    print(f"{W}x{H}, {D} disparities, {threads} threads, {repeat} interleaved repeats ({gap_ms:.0f} ms pause "
          f"between calls); "
          f"sgm first call (compile/cache load) {first:.0f} ms", file=out)
    print(f"{'method':16s} {'median':>8s} {'min':>8s}  {'MDE/s':>7s}", file=out)
    for n in names:
        med, mn = statistics.median(times[n]), min(times[n])
        print(f"{n:16s} {med:8.1f} {mn:8.1f}  {W * H * D / med / 1e3:7.0f}", file=out)
    if opencv:
        s = names[0]
        for n in names[1:]:
            r_med = statistics.median(times[n]) / statistics.median(times[s])
            r_min = min(times[n]) / min(times[s])
            print(f"speed-up vs {n:8s}: median {r_med:.2f}x, min {r_min:.2f}x", file=out)
    st = sgm.stages
    if st:
        keys = [k for k in st[0] if not k.startswith("n_")]
        print("sgm stages (median ms): " + ", ".join(f"{k} {statistics.median(t[k] for t in st):.1f}" for k in keys),
              file=out)
    # no kept buffers: everything allocated by the call itself
    fresh = sgm_runner(D, threads, cost, paths, workspace=False, lr_mode=lr_mode)
    peak = _peak_bytes(fresh, left, right)
    print(f"sgm peak allocated by one call without a kept workspace: {peak / 1e6:.1f} MB = "
          f"{peak / (W * H * D):.2f} x W*H*D bytes (bar: 3.00; the images are {2 * W * H / 1e6:.1f} MB)", file=out)
    return times


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data")
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--disparities", type=int, default=128)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--cost", default="census", choices=["census", "sad"])
    ap.add_argument("--paths", type=int, default=8, choices=[4, 8])
    ap.add_argument("--no-opencv", action="store_true")
    ap.add_argument("--gap-ms", type=float, default=50.0, help="pause before every timed call (default 50)")
    ap.add_argument("--lr-mode", default="full", choices=["full", "opencv"], help="LR check of the matcher (1 px)")
    a = ap.parse_args(argv)
    run(a.data, repeat=a.repeat, num_disparities=a.disparities, threads=a.threads, cost=a.cost, paths=a.paths,
        opencv=not a.no_opencv, gap_ms=a.gap_ms, lr_mode=a.lr_mode)
    return 0


if __name__ == "__main__":
    sys.exit(main())
