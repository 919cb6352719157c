"""The engine: the Numba kernels and their driver. Arrays in (engine/inputs.py: typed records), metric
rows, histories and scores out; it knows nothing of TOML, Parquet, Dask or the command line.

Modules: inputs (the records), layout (the metric row's slots and status bits: one home for the kernels
and the writer), jit (Numba flags and the cache keyed by the engine's sources), events (the event
scheme's coordinate-free pieces), clock, scalar (one run at a time, floor coordinates, every option, the linear
laws), nonlinear (the same for the Hertz-type laws), bookkeeping (the metric rows both share),
lanes and simd (8 runs side by side in SIMD lanes, modal coordinates), score (eq. 20 and the scores of a
run against an experiment), driver (threads, the kernel chosen by argument).

May import the model layer (its array types), the shared bottom modules, NumPy, Numba and llvmlite.
"""
