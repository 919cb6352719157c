"""From per-sensor exports to the engine's inputs: one table (a time column in s and one absolute-acceleration
column per sensor, in m/s^2, on one clock) and the table sensor's record, with a note of every step.

Steps, in order (docs/how-to/import-real-sensor-data.md says why each):
1. read each file (formats.py: the device clock in s, unwrapped; SI units);
2. the shaking axis of each sensor: gravity's axis is the one whose mean is largest in size, if it reads at
   least half of g (where all three axes are exported, the reader has checked that gravity reads g: formats.py);
   the shaking axis the horizontal one with the largest variance (or the one asked for);
3. the clocks: a shared device clock where the sensors' clock ranges overlap (the same instant reads the same
   value on each), else each sensor aligned to the reference by band-limited cross-correlation in the band
   where the floors follow the table (signals.py); on a shared clock the lag found there is reported (it should
   be below a sample), by cross-correlation it is the alignment (in the clock offset);
4. one time grid: the reference's samples over the span every sensor covers (uniform at its median step where
   its clock has gaps); a sensor whose samples fall on them is copied, another is interpolated (a not-a-knot cubic spline: amplitude error below
   5/384 (2 pi f dt)^4, Hall & Meyer 1976, 4e-4 at f = fs / 15), after a zero-phase low-pass at 0.4 x the
   grid's rate where its own rate is higher (no aliasing); across a gap in a sensor's clock (samples missing)
   the grid's samples are linear between the gap's ends, and a warning says where: they are no measurement;
5. the offset (gravity's projection from tilt, the sensor's bias): the mean of a stated quiet window,
   subtracted; the window's standard deviation is the channel's noise (docs: noise in each channel's unit);
6. the sign: each sensor's against the reference in the band below half the first resonance, where a
   floor moves with the table (signals.py); a negative correlation is reversed.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from pounding_sweep.errors import SensorError
from pounding_sweep.model.records import G_STANDARD
from pounding_sweep.model.sensors.formats import SensorFile, clock_gaps, read_sensor
from pounding_sweep.model.sensors.signals import (
    MIN_CORRELATION,
    first_resonance,
    physical_delay_bound,
    relation,
    rigid_band,
)
from pounding_sweep.scene.channels import building_floor

#: a sensor whose clock range overlaps the reference's by this share of the shorter one shares its clock
SHARED_CLOCK_OVERLAP = 0.5
#: an alignment by cross-correlation whose second-best lobe comes this close to the best is ambiguous
AMBIGUOUS = 0.9
#: a quiet window whose standard deviation is above this many times the sensor's quietest stretch: not quiet
QUIET_FACTOR = 3.0
#: the length of the quiet window found when none is stated [s]
QUIET_LENGTH_S = 1.0


@dataclass(frozen=True)
class Imported:
    """The import's result: the table, the reference's record, each sensor's findings, warnings."""

    time_s: np.ndarray  # from 0, the reference's samples over the common span
    columns: dict[str, np.ndarray]  # '<name>_acc_m_s2' -> absolute acceleration [m/s^2], offset removed, sign fixed
    reference: str  # the table's sensor name
    sensors: dict[str, dict]  # name -> what was found and done (axis, sign, offset, noise, lag, clock, file)
    settings: dict
    warnings: list[str] = field(default_factory=list)

    @property
    def dt_s(self) -> float:
        return float((self.time_s[-1] - self.time_s[0]) / (self.time_s.size - 1))

    def column(self, name: str) -> str:
        return f"{name}_acc_m_s2"

    def summary(self) -> list[str]:
        """What was found, a line for the whole and one per sensor (the command prints them)."""
        s = self.settings
        out = [
            f"imported {len(self.sensors)} sensors, reference {self.reference}: {self.time_s.size} samples at "
            f"{s['rate_Hz']:.6g} Hz ({self.time_s[-1]:.3f} s); {_resonance(self)}, band {s['band_Hz'][0]:.3g}-"
            f"{s['band_Hz'][1]:.3g} Hz; quiet window {s['quiet_s'][0]:.3f}-{s['quiet_s'][1]:.3f} s"
        ]
        for n, i in self.sensors.items():
            lag = f", lag found {1e3 * i['lag_found_s']:+.2f} ms" if _checked_lag(i) else ""
            corr = f" (correlation {i['sign_correlation']:+.3f})" if "sign_correlation" in i else ""
            if "sign_correlation" in i and abs(i["sign_correlation"]) < MIN_CORRELATION:  # kept, not found
                corr = f" as recorded (correlation {i['sign_correlation']:+.3f}: too weak to tell)"
            out.append(
                f"  {n}: axis {i['axis']}, sign {'+1' if i['sign'] > 0 else '-1 (reversed)'}{corr}, offset "
                f"{i['offset_removed_m_s2']:+.4f} m/s^2, noise {i['noise_m_s2']:.4f} m/s^2; {i['alignment']}"
                f", clock offset {_seconds(i['clock_offset_s'])} s{lag}"
            )
        return out


#: an axis whose mean is below this share of g is not gravity's (an export without its vertical axis)
GRAVITY_AXIS_SHARE = 0.5


def _axis(sf: SensorFile, choice: str) -> tuple[str, str, dict]:
    """(shaking axis, gravity axis ('' where no exported axis reads gravity), per-axis statistics) of a sensor's
    accelerations. SensorError where the shaking axis would be gravity's (named by `choice`, or the export's only
    acceleration axis): the models are horizontal shear frames, so a vertical channel is never what is meant."""
    acc = {c: v for c, v in sf.channels.items() if sf.kinds[c] == "acceleration"}
    stats = {c: {"mean": float(np.mean(v)), "std": float(np.std(v))} for c, v in acc.items()}
    grav = max(acc, key=lambda c: abs(stats[c]["mean"]))  # g outweighs any tilt's share and any shaking's mean
    if abs(stats[grav]["mean"]) < GRAVITY_AXIS_SHARE * G_STANDARD:  # an export without its vertical axis
        grav = ""
    horizontal = [c for c in acc if c != grav]
    if choice == "auto":
        col = max(horizontal, key=lambda c: stats[c]["std"]) if horizontal else grav
    else:
        col = f"Acc_{choice.upper()}"
        if col not in acc:
            raise SensorError(f"{sf.path}: --axis {choice}: no column {col} (columns: {', '.join(acc)})")
    if col == grav:
        named = f"--axis {choice}: " if choice != "auto" else ""
        what = (
            f"give a horizontal one ({', '.join(c.removeprefix('Acc_').lower() for c in horizontal)}) or leave --axis "
            "out (each sensor's shaking axis)"
            if horizontal
            else f"and the export holds no horizontal acceleration axis (columns: {', '.join(acc)})"
        )
        raise SensorError(
            f"{sf.path}: {named}{col} is the axis gravity acts along (mean {stats[grav]['mean']:.3f} m/s^2), the "
            f"vertical one, not a shaking axis: {what}"
        )
    return col, grav, stats


def import_sensors(
    files: dict[str, str],
    reference: str,
    fmt: str = "auto",
    axis: str = "auto",
    clock: str = "auto",
    quiet_s: tuple[float, float] | None = None,
    band_Hz: tuple[float, float] | None = None,
    max_lag_s: float | None = None,
) -> Imported:
    """Import the sensors `files` (name -> path; `reference` names the table's sensor) as the module docstring
    says. `clock`: 'auto', 'device' (trust a shared clock) or 'xcorr' (align every sensor by correlation);
    `quiet_s`: the window [s from the common start] whose mean is each channel's offset; `band_Hz`: the band of
    sign and alignment (default: from the first resonance); `max_lag_s`: the largest alignment searched
    (default: half the shortest record)."""
    from scipy.interpolate import make_interp_spline

    if reference not in files:
        raise SensorError(f"--reference {reference}: no sensor of that name (sensors: {', '.join(files)})")
    if clock not in ("auto", "device", "xcorr"):
        raise SensorError(f"--clock {clock}: one of auto, device, xcorr")
    if max_lag_s is not None and not (math.isfinite(max_lag_s) and max_lag_s > 0):
        raise SensorError(f"--max-lag {max_lag_s:g}: the largest clock offset searched, a positive number of seconds")
    same: dict[str, str] = {}
    for n, path in files.items():
        key = os.path.realpath(path)
        if key in same:
            raise SensorError(f"{path}: given for sensor {same[key]} and for sensor {n}: one file per sensor")
        same[key] = n
    sens = {n: read_sensor(p, fmt) for n, p in files.items()}
    slowest = min(sens, key=lambda n: sens[n].rate_Hz)
    if band_Hz is not None and band_Hz[1] > 0.5 * sens[slowest].rate_Hz:
        raise SensorError(
            f"--band {band_Hz[0]:g},{band_Hz[1]:g}: HI above {0.5 * sens[slowest].rate_Hz:.4g} Hz, the Nyquist "
            f"frequency of the slowest sensor ({slowest}, {sens[slowest].rate_Hz:.4g} Hz)"
        )
    info: dict[str, dict] = {}
    series: dict[str, np.ndarray] = {}
    warnings: list[str] = [w for sf in sens.values() for w in sf.warnings]
    for n, sf in sens.items():
        col, grav, stats = _axis(sf, axis)
        horiz = [c for c in stats if c != grav]
        share = stats[col]["std"] ** 2 / max(sum(stats[c]["std"] ** 2 for c in horiz), 1e-300) if col in horiz else 1.0
        info[n] = {
            "file": sf.path,
            "format": sf.format,
            "device": sf.device,
            "samples": int(sf.time_s.size),
            "rate_Hz": sf.rate_Hz,
            "clock": sf.clock,
            "axis": col,
            "gravity_axis": grav,
            "gravity_axis_mean_m_s2": stats[grav]["mean"] if grav else float("nan"),
            "axis_std_m_s2": stats[col]["std"],
            "axis_share_of_horizontal_variance": share,
            "reader_notes": list(sf.notes),
        }
        series[n] = sf.channels[col]
        twin = next((m for m in series if m != n and np.array_equal(series[m], series[n])), None)
        if twin is not None:
            raise SensorError(
                f"{sf.path}: sensor {n} holds the same samples as sensor {twin} ({files[twin]}): the same export twice"
            )
        if share < 0.8:
            warnings.append(
                f"{sf.path}: the shaking axis {col} holds only {100 * share:.0f} % of the horizontal variance: the "
                "sensor is turned about the vertical, and the other horizontal axis sees part of the motion"
            )
    warnings[:0] = _at_rest(series, sens)  # first: it says what the warnings after it are worth
    ref = sens[reference]
    fs = ref.rate_Hz
    # the first resonance and the rigid band, from the spectra alone (no alignment needed)
    durations = {n: float(sf.time_s[-1] - sf.time_s[0]) for n, sf in sens.items()}
    floors = [n for n in sens if n != reference]
    f1_from = ""
    if band_Hz is None:
        if not floors:
            raise SensorError(f"{ref.path}: one sensor only: give --band for sign and alignment checks")
        # each floor's transmissibility peak: the top floor's is the first mode, a lower floor's may be a higher one
        # (its strongest response): the top floors' where the names say which they are, else the lowest of all
        for n in floors:
            info[n]["transmissibility_peak_Hz"] = first_resonance(series[reference], fs, series[n], sens[n].rate_Hz)
        f1_from = min(_top_floors(floors), key=lambda n: info[n]["transmissibility_peak_Hz"])
        f1 = info[f1_from]["transmissibility_peak_Hz"]
        band = rigid_band(f1, min(durations.values()), min(sf.rate_Hz for sf in sens.values()))
    else:
        f1, band = float("nan"), tuple(band_Hz)
    lag_limit = max_lag_s if max_lag_s is not None else 0.5 * min(durations.values())
    # clocks: shared or aligned; each sensor's time on the reference's clock
    on_ref: dict[str, np.ndarray] = {}
    doubtful: set[str] = set()  # sensors whose relation to the reference was too weak to tell (warned)
    for n, sf in sens.items():
        if n == reference:
            on_ref[n] = sf.time_s
            info[n]["clock_offset_s"] = 0.0
            info[n]["alignment"] = "reference"
            continue
        period = sf.clock_period_s
        shift = sf.time_s[0] - ref.time_s[0]
        if math.isfinite(period):  # the same counter read at another wrap: compare modulo the period
            t_sf = sf.time_s - (shift - ((shift + period / 2) % period - period / 2))
        else:
            t_sf = sf.time_s
        overlap = (min(ref.time_s[-1], t_sf[-1]) - max(ref.time_s[0], t_sf[0])) / min(
            durations[n], durations[reference]
        )
        shared = sf.clock == ref.clock and overlap >= SHARED_CLOCK_OVERLAP
        # the relation on a common grid: the sensor interpolated onto the reference's samples by its own clock
        t_own = sf.time_s - (sf.time_s[0] - ref.time_s[0])  # both from the same start, for the correlation
        use = clock == "device" or (clock == "auto" and shared)
        if clock == "device" and not shared:
            raise SensorError(
                f"{sf.path}: --clock device, but its clock ({sf.clock}, {sf.time_s[0]:.6f} .. {sf.time_s[-1]:.6f} s) "
                f"does not overlap the reference's ({ref.time_s[0]:.6f} .. {ref.time_s[-1]:.6f} s): not a shared clock"
            )
        t_guess = t_sf if use else t_own
        y = np.interp(ref.time_s, t_guess, series[n], left=0.0, right=0.0)
        inside = (ref.time_s >= t_guess[0]) & (ref.time_s <= t_guess[-1])
        limit = min(lag_limit, 1.0) if use else lag_limit
        rel = relation(series[reference][inside], y[inside], fs, band, limit)
        # the sensor's clock minus the reference's at the same instant
        offset = float(sf.time_s[0] - (t_sf[0] if use else ref.time_s[0] - rel.lag_s))
        info[n]["alignment"] = (
            "shared device clock" if use else f"cross-correlation with {reference} in {band[0]:.3g}-{band[1]:.3g} Hz"
        )
        info[n]["clock_offset_s"] = float(offset)
        info[n]["lag_found_s"] = rel.lag_s
        info[n]["correlation_at_lag"] = rel.correlation
        info[n]["runner_up_correlation"] = rel.runner_up
        on_ref[n] = sf.time_s - offset
        if abs(rel.correlation) < MIN_CORRELATION:
            doubtful.add(n)
            warnings.append(
                f"{sf.path}: correlates with {reference} at {rel.correlation:+.2f} only in {band[0]:.3g}-"
                f"{band[1]:.3g} Hz: its alignment and sign cannot be trusted (another test's file? give --band)"
            )
        elif not use and rel.runner_up >= AMBIGUOUS * abs(rel.correlation):
            warnings.append(
                f"{sf.path}: its alignment by cross-correlation is ambiguous (another lag correlates "
                f"{rel.runner_up:.2f} against {abs(rel.correlation):.2f}: a periodic motion); align it by a shared "
                "clock or trim the files to a broadband part"
            )
        bound = max(1.5 / fs, 2 * physical_delay_bound(f1) if math.isfinite(f1) else 0.0)
        if use and abs(rel.lag_s) > bound:
            warnings.append(
                f"{sf.path}: lags {reference} by {1e3 * rel.lag_s:+.1f} ms on the shared clock (cross-correlation in "
                f"{band[0]:.3g}-{band[1]:.3g} Hz; more than {1e3 * bound:.1f} ms): its clock is not the reference's; "
                "import with --clock xcorr"
            )
    # one grid: the reference's samples over the span every sensor covers
    start = max(t[0] for t in on_ref.values())
    end = min(t[-1] for t in on_ref.values())
    if end - start < 16 / fs:
        raise SensorError(
            "the sensors cover no common span: "
            + ", ".join(f"{n} {t[0]:.3f}..{t[-1]:.3f} s" for n, t in on_ref.items())
        )
    warnings += _span_cut(sens, on_ref, reference, start, end)
    grid = ref.time_s[(ref.time_s >= start - 1e-9) & (ref.time_s <= end + 1e-9)]
    if clock_gaps(ref.time_s).size:  # the reference's own samples are not a uniform grid: one at its median step
        step = float(np.median(np.diff(ref.time_s)))
        grid = grid[0] + step * np.arange(int(np.floor((end - grid[0]) / step + 1e-9)) + 1)
    cols: dict[str, np.ndarray] = {}
    for n, sf in sens.items():
        t, x = on_ref[n], series[n]
        if slower(sf.rate_Hz, fs):
            warnings.append(
                f"{sf.path}: sampled at {sf.rate_Hz:.4g} Hz, the grid ({reference}'s) at {fs:.4g} Hz: above "
                f"{0.5 * sf.rate_Hz:.4g} Hz its column is interpolation, not measurement (a mode there is folded "
                f"or lost in it); score it with lowpass_Hz below {0.5 * sf.rate_Hz:.4g} Hz"
            )
        j = np.searchsorted(t, grid)
        j = np.clip(j, 0, t.size - 1)
        jm = np.clip(j - 1, 0, t.size - 1)
        near = np.where(np.abs(t[j] - grid) <= np.abs(t[jm] - grid), j, jm)
        if np.all(np.abs(t[near] - grid) <= 1e-3 / fs):
            y = x[near]
            info[n]["resampled"] = "samples on the grid: copied"
        else:
            if sf.rate_Hz > 1.05 * fs:
                import scipy.signal

                sos = scipy.signal.butter(8, 0.4 * fs, fs=sf.rate_Hz, output="sos")
                x = scipy.signal.sosfiltfilt(sos, x)
            y = make_interp_spline(t, x, k=3)(grid)
            info[n]["resampled"] = f"cubic spline onto the grid ({sf.rate_Hz:.6g} -> {fs:.6g} Hz" + (
                ", low-passed at 0.4 x the grid rate first)" if sf.rate_Hz > 1.05 * fs else ")"
            )
        gap = clock_gaps(t)
        if gap.size:
            inside = _across_gaps(t, gap, grid)
            y[inside] = np.interp(grid[inside], t, x)  # linear between the gap's ends: no spline overshoot
            w = t[gap + 1] - t[gap]
            within = (t[gap + 1] > grid[0]) & (t[gap] < grid[-1])  # the gaps inside the common span
            if inside.any():
                g = int(np.argmax(np.where(within, w, -1.0)))
                warnings.append(
                    f"{sf.path}: {int(inside.sum())} grid samples of {n} without a measurement, in {int(within.sum())} "
                    f"gap(s) of its clock (samples missing: the largest gap {w[g]:.4g} s, at "
                    f"{t[gap[g]] - grid[0]:.3f}-{t[gap[g] + 1] - grid[0]:.3f} s of the table): linear between the "
                    "gaps' ends there, which is no measurement; leave them out of a score ([experiment] window_s)"
                )
            info[n]["grid_samples_unmeasured"] = int(inside.sum())
        cols[n] = y
    time = grid - grid[0]
    warnings += _quieter_than_the_table(cols, sens, reference)
    # offsets: the mean of the quiet window (stated, or the quietest QUIET_LENGTH_S of the common span)
    stds = {n: _moving_std(cols[n], max(16, int(round(QUIET_LENGTH_S * fs)))) for n in sens}
    if quiet_s is None:
        score = sum(s / np.median(s) for s in stds.values())  # each sensor relative to its typical level
        k = int(np.argmin(score))
        quiet_s = (float(time[k]), float(time[min(k + max(16, int(round(QUIET_LENGTH_S * fs))) - 1, time.size - 1)]))
        how = "the quietest window of the common span (least sum over sensors of the moving standard deviation)"
    else:
        how = "stated (--quiet)"
    q0, q1 = quiet_s
    quiet = (time >= q0 - 0.5 / fs) & (time <= q1 + 0.5 / fs)
    if quiet.sum() < 16:
        raise SensorError(
            f"--quiet {q0:g},{q1:g}: holds {int(quiet.sum())} samples of the common span 0..{time[-1]:.3f} s "
            "(at least 16 needed)"
        )
    for n in sens:
        w = cols[n][quiet]
        off, sd = float(np.mean(w)), float(np.std(w, ddof=1))
        cols[n] = cols[n] - off
        info[n]["offset_removed_m_s2"] = off
        info[n]["noise_m_s2"] = sd
        least = float(stds[n].min()) * np.sqrt(quiet.sum() / max(quiet.sum() - 1, 1))
        if sd > QUIET_FACTOR * least:
            k = int(np.argmin(stds[n]))
            times = f"{sd / least:.1f} x that" if least > 0 else "above that (0)"
            warnings.append(
                f"{files[n]}: the quiet window {q0:g}-{q1:g} s is not quiet on {n} (standard deviation {sd:.4g} m/s^2, "
                f"{times} of its quietest {QUIET_LENGTH_S:g} s, from {time[k]:.2f} s): the offset and "
                "noise taken there include motion; give --quiet a window where nothing moves"
            )
    # signs against the reference, in the rigid band
    for n in sens:
        if n == reference:
            info[n]["sign"] = +1
            continue
        rel = relation(cols[reference], cols[n], fs, band, 1.5 / fs)
        info[n]["sign"] = rel.sign if abs(rel.correlation) >= MIN_CORRELATION else +1
        info[n]["sign_correlation"] = rel.correlation
        if abs(rel.correlation) < MIN_CORRELATION and n not in doubtful:
            warnings.append(
                f"{files[n]}: its sign against {reference} cannot be told (correlation {rel.correlation:+.2f} in "
                f"{band[0]:.3g}-{band[1]:.3g} Hz, below {MIN_CORRELATION}): kept as recorded; check the sensor's "
                "direction (or give --band)"
            )
        cols[n] = cols[n] * info[n]["sign"]
    settings = {
        "reference": reference,
        "format": fmt,
        "axis": axis,
        "clock": clock,
        "quiet_s": [float(q0), float(q1)],
        "quiet_window": how,
        "band_Hz": [float(band[0]), float(band[1])],
        "first_resonance_Hz": f1,
        "first_resonance_from": f1_from,  # the sensor whose transmissibility peak it is ('': --band given)
        "rate_Hz": fs,
        "span_on_reference_clock_s": [float(grid[0]), float(grid[-1])],
    }
    return Imported(time, {f"{n}_acc_m_s2": cols[n] for n in sens}, reference, info, settings, warnings)


#: a sensor slower than the grid by more than this share is interpolated above its own Nyquist frequency
SLOWER_SHARE = 0.05


#: a shaking axis whose standard deviation is under this many times its white noise (model/experiment.py
#: noise_floor, by differences) records no motion: white noise alone gives 1 (to its estimate's scatter, a few
#: percent over a file); the five real tests of ../shared give 2.4-70 (the estimate is an upper bound where the
#: motion holds frequencies near the sensor's Nyquist)
AT_REST_RATIO = 1.5


def _at_rest(series, sens) -> list[str]:
    """A warning when no sensor's shaking axis stands above its own white noise: the axis, sign, clock and
    resonance found from such files are noise (a helper's first 3 s of each file imported with a sensor 'turned
    about the vertical' and a 642 ms 'lag'). One moving sensor is enough (a free vibration leaves the table at
    rest). A warning, not an error: broadband motion near the Nyquist frequency also reads low by differences."""
    from pounding_sweep.model.experiment import noise_floor

    ratios = {}
    for n, x in series.items():
        sigma, _ = noise_floor(np.asarray(x, float))
        ratios[n] = float(np.std(x)) / sigma if sigma > 0 else math.inf
    if not ratios or any(not r < AT_REST_RATIO for r in ratios.values()):
        return []
    most = max(ratios, key=ratios.get)
    return [
        f"{sens[most].path}: no sensor moves beyond its noise: each shaking axis's standard deviation is at most "
        f"{ratios[most]:.2g} times its white noise by differences ({most}'s; under {AT_REST_RATIO:g} on every "
        "sensor): the files hold no shaking (cut before or after the test, or another test's?), and the axis, sign "
        "and clock found from them are noise"
    ]


#: a sensor moving less than this share of the reference's RMS acceleration (on the common grid) is not a floor
#: above it, unless the test shakes above the frame's first resonance: every floor of the five real tests of
#: ../shared moves 1.27-6.8 times its table
QUIETER_SHARE = 0.8


def _quieter_than_the_table(cols, sens, reference: str) -> list[str]:
    """A warning per sensor whose RMS acceleration on the common grid (aligned, about its mean) is below
    QUIETER_SHARE of the reference's: below its first resonance, and under an earthquake's or a transient's broad
    band, a floor of a frame on the table moves more than the table, so such a sensor is the table itself, or not on
    the frame (a helper's test with the floor-1 and table files exchanged imported silently, with a first resonance
    of 10.6 Hz for 7.9). Above the first resonance a floor can move less (a sine there): the message says so."""
    rms = {n: float(np.std(c)) for n, c in cols.items()}
    return [
        f"{sens[n].path}: {n} moves {rms[n] / rms[reference]:.2g} times the reference {reference} (RMS acceleration "
        f"on the common grid, {rms[n]:.3g} against {rms[reference]:.3g} m/s^2), where a floor of a frame moves more "
        f"than its table unless the table shakes above the frame's first resonance: is {reference} the shaking table "
        f"and {n} a floor (two files exchanged)?"
        for n in cols
        if n != reference and rms[reference] > 0 and rms[n] < QUIETER_SHARE * rms[reference]
    ]


def slower(rate_Hz: float, grid_Hz: float) -> bool:
    """Whether a sensor's rate is below the grid's (or a table's) by more than SLOWER_SHARE (the one rule: the import's
    warning and the sweep's aliasing check)."""
    return rate_Hz < (1.0 - SLOWER_SHARE) * grid_Hz


def _across_gaps(t: np.ndarray, gap: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """The grid samples inside one of the gaps (t[i], t[i + 1]), i in `gap`, and not on its ends (within a
    thousandth of a step: the tolerance of a sample on the grid)."""
    tol = 1e-3 * float(np.median(np.diff(t)))
    k = np.clip(np.searchsorted(t, grid, side="right") - 1, 0, t.size - 2)  # the sample at or before each instant
    return np.isin(k, gap) & (grid > t[k] + tol) & (grid < t[k + 1] - tol)


#: a sensor that shortens the common span by more than this share of the reference's is named
SPAN_CUT_SHARE = 0.1


def _span_cut(sens, on_ref, reference, start, end) -> list[str]:
    """Warnings naming the sensors that start later or end earlier than the reference by more than SPAN_CUT_SHARE
    of its span: the common span, and so every column, is cut there."""
    t_ref = on_ref[reference]
    length = t_ref[-1] - t_ref[0]
    out = []
    for n, t in on_ref.items():
        late, early = t[0] - t_ref[0], t_ref[-1] - t[-1]
        if n == reference or max(late, early) <= SPAN_CUT_SHARE * length:
            continue
        out.append(
            f"{sens[n].path}: sensor {n} covers {t[0] - t_ref[0]:.3f}-{t[-1] - t_ref[0]:.3f} s of {reference}'s "
            f"{length:.3f} s: the common span, and every column, is cut to {end - start:.3f} s by it (a file cut short, "
            "or another test's?)"
        )
    return out


def _moving_std(x: np.ndarray, m: int) -> np.ndarray:
    """Standard deviation of every window of m consecutive samples (from running sums, in float64)."""
    c1 = np.concatenate([[0.0], np.cumsum(x - x.mean())])
    c2 = np.concatenate([[0.0], np.cumsum((x - x.mean()) ** 2)])
    s1, s2 = c1[m:] - c1[:-m], c2[m:] - c2[:-m]
    return np.sqrt(np.maximum(s2 - s1 * s1 / m, 0.0) / (m - 1))


#: the first line of every provenance note the import writes: how a folder is known to be its output
PROVENANCE_HEAD = "# Imported by python -m pounding_sweep import"


def _top_floors(floors: list[str]) -> list[str]:
    """Each building's top floor sensor where every floor sensor is named b<building>f<floor> (as a scene's channels
    are), else every floor sensor: a floor's own strongest peak can be a higher mode, never a lower one, so their
    lowest is then the first mode (a spurious low peak of one sensor would win it: name the sensors)."""
    named = {n: building_floor(n, bare=True) for n in floors}  # b<building>f<floor>, as a scene's channels name floors
    if not all(named.values()):
        return floors
    top: dict[int, tuple[int, str]] = {}
    for n, bf in named.items():
        b, f = bf
        if b not in top or f > top[b][0]:
            top[b] = (f, n)
    return [n for _f, n in top.values()]


def _gravity_cell(i: dict) -> str:
    """The provenance table's gravity cell: the axis gravity acts along and its mean, or that none reads it."""
    if not i["gravity_axis"]:
        return "no exported axis reads gravity"
    return f"{i['gravity_axis']}, mean {i['gravity_axis_mean_m_s2']:.3f}"


def _checked_lag(i: dict) -> bool:
    """Whether a sensor's lag found is a check (on a shared clock), not its alignment (in its clock offset)."""
    return "lag_found_s" in i and i["alignment"] == "shared device clock"


def _lag_cell(i: dict) -> str:
    """The provenance table's lag cell: the check on a shared clock, else where the lag went."""
    if _checked_lag(i):
        return f"{1e3 * i['lag_found_s']:+.2f}"
    return "(the clock offset)" if "lag_found_s" in i else "-"


def _seconds(x: float) -> str:
    """A clock offset [s] to the microsecond, without a minus sign on a rounded zero."""
    v = round(float(x), 6)
    return f"{v if v != 0.0 else 0.0:.6f}"


def _resonance(im: Imported) -> str:
    """The summary's words for the first resonance: where it came from, or that the band was given."""
    s = im.settings
    if not s["first_resonance_from"]:
        return "band given (--band), no resonance looked for"
    return f"first resonance {s['first_resonance_Hz']:.4g} Hz ({s['first_resonance_from']}'s; peaks {_peaks(im)})"


def _peaks(im: Imported) -> str:
    """Each floor sensor's transmissibility peak, as the summary and the provenance note give them."""
    return ", ".join(
        f"{n} {i['transmissibility_peak_Hz']:.4g} Hz" for n, i in im.sensors.items() if "transmissibility_peak_Hz" in i
    )


def provenance_text(im: Imported, command: str) -> str:
    """The provenance note: what was read, found and done, sensor by sensor (Markdown)."""
    s = im.settings
    lines = [
        PROVENANCE_HEAD,
        "",
        f"Command: `{command}`",
        "",
        f"- reference (the shaking table): `{im.reference}`; one time grid, its samples at {s['rate_Hz']:.6g} Hz over "
        f"{s['span_on_reference_clock_s'][0]:.6f} .. {s['span_on_reference_clock_s'][1]:.6f} s of its clock, "
        f"written from t_s = 0 ({im.time_s.size} samples, {im.time_s[-1]:.3f} s)",
        (
            f"- {_resonance(im)}, from the spectra (each floor's transmissibility, floor / table, and its lowest "
            f"resonance: the top floor's is the first mode); band of sign and alignment {s['band_Hz'][0]:.4g}-"
            f"{s['band_Hz'][1]:.4g} Hz (below half of the first resonance the floors follow the table)"
            if s["first_resonance_from"]
            else f"- band of sign and alignment {s['band_Hz'][0]:.4g}-{s['band_Hz'][1]:.4g} Hz, given (--band): no "
            "resonance looked for"
        ),
        f"- quiet window {s['quiet_s'][0]:.3f}-{s['quiet_s'][1]:.3f} s ({s['quiet_window']}): its mean subtracted "
        "from each channel (the offset), its standard deviation the channel's noise",
        "",
        "| sensor | file | device | axis (gravity on) | clock | clock offset s | lag found ms | sign (correlation) | "
        "offset removed m/s^2 | noise m/s^2 | resampling |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for n, i in im.sensors.items():
        sign = "+1" if i["sign"] > 0 else "-1 (reversed)"
        corr = f" ({i['sign_correlation']:+.3f})" if "sign_correlation" in i else " (reference)"
        lines.append(
            f"| {n} | {i['file']} | {i['device']} | {i['axis']} ({_gravity_cell(i)}) | {i['alignment']} | "
            f"{_seconds(i['clock_offset_s'])} | "
            f"{_lag_cell(i)} | {sign}{corr} | {i['offset_removed_m_s2']:+.5f} | "
            f"{i['noise_m_s2']:.5f} | {i['resampled']} |"
        )
    notes = [f"- {n}: {x}" for n, i in im.sensors.items() for x in i["reader_notes"]]
    if notes:
        lines += ["", "Reader notes:", *notes]
    if im.warnings:
        lines += ["", "Warnings:", *[f"- {w}" for w in im.warnings]]
    return "\n".join(lines) + "\n"
