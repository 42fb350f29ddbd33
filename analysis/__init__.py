"""Micro-to-macro analysis of particle states: RVE fields, ensembles, elastic fits."""

__version__ = "0.1.0"
