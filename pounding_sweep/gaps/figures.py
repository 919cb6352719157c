"""Figures of a gap study (matplotlib, the `plot` extra; Figure objects, no pyplot): the required gap per
floor pair by each rule against the exact one, and the response ratios adjacent / separated against the
gap over the required gap."""

from __future__ import annotations

import numpy as np


def _figure(**kw):
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise SystemExit("error: plotting needs matplotlib: python -m pip install '.[plot]'") from None
    return Figure(layout="constrained", **kw)


RULE_BARS = (
    ("exact_m", "exact (time history)", "k"),
    ("abs_m", "ABS", "C0"),
    ("srss_m", "SRSS", "C1"),
    ("ddc_m", "DDC", "C2"),
    ("tbec2018_min_m", "TBEC 2018 minimum", "C3"),
)


def required_gap_figure(required, title: str = ""):
    """Grouped bars per floor pair (one panel per record): the exact required gap and each rule's, in mm
    at model scale (and full scale on the right axis when the study has a length scale)."""
    records = list(dict.fromkeys(required.record))
    fig = _figure(figsize=(7.5, 3.2 * len(records) + 0.8))
    axes = fig.subplots(len(records), 1, squeeze=False)[:, 0]
    bars = [b for b in RULE_BARS if b[0] in required and np.isfinite(required[b[0]]).any()]
    width = 0.8 / len(bars)
    for ax, rec in zip(axes, records):
        d = required[required.record == rec].sort_values("pair")
        x = np.arange(len(d))
        for k, (col, label, color) in enumerate(bars):
            v = d[col].to_numpy() * 1e3
            ax.bar(
                x + (k - (len(bars) - 1) / 2) * width,
                v,
                width,
                label=label,
                color=color,
                alpha=0.9 if col == "exact_m" else 0.7,
            )
        ax.set_xticks(x, [f"floor {p}" for p in d.pair])
        lam = float(d.length_scale.iloc[0])
        ax.set_ylabel("required gap [mm]" + (", model scale" if lam != 1 else ""))
        ax.set_title(f"{rec}" + (f"  (full scale: x {lam:g})" if lam != 1 else ""), loc="left", fontsize=10)
        if lam != 1:
            sec = ax.secondary_yaxis("right", functions=(lambda y, lam=lam: y * lam, lambda y, lam=lam: y / lam))
            sec.set_ylabel("full scale [mm]")
        ax.grid(axis="y", alpha=0.3)
    axes[0].legend(fontsize=8, ncols=min(len(bars), 3), loc="upper left")
    fig.suptitle(title or "gap each floor pair needs: exact against the rules", fontsize=11)
    return fig


def response_ratio_figure(ratios, title: str = ""):
    """Response adjacent / separated against gap / required gap, per building: top-floor peak displacement,
    largest story drift, top-floor peak absolute acceleration (one line per record and building)."""
    fig = _figure(figsize=(12, 4.0))
    axes = fig.subplots(1, 3)
    what = (
        ("disp_ratio", "top-floor peak displacement"),
        ("drift_ratio", "largest story drift"),
        ("acc_ratio", "top-floor peak absolute acceleration"),
    )
    records = list(dict.fromkeys(ratios.record))
    styles = ["-", "--", ":", "-."]
    for ax, (col, label) in zip(axes, what):
        for i, rec in enumerate(records):
            for b in (1, 2):
                d = ratios[(ratios.record == rec) & (ratios.building == b)].sort_values("relative_gap")
                ax.plot(
                    d.relative_gap,
                    d[col],
                    marker="o",
                    ms=3,
                    color=f"C{b - 1}",
                    ls=styles[i % len(styles)],
                    label=f"building {b}" + (f", {rec}" if len(records) > 1 else ""),
                )
        ax.axhline(1.0, color="k", lw=0.6)
        ax.axvline(1.0, color="0.6", lw=0.6, ls="--")
        ax.set_xlabel("gap / required gap [-]")
        ax.set_ylabel("adjacent / separated [-]")
        ax.set_title(label, fontsize=10)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(title or "response with a short gap, over the response when separated", fontsize=11)
    return fig
