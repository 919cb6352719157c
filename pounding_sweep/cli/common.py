"""What every command shares: the bad-input exit status, list parsing, and one-line errors."""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import stat
import sys
import threading
from collections.abc import Callable
from pathlib import Path

EXIT_BAD_INPUT = 2


class OneLineParser(argparse.ArgumentParser):
    """argparse with the commands' rule for bad input: one line `error: ...`, exit status 2 (argparse prints its
    usage first). A value that starts with '-' (a negative number list, '-1,0.5') reads as an option unless
    written KEY=VALUE: the message says so."""

    def parse_known_args(self, args=None, namespace=None):  # type: ignore[override]
        self._given = list(sys.argv[1:] if args is None else args)
        return super().parse_known_args(args, namespace)

    def error(self, message: str):  # type: ignore[override]
        given = getattr(self, "_given", [])
        if message.startswith("argument ") and "expected one argument" in message:
            opts = message.split()[1].rstrip(":").split("/")
            nxt = [given[i + 1] for i, a in enumerate(given[:-1]) if a in opts]
            if nxt and nxt[0].startswith("-"):
                message += f" ({nxt[0]!r} reads as an option: write {opts[-1]}={nxt[0]})"
        print(f"error: {self.prog}: {message} (see --help)", file=sys.stderr)
        sys.exit(EXIT_BAD_INPUT)


def print_warning(w) -> None:
    """A collected warning (pounding_sweep.warn) as the commands print it: one `warning:` line on stderr, now."""
    print(f"warning: {w.message}", file=sys.stderr, flush=True)


def split_list(s: str) -> list[str]:
    """'a, b,,c' -> ['a', 'b', 'c']."""
    return [x.strip() for x in s.split(",") if x.strip()]


def numbers(s: str, n: int, what: str, cast=float) -> list:
    """n comma-separated numbers, or ValueError naming the option."""
    parts = split_list(s)
    try:
        vals = [cast(x) for x in parts]
    except ValueError:
        raise ValueError(f"{what} = {s!r}: expected {n} numbers separated by commas") from None
    if len(vals) != n:
        raise ValueError(f"{what} = {s!r}: expected {n} numbers separated by commas")
    return vals


class Bad(Exception):
    """A command-line problem: `<path>: <what> (<value>)`."""

    def __init__(self, path, what, value=None):
        super().__init__(f"{path}: {what}" + ("" if value is None else f" ({value})"))


@contextlib.contextmanager
def interruptible():
    """Ctrl-C raises KeyboardInterrupt while a command runs, even when this process inherited SIGINT ignored
    (a background job of a non-interactive shell, `nohup ... &`, many batch runners): CPython installs its
    handler only where SIGINT is not ignored at start-up, and a sweep would otherwise ignore the signal and run
    to its end. The inherited disposition is restored afterwards (`main()` may be called in a process)."""
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGINT) != signal.SIG_IGN:
        yield
        return
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def first_line(path: Path, limit: int = 65536) -> str:
    """The first line of a regular file (at most `limit` bytes of it), '' when it cannot be read as text."""
    try:
        with open(path, "rb") as f:
            head = f.read(limit)
    except OSError:
        return ""
    return head.split(b"\n", 1)[0].decode("utf-8", errors="replace").rstrip("\r")


def check_replaceable(out: Path, ours: Callable[[Path], bool], command: str) -> None:
    """Refuse (Bad) an output path that holds anything but an earlier output of this command: a user's file is
    never replaced. `ours(path)` says whether a regular file there is provably this command's own output. Checked
    before any work, so that nothing is computed for an answer that could not be written."""
    try:
        mode = os.stat(out).st_mode
    except FileNotFoundError:
        if out.is_symlink():
            raise Bad(out, "a symbolic link to nothing", "give another --out") from None
        return
    except OSError as e:
        raise Bad(out, "cannot use this path for the output", e.strerror or e) from None
    if not stat.S_ISREG(mode):
        from pounding_sweep.scene.files import kind_of

        raise Bad(out, f"exists and is {kind_of(mode)}, not a file {command} wrote", "give another --out")
    if not ours(out):
        raise Bad(
            out,
            f"exists and is not a file {command} wrote; {command} never replaces another file",
            "give another --out, or move it away",
        )


def hidden_temporary(out: Path) -> Path:
    """`.<name>.<pid>.tmp` beside `out`: where a command writes before renaming, never a user's name."""
    return out.with_name(f".{out.name}.{os.getpid()}.tmp")
