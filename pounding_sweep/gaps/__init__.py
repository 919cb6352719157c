"""Seismic-gap studies: how close the buildings come, the gap each floor pair needs (exact and by the
rules of codes and literature), and how the response changes when the gap is short.

Layer: above the sweep layer (it runs scenes through prepare and the engine), beside accuracy.
Modules: rules (ABS, SRSS, DDC with Der Kiureghian's correlation, TBEC 2018's minimum), study (the runs
and the tables), figures (matplotlib, imported lazily).
"""

from pounding_sweep.gaps.rules import RULES, combined_gap, cqc_correlation, tbec2018_minimum_gap_m
from pounding_sweep.gaps.study import (
    RELATIVE_GAPS,
    SEPARATED_GAP_M,
    GapStudy,
    gap_study,
    required_gaps,
    response_ratios,
)

__all__ = [
    "RULES",
    "combined_gap",
    "cqc_correlation",
    "tbec2018_minimum_gap_m",
    "RELATIVE_GAPS",
    "SEPARATED_GAP_M",
    "GapStudy",
    "gap_study",
    "required_gaps",
    "response_ratios",
]
