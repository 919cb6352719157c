"""Modal identification and model update (paper sec. 3): spectra, peak frequencies, damping and mode
shapes of displacement records (modes), the stiffness update that matches a building's first frequency
(update), and both applied to a displacement table (table).

May import the scene and model layers, the shared bottom modules, NumPy and SciPy; never the engine,
the sweep layer or OpenCV.
"""
