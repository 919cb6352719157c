"""Video tracking of the LED markers (paper sec. 3) and synthetic shake-table videos.

Modules: io (reading and writing video), render (synthetic videos with known motion), tracker (markers
-> displacement relative to the table; the table of an [experiment.video] section). The section itself
is plain data in the scene layer (scene/video.py). OpenCV is imported only inside io, render and
tracker, never by `import pounding_sweep` or a sweep without a video.

May import the scene and model layers, the shared bottom modules, NumPy, SciPy, pandas, pyarrow and
OpenCV; never the engine, the sweep layer or the command line.
"""
