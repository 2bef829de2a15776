"""What the guide costs on top of ``run``: milliseconds per 640x480 frame (the OAK-D scenes).

Each OAK-D pair goes once through the pipeline (matcher with 64 disparities, YOLOX-nano when the model is
present, else depth only); then the guide (:class:`stereo_classic.guide.Guide`) runs on the saved results as
one sequence at 10 frames per second, ``--repeat`` passes over all scenes after one warm-up pass. The scene
changes every frame, so the ground is searched for, and the up measured from the vertical lines, in most frames:
the dearest case. ``--still N`` instead shows each scene as a still sequence of N frames (a fresh guide per
scene), as a walk shows one scene frame after frame: the ground is tracked after its first frame and the lines
are read once a second. ``--no-vertical-lines`` leaves that step out. Reported: median and 90th percentile of the
guide's wall milliseconds per frame, the median of its CPU milliseconds (the thread's CPU time: what it costs when
the machine is shared) and the pipeline's median wall time for scale.

    python -m benchmarks.guide_cost [--data DIR] [--repeat N] [--still N] [--no-vertical-lines]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import calib
from stereo_classic.guide import Guide
from stereo_classic.io import read_image
from stereo_classic.pipeline import Localizer

__all__ = ["main", "measure", "oakd_pipeline"]


def oakd_pipeline(data: Path, model: str | None = "yolox_nano") -> tuple[calib.RectifiedRig, list[Path], Localizer]:
    """The OAK-D folder's rig, its ``*_left.png`` files in order, and the pipeline the guide benchmarks run them
    through (64 disparities; ``model`` when it can be had, else depth only)."""
    rig = calib.load_rig(data / "stereodemo_calibration.json")
    lefts = sorted(data.glob("*_left.png"))
    if not lefts:
        raise FileNotFoundError(f"no *_left.png in {data}")
    try:
        loc = Localizer(rig, model, {"num_disparities": 64})
    except (FileNotFoundError, ValueError):
        loc = Localizer(rig, None, {"num_disparities": 64})
    return rig, lefts, loc


def measure(data: Path, repeat: int = 5, model: str | None = "yolox_nano", vertical_lines: bool = True,
            still: int = 0) -> dict[str, float]:
    """{"guide_median_ms", "guide_p90_ms", "guide_cpu_median_ms", "pipeline_median_ms", "frames", "width",
    "height"} over the OAK-D scenes in ``data`` (``vertical_lines``: ``GuideParams.vertical_lines``; ``still``:
    frames of each scene's still sequence, 0 = the scene changes every frame)."""
    rig, lefts, loc = oakd_pipeline(data, model)
    results, pipeline_ms = [], []
    with loc:
        for left in lefts:
            right = left.with_name(left.name.replace("_left", "_right"))
            t0 = time.perf_counter()
            results.append(loc(read_image(left), read_image(right)))
            pipeline_ms.append((time.perf_counter() - t0) * 1e3)
    guide = Guide(vertical_lines=vertical_lines)
    t = 0.0
    times: list[float] = []
    cpu: list[float] = []
    for rep in range(repeat + 1):
        for result in results:
            if still:
                guide.reset()
            for _ in range(max(1, still)):
                t0, c0 = time.perf_counter(), time.thread_time()
                guide.update(result, rig, t)
                if rep > 0:  # the first pass warms up
                    times.append((time.perf_counter() - t0) * 1e3)
                    cpu.append((time.thread_time() - c0) * 1e3)
                t += 0.1
    arr = np.array(times)
    return {"guide_median_ms": float(np.median(arr)), "guide_p90_ms": float(np.percentile(arr, 90)),
            "guide_cpu_median_ms": float(np.median(cpu)), "pipeline_median_ms": float(np.median(pipeline_ms)),
            "frames": float(len(arr)), "width": float(rig.image_size[0]), "height": float(rig.image_size[1])}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.guide_cost", description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=str(Path(__file__).resolve().parents[2] / "shared" / "data" / "oakd"),
                        help="the OAK-D folder (default: ../shared/data/oakd)")
    parser.add_argument("--repeat", type=int, default=5, help="passes over the scenes after a warm-up (default 5)")
    parser.add_argument("--still", type=int, default=0, metavar="N",
                        help="each scene as a still sequence of N frames (default 0: the scene changes every frame)")
    parser.add_argument("--no-vertical-lines", dest="vertical_lines", action="store_false",
                        help="the guide without the up measured from vertical lines (what that step costs)")
    args = parser.parse_args(argv)
    if args.repeat < 1:
        print(f"error: --repeat must be >= 1, got {args.repeat}", file=sys.stderr)
        return 2
    data = Path(args.data)
    if not data.is_dir():
        print(f"error: --data {data} is not a folder", file=sys.stderr)
        return 2
    if args.still < 0:
        print(f"error: --still must be >= 0, got {args.still}", file=sys.stderr)
        return 2
    r = measure(data, args.repeat, vertical_lines=args.vertical_lines, still=args.still)
    print(f"guide: median {r['guide_median_ms']:.1f} ms wall (p90 {r['guide_p90_ms']:.1f} ms), "
          f"{r['guide_cpu_median_ms']:.1f} ms CPU per {int(r['width'])}x{int(r['height'])} frame "
          f"({int(r['frames'])} frames); "
          f"pipeline median {r['pipeline_median_ms']:.0f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
