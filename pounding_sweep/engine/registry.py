"""The kernels, in one table: per kernel its compiled entry point, its compile label, the runs it takes
(one at a time, or LANES side by side), and why it cannot run a given chunk. Everything that chooses a
kernel asks choose(); a new kernel is one entry here (and its module), in the order of preference.

A chunk's contact law comes from its runs (engine/inputs.py RunArrays.law, codes.LAW_*): the driver
splits a chunk by law and asks for each law's runs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

from pounding_sweep.codes import CONTACT_LAWS, HERTZ_LAWS, KELVIN_VOIGT_LAWS
from pounding_sweep.engine import lanes, nonlinear, scalar
from pounding_sweep.engine.bookkeeping import row_end_pieces, score_pieces
from pounding_sweep.engine.inputs import HistorySpec, KernelOptions, ScoreSpec
from pounding_sweep.engine.nonlinear import integrate_nonlinear
from pounding_sweep.engine.scalar import integrate_batch

#: what a user may ask for (the scene's [execution] kernel, the command line): "auto" (the first kernel in
#: KERNELS that can run the chunk), "scalar" (one run at a time: the tests and benchmarks compare the two),
#: "lanes"
CHOICES = ("auto", "scalar", "lanes")


class Chunk(NamedTuple):
    """What decides the kernel of a chunk of runs of one contact law."""

    sys: object  # model.coupled.SystemArrays
    hist: HistorySpec
    opts: KernelOptions
    score: ScoreSpec
    law: int  # codes.LAW_*


@dataclass(frozen=True)
class Kernel:
    """A kernel: what runs a chunk on it and when it cannot."""

    name: str  # its compile-time record's key (engine/compile_times.py TYPICAL_COMPILE_S)
    label: str  # what a first run calls it while it compiles
    lanes: bool  # LANES runs side by side (engine/lanes) or one at a time (start, stop, records...)
    entry: Callable  # its entry point (lanes.integrate_lanes; scalar.integrate_batch: picks the compiled variant)
    laws: tuple  # the contact laws (codes.LAW_*) it integrates
    why_not: Callable[[Chunk], str | None]  # why it cannot run a chunk (None: it can)
    #: its self-contained pieces for a chunk, which a second process may compile while this one compiles the
    #: rest (engine/aside.py): groups of (dispatcher, argument types) pairs, the second process taking the first
    #: group with a piece not compiled or cached yet
    aside: Callable[[Chunk], tuple] = lambda chunk: ()

    @property
    def choice(self) -> str:
        """The CHOICES entry that asks for this kernel."""
        return "lanes" if self.lanes else "scalar"

    def compile_key(self, score: ScoreSpec | None) -> tuple[str, str]:
        """(name, label) of its compile with or without scoring (scoring compiles more code)."""
        if score is not None and score.active:
            return f"{self.name}_scored", f"{self.label} with scoring"
        return self.name, self.label


def _law_names(laws) -> str:
    names = {code: name for name, code in CONTACT_LAWS.items()}
    return ", ".join(names.get(x, str(x)) for x in laws)


def _one_at_a_time(laws):
    def why_not(chunk: Chunk) -> str | None:
        return None if chunk.law in laws else f"integrates the {_law_names(laws)} laws only"

    return why_not


def _scalar_pieces(chunk: Chunk) -> tuple:
    """The scalar kernel's pieces a second process may compile, one group in the order its typing reaches them:
    its event step's pieces (none for the paper's scheme), the run's end book-keeping, then the scoring code when
    the chunk scores."""
    return (scalar.event_pieces(chunk.opts.scheme) + row_end_pieces() + score_pieces(chunk.score),)


def _hertz_pieces(chunk: Chunk) -> tuple:
    """The Hertz-type kernel's pieces a second process may compile, one group in the order its typing reaches them:
    its contact solve and event step's pieces (every scheme's: its time loop holds them all), the run's end
    book-keeping, then the scoring code when the chunk scores."""
    return (nonlinear.event_pieces() + row_end_pieces() + score_pieces(chunk.score),)


def _lane_pieces(chunk: Chunk) -> tuple:
    """The lane kernel's pieces a second process may compile: its scalar step, else its contact loop (two groups:
    the loop after the step would come too late, engine/aside.py start)."""
    return tuple((piece,) for piece in lanes.step_pieces(chunk.sys, chunk.opts, chunk.law))


def _lanes_why_not(chunk: Chunk) -> str | None:
    why = lanes.lane_modes(chunk.sys, chunk.hist, chunk.opts, chunk.score, chunk.law)
    return why if isinstance(why, str) else None


#: the kernels, in the order "auto" prefers them
KERNELS = (
    Kernel(
        "lanes",
        "the lane kernel",
        True,
        lanes.integrate_lanes,
        lanes.LAWS,
        _lanes_why_not,
        _lane_pieces,
    ),
    Kernel(
        "scalar",
        "the scalar kernel",
        False,
        integrate_batch,
        KELVIN_VOIGT_LAWS,
        _one_at_a_time(KELVIN_VOIGT_LAWS),
        _scalar_pieces,
    ),
    Kernel(
        "nonlinear",
        "the Hertz-type contact kernel",
        False,
        integrate_nonlinear,
        HERTZ_LAWS,
        _one_at_a_time(HERTZ_LAWS),
        _hertz_pieces,
    ),
)


def choose(chunk: Chunk, choice: str = "auto") -> Kernel:
    """The kernel that runs `chunk` (ValueError: `choice` names none of CHOICES, or no kernel it allows can
    run the chunk; the message says why)."""
    if choice not in CHOICES:
        raise ValueError(f"kernel = {choice!r}: expected one of {CHOICES}")
    whys = []
    for k in KERNELS:
        if choice != "auto" and k.choice != choice:
            continue
        why = k.why_not(chunk)
        if why is None:
            return k
        whys.append((k, why))
    if choice == "lanes":
        raise ValueError(f"kernel = 'lanes': the lane kernel cannot run this chunk ({whys[0][1]})")
    reasons = "; ".join(f"{k.label}: {why}" for k, why in whys)
    raise ValueError(f"kernel = {choice!r}: no kernel can run this chunk ({reasons})")
