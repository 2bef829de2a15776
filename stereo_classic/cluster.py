"""Frames as tasks on a Dask cluster: ``run --executor dask`` (needs the ``dask`` extra).

:class:`DaskExecutor` connects to a cluster (a scheduler address ``tcp://host:8786`` or a scheduler file) or starts
a :class:`distributed.LocalCluster` sized to this machine, and runs the frames of a
:func:`stereo_classic.runner.run_source` there:

* **Descriptions travel, not images**: each task gets a :class:`~stereo_classic.sources.FrameRef` (paths, scene
  folder, loader) and reads the images on the worker. The run's :class:`~stereo_classic.runner.FrameProcessor`
  (rig, matcher settings, detector spec) is scattered to every worker once.
* **Warm workers**: each worker process keeps one processor per run (one Localizer: the numba kernels compiled,
  the ONNX session open) and processes one frame at a time with as many kernel threads as the worker has.
* **Bounded**: at most ``window`` frames are submitted or waiting to be written (default twice the cluster's
  threads), so memory stays flat over any number of frames.
* **Written here, in order**: results come back as they complete and are written by this process, in frame
  order, through the same :class:`~stereo_classic.outputs.FrameWriter` as a serial run: the output folder is the
  same byte for byte, ``--resume`` works across executors, and nothing on the workers needs the output folder.
  A worker that dies mid-frame loses nothing: the scheduler runs its frames again elsewhere, and each frame is
  written once, when its result arrives.

Usage (starts processes, so not a doctest)::

    with DaskExecutor(n_workers=2, threads_per_worker=1) as ex:
        summary = run_source(source, writer, params_for=..., detector=DetectorSpec("yolox_nano"), executor=ex)
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import importlib
import logging
import threading
import time
import uuid
from collections import deque
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any, Self

from stereo_classic.runner import DetectorSpec, FrameOutput, FrameProcessor
from stereo_classic.sources import FrameRef

__all__ = ["INSTALL_HINT", "LOST_RESULT_RETRIES", "DaskExecutor", "DaskNotInstalledError", "import_distributed"]

log = logging.getLogger("stereo_classic.run")

#: How often a frame whose result was lost with a worker is submitted again before the run fails.
LOST_RESULT_RETRIES = 3

#: The one line that says what to install.
INSTALL_HINT = ('--executor dask needs Dask: pip install "stereo-classic[dask]" (which installs "dask[distributed]")')


class DaskNotInstalledError(ImportError):
    """``dask.distributed`` is not installed; the message says what to install."""


def import_distributed() -> Any:
    """The ``distributed`` module, or :class:`DaskNotInstalledError` saying in one line what to install.

    The level the caller gave the ``distributed`` logger (the command line: WARNING unless ``-v``) is kept:
    importing it sets its own (INFO, about 50 lines a run)."""
    level = logging.getLogger("distributed").level
    try:
        module = importlib.import_module("distributed")
    except ImportError:
        raise DaskNotInstalledError(INSTALL_HINT) from None
    if level:
        logging.getLogger("distributed").setLevel(level)
    return module


# --------------------------------------------------------------------------------------------------
# the worker's side
# --------------------------------------------------------------------------------------------------
_WORKER_CACHE: dict[str, tuple[FrameProcessor, threading.Lock]] = {}
_WORKER_CACHE_LOCK = threading.Lock()


def _worker_threads() -> int | None:
    try:
        from distributed import get_worker

        worker = get_worker()
    except (ImportError, ValueError):
        return None
    n = getattr(worker, "nthreads", None) or getattr(getattr(worker, "state", None), "nthreads", None)
    return int(n) if n else None


def _worker_address() -> str:
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return "local"


def process_on_worker(processor: FrameProcessor, token: str, ref: FrameRef) -> FrameOutput:
    """The task: read and process one frame with this worker's processor for run ``token`` (made on first use,
    with the worker's thread count, and kept: one Localizer per worker process per run)."""
    with _WORKER_CACHE_LOCK:
        entry = _WORKER_CACHE.get(token)
        if entry is None:
            for old, _ in _WORKER_CACHE.values():  # an earlier run's processor: free its buffers
                old.close()
            _WORKER_CACHE.clear()
            threads = _worker_threads() or processor.threads
            entry = _WORKER_CACHE[token] = (dataclasses.replace(processor, threads=threads), threading.Lock())
    local, lock = entry
    with lock:  # one frame at a time per worker: the kernels use the worker's threads
        start = time.perf_counter()
        out = local.process_ref(ref)
        seconds = time.perf_counter() - start
    return dataclasses.replace(out, worker=_worker_address(), seconds=seconds)


# --------------------------------------------------------------------------------------------------
# the client's side
# --------------------------------------------------------------------------------------------------
class DaskExecutor:
    """Run frames on a Dask cluster; use as a context manager (it connects and, for a local cluster, starts and
    stops the workers).

    Parameters
    ----------
    scheduler : str, optional
        ``tcp://host:port`` of a running scheduler, or the path of a scheduler file (``dask scheduler
        --scheduler-file``). None: start a LocalCluster (worker processes) on this machine.
    n_workers, threads_per_worker : int, optional
        Size of the local cluster (default: Dask's choice for this machine).
    window : int, optional
        Frames submitted or waiting to be written at most (default: twice the cluster's threads, at least 2).
    on_dashboard : callable, optional
        Called with the dashboard address of a started local cluster (the command line prints it).

    Raises
    ------
    DaskNotInstalledError
        ``dask[distributed]`` is not installed.
    """

    def __init__(self, scheduler: str | None = None, *, n_workers: int | None = None,
                 threads_per_worker: int | None = None, window: int | None = None,
                 on_dashboard: Callable[[str], None] | None = None) -> None:
        self.distributed = import_distributed()
        for name, value in (("n_workers", n_workers), ("threads_per_worker", threads_per_worker), ("window", window)):
            if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
                raise ValueError(f"`{name}` must be a positive integer or None, got {value!r}")
        self.scheduler = scheduler
        self.n_workers, self.threads_per_worker, self.window = n_workers, threads_per_worker, window
        self.on_dashboard = on_dashboard
        self.cluster: Any = None
        self.client: Any = None

    def __enter__(self) -> Self:
        dd = self.distributed
        if self.scheduler:
            target = str(self.scheduler)
            if "://" not in target and Path(target).is_file():
                self.client = dd.Client(scheduler_file=target)
            else:
                try:
                    self.client = dd.Client(target, timeout="20s")
                except OSError as exc:
                    raise ConnectionError(f"--scheduler {target}: cannot connect to a Dask scheduler there ({exc})"
                                          ) from None
        else:
            kwargs: dict[str, Any] = {"processes": True, "dashboard_address": ":0"}
            if self.n_workers:
                kwargs["n_workers"] = self.n_workers
            if self.threads_per_worker:
                kwargs["threads_per_worker"] = self.threads_per_worker
            self.cluster = dd.LocalCluster(**kwargs)
            self.client = dd.Client(self.cluster)
            if self.on_dashboard is not None:
                self.on_dashboard(str(self.client.dashboard_link))
        return self

    def __exit__(self, *exc: object) -> None:
        if self.client is not None:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()
        self.client = self.cluster = None

    @property
    def threads(self) -> int:
        """Threads in the cluster, all workers together."""
        return int(sum(self.client.nthreads().values())) if self.client is not None else 0

    def run(self, refs: Iterable[FrameRef], processor: FrameProcessor, take: Callable[[FrameOutput], None]) -> None:
        """Process ``refs`` on the cluster and hand each output to ``take`` in frame order, as results arrive.

        The first frame that raises (``processor.on_error == "stop"``) cancels what is in flight and raises here.
        A frame whose result is lost without an error of its own (the worker holding it died after it finished, and
        the scheduler forgot the key: the future comes back cancelled) is submitted again, at most
        :data:`LOST_RESULT_RETRIES` times; frames are written here, in order, so a frame run twice is written once.
        """
        if self.client is None:
            raise RuntimeError("DaskExecutor.run needs `with DaskExecutor(...) as ex:` first")
        dd = self.distributed
        client = self.client
        if isinstance(processor.detector, DetectorSpec) or processor.detector is None:
            shipped = processor
        else:
            raise ValueError("`detector`: a Dask run needs a DetectorSpec (opened on each worker) or None, "
                             f"got an opened {type(processor.detector).__name__}")
        window = self.window or max(2, 2 * self.threads)
        token = uuid.uuid4().hex
        remote = client.scatter(shipped, broadcast=True, hash=False)
        done = dd.as_completed()
        in_flight: set[Any] = set()
        ready: dict[int, FrameOutput] = {}
        order: deque[int] = deque()
        source = iter(refs)
        exhausted = False

        ref_of: dict[str, FrameRef] = {}  # future key -> its frame
        lost: dict[int, int] = {}

        def submit(ref: FrameRef) -> None:
            tries = lost.get(ref.index, 0)
            key = f"stereo-frame-{ref.index}-{token}" + (f"-again{tries}" if tries else "")
            future = client.submit(process_on_worker, remote, token, ref, pure=False, key=key)
            ref_of[future.key] = ref
            in_flight.add(future)
            done.add(future)

        def fill() -> None:
            nonlocal exhausted
            while not exhausted and len(in_flight) + len(ready) < window:
                ref = next(source, None)
                if ref is None:
                    exhausted = True
                    return
                order.append(ref.index)
                submit(ref)

        try:
            fill()
            for future in done:
                in_flight.discard(future)
                ref = ref_of.pop(future.key)
                try:
                    out: FrameOutput = future.result()  # the worker's error, re-raised (on_error="stop")
                except concurrent.futures.CancelledError:  # lost with a worker, not failed: run it again
                    lost[ref.index] = lost.get(ref.index, 0) + 1
                    if lost[ref.index] > LOST_RESULT_RETRIES:
                        raise RuntimeError(f"frame {ref.index}: its result was lost {lost[ref.index]} times (workers "
                                           "dying or the scheduler restarting); nothing of it was written") from None
                    log.warning("frame %d: its result was lost with a worker; running it again", ref.index)
                    submit(ref)
                    continue
                ready[out.index] = out
                while order and order[0] in ready:
                    take(ready.pop(order.popleft()))
                fill()
        finally:
            if in_flight:
                client.cancel(list(in_flight))
            client.cancel([remote])
