"""The tables of a risk study, from its runs (pure functions: DataFrames in, DataFrames out).

Demand: for each contact-free run, the gap each floor pair needs (its largest closing relative displacement,
gaps/study.py) and the largest over the pairs, the one gap that keeps the buildings apart (their gap is the
same at every floor): pounding happens at gap g exactly when that required gap exceeds g. Beside it, the gap
each code rule asks for from the same run's peak displacements (gaps/rules.py).

Groups: the runs at one `scale` value: a stripe of motions all scaled to the intensity `scale` g
([excitation] scaling = 'intensity'), or the ensemble multiplied by the factor `scale` (a cloud, each motion
at its own intensity).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from pounding_sweep.gaps.rules import RULES, combined_gap, tbec2018_minimum_gap_m
from pounding_sweep.gaps.study import SEPARATED_GAP_M
from pounding_sweep.risk.fragility import (
    Fit,
    bootstrap_interval,
    bootstrap_multiplicities,
    fit_lognormal,
    gap_for_probability,
    weighted_exceedance,
)
from pounding_sweep.risk.probability import clopper_pearson, exceedance_counts, required_gap_empirical

#: quantiles of the consequence distributions
QUANTILES = (0.05, 0.16, 0.5, 0.84, 0.95)


def demand_table(runs: pd.DataFrame, n_pairs: int, rho: float) -> pd.DataFrame:
    """One row per contact-free run: motion, group, intensity, the required gap per pair and overall, and the
    gaps ABS, SRSS and DDC (correlation rho) ask for from its peak displacements (largest over the pairs)."""
    out = runs[["motion", "motion_index", "scale", "intensity_g"]].copy()
    req = np.column_stack(
        [np.maximum(0.0, SEPARATED_GAP_M - runs[f"closest_approach_f{j}_m"].to_numpy()) for j in range(1, n_pairs + 1)]
    )
    for j in range(1, n_pairs + 1):
        out[f"required_gap_f{j}_m"] = req[:, j - 1]
    out["required_gap_m"] = req.max(axis=1)
    out["governing_pair"] = req.argmax(axis=1) + 1
    for rule in RULES:
        gaps = np.column_stack(
            [
                combined_gap(runs[f"peak_disp_b1f{j}_m"].to_numpy(), runs[f"peak_disp_b2f{j}_m"].to_numpy(), rule, rho)
                for j in range(1, n_pairs + 1)
            ]
        )
        out[f"{rule.lower()}_gap_m"] = gaps.max(axis=1)
    for j in range(1, n_pairs + 1):
        for b in (1, 2):
            out[f"peak_disp_b{b}f{j}_m"] = runs[f"peak_disp_b{b}f{j}_m"].to_numpy()
    return out


def groups(demand: pd.DataFrame) -> list[tuple[float, pd.DataFrame]]:
    """The runs per `scale` value, each sorted by motion."""
    return [(float(s), d.sort_values("motion_index")) for s, d in demand.groupby("scale", sort=True)]


def group_intensity(d: pd.DataFrame, scaling: str) -> float:
    """The group's intensity [g]: its level (stripes), or the median of its motions' intensities (cloud)."""
    return float(d.scale.iloc[0]) if scaling == "intensity" else float(np.median(d.intensity_g))


def default_gaps(demand: pd.DataFrame, count: int = 100) -> np.ndarray:
    """Geometric gaps from 1 % to 250 % of the largest required gap of the ensemble [m] (beyond the largest: the
    lognormal fragilities' answer for small targets, and bootstrap replicates, may lie there)."""
    top = float(demand.required_gap_m.max())
    if not top > 0:
        return np.geomspace(1e-4, 1e-2, count)
    return np.geomspace(0.01 * top, 2.5 * top, count)


def probability_table(demand: pd.DataFrame, gaps, scaling: str, confidence: float) -> pd.DataFrame:
    """P(pounding) per group and gap with Clopper-Pearson intervals."""
    rows = []
    g = np.asarray(gaps, dtype=float)
    for scale, d in groups(demand):
        k = exceedance_counts(d.required_gap_m.to_numpy(), g)
        n = len(d)
        lo, hi = clopper_pearson(k, np.full(k.shape, n), confidence)
        rows.append(
            pd.DataFrame(
                {
                    "scale": scale,
                    "intensity_g": group_intensity(d, scaling),
                    "gap_m": g,
                    "motions": n,
                    "pounding": k,
                    "probability": k / n,
                    "ci_low": lo,
                    "ci_high": hi,
                }
            )
        )
    return pd.concat(rows, ignore_index=True)


#: the values of one (replicates, gaps, runs) array a cloud's bootstrap fits at once (2^22 float64: 32 MiB; the fit
#: holds about a dozen such arrays)
CLOUD_BLOCK_VALUES = 2**22


class FragilityData:
    """The outcomes the fragility fits use: stripes (scaling = 'intensity': the demand per level and motion)
    or a cloud (every run its own point), with the bootstrap's resampling of the motions."""

    def __init__(self, demand: pd.DataFrame, scaling: str):
        self.scaling = scaling
        self.n_motions = int(demand.motion_index.max()) + 1
        if scaling == "intensity":
            wide = demand.pivot(index="scale", columns="motion_index", values="required_gap_m").sort_index()
            if wide.isna().any().any():
                raise ValueError("every motion needs a run at every level")
            self.x = wide.index.to_numpy(dtype=float)  # (levels,)
            self.demand = wide.to_numpy()  # (levels, motions)
        else:
            self.x = demand.intensity_g.to_numpy(dtype=float)  # (runs,)
            self.demand = demand.required_gap_m.to_numpy()
            self.motion = demand.motion_index.to_numpy()

    def counts(self, gaps) -> tuple[np.ndarray, np.ndarray]:
        """Per gap: the outcomes that pounded and all outcomes (runs of a cloud; motions times levels of stripes)."""
        d = np.ravel(self.demand)
        return exceedance_counts(d, gaps), np.full(np.size(gaps), d.size)

    def fit(self, gaps, mult=None, progress=None):
        """Fits for each gap (and each bootstrap replicate when mult (replicates, motions) is given; a cloud's
        replicates a block at a time, `progress(done, total)` told after each)."""
        g = np.asarray(gaps, dtype=float)
        if self.scaling == "intensity":
            if mult is None:
                k = (self.demand[None, :, :] > g[:, None, None]).sum(-1)  # (gaps, levels)
                n = np.full(k.shape, self.demand.shape[1], dtype=float)
                return fit_lognormal(np.broadcast_to(self.x, k.shape), k, n)
            k = weighted_exceedance(self.demand, g, mult).transpose(0, 2, 1)  # (replicates, gaps, levels)
            n = np.broadcast_to(mult.sum(1)[:, None, None].astype(float), k.shape)
            return fit_lognormal(np.broadcast_to(self.x, k.shape), k, n)
        y = (self.demand[None, :] > g[:, None]).astype(float)  # (gaps, runs)
        if mult is None:
            return fit_lognormal(np.broadcast_to(self.x, y.shape), y, np.ones_like(y))
        # a cloud's replicates a block at a time: each fit holds about a dozen (replicates, gaps, runs) arrays, and
        # 1000 replicates x 100 gaps x 4000 runs at once filled 24 GiB (a helper's default study, killed)
        per = max(1, CLOUD_BLOCK_VALUES // max(y.size, 1))
        fits = []
        for r0 in range(0, mult.shape[0], per):
            w = mult[r0 : r0 + per, self.motion].astype(float)  # (replicates, runs)
            x = np.broadcast_to(self.x, (w.shape[0], g.size, self.x.size))
            fits.append(fit_lognormal(x, y[None], np.ones_like(y)[None], weights=w[:, None, :]))
            if progress is not None:
                progress(r0 + w.shape[0], mult.shape[0])
        return Fit(
            *(np.concatenate([getattr(f, name) for f in fits]) for name in ("theta", "beta", "loglik", "status"))
        )


def fragility_table(data: FragilityData, gaps, boot_fits, confidence: float) -> pd.DataFrame:
    """Per gap: the lognormal fragility's median [g] and dispersion with bootstrap intervals, its status."""
    fit = data.fit(gaps)
    out = pd.DataFrame(
        {
            "gap_m": np.asarray(gaps, dtype=float),
            "median_g": fit.theta,
            "beta": fit.beta,
            "status": fit.status.astype(str),
            "loglik": fit.loglik,
        }
    )
    if boot_fits is not None:
        ok = fit.status == "ok"
        th = np.where(boot_fits.status == "ok", boot_fits.theta, np.nan)
        be = np.where(boot_fits.status == "ok", boot_fits.beta, np.nan)
        lo, hi, found = bootstrap_interval(th, np.where(ok, fit.theta, np.nan), confidence)
        out["median_ci_low_g"], out["median_ci_high_g"] = lo, hi
        out["beta_ci_low"], out["beta_ci_high"], _ = bootstrap_interval(be, np.where(ok, fit.beta, np.nan), confidence)
        out["bootstrap_ok_fraction"] = found
    out["motions"] = data.n_motions
    out["poundings"], out["outcomes"] = data.counts(gaps)
    return out


#: a fragility fitted from fewer poundings, or fewer outcomes without one, is weakly identified: the rule of at
#: least 10 events of the rarer outcome per estimated slope (Peduzzi et al. 1996, J. Clin. Epidemiol. 49:1373)
MIN_EVENTS = 10


def few_events(frag: pd.DataFrame) -> np.ndarray:
    """The fitted ('ok') gaps whose rarer outcome has fewer than MIN_EVENTS: their median and beta rest on a handful
    of runs, and their curves may cross their neighbours' (a wider gap pounding more at some intensity)."""
    rare = np.minimum(frag.poundings, frag.outcomes - frag.poundings)
    return ((frag.status == "ok") & (rare < MIN_EVENTS)).to_numpy()


def required_gap_table(
    demand: pd.DataFrame, data: FragilityData, gaps, fit, boot_fits, intensities, targets, scaling, confidence
) -> pd.DataFrame:
    """Per intensity and target probability: the gap that leaves that probability of pounding, from the stripe's
    order statistics (stripes only) and from the lognormal fragilities (every gap's fit, interpolated in ln
    gap), each with its interval (fragility.bootstrap_interval), and a note saying why a value is missing."""
    rows = []
    by_scale = dict(groups(demand))
    for x in intensities:
        stripe = by_scale.get(float(x)) if scaling == "intensity" else None
        for p in targets:
            row = {"intensity_g": float(x), "target_probability": float(p)}
            notes = []
            if stripe is not None:
                g, lo, hi = required_gap_empirical(stripe.required_gap_m.to_numpy(), p, confidence)
                row.update(empirical_gap_m=g, empirical_ci_low_m=lo, empirical_ci_high_m=hi, motions=len(stripe))
                n = len(stripe)
                if not math.isfinite(g):
                    notes.append(
                        f"order statistics: n p = {n * p:.3g} < 1, no order statistic reaches that quantile "
                        f"({math.ceil(1 / p - 1e-9)} motions at least)"
                    )
                elif not math.isfinite(lo):
                    notes.append(
                        f"order statistics: {n} motions are too few for a distribution-free {confidence:.0%} interval"
                    )
            else:
                row.update(empirical_gap_m=math.nan, empirical_ci_low_m=math.nan, empirical_ci_high_m=math.nan)
                row["motions"] = data.n_motions
                notes.append(
                    "order statistics: no stripe of motions at this intensity (a cloud keeps each motion's own)"
                    if scaling != "intensity"
                    else "order statistics: no stripe at this intensity (not a level of the study)"
                )
            est = float(gap_for_probability(fit, gaps, float(x), float(p)))
            row["lognormal_gap_m"] = est
            row["lognormal_interpolation_m"] = interpolation_error(fit, gaps, float(x), float(p), est)
            if not math.isfinite(est):
                notes.append("lognormal: " + _why_no_gap(fit, gaps, float(x), float(p)))
            if boot_fits is not None:
                reps = gap_for_probability(boot_fits, gaps, float(x), float(p))
                lo, hi, found = bootstrap_interval(reps, est, confidence)
                row.update(lognormal_ci_low_m=float(lo), lognormal_ci_high_m=float(hi))
                row["bootstrap_found_fraction"] = float(found)
                spread = row["lognormal_interpolation_m"]
                if spread > COARSE_SHARE * (float(hi) - float(lo)):
                    g = np.asarray(gaps, dtype=float)
                    i = int(np.searchsorted(g, est))
                    notes.append(
                        f"lognormal: the gaps studied bracket it at {g[max(i - 1, 0)] * 1e3:.4g}-"
                        f"{g[min(i, g.size - 1)] * 1e3:.4g} mm; interpolating through a third gap moves it by "
                        f"{spread * 1e3:.3g} mm, against its interval's {(float(hi) - float(lo)) * 1e3:.3g} mm: the "
                        f"grid is coarse here (a finer [risk] gaps_m near {est * 1e3:.4g} mm)"
                    )
                if math.isfinite(est) and not math.isfinite(float(lo)):
                    notes.append(
                        f"lognormal interval: {found:.1%} of the bootstrap replicates give a gap, fewer than the "
                        f"{1 - (1 - confidence) / 2:.1%} a {confidence:.0%} interval needs (the others' could all lie "
                        "in one tail)"
                    )
            row["note"] = "; ".join(notes)
            rows.append(row)
    return pd.DataFrame(rows)


#: an interpolation error above this share of the interval's width is said (the interval holds only sampling)
COARSE_SHARE = 0.25


def interpolation_error(fit, gaps, x: float, p: float, est: float) -> float:
    """How far the gap for P(pounding | x) = p moves when the fragilities' probits Phi^-1(P) are interpolated
    through three gaps (inverse quadratic in ln gap: the bracketing two and the nearer neighbour) instead of two
    (gap_for_probability): the grid's own error, which the bootstrap interval does not hold. NaN where there is no
    estimate, no third gap with a fitted curve ('ok'), or where the three probits do not fall with the gap (weakly
    identified fits: a finer grid would not help there) or their curve puts the gap outside the three."""
    from scipy.special import ndtri

    if not math.isfinite(est):
        return math.nan
    g = np.asarray(gaps, dtype=float)
    z = fit.probit(np.array([x]))[..., 0]  # (+-inf: 'none', 'all')
    zt = float(ndtri(p))
    i1 = int(np.clip(np.searchsorted(g, est), 1, g.size - 1))
    i0 = i1 - 1
    third = [i for i in (i0 - 1, i1 + 1) if 0 <= i < g.size and np.isfinite(z[i])]
    if not third or not (np.isfinite(z[i0]) and np.isfinite(z[i1])):
        return math.nan
    i2 = min(third, key=lambda i: abs(np.log(g[i]) - np.log(est)))
    pts = sorted((float(np.log(g[i])), float(z[i])) for i in (i0, i1, i2))
    if not (pts[0][1] > pts[1][1] > pts[2][1]):  # the probit must fall with the gap
        return math.nan
    lg = sum(
        yj * math.prod((zt - qk) / (qj - qk) for k, (_, qk) in enumerate(pts) if k != j)
        for j, (yj, qj) in enumerate(pts)
    )
    if not pts[0][0] <= lg <= pts[2][0]:
        return math.nan
    return abs(math.exp(lg) - est)


def _why_no_gap(fit, gaps, x: float, p: float) -> str:
    """Why gap_for_probability found no gap for P(pounding | x) = p: the target beyond the gaps studied on either
    side, or a fragility between them that the data do not identify."""
    prob = fit.probability(np.array([x]))[..., 0]
    g = np.asarray(gaps, dtype=float)
    finite = np.isfinite(prob)
    if finite.any() and np.all(prob[finite] > p) and finite[-1]:
        return f"P = {prob[-1]:.3g} even at the largest gap studied ({1e3 * g[-1]:.4g} mm): widen [risk] gaps_m"
    if finite[0] and prob[0] <= p:
        return f"P = {prob[0]:.3g} already at the smallest gap studied ({1e3 * g[0]:.4g} mm)"
    bad = sorted(set(fit.status[~finite].astype(str)))
    return (
        "the fragilities around it are not identified "
        f"({'; '.join(f'{b}: {NOT_IDENTIFIED.get(b, b)}' for b in bad)}: see fragility.status)"
    )


#: why a fit with that status has no fragility curve (the notes of the required-gap and annual-rate tables)
NOT_IDENTIFIED = {
    "separated": "the outcomes do not overlap in intensity",
    "flat": "pounding does not grow with the intensity",
}


def rule_gaps(stripe: pd.DataFrame, n_pairs: int, rho: float, top_height_full_m: float | None, length_scale: float):
    """{rule: gap [m]} a code rule asks for at a group: ABS, SRSS, DDC from the median peak displacements of its
    motions per floor pair (a design value, largest over the pairs), TBEC 2018's minimum at the top facing
    floor (full-scale height, back to model scale)."""
    out = {}
    for rule in RULES:
        out[rule] = max(
            combined_gap(
                float(np.median(stripe[f"peak_disp_b1f{j}_m"])),
                float(np.median(stripe[f"peak_disp_b2f{j}_m"])),
                rule,
                rho,
            )
            for j in range(1, n_pairs + 1)
        )
    if top_height_full_m is not None:
        out["TBEC2018_min"] = tbec2018_minimum_gap_m(top_height_full_m) / length_scale
    return out


def code_rule_table(
    demand, data: FragilityData, n_pairs, rho, top_height_full_m, length_scale, intensities, scaling, confidence, mult
) -> pd.DataFrame:
    """Per intensity and rule: the gap the rule asks for (design value: the median peaks), the probability of
    pounding it leaves (the stripe's fraction with its Clopper-Pearson interval; the lognormal fragility at that
    gap with its bootstrap interval), and with the rule applied motion by motion to each motion's own peaks,
    the fraction of motions that still pound."""
    rows = []
    by_scale = dict(groups(demand))
    for x in intensities:
        stripe = by_scale.get(float(x)) if scaling == "intensity" else demand
        gaps = rule_gaps(stripe, n_pairs, rho, top_height_full_m, length_scale)
        req = stripe.required_gap_m.to_numpy()
        n = req.size
        for rule, g in gaps.items():
            k = int((req > g).sum())
            lo, hi = clopper_pearson(k, n, confidence)
            row = {
                "intensity_g": float(x),
                "rule": rule,
                "gap_m": g,
                "motions": n,
                "pounding": k,
                "probability": k / n,
                "ci_low": float(lo),
                "ci_high": float(hi),
            }
            fit = data.fit([g])
            row["lognormal_probability"] = float(fit.probability([float(x)])[0, 0])
            if mult is not None:
                bf = data.fit([g], mult)
                p = bf.probability([float(x)])[:, 0, 0]
                lo, hi, _ = bootstrap_interval(p, row["lognormal_probability"], confidence)
                row["lognormal_ci_low"], row["lognormal_ci_high"] = float(lo), float(hi)
            col = f"{rule.lower()}_gap_m"
            if col in stripe:
                kk = int((req > stripe[col].to_numpy()).sum())
                lo2, hi2 = clopper_pearson(kk, n, confidence)
                row.update(per_motion_pounding=kk, per_motion_probability=kk / n)
                row.update(per_motion_ci_low=float(lo2), per_motion_ci_high=float(hi2))
            rows.append(row)
    return pd.DataFrame(rows)


def consequence_table(contact: pd.DataFrame, free: pd.DataFrame, floors: tuple[int, int], n_pairs: int):
    """Per contact gap and group: the distribution over the motions of the response with pounding against the
    response of the same motion without it (ratios of the top floor's peak displacement, the largest story
    drift, the top floor's peak absolute acceleration, per building), the largest pounding force and the
    impacts (long format: quantity, n, mean, quantiles)."""
    key = ["motion_index", "scale"]
    merged = contact.merge(free, on=key, suffixes=("", "_free"), validate="many_to_one")
    q = {}
    for b, nf in zip((1, 2), floors):
        top_d, top_a = f"peak_disp_b{b}f{nf}_m", f"peak_abs_acc_b{b}f{nf}_m_s2"
        drifts = [f"peak_drift_b{b}s{s}_m" for s in range(1, nf + 1)]
        q[f"disp_ratio_b{b}"] = merged[top_d] / merged[top_d + "_free"]
        q[f"drift_ratio_b{b}"] = merged[drifts].max(axis=1) / merged[[d + "_free" for d in drifts]].max(axis=1)
        q[f"acc_ratio_b{b}"] = merged[top_a] / merged[top_a + "_free"]
    q["peak_force_N"] = merged[[f"peak_force_f{j}_N" for j in range(1, n_pairs + 1)]].max(axis=1)
    q["impacts"] = merged[[f"impacts_f{j}" for j in range(1, n_pairs + 1)]].sum(axis=1)
    vals = pd.DataFrame(q)
    vals["gap_m"] = merged.gap_m.to_numpy()
    vals["scale"] = merged.scale.to_numpy()
    vals["intensity_g"] = merged.intensity_g.to_numpy()
    rows = []
    for (gap, scale), d in vals.groupby(["gap_m", "scale"], sort=True):
        pounded = int((d.impacts > 0).sum())
        for name in q:
            v = d[name].to_numpy(dtype=float)
            row = {
                "gap_m": float(gap),
                "scale": float(scale),
                "intensity_g": float(np.median(d.intensity_g)),
                "quantity": name,
                "unit": "N" if name.endswith("_N") else "-",  # forces; the ratios and impact counts have none
                "motions": v.size,
                "pounded": pounded,
                "mean": float(np.mean(v)),
            }
            for qq in QUANTILES:
                row[f"q{round(qq * 100):02d}"] = float(np.quantile(v, qq))
            rows.append(row)
    return pd.DataFrame(rows)


def annual_rate_table(hazard, fit, boot_fits, gaps, confidence: float, integrate, levels_g=None) -> pd.DataFrame:
    """Per gap: the annual rate of pounding, the fragility integrated over the hazard curve
    (integrate = hazard.annual_rate), with its bootstrap interval, where the fragility is fitted ('ok'). Where no
    motion pounded at any level ('none') or every motion at every level ('all') the rate comes from intensities
    the study did not reach (the hazard curve runs beyond its levels `levels_g`), and a separated fit has no
    curve: NaN there, the fit's status and a note saying so (an integral of P = 0 or 1 would read as a rate)."""
    ok = fit.status == "ok"
    rate = np.where(ok, integrate(hazard, fit.probability), np.nan)
    out = pd.DataFrame({"gap_m": np.asarray(gaps, dtype=float), "annual_rate_per_yr": rate})
    if boot_fits is not None:
        # a replicate whose fit is not 'ok' gives no rate, as the estimate would not
        reps = np.where(boot_fits.status == "ok", integrate(hazard, boot_fits.probability), np.nan)
        out["ci_low_per_yr"], out["ci_high_per_yr"], out["bootstrap_found_fraction"] = bootstrap_interval(
            reps, rate, confidence
        )
    out["return_period_yr"] = 1.0 / out.annual_rate_per_yr
    out["status"] = fit.status.astype(str)
    lo = f" (the lowest level, {min(levels_g):g} g)" if levels_g else ""
    hi = f" (up to {max(levels_g):g} g)" if levels_g else ""
    why = {
        "ok": "",
        "none": f"no motion pounds at any level studied{hi}: the rate lies at intensities the study did not reach "
        "(add higher levels)",
        "all": f"every motion pounds at every level studied, down to the lowest{lo}: the rate lies at intensities "
        "the study did not reach (add lower levels)",
        **{st: f"the fragility is not identified ({w}): no curve to integrate" for st, w in NOT_IDENTIFIED.items()},
    }
    out["note"] = [why.get(st, st) for st in out.status]
    return out


def bootstrap(data: FragilityData, gaps, replicates: int, seed: int, progress=None):
    """(multiplicities, fits) of the bootstrap over motions, or (None, None) without one; `progress(done, total)`
    follows the replicates fitted."""
    if replicates <= 0:
        return None, None
    mult = bootstrap_multiplicities(data.n_motions, replicates, seed)
    return mult, data.fit(gaps, mult, progress)


__all__ = [
    "QUANTILES",
    "demand_table",
    "groups",
    "group_intensity",
    "default_gaps",
    "probability_table",
    "FragilityData",
    "fragility_table",
    "required_gap_table",
    "rule_gaps",
    "code_rule_table",
    "consequence_table",
    "annual_rate_table",
    "bootstrap",
]
