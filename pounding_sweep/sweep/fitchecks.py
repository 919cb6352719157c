"""Checks of a calibrated fit, channel by channel, that name a data fault the fit cannot see as such (issue 27
item 2): a channel whose sign is reversed against the model (a sensor mounted or wired the other way round).

A reversed channel cannot be fitted, so the fit bends to shrink the model's response there (on a 6 Hz test with
one top floor negated: k_s/k on its bound, misfit 105 times the noise floor, the channel's correlation with the
model only -0.23). The check therefore asks the data: each channel the model anticorrelates with is negated and
the fit continued from its optimum (least squares, at most MAX_NFEV steps); the channel is named when its own
residual falls below IMPROVEMENT times what it was and the whole misfit falls too (that case: 105 -> 1.00, k_s/k
3.00 and r 0.500, the hidden values). The channel's own residual, not the whole misfit, is judged: on a real test
where the model misfits every channel (Northridge IMU, 136 noise floors as measured) one reversed floor raised the
misfit to 268 and negating it back only halved the whole, while that floor's own residual fell by far more.
It runs only when the misfit already says the model cannot explain the data.

Before any fit, `at_noise_level` names a channel whose scored samples stand below, or barely above, the noise floor
the fit weighs them by: a noise typed in the wrong unit, a noise window inside the shaking, or a scored window without the
shaking (a record cut short) all make a fit to noise look like a fit "within the noise" (a helper's real Sine 1.5
test: relative error 66 %, "residual 0.14 times the noise floor", a 0.3 % interval on the stiffness)."""

from __future__ import annotations

import numpy as np

from pounding_sweep.sweep.fitstats import fit_label, local_fit, misfit_of

#: a channel whose scored samples vary by fewer noise floors than this (their standard deviation) stands barely above
#: the noise it is weighed by: with the floor right, the spread squared is the signal's power plus the noise's, so
#: under 1 the floor cannot be right, and at 1.5 the signal's power is at most 1.25 times the noise's (the faults
#: met: a noise in the wrong unit 0.17-0.26, a record cut to 3 s 0.83-0.89, a noise window in the shaking 0.97-1.0;
#: real data with the noise stated right, 2.6 and more)
SIGNAL_MIN_NOISE_FLOORS = 1.5
#: a negated channel's own residual must fall below this fraction of what it was (a sign fault is not a nuance)
IMPROVEMENT = 0.5
#: the continued fit's budget (function evaluations of least squares; each costs a Jacobian of runs)
MAX_NFEV = 30


def _model_of(fit, c: int) -> tuple[np.ndarray, np.ndarray]:
    """(model, measured) of channel c at the fit: the residuals are (model - measured) / sigma."""
    t = fit.problem.target
    ends = np.cumsum([0, *fit.sizes])
    y = np.asarray(t.values[c], float)
    return y + fit.residuals[ends[c] : ends[c + 1]] * float(t.sigma[c]), y


def correlation(model: np.ndarray, measured: np.ndarray) -> float:
    """Pearson's correlation of the finite samples (0 for a constant series)."""
    ok = np.isfinite(model) & np.isfinite(measured)
    m, y = model[ok], measured[ok]
    if m.size < 3 or np.std(m) == 0.0 or np.std(y) == 0.0:
        return 0.0
    return float(np.corrcoef(m, y)[0, 1])


def reversed_channels(fit) -> list[tuple[str, float, float, dict]]:
    """(channel, correlation at the fit, misfit with it negated, the parameters then) of each channel that looks
    reversed. Negates the problem's target in place for the continued fit and restores it."""
    prob = fit.problem
    t = prob.target
    found = []
    ends = np.cumsum([0, *fit.sizes])
    for c, code in enumerate(t.codes):
        rho = correlation(*_model_of(fit, c))
        if rho >= 0.0:
            continue
        t.values[c] = -t.values[c]
        try:
            res = local_fit(prob, fit.z_opt, MAX_NFEV)
        finally:
            t.values[c] = -t.values[c]
        misfit = misfit_of(res.fun, fit.sizes)
        part = slice(ends[c], ends[c + 1])  # the channel's own residual: the others' model error does not dilute it
        own_before, own_after = np.sqrt(np.mean(fit.residuals[part] ** 2)), np.sqrt(np.mean(res.fun[part] ** 2))
        if misfit < fit.misfit_ratio and own_after < IMPROVEMENT * own_before:
            theta = prob.to_theta(res.z)
            found.append((code, rho, misfit, dict(zip(fit.names, map(float, theta)))))
    return found


def reversed_channel_warnings(fit) -> list[str]:
    """One warning per channel that looks reversed at the fit."""
    out = []
    for code, rho, misfit, params in reversed_channels(fit):
        shown = ", ".join(f"{n} {v:.4g}" for n, v in params.items())
        out.append(
            f"{fit_label(fit.law)}: channel {code} looks reversed against the model: negated, the fit reaches "
            f"{misfit:.2f} times the noise floor instead of {fit.misfit_ratio:.1f} ({shown}; correlation with the "
            "model at the fit "
            f"{rho:.2f}): check how that sensor was mounted and negate the table's column, or import the raw files "
            "with python -m pounding_sweep import, which makes every sensor's sign agree with the table's"
        )
    return out


def at_noise_level(target, columns: dict, sources: dict, window: tuple[float, float]) -> list[str]:
    """A message per fitted channel whose samples in the scored window vary by less than SIGNAL_MIN_NOISE_FLOORS
    times its noise floor, with what most likely set that floor wrong (`sources`: channel -> where it came from)."""
    from pounding_sweep.scene.channels import shown_value

    out = []
    for c, code in enumerate(target.codes):
        spread, sigma = float(np.std(target.values[c])), float(target.sigma[c])
        if not spread < SIGNAL_MIN_NOISE_FLOORS * sigma:
            continue
        source = sources.get(code, "")
        window_hint = "is the shaking inside the scored window (window_s, time_offset_s, a record long enough)?"
        if source.startswith("[experiment] noise."):
            why = f"is that value in the column's own unit, and the sensor's noise at rest? {window_hint}"
        elif "noise_window_s" in source:
            why = f"is noise_window_s at rest (before or after the shaking)? {window_hint}"
        else:
            why = window_hint
        verdict = (
            "less than the noise alone would: that floor cannot be right, and neither can the intervals it gives"
            if spread < sigma
            else "barely above it: a fit there rests on the noise model, and its noise-based intervals with it"
        )
        out.append(
            f"[experiment] channel {columns.get(code, code)} ({code}): its samples in the scored window "
            f"{window[0]:.6g}-{window[1]:.6g} s vary by {shown_value(code, spread)} (standard deviation), "
            f"{spread / sigma:.2g} times the noise floor they are weighed by ({shown_value(code, sigma)}: {source}), "
            f"{verdict}; {why}"
        )
    return out


#: a step error whose RMS exceeds this share of the residual's on a channel is a part of the misfit worth naming (its
#: square, 11 % of the residual's variance); where the fit reaches its noise, a step error above the noise is
STEP_SHARE = 1.0 / 3.0


def step_error(prob, half, theta: np.ndarray, order: int) -> dict[str, float]:
    """Each fitted channel's integration error at the optimum `theta` [SI RMS over its samples], estimated by halving
    the step (`half`: the same problem at dt / 2): e(dt) = (x_dt - x_dt/2) / (1 - 2^-order) for a method of that
    order (Richardson; Newmark average acceleration is second order, 4/3 of the difference)."""
    r1, r2 = prob.residuals(theta[None, :])[0], half.residuals(theta[None, :])[0]
    ends = np.cumsum([0, *prob.sizes()])
    factor = 1.0 / (1.0 - 2.0**-order)
    out = {}
    for c, code in enumerate(prob.target.codes):
        d = (r1[ends[c] : ends[c + 1]] - r2[ends[c] : ends[c + 1]]) * float(prob.target.sigma[c]) * factor
        out[code] = float(np.sqrt(np.mean(d * d)))
    return out


def step_error_warning(fit, dt: float, misfit_factor: float) -> str | None:
    """A warning where the step's own error is a named part of the fit's residual (above STEP_SHARE of it on a
    channel), or, where the fit reaches its noise (misfit at most misfit_factor), above the noise floor, with the
    step that would bring it under that share (second order: the error falls with dt^2)."""
    from pounding_sweep.scene.channels import shown_value

    worst, ratio = None, 0.0
    for code, e in fit.step_error.items():
        limit = fit.noise_m[code] if fit.misfit_ratio <= misfit_factor else STEP_SHARE * fit.rms_m[code]
        if limit > 0 and e / limit > ratio:
            worst, ratio = code, e / limit
    if worst is None or ratio <= 1.0:
        return None
    at_noise = fit.misfit_ratio <= misfit_factor
    against = "its noise floor" if at_noise else f"{STEP_SHARE:.2g} of its residual"
    meaning = (
        "the fit matches the data to their noise, but at this step the model's integration errs by more: the values "
        "fitted are those of the discretised model"
        if at_noise
        else "part of the misfit is the integration, not the model"
    )
    return (
        f"{fit_label(fit.law)}: the time step's own error at the fit (dt_s = {dt:g} s, estimated by halving it) is "
        f"{shown_value(worst, fit.step_error[worst])} RMS on {worst}, {ratio:.2g} times {against} "
        f"({shown_value(worst, fit.rms_m[worst])} residual, {shown_value(worst, fit.noise_m[worst])} noise): "
        f"{meaning}; a step near {dt / np.sqrt(ratio):.2g} s would bring it under"
    )
