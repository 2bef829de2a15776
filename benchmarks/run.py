"""One benchmark run: accuracy, speed, memory, detectors, pipeline and distances, then the report.

:func:`run_benchmark` measures and returns every raw number as one JSON-ready dict;
:func:`write_report` turns it into report.json, report.md, report.html and figures.
"""

from __future__ import annotations

import datetime as _dt
import importlib
import logging
import os
import platform
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from benchmarks import metrics as _metrics
from benchmarks.methods import Method, Setup, default_methods, output_views, timing_pair
from benchmarks.scenes import (
    FAMILIES,
    BenchScene,
    SpeedInput,
    disparity_range,
    load_scenes,
    speed_inputs,
)
from benchmarks.timing import summarize, time_interleaved

__all__ = ["DEFAULT_SIZES", "BenchConfig", "family_means", "machine_info", "method_metrics", "run_benchmark"]

log = logging.getLogger("benchmarks")

#: The speed sizes: the KITTI pair, VGA with 64 disparities (the worn camera's size, which the frame-rate issue
#: measures the matcher against 3WAY at) and full HD with 256 disparities.
DEFAULT_SIZES: tuple[tuple[int, int, int], ...] = ((1242, 375, 128), (640, 480, 64), (1920, 1080, 256))


@dataclass
class BenchConfig:
    """What to run (the command-line options)."""

    data_dir: Path | None = None
    out_dir: Path = Path("bench_out")
    scenes: list[str] | None = None
    methods: list[str] | None = None
    repeat: int = 5
    threads: tuple[int, ...] = (1, 2)
    block_size: int = 5
    sizes: tuple[tuple[int, int, int], ...] = DEFAULT_SIZES
    stereo_onnx: list[Path] = field(default_factory=list)
    onnx_options: dict[str, Any] = field(default_factory=dict)
    models_dir: Path | None = None
    memory: bool = True
    objects: bool = True
    figures: bool = True
    quick: bool = False
    progress: bool | None = None
    scaling: bool = True

    def __post_init__(self) -> None:
        if isinstance(self.repeat, bool) or not isinstance(self.repeat, int) or self.repeat < 1:
            raise ValueError(f"`repeat` must be an integer >= 1, got {self.repeat!r}")
        if not self.threads or any(not isinstance(t, int) or t < 1 for t in self.threads):
            raise ValueError(f"`threads` must be one or more integers >= 1, got {self.threads!r}")
        if self.block_size < 1 or self.block_size % 2 == 0:
            raise ValueError(f"`block_size` must be a positive odd integer, got {self.block_size!r}")


def _version(module: str) -> str | None:
    try:
        mod = importlib.import_module(module)
    except Exception:  # noqa: BLE001 - absent or broken: no version
        return None
    return str(getattr(mod, "__version__", "unknown"))


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _git_commit() -> str | None:
    repo = Path(__file__).resolve().parents[1]
    try:
        head = subprocess.run(["git", "-C", str(repo), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10, check=False)
        dirty = subprocess.run(["git", "-C", str(repo), "status", "--porcelain", "--untracked-files=no"], capture_output=True, text=True, timeout=10, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    if head.returncode != 0:
        return None
    return head.stdout.strip() + ("-dirty" if dirty.stdout.strip() else "")


def machine_info() -> dict[str, Any]:
    """CPU model, cores, memory, OS, library versions and the date (UTC)."""
    try:
        affinity = len(os.sched_getaffinity(0))
    except AttributeError:
        affinity = None
    try:
        mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    except (ValueError, OSError, AttributeError):
        mem = None
    return {
        "date_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S"),
        "cpu_model": _cpu_model(),
        "logical_cpus": os.cpu_count(),
        "usable_cpus": affinity,
        "memory_gib": mem,
        "os": platform.platform(),
        "python": platform.python_version(),
        "versions": {name: _version(name) for name in ("numpy", "numba", "cv2", "onnxruntime", "skimage", "matplotlib", "stereo_classic")},
        "opencv_threads_default": cv2.getNumThreads(),
        "git_commit": _git_commit(),
    }


class _Progress:
    def __init__(self, total: int, enabled: bool | None) -> None:
        try:
            from tqdm import tqdm

            self.bar = tqdm(total=total, file=sys.stderr, disable=enabled is False if enabled is not None else None, unit="run", dynamic_ncols=True)
        except ImportError:  # tqdm is a runtime dependency, but never fail for a progress bar
            self.bar = None

    def step(self, label: str) -> None:
        if self.bar is not None:
            self.bar.set_postfix_str(label[:40], refresh=False)
            self.bar.update(1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _first_calls(methods: Sequence[Method], setup: Setup, left: np.ndarray, right: np.ndarray, progress: _Progress,
                 label: str) -> tuple[dict, dict, dict, dict]:
    """Prepare each method and run it once on the pair as read: (runners, first-call ms, outputs), errors per method.

    The runners returned (what the speed tables time) call the method on :func:`benchmarks.methods.timing_pair`, a
    network on the pair as read.
    """
    import time

    runners, first, outputs, errors = {}, {}, {}, {}
    grey = timing_pair(left, right)
    for m in methods:
        try:
            runner = m.prepare(setup)
            t0 = time.perf_counter()
            out = runner(left, right)
            first[m.name] = (time.perf_counter() - t0) * 1000.0
            outputs[m.name] = output_views(out, left.shape[:2])  # (output, measured)
            # timed on the grey pair (timing_pair: the same work for every classical method), a network on its input
            pair = (left, right) if m.family == "onnx" else grey
            if pair[0] is not left and m.family != "peer":
                # untimed: OpenCV's matcher, made for the colour pair's channels, is made again, and a matcher's
                # buffers for the new input made; a peer (seconds a call, no state) is timed once anyway
                runner(*pair)
            runners[m.name] = (lambda r=runner, p=pair: r(*p))
        except Exception as exc:  # noqa: BLE001 - one failing method must not stop the others; reported
            errors[m.name] = f"{type(exc).__name__}: {exc}"
            log.warning("%s failed on %s: %s", m.name, label, errors[m.name])
        progress.step(f"{label} {m.name}")
    return runners, first, outputs, errors


def method_metrics(output: np.ndarray, measured: np.ndarray, scene: BenchScene, ndisp: int) -> dict[str, Any]:
    """:func:`benchmarks.metrics.scene_metrics` of one method's result on one scene.

    The dense and unknown-is-bad ("all") views score ``output`` (what a user gets, filled pixels included);
    the valid view scores ``measured`` (only what was measured: a filled pixel is not an estimate), so its
    density is the measured density. For a method without filled pixels the two are the same array.
    """
    kw = {"nonocc_mask": scene.nonocc_mask, "max_disparity": ndisp}
    result = _metrics.scene_metrics(output, scene.gt_disparity, **kw)
    if measured is not output:
        on_measured = _metrics.scene_metrics(measured, scene.gt_disparity, **kw)
        for region, views in result.items():
            views["valid"] = on_measured[region]["valid"]
    return result


def family_means(accuracy: dict[str, dict[str, Any]], families: dict[str, str], names: Sequence[str]) -> dict[str, dict]:
    """Per family (:data:`benchmarks.scenes.FAMILIES` order) and method, the mean metrics over that family's scenes.

    ``accuracy[scene][method]`` as in the report (an entry with "error" is left out); ``families[scene]`` the
    scene's family. Each mean carries ``"scenes"``, the number of scenes averaged.
    """
    out: dict[str, dict] = {}
    for family in FAMILIES:
        scenes = [s for s in accuracy if families.get(s) == family]
        if not scenes:
            continue
        per_method = {}
        for n in names:
            runs = [accuracy[s][n] for s in scenes if n in accuracy[s] and "error" not in accuracy[s][n]]
            if runs:
                per_method[n] = _metrics.mean_metrics(runs)
                per_method[n]["scenes"] = len(runs)
        out[family] = per_method
    return out


def _speed_rows(name: str, kind: str, note: str, size: tuple[int, int], ndisp: int, setup: Setup,
                methods: Sequence[Method], left: np.ndarray, right: np.ndarray, repeat: int, progress: _Progress) -> tuple[list[dict], dict, dict]:
    runners, first, outputs, errors = _first_calls(methods, setup, left, right, progress, f"{name} t{setup.threads}")
    step = lambda n: progress.step(f"{name} t{setup.threads} {n}")  # noqa: E731
    peers = {m.name for m in methods if m.family == "peer"}
    # the accuracy peers (single-threaded, seconds a frame) are timed once: their time is quoted, not compared
    fast = {n: r for n, r in runners.items() if n not in peers}
    slow = {n: r for n, r in runners.items() if n in peers}
    timed = time_interleaved(fast, repeat, first_call=False, on_step=step) if fast else {}
    timed.update(time_interleaved(slow, 1, first_call=False, on_step=step) if slow else {})
    rows = []
    for m in methods:
        row: dict[str, Any] = {"input": name, "kind": kind, "note": note, "width": size[0], "height": size[1],
                               "num_disparities": ndisp, "threads": setup.threads, "method": m.name}
        if m.name in timed:
            row.update(summarize(timed[m.name], size[0], size[1], ndisp))
            row["first_call_ms"] = first[m.name]
        else:
            row["error"] = errors.get(m.name, m.reason or "not available")
        rows.append(row)
    return rows, outputs, errors


def run_benchmark(config: BenchConfig, *, argv: Sequence[str] | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
    """Run everything ``config`` asks for.

    Returns
    -------
    (report, arrays)
        ``report``: JSON-ready dict of every number. ``arrays``: what the figures need (per scene the
        images, ground truth and each method's disparity), not written to JSON.
    """
    from benchmarks.stereo_onnx import onnx_method

    methods = default_methods(config.methods)
    onnx_specs = []
    for path in config.stereo_onnx:
        m = onnx_method(path, **config.onnx_options)
        methods.append(m)
        onnx_specs.append({"name": m.name, "path": str(path), "options": dict(config.onnx_options)})
    available = [m for m in methods if m.available]
    for m in methods:
        if not m.available:
            log.warning("%s: not available (%s)", m.name, m.reason)

    scenes = load_scenes(config.data_dir, config.scenes)
    sizes = () if config.quick else config.sizes
    extra_inputs = speed_inputs(scenes, sizes)
    threads = tuple(config.threads[:1]) if config.quick else tuple(config.threads)
    acc_threads = max(threads)

    notes: list[str] = []
    if config.quick:
        notes.append("--quick: real scenes only (no synthetic speed sizes), one thread count, memory of all methods in one child process.")
    report: dict[str, Any] = {
        "schema": "stereo_classic.benchmarks/2",
        "command": ["python", "-m", "benchmarks", *(argv or [])],
        "machine": machine_info(),
        "config": {
            "data_dir": None if config.data_dir is None else str(config.data_dir),
            "repeat": config.repeat, "threads": list(threads), "block_size": config.block_size,
            "sizes": [list(s) for s in sizes], "quick": config.quick, "min_disparity": 0,
            "disparity_range": "ground-truth maximum + 1 rounded up to 16 (LiDAR-only KITTI frame: 128; else the dataset's bound)",
            "accuracy_threads": acc_threads,
        },
        "notes": notes,
        "methods": [{"name": m.name, "family": m.family, "description": m.description, "available": m.available,
                     "reason": m.reason or None, "params": m.params} for m in methods],
        "scenes": [],
        "accuracy": {},
        "accuracy_mean": {},
        "errors": {},
        "scaling": None,
        "speed": [],
        "memory": [],
    }
    arrays: dict[str, Any] = {"scenes": {}}

    total = (len(scenes) + len(extra_inputs)) * len(threads) * len(available) * (config.repeat + 1)
    progress = _Progress(total, config.progress)
    try:
        for scene in scenes:
            ndisp = disparity_range(scene)
            report["scenes"].append({
                "name": scene.name, "family": scene.family, "size": list(scene.size), "num_disparities": ndisp,
                "has_gt": scene.gt_disparity is not None, "has_nonocc": scene.nonocc_mask is not None,
                "has_lidar": scene.gt_depth is not None, "has_rig": scene.rig is not None, "source": scene.source,
            })
            outputs: dict[str, tuple[np.ndarray, np.ndarray]] = {}
            for t in threads:
                setup = Setup(num_disparities=ndisp, min_disparity=0, block_size=config.block_size, threads=t)
                log.info("scene %s (%dx%d, %d disparities), %d thread(s)", scene.name, *scene.size, ndisp, t)
                # an accuracy peer runs single-threaded whatever the setup: it runs at the accuracy thread count only
                at_t = [m for m in available if m.family != "peer" or t == acc_threads]
                rows, outs, errs = _speed_rows(scene.name, "scene", scene.source, scene.size, ndisp, setup, at_t,
                                               scene.left, scene.right, config.repeat, progress)
                report["speed"] += rows
                if t == acc_threads:
                    outputs = outs
                    if errs:
                        report["errors"][scene.name] = errs
            arrays["scenes"][scene.name] = {"scene": scene, "outputs": {n: o for n, (o, _) in outputs.items()},
                                            "measured": {n: v for n, (_, v) in outputs.items()}, "ndisp": ndisp}
            if scene.gt_disparity is not None:
                per_method = {}
                for m in methods:
                    if m.name in outputs:
                        per_method[m.name] = method_metrics(*outputs[m.name], scene, ndisp)
                    else:
                        per_method[m.name] = {"error": report["errors"].get(scene.name, {}).get(m.name, m.reason or "not available")}
                report["accuracy"][scene.name] = per_method

        speed_methods = [m for m in available if m.family != "peer"]  # the synthetic sizes are for speed alone
        for inp in extra_inputs:
            for t in threads:
                setup = Setup(num_disparities=inp.num_disparities, min_disparity=0, block_size=config.block_size, threads=t)
                log.info("speed input %s, %d thread(s): %s", inp.name, t, inp.note)
                rows, _outs, _errs = _speed_rows(inp.name, "synthetic", inp.note, inp.size, inp.num_disparities, setup,
                                                 speed_methods, inp.left, inp.right, config.repeat, progress)
                report["speed"] += rows
    finally:
        progress.close()
        cv2.setNumThreads(-1)

    # accuracy averaged per dataset family over its scenes with ground truth (only scenes where the method ran)
    report["accuracy_mean"] = family_means(report["accuracy"], {s["name"]: s["family"] for s in report["scenes"]},
                                           [m.name for m in methods])
    if config.scaling:
        report["scaling"] = _scaling(config, scenes, extra_inputs, progress_enabled=config.progress)

    if config.memory and available:
        report["memory"] = _memory(config, scenes, extra_inputs, [m for m in available if m.family != "peer"],
                                   onnx_specs, max(threads))
    if config.objects:
        report.update(_objects(config, scenes, arrays, threads))
    return report, arrays


def _scaling(config: BenchConfig, scenes: Sequence[BenchScene], extra: Sequence[SpeedInput], *,
             progress_enabled: bool | None) -> dict[str, Any]:
    """The thread-scaling table (:func:`benchmarks.sgm_speed.thread_scaling`) on the KITTI pair, 128 disparities."""
    from benchmarks.sgm_speed import scaling_threads, thread_scaling

    target = next(((s.name, s.left, s.right, f"{s.name} ({s.source})") for s in scenes if s.size == (1242, 375)), None)
    if target is None:
        target = next(((i.name, i.left, i.right, i.note) for i in extra if i.size == (1242, 375)), None)
    if target is None:
        return {"available": False, "reason": "no 1242x375 input (the KITTI pair, or --sizes 1242x375x128 without --quick)"}
    name, left, right, note = target
    counts = (1, 2) if config.quick else scaling_threads()
    log.info("thread scaling on %s: threads %s", name, ", ".join(map(str, counts)))
    progress = _Progress(len(counts) * 2 * (config.repeat + 1), progress_enabled)
    try:
        result = thread_scaling(left, right, num_disparities=128, block_size=config.block_size, threads=counts,
                                repeat=config.repeat, name=name, on_step=progress.step)
    except Exception as exc:  # noqa: BLE001 - reported in its section, the rest of the report stands
        log.warning("thread scaling failed: %s", exc)
        return {"available": False, "reason": f"{type(exc).__name__}: {exc}"}
    finally:
        progress.close()
    result["note"] = note + (" (--quick: 1 and 2 threads only)" if config.quick else "")
    return result


def _memory(config: BenchConfig, scenes: Sequence[BenchScene], extra: Sequence[SpeedInput], methods: Sequence[Method],
            onnx_specs: Sequence[dict], threads: int) -> list[dict[str, Any]]:
    from benchmarks.memprobe import measure_memory

    targets: list[tuple[str, np.ndarray, np.ndarray, int]] = []
    if config.quick:
        s = scenes[0]
        targets.append((s.name, s.left, s.right, disparity_range(s)))
    else:
        wanted = {(w, h, d) for w, h, d in config.sizes}
        for s in scenes:
            if (s.size[0], s.size[1], disparity_range(s)) in wanted:
                targets.append((s.name, s.left, s.right, disparity_range(s)))
        for inp in extra:
            targets.append((inp.name, inp.left, inp.right, inp.num_disparities))
        if not targets and scenes:
            s = scenes[0]
            targets.append((s.name, s.left, s.right, disparity_range(s)))
    rows = []
    for name, left, right, ndisp in targets:
        log.info("memory on %s (%dx%d, %d disparities): one child process per method%s", name, left.shape[1], left.shape[0], ndisp,
                 "" if not config.quick else " (quick: one for all)")
        setup = Setup(num_disparities=ndisp, min_disparity=0, block_size=config.block_size, threads=threads)
        res = measure_memory([m.name for m in methods], left, right, setup, onnx=onnx_specs, isolate=not config.quick)
        for m in methods:
            rows.append({"input": name, "width": int(left.shape[1]), "height": int(left.shape[0]), "num_disparities": ndisp,
                         "threads": threads, "method": m.name, "wxhxd_mb": left.shape[0] * left.shape[1] * ndisp / 2**20,
                         **res.get(m.name, {"error": "not measured"})})
    return rows


def _pipeline_inputs(config: BenchConfig, kitti: BenchScene | None) -> list[tuple[BenchScene, int, str]]:
    """(scene, num_disparities, note) of the pipeline's frame rate: the KITTI pair at 128 and a 640x480 pair at 64."""
    out: list[tuple[BenchScene, int, str]] = []
    if kitti is not None:
        out.append((kitti, 128, "the KITTI pair"))
    oakd = Path(config.data_dir) / "oakd" if config.data_dir is not None else None
    small = None
    if oakd is not None and oakd.is_dir():
        try:
            from stereo_classic.datasets import iter_oakd

            found = [BenchScene.from_scene(sc, source=str(oakd)) for sc in iter_oakd(oakd)]
            small = next((sc for sc in found if sc.name == "selfie"), found[0] if found else None)
        except Exception as exc:  # noqa: BLE001 - reported as a missing row, the rest stands
            log.warning("OAK-D scenes not loaded for the pipeline: %s", exc)
    if small is not None:
        out.append((small, 64, f"OAK-D scene {small.name}"))
    else:
        from benchmarks.scenes import demo_scene

        demo = demo_scene()
        factor = 640 / demo.size[0]
        size = (640, round(demo.size[1] * factor))
        small = BenchScene(f"{demo.name} x{factor:.3f}", cv2.resize(demo.left, size, interpolation=cv2.INTER_AREA),
                           cv2.resize(demo.right, size, interpolation=cv2.INTER_AREA), rig=demo.rig.scaled(factor),
                           source=demo.source)
        out.append((small, 64, f"the demo scene resized to {size[0]}x{size[1]} (no OAK-D scenes)"))
    return out


def _default_model(config: BenchConfig, models: Sequence[Path]) -> Path | None:
    """``yolox_nano`` (run's default detector) from ``--models``, else ``detectors.resolve_model()`` without download."""
    found = next((p for p in models if p.stem == "yolox_nano"), None)
    if found is not None or config.models_dir is not None:
        return found
    try:
        from detectors import resolve_model

        return Path(resolve_model(download=False))
    except Exception:  # noqa: BLE001 - no default model: the sections say not available
        return None


def _objects(config: BenchConfig, scenes: Sequence[BenchScene], arrays: dict, threads: Sequence[int]) -> dict[str, Any]:
    from benchmarks import objects

    out: dict[str, Any] = {}
    models = objects.find_detector_models(config.models_dir)
    default_model = _default_model(config, models)
    kitti = next((s for s in scenes if "kitti" in f"{s.name} {s.source}".lower() and s.rig is not None), None)
    moto = next((s for s in scenes if "motorcycle" in s.name.lower() and s.rig is not None), None)
    image = (kitti or moto or scenes[0]).left
    log.info("detector latency (%d model(s))", len(models))
    out["detectors"] = objects.detector_latency(models, image, threads=threads, repeat=config.repeat)
    out["pipeline"] = []
    if default_model is None:  # the frame rate is the pipeline's with its default detector, or not measured
        out["pipeline"].append({"available": False, "input": "every input",
                                "reason": "no yolox_nano model (give --models DIR or set STEREO_CLASSIC_MODELS)"})
    for scene, ndisp, note in _pipeline_inputs(config, kitti) if default_model is not None else ():
        for concurrent in (False, True):
            log.info("whole pipeline on %s (%d disparities, 2 threads, concurrent=%s)", scene.name, ndisp, concurrent)
            row = objects.pipeline_fps(scene, default_model, num_disparities=ndisp, threads=2, repeat=config.repeat,
                                       concurrent=concurrent)
            row.update({"input": note, "concurrent": concurrent})
            out["pipeline"].append(row)
    from benchmarks import pipeline_table

    log.info("pipeline table: run and guide, frame by frame (KITTI pair x30, OAK-D scenes)")
    out["pipeline_table"] = pipeline_table.measure(config.data_dir, default_model)
    out["distance"] = {}
    for scene in (kitti, moto):
        if scene is None:
            continue
        log.info("object distances on %s", scene.name)
        item = arrays["scenes"].get(scene.name, {})
        # fusion reads measured pixels only (as localize does with a DisparityMap): filled values are not measurements
        outputs = {**item.get("outputs", {}), **item.get("measured", {})}
        out["distance"][scene.name] = objects.distance_errors(scene, default_model, outputs)
    if not out["distance"]:
        out["distance"]["none"] = {"available": False, "reason": "neither the KITTI pair nor Motorcycle with calibration was loaded"}
    if kitti is None:
        out["kitti_objects"] = {"available": False, "reason": "the KITTI pair (kitti_object_pair) was not loaded"}
    else:
        from benchmarks.kitti_objects import kitti_object_benchmark

        log.info("per-object distance against the KITTI labels")
        try:
            out["kitti_objects"] = kitti_object_benchmark(Path(kitti.source), threads=2)
        except Exception as exc:  # noqa: BLE001 - reported in its section
            log.warning("KITTI object benchmark failed: %s", exc)
            out["kitti_objects"] = {"available": False, "reason": f"{type(exc).__name__}: {exc}"}
    return out
