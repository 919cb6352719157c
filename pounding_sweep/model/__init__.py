"""The model layer: a scene turned into arrays, before any kernel. The two shear frames (structure:
mass, stiffness, Rayleigh damping, modes; coupled: the coupled system and its Newmark matrices at a
dt; modal: its modal coordinates), the contact laws' parameters (contact: eqs. 9-10), ground-motion
records (records: AT2 / CSV readers, similitude scaling, resampling) and the excitation of each run
(excitation), the sweep grid (grid), and experiment tables read and checked (experiment).

May import the scene layer, the shared bottom modules (errors, codes), NumPy, SciPy and pandas; never
Numba or anything above (engine, sweep, video, the command line).
"""
