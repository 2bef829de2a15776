"""Timing harness: first call (JIT compile / cache load) apart, then interleaved repetitions.

Speed claims are ratios measured side by side in one run: every repetition runs each method once,
in a rotating order, so slow drift of a shared machine hits all methods alike. The first call of a
runner is timed on its own (it includes numba compilation or cache loading and buffer allocation)
and excluded from the statistics.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass

__all__ = ["TimingResult", "time_interleaved", "summarize", "mde_per_s"]


@dataclass(frozen=True)
class TimingResult:
    """Times of one runner, milliseconds."""

    first_call_ms: float
    times_ms: tuple[float, ...]
    #: CPU time of each timed call (``time.process_time``: every thread of the process), milliseconds
    cpu_ms: tuple[float, ...] = ()

    @property
    def median_ms(self) -> float | None:
        return statistics.median(self.times_ms) if self.times_ms else None

    @property
    def cpu_median_ms(self) -> float | None:
        return statistics.median(self.cpu_ms) if self.cpu_ms else None

    @property
    def min_ms(self) -> float | None:
        return min(self.times_ms) if self.times_ms else None

    @property
    def max_ms(self) -> float | None:
        return max(self.times_ms) if self.times_ms else None


def mde_per_s(width: int, height: int, num_disparities: int, ms: float | None) -> float | None:
    """Million disparity estimates per second: W x H x D / seconds / 1e6."""
    if ms is None or ms <= 0:
        return None
    return width * height * num_disparities / (ms / 1000.0) / 1e6


def time_interleaved(
    runners: Mapping[str, Callable[[], object]],
    repeat: int,
    *,
    first_call: bool = True,
    on_step: Callable[[str], None] | None = None,
    pause_s: float = 0.02,
) -> dict[str, TimingResult]:
    """Time each zero-argument callable ``repeat`` times, interleaved, after one untimed-for-stats first call.

    Parameters
    ----------
    runners : mapping name -> callable
    repeat : int
        Timed repetitions per runner (>= 1).
    first_call : bool
        Run (and time separately) one call per runner before the repetitions.
    on_step : callable, optional
        Called with the runner's name after every call (progress bars).
    pause_s : float
        Sleep before every timed call (not timed), so that no method pays for the threads of the one
        before it still winding down (OpenCV's pool spins a while after a job).

    Returns
    -------
    dict name -> TimingResult
    """
    if isinstance(repeat, bool) or not isinstance(repeat, int) or repeat < 1:
        raise ValueError(f"`repeat` must be an integer >= 1, got {repeat!r}")
    if not pause_s >= 0:
        raise ValueError(f"`pause_s` must be >= 0 seconds, got {pause_s!r}")
    names = list(runners)
    first: dict[str, float] = {}
    if first_call:
        for name in names:
            t0 = time.perf_counter()
            runners[name]()
            first[name] = (time.perf_counter() - t0) * 1000.0
            if on_step:
                on_step(name)
    times: dict[str, list[float]] = {n: [] for n in names}
    cpu: dict[str, list[float]] = {n: [] for n in names}
    for rep in range(repeat):
        shift = rep % len(names) if names else 0
        for name in names[shift:] + names[:shift]:
            if pause_s > 0:
                time.sleep(pause_s)
            c0 = time.process_time()
            t0 = time.perf_counter()
            runners[name]()
            times[name].append((time.perf_counter() - t0) * 1000.0)
            cpu[name].append((time.process_time() - c0) * 1000.0)
            if on_step:
                on_step(name)
    return {n: TimingResult(first.get(n, float("nan")), tuple(times[n]), tuple(cpu[n])) for n in names}


def summarize(result: TimingResult, width: int, height: int, num_disparities: int) -> dict[str, float | None | list[float]]:
    """JSON-ready numbers of one timing: median/min/max ms, M disparity-estimates/s, first call, raw times."""
    return {
        "median_ms": result.median_ms,
        "min_ms": result.min_ms,
        "max_ms": result.max_ms,
        "mde_per_s": mde_per_s(width, height, num_disparities, result.median_ms),
        "cpu_median_ms": result.cpu_median_ms,
        "first_call_ms": result.first_call_ms if result.first_call_ms == result.first_call_ms else None,
        "times_ms": list(result.times_ms),
    }
