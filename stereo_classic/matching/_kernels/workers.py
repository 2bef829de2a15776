"""The kernels' worker threads: one shared pool, and the ways the driver hands stripes (or other tasks) to it.

The calling thread is always worker 0 and the pool's threads the others; which worker runs a task must never
change its result (the decomposition is fixed by the image size: see ``core.stripes``).
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

__all__ = ["CPUS_RECHECK_S", "pool", "run_chained", "run_stripes", "run_tasks", "usable_cpus"]

_POOL: ThreadPoolExecutor | None = None
_POOL_LOCK = threading.Lock()
_POOL_SIZE = 0


#: Seconds ``usable_cpus`` keeps what it read (a frame asks it about twenty times; each read opens files in /sys).
CPUS_RECHECK_S = 1.0
_cpus_read: list[float] = [0.0, -math.inf]  # [count, time.monotonic() of the read]


def usable_cpus() -> int:
    """CPUs this process may run on: the affinity mask, capped by a cgroup v2/v1 CPU quota when one is set (read
    again once ``CPUS_RECHECK_S`` have passed)."""
    now = time.monotonic()
    if now - _cpus_read[1] >= CPUS_RECHECK_S:
        _cpus_read[:] = [_read_usable_cpus(), now]
    return int(_cpus_read[0])


def _read_usable_cpus() -> int:
    try:
        n = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        n = os.cpu_count() or 1
    quota = None
    try:
        with open("/sys/fs/cgroup/cpu.max", encoding="ascii") as fh:
            q, period = fh.read().split()[:2]
            if q != "max":
                quota = float(q) / float(period)
    except (OSError, ValueError):
        try:
            with open("/sys/fs/cgroup/cpu/cpu.cfs_quota_us", encoding="ascii") as fh:
                q_us = float(fh.read())
            with open("/sys/fs/cgroup/cpu/cpu.cfs_period_us", encoding="ascii") as fh:
                p_us = float(fh.read())
            if q_us > 0 and p_us > 0:
                quota = q_us / p_us
        except (OSError, ValueError):
            pass
    if quota is not None:
        n = min(n, max(1, int(quota + 0.5)))
    return max(1, n)


def pool(workers: int = 1) -> ThreadPoolExecutor:
    """The shared worker pool, with at least ``workers`` threads."""
    global _POOL, _POOL_SIZE
    with _POOL_LOCK:
        if _POOL is None or _POOL_SIZE < workers:
            old = _POOL
            _POOL = ThreadPoolExecutor(max_workers=max(1, workers), thread_name_prefix="sgm")
            _POOL_SIZE = max(1, workers)
            if old is not None:
                old.shutdown(wait=False)
        return _POOL


def _on_workers(n_workers: int, work: Callable[[int], None]) -> None:
    """``work(t)`` for t in 0 .. n_workers - 1: worker 0 on the calling thread, the others on the pool; returns
    when all are done (raising the first error of a pool worker)."""
    futures = [pool(n_workers - 1).submit(work, t) for t in range(1, n_workers)]
    try:
        work(0)
    finally:
        for f in futures:
            f.result()


def run_stripes(bands: list[tuple[int, int]], n_workers: int, stripe: Callable[[int, int, int], Any]) -> list[Any]:
    """Call ``stripe(t, y0, y1)`` for every band (:func:`run_tasks`); the results in band order."""
    return run_tasks(bands, n_workers, lambda t, band: stripe(t, *band))


def run_tasks(tasks: list[Any], n_workers: int, fn: Callable[[int, Any], Any]) -> list[Any]:
    """Call ``fn(t, task)`` for every task, on ``n_workers`` workers (the calling thread is worker 0, the others
    pool threads; ``t`` names the worker, so that it can use buffers of its own). Each worker takes the next
    task in turn; which worker runs a task must not change its result. Returns the results in task order."""
    results: list[Any] = [None] * len(tasks)
    if n_workers <= 1:
        for i, task in enumerate(tasks):
            results[i] = fn(0, task)
        return results
    queue = iter(enumerate(tasks))
    lock = threading.Lock()

    def work(t: int) -> None:
        while True:
            with lock:
                item = next(queue, None)
            if item is None:
                return
            i, task = item
            results[i] = fn(t, task)

    _on_workers(n_workers, work)
    return results


def run_chained(n_items: int, n_workers: int, fn: Callable[[int, int, bool], Any],
                follow: Callable[[int, int], Any] | None = None) -> None:
    """Call ``fn(t, i, after)`` for i in 0 .. n_items - 1 on ``n_workers`` workers, each worker going down a run of
    consecutive items: ``after`` says that worker ``t``'s previous call was item i - 1 (so it may reuse what that
    call left in the worker's buffers). Worker t starts at item ``t * n_items // n_workers``; when its next item is
    taken (or there is none) it takes the last free item. Which worker runs an item, and whether ``after`` is true,
    must not change the result.

    ``follow(t, i)``: a second step for item i, run once ``fn`` has done it, on whichever worker is free: a worker
    whose run is broken does the follow-ups of finished items before it takes a free item out of turn, and waits
    for them while others still run theirs (so the follow-ups fill the time a worker would idle while the last
    items finish). Each item's follow-up runs once, on one worker, after its ``fn`` has returned."""
    if n_workers <= 1:
        for i in range(n_items):
            fn(0, i, i > 0)
            if follow is not None:
                follow(0, i)
        return
    taken = [False] * n_items
    ready: list[int] = []  # items done by fn whose follow-up no worker has taken
    state = {"left": n_items, "failed": False}  # items not yet done by fn; a worker raised
    cond = threading.Condition()
    starts = [t * n_items // n_workers for t in range(n_workers)]

    def next_job(nxt: int) -> tuple[str, int]:  # under cond
        while True:
            if state["failed"]:
                return "stop", -1
            if 0 <= nxt < n_items and not taken[nxt]:
                taken[nxt] = True
                return "item", nxt
            if ready:
                return "follow", ready.pop(0)
            free = [i for i in range(n_items) if not taken[i]]
            if free:
                taken[free[-1]] = True
                return "item", free[-1]
            if follow is None or state["left"] == 0:
                return "stop", -1
            cond.wait()

    def work(t: int) -> None:
        prev = -2
        nxt = starts[t]
        try:
            while True:
                with cond:
                    kind, i = next_job(nxt)
                if kind == "stop":
                    return
                if kind == "follow":
                    follow(t, i)
                    continue
                fn(t, i, i == prev + 1)
                with cond:
                    state["left"] -= 1
                    if follow is not None:
                        ready.append(i)
                    cond.notify_all()
                prev, nxt = i, i + 1
        except BaseException:
            with cond:
                state["failed"] = True
                cond.notify_all()
            raise

    _on_workers(n_workers, work)
