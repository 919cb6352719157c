"""Issue 25: Ctrl-C works the same however the command was started. A process started with SIGINT ignored (what a
background job of a non-interactive shell inherits: `nohup ... &`, many CI and batch runners) still stops at
Ctrl-C with its one line, and `main()` called in a process leaves the caller's SIGINT disposition as it found it.
"""

from __future__ import annotations

import signal
import subprocess
import sys

from conftest import REPO, SWEEPS
from gates import SAFETY_S, GatedSweep, sigint_ignored

from pounding_sweep.cli.common import interruptible
from pounding_sweep.sweep.results import part_files


def test_a_sweep_started_with_sigint_ignored_still_stops_at_ctrl_c(tmp_path):
    text = (SWEEPS / "paper_6hz.toml").read_text().replace("duration_s = 5.0", "duration_s = 0.2")
    (tmp_path / "s.toml").write_text(text + "\n[execution]\nchunk_runs = 5\n")
    out = tmp_path / "out.parquet"
    argv = (tmp_path / "s.toml", "--out", out, "--quiet", "--threads", "1")
    sweep = GatedSweep(tmp_path / "gate", ["part-1"], *argv, preexec_fn=sigint_ignored)
    code, _, err = sweep.stop_at("part-1", signal.SIGINT)
    assert code == 130 and err == "interrupted: the finished parts are kept; run the same command again to resume\n"
    assert len(part_files(out)) == 1


def test_interruptible_turns_an_ignored_sigint_into_keyboardinterrupt_and_back():
    """In a process that inherited SIGINT ignored: inside, the signal raises KeyboardInterrupt; after, it is
    ignored again."""
    code = (
        "import os, signal\n"
        "signal.signal(signal.SIGINT, signal.SIG_IGN)\n"
        "from pounding_sweep.cli.common import interruptible\n"
        "with interruptible():\n"
        "    try:\n"
        "        os.kill(os.getpid(), signal.SIGINT)\n"
        "        for _ in range(1000):\n"
        "            pass\n"  # the handler runs at the next bytecode boundary
        "        print('not interrupted')\n"
        "    except KeyboardInterrupt:\n"
        "        print('interrupted')\n"
        "print(signal.getsignal(signal.SIGINT) == signal.SIG_IGN)\n"
    )
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=SAFETY_S)
    assert p.stdout.split() == ["interrupted", "True"], p.stderr


def test_interruptible_leaves_a_handler_it_did_not_replace():
    before = signal.getsignal(signal.SIGINT)
    with interruptible():
        inside = signal.getsignal(signal.SIGINT)
    assert signal.getsignal(signal.SIGINT) == before
    assert inside == (signal.default_int_handler if before == signal.SIG_IGN else before)
