"""The affine (Voigt) stiffness of an RVE from its own contacts (issue 27, item 4).

A micro-mechanical reference beside the fitted moduli (:mod:`analysis.elastic`):
impose on every particle of the relaxed pile the displacement of one uniform
strain, ``u(x) = x · ε`` (``u_j = x_i ε_ij``, docs/formats.md#conventions), with
no particle rotation, keep every contact sticking, and sum the contact-force
changes this gives in the RVE stress of Eq. 2.  The result, per RVE,

    Δσ_M = C_MN ε_N      (Mandel: t_M = (t_xx, t_yy, √2 t_xy)),

is the Voigt stiffness.  A disordered packing relaxes by non-affine motion and
by sliding, so its real response is softer: the ratio of ``C`` to the fitted
stiffness measures how far the pile is from affine deformation.

**The sum.**  Eq. 2 gives the RVE stress ``σ_ab = (1/V) Σ_p Σ_c b_a f_b``
over the member particles ``p`` and all their contacts ``c`` (the support
included), ``b = s − x_p`` the branch vector to the force point ``s`` and
``f`` the force on ``p``.  Under the affine field the other body of the
contact moves relative to ``p`` by ``l · ε`` at the contact, with ``l = x_q −
x_p`` (``q`` the other particle) or ``l = s − x_p`` for the support (its
material point at ``s`` follows the field, whose origin on the support makes
pure normal strains leave it in place), and the force on ``p`` changes by
``Δf = K (l · ε)``, ``K = k_n n nᵀ + k_t t tᵀ`` (``n`` the contact normal,
``t = (−n_y, n_x)``).  So

    C_ab,cd = (1/V) Σ_p Σ_c b_a K_bd l_c,   symmetrised in (a, b) and in (c, d).

For a contact with both particles in the RVE the two ends add up to
``l_a K_bd l_c`` (``b_p − b_q = l``): the classical Voigt sum
``(1/V) Σ_c (k_n (l⊗n)(l⊗n) + k_t (l⊗t)(l⊗t))``.  A contact with one
particle outside counts through its member's branch vector alone, as it does
in the stress; such contacts make ``C`` slightly unsymmetric (``C_MN ≠ C_NM``),
which the isotropic projections below do not see.

**Normal stiffness** from the paper's law ``F = Y A / l``, ``l = r_i r_j /
(r_i + r_j)`` with ``r_i, r_j`` the distances of the force point from both
centres (``l = r_i`` on the support; :mod:`sim.contact_law`).  The overlap
``A`` of two convex polygons is bounded by the part of each boundary inside
the other; translating ``j`` relative to ``i`` by ``d`` sweeps the part of
``∂P_j`` inside ``P_i``, a polyline from one crossing of the boundaries to the
other whose outward normals integrate to ``−L n`` (``L`` the length of the
contact line, the chord between the crossings, and ``n`` its normal from
``i`` to ``j``).  So, exactly to first order in ``d`` and whatever the
corners involved,

    dA = −L n · d = L dδ       (δ the approach along n; tangential motion does not change A),

the rate the simulator uses for its damping (``dA/dt = L v_n``), and

    dF/dδ = Y L / l − (Y A / l²) dl/dδ.

The first term is ``k_n = Y L / l``, what is used here.  The second, from the
force point moving relative to the centres as the chord lengthens, is
neglected: it is ``A / (L l)`` (the overlap depth ``A / L`` over ``l``)
times ``dl/dδ``, which is small where the chord is fixed by corners (nearly
parallel faces) and of order one where faces cross at a small angle.  Also
neglected, all of the same order ``A / (L l)`` against the terms kept: the
turn of the normal (the preload ``F`` rotating with the contact), the change
of the branch vectors under the preload and of the RVE area.  The fields
file records the median of ``A / (L l)`` over the contacts
(``voigt_depth_ratio_median``, about 1e-3 in the smoke piles).  Against the
simulator's own narrow phase and law under small affine strains
(tests/test_analysis_voigt.py, and by hand on the smoke piles, docs/analysis.md)
the neglected part is 0.6 times that median on a packing of trapezoidal
overlaps, and a few per cent of ``C`` (under 4 % of K and G) on a real pile,
whose faces often cross at small angles.

``L`` is not stored in a state file; it is recovered from the polygons: the
contact line passes through the force point ``s`` (its midpoint) along
``t``, and since both crossings lie on the boundary of the convex overlap, it
is the intersection of that line with both polygons (and with the support's
half-plane ``y <= 0``, which the line ``y = 0`` of a support contact only
touches).  It often runs along a face of one polygon (a face pressed into
the other), which :func:`_chord` allows for.

**Tangential stiffness**: the Cundall–Strack spring loads as ``F∥ ← F∥ +
(2/7) Y v∥ dt`` (``sim.contact_law.tangential_stiffness``), so ``k_t = (2/7)
Y`` for a contact that sticks, on particles and on the support (0 without
friction, ``friction`` or ``support_friction`` = 0, where the simulator
switches the spring off).  Every contact counts as sticking (a contact at its
Coulomb limit ``μ F`` has no tangential stiffness in the direction of
sliding); the fields file records the share of contacts at that limit
(``voigt_sliding_fraction``).  Damping plays no part in a quasi-static
response.

**Isotropic projections** (the paper's law, ``tr Δσ = 2K tr Δu``,
``dev Δσ = 2G dev Δu``, :func:`analysis.general_elastic.isotropic_stiffness`):
``K = (C_11 + C_22 + C_12 + C_21) / 4`` and ``G = (C_11 + C_22 − C_12 − C_21
+ 2 C_33) / 8``, the isotropic law nearest to ``C`` in the Mandel norm; both
exact for an isotropic ``C``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

from .states import State

#: The Cundall–Strack factor: ``k_t = TANGENTIAL_FACTOR · Y`` (sim/contact_law.py, the Appendix's 2/7).
TANGENTIAL_FACTOR = 2.0 / 7.0

#: A contact counts as at its Coulomb limit where ``|T| >= (1 - SLIDING_TOLERANCE) μ F``.
SLIDING_TOLERANCE = 1e-6

SQRT2 = np.sqrt(2.0)


#: A corner within this fraction of its polygon's size from a line lies on it (:func:`_chord`).
ON_LINE = 1e-9


def _chord(vx: np.ndarray, vy: np.ndarray, count: np.ndarray, s: np.ndarray, t: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray]:
    """Parameters ``(τ_min, τ_max)`` of the segment of the line ``s + τ t`` inside each convex polygon.

    ``vx, vy`` are ``(k, kmax)`` corners, padded by repeating the last
    (:meth:`analysis.states.State.world_vertices`); ``count`` the real corner
    numbers; ``s``, ``t`` ``(k, 2)``, ``t`` a unit vector.  The segment runs
    between the extreme points where edges cross the line and the corners
    that lie on it (within :data:`ON_LINE` of the polygon's size): a contact
    line often runs along a face of one polygon, whose corners then lie on
    it.  NaN where the line misses the polygon.
    """
    kmax = vx.shape[1]
    col = np.arange(kmax)[None, :]
    real = col < count[:, None]
    nxt = np.where(real, (col + 1) % count[:, None], 0)
    rows = np.arange(vx.shape[0])[:, None]
    n = np.column_stack([t[:, 1], -t[:, 0]])
    d = (vx - s[:, [0]]) * n[:, [0]] + (vy - s[:, [1]]) * n[:, [1]]          # distance from the line
    p = (vx - s[:, [0]]) * t[:, [0]] + (vy - s[:, [1]]) * t[:, [1]]          # position along it
    size = np.max(np.hypot(vx - vx.mean(axis=1, keepdims=True), vy - vy.mean(axis=1, keepdims=True)), axis=1)
    tol = ON_LINE * size[:, None]
    on = real & (np.abs(d) <= tol)
    d1, p1 = d[rows, nxt], p[rows, nxt]
    cross = real & (((d > tol) & (d1 < -tol)) | ((d < -tol) & (d1 > tol)))
    with np.errstate(invalid="ignore", divide="ignore"):
        at = np.where(cross, p + (p1 - p) * d / (d - d1), np.nan)
    points = np.where(on, p, at)
    hit = np.isfinite(points).any(axis=1)
    lo = np.where(hit, np.min(np.where(np.isfinite(points), points, np.inf), axis=1), np.nan)
    hi = np.where(hit, np.max(np.where(np.isfinite(points), points, -np.inf), axis=1), np.nan)
    return lo, hi


def contact_stiffness(state: State) -> dict[str, np.ndarray]:
    """Per contact of ``state``: the contact-line length, ``l``, ``k_n`` and ``k_t``, and diagnostics.

    Parameters
    ----------
    state : State
        A particle state (docs/formats.md#state-files) with the attribute
        ``youngs_modulus``.

    Returns
    -------
    dict
        ``length`` (m, the contact line ``L``), ``l`` (m, the law's
        characteristic length), ``k_n = Y L / l`` and ``k_t = (2/7) Y`` (N/m;
        0 where the contact's friction coefficient, attribute ``friction`` or
        ``support_friction``, is 0: the simulator then has no spring),
        ``depth_ratio = A / (L l)`` (the order of what ``k_n`` neglects) and
        ``sliding`` (bool: pressed and at the Coulomb limit, with the attributes
        ``friction`` and ``support_friction``; False where they are missing).
    """
    Y = float(state.attrs["youngs_modulus"])
    i, j = state.contact_i.astype(np.int64), state.contact_j.astype(np.int64)
    pp = j >= 0
    s = np.column_stack([state.contact_x, state.contact_y])
    n = np.column_stack([state.normal_x, state.normal_y])
    t = np.column_stack([-n[:, 1], n[:, 0]])
    vx, vy, counts = state.world_vertices()
    lo, hi = _chord(vx[i], vy[i], counts[i], s, t)
    jj = np.where(pp, j, 0)
    lo_j, hi_j = _chord(vx[jj], vy[jj], counts[jj], s, t)
    lo = np.where(pp, np.maximum(lo, lo_j), lo)
    hi = np.where(pp, np.minimum(hi, hi_j), hi)
    length = np.where(np.isfinite(hi - lo), np.maximum(hi - lo, 0.0), 0.0)
    pos = np.column_stack([state.x, state.y])
    r_i = np.hypot(*(s - pos[i]).T)
    r_j = np.where(pp, np.hypot(*(s - pos[jj]).T), np.inf)
    with np.errstate(invalid="ignore", divide="ignore"):
        l = np.where(pp, r_i * r_j / (r_i + r_j), r_i)
        k_n = np.where(l > 0, Y * length / l, np.nan)
        depth_ratio = state.overlap_area / (length * l)
    f = np.column_stack([state.force_x, state.force_y])
    normal = -np.einsum("ka,ka->k", f, n)
    tangential = -np.einsum("ka,ka->k", f, t)
    if "friction" in state.attrs:
        mu = np.where(pp, float(state.attrs["friction"]),
                      float(state.attrs.get("support_friction", state.attrs["friction"])))
        sliding = (normal > 0) & (np.abs(tangential) >= (1.0 - SLIDING_TOLERANCE) * mu * normal)
    else:
        mu = np.ones(i.size)
        sliding = np.zeros(i.size, dtype=bool)
    k_t = np.where(mu > 0, TANGENTIAL_FACTOR * Y, 0.0)      # without friction the simulator has no spring
    return {"length": length, "l": l, "k_n": k_n, "k_t": k_t, "depth_ratio": depth_ratio, "sliding": sliding}


def particle_voigt_moment(state: State, stiffness: dict[str, np.ndarray] | None = None) -> np.ndarray:
    """Per particle, ``Σ_c`` of its contacts' Mandel stiffness moments ``sym(b ⊗ K E_N l)``: ``(n, 3, 3)``, N m.

    Column ``N`` is the Mandel vector of the change of the particle's Eq. 2
    moment ``Σ_c b ⊗ f`` (symmetric part) under the unit Mandel strain
    ``E_N`` (``E_1 = e_x e_x``, ``E_2 = e_y e_y``, ``E_3 = (e_x e_y + e_y
    e_x)/√2``), see the module docstring.
    """
    k = contact_stiffness(state) if stiffness is None else stiffness
    i, j = state.contact_i.astype(np.int64), state.contact_j.astype(np.int64)
    pp = j >= 0
    s = np.column_stack([state.contact_x, state.contact_y])
    pos = np.column_stack([state.x, state.y])
    n = np.column_stack([state.normal_x, state.normal_y])
    t = np.column_stack([-n[:, 1], n[:, 0]])
    # both ends of a particle pair, and the one end of a support contact
    part = np.concatenate([i, j[pp]])
    branch = np.concatenate([s - pos[i], s[pp] - pos[j[pp]]])
    rel = np.concatenate([np.where(pp[:, None], pos[np.where(pp, j, 0)] - pos[i], s - pos[i]),
                          pos[i[pp]] - pos[j[pp]]])
    nn = np.concatenate([n, n[pp]])
    tt = np.concatenate([t, t[pp]])
    kn = np.concatenate([k["k_n"], k["k_n"][pp]])
    kt = np.concatenate([k["k_t"], k["k_t"][pp]])
    out = np.zeros((state.n_particles, 3, 3))
    lx, ly = rel[:, 0], rel[:, 1]
    for col, (ex, ey) in enumerate(((lx, 0 * lx), (0 * ly, ly), (ly / SQRT2, lx / SQRT2))):   # E_N l
        g = (kn * (nn[:, 0] * ex + nn[:, 1] * ey))[:, None] * nn + (kt * (tt[:, 0] * ex + tt[:, 1] * ey))[:, None] * tt
        m = (branch[:, 0] * g[:, 0], branch[:, 1] * g[:, 1],
             SQRT2 * 0.5 * (branch[:, 0] * g[:, 1] + branch[:, 1] * g[:, 0]))
        for row in range(3):
            out[:, row, col] = np.bincount(part, weights=m[row], minlength=state.n_particles)
    return out


def rve_voigt_stiffness(W: sp.csr_matrix, moments: np.ndarray, volume: np.ndarray) -> np.ndarray:
    """``C = (1/V) Σ_{p in RVE}`` of :func:`particle_voigt_moment`: ``(n_rve, 3, 3)`` Mandel, N/m."""
    with np.errstate(invalid="ignore", divide="ignore"):
        flat = np.asarray(W @ moments.reshape(moments.shape[0], 9))
        return flat.reshape(-1, 3, 3) / np.asarray(volume, float)[:, None, None]


def isotropic_projection(C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(K, G)`` of Mandel stiffnesses ``(..., 3, 3)`` (module docstring)."""
    C = np.asarray(C, float)
    c11, c22, c33 = C[..., 0, 0], C[..., 1, 1], C[..., 2, 2]
    c12 = C[..., 0, 1] + C[..., 1, 0]
    return 0.25 * (c11 + c22 + c12), 0.125 * (c11 + c22 - c12 + 2.0 * c33)


def summary_attributes(stiffness: dict[str, np.ndarray]) -> dict[str, Any]:
    """The fields file's global attributes on the contacts: ``voigt_depth_ratio_median``, ``voigt_sliding_fraction``."""
    d = stiffness["depth_ratio"]
    d = d[np.isfinite(d)]
    return {"voigt_depth_ratio_median": float(np.median(d)) if d.size else float("nan"),
            "voigt_sliding_fraction": float(np.mean(stiffness["sliding"])) if d.size else float("nan")}


#: The core RVEs of the comparison (those of :mod:`analysis.pile_quantities`): ``|x| <= 0.03 m``, ``y <= 0.05 m``.
CORE = {"x": 0.03, "y": 0.05}


def compare_with_fit(fields, mod, core: dict[str, float] = CORE) -> dict[str, Any]:
    """Voigt K, G of one pile against its own isotropic fit: their ratios, median over the core RVEs.

    Parameters
    ----------
    fields : xarray.Dataset
        A per-pile fields file with ``voigt_bulk_modulus``, ``voigt_shear_modulus``
        and the increments the fit needs.
    mod : xarray.Dataset
        The pile's own fits, :func:`analysis.elastic.moduli_dataset` of ``fields``
        (passed in: ``analysis.elastic`` imports the ensemble, which imports
        the fields and so this module).
    core : dict
        ``{"x": half width, "y": top}`` of the core, m.

    Returns
    -------
    dict
        Per ``fit`` (``compliance``, ``modulus``, ``average``) and ``points``
        (1, 5): ``bulk_ratio`` and ``shear_ratio`` (median over the core RVEs
        where both are finite of Voigt over fitted), ``n`` (those RVEs), and
        the medians of the Voigt and fitted K and G there; the keys are
        ``"{fit}/m{points}"``.
    """
    inside = (np.abs(fields["x"]) <= core["x"]) & (fields["y"] <= core["y"])
    kv = fields["voigt_bulk_modulus"].where(inside)
    gv = fields["voigt_shear_modulus"].where(inside)
    out = {}
    for fit in mod["fit"].values:
        for m in mod["points"].values:
            k = mod["bulk_modulus"].sel(fit=fit, points=m)
            g = mod["shear_modulus"].sel(fit=fit, points=m)
            ok = (np.isfinite(kv) & np.isfinite(gv) & np.isfinite(k) & np.isfinite(g)).transpose("y", "x").values
            row = {"n": int(ok.sum())}
            for name, a in (("bulk_ratio", kv / k), ("shear_ratio", gv / g), ("voigt_bulk_modulus", kv),
                            ("voigt_shear_modulus", gv), ("bulk_modulus", k), ("shear_modulus", g)):
                v = a.transpose("y", "x").values[ok]
                row[name] = float(np.median(v)) if v.size else float("nan")
            out[f"{fit}/m{int(m)}"] = row
    return out
