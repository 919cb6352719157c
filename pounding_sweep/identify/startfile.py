"""The modes identify found, written as a TOML file a calibration starts from ([calibrate] start_from; the format
and its reader: scene/starts.py): per building, mode by mode, the frequency and the damping estimate identify
trusts most, with its 95 % interval and which estimate it is."""

from __future__ import annotations

import json
import math

from pounding_sweep.identify.modes import Mode


def damping_estimate(m: Mode) -> tuple[float, tuple[float, float], str]:
    """(ratio, 95 % interval, method) of one mode: the logarithmic decrement of free vibration (interval
    +/- 1.96 standard errors where it has one), else the ratio fitted to the transmissibility, else the half-power
    bandwidth (its interval: +/- a resolution on the band), else NaN. A negative estimate is kept as it is (identify
    notes it as unreliable; a calibration clips it into its bounds)."""
    nan2 = (math.nan, math.nan)
    if m.damping_log_decrement is not None and math.isfinite(m.damping_log_decrement):
        z, se = m.damping_log_decrement, m.damping_log_decrement_se
        ci = (z - 1.96 * se, z + 1.96 * se) if se is not None and math.isfinite(se) else nan2
        return z, ci, "logarithmic decrement"
    if math.isfinite(m.damping_fit):
        return m.damping_fit, m.damping_fit_ci95, "fitted to the transmissibility"
    if math.isfinite(m.damping_half_power):
        return m.damping_half_power, m.damping_half_power_interval, "half-power bandwidth"
    return math.nan, nan2, "none"


#: the words identify's notes use for each damping estimate (identify/modes.py)
NOTE_WORDS = {
    "logarithmic decrement": "logarithmic decrement",
    "fitted to the transmissibility": "fitted damping",
    "half-power bandwidth": "half-power",
}


def damping_reliable(m: Mode, z: float, ci: tuple[float, float], method: str, notes) -> bool:
    """Whether identify trusts the damping estimate z (by `method`, 95 % interval ci) of mode m: above 0, its
    interval (where known) above 0, and none of the identification's notes on that mode and that estimate (a
    note starts with the mode's frequency to 3 decimals, as identify writes it) calls it unreliable."""
    head = f"{m.frequency_Hz:.3f} Hz:"
    word = NOTE_WORDS.get(method, method)
    mine = [n for n in notes if n.startswith(head) and word in n]
    return (
        math.isfinite(z)
        and z > 0
        and not (math.isfinite(ci[0]) and ci[0] <= 0)
        and not any("unreliable" in n for n in mine)
    )


def _num(v: float) -> str:
    return "nan" if math.isnan(v) else f"{v:.6g}"


def modes_toml(ident, header: str) -> str:
    """The modes file of a TableIdentification (identify/table.py): `header` its first line, then one
    [buildingN] table per building with modes (columns that name no floor are left out)."""
    lines = [
        header,
        "# identified modes, mode 1 first: frequency [Hz], damping ratio [-] with its 95 % interval and method;",
        "# [calibrate] start_from = '<this file>' starts a fit from them (docs/tutorials/real-shake-table.md);",
        "# damping_reliable: false where identify does not trust the damping (not above 0, its interval reaching 0,",
        "# or its notes call that estimate unreliable): a calibration starting there says so",
    ]
    for b, r in sorted(ident.results.items()):
        if b == 0 or not r.modes:
            continue
        est = [damping_estimate(m) for m in r.modes]
        lines += [
            "",
            f"[building{b}]",
            "channels = [" + ", ".join(json.dumps(c) for c in r.channels) + "]",  # a TOML basic string
            "frequencies_Hz = [" + ", ".join(_num(m.frequency_Hz) for m in r.modes) + "]",
            "damping_ratios = [" + ", ".join(_num(z) for z, _, _ in est) + "]",
            "damping_ci95 = [" + ", ".join(f"[{_num(a)}, {_num(c)}]" for _, (a, c), _ in est) + "]",
            "damping_methods = [" + ", ".join(json.dumps(w) for _, _, w in est) + "]",
            "damping_reliable = ["
            + ", ".join(
                "true" if damping_reliable(m, z, ci, w, r.notes) else "false" for m, (z, ci, w) in zip(r.modes, est)
            )
            + "]",
        ]
    return "\n".join(lines) + "\n"
