"""pounding_sweep: parameter sweeps of pounding between two adjacent shear frames.

Layers, each a subpackage that imports only those below it (tests/test_layers.py checks it):

    errors, codes, progress, warn   shared bottom modules (import nothing of the package)
    scene      TOML -> validated, frozen dataclasses; --describe; the config hash
    model      scene -> arrays: structure, contact parameters, records, excitation, grid, experiment tables
    engine     the Numba kernels and their driver (arrays in, metric rows out)
    video, identify           LED tracking; modal identification and model update
    sweep      prepare -> run chunks (local threads, Dask) -> Parquet, resume, scoring, ranking, simulate
    reference, synthetic      the slow oracles; synthetic experiments
    accuracy   error against run time, stability of runs
    plots, cli                figures; the command line (python -m pounding_sweep)

Units are SI throughout (m, kg, s, N).
"""

__version__ = "0.1.0"
