"""What every command shares: the bad-input exit status, list parsing, and one-line errors."""

from __future__ import annotations

import contextlib
import signal
import threading

EXIT_BAD_INPUT = 2


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
