"""What each column of a risk study's tables means (stored in each table's metadata; docs/how-to/probabilistic-pounding.md)."""

from __future__ import annotations

from pounding_sweep.gaps.rules import TBEC2018_RULE

_GROUP = {
    "scale": "the runs' [sweep] scale: the intensity level [g] (scaling = 'intensity') or the factor on the motions",
    "intensity_g": "the group's intensity [g]: its level, or the median of its motions' intensities (a cloud)",
    "motions": "motions in the group (or the study) [-]",
}
_CI = {
    "ci_low": "lower end of the exact (Clopper-Pearson) interval at [risk] confidence [-]",
    "ci_high": "upper end of that interval [-]",
}

COLUMN_DOCS = {
    "demand": {
        "motion": "the record's name or the stochastic motion's seed",
        "motion_index": "the motion's place on the [sweep] record or seed axis [-]",
        "scale": _GROUP["scale"],
        "intensity_g": "the run's intensity as run [g]",
        "required_gap_f*_m": "gap floor pair * needs in this run: its largest closing relative displacement u1 - u2 [m]",
        "required_gap_m": "the largest over the pairs: pounding at gap g exactly when this exceeds g [m]",
        "governing_pair": "the pair that needs it [-]",
        "abs_gap_m": "ABS rule, u1 + u2 of the run's peak displacements, largest over the pairs [m]",
        "srss_gap_m": "SRSS rule, sqrt(u1^2 + u2^2), largest over the pairs [m]",
        "ddc_gap_m": "double-difference rule with Der Kiureghian's correlation, largest over the pairs [m]",
        "peak_disp_b*f*_m": "the run's peak |displacement| of building b, floor f, without contact [m]",
    },
    "probability": {
        **_GROUP,
        "gap_m": "gap between the buildings at rest [m]",
        "pounding": "motions whose required gap exceeds gap_m [-]",
        "probability": "pounding / motions: P(pounding | gap, group) [-]",
        **_CI,
    },
    "fragility": {
        "gap_m": "gap [m]",
        "median_g": "lognormal fragility's median theta: P(pounding | x) = Phi(ln(x / theta) / beta) [g]",
        "beta": "its dispersion (log standard deviation) [-]",
        "status": "'ok'; 'separated' (every pounding at or above every non-pounding, both at one intensity at most: "
        "beta -> 0, median between them); 'none' (no pounding: median inf); 'all' (pounding at every point: "
        "median 0); 'flat' (pounding does not grow with the intensity)",
        "loglik": "log-likelihood of the fit (binomial, Baker 2015); not 'ok': the supremum the data allow [-]",
        "median_ci_low_g": "bootstrap (over motions) percentile interval of the median; NaN where the fit is not 'ok' "
        "or more than (1 - confidence) / 2 of the replicates are not [g]",
        "median_ci_high_g": "its upper end [g]",
        "beta_ci_low": "bootstrap percentile interval of beta [-]",
        "beta_ci_high": "its upper end [-]",
        "bootstrap_ok_fraction": "fraction of bootstrap replicates whose fit is 'ok' [-]",
        "motions": "motions of the study [-]",
        "poundings": "outcomes that pounded at this gap (runs of a cloud; motions x levels of stripes) [-]",
        "outcomes": "all outcomes the fit weighs; fewer than 10 of the rarer outcome: weakly identified [-]",
    },
    "required_gap": {
        "intensity_g": "intensity [g]",
        "target_probability": "target probability of pounding [-]",
        "empirical_gap_m": "the order statistic of the stripe's required gaps exceeded by at most that fraction [m]",
        "empirical_ci_low_m": "distribution-free interval (order statistics) at [risk] confidence; NaN: too few motions [m]",
        "empirical_ci_high_m": "its upper end [m]",
        "motions": "motions behind it [-]",
        "lognormal_gap_m": "gap at which the lognormal fragilities give the target (interpolated in ln gap) [m]",
        "lognormal_interpolation_m": "how far it moves interpolated through three gaps instead of two: the gap grid's "
        "own error, not in the interval (a note where it exceeds a quarter of the interval); NaN without a third "
        "fitted gap or where the fits' probits do not fall with the gap (weakly identified fits) [m]",
        "lognormal_ci_low_m": "bootstrap percentile interval; NaN without an estimate or where more than "
        "(1 - confidence) / 2 of the replicates give no gap [m]",
        "lognormal_ci_high_m": "its upper end [m]",
        "bootstrap_found_fraction": "fraction of replicates that give a gap (target inside the gaps studied, fits "
        "identified) [-]",
        "note": "why a value of the row is NaN, or the gap grid is coarse for it ('' when neither)",
    },
    "code_rules": {
        "intensity_g": "intensity [g]",
        "rule": "ABS, SRSS, DDC (from the median peak displacements of the motions at this intensity) or "
        f"TBEC2018_min ({TBEC2018_RULE}, at the top facing floor)",
        "gap_m": "the gap the rule asks for [m]",
        "motions": "motions [-]",
        "pounding": "motions that pound at that gap [-]",
        "probability": "pounding / motions [-]",
        **_CI,
        "lognormal_probability": "the lognormal fragility of that gap at this intensity [-]",
        "lognormal_ci_low": "bootstrap percentile interval; NaN as for the required gap's [-]",
        "lognormal_ci_high": "its upper end [-]",
        "per_motion_pounding": "motions that pound at the gap the rule gives from their own peaks [-]",
        "per_motion_probability": "per_motion_pounding / motions [-]",
        "per_motion_ci_low": "Clopper-Pearson interval [-]",
        "per_motion_ci_high": "its upper end [-]",
    },
    "consequences": {
        "gap_m": "gap of the contact runs [m]",
        "scale": _GROUP["scale"],
        "intensity_g": "median intensity of the motions [g]",
        "quantity": "disp_ratio_b* (top floor peak displacement with / without contact), drift_ratio_b* (largest "
        "story drift), acc_ratio_b* (top floor peak absolute acceleration), peak_force_N (largest pounding force "
        "over the pairs [N]), impacts (contact phases over the pairs)",
        "unit": "the quantity's unit, that of its mean and quantiles ('N': the force; '-': the ratios and counts)",
        "motions": "motions [-]",
        "pounded": "motions with at least one impact [-]",
        "mean": "mean over the motions (the quantity's unit)",
        "q05": "5 % quantile over the motions",
        "q16": "16 %",
        "q50": "median",
        "q84": "84 %",
        "q95": "95 %",
    },
    "annual_rate": {
        "gap_m": "gap [m]",
        "annual_rate_per_yr": "annual rate of pounding: the fragility integrated over the hazard curve; NaN where "
        "the fragility is not 'ok' (see note) [1/yr]",
        "ci_low_per_yr": "bootstrap percentile interval; NaN without an estimate or where more than "
        "(1 - confidence) / 2 of the replicates give none [1/yr]",
        "ci_high_per_yr": "its upper end [1/yr]",
        "bootstrap_found_fraction": "fraction of replicates that give a rate [-]",
        "return_period_yr": "1 / annual rate [yr]",
        "status": "the gap's fragility status (fragility table)",
        "note": "why the rate is NaN ('' when it is given)",
    },
}
