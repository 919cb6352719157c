"""pounding_sweep: parameter sweeps of pounding between two adjacent shear frames.

Data flow: scene (config) -> model (structure, contact) -> excitation -> Numba kernel
-> per-run metrics -> Parquet. Units are SI throughout (m, kg, s, N).
"""

__version__ = "0.1.0"
