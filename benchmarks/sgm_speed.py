"""Speed probe of the SGM kernels against OpenCV StereoSGBM, side by side, interleaved.

    python -m benchmarks.sgm_speed [--data ../shared/data] [--scene kitti|oakd] [--repeat 15] [--disparities 128]
                                   [--threads 2] [--cost census+grad] [--paths 3] [--no-opencv]
                                   [--gap-ms 50] [--lr-mode full|opencv]

Loads the KITTI pair (1242 x 375; ``--scene oakd``: the OAK-D living room, 640 x 480), greyscale, times every method once per repetition in a rotating
order (so drift of a shared machine hits all alike), the first call apart (numba compile or cache
load), and prints median/min ms, M disparity-estimates/s, ratios to each OpenCV mode, the kernel's
per-stage ms and the peak memory it allocated (tracemalloc, numpy buffers) against 3 x W x H x D.
Both sides use 2 threads, block 5 (OpenCV P1 8*25, P2 32*25; the matcher its own penalties for the cost) and
a 1 px LR check; the matcher's cost and paths default to its own defaults (census+grad, 3 paths).

    python -m benchmarks.sgm_speed --scaling [--repeat 5]

prints the thread-scaling table instead (:func:`thread_scaling`: the matcher's defaults and OpenCV
MODE_SGBM_3WAY at 1..cores threads, plus 2, 4 and 8; the same function makes the report's table).

    python -m benchmarks.sgm_speed --padding [--threads 1] [--paths 3] [--cost census+grad] [--repeat 11]

times the matcher with the kernels' disparity padding (``padded_disparities``) and without it, interleaved in
one process, for ranges of 16 to 128 (:func:`padding_table`); the output is checked to be the same.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
import tracemalloc
from pathlib import Path

import cv2
import numpy as np

__all__ = [
    "SCALING_METHODS",
    "SCENES",
    "load_kitti_grey",
    "load_scene_grey",
    "main",
    "opencv_runner",
    "padding_table",
    "run",
    "scaling_threads",
    "sgm_runner",
    "thread_scaling",
    "usable_cores",
]

#: Methods of the thread-scaling table (names of ``benchmarks.methods``).
SCALING_METHODS: tuple[str, ...] = ("sc-default", "ocv-3way")

REPO = Path(__file__).resolve().parents[1]


def load_kitti_grey(data: Path) -> tuple[np.ndarray, np.ndarray]:
    folder = data / "kitti_object_pair"
    left = cv2.imread(str(folder / "left.png"), cv2.IMREAD_GRAYSCALE)
    right = cv2.imread(str(folder / "right.png"), cv2.IMREAD_GRAYSCALE)
    if left is None or right is None:
        raise FileNotFoundError(f"KITTI pair not found in {folder}")
    return np.ascontiguousarray(left), np.ascontiguousarray(right)


#: ``--scene``: the pair timed by ``run`` (KITTI 1242 x 375, or the OAK-D VGA living room, 640 x 480).
SCENES = {"kitti": ("kitti_object_pair/left.png", "kitti_object_pair/right.png"),
          "oakd": ("oakd/living_room_left.png", "oakd/living_room_right.png")}


def load_scene_grey(data: Path, scene: str = "kitti") -> tuple[np.ndarray, np.ndarray]:
    """The grey pair of ``scene`` (a key of SCENES) under ``data``."""
    if scene == "kitti":
        return load_kitti_grey(data)
    paths = [data / name for name in SCENES[scene]]
    left, right = (cv2.imread(str(path), cv2.IMREAD_GRAYSCALE) for path in paths)
    if left is None or right is None:
        raise FileNotFoundError(f"pair {scene!r} not found: {paths[0]}, {paths[1]}")
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
    import stereo_classic as sc
    from stereo_classic.matching._kernels.core import Workspace, sgm_match

    defaults = sc.SGMParams(cost=cost)  # the matcher's penalties for this cost unless given
    kw.setdefault("p1", defaults.effective_p1)
    kw.setdefault("p2", defaults.effective_p2)
    kw.setdefault("p1_cross", defaults.effective_p1_vertical)
    kw.setdefault("cross_texture", defaults.p1_vertical_texture)

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


def run(data: Path, *, repeat: int = 15, num_disparities: int = 128, threads: int = 2, cost: str = "census+grad",
        paths: int = 3, opencv: bool = True, gap_ms: float = 50.0, lr_mode: str = "full",
        out=sys.stdout, scene: str = "kitti") -> dict[str, list[float]]:
    cv2.setNumThreads(threads)
    left, right = load_scene_grey(data, scene)
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


def usable_cores() -> int:
    """CPUs this process may run on (``os.sched_getaffinity``), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def scaling_threads(cores: int | None = None) -> tuple[int, ...]:
    """Thread counts of the scaling table: 1..cores, and 2, 4 and 8 even beyond the cores (oversubscription shows).

    >>> scaling_threads(2), scaling_threads(6)
    ((1, 2, 4, 8), (1, 2, 3, 4, 5, 6, 8))
    """
    cores = usable_cores() if cores is None else int(cores)
    return tuple(sorted(set(range(1, max(1, cores) + 1)) | {1, 2, 4, 8}))


def thread_scaling(left: np.ndarray, right: np.ndarray, *, num_disparities: int = 128, block_size: int = 5,
                   threads: tuple[int, ...] | None = None, repeat: int = 5, methods: tuple[str, ...] = SCALING_METHODS,
                   name: str = "", pause_s: float = 0.02, on_step=None) -> dict:
    """Time each method at each thread count on one pair, in grey: ms, speed-up, efficiency, CPU s per call, same output.

    Each method is prepared once per thread count (a matcher of its own, its buffers alive until the end: for the
    default 3 paths about 16 MB at 1242x375x128 each); its first call is timed apart (compile, allocation) and its
    output kept. Then ``repeat`` calls of every (method, thread count) run interleaved in one rotation (rotating
    order, ``pause_s`` untimed sleep before each, as :func:`benchmarks.timing.time_interleaved`), so that the
    speed-ups compare calls made side by side, not blocks minutes apart; each call is wrapped in
    ``time.process_time()`` (CPU time of every thread of the process).

    Returns
    -------
    dict
        ``cores``, ``threads``, ``rows`` (per method and thread count: ``median_ms``, ``min_ms``, ``max_ms``,
        ``speedup`` = ms at 1 thread / ms, ``efficiency`` = speedup / min(threads, cores), ``cpu_s_per_call``,
        ``speedup_best`` = fastest call at 1 thread / fastest call, ``cpu_ratio`` = CPU s per call / that at 1
        thread, ``identical`` = output bit-identical (NaN equal) to the
        1-thread output, ``first_call_ms``), the input's size and ``how``.
    """
    from benchmarks.methods import Setup, default_methods, output_views, timing_pair
    from benchmarks.timing import time_interleaved

    left, right = timing_pair(left, right)  # grey: the same work for every method (timing_pair)

    if isinstance(repeat, bool) or not isinstance(repeat, int) or repeat < 1:
        raise ValueError(f"`repeat` must be an integer >= 1, got {repeat!r}")
    cores = usable_cores()
    counts = tuple(sorted({int(t) for t in threads})) if threads else scaling_threads(cores)
    if not counts or counts[0] < 1:
        raise ValueError(f"`threads` must be integers >= 1, got {threads!r}")
    if counts[0] != 1:
        counts = (1,) + counts  # the speed-up and the identity are against 1 thread
    chosen = default_methods(list(methods))
    shape = left.shape[:2]
    rows: list[dict] = []
    calls: dict[tuple[str, int], object] = {}
    cpu: dict[tuple[str, int], float] = {}
    first: dict[tuple[str, int], float] = {}
    outputs: dict[tuple[str, int], np.ndarray] = {}
    try:
        for t in counts:
            setup = Setup(num_disparities=num_disparities, min_disparity=0, block_size=block_size, threads=t)
            for m in chosen:
                key = (m.name, t)
                runner = m.prepare(setup)
                t0 = time.perf_counter()
                out = runner(left, right)
                first[key] = (time.perf_counter() - t0) * 1e3
                outputs[key] = np.array(output_views(out, shape)[0], copy=True)
                cpu[key] = 0.0

                def call(r=runner, k=key):
                    c0 = time.process_time()
                    r(left, right)
                    cpu[k] += time.process_time() - c0

                calls[key] = call
                if on_step:
                    on_step(f"{m.name} t{t}")
        # every method at every thread count in one rotation: drift of a shared machine hits all counts alike
        timed = time_interleaved({f"{n} t{t}": c for (n, t), c in calls.items()}, repeat, first_call=False,
                                 pause_s=pause_s, on_step=on_step)
        for t in counts:
            for m in chosen:
                ref = timed[f"{m.name} t1"]
                key = (m.name, t)
                res = timed[f"{m.name} t{t}"]
                row = {"method": m.name, "threads": t, "median_ms": res.median_ms, "min_ms": res.min_ms,
                       "max_ms": res.max_ms, "first_call_ms": first[key], "cpu_s_per_call": cpu[key] / repeat,
                       "times_ms": list(res.times_ms)}
                row["speedup"] = ref.median_ms / row["median_ms"] if row["median_ms"] else None
                # the least disturbed calls: on a shared machine the minimum is the robust estimate of a call's cost
                row["speedup_best"] = ref.min_ms / row["min_ms"] if row["min_ms"] else None
                row["efficiency"] = row["speedup"] / min(t, cores) if row["speedup"] is not None else None
                base_cpu = cpu[(m.name, 1)] / repeat
                row["cpu_ratio"] = row["cpu_s_per_call"] / base_cpu if base_cpu > 0 else None
                row["identical"] = bool(np.array_equal(outputs[key], outputs[(m.name, 1)], equal_nan=True))
                rows.append(row)
    finally:
        calls.clear()
        cv2.setNumThreads(-1)
    return {
        "available": True, "input": name, "width": int(shape[1]), "height": int(shape[0]),
        "num_disparities": int(num_disparities), "block_size": int(block_size), "cores": cores,
        "threads": list(counts), "repeat": repeat, "methods": [m.name for m in chosen], "rows": rows,
        "how": (f"the grey pair (cv2.COLOR_BGR2GRAY of a colour one); first call of each method and thread count apart, then {repeat} calls of every (method, thread "
                f"count) interleaved in one rotation ({pause_s * 1e3:.0f} ms untimed pause before each); CPU s = time.process_time() delta around each call (all threads of the "
                "process); efficiency = speed-up / min(threads, usable cores); identical = np.array_equal(output, "
                "1-thread output, equal_nan=True)"),
    }


def padding_table(left: np.ndarray, right: np.ndarray, *, disparities=(16, 32, 48, 64, 80, 96, 112, 128),
                  threads: int = 1, paths: int = 3, cost: str = "census+grad", repeat: int = 11) -> list[dict]:
    """Per number of disparities: ms of the matcher (its defaults but ``paths`` and ``cost``) with the kernels'
    padding and without it (``DISPARITY_BLOCK``, ``ONE_SWEEP_BLOCK`` and the least number set to 1 for those calls), both prepared
    once and then called in turn ``repeat`` times (:func:`benchmarks.timing.time_interleaved`), and whether the
    two disparity maps are identical."""
    import stereo_classic as sc
    from benchmarks.timing import time_interleaved
    from stereo_classic.matching._kernels import core

    saved = (core.DISPARITY_BLOCK, core.ONE_SWEEP_BLOCK, core.MIN_DISPARITIES_ONE_SWEEP)

    def padding(on: bool) -> None:
        core.DISPARITY_BLOCK, core.ONE_SWEEP_BLOCK, core.MIN_DISPARITIES_ONE_SWEEP = saved if on else (1, 1, 1)

    rows = []
    try:
        for n in disparities:
            matcher = sc.StereoMatcher(sc.SGMParams(num_disparities=int(n), paths=paths, cost=cost, threads=threads))
            outputs = {}

            def call(on: bool, m=matcher, out=outputs):
                padding(on)
                out[on] = m.compute(left, right).disparity

            padding(True)
            padded_to = core.padded_disparities(n, paths)
            timed = time_interleaved({"padded": lambda: call(True), "as is": lambda: call(False)}, repeat)
            rows.append({"num_disparities": int(n), "padded_to": padded_to,
                         "as_is_ms": timed["as is"].median_ms, "as_is_min_ms": timed["as is"].min_ms,
                         "padded_ms": timed["padded"].median_ms, "padded_min_ms": timed["padded"].min_ms,
                         "identical": bool(np.array_equal(outputs[True], outputs[False], equal_nan=True))})
            matcher.release()
    finally:
        padding(True)
    return rows


def format_scaling(result: dict) -> str:
    """The thread-scaling result as a plain-text table."""
    lines = [(f"{result['width']}x{result['height']}, {result['num_disparities']} disparities, "
              f"{result['cores']} usable cores, {result['repeat']} repeats")]
    lines.append(f"{'method':12s} {'threads':>7s} {'median ms':>10s} {'speed-up':>9s} {'effic.':>7s} "
                 f"{'CPU s/call':>11s} {'CPU ratio':>9s}  identical")
    for r in result["rows"]:
        lines.append(f"{r['method']:12s} {r['threads']:7d} {r['median_ms']:10.1f} {r['speedup']:9.2f} "
                     f"{r['efficiency']:7.2f} {r['cpu_s_per_call']:11.3f} {r['cpu_ratio'] or float('nan'):9.2f}  "
                     f"{'yes' if r['identical'] else 'NO'}")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.sgm_speed", description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data")
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--disparities", type=int, default=128)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--cost", default="census+grad", choices=["census+grad", "census", "sad"],
                    help="matching cost (default: the matcher's, census+grad)")
    ap.add_argument("--paths", type=int, default=3, choices=[3, 4, 8], help="paths (default: the matcher's, 3)")
    ap.add_argument("--no-opencv", action="store_true")
    ap.add_argument("--gap-ms", type=float, default=50.0, help="pause before every timed call (default 50)")
    ap.add_argument("--lr-mode", default="full", choices=["full", "opencv"], help="LR check of the matcher (1 px)")
    ap.add_argument("--scaling", action="store_true", help="the thread-scaling table (matcher defaults and 3WAY)")
    ap.add_argument("--scene", default="kitti", choices=sorted(SCENES),
                    help="pair to time: kitti (1242x375, default) or oakd (living room, 640x480; use 64 disparities)")
    ap.add_argument("--padding", action="store_true", help="the matcher with and without its disparity padding")
    a = ap.parse_args(argv)
    if a.padding:
        left, right = load_kitti_grey(a.data)
        print(f"KITTI pair {left.shape[1]}x{left.shape[0]}, {a.threads} thread(s), {a.paths} paths, {a.cost}, "
              f"{a.repeat} calls each, interleaved: ms median (fastest)")
        print(f"{'disparities':>11s} {'padded to':>9s} {'as is':>14s} {'padded':>14s}  identical")
        for r in padding_table(left, right, threads=a.threads, paths=a.paths, cost=a.cost, repeat=a.repeat):
            print(f"{r['num_disparities']:11d} {r['padded_to']:9d} {r['as_is_ms']:7.1f} ({r['as_is_min_ms']:5.1f}) "
                  f"{r['padded_ms']:7.1f} ({r['padded_min_ms']:5.1f})  {'yes' if r['identical'] else 'NO'}")
        return 0
    if a.scaling:
        left, right = load_kitti_grey(a.data)
        print(format_scaling(thread_scaling(left, right, num_disparities=a.disparities, repeat=a.repeat,
                                            name="kitti_object_pair")))
        return 0
    run(a.data, repeat=a.repeat, num_disparities=a.disparities, threads=a.threads, cost=a.cost, paths=a.paths,
        opencv=not a.no_opencv, gap_ms=a.gap_ms, lr_mode=a.lr_mode, scene=a.scene)
    return 0


if __name__ == "__main__":
    sys.exit(main())
