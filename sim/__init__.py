"""2D discrete-element simulator of soft, shape-invariant convex polygons.

Implements Section 2 and the Appendix of Roul, Schinner & Kassner,
"Mechanical properties of non-cohesive polygonal particle aggregates",
Granular Matter (2010).
"""

__version__ = "0.1.0"
