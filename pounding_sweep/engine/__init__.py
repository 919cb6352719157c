"""The engine: the Numba kernels and their driver. Arrays in (engine/inputs.py: typed records), metric
rows, histories and scores out; it knows nothing of TOML, Parquet, Dask or the command line.

Modules: inputs (the records), layout (the metric row's slots and status bits: one home for the kernels
and the writer), jit (Numba flags and the cache keyed by the engine's sources), registry (the kernels:
each one's entry point, compile label and why it cannot run a chunk), events (the event scheme's located
step, written once, each kernel supplying its coordinate-specific pieces), floors (those pieces in floor
coordinates), scalar (one run at a time, floor coordinates, every option, the linear laws), nonlinear
(the same for the Hertz-type laws), bookkeeping (the metric rows both share), lanes (a package: a SIMD register's width of runs
side by side in SIMD lanes, modal coordinates) and simd (its vector type), clock, score (eq. 20 and the
scores of a run against an experiment), driver (threads; the kernel the registry chooses). docs/explanation/engine.md
explains them.

May import the model layer (its array types), the shared bottom modules, NumPy, Numba and llvmlite.
"""
