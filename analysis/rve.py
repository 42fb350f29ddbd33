"""Representative volume elements (RVEs): the grid of centres and membership.

Conventions (documented once, used by every field):

* An RVE is a square of side ``size`` or a disc of diameter ``size`` around
  its centre, **clipped to the half-plane y >= 0 above the support**; its
  volume ``V`` (an area in 2D) is the area of that clipped shape.
* A **particle belongs** to an RVE when its centre of mass lies inside
  (boundary included), with weight 1. Membership is decided once, on the
  positions at full gravity (``relaxed``), and used for both stages so the
  increments are differences over one and the same set of particles.
* For **stress and fabric** every contact of a member particle counts,
  including contacts with non-members and with the support (each contact
  enters through its member particle's Eq. 2 / Eq. 10 sum).
* For **strain** a particle–particle contact counts when both of its
  particles are members (the branch vector ``l`` then lies in the RVE).

The grid is regular, in absolute coordinates (x = 0 at the pouring axis,
y = 0 on the support), the same for every pile, so ensembles need no
interpolation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

SHAPES = ("square", "circle")


@dataclass(frozen=True)
class Grid:
    """Regular grid of RVE centres; ``x`` and ``y`` are the 1-D coordinates (m)."""

    x: np.ndarray
    y: np.ndarray

    @classmethod
    def from_params(cls, grid: dict) -> "Grid":
        s = float(grid["spacing"])
        nx = int(np.floor((grid["x_max"] - grid["x_min"]) / s + 1e-9)) + 1
        ny = int(np.floor((grid["y_max"] - grid["y_min"]) / s + 1e-9)) + 1
        x = np.round(grid["x_min"] + s * np.arange(nx), 12)
        y = np.round(grid["y_min"] + s * np.arange(ny), 12)
        return cls(x=x, y=y)

    @property
    def shape(self) -> tuple[int, int]:
        return (self.y.size, self.x.size)

    def centres(self) -> np.ndarray:
        """Centres as ``(ny*nx, 2)``, flattened in (y, x) C order."""
        X, Y = np.meshgrid(self.x, self.y)
        return np.column_stack([X.ravel(), Y.ravel()])


def rve_area(cy: np.ndarray, shape: str, size: float) -> np.ndarray:
    """Area V of the RVE (square of side / disc of diameter ``size``) above y = 0."""
    cy = np.asarray(cy, dtype=float)
    if shape == "square":
        top = cy + size / 2
        bottom = np.maximum(cy - size / 2, 0.0)
        return size * np.clip(top - bottom, 0.0, size)
    if shape == "circle":
        r = size / 2
        d = np.clip(cy, -r, r)  # signed distance of the centre above the support
        cap = r * r * np.arccos(d / r) - d * np.sqrt(np.maximum(r * r - d * d, 0.0))
        return np.pi * r * r - cap
    raise ValueError(f"RVE shape {shape!r} not in {SHAPES}")


def membership(centres: np.ndarray, px: np.ndarray, py: np.ndarray, shape: str, size: float) -> sp.csr_matrix:
    """Sparse 0/1 matrix ``W[r, p]``: particle ``p``'s centre lies in RVE ``r``.

    Square RVEs use the Chebyshev distance (|dx| <= size/2 and |dy| <= size/2),
    discs the Euclidean one; particles below the support (y < 0) never belong.
    """
    if shape not in SHAPES:
        raise ValueError(f"RVE shape {shape!r} not in {SHAPES}")
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    pts = np.column_stack([px, py])
    n_r, n_p = centres.shape[0], pts.shape[0]
    if n_r == 0 or n_p == 0:
        return sp.csr_matrix((n_r, n_p))
    p = np.inf if shape == "square" else 2.0
    # a tiny relative margin makes membership of particles exactly on an edge
    # independent of floating-point noise in the centres
    r = size / 2 * (1 + 1e-12)
    pairs = cKDTree(centres).sparse_distance_matrix(cKDTree(pts), r, p=p, output_type="ndarray")
    rows, cols = pairs["i"].astype(np.int64), pairs["j"].astype(np.int64)
    keep = py[cols] >= 0
    rows, cols = rows[keep], cols[keep]
    return sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n_r, n_p))


def pair_membership(W: sp.csr_matrix, i: np.ndarray, j: np.ndarray) -> sp.csr_matrix:
    """Sparse 0/1 matrix ``Wc[r, c]``: both particles ``i[c]`` and ``j[c]`` are in RVE ``r``."""
    Wc = W.tocsc()
    return Wc[:, i].multiply(Wc[:, j]).tocsr()


def rve_sum(W: sp.csr_matrix, values: np.ndarray) -> np.ndarray:
    """Sum of per-particle (or per-contact) ``values`` over each RVE: ``W @ values``.

    ``values`` may have trailing dimensions (e.g. ``(n, 2, 2)`` tensors).
    """
    values = np.asarray(values, dtype=float)
    flat = values.reshape(values.shape[0], -1)
    return np.asarray(W @ flat).reshape((W.shape[0],) + values.shape[1:])


# flags of `mask_reason` (CF flag_masks)
MASK_TOO_FEW_PARTICLES = 1
MASK_LOW_SOLID_FRACTION = 2
MASK_FLAGS = {"flag_masks": np.array([MASK_TOO_FEW_PARTICLES, MASK_LOW_SOLID_FRACTION], dtype=np.int32),
              "flag_meanings": "too_few_particles low_solid_fraction"}


def mask_reason(n_particles: np.ndarray, solid_fraction: np.ndarray, min_particles: int,
                min_solid_fraction: float) -> np.ndarray:
    """Bit mask why an RVE is not used (0 = valid): 1 too few particles, 2 solid fraction too low."""
    m = np.where(n_particles < min_particles, MASK_TOO_FEW_PARTICLES, 0)
    sf = np.nan_to_num(solid_fraction, nan=0.0)
    m = m | np.where(sf < min_solid_fraction, MASK_LOW_SOLID_FRACTION, 0)
    return m.astype(np.int32)
