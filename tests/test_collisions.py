"""Binary collisions against conservation laws and an independent ODE solution.

The references are computed here from the force law of the paper's Appendix
with scipy's solve_ivp at rtol 1e-12, independently of the simulator's
geometry, contact bookkeeping and integrators.
"""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from scenes import diamond, rectangle, scene

W = 2.0e-3          # half side of the squares, m
DELTA = 0.2 * W     # vertical offset of the second square (avoids collinear edges)
Y = 1.0e7


def _collide(sim, max_steps=20000):
    """Run a collision step by step; returns (duration, steps) of the contact."""
    start = end = None
    for _ in range(max_steps):
        sim.run(steps=1)
        active = len(sim.contacts()["i"]) > 0
        if active and start is None:
            start = sim.time
        if start is not None and not active:
            end = sim.time
            break
    assert start is not None and end is not None, "no complete collision"
    return end - start


def _momentum(sim):
    return (sim.shapes.mass[:sim.n, None] * sim.velocity).sum(axis=0)


def _energy(sim):
    return sim.kinetic_energy()


def _edge_scene(integrator, v, damping=0.0, friction=0.0, rotate=True):
    """Two squares approaching edge-on-edge at relative speed 2v.

    The time step is a tenth of the stability limit, so that the comparison
    tests the force law rather than the integrator's error at coarse steps.
    """
    sq = rectangle(2 * W, 2 * W)
    gap = 1e-6
    return scene([sq, sq], [(0.0, 0.0, 0.0, v, 0.0, 0.0),
                            (2 * W + gap, DELTA, 0.0, -v, 0.0, 0.0)],
                 youngs_modulus=Y, damping=damping, friction=friction,
                 integrator=integrator, rotate=rotate, dt_safety=0.1)


def _edge_reference(m_perp, v_rel, damping):
    """Restitution and duration of the edge-on-edge contact from the force law.

    Overlap depth d: A = h d with h = 2W - DELTA, force point at
    (W - d/2, DELTA/2) from either centre, so l = r/2 with
    r = sqrt((W - d/2)² + DELTA²/4); dA/dt = h d'.
    """
    h = 2 * W - DELTA

    def rhs(t, s):
        d, dd = s
        r = np.hypot(W - d / 2, DELTA / 2)
        l = r / 2
        f_el = Y * h * d / l
        damp = damping * np.sqrt(Y * m_perp) * h * dd / l
        if dd < 0 and damp < -f_el:
            damp = -f_el
        return [dd, -(f_el + damp) / m_perp]

    out = lambda t, s: s[0]
    out.terminal, out.direction = True, -1
    sol = solve_ivp(rhs, (0, 1.0), [0.0, v_rel], rtol=1e-12, atol=1e-20, events=out,
                    max_step=1e-6)
    t_end = sol.t_events[0][0]
    return -sol.y_events[0][0][1] / v_rel, t_end


@pytest.mark.parametrize("integrator", ["gear", "verlet"])
def test_undamped_edge_collision_conserves_momentum_and_energy(integrator):
    v = 0.05
    sim = _edge_scene(integrator, v)
    p0 = _momentum(sim)
    e0 = _energy(sim)
    duration = _collide(sim)
    p1 = _momentum(sim)
    e1 = _energy(sim)
    scale = sim.shapes.mass[0] * v
    assert np.all(np.abs(p1 - p0) < 1e-12 * scale)
    assert abs(e1 - e0) < 2e-3 * e0
    # contact duration: half period of the linear spring k = Y h / l, l = W / 2
    m_perp = sim.shapes.mass[0] / 2
    k = Y * (2 * W - DELTA) / (np.hypot(W, DELTA / 2) / 2)
    half_period = np.pi * np.sqrt(m_perp / k)
    assert abs(duration - half_period) < 0.02 * half_period + 2 * sim.dt


@pytest.mark.parametrize("integrator", ["gear", "verlet"])
@pytest.mark.parametrize("damping", [0.05, 0.3])
def test_damped_edge_collision_restitution_matches_ode(integrator, damping):
    v = 0.05
    # the force point sits DELTA/2 off the centre line, so the normal force
    # also spins the squares; the one-dimensional reference has no rotation
    sim = _edge_scene(integrator, v, damping=damping, rotate=False)
    duration = _collide(sim)
    v_rel_after = sim.velocity[1, 0] - sim.velocity[0, 0]
    e_sim = v_rel_after / (2 * v)
    e_ref, t_ref = _edge_reference(sim.shapes.mass[0] / 2, 2 * v, damping)
    assert e_ref < 0.999  # the damping does dissipate
    # the damping force jumps at first contact; the integrators' error from that
    # jump is first order in dt, 0.006 for Gear at gamma = 0.3 and dt = limit / 10
    assert abs(e_sim - e_ref) < 1e-2
    assert abs(duration - t_ref) < 0.01 * t_ref + 2 * sim.dt


def _corner_reference(m, R, v, damping):
    """Corner of a square (90°) hitting the support: A = d², L = 2d, l = R - d."""
    def rhs(t, s):
        d, dd = s
        l = R - d
        f_el = Y * d * d / l
        damp = damping * np.sqrt(Y * m) * 2 * d * dd / l
        if dd < 0 and damp < -f_el:
            damp = -f_el
        return [dd, -(f_el + damp) / m]

    out = lambda t, s: s[0]
    out.terminal, out.direction = True, -1
    sol = solve_ivp(rhs, (0, 1.0), [1e-30, v], rtol=1e-12, atol=1e-22, events=out,
                    max_step=1e-6)
    return -sol.y_events[0][0][1] / v, sol.t_events[0][0]


@pytest.mark.parametrize("integrator", ["gear", "verlet"])
@pytest.mark.parametrize("damping", [0.0, 0.2])
def test_corner_on_support_matches_ode(integrator, damping):
    """A corner hitting a flat body: force ∝ overlap², a different law from edges."""
    R = 2.0e-3
    v = 0.1
    sim = scene([diamond(R)], [(0.0, R + 1e-7, 0.0, 0.0, -v, 0.0)], support=True,
                youngs_modulus=Y, damping=damping, friction=0.0, support_friction=0.0,
                integrator=integrator, dt_safety=0.1)
    duration = _collide(sim)
    e_sim = sim.velocity[0, 1] / v
    e_ref, t_ref = _corner_reference(sim.shapes.mass[0], R, v, damping)
    if damping == 0.0:
        assert abs(e_sim - 1.0) < 2e-3
    assert abs(e_sim - e_ref) < 5e-3
    assert abs(duration - t_ref) < 0.02 * t_ref + 2 * sim.dt


def _angular_momentum(sim):
    x = sim.position
    v = sim.velocity
    m = sim.shapes.mass[:sim.n]
    return float(np.sum(m * (x[:, 0] * v[:, 1] - x[:, 1] * v[:, 0])) +
                 np.sum(sim.shapes.inertia[:sim.n] * sim.omega))


@pytest.mark.parametrize("integrator", ["gear", "verlet"])
def test_frictional_oblique_collision_conserves_angular_momentum(integrator):
    """Undamped normal law with Coulomb friction, no support: L and p conserved."""
    sq = rectangle(2 * W, 2 * W)
    hexagon = (np.array([2, 1, -1, -2, -1, 1]) * W * 0.9,
               np.array([0, 1.7, 1.7, 0, -1.7, -1.7]) * W * 0.9)
    sim = scene([sq, hexagon], [(0.0, 0.0, 0.2, 0.08, 0.02, 3.0),
                                (3.3 * W, 0.8 * W, 0.5, -0.08, -0.03, -2.0)],
                youngs_modulus=Y, damping=0.0, friction=0.5, integrator=integrator)
    l0 = _angular_momentum(sim)
    p0 = _momentum(sim)
    _collide(sim)
    scale = sim.shapes.mass[0] * 0.1 * W
    assert abs(_angular_momentum(sim) - l0) < 1e-6 * scale
    assert np.all(np.abs(_momentum(sim) - p0) < 1e-12 * sim.shapes.mass[0])
    # friction did act: the spins changed
    assert abs(sim.omega[0] - 3.0) > 1e-3
