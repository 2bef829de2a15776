"""The whole pipeline as ``run`` and ``guide`` drive it, frame by frame: per stage median wall ms and process CPU ms
per frame, frames/s and latency (frame read to record written).

    python -m benchmarks.pipeline_table [--data ../shared/data] [--models ../shared/models]

Inputs: the KITTI pair read 30 times (1242x375, 128 disparities, as ``run --left ... --num-disparities 128 --save
json``) and the 12 OAK-D scenes in turn (640x480, 64 disparities: the dataset's range). Each frame is read from disk
(``cv2.imread``, the "read" stage), goes through one ``stereo_classic.Localizer`` (matcher defaults at 2 threads,
the default detector at one thread as ``run`` has it, frame checks on), then ``run``'s record (the objects as one
JSON line, appended and flushed: "write") or ``guide``'s (``Guide.update``: "guide", then the haptics record:
"write"). Latency is the time from the start of a frame's read to its record written; frames/s is frames over the
loop's wall time. The first frame (kernel compilation, session warm-up) is excluded. CPU ms are
``time.process_time`` deltas (every thread of the process), which are steadier than wall times across machines of a
kind.

The stages are measured with the frames taken one after another (each stage's CPU is its own). ``run`` and
``guide`` pipeline them by default (``Localizer.submit``: frame N + 1 is read and matched while frame N's
detection, fusion and checks run in the Localizer's worker, and frame N is written after): the rows "frames/s,
pipelined" and "latency, pipelined" are the same loop run that way, as the commands run it.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from stereo_classic.cli.run import DETECTOR_THREADS  # the detector's threads, as run and guide give it

__all__ = ["STAGES", "measure", "pipeline_inputs", "main"]

REPO = Path(__file__).resolve().parents[1]

#: Rows of the table, in order (those a command does not have are left out).
STAGES = ("read", "rectify", "disparity", "detect", "localize", "checks", "guide", "write", "total")


def pipeline_inputs(data_dir: Path | None, frames: int | None = None) -> list[dict[str, Any]]:
    """The inputs found under ``data_dir``: name, frames ((left path, right path) per frame), rig, disparities;
    ``frames``: at most that many of each (a quick look; the table's inputs are whole)."""
    from stereo_classic.datasets import iter_oakd, load_scene

    out: list[dict[str, Any]] = []
    if data_dir is None:
        return out
    kitti = Path(data_dir) / "kitti_object_pair"
    if (kitti / "left.png").is_file():
        scene = load_scene(kitti)
        out.append({"input": "KITTI pair x30", "frames": [(kitti / "left.png", kitti / "right.png")] * 30,
                    "rig": scene.rig, "num_disparities": 128, "size": list(scene.left.shape[1::-1])})
    oakd = Path(data_dir) / "oakd"
    if oakd.is_dir():
        scenes = list(iter_oakd(oakd))
        if scenes:
            out.append({"input": f"OAK-D {len(scenes)} scenes",
                        "frames": [(oakd / f"{s.name}_left.png", oakd / f"{s.name}_right.png") for s in scenes],
                        "rig": scenes[0].rig, "num_disparities": 64, "size": list(scenes[0].left.shape[1::-1])})
    for spec in out:
        spec["frames"] = spec["frames"][:frames]
    return out


def _read(path: Path) -> Any:
    import cv2

    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise FileNotFoundError(f"cannot read {path}")
    return image


def _record(command: str, guide: Any, result: Any, rig: Any, i: int) -> dict[str, Any]:
    if guide is not None:
        return guide.update(result, rig, i / 10.0, frame=f"{i:05d}").haptics_record()
    return {"frame": f"{i:05d}", "objects": result.objects.to_json(), "warnings": [w.to_json() for w in result.warnings]}


@contextmanager
def _warm_localizer(spec: dict[str, Any], model: Path, guided: bool) -> Iterator[Any]:
    """The input's Localizer (matcher at 2 threads, the detector as ``run`` has it), warmed up as ``run`` and
    ``guide`` are: the kernels of the matcher and of the frame checks' half-size looks loaded before the first frame
    (``pipeline.load_frame_kernels``: with a cold numba cache a look's kernels, compiled per range, otherwise compiled
    inside a timed frame whose checks were the first to look, 4.8 s in one OAK-D frame of the run at 2c7848d); the
    first frame through it (allocation, the detector's session); and, for ``guide``, every distinct frame through a
    throwaway Guide: its kernels compile on the first call that takes each of their paths (the floor, drop-offs,
    tracks), and with a cold numba cache those calls made the guide stage's mean CPU ten times its median on the
    OAK-D scenes."""
    from stereo_classic.guide import Guide
    from stereo_classic.matching import SGMParams
    from stereo_classic.pipeline import Localizer, load_frame_kernels, open_detector

    frames = spec["frames"]
    matcher = {"num_disparities": spec["num_disparities"], "threads": 2}
    load_frame_kernels(SGMParams(**matcher))
    with Localizer(spec["rig"], open_detector(str(model), threads=DETECTOR_THREADS), matcher) as loc:
        loc(_read(frames[0][0]), _read(frames[0][1]))
        if guided:
            guide = Guide()
            for i, (lp, rp) in enumerate(dict.fromkeys(frames)):
                guide.update(loc(_read(lp), _read(rp)), spec["rig"], i / 10.0, frame=f"warm-up {i}")
        yield loc


def _pipelined(spec: dict[str, Any], model: Path, command: str, tmp: Path) -> tuple[float, float]:
    """(frames/s, median latency ms) of the loop pipelined as ``run`` drives it: frame N + 1 read and submitted
    (matched here) before frame N's result is taken, its record made and written."""
    from stereo_classic.guide import Guide

    guide = Guide() if command == "guide" else None
    frames = spec["frames"]
    latency: list[float] = []
    with _warm_localizer(spec, model, guide is not None) as loc, \
            open(tmp / f"{command}_pipelined.jsonl", "w", encoding="utf-8") as sink:
        loop = time.perf_counter()
        pending = None  # (frame index, its start, its future)
        for i in range(len(frames) + 1):
            current = None
            if i < len(frames):
                t0 = time.perf_counter()
                left, right = _read(frames[i][0]), _read(frames[i][1])
                current = (i, t0, loc.submit(left, right))
            if pending is not None:
                j, t0, future = pending
                sink.write(json.dumps(_record(command, guide, future.result(), spec["rig"], j)) + "\n")
                sink.flush()
                latency.append((time.perf_counter() - t0) * 1e3)
            pending = current
        seconds = time.perf_counter() - loop
    return len(frames) / seconds, statistics.median(latency)


def _one(spec: dict[str, Any], model: Path, command: str, tmp: Path) -> dict[str, Any]:
    from stereo_classic.guide import Guide

    wall: dict[str, list[float]] = {}
    cpu: dict[str, list[float]] = {}
    latency: list[float] = []
    guide = Guide() if command == "guide" else None
    frames = spec["frames"]
    with _warm_localizer(spec, model, guide is not None) as loc, \
            open(tmp / f"{command}.jsonl", "w", encoding="utf-8") as sink:
        loop = time.perf_counter()
        for i, (lp, rp) in enumerate(frames):
            stamp: dict[str, float] = {}
            t0, c0 = time.perf_counter(), time.process_time()
            left, right = _read(lp), _read(rp)
            t1, c1 = time.perf_counter(), time.process_time()
            result = loc(left, right)
            stamp.update({f"w:{k}": v for k, v in result.timings_ms.items() if k != "total"})
            stamp.update({f"c:{k}": v for k, v in result.cpu_ms.items() if k != "total"})
            t2, c2 = time.perf_counter(), time.process_time()
            record = _record(command, guide, result, spec["rig"], i)
            t3, c3 = time.perf_counter(), time.process_time()
            sink.write(json.dumps(record) + "\n")
            sink.flush()
            t4, c4 = time.perf_counter(), time.process_time()
            stamp.update({"w:read": (t1 - t0) * 1e3, "c:read": (c1 - c0) * 1e3, "w:write": (t4 - t3) * 1e3,
                          "c:write": (c4 - c3) * 1e3, "w:total": (t4 - t0) * 1e3, "c:total": (c4 - c0) * 1e3})
            if guide is not None:
                stamp.update({"w:guide": (t3 - t2) * 1e3, "c:guide": (c3 - c2) * 1e3})
            for key, value in stamp.items():
                (wall if key[0] == "w" else cpu).setdefault(key[2:], []).append(float(value))
            latency.append((t4 - t0) * 1e3)
        seconds = time.perf_counter() - loop
    stages = {k: {"median_ms": statistics.median(wall[k]), "cpu_ms": statistics.fmean(cpu.get(k, [0.0]))}
              for k in STAGES if k in wall}
    fps_pipelined, latency_pipelined = _pipelined(spec, model, command, tmp)
    return {"available": True, "command": command, "input": spec["input"], "size": spec["size"],
            "num_disparities": spec["num_disparities"], "frames": len(frames), "fps": len(frames) / seconds,
            "latency_median_ms": statistics.median(latency), "stages": stages, "model": Path(model).name,
            "fps_pipelined": fps_pipelined, "latency_pipelined_ms": latency_pipelined}


def measure(data_dir: Path | None, model: Path | None, *, frames: int | None = None) -> dict[str, Any]:
    """The pipeline table's rows for ``run`` and ``guide`` on every input found (see the module docstring)."""
    how = (f"benchmarks.pipeline_table: each frame read from disk, Localizer (2 threads, detector at "
           f"{DETECTOR_THREADS} thread, checks on), then run's JSON record or Guide.update and its haptics record; "
           f"first frame excluded; stages taken one frame after another, and the loop again pipelined as run does")
    if model is None:
        return {"available": False, "reason": "no yolox_nano model (give --models DIR or set STEREO_CLASSIC_MODELS)"}
    specs = pipeline_inputs(data_dir, frames)
    if not specs:
        return {"available": False, "reason": "neither ../shared/data/kitti_object_pair nor oakd was found"}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for spec in specs:
            for command in ("run", "guide"):
                try:
                    rows.append(_one(spec, model, command, Path(tmp)))
                except Exception as exc:  # noqa: BLE001 - a row that cannot be measured says why
                    rows.append({"available": False, "command": command, "input": spec["input"],
                                 "reason": f"{type(exc).__name__}: {exc}"})
    return {"available": True, "rows": rows, "how": how}


def format_table(table: dict[str, Any]) -> str:
    """Markdown: one column per (command, input), rows: stage "median ms / CPU ms", frames/s, latency."""
    if not table.get("available"):
        return f"pipeline table not measured: {table.get('reason')}"
    rows = [r for r in table["rows"] if r.get("available")]
    head = [f"`{r['command']}` {r['input']} ({r['size'][0]}x{r['size'][1]}x{r['num_disparities']})" for r in rows]
    lines = ["| stage: median ms / CPU ms per frame | " + " | ".join(head) + " |",
             "|---|" + "---|" * len(rows)]
    for stage in STAGES:
        if any(stage in r["stages"] for r in rows):
            cells = [f"{r['stages'][stage]['median_ms']:.1f} / {r['stages'][stage]['cpu_ms']:.1f}"
                     if stage in r["stages"] else "-" for r in rows]
            lines.append(f"| {stage} | " + " | ".join(cells) + " |")
    lines.append("| frames/s | " + " | ".join(f"{r['fps']:.1f}" for r in rows) + " |")
    lines.append("| latency, read to record written (median ms) | "
                 + " | ".join(f"{r['latency_median_ms']:.0f}" for r in rows) + " |")
    if any("fps_pipelined" in r for r in rows):
        lines.append("| frames/s, pipelined (the commands' default) | "
                     + " | ".join(f"**{r['fps_pipelined']:.1f}**" if "fps_pipelined" in r else "-" for r in rows) + " |")
        lines.append("| latency, pipelined (median ms) | "
                     + " | ".join(f"{r['latency_pipelined_ms']:.0f}" if "fps_pipelined" in r else "-" for r in rows)
                     + " |")
    missing = [f"{r['command']} {r['input']}: {r['reason']}" for r in table["rows"] if not r.get("available")]
    return "\n".join(lines + ([""] + missing if missing else []))


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.pipeline_table", description=__doc__.splitlines()[0])
    p.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data")
    p.add_argument("--models", type=Path, default=REPO.parent / "shared" / "models")
    a = p.parse_args(argv)
    model = a.models / "yolox_nano.onnx"
    table = measure(a.data, model if model.is_file() else None)
    print(format_table(table))
    return 0 if table.get("available") else 1


if __name__ == "__main__":
    sys.exit(main())
