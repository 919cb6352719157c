"""The sweep layer: a scene's grid run chunk by chunk (prepare -> executors -> engine) into a Parquet
dataset, resumed where an interrupted run left it, scored against an experiment as it goes, the best
runs ranked and refined; one run in memory (simulate); dt = "auto" by step doubling.

May import scene, model, engine and video (lazily: OpenCV only for an [experiment.video]); never the
command line or the plots. Modules: prepare, run, resume, results (Parquet parts and metadata),
executors (local threads, Dask), scoring (experiment samples), ranking, autodt, simulate.
"""

from pounding_sweep.sweep.prepare import Prepared, prepare
from pounding_sweep.sweep.run import SweepSummary, run_scene
from pounding_sweep.sweep.simulate import simulate, with_overrides

__all__ = ["Prepared", "prepare", "SweepSummary", "run_scene", "simulate", "with_overrides"]
