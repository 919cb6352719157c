"""Warnings about input that runs but is probably not what was meant (a gap in mm in a metre field, a
record's time in ms, a time step too coarse for the contact): one mechanism for every layer.

A layer that notices such a thing calls `warn(kind, message)`; it imports nothing else of the package
(this module imports nothing). Inside `collecting()` (the sweep opens one per run) each warning is
kept, once per message, and handed to the collector's callback as it happens (the command line prints
it at once as `warning: ...` on stderr, before the long part of a run); the sweep stores the list in
its result metadata and summary. Outside a collector (a notebook calling `simulate`) a warning is a
Python `InputWarning`, shown the usual way.

Errors (input that cannot give a sensible result) are not warnings: they are pounding_sweep.errors.
"""

from __future__ import annotations

import contextlib
import contextvars
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field


class InputWarning(UserWarning):
    """Input that runs but is probably a mistake: the message says what was seen and what to do."""


@dataclass(frozen=True)
class WarningRecord:
    """One warning: a short kind (for tests and tables: 'no_contact', 'record_step', ...) and the message."""

    kind: str
    message: str

    def __str__(self) -> str:
        return self.message


@dataclass
class Collector:
    """The warnings of one run, in order, each message once; `echo` is called with each new one."""

    echo: Callable[[WarningRecord], None] | None = None
    items: list[WarningRecord] = field(default_factory=list)

    def add(self, w: WarningRecord) -> None:
        if any(x.message == w.message for x in self.items):
            return
        self.items.append(w)
        if self.echo is not None:
            self.echo(w)

    def messages(self) -> list[str]:
        return [w.message for w in self.items]


_ACTIVE: contextvars.ContextVar[Collector | None] = contextvars.ContextVar("pounding_sweep_warnings", default=None)


def warn(kind: str, message: str) -> None:
    """Report a probable input mistake: to the active collector, else as a Python InputWarning."""
    c = _ACTIVE.get()
    if c is None:
        warnings.warn(message, InputWarning, stacklevel=2)
    else:
        c.add(WarningRecord(kind, message))


@contextlib.contextmanager
def collecting(echo: Callable[[WarningRecord], None] | None = None) -> Iterator[Collector]:
    """Collect the warnings raised inside (nested: the outer collector gets them as well)."""
    outer = _ACTIVE.get()

    def both(w: WarningRecord) -> None:
        if echo is not None:
            echo(w)
        if outer is not None:
            outer.add(w)

    c = Collector(both)
    token = _ACTIVE.set(c)
    try:
        yield c
    finally:
        _ACTIVE.reset(token)
