"""Micro-to-macro analysis of particle states: RVE fields, ensembles, elastic fits.

Reads particle-state files only through the data contract (docs/formats.md#state-files):
the data flows one way, from the simulator to the analysis.  Of the simulator's
package it imports five light modules only, which import nothing else of it
and load without Numba: the settings reader :mod:`sim.settings_file`, the
schema check :mod:`sim.schema`, the command line's path check
:mod:`sim.distinct_paths`, the digests :mod:`sim.digest` and the atomic write
:mod:`sim.atomic` (tests/test_layering.py).  Modules, one concern each:

``states``        read and validate contract state files
``rve``           grid of RVE centres, membership of particles and contacts
``stress``        Eq. 2 (particle and RVE stress)
``strain``        Eqs 3–9 (Cambou best-fit displacement gradient)
``fabric``        Eqs 10–12 (fabric tensor)
``orientation``   principal values and axis angles
``solid_fraction``, ``surface``  packing fraction, free surface and depth
``fields``        the per-pile fields file (docs/formats.md#fields)
``ensemble``      seed averages with standard errors (docs/formats.md#ensemble-fields)
``elastic``       Eqs 16–22 (isotropic and cubic fits)
``invariants``    Sect. 6 (trace of stress vs trace of strain)
``base_pressure`` forces per unit length on the support
``balance``       balance-law checks
``convergence``   RVE-size convergence (Fig. 1)
``figures``       Figs 1–5 and the base pressure
``draw``          pictures of particle states (polygons by Eq. 2 pressure, force network)
``netcdf``        CF attributes and atomic writes

Numerics of whole piles, their error and cost against run time (the workflow's
target ``numerics_piles``), live in the subpackage :mod:`analysis.numerics`.

Command line: ``python -m analysis --help``.
"""

__version__ = "0.1.0"
