"""Preloaded into every worker process of the LocalCluster a sweep starts (DaskExecutor): Ctrl-C in the
terminal reaches the whole process group, and the workers, which the sweep closes itself, would each
print a KeyboardInterrupt traceback. They ignore SIGINT instead; the sweep's own process handles it."""

from __future__ import annotations

import signal


def dask_setup(worker) -> None:  # noqa: ARG001 - Dask's preload hook, called in the worker's main thread
    signal.signal(signal.SIGINT, signal.SIG_IGN)
