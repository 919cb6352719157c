"""Who runs the chunks of a grid: threads in this process, or Dask distributed workers.

Every executor calls the same `run_part` on the same prepared scene, and the kernel has no
cross-run reductions or fastmath, so a run's row is bit-identical whichever executor ran it.
Results come back to the caller, which alone writes the Parquet parts (exactly once per chunk,
even when Dask runs a task twice after losing a worker).
"""

from __future__ import annotations

import logging
import socket
import time
import uuid
from collections.abc import Iterable, Iterator
from concurrent.futures import CancelledError
from dataclasses import dataclass

import numpy as np

from pounding_sweep.engine.driver import resolve_threads
from pounding_sweep.errors import ClusterError


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
    the scheduler; when every worker holding the prepared scene is lost (a node, or kills in quick
    succession), the scene is scattered again to the workers there are and the unfinished chunks are
    submitted again. The caller writes each part once, whoever ran it and however often. A scheduler
    that cannot be reached, or is lost and does not come back within `timeout_s`, is a ClusterError
    (one line; the parts written so far are kept and the same command resumes)."""

    name = "dask"
    #: scatters of the prepared scene without a finished part in between before the sweep gives up
    MAX_RESCATTERS = 5

    def __init__(self, address: str = "", workers: int = 0, window_per_worker: int = 3, timeout_s: float = 10.0):
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError as e:  # the optional extra is missing
            raise ClusterError(
                "[execution] executor = 'dask' needs the 'dask' extra: python -m pip install '.[dask]'"
            ) from e
        self.cluster = None
        self.address = address
        self.timeout_s = timeout_s
        # what Dask logs about lost workers or a lost scheduler is handled here, and said in one line if fatal
        names = ["distributed"] + [n for n in logging.root.manager.loggerDict if n.startswith("distributed.")]
        self._log_levels = {n: logging.getLogger(n).level for n in names}
        for n in names:
            logging.getLogger(n).setLevel(logging.CRITICAL)
        if address:
            _probe(address, timeout_s)
            try:
                self.client = Client(address, timeout=f"{timeout_s}s")
            except Exception as e:  # noqa: BLE001 - a timeout, or something else listening (a garbled handshake)
                raise ClusterError(
                    f"no Dask scheduler answered at {address} within {timeout_s:g} s ({type(e).__name__}: {_reason(e)})"
                ) from None
        else:
            n = workers or resolve_threads(0)
            self.cluster = LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=True,
                # a free port: None still binds 8787 and warns on stderr when it is taken (dask/distributed#8136)
                dashboard_address=":0",
                silence_logs=logging.CRITICAL,
                preload=["pounding_sweep.sweep.dask_worker"],  # workers ignore Ctrl-C: this process handles it
            )
            self.client = Client(self.cluster)
        self.workers = max(1, len(self.client.scheduler_info().get("workers", {})) or workers or 1)
        self.window = window_per_worker * self.workers

    def map(self, prep, chunks: Iterable[tuple[int, int, int]], done=None) -> Iterator[PartResult]:
        """The chunks' results as they complete. `done` is not called: the runs finish in other processes,
        and progress counts whole parts."""
        from dask.distributed import as_completed

        try:
            from distributed.scheduler import KilledWorker
        except ImportError:  # pragma: no cover - moved in some versions
            KilledWorker = ()  # noqa: N806
        todo = iter(chunks)
        done = as_completed()
        tag = uuid.uuid4().hex[:12]
        in_flight: dict = {}  # future -> chunk
        state = {"shared": self.client.scatter(prep, broadcast=True, hash=False), "attempt": 0}

        def submit(c) -> None:
            index, start, stop = c
            fut = self.client.submit(
                run_part,
                state["shared"],
                index,
                start,
                stop,
                1,
                0,
                key=f"pounding-part-{tag}-{state['attempt']}-{index}",
                retries=2,
            )
            in_flight[fut] = c
            done.add(fut)

        def submit_next() -> bool:
            c = next(todo, None)
            if c is not None:
                submit(c)
            return c is not None

        for _ in range(self.window):
            if not submit_next():
                break
        failures = 0
        for fut in done:
            c = in_flight.pop(fut, None)
            if c is None:  # a future of an earlier attempt, already submitted again
                continue
            try:
                result = fut.result()
            except (CancelledError, OSError) as e:  # the scene was lost with its workers, or the scheduler was
                if not isinstance(e, CancelledError) and fut.status == "error":
                    raise  # the task's own error, not the cluster's
                failures += 1
                lost = [c, *in_flight.values()]
                for f in list(in_flight):
                    f.release()
                in_flight.clear()
                self._recover(prep, state, failures)
                for c2 in sorted(lost):
                    submit(c2)
                continue
            except KilledWorker as e:
                raise ClusterError(
                    f"Dask: part {c[0]} (runs {c[1]}..{c[2] - 1}) was running on every worker that died "
                    f"({_reason(e)}); the parts written so far are kept: run the same command again to resume"
                ) from None
            failures = 0
            fut.release()
            yield result
            submit_next()

    def _recover(self, prep, state: dict, failures: int) -> None:
        """Scatter the prepared scene again, once the scheduler answers and a worker is there."""
        where = f"at {self.address}" if self.address else "of the LocalCluster"
        if failures > self.MAX_RESCATTERS:
            raise ClusterError(
                f"Dask: the workers {where} were lost {failures} times in a row; the parts written so far are "
                "kept: run the same command again to resume"
            )
        kept = "the parts written so far are kept: run the same command again to resume"
        deadline = time.monotonic() + self.timeout_s
        while time.monotonic() < deadline and self.client.status != "closed":
            if self.client.status == "running":
                try:
                    self.client.wait_for_workers(1, timeout=max(0.1, deadline - time.monotonic()))
                    state["shared"] = self.client.scatter(prep, broadcast=True, hash=False)
                    state["attempt"] += 1
                    return
                except TimeoutError:
                    if self.client.status == "running":
                        raise ClusterError(
                            f"Dask: lost every worker {where}, and none came back within {self.timeout_s:g} s; {kept}"
                        ) from None
                except (OSError, CancelledError):  # the connection to the scheduler broke: wait for it
                    pass
            time.sleep(0.1)
        raise ClusterError(
            f"Dask: lost the scheduler {where}, and it did not come back within {self.timeout_s:g} s; {kept}"
        )

    def close(self) -> None:
        for closer in (self.client.close, self.cluster.close if self.cluster is not None else None):
            if closer is None:
                continue
            try:
                closer()
            except Exception:  # noqa: BLE001 - a scheduler already gone: nothing left to close
                pass
        for n, level in self._log_levels.items():
            logging.getLogger(n).setLevel(level)


def _probe(address: str, timeout_s: float) -> None:
    """Fail fast, in one line, when nothing listens at a scheduler address (Dask would retry for its whole
    timeout and then report a timeout), or, at a tcp:// one, when what listens is not a Dask scheduler. A Dask
    server writes its handshake as soon as it accepts a connection (distributed.comm.core: both ends write
    theirs, then read), while Dask's client, having written its own, waits for that reply with no time limit:
    a server that accepts and says nothing (a web server waiting for its request) would hang the sweep for ever.
    So the probe waits up to `timeout_s` for the server's first bytes; none (or the connection closed) is a
    ClusterError naming the address."""
    scheme, sep, rest = address.partition("://")
    if not sep:
        scheme, rest = "tcp", address
    if scheme not in ("tcp", "tls", "ws", "wss"):
        return
    host, _, port = rest.rpartition(":")
    try:
        conn = socket.create_connection((host.strip("[]"), int(port)), timeout=min(timeout_s, 5.0))
    except (OSError, ValueError) as e:
        raise ClusterError(f"cannot reach a Dask scheduler at {address} ({_reason(e)})") from None
    with conn:
        if scheme != "tcp":  # TLS and websockets speak first from the client: nothing to wait for here
            return
        conn.settimeout(timeout_s)
        try:
            first = conn.recv(1)
        except OSError as e:  # socket.timeout is an OSError
            first, why = b"", f"no Dask handshake within {timeout_s:g} s ({_reason(e)})"
        else:
            why = "it closed the connection without a Dask handshake"
        if not first:
            raise ClusterError(
                f"no Dask scheduler at {address}: something listens there, but {why}; give the scheduler's address"
            )


def _reason(e: BaseException) -> str:
    text = (e.strerror if isinstance(e, OSError) and e.strerror else str(e)).strip().splitlines()
    return (text[0] if text else type(e).__name__)[:160]


def make_executor(kind: str, threads: int = 0, address: str = "", workers: int = 0, *, timeout_s: float):
    """The executor a scene's [execution] (or the command line) asks for (timeout_s: its dask_timeout_s)."""
    if kind == "dask":
        return DaskExecutor(address, workers, timeout_s=timeout_s)
    return LocalExecutor(threads)
