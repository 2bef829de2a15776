"""Where a frame's CPU time goes, kernel by kernel: ``perf`` samples of the matcher, named through a perf map of the
numba functions of this process.

    python -m benchmarks.kernel_profile [--data ../shared/data] [--scene kitti|oakd] [--disparities N]
                                        [--threads 1] [--frames 100] [--rate 4000]

Runs ``StereoMatcher.compute`` on the pair (greyscale, the matcher's defaults) ``--frames`` times while ``perf record
-e cpu-clock`` samples this process: a software event, which needs no hardware counters (virtual machines often
have none). numba's machine code has no symbols perf can read, so the addresses of every compiled function of
``stereo_classic`` (the kernels, their wrappers, and the callees linked into them) are written to
``/tmp/perf-<pid>.map`` first, perf's file for code made at run time, and removed afterwards. Prints, per function,
the CPU milliseconds a frame (samples / rate / frames, every thread together), nanoseconds a pixel and a pixel and
disparity, and its share of the samples; ``[k]`` marks the kernel's own functions (page faults, scheduling).

Needs Linux ``perf`` allowed to sample the process's own threads (``kernel.perf_event_paranoid`` at most 2, the usual
default). Timings of the wall clock live in ``sgm_speed`` and the report; this says which function to look at.
"""

from __future__ import annotations

import argparse
import gc
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterable, Mapping
from pathlib import Path

__all__ = ["main", "numba_symbols", "parse_report", "perf_available", "profile", "readable_name", "summarize",
           "write_perf_map"]

REPO = Path(__file__).resolve().parents[1]

#: Bytes a map entry spans at most (a function runs to the next known address, or this far).
_MAX_SPAN = 1 << 20


_COMPONENT = re.compile(r"(\d+)")


def readable_name(mangled: str) -> str:
    """``module.function`` of a numba symbol (``_ZN14stereo_classic8matching8_kernels4cost8row_costB3v29...E...`` ->
    ``cost.row_cost``; ``cfunc.`` and ``cpython.`` wrappers keep the prefix); other names as they are."""
    prefix, body = ("cfunc.", mangled[6:]) if mangled.startswith("cfunc._ZN") else ("", mangled)
    if not body.startswith("_ZN"):
        return mangled
    parts, i = [], 3
    while i < len(body) and body[i].isdigit():
        m = _COMPONENT.match(body, i)
        n = int(m.group(1))
        parts.append(body[m.end():m.end() + n])
        i = m.end() + n
    if parts and parts[0] == "cpython":
        prefix, parts = prefix + "cpython.", parts[1:]
    return prefix + ".".join(parts[-2:]) if parts else mangled


def numba_symbols(package: str = "stereo_classic") -> dict[int, str]:
    """Address -> readable name (``module.function``; ``cfunc.`` / ``cpython.`` for numba's wrappers) of every function
    in the machine code numba has compiled or loaded from its cache in this process for ``package``'s dispatchers,
    the callees linked into a kernel's code included (read from each code library's modules of definitions, numba's
    private ``_final_module`` and ``_shared_module``: the second is the one that holds them when loaded from the
    cache)."""
    from numba.core.registry import CPUDispatcher

    out: dict[int, str] = {}
    for obj in gc.get_objects():
        try:  # a weak proxy whose object is gone raises on any look (some test orders leave one behind)
            if not isinstance(obj, CPUDispatcher) or not getattr(obj.py_func, "__module__", "").startswith(package):
                continue
        except ReferenceError:
            continue
        for cres in obj.overloads.values():
            library = cres.library
            modules = [m for m in (getattr(library, "_final_module", None), getattr(library, "_shared_module", None))
                       if m is not None]
            for fn in (fn for m in modules for fn in m.functions):
                if fn.is_declaration:
                    continue
                try:  # the JIT's symbol table: the copy the callers' code runs
                    address = int(library.get_pointer_to_function(fn.name) or 0)
                except Exception:  # noqa: BLE001 - a name the JIT does not export
                    address = 0
                if address:
                    out[address] = readable_name(fn.name)
    return out


def write_perf_map(symbols: Mapping[int, str], pid: int | None = None, directory: Path = Path("/tmp")) -> Path:
    """``perf-<pid>.map`` in ``directory`` (perf reads /tmp): one line ``start size name`` a symbol, hexadecimal, each
    spanning to the next address (at most 1 MiB)."""
    pid = os.getpid() if pid is None else pid
    starts = sorted(symbols)
    path = directory / f"perf-{pid}.map"
    with open(path, "w", encoding="ascii") as fh:
        for i, start in enumerate(starts):
            span = min(starts[i + 1] - start, _MAX_SPAN) if i + 1 < len(starts) else _MAX_SPAN
            fh.write(f"{start:x} {span:x} {symbols[start]}\n")
    return path


_REPORT_LINE = re.compile(r"^\s*(\d+)\s+\[(.)\]\s+(.+?)\s*$")


def parse_report(text: str) -> dict[str, int]:
    """Samples per symbol from ``perf report --no-children --sort sym -g none -F sample,sym`` (``[k]`` symbols get a
    ``[k] `` prefix; lines that are not a sample count are skipped)."""
    out: dict[str, int] = {}
    for line in text.splitlines():
        m = _REPORT_LINE.match(line)
        if m is None or line.lstrip().startswith("#"):
            continue
        name = ("[k] " if m.group(2) == "k" else "") + m.group(3)
        out[name] = out.get(name, 0) + int(m.group(1))
    return out


def summarize(samples: Mapping[str, int], *, frames: int, rate: float, pixels: int, disparities: int,
              top: int = 15) -> list[dict]:
    """Rows for the ``top`` symbols by samples, then one "other" and one "total": ms of CPU a frame, ns a pixel, ns a
    pixel and disparity, share of the samples."""
    if frames < 1 or rate <= 0 or pixels < 1 or disparities < 1:
        raise ValueError(f"frames, rate, pixels and disparities must be positive, got {frames}, {rate}, {pixels}, "
                         f"{disparities}")
    total = sum(samples.values())

    def row(name: str, n: int) -> dict:
        ms = n / rate / frames * 1e3
        return {"function": name, "samples": n, "ms_per_frame": ms, "ns_per_pixel": ms * 1e6 / pixels,
                "ns_per_pixel_disparity": ms * 1e6 / pixels / disparities, "share": n / total if total else 0.0}

    ranked = sorted(samples.items(), key=lambda kv: (-kv[1], kv[0]))
    rows = [row(name, n) for name, n in ranked[:top]]
    rows.append(row("other", sum(n for _, n in ranked[top:])))
    rows.append(row("total", total))
    return rows


def perf_available() -> str | None:
    """None when ``perf record`` can attach to this process and sample it here (as ``profile`` does: a child attaching
    to its parent, which some kernels' ptrace rules forbid), else why not."""
    perf = shutil.which("perf")
    if perf is None:
        return "no `perf` on PATH"
    with tempfile.TemporaryDirectory() as tmp:
        try:
            run = subprocess.run([perf, "record", "-q", "-e", "cpu-clock", "-p", str(os.getpid()), "-o",
                                  str(Path(tmp) / "probe.data"), "--", "sleep", "0.1"],
                                 capture_output=True, text=True, timeout=60)
        except (OSError, subprocess.SubprocessError) as exc:
            return f"`perf record` failed: {exc}"
        if run.returncode != 0:
            said = (run.stderr or run.stdout).strip().splitlines()
            return f"`perf record` failed: {said[-1] if said else f'exit status {run.returncode}'}"
    return None


def profile(compute, frames: int, *, rate: int = 4000, warm: int = 2) -> tuple[dict[str, int], float]:
    """(samples per symbol, wall seconds) of ``frames`` calls of ``compute()`` (after ``warm`` unsampled ones that
    compile or load the kernels), ``perf record -e cpu-clock -F rate`` attached to this process, the perf map written
    before and removed after. Raises RuntimeError when perf cannot run."""
    why = perf_available()
    if why is not None:
        raise RuntimeError(why)
    perf = shutil.which("perf") or "perf"
    for _ in range(max(1, warm)):
        compute()
    map_path = write_perf_map(numba_symbols())
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "perf.data"
        rec = subprocess.Popen([perf, "record", "-q", "-e", "cpu-clock", "-F", str(int(rate)), "-p", str(os.getpid()),
                                "-o", str(data)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        try:
            time.sleep(0.5)  # perf attaches to every thread before the first call
            t0 = time.perf_counter()
            for _ in range(frames):
                compute()
            seconds = time.perf_counter() - t0
        finally:
            rec.send_signal(signal.SIGINT)
            _, err = rec.communicate(timeout=120)
        try:
            if rec.returncode not in (0, 130, -signal.SIGINT) or not data.exists():
                raise RuntimeError(f"`perf record` failed ({rec.returncode}): {err.strip()}")
            report = subprocess.run([perf, "report", "-i", str(data), "--no-children", "--sort", "sym", "-g", "none",
                                     "-F", "sample,sym"], capture_output=True, text=True, timeout=600)
            if report.returncode != 0:
                raise RuntimeError(f"`perf report` failed: {report.stderr.strip()}")
        finally:
            map_path.unlink(missing_ok=True)
    return parse_report(report.stdout), seconds


def format_rows(rows: Iterable[dict]) -> str:
    lines = [f"{'function':44s} {'ms/frame':>9s} {'ns/px':>8s} {'ns/px/d':>8s} {'share':>6s}"]
    for r in rows:
        lines.append(f"{r['function'][:44]:44s} {r['ms_per_frame']:9.3f} {r['ns_per_pixel']:8.2f} "
                     f"{r['ns_per_pixel_disparity']:8.3f} {100 * r['share']:5.1f}%")
    return "\n".join(lines)


def main(argv=None) -> int:
    from benchmarks.sgm_speed import SCENES, load_scene_grey
    from stereo_classic.matching import SGMParams, StereoMatcher

    ap = argparse.ArgumentParser(prog="python -m benchmarks.kernel_profile", description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data")
    ap.add_argument("--scene", default="kitti", choices=sorted(SCENES),
                    help="kitti (1242x375, 128 disparities) or oakd (living room, 640x480, 64)")
    ap.add_argument("--disparities", type=int, default=None, help="default: 128 for kitti, 64 for oakd")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--rate", type=int, default=4000, help="samples a second a thread (default 4000)")
    a = ap.parse_args(argv)
    if a.frames < 1 or a.rate < 1 or a.threads < 1:
        ap.error(f"--frames, --rate and --threads must be positive, got {a.frames}, {a.rate}, {a.threads}")
    why = perf_available()
    if why is not None:
        print(f"error: {why}; this probe needs Linux perf (docs/development.md)", file=sys.stderr)
        return 1
    try:
        left, right = load_scene_grey(a.data, a.scene)
    except FileNotFoundError as exc:
        print(f"error: {exc} (--data)", file=sys.stderr)
        return 1
    disparities = a.disparities or (128 if a.scene == "kitti" else 64)
    matcher = StereoMatcher(SGMParams(num_disparities=disparities, threads=a.threads))
    samples, seconds = profile(lambda: matcher.compute(left, right), a.frames, rate=a.rate)
    wall = seconds / a.frames * 1e3
    h, w = left.shape
    print(f"{a.scene} {w}x{h}, {disparities} disparities, {a.threads} thread(s), {a.frames} frames, perf cpu-clock "
          f"at {a.rate} Hz; about {wall:.1f} ms a frame of wall time with the sampling")
    print(format_rows(summarize(samples, frames=a.frames, rate=a.rate, pixels=h * w, disparities=disparities)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
