"""dt = "auto": each run's time step chosen by step doubling against a tolerance the scene sets.

Every run starts at dt_max; the chunk is run again at dt/2, dt/4, ... and a run is accepted at the
first level whose result differs from the previous level's by less than the tolerance, after the
Richardson factor of the scheme's order p: error(dt/2) ~ |M(dt/2) - M(dt)| / (2^p - 1) (Hairer,
Norsett & Wanner, Solving ODEs I, sec. II.4). M is what the run is judged by: with an experiment,
the eq. 20 error (in fractions of the experiment's RMS) and the numerical peak of each channel;
without, the peak displacements and peak forces (relative to the largest of their kind). Runs that
do not meet it by dt_min keep the finest result and are flagged `dt_tolerance_not_met`. The chosen
dt and the estimate are written per run (columns dt_s, dt_error_estimate); run_time_s is the time
spent on the run over all levels tried.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from pounding_sweep.engine import layout as L
from pounding_sweep.engine.score import S_PEAK_NUM, S_REL_RMS_PCT

ORDER = {"event": 2, "implicit": 1, "paper": 1}  # observed orders across impacts (benchmarks/ACCURACY.md)


class AutoDt:
    """The ladder of fixed-dt preparations of one scene, built on first use of each level."""

    def __init__(self, scene, prepare):
        i = scene.integration
        self.scene = scene
        self.tol = i.dt_tolerance
        self.dt_max = i.dt_max_s
        self.n_levels = max(1, int(math.floor(math.log2(i.dt_max_s / i.dt_min_s) + 1e-9)) + 1)
        self.factor = 2.0 ** ORDER[i.scheme] - 1.0
        self._prepare = prepare
        self._levels: dict = {}
        self.check_finest()

    def check_finest(self) -> None:
        """Refuse before any run a dt_min_s whose runs would be too long to integrate (the finest
        level is otherwise only built mid-sweep, after parts were written)."""
        from pounding_sweep.model.excitation import Excitation
        from pounding_sweep.scene import MAX_STEPS, ConfigError

        duration = Excitation.from_scene(self.scene, self.dt_max).max_duration_s
        steps = duration / self.dt(self.n_levels - 1)
        if steps > MAX_STEPS:
            raise ConfigError(
                f"[integration] dt_min_s = {self.scene.integration.dt_min_s!r}: runs of {duration:.4g} s "
                f"would take {steps:,.0f} steps at the finest level, more than {MAX_STEPS:,}"
            )

    def dt(self, level: int) -> float:
        return self.dt_max / 2.0**level

    def level(self, k: int):
        if k not in self._levels:
            fixed = dataclasses.replace(self.scene.integration, dt_s=self.dt(k))
            self._levels[k] = self._prepare(dataclasses.replace(self.scene, integration=fixed))
        return self._levels[k]

    def __getstate__(self):  # ship the recipe to Dask workers, not the arrays of every level
        return {**self.__dict__, "_levels": {}}

    def run(self, params: dict, threads: int = 1, batch_runs: int = 0):
        """As Prepared.run, each run at its own dt; derived gains dt_s and dt_error_estimate."""
        n = params["run_id"].size
        metrics, run_time, _, scores, derived = self.level(0).run(params, threads, batch_runs)
        spent = run_time.copy()
        dt = np.full(n, self.dt(0))
        est = np.full(n, np.inf)
        pending = np.arange(n)
        prev_m = metrics.copy()  # each run's result at the level before (indexed by run)
        prev_s = None if scores is None else scores.copy()
        for k in range(1, self.n_levels):
            sub = {key: v[pending] for key, v in params.items()}
            m, rt, _, sc, der = self.level(k).run(sub, threads, batch_runs)
            spent[pending] += rt
            e = self.estimate(prev_m[pending], m, None if sc is None else prev_s[pending], sc)
            metrics[pending] = m
            prev_m[pending] = m
            if sc is not None:
                scores[pending] = sc
                prev_s[pending] = sc
            for key, v in der.items():
                derived[key][pending] = v
            dt[pending] = self.dt(k)
            est[pending] = e
            pending = pending[~(e <= self.tol)]
            if pending.size == 0:
                break
        status_col = L.n_metrics(self.level(0).sysarr.m.size, self.level(0).sysarr.i1.size) - L.PER_RUN + L.RUN_STATUS
        if pending.size:
            metrics[pending, status_col] = metrics[pending, status_col].astype(np.int64) | L.STATUS_DT_UNCONVERGED
        derived["dt_s"] = dt
        derived["dt_error_estimate"] = est
        return metrics, spent, None, scores, derived

    def estimate(self, coarse: np.ndarray, fine: np.ndarray, sc_coarse, sc_fine) -> np.ndarray:
        """Richardson estimate of each run's relative error at the finer dt."""
        nd = self.level(0).sysarr.m.size
        npair = self.level(0).sysarr.i1.size
        if sc_fine is not None:
            rms = np.abs(sc_fine[:, :, S_REL_RMS_PCT] - sc_coarse[:, :, S_REL_RMS_PCT]) / 100.0
            pk_f, pk_c = sc_fine[:, :, S_PEAK_NUM], sc_coarse[:, :, S_PEAK_NUM]
            peak = np.abs(pk_f - pk_c) / np.maximum(np.abs(pk_f), 1e-300)
            err = np.maximum(rms.max(axis=1), peak.max(axis=1))
        else:
            d_idx = [L.dof_slot(i, L.DOF_PEAK_DISP) for i in range(nd)]
            f_idx = [L.PER_DOF * nd + L.PER_PAIR * j + L.PAIR_PEAK_FORCE for j in range(npair)]
            err = np.zeros(fine.shape[0])
            for idx in (d_idx, f_idx):
                scale = np.abs(fine[:, idx]).max(axis=1)
                diff = np.abs(fine[:, idx] - coarse[:, idx]).max(axis=1)
                err = np.maximum(err, np.where(scale > 0, diff / np.where(scale > 0, scale, 1.0), 0.0))
        status_col = L.PER_DOF * nd + L.PER_PAIR * npair + L.RUN_STATUS
        bad = (fine[:, status_col].astype(np.int64) | coarse[:, status_col].astype(np.int64)) & L.STATUS_NONFINITE
        err = err / self.factor
        return np.where((bad != 0) | ~np.isfinite(err), np.inf, err)
