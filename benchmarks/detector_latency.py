"""Per-image latency of a detector, split into preprocessing, model and postprocessing.

For the benchmarks: ``measure_latency("yolox_nano", images)`` returns one row per thread count with
median milliseconds per stage. Repetitions of the thread counts are interleaved (1, 2, 1, 2, ...)
so that load on a shared machine hits all of them alike; warm-up runs are excluded.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from detectors import OnnxDetector

__all__ = ["measure_latency", "format_table"]

_STAGES = ("preprocess", "inference", "postprocess", "total")


def measure_latency(
    model: str | os.PathLike,
    images: Sequence[np.ndarray],
    *,
    threads: Sequence[int] = (1, 2),
    repeats: int = 20,
    warmup: int = 3,
    **detector_options,
) -> list[dict]:
    """Median latency per image and stage for each thread count.

    Parameters
    ----------
    model : str or path
        Model name or ONNX path (see :func:`detectors.resolve_model`).
    images : sequence of (H, W, 3) uint8 BGR
        Images cycled through; every repetition runs all of them.
    threads : sequence of int
        onnxruntime intra-op thread counts to compare.
    repeats, warmup : int
        Timed and untimed passes over ``images`` per thread count.
    **detector_options
        Passed to :class:`OnnxDetector` (``conf_threshold``, ``family``, ...).

    Returns
    -------
    list of dict
        Per thread count: ``model``, ``family``, ``input_size``, ``threads``, ``n``, and for each stage
        ``<stage>_ms`` (median) and ``<stage>_p90_ms``; also ``preprocess_over_model`` (ratio of medians).
    """
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise ValueError(f"`repeats` must be a positive int, got {repeats!r}")
    if isinstance(warmup, bool) or not isinstance(warmup, int) or warmup < 0:
        raise ValueError(f"`warmup` must be a non-negative int, got {warmup!r}")
    if not images:
        raise ValueError("`images` must hold at least one image")
    if not threads or any(isinstance(t, bool) or not isinstance(t, int) or t < 1 for t in threads):
        raise ValueError(f"`threads` must be positive ints, got {threads!r}")
    detectors = {t: OnnxDetector(model, threads=t, **detector_options) for t in threads}
    samples: dict[int, dict[str, list[float]]] = {t: {s: [] for s in _STAGES} for t in threads}
    for _ in range(warmup):
        for t in threads:
            for img in images:
                detectors[t].detect(img)
    for _ in range(repeats):
        for t in threads:
            det = detectors[t]
            for img in images:
                det.detect(img)
                for s in _STAGES:
                    samples[t][s].append(det.last_timings_ms[s])
    rows = []
    for t in threads:
        det = detectors[t]
        row: dict = {"model": det.model_path.name if det.model_path else "<bytes>", "family": det.family,
                     "input_size": det.input_size, "threads": t, "n": len(samples[t]["total"])}
        for s in _STAGES:
            v = np.asarray(samples[t][s])
            row[f"{s}_ms"] = float(np.median(v))
            row[f"{s}_p90_ms"] = float(np.percentile(v, 90))
        row["preprocess_over_model"] = row["preprocess_ms"] / row["inference_ms"]
        rows.append(row)
    return rows


def format_table(rows: Sequence[dict]) -> str:
    """Plain-text table of :func:`measure_latency` rows (median ms)."""
    head = f"{'model':<22} {'thr':>3} {'pre':>7} {'model':>7} {'post':>7} {'total':>7}"
    lines = [head]
    for r in rows:
        lines.append(f"{r['model']:<22} {r['threads']:>3} {r['preprocess_ms']:>7.2f} {r['inference_ms']:>7.2f} "
                     f"{r['postprocess_ms']:>7.2f} {r['total_ms']:>7.2f}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """``python -m benchmarks.detector_latency MODEL IMAGE...``: 0 printed, 1 unreadable image, 2 usage error."""
    import argparse
    import sys

    from detectors.imageio import read_image

    parser = argparse.ArgumentParser(prog="python -m benchmarks.detector_latency",
                                     description="A detector's median latency per stage at 1 and 2 threads.")
    parser.add_argument("model", metavar="MODEL", help="model name or .onnx path")
    parser.add_argument("images", metavar="IMAGE", nargs="+", help="image files")
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    try:
        imgs = [read_image(p) for p in args.images]
    except (FileNotFoundError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    print(format_table(measure_latency(args.model, imgs)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
