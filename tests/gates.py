"""A real `python -m pounding_sweep` process for the fault tests, stopped at a named point of the sweep
(pounding_sweep/sweep/gate.py: after part N, before the calibration, before the best table's rename) while the
test acts: no test races the clock, whatever the machine's speed or load.

The child starts with SIGINT at its default whatever this process inherited (a background job of a
non-interactive shell inherits it ignored, and so would every child): the tests that send Ctrl-C test the
sweep, not the way pytest was started. (The command line restores the default itself too: cli/common.py
interruptible; test_signals.py checks that on its own.)
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from conftest import REPO

from pounding_sweep.sweep.gate import ENV

#: safety net of every wait here: far above what any step needs on a loaded 2-core machine (seconds); a test
#: that hits it has hung, and fails saying so instead of blocking the suite
SAFETY_S = 900.0


def sigint_default() -> None:
    """preexec_fn: the child's SIGINT at its default (Popen resets SIGPIPE and SIGXFSZ only)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def sigint_ignored() -> None:
    """preexec_fn: the child inherits SIGINT ignored, as a background job of a non-interactive shell does."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def command(*argv) -> list[str]:
    return [sys.executable, "-m", "pounding_sweep", *map(str, argv)]


def run(*argv, env: dict | None = None) -> subprocess.CompletedProcess:
    """The command to its end (SIGINT at its default; a safety-net timeout only)."""
    return subprocess.run(
        command(*argv),
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=SAFETY_S,
        preexec_fn=sigint_default,
        env=env,
    )


class GatedSweep:
    """`python -m pounding_sweep ARGV` that waits at each of `points` until released."""

    def __init__(self, gate_dir: Path, points, *argv, start_new_session: bool = False, preexec_fn=sigint_default):
        self.dir = Path(gate_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST")}
        env[ENV] = f"{','.join(points)}@{self.dir}"
        self.proc = subprocess.Popen(
            command(*argv),
            cwd=REPO,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
            preexec_fn=preexec_fn,
            start_new_session=start_new_session,
        )
        self.pid = self.proc.pid

    def wait_at(self, point: str) -> None:
        """Until the sweep waits at `point`; an AssertionError (with its stderr) if it ended first."""
        reached = self.dir / f"{point}.reached"
        deadline = time.monotonic() + SAFETY_S
        while not reached.exists():
            if self.proc.poll() is not None:
                out, err = self.proc.communicate()
                raise AssertionError(f"the sweep ended (exit {self.proc.returncode}) before {point}: {err or out}")
            if time.monotonic() > deadline:
                self.kill()
                raise AssertionError(f"safety net: the sweep did not reach {point} within {SAFETY_S:g} s")
            time.sleep(0.01)
        assert reached.read_text().strip() == str(self.pid)

    def release(self, point: str) -> None:
        (self.dir / f"{point}.release").touch()

    def signal(self, sig: int, group: bool = False) -> None:
        if group:
            os.killpg(self.pid, sig)
        else:
            self.proc.send_signal(sig)

    def stop_at(self, point: str, sig: int, group: bool = False) -> tuple[int, str, str]:
        """Wait at `point`, send `sig` there (to the whole process group with `group`), and return how the sweep
        ended: (exit status, stdout, stderr)."""
        try:
            self.wait_at(point)
            self.signal(sig, group)
            return self.finish()
        finally:
            self.kill()

    def finish(self) -> tuple[int, str, str]:
        """(exit status, stdout, stderr) once it has ended."""
        out, err = self.proc.communicate(timeout=SAFETY_S)
        return self.proc.returncode, out, err

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.communicate()
