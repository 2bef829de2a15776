"""``python -m benchmarks.throughput``: frames per second of ``run`` serial and on Dask, and peak memory over 2000 pairs.

Writes ``benchmarks/results/throughput.md`` (or ``--out``). Two parts:

* **Throughput**: ``run --dataset`` over ``--frames`` generated pairs (symlinks cycling through the OAK-D scenes of
  ``../shared/data``, 640x480, default detector), serial with 1 and 2 threads and on a local Dask cluster of
  2 workers x 1 thread (started once, before timing; each run's numba cache load and ONNX session creation are
  included, as a user sees them). The figure is the command's own "N frame(s) in S s" (the frame loop, opening
  the input and the cluster excluded); runs are interleaved over ``--repeat`` rounds and the median is reported.
* **Memory**: ``run --dataset`` over ``--memory-frames`` generated pairs (``--scale 0.25 --model none --save json``)
  serial and on Dask; peak RSS of the command's process (``resource.getrusage``) and, for Dask, the largest
  worker's.

Needs the ``dask`` extra and ``../shared/data`` (or ``$STEREO_CLASSIC_DATA``).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

__all__ = ["main"]

REPO = Path(__file__).resolve().parents[1]

_PEAK = """
import json, resource, sys
from stereo_classic.cli import main
rc = main(sys.argv[1:])
print(json.dumps({"rc": rc, "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def _dataset(root: Path, oakd: Path, n: int) -> Path:
    names = sorted(p.name[: -len("_left.png")] for p in oakd.glob("*_left.png"))
    root.mkdir(parents=True)
    shutil.copy(oakd / "stereodemo_calibration.json", root)
    for i in range(n):
        name = names[i % len(names)]
        for side in ("left", "right"):
            (root / f"f{i:05d}_{side}.png").symlink_to(oakd / f"{name}_{side}.png")
    return root


def _run(argv: list[str]) -> tuple[dict[str, float], str]:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    done = subprocess.run([sys.executable, "-c", _PEAK, *argv], capture_output=True, text=True, check=False,
                          env=env)
    if done.returncode != 0 or not done.stdout.strip():
        raise RuntimeError(f"run failed ({done.returncode}): {done.stderr[-2000:]}")
    info = json.loads(done.stdout.strip().splitlines()[-1])
    if info["rc"] not in (0, 1):  # 1: frames flagged (not measured) by the pair checks; they are still written
        raise RuntimeError(f"run exited {info['rc']}: {done.stderr[-2000:]}")
    m = re.search(r"(\d+) frame\(s\) in ([\d.]+) s", done.stderr)
    if m:
        info["frames"], info["seconds"] = int(m.group(1)), float(m.group(2))
        info["fps"] = info["frames"] / info["seconds"]
    return info, done.stderr


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.throughput", description=__doc__.splitlines()[0])
    p.add_argument("--data", type=Path, default=Path(os.environ.get("STEREO_CLASSIC_DATA", REPO.parent / "shared/data")))
    p.add_argument("--frames", type=int, default=96, help="frames per throughput run (default 96)")
    p.add_argument("--repeat", type=int, default=2, help="interleaved rounds (default 2)")
    p.add_argument("--memory-frames", type=int, default=2000, help="frames of the memory check (default 2000)")
    p.add_argument("--out", type=Path, default=REPO / "benchmarks" / "results" / "throughput.md")
    args = p.parse_args(argv)
    oakd = args.data / "oakd"
    if not oakd.is_dir():
        print(f"error: {oakd} not found (the OAK-D scenes of ../shared/data)", file=sys.stderr)
        return 1
    import distributed

    from stereo_classic.io import atomic_write

    with tempfile.TemporaryDirectory() as tmp_name, distributed.LocalCluster(
            processes=True, n_workers=2, threads_per_worker=1, dashboard_address=":0",
            silence_logs=logging.ERROR) as cluster:
        tmp = Path(tmp_name)
        data = _dataset(tmp / "data", oakd, args.frames)
        common = ["run", "--dataset", str(data), "--no-progress"]
        configs = {
            "serial, 1 thread": ["--threads", "1"],
            "serial, 2 threads": ["--threads", "2"],
            "Dask, 2 workers x 1 thread": ["--executor", "dask", "--scheduler", cluster.scheduler_address],
        }
        fps: dict[str, list[float]] = {k: [] for k in configs}
        for r in range(args.repeat):
            for label, extra in configs.items():
                info, _ = _run([*common, *extra, "-o", str(tmp / f"out_{len(fps[label])}_{r}")])
                fps[label].append(info["fps"])
                print(f"{label}: {info['fps']:.2f} frames/s", file=sys.stderr)
        load = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp_name, distributed.LocalCluster(  # fresh workers for the memory check
            processes=True, n_workers=2, threads_per_worker=1, dashboard_address=":0",
            silence_logs=logging.ERROR) as cluster:
        tmp = Path(tmp_name)
        big = _dataset(tmp / "big", oakd, args.memory_frames)
        small = ["run", "-q", "--dataset", str(big), "--model", "none", "--scale", "0.25", "--save", "json"]
        memory = {}
        for label, extra in (("serial", ["--threads", "1"]),
                             ("Dask, 2 workers x 1 thread", ["--executor", "dask", "--scheduler",
                                                             cluster.scheduler_address])):
            info, _ = _run([*small, *extra, "-o", str(tmp / f"mem_{len(memory)}")])
            lines = len((tmp / f"mem_{len(memory)}" / "objects.jsonl").read_text().splitlines())
            memory[label] = (info["peak_mb"], lines)
            print(f"memory {label}: {info['peak_mb']:.0f} MB, {lines} frames", file=sys.stderr)
        client = distributed.Client(cluster)
        workers = client.run(lambda: __import__("resource").getrusage(0).ru_maxrss / 1024)
        client.close()

    best_serial = max(statistics.median(fps[k]) for k in configs if k.startswith("serial"))
    rows = [f"| {k} | {statistics.median(v):.2f} | {', '.join(f'{x:.2f}' for x in v)} | "
            f"{statistics.median(v) / best_serial:.0%} |" for k, v in fps.items()]
    text = "\n".join([
        "# `run` throughput and memory",
        "",
        (f"`python -m benchmarks.throughput` on {os.cpu_count()} CPU cores: `run --dataset` over {args.frames} pairs "
        "(OAK-D scenes, 640x480, yolox_nano), median of interleaved rounds; frames/s from the command's own frame "
        "loop time."),
        "",
        (f"Load average (1 min) at the end of the throughput runs: {load[0]:.1f} on {os.cpu_count()} cores; "
        "above the core count, other processes shared the cores and the rounds are noisy."),
        "",
        "| executor | frames/s (median) | rounds | of best serial |",
        "|---|---|---|---|",
        *rows,
        "",
        f"Peak RSS over {args.memory_frames} pairs (`--scale 0.25 --model none --save json`):",
        "",
        "| executor | peak RSS of the command (MB) | frames written |",
        "|---|---|---|",
        *[f"| {k} | {v[0]:.0f} | {v[1]} |" for k, v in memory.items()],
        "",
        (f"Peak RSS of each Dask worker process over the memory run (MB): "
        f"{', '.join(f'{v:.0f}' for v in workers.values())}."),
        "",
    ])
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_write(args.out, "w") as f:
        f.write(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
