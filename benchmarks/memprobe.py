"""Peak memory per method, measured as resident-set high water in a child process.

``tracemalloc`` does not see numba's or OpenCV's allocations, so this measures the operating
system's view: a child process loads the pair, runs the method once on a small crop (numba
compilation or cache loading, library initialisation), then resets the kernel's RSS high-water mark
(``/proc/self/clear_refs``, Linux >= 4.0), builds a fresh runner and runs it once on the full pair.
``extra_mb`` = high water during that call minus RSS just before building the runner: the working
memory the method needed. Where the reset is not possible, ``resource.getrusage`` ``ru_maxrss`` of
the whole child is reported instead, and ``how`` says so.

Run as ``python -m benchmarks.memprobe SPEC.json`` (used by :func:`measure_memory`).
"""

from __future__ import annotations

import gc
import json
import logging
import os
import resource
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["measure_memory", "rss_bytes", "reset_peak", "peak_bytes"]

log = logging.getLogger("benchmarks")

_MARK = "MEMPROBE_RESULT "


def _status_kb(key: str) -> int | None:
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def rss_bytes() -> int | None:
    """Current resident set size of this process (bytes), or None where /proc is missing."""
    kb = _status_kb("VmRSS")
    return None if kb is None else kb * 1024


def reset_peak() -> bool:
    """Reset this process's RSS high-water mark to its current RSS; False where not supported."""
    try:
        with open("/proc/self/clear_refs", "w", encoding="ascii") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


def peak_bytes() -> int:
    """RSS high water (bytes): VmHWM when readable, else ``ru_maxrss``."""
    kb = _status_kb("VmHWM")
    if kb is not None:
        return kb * 1024
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024


def _child(spec_path: str) -> int:
    from benchmarks.methods import Setup, default_methods
    from benchmarks.stereo_onnx import onnx_method

    spec = json.loads(Path(spec_path).read_text())
    pair = np.load(spec["pair"])
    left, right = pair["left"], pair["right"]
    setup = Setup(**spec["setup"])
    methods = {m.name: m for m in default_methods([n for n in spec["methods"] if not n.startswith("onnx:")])}
    for item in spec.get("onnx", []):
        m = onnx_method(item["path"], **item.get("options", {}))
        methods[m.name] = m
    crop_w = min(left.shape[1], setup.num_disparities + 48)
    small_l = np.ascontiguousarray(left[: min(48, left.shape[0]), :crop_w])
    small_r = np.ascontiguousarray(right[: min(48, right.shape[0]), :crop_w])
    results: dict[str, Any] = {}
    for name in spec["methods"]:
        method = methods.get(name)
        if method is None or not method.available:
            results[name] = {"error": "not available"}
            continue
        try:
            warm = method.prepare(setup)
            warm(small_l, small_r)
            del warm
            gc.collect()
            can_reset = reset_peak()
            before = rss_bytes()
            runner = method.prepare(setup)
            runner(left, right)
            peak = peak_bytes()
            del runner
            gc.collect()
            if can_reset and before is not None:
                results[name] = {
                    "peak_rss_mb": peak / 2**20,
                    "extra_mb": max(0, peak - before) / 2**20,
                    "baseline_mb": before / 2**20,
                    "how": "VmHWM reset via /proc/self/clear_refs before the call, minus VmRSS before building the runner",
                }
            else:
                results[name] = {
                    "peak_rss_mb": peak / 2**20,
                    "extra_mb": None,
                    "baseline_mb": None,
                    "how": "ru_maxrss of the whole child process (high-water reset not supported)",
                }
        except Exception as exc:  # noqa: BLE001 - reported per method, the probe goes on
            results[name] = {"error": f"{type(exc).__name__}: {exc}"}
    print(_MARK + json.dumps(results), flush=True)
    return 0


def measure_memory(
    method_names: Sequence[str],
    left: np.ndarray,
    right: np.ndarray,
    setup: Any,
    *,
    onnx: Sequence[dict] = (),
    isolate: bool = True,
    timeout_s: float = 600.0,
) -> dict[str, dict[str, Any]]:
    """Peak memory of each method on (left, right), each in its own child process when ``isolate``.

    Parameters
    ----------
    method_names : names of built-in methods, or ``"onnx:<name>"`` entries described in ``onnx``
    left, right : the input pair
    setup : benchmarks.methods.Setup
    onnx : list of ``{"name": ..., "path": ..., "options": {...}}``
    isolate : one child per method (True) or one child for all, run one after the other (False)

    Returns
    -------
    dict name -> {"peak_rss_mb", "extra_mb", "baseline_mb", "how", "isolated"} or {"error": ...}
    """
    groups = [[n] for n in method_names] if isolate else [list(method_names)]
    out: dict[str, dict[str, Any]] = {}
    with tempfile.TemporaryDirectory(prefix="bench_mem_") as tmp:
        pair = Path(tmp) / "pair.npz"
        np.savez(pair, left=left, right=right)
        for i, group in enumerate(groups):
            spec = {
                "pair": str(pair),
                "setup": {"num_disparities": setup.num_disparities, "min_disparity": setup.min_disparity,
                          "block_size": setup.block_size, "threads": setup.threads},
                "methods": group,
                "onnx": [o for o in onnx if o["name"] in group],
            }
            spec_path = Path(tmp) / f"spec{i}.json"
            spec_path.write_text(json.dumps(spec))
            env = dict(os.environ)
            repo = str(Path(__file__).resolve().parents[1])
            env["PYTHONPATH"] = repo + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
            try:
                proc = subprocess.run(
                    [sys.executable, "-m", "benchmarks.memprobe", str(spec_path)],
                    capture_output=True, text=True, timeout=timeout_s, env=env, check=False,
                )
            except subprocess.TimeoutExpired:
                for name in group:
                    out[name] = {"error": f"memory probe timed out after {timeout_s:.0f} s"}
                continue
            lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(_MARK)]
            if proc.returncode != 0 or not lines:
                tail = (proc.stderr or proc.stdout).strip().splitlines()[-1:] or ["no output"]
                for name in group:
                    out[name] = {"error": f"memory probe exited with {proc.returncode}: {tail[0]}"}
                continue
            for name, value in json.loads(lines[-1][len(_MARK):]).items():
                value["isolated"] = isolate
                out[name] = value
    return out


if __name__ == "__main__":
    logging.basicConfig(level=logging.WARNING)
    sys.exit(_child(sys.argv[1]))
