"""Video tracking of the LED markers (paper sec. 3), synthetic shake-table videos, and the
`track` / `identify` commands.

Modules: io (reading/writing video, VideoError), render (synthetic videos with known motion),
tracker (markers -> displacement relative to the table), scene (the `[experiment.video]`
section; no OpenCV import), cli. OpenCV is imported only inside this package's io, render and
tracker modules, never by `import pounding_sweep` or a sweep.
"""
