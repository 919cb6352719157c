"""The event scheme's located step, written once for every kernel, and the ground motion a step sees.

Event scheme (Wriggers, Computational Contact Mechanics, 2006, sec. 9.5 on event-driven integration):
a step is taken with the contact set of its start; where its end contradicts the set, the switch
instant is located on the real sub-step map (from the estimate of the step's cubic Hermite interpolant
of the penetration: a Newton step with the interpolant's slope, then secants, inside a false-position
bracket), the step is split there, the set switched and the
rest of the step continued with the new set.

What depends on a kernel's coordinates comes in an EventOps record of its own compiled functions
(floors in engine/floors.py for the scalar and Hertz-type kernels, modes in engine/lanes/lane_step.py):
how the state advances over a sub-step, a pair's penetration and rate, the switch tolerance, the
divergence guard, the book-keeping of an accepted piece and the switch itself. What does not is here:
the contact indicator (the penetration, or under the no-tension law min(penetration, F / k_s)), the
first crossing on the interpolant, the search on real sub-steps, and the loop over a step's
pieces (event_step). Numba compiles these once per kernel (a record of dispatchers is a type of its
own, compiled into its kernels by event_functions: engine/jit.py and that function say why).

The kernel's state `st` is the kernel's own record; its `pairs` field is a Pairs record.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from pounding_sweep.codes import EXC_HARMONIC
from pounding_sweep.engine.jit import inline_generic, njit_generic, njit_generic_lanes, njit_inner, njit_kernel

MAX_EVENTS = 16  # contact switches located inside one step before the step is taken as it is (flagged)
EVENT_MIN_FRACTION = 1e-9  # a sub-step shorter than this fraction of dt is not integrated (rounding)
#: the switch search ends once the indicator at a sub-step's end is within this fraction of the switch tolerance
#: (switch_tolerance: 1e-15 m + 1e-12 (|u1| + |u2|), below which every kernel reads a penetration as no switch):
#: that close, the located instant is the crossing to every later test. Searching on to 1e-13 of the penetration's
#: scale (below its rounding) took 1.3 more sub-steps per switch (benchmarks/count_substeps.py: 3.50 against 2.22)
ROUNDING_FRACTION = 0.1
#: constant arguments of compiled calls, typed as values: Numba compiles a callee once per literal it is passed (a
#: call with True and one with False are two compiles of it and of all it calls, an int literal 0 a third), so
#: the engine passes its constants typed (these, np.int64(...)) and each callee compiles once per kernel
#: (tests/engine/test_aside.py lists any copy). The state pair() reads: its start or its end
AT_START, AT_END = np.bool_(False), np.bool_(True)
#: advance's `cold`: start an iterated contact solve from zero force, or from the last piece's forces
COLD, WARM = np.bool_(True), np.bool_(False)


class Pairs(NamedTuple):
    """The contact state of one run's pairs (or one lane's) inside a step."""

    active: np.ndarray  # (P,) bool: the contact set (pairs whose contact law acts)
    just: np.ndarray  # (P,) bool: switched at the event just handled (their start lies on the crossing)
    switch: np.ndarray  # (P,) bool: the pairs that switch at the located event
    theta: np.ndarray  # (P,) fraction of the step at each pair's first crossing on the interpolant (2.0: none)
    c: np.ndarray  # (P,) dashpot c_j [N s/m] of the no-tension indicator
    k_s: float  # contact stiffness k_s [N/m] of the no-tension indicator
    no_tension: bool  # the indicator is min(penetration, F / k_s) (codes.LAW_NO_TENSION), else the penetration


def empty_pairs() -> Pairs:
    """A Pairs of the kernels' types (empty bool and float64 arrays, a float, a bool), for the signatures a second
    process compiles the event steps' pieces with (engine/aside.py; scalar.event_pieces, nonlinear.event_pieces)."""
    b1, f1 = np.empty(0, dtype=np.bool_), np.empty(0)
    return Pairs(b1, b1, b1, f1, f1, 0.0, False)


class Ground(NamedTuple):
    """A run's ground motion inside a step: harmonic (exact at any instant) or sampled (linear between samples)."""

    harmonic: bool
    amp: float  # table displacement amplitude [m] (harmonic)
    omega: float  # circular frequency [rad/s] (harmonic)


class EventOps(NamedTuple):
    """A kernel's coordinate-specific pieces of the event step (compiled functions).

    advance(st, h, ag_s, ag_e, cold) -> int: the end state of a step of length h from the start state, the
        pairs in st.pairs.active carrying their law (ag_s, ag_e: the ground acceleration at its ends; cold:
        start the contact solve from zero force); negative when that solve did not settle.
    pair(st, end, j) -> (penetration [m], its rate [m/s]) of pair j at the start or the end state.
    tolerance(st, j) -> the switch tolerance of pair j at the end state [m] (switch_tolerance).
    finite(st) -> bool: the end state is finite (the kernels' divergence guard).
    accept(st, hs, t_e, ag_s, ag_e): book the piece of length hs ending at t_e; the end state becomes the start.
    switch(st, t, ag): switch the pairs in st.pairs.switch at the start state (time t, ground acceleration ag).
    crossing(herm, h, law, sign, f_lo, f_hi): bisect_crossing or bracket_crossing (how the kernel finds a
        crossing on the step's interpolant).
    """

    advance: object
    pair: object
    tolerance: object
    finite: object
    accept: object
    switch: object
    crossing: object


@njit_kernel
def ground_acceleration(kind, amp, omega, rec_flat, rec_off, rec_len, step, dt):
    """Ground (table) acceleration [m/s^2] at t = step * dt."""
    if kind == EXC_HARMONIC:
        return -amp * omega * omega * np.sin(omega * step * dt)
    if step < rec_len:
        return amp * rec_flat[rec_off + step]
    return 0.0


@njit_kernel
def ground_acceleration_at(amp, omega, t):
    """Harmonic ground acceleration [m/s^2] at any time t (event sub-steps)."""
    return -amp * omega * omega * np.sin(omega * t)


@njit_inner
def ag_inside(ground, t_s, hs, h, ag_s, ag_e):
    """Ground acceleration hs into the rest (length h, from t_s) of a step: exact for harmonic motion,
    linear between the record's samples otherwise."""
    if ground.harmonic:
        return ground_acceleration_at(ground.amp, ground.omega, t_s + hs)
    return ag_s + (ag_e - ag_s) * (hs / h)


@njit_kernel
def hermite_indicator(herm, tau, h, law):
    """Contact indicator at fraction tau of the step (> 0: the pair should be in contact), from the cubic
    Hermite interpolant herm = (p0, p1, m0, m1) of the penetration (end values p0, p1; end slopes
    m0, m1 = v_rel h). law = (no_tension, k_s, c): under no tension, min(penetration, F / k_s)."""
    p0, p1, m0, m1 = herm
    no_tension, k_s, c = law
    t2 = tau * tau
    t3 = t2 * tau
    p = (2 * t3 - 3 * t2 + 1) * p0 + (t3 - 2 * t2 + tau) * m0 + (-2 * t3 + 3 * t2) * p1 + (t3 - t2) * m1
    if not no_tension:
        return p
    dp = (6 * t2 - 6 * tau) * p0 + (3 * t2 - 4 * tau + 1) * m0 + (-6 * t2 + 6 * tau) * p1 + (3 * t2 - 2 * tau) * m1
    f = p + (c / k_s) * dp / h  # no tension: in contact while penetrating and pushing (F / k_s, metres)
    return min(p, f)


@njit_kernel
def hermite_slope(herm, tau, h, law):
    """d/dtau of hermite_indicator at tau (the cubic's derivative; under no tension that of the smaller of
    the penetration and F / k_s)."""
    p0, p1, m0, m1 = herm
    no_tension, k_s, c = law
    t2 = tau * tau
    dp = (6 * t2 - 6 * tau) * p0 + (3 * t2 - 4 * tau + 1) * m0 + (-6 * t2 + 6 * tau) * p1 + (3 * t2 - 2 * tau) * m1
    if not no_tension:
        return dp
    t3 = t2 * tau
    p = (2 * t3 - 3 * t2 + 1) * p0 + (t3 - 2 * t2 + tau) * m0 + (-2 * t3 + 3 * t2) * p1 + (t3 - t2) * m1
    f = p + (c / k_s) * dp / h
    if p <= f:
        return dp
    d2p = (12 * tau - 6) * p0 + (6 * tau - 4) * m0 + (-12 * tau + 6) * p1 + (6 * tau - 2) * m1
    return dp + (c / k_s) * d2p / h


@njit_kernel
def switch_tolerance(up, uq):
    """Penetration [m] below which a contact switch is rounding, not motion: a femtometre, or 1e-12 of
    the floors' displacement. Without it a pair resting exactly at zero penetration (gap 0 at rest)
    would switch back and forth on rounding noise."""
    return 1e-15 + 1e-12 * (abs(up) + abs(uq))


@njit_kernel
def secant_point(lo, hi, f_lo, f_hi):
    """The false-position point of the bracket (lo, hi), or its midpoint when that falls outside."""
    x = hi - f_hi * (hi - lo) / (f_hi - f_lo)
    return x if lo < x < hi else 0.5 * (lo + hi)


@njit_kernel
def illinois(lo, hi, f_lo, f_hi, side, x, fx):
    """One update of an Illinois false-position bracket (lo, hi) with f(lo) < 0 <= f(hi): x, where
    f is fx, replaces the end of its sign; when the same end moves twice running, the other end's
    value is halved (the modified regula falsi: Dowell & Jarratt, BIT 11, 1971). Returns (lo, hi,
    f_lo, f_hi, side), side = 1 after the high end moved, -1 after the low end."""
    if fx >= 0.0:
        if side == 1:
            f_lo *= 0.5
        return lo, x, f_lo, fx, 1
    if side == -1:
        f_hi *= 0.5
    return x, hi, fx, f_hi, -1


@njit_inner
def bisect_crossing(herm, h, law, sign, f_lo, f_hi):
    """The crossing in (0, 1] of sign * hermite_indicator(herm, ., h, law) (f_lo < 0 <= f_hi at the
    bracket's ends): 60 halvings, the upper end kept (the scalar kernels)."""
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if sign * hermite_indicator(herm, mid, h, law) >= 0.0:
            hi = mid
        else:
            lo = mid
    return hi


@njit_kernel
def monotone_cubic(herm, sign):
    """Whether sign * the cubic Hermite interpolant herm = (p0, p1, m0, m1) never decreases on [0, 1]: its
    derivative, the quadratic a tau^2 + b tau + m0, is >= 0 at both ends and at its vertex where that lies
    inside. Then the interpolant crosses zero at most once there."""
    p0, p1, m0, m1 = herm
    a = sign * (6.0 * (p0 - p1) + 3.0 * (m0 + m1))
    b = sign * (6.0 * (p1 - p0) - 4.0 * m0 - 2.0 * m1)
    c = sign * m0
    if c < 0.0 or a + b + c < 0.0:  # the slopes at tau = 0 and 1
        return False
    if a > 0.0 and 0.0 < -b < 2.0 * a:  # a minimum inside (0, 1)
        return c - b * b / (4.0 * a) >= 0.0
    return True


@njit_inner
def bracket_crossing(herm, h, law, sign, f_lo, f_hi):
    """bisect_crossing's crossing with fewer evaluations (the lane kernel). Where the interpolant can cross
    more than once on the step (no-tension law, or a cubic that is not monotone there: monotone_cubic), 20
    halvings first narrow the bracket to 1e-6 exactly as bisection does, so the same crossing is taken;
    where it crosses once, any bracket finds it and the halvings are skipped (they were 40 % of this
    function's evaluations). Illinois false position then finishes to 1e-15. Returns the upper bracket end."""
    lo, hi = 0.0, 1.0
    for _ in range(0 if not law[0] and monotone_cubic(herm, sign) else 20):
        mid = 0.5 * (lo + hi)
        f = sign * hermite_indicator(herm, mid, h, law)
        if f >= 0.0:
            hi, f_hi = mid, f
        else:
            lo, f_lo = mid, f
    side = np.int64(0)
    for _it in range(60):
        if hi - lo <= 1e-15 or f_hi == 0.0:
            break
        t = secant_point(lo, hi, f_lo, f_hi) if _it % 4 != 3 else 0.5 * (lo + hi)
        f = sign * hermite_indicator(herm, t, h, law)
        lo, hi, f_lo, f_hi, side = illinois(lo, hi, f_lo, f_hi, side, t, f)
    return hi


def event_functions(ops: EventOps, inline: bool = False):  # noqa: C901 (39: the closures it makes count into it)
    """The event step compiled with a kernel's pieces: (event_step, contradicts). With `inline` (the lane
    kernel: its state record is wide, and a call passes it whole) the small functions (indicator, called
    several times per switch, and contradicts) are inlined into their callers, as the kernel's pieces are;
    event_step, locate_event and first_event stay compiled functions of their own either way: each runs
    once or twice per step or switch, beside work a call's cost does not show in (benchmarks/
    compare_checkouts.py: 0.975 event, 0.997 implicit, --paired 20), and inlined they make the lane kernel's
    compile 38.0 s against 28.7 s (benchmarks/profile_compile.py --case 1; 97 s against 50 s before
    engine/inlining.py).

    event_step(st, ground, t_s, h, ag_s, ag_e, hmin) -> (finite, switches located, unsettled count): the
    rest of a step from t_s (length h, ground acceleration ag_s to ag_e), its trial with the start's contact
    set already in st; accepted whole where no pair contradicts the set, else split at the located switches
    (at most MAX_EVENTS; more is chatter: the last trial is kept and counted) and continued with the new
    set. The unsettled count adds chatter and contact solves that did not settle.
    contradicts(st) -> bool: whether some pair's end state contradicts the contact set (an event inside).

    The pieces are closure variables, so every call is a direct call resolved at compile time. (Passed as
    arguments instead, Numba would pass each compiled function as a value, a constant holding its address
    in this process, and a kernel holding one is never cached. These functions are not cached on their own:
    the cached kernels that call them hold their code.)"""
    advance, pair, tolerance, is_finite, accept, switch, crossing = ops
    compiled = inline_generic if inline else njit_generic
    # the lane kernel's are optimised in their own module first, as its step is (engine/linking.py)
    large = njit_generic_lanes if inline else njit_generic

    @compiled
    def indicator(st, end, j):
        """Pair j's contact indicator at the start or end state, signed so that >= 0 contradicts its contact state."""
        pr = st.pairs
        pen, rate = pair(st, end, j)
        want = pen
        if pr.no_tension:
            want = min(pen, pen + (pr.c[j] / pr.k_s) * rate)
        return -want if pr.active[j] else want

    @compiled
    def contradicts(st):
        """Whether some pair's end state contradicts the contact set beyond the switch tolerance: an event
        inside the piece (an impact, a separation, or under no tension the force reaching zero)."""
        pr = st.pairs
        for j in range(pr.active.size):
            pe, rate = pair(st, AT_END, j)
            if pr.no_tension and pe > 0.0:
                pe = min(pe, pe + (pr.c[j] / pr.k_s) * rate)
            # the tolerance is positive: it is needed only where the sign already contradicts
            if (pe < 0.0 and pe < -tolerance(st, j)) if pr.active[j] else (pe > 0.0 and pe > tolerance(st, j)):
                return True
        return False

    @large
    def first_event(st, h):
        """Fraction of the piece (0..1] of length h at which the first pair leaves its contact state, or 2.0
        if none does, from each pair's Hermite interpolant between the start and end states; each pair's
        crossing in st.pairs.theta, the pairs crossing first marked in st.pairs.switch."""
        pr = st.pairs
        first = 2.0
        for j in range(pr.active.size):
            pr.theta[j] = 2.0
            p0, r0 = pair(st, AT_START, j)
            p1, r1 = pair(st, AT_END, j)
            herm = (p0, p1, r0 * h, r1 * h)
            law = (pr.no_tension, pr.k_s, pr.c[j])
            sign = -1.0 if pr.active[j] else 1.0  # > 0: the state contradicts the set
            f1 = sign * hermite_indicator(herm, 1.0, h, law)
            if f1 <= 0.0 or f1 <= tolerance(st, j):  # (the tolerance is positive)
                continue
            f0 = sign * hermite_indicator(herm, 0.0, h, law)
            if not pr.just[j] and f0 >= 0.0:
                pr.theta[j] = 0.0  # already contradicts at the start
            else:
                pr.theta[j] = crossing(herm, h, law, sign, min(f0, -1e-300), f1)
            if pr.theta[j] < first:
                first = pr.theta[j]
        for j in range(pr.active.size):
            pr.switch[j] = pr.theta[j] <= first + 1e-9
        return first

    @large
    def locate_event(st, theta, h, hmin, ground, t_s, ag_s, ag_e):
        """Length hs (0 <= hs <= h) of the sub-step that ends where the first pair switches.

        The interpolant's estimate (theta) starts a search on the indicator after a real sub-step of length
        hs, so the switch happens where the discrete motion crosses (penetration 0, or no-tension force 0)
        and the contact springs store or return no energy there. The second sub-step is a Newton step with
        the interpolant's slope at theta, the next ones secants through the last two; one that falls
        outside the bracket (and from the tenth on) is Illinois false position on it, so every sub-step
        stays inside the bracket. It ends where the indicator is within ROUNDING_FRACTION of the switch
        tolerance (or within 1e-13 of the penetration's scale, or the bracket within 1e-13 h). The estimate is
        off by the sub-step map's own error, so the Newton step often ends it: 2.0-3.0 sub-steps per switch
        (benchmarks/count_substeps.py), against 3.4-4.6 while the search went on to 1e-13 of the penetration's
        scale and 4.0-5.2 with plain Illinois. A pair that crosses earlier inside the accepted sub-step takes
        over (searched only where another pair contradicts its state at the sub-step's end). Leaves the sub-step's end state in st and the pairs to switch in st.pairs.switch;
        0 (switch at the start) when the crossing is closer than hmin. ag_s, ag_e: the ground acceleration at t_s and at t_s + h.
        Returns (hs, the ground acceleration at t_s + hs): the sub-step's own, so the caller does not evaluate
        a harmonic motion's sine again (with 0, ag_s)."""
        pr = st.pairs
        npair = pr.active.size
        if theta * h < hmin:
            return 0.0, ag_s
        target = np.int64(0)
        for j in range(npair):
            if pr.theta[j] < pr.theta[target]:
                target = j
        hi = h
        hs = h
        f_hi = indicator(st, AT_END, target)  # the trial over h contradicts
        for _ in range(npair + 1):
            lo = 0.0
            f_lo = min(indicator(st, AT_START, target), -1e-300)  # agrees at the start
            if theta * hi < hmin:
                return 0.0, ag_s  # a sub-step this short only amplifies rounding (the solve scales as 1/h^2)
            hs = min(max(theta * hi, hmin), hi)
            h_eval = hs
            ag_eval = ag_s
            side = np.int64(0)
            scale = 0.0
            p_start, r_start = pair(st, AT_START, target)
            p_hi, r_hi = pair(st, AT_END, target)
            herm = (p_start, p_hi, r_start * hi, r_hi * hi)
            sign = -1.0 if pr.active[target] else 1.0
            slope = sign * hermite_slope(herm, theta, hi, (pr.no_tension, pr.k_s, pr.c[target])) / hi
            hs_prev = hs
            phi_prev = 0.0
            floor = ROUNDING_FRACTION * tolerance(st, target)  # at the end state over hi: the floors' scale
            for _it in range(100):
                ag_eval = ag_inside(ground, t_s, hs, h, ag_s, ag_e)
                advance(st, hs, ag_s, ag_eval, COLD)
                h_eval = hs
                phi = indicator(st, AT_END, target)
                p_end, _r = pair(st, AT_END, target)
                scale = max(scale, abs(p_end) + abs(p_start))
                lo, hi, f_lo, f_hi, side = illinois(lo, hi, f_lo, f_hi, side, hs, phi)
                if abs(phi) <= max(1e-13 * scale, floor) or hi - lo <= 1e-13 * h or (hs <= hmin and phi >= 0.0):
                    break
                nxt = -1.0  # Newton from the interpolant's slope, then secants of the last two sub-steps
                if _it == 0:
                    if slope > 0.0:
                        nxt = hs - phi / slope
                elif _it < 8 and phi != phi_prev:
                    nxt = hs - phi * (hs - hs_prev) / (phi - phi_prev)
                hs_prev = hs
                phi_prev = phi
                if not (lo < nxt < hi):
                    nxt = secant_point(lo, hi, f_lo, f_hi)
                hs = max(nxt, hmin)
            hs = h_eval  # the sub-step whose end state is in st
            # does another pair switch inside this sub-step, before it ends? Only one that contradicts its state
            # at the sub-step's end can (first_event's own first test, f1 > tolerance): without one, no crossing
            # is searched. Half the tolerance here: first_event's end value can differ from indicator's by an ulp
            # (no tension: (c / k_s) (r h) / h), so every pair it would search passes, and it decides as before
            others = False
            for j in range(npair):
                pr.theta[j] = 2.0
                if j != target:
                    others = others or indicator(st, AT_END, j) > 0.5 * tolerance(st, j)
            if others:
                first_event(st, hs)
            earlier = np.int64(-1)
            for j in range(npair):
                if j != target and pr.theta[j] < 1.0 - 1e-9 and (earlier < 0 or pr.theta[j] < pr.theta[earlier]):
                    earlier = j
            if earlier < 0:
                break
            target = earlier
            theta = pr.theta[earlier]
            f_hi = indicator(st, AT_END, target)
            hi = hs
        for j in range(npair):
            pr.switch[j] = j == target or pr.theta[j] <= 1.0  # the target, and pairs crossing with it
        return hs, ag_eval

    @large
    def event_step(st, ground, t_s, h, ag_s, ag_e, hmin):
        """The rest of a step from t_s (length h, ground acceleration ag_s to ag_e), its trial with the start's
        contact set already in st: accepted whole where no pair contradicts the set, else split at the located
        switches (at most MAX_EVENTS; more is chatter: the last trial is kept and counted) and continued with
        the new set. Returns (finite, switches located, unsettled count: chatter and unsettled contact solves)."""
        pr = st.pairs
        n_ev = 0
        uns = 0
        for j in range(pr.just.size):
            pr.just[j] = False
        finite = True
        while True:  # the step's pieces between contact events
            finite = is_finite(st)
            if not finite:
                break
            hs = h  # the piece to accept now
            ag_p = ag_e
            last = True
            if contradicts(st):
                theta = first_event(st, h)
                if theta <= 1.0 and n_ev >= MAX_EVENTS:
                    uns += 1  # the switches chatter: keep the trial, say so
                elif theta <= 1.0:
                    n_ev += 1
                    last = False
                    hs, ag_p = locate_event(st, theta, h, hmin, ground, t_s, ag_s, ag_e)
                    if hs <= hmin or h - hs <= hmin:
                        hs = 0.0 if hs <= hmin else h  # switch at the start of what is left, or at its end
                        ag_p = ag_inside(ground, t_s, hs, h, ag_s, ag_e)
                    finite = is_finite(st)
                    if not finite:
                        break
            if hs > 0.0:
                accept(st, hs, t_s + hs, ag_s, ag_p)
            if last:
                break
            t_s += hs
            h -= hs
            ag_s = ag_p
            switch(st, t_s, ag_s)
            if h <= 0.0:
                break
            if advance(st, h, ag_s, ag_e, WARM) < 0:
                uns += 1
        return finite, n_ev, uns

    return event_step, contradicts
