"""Principal values and orientation of principal axes of symmetric 2×2 tensors.

Angle convention (used for fabric, stress and strain alike): the angle of an
axis is measured **from the vertical (+y) axis, positive counter-clockwise**
(the mathematically positive sense), in degrees, folded into (−90, 90]. An
axis at +40° has its upper end leaning towards −x; at −40° towards +x. With
this convention the pattern of the paper's Fig. 3c (−40° on the left flank,
+40° on the right) means axes whose upper ends lean towards the pile axis.
Where the two principal values coincide (to rounding) the axis is undefined
and the angle is NaN.

Which axis is "major": for the fabric the largest eigenvalue (most contacts);
for stress (compression negative) the most compressive, i.e. the smallest
eigenvalue; for the increments (``stress_increment``, ``strain_increment``,
defined reduced − relaxed, an unloading) the largest eigenvalue, which is the
most compressive direction of the loading step reduced → full gravity.
"""

from __future__ import annotations

import numpy as np


def principal_values(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues ``(min, max)`` of the symmetric part of tensors ``(..., 2, 2)``."""
    a, d = t[..., 0, 0], t[..., 1, 1]
    b = 0.5 * (t[..., 0, 1] + t[..., 1, 0])
    mean = 0.5 * (a + d)
    rad = np.sqrt(0.25 * (a - d) ** 2 + b * b)
    return mean - rad, mean + rad


def fold_axis_angle(deg: np.ndarray) -> np.ndarray:
    """Fold an axis angle (degrees) into (−90, 90] (axes have no sign)."""
    out = np.mod(np.asarray(deg, dtype=float) + 90.0, 180.0) - 90.0
    return np.where(out == -90.0, 90.0, out)


def axis_angle_from_vertical(t: np.ndarray, major: str = "largest", rtol: float = 1e-10) -> np.ndarray:
    """Angle (degrees, from +y, counter-clockwise, in (−90, 90]) of a principal axis.

    Parameters
    ----------
    t : tensors ``(..., 2, 2)`` (symmetric part used).
    major : ``"largest"`` for the eigenvector of the largest eigenvalue,
        ``"smallest"`` for the smallest (most compressive stress).
    rtol : the angle is NaN when ``lambda_max - lambda_min <= rtol * max|lambda|``.
    """
    a, d = t[..., 0, 0], t[..., 1, 1]
    b = 0.5 * (t[..., 0, 1] + t[..., 1, 0])
    # eigenvector of the largest eigenvalue is at phi from +x (counter-clockwise)
    phi = 0.5 * np.degrees(np.arctan2(2 * b, a - d))
    if major == "largest":
        ang = phi - 90.0
    elif major == "smallest":
        ang = phi
    else:
        raise ValueError(f"major must be 'largest' or 'smallest', got {major!r}")
    lo, hi = principal_values(t)
    scale = np.maximum(np.abs(lo), np.abs(hi))
    undefined = ~((hi - lo) > rtol * scale)
    return np.where(undefined, np.nan, fold_axis_angle(ang))


def axis_angle_difference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Difference ``a - b`` of two axis angles (degrees), folded into (−90, 90]."""
    return fold_axis_angle(np.asarray(a) - np.asarray(b))
