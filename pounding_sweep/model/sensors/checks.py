"""What an experiment's channels and record say about the sensors that made them, as warnings naming the
channel and the fix: gravity or an offset left in an acceleration, a channel reversed or lagging against the
floor below it (or the table's record), a sample rate that aliases the model's modes.

Why these tests hold on any shake-table test:
- offset: a test that starts and ends at rest has zero mean acceleration (the integral of a is the change of
  velocity, 0), and any stretch of motion a mean of at most twice its peak velocity over its length, so a mean
  above both that and 3 noise standard deviations is a sensor offset (tilt puts g sin(angle) on a horizontal
  axis) or gravity itself (a vertical axis reads about g);
- sign and lag: below half the first resonance a floor moves with the floor below it and with the table,
  in phase within a millisecond or so (signals.py): a negative correlation there is a reversed sensor, a lag a
  clock that is not shared. Floors are compared with floors of the same kind (absolute accelerations with each
  other and with the table's acceleration; displacements relative to the table with each other);
- aliasing: a mode above half the sample rate cannot be seen at its frequency; sampled without an anti-alias
  filter it folds onto another frequency (|f - m fs|), with one it is gone from the measurement but not from the
  model, which the scoring samples without one.
"""

from __future__ import annotations

import numpy as np

from pounding_sweep.model.records import G_STANDARD
from pounding_sweep.model.sensors.formats import GRAVITY_SHARE
from pounding_sweep.model.sensors.signals import physical_delay_bound, proportional_band

#: a mean acceleration above this many noise standard deviations is an offset
OFFSET_SIGMAS = 3.0
#: |mean| T above this many times the motion's peak velocity: an offset (twice the peak bounds any motion's)
DRIFT_FACTOR = 4.0
#: the fewest samples a sign or lag check uses
MIN_SAMPLES = 256


def offset_problem(name: str, x: np.ndarray, dt: float, noise: float = 0.0) -> str | None:
    """A warning when the mean m of acceleration x [m/s^2, sampled every dt s] is gravity or an offset: the
    mean of a record of length T is (v(T) - v(0)) / T, at most twice the peak velocity of its (mean-free)
    motion over T, so |m| T above DRIFT_FACTOR times that peak is no motion's; and, where the channel's noise
    standard deviation `noise` [m/s^2] is known, above OFFSET_SIGMAS of it."""
    m = float(np.mean(x))
    T = x.size * dt
    v = np.cumsum(x - m) * dt
    peak = float(np.max(np.abs(v - v.mean())))
    if abs(m) * T <= DRIFT_FACTOR * peak or abs(m) <= OFFSET_SIGMAS * noise:
        return None
    if abs(abs(m) - G_STANDARD) <= GRAVITY_SHARE * G_STANDARD:
        return (
            f"{name}: mean {m:.4g} m/s^2, about {'+' if m > 0 else '-'}g: gravity is in it (a vertical axis, or "
            "raw sensor output): use the horizontal shaking axis and subtract the mean of a quiet window "
            "(python -m pounding_sweep import does both)"
        )
    return (
        f"{name}: mean {m:.4g} m/s^2: over its {T:.4g} s it would change the velocity by {abs(m) * T:.3g} m/s, "
        f"{abs(m) * T / peak:.0f} times the motion's peak velocity {peak:.3g} m/s; a test that starts and ends at "
        "rest has zero mean acceleration, so this is a sensor offset (tilt puts g sin(angle) on a horizontal "
        "axis): subtract the mean of a quiet window before the shaking (python -m pounding_sweep import --quiet "
        "START,END)"
    )


def pair_problems(name: str, x: np.ndarray, below_name: str, below: np.ndarray, fs: float) -> list[tuple[str, str]]:
    """Sign and lag of channel x against the channel below it (same kind, same samples), in the band where the
    two are nearly proportional (signals.proportional_band): (kind, warning) for each that is wrong."""
    n = min(x.size, below.size)
    if n < MIN_SAMPLES or np.std(x[:n]) == 0 or np.std(below[:n]) == 0:
        return []
    x, below = x[:n], below[:n]
    found = proportional_band(below, x, fs)
    if found is None:
        return []
    band, rel = found
    out = []
    where = f"in {band[0]:.3g}-{band[1]:.3g} Hz, where the two move together"
    if rel.sign < 0:
        out.append(
            (
                "channel_sign",
                f"{name}: reversed against {below_name}: correlation {rel.correlation:+.2f} {where}; the sensor is "
                f"mounted the other way round: multiply the column by -1 (python -m pounding_sweep import fixes signs)",
            )
        )
    bound = max(1.5 / fs, 2.0 * physical_delay_bound(2 * band[1]))
    if abs(rel.lag_s) > bound:
        out.append(
            (
                "channel_lag",
                f"{name}: lags {below_name} by {1e3 * rel.lag_s:+.1f} ms (cross-correlation {where}; a floor lags "
                f"by less than {1e3 * bound:.1f} ms there): its clock is not the others'; shift its time by "
                f"{-rel.lag_s:+.4f} s (python -m pounding_sweep import aligns clocks by cross-correlation)",
            )
        )
    return out


def aliasing_problems(where: str, fs: float, modes_Hz: dict[str, list[float]]) -> list[str]:
    """A warning per building whose modes lie above half the sample rate fs (module docstring)."""
    out = []
    nyq = fs / 2
    for b, fr in modes_Hz.items():
        high = [(k + 1, f) for k, f in enumerate(fr) if f > nyq]
        if high:
            folded = ", ".join(
                f"mode {k} at {f:.4g} Hz folds onto {abs(f - fs * round(f / fs)):.4g} Hz" for k, f in high
            )
            out.append(
                f"{where}: sampled at {fs:.6g} Hz (Nyquist {nyq:.6g} Hz), below {b}'s modes: {folded}; the scoring "
                "samples the model without an anti-alias filter, a sensor usually with one: record at more than "
                f"{2 * max(f for _, f in high):.4g} Hz, or low-pass both (lowpass_Hz) below {nyq:.4g} Hz"
            )
    return out


def record_problem(rec) -> str | None:
    """Gravity or an offset in a ground-motion record (records.GroundRecord): the record drives the model as read."""
    w = offset_problem(f"{rec.source} (record)", rec.acc_m_s2, rec.dt_s)
    return None if w is None else w + "; the record drives the model as read, offset included"


def consensus_problems(names: list[str], series: list[np.ndarray], fs: float) -> list[tuple[str, str]]:
    """(kind, warning) for the channels of one building and kind (`names`, floor order, lowest first) that are
    reversed or late against the others. Each floor is related to the one above it in the band where the two move
    together (signals.proportional_band); the signs and lags, chained from the lowest, give each channel's sign
    and lag relative to the lowest; the majority sign and the median lag are the building's, and a channel that
    departs from them is named. With two channels (or a tie) which one is at fault cannot be told: the pair is
    named. A pair that does not move together breaks the chain (each part judged on its own)."""
    out: list[tuple[str, str]] = []
    parts, part = [], [(0, +1, 0.0, None)]  # (index, sign, lag relative to the part's first, band of the link)
    for k in range(len(names) - 1):
        n = min(series[k].size, series[k + 1].size)
        found = proportional_band(series[k][:n], series[k + 1][:n], fs) if n >= MIN_SAMPLES else None
        if found is None:
            parts.append(part)
            part = [(k + 1, +1, 0.0, None)]
            continue
        band, rel = found
        _, s, lag, _ = part[-1]
        part.append((k + 1, s * rel.sign, lag + rel.lag_s, band))
    parts.append(part)
    for part in (p for p in parts if len(p) >= 2):
        signs = np.array([s for _, s, _, _ in part])
        lags = np.array([t for _, _, t, _ in part])
        bands = [b for *_, b in part if b is not None]
        top = max(b[1] for b in bands)
        where = (
            f"in the band where the floors move together (from {min(b[0] for b in bands):.3g} Hz up to {top:.3g} Hz)"
        )
        plus, minus = int(np.sum(signs > 0)), int(np.sum(signs < 0))
        if plus and minus:
            if plus != minus:
                odd = -1 if plus > minus else +1
                for i, s, _, _ in part:
                    if s == odd:
                        out.append(
                            (
                                "channel_sign",
                                f"{names[i]}: reversed against the other floors of its building {where}; the sensor is "
                                "mounted the other way round: multiply the column by -1 (python -m pounding_sweep "
                                "import fixes signs against the table)",
                            )
                        )
            else:
                for (i, s, _, _), (j, t, _, _) in zip(part, part[1:]):
                    if s != t:
                        out.append(
                            (
                                "channel_sign",
                                f"{names[j]}: reversed against {names[i]} {where}: one of the two is mounted the other "
                                "way round, and these channels alone cannot tell which: compare with the table's motion "
                                "(python -m pounding_sweep import fixes signs against it)",
                            )
                        )
        bound = max(1.5 / fs, 2.0 * physical_delay_bound(2 * top))
        if len(part) >= 3:
            ref = float(np.median(lags))
            for i, _, t, _ in part:
                if abs(t - ref) > bound:
                    out.append(
                        (
                            "channel_lag",
                            f"{names[i]}: lags the other floors of its building by {1e3 * (t - ref):+.1f} ms "
                            f"(cross-correlation {where}; floors lag each other by less than {1e3 * bound:.1f} ms "
                            f"there): its clock is not the others'; shift its time by {ref - t:+.4f} s (python -m "
                            "pounding_sweep import aligns clocks by cross-correlation)",
                        )
                    )
        elif abs(lags[1] - lags[0]) > bound:
            i, j = part[0][0], part[1][0]
            out.append(
                (
                    "channel_lag",
                    f"{names[j]}: lags {names[i]} by {1e3 * (lags[1] - lags[0]):+.1f} ms (cross-correlation {where}; "
                    f"floors lag each other by less than {1e3 * bound:.1f} ms there): their clocks differ; shift one by "
                    "that much (python -m pounding_sweep import aligns clocks by cross-correlation)",
                )
            )
    return out
