"""Numerical checks of the simulator: accuracy against run time, stability limits, cost of scenes, and the bench
(``python -m sim bench``: :mod:`sim.numerics.bench`, with its LAMMPS peer)."""
