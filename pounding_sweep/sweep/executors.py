"""Who runs the chunks of a grid: threads in this process, or Dask distributed workers.

Every executor calls the same `run_part` on the same prepared scene, and the kernel has no
cross-run reductions or fastmath, so a run's row is bit-identical whichever executor ran it.
Results come back to the caller, which alone writes the Parquet parts (exactly once per chunk,
even when Dask runs a task twice after losing a worker).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from pounding_sweep.engine.driver import resolve_threads


@dataclass
class PartResult:
    """One chunk of the grid, integrated: the kernel's arrays for runs [start, stop)."""

    index: int
    start: int
    stop: int
    params: dict
    metrics: np.ndarray
    run_time: np.ndarray
    hist: np.ndarray | None
    scores: np.ndarray | None
    derived: dict


def run_part(prep, index: int, start: int, stop: int, threads: int = 1, batch_runs: int = 0, done=None) -> PartResult:
    """Integrate runs [start, stop) of the prepared scene (the unit of work of every executor); `done(n)`:
    called as groups of n runs finish (engine.driver.run_chunk)."""
    params = prep.grid.chunk(start, stop)
    metrics, run_time, hist, scores, derived = prep.run(params, threads, batch_runs, done)
    return PartResult(index, start, stop, params, metrics, run_time, hist, scores, derived)


class LocalExecutor:
    """Chunks one after another in this process, each on a pool of `threads` threads."""

    name = "local"

    def __init__(self, threads: int = 0):
        self.threads = resolve_threads(threads)
        self.workers = self.threads

    def map(self, prep, chunks: Iterable[tuple[int, int, int]], done=None) -> Iterator[PartResult]:
        """The chunks' results in order; `done(n)` is called from the threads as groups of n runs finish."""
        for index, start, stop in chunks:
            yield run_part(prep, index, start, stop, self.threads, prep.scene.execution.batch_runs, done)

    def close(self) -> None:
        pass


class DaskExecutor:
    """Chunks as Dask tasks: on an embedded LocalCluster (worker processes with one thread each, so
    kernel threads never oversubscribe the cores) or on the scheduler at `address`.

    The prepared scene (structure, resampled records, experiment samples) is scattered to every
    worker once; each task then carries only its chunk bounds. At most `window` tasks are in
    flight, so memory stays flat however large the grid. A task lost with its worker is rerun by
    the scheduler; the caller still writes each part once."""

    name = "dask"

    def __init__(self, address: str = "", workers: int = 0, window_per_worker: int = 3):
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError as e:  # the optional extra is missing
            raise RuntimeError("the Dask executor needs the 'dask' extra: python -m pip install '.[dask]'") from e
        self.cluster = None
        if address:
            self.client = Client(address, timeout="30s")
        else:
            n = workers or resolve_threads(0)
            self.cluster = LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=logging.ERROR
            )
            self.client = Client(self.cluster)
        self.workers = max(1, len(self.client.scheduler_info().get("workers", {})) or workers or 1)
        self.window = window_per_worker * self.workers

    def map(self, prep, chunks: Iterable[tuple[int, int, int]], done=None) -> Iterator[PartResult]:
        """The chunks' results as they complete. `done` is not called: the runs finish in other processes,
        and progress counts whole parts."""
        from dask.distributed import as_completed

        shared = self.client.scatter(prep, broadcast=True, hash=False)
        todo = iter(chunks)
        done = as_completed()
        tag = f"{prep.scene.config_hash()[:12]}-{os.getpid()}"

        def submit_next() -> bool:
            c = next(todo, None)
            if c is None:
                return False
            index, start, stop = c
            done.add(
                self.client.submit(
                    run_part, shared, index, start, stop, 1, 0, key=f"pounding-part-{tag}-{index}", retries=2
                )
            )
            return True

        for _ in range(self.window):
            if not submit_next():
                break
        for fut in done:
            result = fut.result()
            fut.release()
            yield result
            submit_next()

    def close(self) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def make_executor(kind: str, threads: int = 0, address: str = "", workers: int = 0):
    """The executor a scene's [execution] (or the command line) asks for."""
    if kind == "dask":
        return DaskExecutor(address, workers)
    return LocalExecutor(threads)
