"""Cosine and sine of a particle's orientation, computed without libm.

Every step places every particle's corners at ``(x + X cos θ − Y sin θ,
y + X sin θ + Y cos θ)`` (:func:`sim.step.predict_and_place`), so the cosine
and sine of θ are computed once per particle and step.  libm's ``sin`` and
``cos`` cost more than half of that prediction pass (measured with
``python -m sim numerics kernel-profile --kernel predict``), and their last
bit may differ between hosts' math libraries.  :func:`cos_sin` computes both
with a few multiplications and additions (IEEE arithmetic, no math
library):

1. **Reduction.**  ``k = round(θ / (π/2))`` and ``y = θ − k π/2`` with π/2
   split in two parts (Cody & Waite): the first part carries 33 significant
   bits, so ``k`` times it is exact for ``|k| < 2**20``; the second carries
   the next 53 bits.  ``|y| ≤ π/4``.
2. **Kernels.**  Odd and even polynomials of degree 13 and 14 in ``y``
   (the minimax coefficients of Sun Microsystems' freely distributed fdlibm,
   whose error on ``[−π/4, π/4]`` lies below 2**-58); the cosine's
   ``1 − y²/2`` is summed with its rounding error carried, in fdlibm's manner.
3. **Quadrant.**  ``k mod 4`` swaps and negates the two.

Both values are within one unit in the last place of the correctly rounded
ones for ``|θ| ≤ 1000`` rad and within 2**-53 of them in absolute value up to
:data:`REDUCTION_LIMIT` (checked against numpy in ``tests/test_rotation.py``).
Beyond that limit (a particle would have turned 130 000 times) libm is used.
"""

from __future__ import annotations

import math

import numpy as np

from .kernel_cache import njit

#: The first 33 significant bits of π/2, so that ``k * PIO2_HIGH`` is exact.
PIO2_HIGH = 1.57079632673412561417e+00
#: π/2 − PIO2_HIGH, rounded to double.
PIO2_LOW = 6.07710050650619224932e-11
#: 2/π, rounded to double.
TWO_OVER_PI = 6.36619772367581382433e-01
#: Largest |θ| (rad) reduced here: ``k`` stays below 2**19, well inside the
#: range where ``k * PIO2_HIGH`` is exact.
REDUCTION_LIMIT = 2.0 ** 19 * (math.pi / 2)

# fdlibm's minimax coefficients: sin y ≈ y + y³ (S1 + y² S2 + ... + y¹⁰ S6)
S1 = -1.66666666666666324348e-01
S2 = 8.33333333332248946124e-03
S3 = -1.98412698298579493134e-04
S4 = 2.75573137070700676789e-06
S5 = -2.50507602534068634195e-08
S6 = 1.58969099521155010221e-10
# cos y ≈ 1 − y²/2 + y⁴ (C1 + y² C2 + ... + y¹⁰ C6)
C1 = 4.16666666666666019037e-02
C2 = -1.38888888888741095749e-03
C3 = 2.48015872894767294178e-05
C4 = -2.75573143513906633035e-07
C5 = 2.08757232129817482790e-09
C6 = -1.13596475577881948265e-11


@njit(cache=True, inline="always")
def cos_sin(theta):
    """Cosine and sine of an angle, without libm for ``|theta| ≤ REDUCTION_LIMIT``.

    Parameters
    ----------
    theta : float
        Angle, rad.

    Returns
    -------
    (float, float)
        ``cos(theta)`` and ``sin(theta)``: within one unit in the last place
        of the correctly rounded values for ``|theta| ≤ 1000``, within 2**-53
        of them up to :data:`REDUCTION_LIMIT`, libm's beyond (module
        docstring).
    """
    if not abs(theta) <= REDUCTION_LIMIT:  # also NaN and ±inf: libm's answer
        return math.cos(theta), math.sin(theta)
    k = np.floor(theta * TWO_OVER_PI + 0.5)
    y = (theta - k * PIO2_HIGH) - k * PIO2_LOW
    z = y * y
    sin_y = y + y * z * (S1 + z * (S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))))
    tail = z * z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6)))))
    half_z = 0.5 * z
    w = 1.0 - half_z
    cos_y = w + (((1.0 - w) - half_z) + tail)
    quadrant = np.int64(k) & 3
    if quadrant & 1:
        c, s = sin_y, cos_y
    else:
        c, s = cos_y, sin_y
    if quadrant == 1 or quadrant == 2:
        c = -c
    if quadrant >= 2:
        s = -s
    return c, s
