"""The vector loops (engine/lanes/vector.py) compiled for one pair of floor counts, and the group driver's call of
them through their machine-code addresses.

The vector loops unroll over the floors (the counts are compile-time constants: the lengths of the tuples nt, n1t);
the group driver around them does not need to. Compiled with the counts in its types, the driver (its inlined
book-keeping and its call of the scalar step) was compiled again for every new pair of floor counts (8.2 s of a
new pair's compile on a Zen 4: docs/explanation/performance.md). Here each pair's loops are wrapped in functions
whose arguments hold no floor count (`floor_loops`), and the driver calls them through their addresses
(`call_quiet`, `call_contact`, with Numba's own calling convention), so it is compiled once for every pair.
"""

from __future__ import annotations

import threading

from llvmlite import ir
from numba import typeof, types
from numba.core import cgutils
from numba.core.callconv import excinfo_t
from numba.core.errors import TypingError
from numba.extending import intrinsic

from pounding_sweep.engine.jit import njit_step
from pounding_sweep.engine.lanes.vector import _contact, _quiet

#: what the loops return: (step, lanes with an event, lanes diverged), and the contact loop (..., phases ended)
QUIET_RETURNS = types.UniTuple(types.int64, 3)
CONTACT_RETURNS = types.UniTuple(types.int64, 4)


def _codegen(returns):
    """The code calling the compiled function at address args[0] (int64) with the other arguments, by Numba's
    calling convention (numba/core/callconv.py CPUCallConv), returning `returns`; an error status the callee sets
    is passed on to the caller."""

    def codegen(context, builder, signature, llargs):
        cc = context.call_conv
        argtys = signature.args[1:]
        fnty = cc.get_function_type(returns, argtys)
        fn = builder.inttoptr(llargs[0], fnty.as_pointer())
        retty = cc.get_return_type(returns).pointee
        ret = cgutils.alloca_once(builder, retty)
        builder.store(cgutils.get_null_value(retty), ret)
        excinfo = cgutils.alloca_once(builder, ir.PointerType(excinfo_t))
        packed = list(cc._get_arg_packer(argtys).as_arguments(builder, llargs[1:]))
        code = builder.call(fn, [ret, excinfo, *packed])
        status = cc._get_return_status(builder, code, builder.load(excinfo))
        with builder.if_then(status.is_error, likely=False):
            cc.return_status_propagate(builder, status)
        return context.get_returned_value(builder, returns, builder.load(ret))

    return codegen


def _typed(kind: str, returns, addr, args):
    """The call's signature, where the loop was compiled for exactly these argument types (floor_loops runs
    before the driver compiles); None while an argument is still a literal (Numba then types the call again
    without literals); else a typing error naming both, as a callee reached by its address would read
    arguments of other types wrongly."""
    if any(isinstance(a, types.Literal) for a in args):
        return None
    which = 1 if kind == "contact" else 0
    compiled = {tuple(sig) for pair in _made.values() for sig in pair[which].signatures}
    if tuple(args) not in compiled:
        raise TypingError(
            f"the group driver calls the {kind} loop with {tuple(args)}, but it was compiled for "
            f"{sorted(map(str, compiled))} (engine/lanes/loops.py loop_signatures): make them agree"
        )
    return returns(addr, *args), _codegen(returns)


@intrinsic
def call_quiet(typingctx, addr, W, step0, step1, dt, scheme, law, Cv, prof, pid_lane, uniform, pid0, mg):
    """A pair's quiet loop (_wrappers) at address addr: vector._quiet without the floor-count tuples."""
    return _typed(
        "quiet", QUIET_RETURNS, addr, (W, step0, step1, dt, scheme, law, Cv, prof, pid_lane, uniform, pid0, mg)
    )


@intrinsic
def call_contact(typingctx, addr, W, step0, step1, dt, scheme, law, Cv, pon, prof, pid_lane, uniform, pid0, mg):
    """A pair's contact loop (_wrappers) at address addr: vector._contact without the floor-count tuples."""
    args = (W, step0, step1, dt, scheme, law, Cv, pon, prof, pid_lane, uniform, pid0, mg)
    return _typed("contact", CONTACT_RETURNS, addr, args)


_made: dict = {}  # (n, n1) -> (quiet, contact): the pairs' loops made in this process


def made_loops() -> list:
    """The loops made in this process, every pair's (benchmarks/profile_lanes.py maps their machine code)."""
    return [fn for pair in _made.values() for fn in pair]


def _wrappers(n: int, n1: int) -> tuple:
    """The quiet and contact loops for N = n floors, N1 = n1 of them in building 1: functions without the counts
    in their arguments (the counts are their closures' constants: Numba's cache keys a closure by its cells, so
    each pair has its own cached entry), named quiet_loop_N_N1 and contact_loop_N_N1 (engine/aside.py finds a
    piece by its name: this module's __getattr__)."""
    if (n, n1) in _made:
        return _made[(n, n1)]
    nt, n1t = (0,) * n, (0,) * n1

    def quiet(W, step0, step1, dt, scheme, law, Cv, prof, pid_lane, uniform, pid0, mg):
        return _quiet(W, step0, step1, dt, scheme, law, nt, n1t, Cv, prof, pid_lane, uniform, pid0, mg)

    def contact(W, step0, step1, dt, scheme, law, Cv, pon, prof, pid_lane, uniform, pid0, mg):
        return _contact(W, step0, step1, dt, scheme, law, nt, n1t, Cv, pon, prof, pid_lane, uniform, pid0, mg)

    quiet.__name__ = quiet.__qualname__ = f"quiet_loop_{n}_{n1}"
    contact.__name__ = contact.__qualname__ = f"contact_loop_{n}_{n1}"
    return _made.setdefault((n, n1), (njit_step(quiet), njit_step(contact)))


def __getattr__(name: str):
    """quiet_loop_N_N1 and contact_loop_N_N1: a pair's loops by name (engine/aside.py's second process)."""
    kind, _, counts = name.partition("_loop_")
    n, _, n1 = counts.partition("_")
    if kind in ("quiet", "contact") and n.isdigit() and n1.isdigit():
        return _wrappers(int(n), int(n1))[kind == "contact"]
    raise AttributeError(name)


def contact_loop(n: int, n1: int):
    """The contact loop of N = n floors, N1 = n1 of them in building 1 (its dispatcher)."""
    return _wrappers(n, n1)[1]


#: the excitation profiles' type (engine/inputs.py LaneExcitation.prof, made by lanes.excitation_profiles)
PROFILES = types.Array(types.float64, 2, "C")


def loop_signatures(model, opts, runs, gw) -> tuple:
    """The argument types the group driver (groups._integrate_groups) calls the quiet and the contact loop with,
    for this model (LaneModel), options, runs (RunArrays) and work arrays (groups.group_work): W, two steps, dt,
    scheme, law, the coefficient table, (contact: the pairs in contact, int64), the profiles, the lanes' profile
    ids, uniform (a bool), the first profile id and the metric groups. The driver's call must pass exactly these
    types (the callee is reached by its address): the call's typing checks them (_typed, against every pair's compiled loops)."""
    i64 = types.int64
    head = (typeof(gw.W), i64, i64, typeof(model.dt), typeof(opts.scheme), typeof(runs.law).dtype, typeof(model.Cv))
    tail = (PROFILES, typeof(gw.pid), types.boolean, typeof(gw.pid).dtype, typeof((model.gt, opts.groups)))
    return head + tail, head + (typeof(gw.act_pair).dtype,) + tail


_lock = threading.Lock()
_addresses: dict = {}


def floor_loops(model, opts, runs, gw, prof) -> tuple:
    """(quiet, contact): the addresses of the pair's loops, compiled (or loaded from the cache) for the driver's
    argument types (loop_signatures); the wrappers stay alive as long as this process (_wrappers' cache)."""
    if typeof(prof) != PROFILES:  # the driver passes it on as it is: the callee must expect its type
        raise TypeError(f"the excitation profiles must be {PROFILES}, not {typeof(prof)}")
    n, n1, _p, _rows = gw.sizes
    sigs = loop_signatures(model, opts, runs, gw)
    key = (n, n1, sigs)
    with _lock:  # the threads of one chunk ask at once: one compiles, the others find it
        if key not in _addresses:
            out = []
            for fn, sig, returns in zip(_wrappers(n, n1), sigs, (QUIET_RETURNS, CONTACT_RETURNS)):
                fn.compile(sig)
                cres = fn.overloads[sig]
                if cres.signature.return_type != returns:
                    raise TypeError(f"{fn.__name__} returns {cres.signature.return_type}, its call expects {returns}")
                out.append(cres.library.get_pointer_to_function(cres.fndesc.llvm_func_name))
            _addresses[key] = tuple(out)
        return _addresses[key]
