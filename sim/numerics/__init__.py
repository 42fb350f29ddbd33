"""Numerical checks of the simulator: accuracy against run time, stability limits, cost of scenes."""
