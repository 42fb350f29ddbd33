"""Binary collision scenes and what is measured on them.

A particle i (a square lying flat, or a diamond standing on a corner) falls
onto the top edge of a plate j (a rectangle 8W × 2W) in zero gravity, without
rotation, with relative normal and tangential speeds.  The centre-of-mass
frame is at rest.  The observables, measured from the simulator's positions
and velocities after every step, are compared with the reference of
:mod:`sim.numerics.reference`:

* normal and tangential restitution: relative velocities a few steps after
  separation (Gear's higher derivatives settle over a few steps after the
  force vanishes; :data:`SETTLE_STEPS`);
* contact duration: from the exact touch-down time (free flight from a known
  gap) to the separation time, found by cubic Hermite interpolation of the
  depth between the two steps around it (error O(dt⁴));
* maximum overlap: the maximum of the same interpolant on the step interval
  where the approach velocity changes sign, as an area.

Interpolating avoids an O(dt) error from sampling at step boundaries, so the
measured errors are the integrators'.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config import ModelParams
from ..engine import Simulation
from .polygons import diamond, rectangle, shapes_of
from .reference import CollisionOutcome, CornerOnFlat, EdgeOnFlat, collision_reference

#: Observables of a collision, the fields of :class:`CollisionOutcome` that
#: :func:`measure` returns: (units, long name, error kind).  Restitution
#: coefficients are O(1) and compared by their absolute error, the others
#: relatively.
OBSERVABLES = {
    "normal_restitution": ("1", "normal coefficient of restitution", "absolute"),
    "tangential_restitution": ("1", "tangential coefficient of restitution", "absolute"),
    "duration": ("s", "contact duration", "relative"),
    "max_overlap_area": ("m2", "largest overlap area", "relative"),
}

#: Half side of the square (and the plate's half thickness), m.
HALF_SIDE = 2.0e-3
#: Steps run after separation before the velocities are read.
SETTLE_STEPS = 20
CONTACTS = ("edge", "corner")


@dataclass(frozen=True)
class CollisionCase:
    """One binary collision.

    Attributes
    ----------
    name : str
    contact : {"edge", "corner"}
        A square's edge or a diamond's 90° corner onto the plate's edge.
    damping, friction : float
        γ and μ of the contact law.
    normal_speed, tangential_speed : float
        Relative speeds at touch-down, m/s.
    youngs_modulus : float
        Y, N/m.
    """

    name: str
    contact: str
    damping: float
    friction: float
    normal_speed: float = 0.1
    tangential_speed: float = 0.1
    youngs_modulus: float = 1.0e7

    def __post_init__(self):
        if self.contact not in CONTACTS:
            raise ValueError(f"collision case {self.name!r}: contact = {self.contact!r}: "
                             f"must be one of {list(CONTACTS)}")
        if not self.normal_speed > 0:
            raise ValueError(f"collision case {self.name!r}: normal_speed = "
                             f"{self.normal_speed!r}: must be > 0")


def _polygons(case):
    """Corners of (i, j): the falling particle and the plate."""
    w = HALF_SIDE
    upper = rectangle(2 * w, 2 * w) if case.contact == "edge" else diamond(math.sqrt(2) * w)
    return upper, rectangle(8 * w, 2 * w)


def geometry(case):
    """The reference geometry (:mod:`sim.numerics.reference`) of a case."""
    w = HALF_SIDE
    if case.contact == "edge":
        return EdgeOnFlat(2 * w, w, w)
    return CornerOnFlat(math.pi / 4, math.sqrt(2) * w, w)


#: Offset of i's centre from j's along the edge at the start, m (off-centre, so
#: that r_j changes as i slides).
OFFSET = 0.5 * HALF_SIDE
#: Gap between the particles at the start, m.
GAP = 1e-3 * HALF_SIDE


def scene(case, integrator, dt=None):
    """The collision as a :class:`sim.engine.Simulation`, particles placed.

    Parameters
    ----------
    case : CollisionCase
    integrator : {"gear", "verlet"}
    dt : float or None
        Time step, s (None: the automatic rule).

    Returns
    -------
    Simulation
    """
    shapes = shapes_of(*_polygons(case))
    model = ModelParams(youngs_modulus=case.youngs_modulus, damping=case.damping,
                        friction=case.friction, integrator=integrator, dt=dt)
    sim = Simulation(shapes, model, gravity=(0.0, 0.0), support=False, rotate=False)
    m_i, m_j = shapes.mass
    v_rel = np.array([case.tangential_speed, -case.normal_speed])
    v_i = m_j / (m_i + m_j) * v_rel
    v_j = -m_i / (m_i + m_j) * v_rel
    sim.place(0, OFFSET, HALF_SIDE + geometry(case).reach + GAP, 0.0, *v_i, 0.0)
    sim.place(1, 0.0, 0.0, 0.0, *v_j, 0.0)
    return sim


def touch_down_time(case):
    """Time of first contact: the gap closed at the approach speed (free flight)."""
    return GAP / case.normal_speed


def reference(case, rtol=1e-12):
    """The reference outcome of a case (:func:`sim.numerics.reference.collision_reference`)."""
    shapes = shapes_of(*_polygons(case))
    return collision_reference(
        geometry(case), shapes.mass[0], shapes.inertia[0], shapes.mass[1], shapes.inertia[1],
        case.youngs_modulus, case.damping, case.friction, case.normal_speed,
        case.tangential_speed, OFFSET + case.tangential_speed * touch_down_time(case), rtol)


def _depth(sim, case):
    """Overlap depth d and its rate d' from the particles' positions and velocities."""
    top = HALF_SIDE + geometry(case).reach
    d = top - (sim.r[0, 1, 0] - sim.r[0, 1, 1])
    dd = -(sim.r[1, 1, 0] - sim.r[1, 1, 1]) / sim.dt
    return d, dd


def hermite(t0, t1, y0, y1, v0, v1):
    """Cubic Hermite interpolant on ``[t0, t1]`` matching values and slopes.

    ``H(s) = (2s³−3s²+1) y0 + (s³−2s²+s) h v0 + (−2s³+3s²) y1 + (s³−s²) h v1``
    with ``h = t1 − t0``, ``s = (t − t0)/h``; returned as polynomial
    coefficients in ``s`` (highest first, for :func:`numpy.roots`).
    """
    h = t1 - t0
    return np.array([2 * y0 + h * v0 - 2 * y1 + h * v1,
                     -3 * y0 - 2 * h * v0 + 3 * y1 - h * v1,
                     h * v0,
                     y0])


def _root_in_unit(coeffs):
    """The real root of a polynomial in [0, 1] (the one nearest the middle)."""
    roots = np.roots(coeffs)
    real = roots[(abs(roots.imag) < 1e-9) & (roots.real >= -1e-9) & (roots.real <= 1 + 1e-9)]
    if not len(real):
        raise RuntimeError("no crossing inside the step interval")
    return float(real.real[np.argmin(abs(real.real - 0.5))])


def _run_until(sim, case, crossed, chunk):
    """Advance until the step on which ``crossed(before, after)`` first holds.

    Runs in chunks (doubling while nothing happens); a chunk in which the
    event happened is undone (:meth:`Simulation.restore` retraces the run
    exactly) and redone in chunks an eighth as long, down to single steps.
    ``crossed`` must hold over a chunk whenever it holds for one of its steps
    (true for sign changes of the monotone depth and approach speed).

    Returns
    -------
    before, after : tuple
        ``(t, d, d')`` at the start and end of that step.
    """
    before = (sim.time, *_depth(sim, case))
    while True:
        start = sim.snapshot()
        sim.run(steps=chunk)
        after = (sim.time, *_depth(sim, case))
        if crossed(before, after):
            if chunk == 1:
                return before, after
            sim.restore(start)
            chunk = max(1, chunk // 8)
        else:
            before = after
            chunk *= 2


def measure(case, integrator, dt):
    """Run one collision and measure it.

    Returns
    -------
    outcome : CollisionOutcome
    steps : int
        Steps from the start to the first step after separation (the cost of
        the collision, timed by :func:`sim.numerics.collisions.wall_time`).
    """
    sim = scene(case, integrator, dt)
    v_rel0 = np.array([case.tangential_speed, -case.normal_speed])
    # the normal force never attracts, so d' only decreases: it changes sign
    # once, at the deepest point, and d once more, at separation
    before, after = _run_until(sim, case, lambda b, a: b[2] > 0 >= a[2], 8)
    c = hermite(before[0], after[0], before[1], after[1], before[2], after[2])
    deepest = float(np.polyval(c, _root_in_unit(np.polyder(c))))
    before, after = _run_until(sim, case, lambda b, a: b[1] > 0 >= a[1], 8)
    c = hermite(before[0], after[0], before[1], after[1], before[2], after[2])
    t_sep = before[0] + _root_in_unit(c) * (after[0] - before[0])
    steps = sim.step
    sim.run(steps=SETTLE_STEPS)
    v = sim.velocity
    v_rel = v[0] - v[1]
    e_t = v_rel[0] / v_rel0[0] if v_rel0[0] != 0 else 1.0
    return CollisionOutcome(float(-v_rel[1] / v_rel0[1]), float(e_t),
                            t_sep - touch_down_time(case),
                            float(geometry(case).contact(deepest, 0.0)[0])), steps
