"""Reference solutions of binary collisions: the force law of the paper's
Appendix integrated by scipy's ``solve_ivp`` (DOP853, rtol 1e-12),
independently of the simulator's narrow phase, contact bookkeeping and
integrators.

The scenes are a particle i hitting a flat edge of a particle j (a plate) or
of the support (j of infinite mass), without rotation (the simulator runs
them with ``rotate=False``).  The relative motion then has two degrees of
freedom, the overlap depth ``d`` along the edge normal and the offset ``x``
of i's centre along the edge from j's centre, and the contact geometry is
analytic in ``(d, x)``:

* edge on flat (:class:`EdgeOnFlat`): ``A = L₀ d``, contact-line length ``L₀``;
* corner on flat (:class:`CornerOnFlat`), interior corner angle ``2α``:
  ``A = d² tan α``, ``L = 2 d tan α``.

Both boundaries cross on j's flat edge, so the contact line lies on it, the
normal is the edge normal and the force point is the foot of i's centre on the
edge: ``r_i = reach − d`` (reach: distance from i's centre to its lowest
point), ``r_j = sqrt(x² + h_j²)`` (``h_j``: half thickness of the plate).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from ..contact_law import tangential_stiffness


@dataclass(frozen=True)
class EdgeOnFlat:
    """Geometry of an edge of length ``edge_length`` lying flat on j's edge.

    Attributes
    ----------
    edge_length : float
        Contact-line length L₀ (i's edge, shorter than j's), m.
    reach : float
        Distance from i's centre to the edge, m.
    lower_half_height : float or None
        Distance from j's centre to its edge, m; None for the support.
    """

    edge_length: float
    reach: float
    lower_half_height: float | None

    def contact(self, d, x):
        """Overlap area ``A = L₀ d``, contact-line length, ``r_i``, ``r_j``."""
        return (self.edge_length * d, self.edge_length + 0.0 * d, self.reach - d,
                _lower_arm(self.lower_half_height, x))


@dataclass(frozen=True)
class CornerOnFlat:
    """Geometry of a corner of interior angle ``2 half_angle`` pressing into j's edge.

    Attributes
    ----------
    half_angle : float
        Half the interior angle of the corner, rad.
    reach : float
        Distance from i's centre to the corner, m.
    lower_half_height : float or None
        Distance from j's centre to its edge, m; None for the support.
    """

    half_angle: float
    reach: float
    lower_half_height: float | None

    def contact(self, d, x):
        """Overlap area ``A = d² tan α``, contact-line length ``2 d tan α``, ``r_i``, ``r_j``."""
        t = math.tan(self.half_angle)
        return t * d * d, 2.0 * t * d, self.reach - d, _lower_arm(self.lower_half_height, x)


def _lower_arm(half_height, x):
    """Distance ``r_j = sqrt(x² + h_j²)`` from j's centre to the force point (inf: support).

    Written with ``sqrt`` of a sum of squares so that complex-step derivatives work.
    """
    if half_height is None:
        return math.inf
    return np.sqrt(x * x + half_height * half_height)


@dataclass(frozen=True)
class CollisionOutcome:
    """What a collision is measured by.

    Attributes
    ----------
    normal_restitution : float
        ``−v_n(after) / v_n(before)`` of the relative normal velocity.
    tangential_restitution : float
        ``v_t(after) / v_t(before)`` of the relative tangential velocity
        (1 when there is no tangential velocity).
    duration : float
        Contact duration, s.
    max_overlap_area : float
        Largest overlap area, m².
    """

    normal_restitution: float
    tangential_restitution: float
    duration: float
    max_overlap_area: float


def characteristic_length(r_i, r_j):
    """``l = r_i r_j / (r_i + r_j)`` (Appendix); ``l = r_i`` against the support (r_j = inf)."""
    if np.isinf(r_j):
        return r_i
    return r_i * r_j / (r_i + r_j)


def tangential_mass(m_i, inertia_i, m_j, inertia_j, r_i, r_j):
    """``m∥ = 1 / (1/m_i + 1/m_j + r_i²/I_i + r_j²/I_j)`` (Appendix); j may be infinite."""
    inv = 1.0 / m_i + r_i * r_i / inertia_i
    if not np.isinf(m_j):
        inv += 1.0 / m_j + r_j * r_j / inertia_j
    return 1.0 / inv


def elastic_normal_force(geometry, youngs_modulus, d, x):
    """Elastic normal force ``F⊥ = Y A / l`` (Appendix (i)) at depth d and offset x."""
    area, _, r_i, r_j = geometry.contact(d, x)
    return youngs_modulus * area / characteristic_length(r_i, r_j)


def cap_rate(geometry, youngs_modulus, friction, d, x, dd, dx):
    """Time derivative of the Coulomb cap ``μ F⊥(d, x)`` along ``(d', x')``.

    By complex-step differentiation, ``∂f/∂d ≈ Im f(d + ih) / h``, exact to
    round-off for the analytic geometry of this module.
    """
    h = 1e-30 * max(geometry.reach, 1e-300)
    fd = elastic_normal_force(geometry, youngs_modulus, d + 1j * h, x).imag / h
    fx = elastic_normal_force(geometry, youngs_modulus, d, x + 1j * h).imag / h
    return friction * (fd * dd + fx * dx)


def spring_rate(f_spring, cap, rate, cap_dt):
    """Rate of the Cundall–Strack spring ``F*∥`` in continuous time (Appendix (iii)).

    Below the cap the spring loads at ``(2/7) Y v∥`` (``rate``).  On the cap
    (``|F*∥| ≥ μ F⊥``) it cannot outgrow the cap: it follows the cap
    (``± d(μF⊥)/dt``) or falls back inside, whichever is slower outwards; this
    is the limit ``dt → 0`` of the simulator's ``F* ← clip(F* + k∥ v∥ dt, ±μF⊥)``.
    """
    if abs(f_spring) < cap:
        return rate
    if f_spring > 0.0 or (f_spring == 0.0 and rate > 0.0):
        return min(rate, cap_dt)
    if f_spring < 0.0 or rate < 0.0:
        return max(rate, -cap_dt)
    return rate


def collision_reference(geometry, mass_i, inertia_i, mass_j, inertia_j, youngs_modulus,
                        damping, friction, normal_speed, tangential_speed, offset,
                        rtol=1e-12):
    """Integrate one collision from touch-down to separation.

    State ``(d, d', x, x', F*∥)``.  With ``m⊥ = m_i m_j / (m_i + m_j)`` and
    the Appendix's force law:

    * normal: ``F⊥ = Y A / l``, ``D⊥ = γ sqrt(Y m⊥) (dA/dt) / l`` with
      ``dA/dt = L d'``, ``D⊥ ≥ −F⊥`` while separating; ``d'' = −(F⊥ + D⊥)/m⊥``;
    * tangential: the spring ``F*∥`` (:func:`spring_rate`), damping
      ``sqrt((2/7) Y m∥) x'``, total capped at ``μ F⊥``; ``x'' = −T / m⊥``.

    Parameters
    ----------
    geometry : EdgeOnFlat or CornerOnFlat
    mass_i, inertia_i, mass_j, inertia_j : float
        Masses (kg) and moments of inertia (kg m²); ``mass_j = inf`` for the support.
    youngs_modulus, damping, friction : float
        Y (N/m), γ, μ.
    normal_speed : float
        Approach speed at touch-down, m/s (> 0).
    tangential_speed : float
        Relative tangential speed at touch-down, m/s.
    offset : float
        Offset x of i's centre from j's centre along the edge at touch-down, m.
    rtol : float
        Relative tolerance of solve_ivp (absolute tolerances are scaled from it).

    Returns
    -------
    CollisionOutcome
    """
    if not normal_speed > 0:
        raise ValueError(f"normal_speed = {normal_speed!r}: must be > 0 (an approach)")
    m_perp = mass_i if np.isinf(mass_j) else mass_i * mass_j / (mass_i + mass_j)
    k_t = tangential_stiffness(youngs_modulus)

    def rhs(t, s):
        d, dd, x, dx, f_spring = s
        area, length, r_i, r_j = geometry.contact(d, x)
        l = characteristic_length(r_i, r_j)
        f_el = youngs_modulus * area / l
        f_damp = damping * math.sqrt(youngs_modulus * m_perp) * length * dd / l
        if dd < 0.0 and f_damp < -f_el:
            f_damp = -f_el
        cap = friction * f_el
        m_par = tangential_mass(mass_i, inertia_i, mass_j, inertia_j, r_i, r_j)
        rate = spring_rate(f_spring, cap, k_t * dx,
                           cap_rate(geometry, youngs_modulus, friction, d, x, dd, dx))
        total = min(max(min(max(f_spring, -cap), cap) + math.sqrt(k_t * m_par) * dx, -cap),
                    cap)
        return [dd, -(f_el + f_damp) / m_perp, dx, -total / m_perp, rate]

    def separated(t, s):
        return s[0]

    separated.terminal, separated.direction = True, -1

    def deepest(t, s):
        return s[1]

    deepest.direction = -1
    scale_t = geometry.reach / normal_speed
    atol = rtol * np.array([geometry.reach, normal_speed, geometry.reach,
                            normal_speed, youngs_modulus * geometry.reach])
    sol = solve_ivp(rhs, (0.0, 1e3 * scale_t), [0.0, normal_speed, offset, tangential_speed, 0.0],
                    method="DOP853", rtol=rtol, atol=atol, events=(separated, deepest),
                    max_step=1e-4 * scale_t)
    if sol.status != 1 or not len(sol.t_events[0]):
        raise RuntimeError(f"reference collision did not end: {sol.message}")
    end = sol.y_events[0][0]
    d_max = max(sol.y_events[1][:, 0]) if len(sol.t_events[1]) else float(np.max(sol.y[0]))
    e_t = end[3] / tangential_speed if tangential_speed != 0 else 1.0
    return CollisionOutcome(float(-end[1] / normal_speed), float(e_t),
                            float(sol.t_events[0][0]),
                            float(geometry.contact(d_max, offset)[0]))


def linear_spring_half_period(stiffness, mass):
    """Half period ``π sqrt(m / k)`` of a mass on a linear spring: the contact
    duration of an undamped edge-on-flat collision when ``l`` stays constant."""
    return math.pi * math.sqrt(mass / stiffness)
