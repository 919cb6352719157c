"""Probabilistic pounding: over an ensemble of ground motions (a record suite scaled to an intensity measure,
or a stochastic family with the seed as an axis), the probability of pounding against the gap, lognormal
fragility curves, the gap a target probability needs, the probability each code rule's gap leaves, and with a
hazard curve the annual rate of pounding; and the closed-form oracles that check the Monte Carlo.

Layer: above the gap studies (it takes their rules and separated gap) and the sweep layer (its runs go through
run_scene: resumable, any executor), below plots and the command line. Modules: probability (binomial and
order-statistic intervals), fragility (lognormal MLE, bootstrap over motions), oracle (Lyapunov, Rice,
Poisson, Vanmarcke), hazard (annual rate), analysis (the tables), study (runs and output), columns (what the
columns mean), figures (matplotlib, imported lazily).
"""

from pounding_sweep.risk.fragility import Fit, fit_lognormal
from pounding_sweep.risk.probability import clopper_pearson, probability_of_pounding, required_gap_empirical
from pounding_sweep.risk.study import RiskStudy, analyse, risk_study, write_study

__all__ = [
    "Fit",
    "fit_lognormal",
    "clopper_pearson",
    "probability_of_pounding",
    "required_gap_empirical",
    "RiskStudy",
    "analyse",
    "risk_study",
    "write_study",
]
