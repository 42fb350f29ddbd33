"""The time-step rule: the stiffest contact against the lightest particle.

A contact between two polygons has two oscillation modes that the explicit
integrators must resolve (paper, Appendix):

* **normal**: an edge-on-edge contact of contact-line length L has stiffness
  ``k⊥ = dF⊥/dd = Y L / l`` (``F⊥ = Y A / l`` with ``A ≈ L d``), damping
  coefficient ``γ sqrt(Y m⊥) L / l`` and so damping ratio ``ζ⊥ = (γ/2) sqrt(L/l)``;
* **tangential**: the Cundall–Strack spring ``k∥ = (2/7) Y`` with damping
  ``sqrt((2/7) Y m∥)``, i.e. damping ratio exactly ``ζ∥ = 1/2``.

The bound takes, over all particles, the longest edge ``L_max`` (an
edge-on-edge contact line cannot be longer while overlaps stay small), the
shortest characteristic length ``l_min = ρ_min / 2`` (two particles touching
at their inradius ``ρ``), and the largest inverse mass at a contact point
including rotation, ``2 max_i (1/m_i + R_i²/I_i)`` (two such particles, R the
circumradius).  Then ``ω⊥² = k⊥ · 2q`` and ``ω∥² = k∥ · 2q`` and the stability
limit is

``dt_limit = min(h*(ζ⊥) / ω⊥, h*(ζ∥) / ω∥)``

with ``h*(ζ)`` the largest stable ``ω dt`` of the integrator for a damped
oscillator (:func:`sim.integrators.stability_limit`: 0.313 for Gear and 2 for
Verlet when undamped; 0.157 and 0.83 at ζ = 1/2).  The automatic time step is
``dt_safety · dt_limit``; a given ``dt`` above ``dt_limit`` is refused.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .contact_law import tangential_stiffness
from .integrators import stability_limit


@dataclass(frozen=True)
class TimeStepBound:
    """The pieces of the time-step rule, for reporting.

    Attributes
    ----------
    dt_limit : float
        Stability limit of the chosen integrator, s.
    omega_normal, omega_tangential : float
        Highest contact frequencies, rad/s.
    zeta_normal, zeta_tangential : float
        Their damping ratios.
    mode : str
        Which mode sets the limit.
    """

    dt_limit: float
    omega_normal: float
    omega_tangential: float
    zeta_normal: float
    zeta_tangential: float
    mode: str


def stability_bound(youngs_modulus, damping, integrator, mass, inertia, radius,
                    inradius, max_edge) -> TimeStepBound:
    """Stability limit of the time step for a set of particles.

    Parameters
    ----------
    youngs_modulus : float
        Y in N/m.
    damping : float
        Normal damping coefficient γ.
    integrator : {"gear", "verlet"}
    mass, inertia, radius, inradius : array_like
        Per-particle mass (kg), moment of inertia (kg m²), circumradius and
        inradius (m).
    max_edge : float
        Longest polygon edge over all particles, m.

    Returns
    -------
    TimeStepBound
    """
    mass = np.asarray(mass, float)
    inertia = np.asarray(inertia, float)
    radius = np.asarray(radius, float)
    inradius = np.asarray(inradius, float)
    inv_mass = 2.0 * float(np.max(1.0 / mass + radius ** 2 / inertia))
    l_min = 0.5 * float(np.min(inradius))
    ratio = max_edge / l_min
    k_normal = youngs_modulus * ratio
    k_tangential = tangential_stiffness(youngs_modulus)
    omega_n = np.sqrt(k_normal * inv_mass)
    omega_t = np.sqrt(k_tangential * inv_mass)
    zeta_n = 0.5 * damping * np.sqrt(ratio)
    zeta_t = 0.5
    # no cap at critical damping: h*(ζ) keeps falling beyond ζ = 1 (about 1/ζ)
    dt_n = stability_limit(integrator, round(float(zeta_n), 3)) / omega_n
    dt_t = stability_limit(integrator, zeta_t) / omega_t
    mode = "normal" if dt_n <= dt_t else "tangential"
    return TimeStepBound(float(min(dt_n, dt_t)), float(omega_n), float(omega_t),
                         float(zeta_n), zeta_t, mode)


def choose_dt(bound: TimeStepBound, dt: float | None, dt_safety: float,
              integrator: str) -> float:
    """Apply the rule: the automatic step, or a given one checked against the limit.

    Parameters
    ----------
    bound : TimeStepBound
    dt : float or None
        Requested time step (s), or None for automatic.
    dt_safety : float
        Fraction of the limit used by the automatic rule.
    integrator : str
        Named in the error message.

    Returns
    -------
    float

    Raises
    ------
    ValueError
        If the given ``dt`` exceeds the stability limit.
    """
    if dt is None:
        return dt_safety * bound.dt_limit
    if dt > bound.dt_limit:
        raise ValueError(
            f"model.dt = {dt:.4g} s exceeds the stability limit {bound.dt_limit:.4g} s of "
            f"the {integrator} integrator for these particles (set by the {bound.mode} "
            f"contact mode, omega = {max(bound.omega_normal, bound.omega_tangential):.4g} "
            f"rad/s); use dt <= {bound.dt_limit:.4g} s or dt: null for the automatic "
            f"rule ({dt_safety} x limit)")
    return dt
