"""How long a kernel's compile takes (a first one, or one with its largest piece cached): the range measured on
2-core machines, and the last time on this one.

The command line says it when a compile starts (progress.py); the record lives beside the kernel cache
(engine/jit.py `_root`). Compiles nothing (engine/jit.py NOT_COMPILED): editing a figure here does not make every
user compile the kernels again.
"""

from __future__ import annotations

import json
import os

from pounding_sweep.engine import jit

#: how long compiling a kernel took on quiet 2-core x86-64 machines, (fastest, slowest) of those measured: AMD Zen 4
#: and Zen 3 (benchmarks/bench_compile.py; wall time, with engine/aside.py's second process; Zen 3 compiles about
#: twice as slowly), for the first compile on a machine; later ones say how long the last one took here
#: (COMPILE_TIMES)
TYPICAL_COMPILE_S = {
    "lanes": (24.0, 47.0),
    # the lane kernel again with its step cached (a new pair of floor counts: its two vector loops, engine/lanes/
    # loops.py); benchmarks/bench_compile.py's "a new pair" case: 4.0-5.0 s on the Zen 4 (d71796d; not measured
    # since on the Zen 3, which compiles about twice as slowly: the upper end is that guess)
    "lanes_again": (4.0, 10.0),
    # the scalar kernel since 2c0dfb7 (its event-step pieces, run's end and scoring in the second process): 8.3 s
    # (histories) and 8.3-11.8 s (README scene) on the Zen 4, whose speed moved by a fifth within minutes that
    # session; the Zen 3's twice that
    "scalar": (8.0, 20.0),
    "scalar_scored": (8.0, 22.0),
    # the Hertz-type kernel since 33ba54a (its contact solve and event-step pieces in the second process too): 10.1-
    # 10.3 s, 9.4-9.9 s with scoring (compile events, the README scene cut to 10 ms with law = "hertzdamp") on the
    # Zen 4; the Zen 3's twice that
    "nonlinear": (10.0, 21.0),
    "nonlinear_scored": (9.0, 20.0),
}
COMPILE_TIMES = "compile_times.json"
#: the suffix of a kernel's key for a compile whose largest piece was cached already (engine/aside.py first_cached):
#: shorter than a first compile, so its time is estimated and remembered apart
AGAIN = "_again"


def key(kernel: str, again: bool) -> str:
    """The record's key of a compile of `kernel`, its largest piece cached already (`again`) or not."""
    return kernel + AGAIN if again else kernel


def compile_estimate(kernel: str) -> tuple[tuple[float, float], bool]:
    """((least, most) seconds, measured here): how long compiling `kernel` ('lanes', 'scalar', 'scalar_scored',
    'nonlinear', ..., and each with AGAIN) took on this machine the last time (least = most), else the range on
    2-core machines (for a key with AGAIN and no range of its own, the first compile's: the most it can take)."""
    try:
        last = json.loads((jit._root() / COMPILE_TIMES).read_text())[kernel]
        if isinstance(last, (int, float)) and last > 0:
            return (float(last), float(last)), True
    except (OSError, ValueError, KeyError, TypeError):
        pass
    if kernel not in TYPICAL_COMPILE_S and kernel.endswith(AGAIN):
        kernel = kernel[: -len(AGAIN)]
    return TYPICAL_COMPILE_S.get(kernel, (20.0, 50.0)), False


def record_compile(kernel: str, seconds: float) -> None:
    """Remember how long compiling `kernel` took here (best effort: a cache that cannot be written is fine)."""
    path = jit._root() / COMPILE_TIMES
    try:
        try:
            times = json.loads(path.read_text())
            times = times if isinstance(times, dict) else {}
        except (OSError, ValueError):
            times = {}
        times[kernel] = round(float(seconds), 2)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        tmp.write_text(json.dumps(times, sort_keys=True))
        os.replace(tmp, path)
    except OSError:
        pass
