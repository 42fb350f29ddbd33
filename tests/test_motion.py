"""Equations of motion: free fall and a block on an inclined support."""

import numpy as np
import pytest

from scenes import rectangle, regular_polygon, scene

G = 9.81


@pytest.mark.parametrize("integrator", ["gear", "verlet"])
def test_free_fall_is_exact(integrator):
    """Constant acceleration: both integrators reproduce x0 + v0 t + g t²/2."""
    gravity = (1.5, -G)
    x0, y0, vx0, vy0, w0 = 0.01, 0.5, 0.3, 1.2, 4.0
    sim = scene([regular_polygon(7, 3e-3)], [(x0, y0, 0.1, vx0, vy0, w0)],
                gravity=gravity, integrator=integrator)
    sim.run(steps=4000)
    t = sim.time
    expect = np.array([x0 + vx0 * t + 0.5 * gravity[0] * t * t,
                       y0 + vy0 * t + 0.5 * gravity[1] * t * t])
    assert np.allclose(sim.position[0], expect, rtol=0, atol=1e-12)
    assert np.allclose(sim.velocity[0], [vx0 + gravity[0] * t, vy0 + gravity[1] * t],
                       rtol=0, atol=1e-11)
    assert sim.theta[0] == pytest.approx(0.1 + w0 * t, abs=1e-12)


def _incline(angle_deg, friction, integrator):
    """A square resting on the support under gravity tilted by ``angle_deg``."""
    a = np.radians(angle_deg)
    side = 4e-3
    sim = scene([rectangle(side, side)], [(0.0, side / 2 - 5e-7, 0.0, 0, 0, 0)],
                gravity=(G * np.sin(a), -G * np.cos(a)), support=True,
                friction=friction, support_friction=friction, damping=0.3,
                integrator=integrator)
    sim.run(duration=0.02)  # settle the normal contact
    return sim


@pytest.mark.parametrize("integrator", ["gear", "verlet"])
def test_block_sticks_below_friction_angle(integrator):
    mu = 0.5
    sim = _incline(np.degrees(np.arctan(0.8 * mu)), mu, integrator)
    x1 = sim.position[0, 0]
    sim.run(duration=0.1)
    # only the elastic creep of the tangential spring, far below a micron
    assert abs(sim.position[0, 0] - x1) < 1e-8
    assert abs(sim.velocity[0, 0]) < 1e-6


@pytest.mark.parametrize("integrator", ["gear", "verlet"])
@pytest.mark.parametrize("tan_theta", [0.7, 0.9])
def test_block_slides_above_friction_angle(integrator, tan_theta):
    mu = 0.5
    a = np.arctan(tan_theta)
    sim = _incline(np.degrees(a), mu, integrator)
    t1, v1 = sim.time, sim.velocity[0, 0]
    sim.run(duration=0.05)
    accel = (sim.velocity[0, 0] - v1) / (sim.time - t1)
    expect = G * (np.sin(a) - mu * np.cos(a))
    assert accel == pytest.approx(expect, rel=1e-2)
    # the single force point (midpoint of the contact line) lets the block
    # lean onto its leading corner, but it must not tip over
    assert abs(sim.theta[0]) < 0.05


@pytest.mark.parametrize("integrator", ["gear", "verlet"])
def test_spin_drag_damps_the_rotation_alone_exponentially(integrator):
    """``pour.spin_drag`` c: I dω/dt = −c I ω, so ω(t) = ω0 e^(−ct), while the
    free flight of the centre stays exactly ballistic. The drag is taken at the
    predicted ω, first order in dt: each step multiplies ω by 1 − c dt instead of
    e^(−c dt), a relative excess of c² dt t / 2 after time t, as measured."""
    gravity = (0.0, -G)
    x0, y0, vx0, vy0, w0, c = 0.01, 0.5, 0.3, 1.2, 40.0, 50.0
    sim = scene([regular_polygon(7, 3e-3)], [(x0, y0, 0.1, vx0, vy0, w0)], gravity=gravity,
                integrator=integrator)
    sim.spin_drag = c
    sim.run(duration=0.02)
    t = sim.time
    excess = sim.omega[0] / (w0 * np.exp(-c * t)) - 1
    assert excess == pytest.approx(c * c * sim.dt * t / 2, rel=0.05)
    assert sim.theta[0] == pytest.approx(0.1 + w0 * (1 - np.exp(-c * t)) / c, rel=1e-3)
    assert np.allclose(sim.velocity[0], [vx0, vy0 - G * t], rtol=0, atol=1e-11)
    assert np.allclose(sim.position[0], [x0 + vx0 * t, y0 + vy0 * t - 0.5 * G * t * t], rtol=0, atol=1e-12)
