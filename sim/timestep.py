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
``dt_safety · dt_limit``; a given ``dt`` above ``dt_limit`` is refused, and
so is a particle set whose contact frequency is not a finite positive
double (:func:`stability_bound`: a modulus or a mass at the ends of the
floating-point range).

A run checks three more rules before its first step (:func:`check_run`),
since resolving the contacts does not make the step short enough for the run:

* **motion**: the fastest a particle can move in the run (from the energy it
  can gain: its start speed and a free fall over the height the run gives it)
  times ``dt`` stays within :func:`motion_limit`, so the pair list stays
  valid and no particle passes through another in one step;
* **steps**: the run's simulated time over ``dt`` is at most
  :data:`MAX_STEPS` (also what refuses a ``dt`` that underflows);
* **drag**: the background drag (``relax.drag``, ``pour.spin_drag``) is a
  velocity-dependent force like the contact damping, integrated the same
  way; with it a contact mode's damping ratio grows by ``c / 2ω`` and a free
  particle's motion must stay stable too (:func:`drag_limit`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .config import ConfigError
from .contact_law import tangential_stiffness
from .integrators import stability_limit
from .rebuild import REBUILD_FRACTION

#: The most steps one run (a pour, a relaxation, a probe) may take.  The
#: study's longest, the full-size pour, takes about 5·10⁶; 10¹⁰ steps of its
#: 3500 particles at its 1 µs per particle-step would take about a year of
#: wall time, so a run asking for more is a mistake in its settings.
MAX_STEPS = 1e10

#: The largest distance a particle may move in one step, as a fraction of the
#: smallest inradius of the particles (:func:`motion_limit`).
MOTION_FRACTION = 0.1

#: Damping ratio at which :func:`drag_limit` takes ``2 ζ h*(ζ)``, the limit of
#: ``c dt`` for a drag ``c`` on a free particle (ζ → ∞: 0.163 for Gear, 1.00
#: for Verlet, to 4 digits already at ζ = 10).
FREE_ZETA = 1000.0


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
                    inradius, max_edge, density=None) -> TimeStepBound:
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
    density : float, optional
        ``model.density`` that made the masses, kg/m², named in the error.

    Returns
    -------
    TimeStepBound

    Raises
    ------
    sim.config.ConfigError
        For a modulus and particles whose frequencies would leave double
        precision (masses and ``Y/m*`` outside ``1e±290``), in one line.
    """
    mass = np.asarray(mass, float)
    inertia = np.asarray(inertia, float)
    radius = np.asarray(radius, float)
    _check_range(youngs_modulus, mass, inertia, radius, density)
    inradius = np.asarray(inradius, float)
    inv_mass = 2.0 * float(np.max(1.0 / mass + radius ** 2 / inertia))
    l_min = 0.5 * float(np.min(inradius))
    ratio = max_edge / l_min
    k_normal = youngs_modulus * ratio
    k_tangential = tangential_stiffness(float(youngs_modulus))
    omega_n = np.sqrt(k_normal * inv_mass)
    omega_t = np.sqrt(k_tangential * inv_mass)
    zeta_n = 0.5 * damping * np.sqrt(ratio)
    zeta_t = 0.5
    # no cap at critical damping: h*(ζ) keeps falling beyond ζ = 1 (about 1/ζ)
    dt_n = stability_limit(integrator, round(float(zeta_n), 3)) / omega_n
    dt_t = stability_limit(integrator, zeta_t) / omega_t
    limit = min(dt_n, dt_t)
    mode = "normal" if dt_n <= dt_t else "tangential"
    return TimeStepBound(float(limit), float(omega_n), float(omega_t),
                         float(zeta_n), zeta_t, mode)


def _check_range(youngs_modulus, mass, inertia, radius, density):
    """Refuse a modulus and particles whose frequencies would leave double precision.

    The squared contact frequency is ``Y/m*``, with ``1/m* = 1/m + R²/I``
    the inverse mass at a contact point, times the edge ratio (about 1 to
    10³ for the shapes the particle settings allow), and the time step about
    its inverse square root: with the masses and ``Y/m*`` within ``1e±290``
    every product of the rule stays a finite positive double, with 10¹⁸ to
    spare.

    Raises
    ------
    sim.config.ConfigError
        One line naming ``model.youngs_modulus`` and ``model.density``.
    """
    with np.errstate(all="ignore"):     # an inertia that underflowed to 0 is refused below
        reach = 1.0 / mass + radius ** 2 / inertia
        low, high = youngs_modulus * float(np.min(reach)), youngs_modulus * float(np.max(reach))
    light, heavy = float(np.min(mass)), float(np.max(mass))
    if all(1e-290 <= x <= 1e290 for x in (light, heavy, low, high)):
        return
    raise ConfigError(
        f"model.youngs_modulus = {youngs_modulus!r} N/m over particles of {light:.3g} to "
        f"{heavy:.3g} kg (model.density = {density!r} kg/m^2 times their areas) makes Y/m* "
        f"{low:.3g} to {high:.3g} 1/s^2 (1/m* = 1/m + R^2/I, the inverse mass at a contact "
        "point); allowed: masses and Y/m* within 1e-290 to 1e290, where the time-step rule's "
        "products stay finite doubles (the study's: Y = 1e7 N/m, density 2500 kg/m^2, Y/m* "
        "about 2e8 to 1e9 1/s^2)")


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


def motion_limit(scene) -> float:
    """The largest distance (m) a particle may move in one step of `scene`.

    The smaller of two lengths:

    * ``(1/2 − REBUILD_FRACTION) · skin`` (:mod:`sim.rebuild`): a pair stays
      valid while both its particles are within half the skin of their
      reference centres, and the list is refreshed after the step in which
      one passed ``REBUILD_FRACTION`` of it; one step may add no more than the
      difference;
    * :data:`MOTION_FRACTION` of the smallest inradius: two particles closing
      in at that speed overlap by at most a fifth of the thinnest one's
      inradius per step, so no particle passes through another within a step
      and a contact is met over several steps.

    Parameters
    ----------
    scene : sim.scene.Scene

    Returns
    -------
    float
    """
    return min((0.5 - REBUILD_FRACTION) * scene.skin,
               MOTION_FRACTION * float(np.min(scene.shapes.inradius)))


def drag_limit(bound: TimeStepBound, integrator: str, drag: float) -> float:
    """Stability limit of the time step (s) with a background drag on top of the contacts.

    A drag ``c`` (1/s) acts like the contact damping (a force against the
    predicted velocity): on a contact mode of frequency ω it raises the
    damping ratio by ``c / 2ω``, so that mode needs ``ω dt < h*(ζ + c/2ω)``;
    on a free particle it needs ``c dt < 2 ζ h*(ζ)`` for ζ → ∞
    (:data:`FREE_ZETA`).  Taking ``c`` on every mode also covers a drag on the
    rotation alone (``pour.spin_drag``).

    Parameters
    ----------
    bound : TimeStepBound
    integrator : {"gear", "verlet"}
    drag : float
        The strongest drag the run applies, 1/s.

    Returns
    -------
    float
        ``bound.dt_limit`` without drag.
    """
    if drag <= 0.0:
        return bound.dt_limit
    free = 2.0 * FREE_ZETA * stability_limit(integrator, FREE_ZETA) / drag
    modes = ((bound.zeta_normal, bound.omega_normal),
             (bound.zeta_tangential, bound.omega_tangential))
    # ζ rounded up to the 3 digits that stability_limit is cached at: h* falls with ζ
    return min(free, *(stability_limit(integrator, math.ceil(1e3 * (z + drag / (2 * w))) / 1e3) / w
                       for z, w in modes))


def dt_source(model, kept=None) -> str:
    """Where a run's time step comes from, naming its settings (for :func:`check_run`).

    Parameters
    ----------
    model : sim.config.ModelParams
        The settings of the run.
    kept : str, optional
        Where a ``dt`` was kept from when ``model.dt`` is null (the input file
        of a relaxation or probe).
    """
    if model.dt is not None:
        return f"model.dt = {model.dt!r} s"
    if kept is not None:
        return f"kept from {kept} (model.dt = null)"
    return (f"automatic: model.dt_safety = {model.dt_safety} of the contact limit of "
            f"model.youngs_modulus = {model.youngs_modulus!r} N/m and model.density = "
            f"{model.density!r} kg/m^2")


def check_run(scene, what, duration, speed, drag, sources) -> None:
    """Refuse a run whose time step cannot carry it, before its first step.

    The rules (module docstring): at most :data:`MAX_STEPS` steps over
    ``duration``; ``speed · dt`` within :func:`motion_limit`; ``dt`` within
    :func:`drag_limit` of ``drag``.

    Parameters
    ----------
    scene : sim.scene.Scene
        The run's particles, time step and integrator.
    what : str
        The run, leading the message.
    duration : float
        The longest simulated time the run may take, s.
    speed : float
        The fastest a particle can move in the run, m/s.
    drag : float
        The strongest drag the run applies, 1/s.
    sources : dict
        For the message, the settings and their values that make each of
        ``"duration"``, ``"speed"``, ``"drag"`` and ``"dt"`` (:func:`dt_source`).

    Raises
    ------
    sim.config.ConfigError
        One line naming the settings, their values and what is allowed.
    """
    dt, integrator = scene.dt, scene.model.integrator
    at = f"dt = {dt:.3g} s ({sources['dt']})"
    steps = duration / dt if dt > 0 else math.inf     # dt_safety 5e-324 rounds the step to 0
    if not steps <= MAX_STEPS:
        raise ConfigError(
            f"{what}: {sources['duration']} make up to {duration:.4g} s of simulated time, "
            f"{steps:.3g} steps of {at}; allowed: at most {MAX_STEPS:.0e} steps, i.e. at most "
            f"{MAX_STEPS * dt:.3g} s at this dt"
            + (f" or dt >= {duration / MAX_STEPS:.3g} s" if math.isfinite(duration) else ""))
    limit = motion_limit(scene)
    if not speed * dt <= limit:
        raise ConfigError(
            f"{what}: {sources['speed']} let a particle reach {speed:.3g} m/s, "
            f"{speed * dt:.3g} m in one step of {at}; allowed: at most {limit:.3g} m per step "
            f"(the smaller of {MOTION_FRACTION} x the smallest inradius and "
            f"{0.5 - REBUILD_FRACTION:.2f} x the pair list's skin), i.e. speeds <= "
            f"{limit / dt:.3g} m/s at this dt"
            + (f" or dt <= {limit / speed:.3g} s at this speed" if math.isfinite(speed) else ""))
    stable = drag_limit(scene.bound, integrator, drag)
    if not dt <= stable:
        raise ConfigError(
            f"{what}: {sources['drag']} with {at} is beyond the {integrator} integrator's "
            f"stability limit with that drag (drag x dt = {drag * dt:.3g}); allowed: "
            f"dt <= {stable:.3g} s at this drag")
