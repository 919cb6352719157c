"""Figures of a risk study (matplotlib, the `plot` extra; Figure objects, no pyplot): the probability of pounding
against the gap with its interval bands and the code rules' gaps, the fragility curves, and the gap a target
probability needs."""

from __future__ import annotations

import numpy as np

RULE_STYLE = {"ABS": ("C0", "--"), "SRSS": ("C1", "-."), "DDC": ("C2", ":"), "TBEC2018_min": ("C3", "-")}


def _figure(**kw):
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise SystemExit("error: plotting needs matplotlib: python -m pip install '.[plot]'") from None
    return Figure(layout="constrained", **kw)


def _shown_intensities(study, most: int = 4) -> list[float]:
    """The table intensities, or up to `most` groups spread over the levels."""
    req = study.required_gap
    xs = sorted(set(req.intensity_g)) if len(req) else sorted(set(study.probability.intensity_g))
    if len(xs) > most:
        xs = [xs[i] for i in np.linspace(0, len(xs) - 1, most).round().astype(int)]
    return xs


def probability_figure(study):
    """P(pounding) against the gap [mm] per intensity, with the Clopper-Pearson band, and each code rule's gap
    at that intensity as a marker on its curve."""
    fig = _figure(figsize=(8.0, 4.8))
    ax = fig.subplots()
    prob, rules = study.probability, study.code_rules
    near = prob.groupby("intensity_g").size().index.to_numpy()
    for i, x in enumerate(_shown_intensities(study)):
        xg = near[np.argmin(np.abs(near - x))]
        d = prob[prob.intensity_g == xg].sort_values("gap_m")
        color = f"C{i % 10}"
        g = d.gap_m.to_numpy() * 1e3
        ax.fill_between(g, d.ci_low, d.ci_high, color=color, alpha=0.2, lw=0, step="post")
        ax.step(g, d.probability, where="post", color=color, label=f"{xg:.3g} g ({int(d.motions.iloc[0])} motions)")
        # rules whose markers would overlap (SRSS and DDC for far-apart periods: gaps within 1 %, one probability)
        # share a marker and a label; near P = 1 the label goes below, inside the axes
        at: list[tuple[float, float, list[str]]] = []
        for rule, row in rules[np.isclose(rules.intensity_g, x)].set_index("rule").iterrows():
            gap_mm, p, name = float(row.gap_m) * 1e3, float(row.probability), str(rule).replace("2018_min", " min")
            if not gap_mm > 0.0:  # a gap of 0 (identical buildings: no relative motion) has no place on a log axis
                continue
            same = [a for a in at if abs(np.log(a[0] / gap_mm)) < 0.01 and abs(a[1] - p) < 0.01]
            if same:
                same[0][2].append(name)
            else:
                at.append((gap_mm, p, [name]))
        for gap_mm, p, names in at:
            ax.plot([gap_mm], [p], marker="o", mfc="white", mec=color, ms=6)
            below = (5, -11) if p > 0.9 else (5, 4)
            ax.annotate(
                ", ".join(names), (gap_mm, p), textcoords="offset points", xytext=below, fontsize=7, color=color
            )
    ax.set_xscale("log")
    ax.set_xlabel("gap at rest [mm]")
    ax.set_ylabel("P(pounding)")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, title=_im_label(study), title_fontsize=8)
    ax.set_title(f"{study.scene.name}: probability of pounding (bands: {_conf(study)} Clopper-Pearson; "
                 "circles: code rules' gaps)", fontsize=9)  # fmt: skip
    return fig


def fragility_figure(study, most: int = 5):
    """Lognormal fragility curves against the intensity for a few gaps (the code rules' and quantiles of the
    gaps studied), with the stripes' fractions (and their intervals) as points."""
    fig = _figure(figsize=(8.0, 4.8))
    ax = fig.subplots()
    from pounding_sweep.risk.analysis import few_events

    frag = study.fragility[(study.fragility.status == "ok") & ~few_events(study.fragility)]
    if frag.empty:
        frag = study.fragility
    pick = frag.iloc[np.unique(np.linspace(0, len(frag) - 1, most).round().astype(int))]
    # the intensities the runs had, a little beyond: past them a curve is an extrapolation of the lognormal form
    seen = study.demand.intensity_g.to_numpy(dtype=float)
    x = np.geomspace(max(1e-3, float(np.min(seen)) / 1.5), float(np.max(seen)) * 1.5, 300)
    from scipy.special import ndtr

    for i, row in enumerate(pick.itertuples()):
        color = f"C{i % 10}"
        if row.status == "ok":
            ax.plot(x, ndtr(np.log(x / row.median_g) / row.beta), color=color,
                    label=f"gap {row.gap_m * 1e3:.4g} mm: median {row.median_g:.3g} g, beta {row.beta:.2f}")  # fmt: skip
            if np.isfinite(getattr(row, "median_ci_low_g", np.nan)):
                lo = ndtr(np.log(x / row.median_ci_high_g) / row.beta)
                hi = ndtr(np.log(x / row.median_ci_low_g) / row.beta)
                ax.fill_between(x, lo, hi, color=color, alpha=0.15, lw=0)
        else:
            ax.plot([], [], color=color, label=f"gap {row.gap_m * 1e3:.4g} mm: {row.status}")
        pts = study.probability[np.isclose(study.probability.gap_m, row.gap_m)]
        if study.scene.excitation.scaling == "intensity":
            ax.errorbar(pts.intensity_g, pts.probability, yerr=[pts.probability - pts.ci_low, pts.ci_high - pts.probability],
                        fmt="o", ms=3, color=color, alpha=0.7, capsize=2)  # fmt: skip
    ax.set_xscale("log")
    ax.set_xlabel(_im_label(study))
    ax.set_ylabel("P(pounding)")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    ax.set_title(f"{study.scene.name}: lognormal fragility by maximum likelihood (bands: median's {_conf(study)} "
                 "bootstrap interval; points: stripes)", fontsize=9)  # fmt: skip
    return fig


def required_gap_figure(study, targets=None):
    """The gap a target probability needs, against the target, per intensity: the lognormal fragilities'
    answer with its bootstrap band (the table's interval: none where too few replicates give a gap), the
    stripes' order statistics with their distribution-free intervals. None where no intensity has a gap to draw
    (every run pounds, or none: the table's notes say why): a figure with nothing in it is not drawn."""
    import pounding_sweep.risk.analysis as A
    from pounding_sweep.risk.fragility import bootstrap_interval, gap_for_probability

    fig = _figure(figsize=(8.0, 4.8))
    ax = fig.subplots()
    targets = np.geomspace(0.005, 0.5, 40) if targets is None else np.asarray(targets)
    data = A.FragilityData(study.demand, study.scene.excitation.scaling)
    gaps = study.fragility.gap_m.to_numpy()
    fit = data.fit(gaps)
    boot = study.boot
    drawn = 0
    for i, x in enumerate(_shown_intensities(study)):
        color = f"C{i % 10}"
        g = np.array([float(gap_for_probability(fit, gaps, x, p)) for p in targets])
        g = np.where(g > 0.0, g, np.nan)  # a log axis: no gap (NaN) and a gap of 0 leave the curve open there
        if np.isfinite(g).any():
            ax.plot(targets, g * 1e3, color=color, label=f"{x:.3g} g, lognormal")
            drawn += 1
        if boot is not None:
            conf = study.scene.risk.confidence
            band = np.array([bootstrap_interval(gap_for_probability(boot, gaps, x, p), g[k], conf)[:2]
                             for k, p in enumerate(targets)])  # fmt: skip
            band = np.where(band > 0.0, band, np.nan)
            ax.fill_between(targets, band[:, 0] * 1e3, band[:, 1] * 1e3, color=color, alpha=0.15, lw=0)
        req = study.required_gap[np.isclose(study.required_gap.intensity_g, x)]
        ok = np.isfinite(req.empirical_gap_m) & (req.empirical_gap_m > 0.0)
        drawn += int(ok.any())
        if ok.any():
            r = req[ok]
            lo = (r.empirical_gap_m - r.empirical_ci_low_m.fillna(r.empirical_gap_m)) * 1e3
            hi = (r.empirical_ci_high_m.fillna(r.empirical_gap_m) - r.empirical_gap_m) * 1e3
            ax.errorbar(r.target_probability, r.empirical_gap_m * 1e3, yerr=[lo, hi], fmt="s", ms=4, color=color,
                        capsize=3, label=f"{x:.3g} g, order statistics")  # fmt: skip
    if not drawn:
        return None
    for rule, (c, ls) in RULE_STYLE.items():
        rows = study.code_rules[study.code_rules.rule == rule]
        if len(rows) and rule == "TBEC2018_min":
            ax.axhline(float(rows.gap_m.iloc[0]) * 1e3, color=c, ls=ls, lw=0.8, label="TBEC 2018 minimum")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("target probability of pounding")
    ax.set_ylabel("required gap [mm]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    ax.set_title(f"{study.scene.name}: the gap a target probability needs ({_conf(study)} intervals; a band only "
                 "where the table gives one)", fontsize=9)  # fmt: skip
    return fig


def _conf(study) -> str:
    return f"{study.scene.risk.confidence * 100:g} %"


def _im_label(study) -> str:
    im = study.facts["intensity"]
    if im["measure"] == "sa":
        return f"Sa({im['period_s']:.3g} s, 5 %) [g]"
    return "PGA [g]"
