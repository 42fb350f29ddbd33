"""2D discrete-element simulator of soft, shape-invariant convex polygons.

Implements Section 2 and the Appendix of Roul, Schinner & Kassner,
"Mechanical properties of non-cohesive polygonal particle aggregates",
Granular Matter (2010).

Importing the package runs nothing: the modules that the analysis and the
workflow share (:mod:`sim.atomic`, :mod:`sim.digest`, :mod:`sim.distinct_paths`,
:mod:`sim.schema`, :mod:`sim.settings_file`) load without Numba, and the
kernels' modules set Numba's cache folder themselves
(:mod:`sim.kernel_cache`).
"""

__version__ = "0.1.0"
