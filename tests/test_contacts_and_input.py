"""Contact-law properties, the broad phase, the time-step rule and bad input."""

import dataclasses

import numpy as np
import pytest
import yaml

from scenes import rectangle, regular_polygon, scene, shapes_of
from sim.blowup import BlowUpError
from sim.broadphase import candidate_pairs, refreshed_pairs
from sim.config import ConfigError, ModelParams, SimConfig
from sim.contact_law import (characteristic_length, damping_coefficient, normal_force,
                             pair_damping_coefficients, tangential_force)
from sim.engine import Simulation
from sim.integrators import stability_limit
from sim.io import StateFileError, load_simulation, save_state
from sim.shapes import make_shapes


def _contact_on_first(polygons, states):
    """Force, point and area of the contact seen by particle 0 after one step."""
    sim = scene(polygons, states, youngs_modulus=1e7, damping=0.3, friction=0.5,
                max_overlap_fraction=0.9)
    sim.run(steps=1)
    c = sim.contacts()
    assert len(c["i"]) == 1
    sign = 1.0 if c["i"][0] == 0 else -1.0
    return sign * np.array([c["fx"][0], c["fy"][0]]), np.array([c["x"][0], c["y"][0]]), \
        c["area"][0]


@pytest.mark.parametrize("seed", range(5))
def test_newtons_third_law_per_contact(seed):
    """Numbering the pair the other way round gives the opposite force at the same point."""
    rng = np.random.default_rng(seed)
    polys = [rectangle(5e-3, 3e-3), regular_polygon(6, 3e-3, rng.uniform(0, 1))]
    states = [(0, 0, rng.uniform(0, 6), *rng.normal(0, 0.1, 2), rng.normal(0, 5)),
              (3.8e-3, rng.uniform(-1e-3, 1e-3), rng.uniform(0, 6), *rng.normal(0, 0.1, 2),
               rng.normal(0, 5))]
    f_a, s_a, area_a = _contact_on_first(polys, states)
    f_b, s_b, area_b = _contact_on_first(polys[::-1], states[::-1])
    # in the second scene particle 0 is the hexagon: it feels the opposite force
    scale = np.hypot(*f_a)
    assert scale > 0
    assert np.all(np.abs(f_a + f_b) < 1e-9 * scale)
    assert np.allclose(s_a, s_b, rtol=0, atol=1e-15)
    assert area_a == pytest.approx(area_b, rel=1e-12)


def test_normal_force_never_attracts():
    """On separation the damping is clamped at -F⊥ (Appendix (ii))."""
    for rate in np.linspace(-1.0, 1.0, 41):
        f_el, total = normal_force(1e-9, rate * 1e-3, 1e-3, damping_coefficient(0.02, 1e7, 5.0),
                                   1e7)
        assert total >= 0.0
        assert f_el == pytest.approx(1e7 * 1e-9 / 1e-3)
        if rate > 0:
            assert total > f_el


@pytest.mark.parametrize("rate", [-1e-3, -1e-5, -1e-7, 0.0, 1e-5])
def test_normal_damping_is_the_appendix_value_clamped_at_minus_the_elastic_force(rate):
    """Total = F + D* with D* = gamma sqrt(Y m) dA/dt / l, but never below 0:
    a fast separation gives exactly 0, a slow one the undamped value less D*."""
    area, l, m, Y, gamma = 1e-9, 1e-3, 0.02, 1e7, 5.0
    f_el, total = normal_force(area, rate, l, damping_coefficient(m, Y, gamma), Y)
    expected = Y * area / l + gamma * np.sqrt(Y * m) * rate / l
    assert total == pytest.approx(max(expected, 0.0), rel=1e-12, abs=1e-300)
    if expected < 0:
        assert total == 0.0


def test_pair_damping_coefficients_use_each_pairs_reduced_mass():
    """The pair list's damping coefficient is γ sqrt(Y m_i m_j / (m_i + m_j))
    (Appendix (ii)) of that pair's masses, and the same bits as the
    coefficient computed for one contact."""
    rng = np.random.default_rng(3)
    mass = rng.uniform(0.005, 0.05, 12)
    pi = np.array([0, 0, 3, 5, 7, 10])
    pj = np.array([1, 11, 4, 9, 8, 11])
    Y, gamma = 1e7, 0.3
    got = pair_damping_coefficients(pi, pj, 1.0 / mass, Y, gamma)
    m_perp = mass[pi] * mass[pj] / (mass[pi] + mass[pj])
    np.testing.assert_allclose(got, gamma * np.sqrt(Y * m_perp), rtol=1e-14)
    for p in range(len(pi)):
        one = damping_coefficient(1.0 / (1.0 / mass[pi[p]] + 1.0 / mass[pj[p]]), Y, gamma)
        assert got[p] == one


def test_pair_history_is_carried_across_a_rebuild():
    """The tangential springs of pairs kept by a new pair list keep their
    value; new pairs start at zero (both lists sorted by (i, j))."""
    from sim.broadphase import carry_history, match_pairs

    old_i, old_j = np.array([0, 0, 1, 2]), np.array([1, 3, 2, 5])
    new_i, new_j = np.array([0, 1, 1, 2, 4]), np.array([3, 2, 4, 5, 6])
    match = match_pairs(old_i, old_j, new_i, new_j)
    carried = carry_history(match, np.array([1.5, -2.5, 3.5, 4.5]))
    np.testing.assert_array_equal(carried, [-2.5, 3.5, 0.0, 4.5, 0.0])


A_SIDE = 5e-3  # side of the stacked squares, m
K_T = 2.0 / 7.0 * 1e7  # Cundall-Strack stiffness (2/7) Y, N/m


def _stack(v=1e-4, dt=2e-7):
    """Square 1 on square 0 on the support, both at their equilibrium overlaps
    (``m g = Y A / l``: l = a/4 between the squares, a/2 on the support), no
    rotation; square 1 starts sliding at ``v`` (m/s): too slow to slip
    (amplitude k_t v / omega far below mu F), so the contact sticks and rocks."""
    m_g = 2500.0 * A_SIDE ** 2 * 9.81
    d_support = 2 * m_g / (1e7 * A_SIDE / (A_SIDE / 2))
    d_pair = m_g / (1e7 * A_SIDE / (A_SIDE / 4))
    y0 = A_SIDE / 2 - d_support
    return scene([rectangle(A_SIDE, A_SIDE)] * 2,
                 [(0, y0, 0, 0, 0, 0), (0, y0 + A_SIDE - d_pair, 0, v, 0, 0)],
                 gravity=(0, -9.81), support=True, rotate=False, youngs_modulus=1e7,
                 damping=0.3, friction=0.5, support_friction=0.9, integrator="verlet", dt=dt)


def _pair_spring(sim, i=0, j=1):
    """The spring of pair (i, j), or None when the pair is not in the list."""
    at = np.flatnonzero((sim.pi == i) & (sim.pj == j))
    return float(sim.spring[at[0]]) if len(at) else None


def _hooke(sim, x_from):
    """Spring the Cundall-Strack law predicts: k_t times the displacement of 1
    relative to 0 along the tangent t = (-n_y, n_x) = (-1, 0) (n = +y, 0 to 1)
    taken as v_rel . t = v1x - v0x, since ``x_from`` (x of both at contact)."""
    x = sim.position[:2, 0] - x_from
    return K_T * (x[1] - x[0])


def test_a_rebuild_carries_the_spring_of_a_sticking_contact():
    """``Simulation._rebuild`` in the middle of a sticking contact: the spring
    is carried bit for bit, then keeps following Hooke's law F* = k_t dx (from
    contact, not from the rebuild), and the run is the very run without the
    rebuild.  Tolerance: the spring sums v dt at the predicted velocity, off
    from dx by at most |dv| dt / 2 <= v dt."""
    sim, twin = _stack(), _stack()
    x0 = sim.position[:2, 0]
    for s in (sim, twin):
        s.run(steps=1100)  # a quarter period: the spring is near its largest
    before = _pair_spring(sim)
    assert abs(before - _hooke(sim, x0)) <= K_T * 1e-4 * 2e-7
    assert 0.01 < before < 0.5 * 2500 * A_SIDE ** 2 * 9.81  # loaded, below mu F: sticking
    old_list = sim.pi
    sim._rebuild()
    assert sim.pi is not old_list
    assert _pair_spring(sim) == before  # bit for bit
    for s in (sim, twin):
        s.run(steps=3000)
    assert abs(_pair_spring(sim) - _hooke(sim, x0)) <= K_T * 1e-4 * 2e-7
    assert np.sign(_pair_spring(sim)) != np.sign(before)  # it rocked back past 0
    np.testing.assert_array_equal(sim.r, twin.r)
    np.testing.assert_array_equal(sim.spring, twin.spring)


def test_placing_a_particle_again_clears_its_pair_springs_as_its_support_spring():
    """``Simulation.place`` on square 0 of a sticking stack, at its own position
    and velocity: it starts afresh, so the loaded springs of its contacts with
    the support and with square 1 both go to zero (place once cleared the
    support's and kept the pair's), and the pair's spring then follows Hooke's
    law F* = k_t dx from the placement (tolerance as in the test above)."""
    sim = _stack()
    sim.run(steps=1100)
    assert _pair_spring(sim) > 0.01 and sim.bspring[0, 0] != 0.0   # both loaded
    sim.place(0, *sim.position[0], 0.0, *sim.velocity[0], 0.0)
    assert sim.bspring[0, 0] == 0.0
    assert _pair_spring(sim) == 0.0
    x0 = sim.position[:2, 0]
    sim.run(steps=1100)
    tolerance = K_T * 1e-4 * 2e-7
    assert abs(_pair_spring(sim)) > 10 * tolerance   # loaded again, from the placement
    assert abs(_pair_spring(sim) - _hooke(sim, x0)) <= tolerance


def test_rebuilding_the_pair_list_at_any_step_changes_no_bit():
    """A packing settling in its box, its pair list rebuilt every 7 steps
    against the same run rebuilt only when the particles have moved: the same
    bits, positions and contact springs, since ``_rebuild`` carries each
    pair's spring and narrow-phase witness (the warm start and the clipping
    agree only to rounding, so a lost witness shows in the last bits)."""
    from sim.numerics.bench import dense_packing

    sim, twin = dense_packing(150, seed=3), dense_packing(150, seed=3)
    for s in (sim, twin):
        s.run(steps=2000)
    for _ in range(30):
        sim._stale = True
        sim.run(steps=7)
        twin.run(steps=7)
    np.testing.assert_array_equal(sim.r, twin.r)
    c, d = sim.contacts(), twin.contacts()
    assert np.count_nonzero(c["spring"]) > 10
    for k in ("i", "j", "spring", "witness"):
        np.testing.assert_array_equal(c[k], d[k], err_msg=k)


def test_pairs_new_to_the_list_start_unloaded_and_take_no_other_pairs_spring():
    """Square 1 is lifted out of the pair list (placed far away) and square 2
    put where it was, sliding, before the same rebuild: the new pair (0, 2)
    starts from zero, not from the loaded spring of the pair (0, 1) that left
    (F* = k_t dx from its own contact on).  Then 1 comes back on top of 2: the
    new pair (1, 2) starts from zero while (0, 2) keeps its spring."""
    sim = scene([rectangle(A_SIDE, A_SIDE)] * 3, [], gravity=(0, -9.81), support=True,
                rotate=False, youngs_modulus=1e7, damping=0.3, friction=0.5,
                support_friction=0.9, integrator="verlet", dt=2e-7)
    stack = _stack()
    for k in range(2):
        sim.place(k, *stack.position[k], 0.0, *stack.velocity[k], 0.0)
    sim.place(2, 0.5, A_SIDE / 2)  # far away on the support
    sim.run(steps=1100)
    assert _pair_spring(sim, 0, 1) > 0.01
    top = sim.position[1].copy()
    sim.place(1, -0.5, 0.5)
    sim.place(2, *top, 0.0, 1e-4, 0.0)
    sim.run(steps=1)
    assert _pair_spring(sim, 0, 1) is None
    first = _pair_spring(sim, 0, 2)
    assert 0 < first <= K_T * 2e-4 * 2e-7  # one step's increment k_t v dt
    x0 = sim.position[[0, 2], 0]
    sim.run(steps=1000)
    loaded = _pair_spring(sim, 0, 2)
    assert abs(loaded - first - K_T * ((sim.position[2, 0] - x0[1]) -
                                       (sim.position[0, 0] - x0[0]))) <= K_T * 1e-4 * 2e-7
    sim.place(1, sim.position[2, 0], sim.position[2, 1] + A_SIDE - 1e-8, 0.0, 0.0, 0.0)
    sim.run(steps=1)
    c = sim.contacts()
    assert np.any((c["i"] == 1) & (c["j"] == 2))
    assert abs(_pair_spring(sim, 1, 2)) <= K_T * 2e-4 * 2e-7
    assert abs(_pair_spring(sim, 0, 2) - loaded) < 0.1 * abs(loaded)


def test_tangential_force_capped_and_opposes_sliding():
    f_el = 2.0
    mu = 0.4
    spring = 0.0
    for _ in range(200):  # steady sliding in +t: spring saturates at mu F
        total, spring = tangential_force(spring, 0.01, f_el, 0.01, 1e7, mu, 1e-6)
        assert abs(total) <= mu * f_el * (1 + 1e-12)
    assert total == pytest.approx(mu * f_el)      # acts on i as -T t: opposes sliding
    assert spring == pytest.approx(mu * f_el)
    total, spring = tangential_force(spring, -0.01, f_el, 0.01, 1e7, mu, 1e-6)
    assert total < mu * f_el  # reversal unloads the spring first


def _coulomb_law(spring, v, f_el, m_par, mu, dt, youngs_modulus=1e7):
    """The Appendix's (iii) by hand: the spring loads by k_t v dt and is held
    within +-mu F; the damping v sqrt(k_t m) is added and the total is held
    within +-mu F too."""
    k_t = 2.0 / 7.0 * youngs_modulus
    cap = mu * f_el
    spring = min(max(spring + k_t * v * dt, -cap), cap)
    return min(max(spring + v * np.sqrt(k_t * m_par), -cap), cap), spring


@pytest.mark.parametrize("speed", [1e-4, 2e-3, 1.0])
@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_coulomb_cap_at_slow_and_fast_sliding_and_on_reversal(speed, direction):
    """Sliding at ``speed`` until the spring saturates, then reversing: every
    step gives the hand-worked law, and |T| <= mu F throughout.  Slow (1e-4
    m/s): the total stays below the cap while the spring loads (damping
    0.017 N); 2e-3 m/s: the damping alone (0.34 N) is under the cap (0.8 N);
    fast (1 m/s): capped from the first step, and on reversal the spring
    jumps from +mu F to -mu F in one step (k_t v dt = 29 N)."""
    f_el, mu, m_par, dt = 2.0, 0.4, 0.01, 1e-5
    cap = mu * f_el
    v = direction * speed
    n_load = int(np.ceil(cap / (2.0 / 7.0 * 1e7 * speed * dt))) + 5
    spring = hand = 0.0
    below = 0
    for k in range(2 * n_load + 2 * n_load):
        vk = v if k < 2 * n_load else -v
        total, spring = tangential_force(spring, vk, f_el, m_par, 1e7, mu, dt)
        want, hand = _coulomb_law(hand, vk, f_el, m_par, mu, dt)
        assert abs(total) <= cap and abs(spring) <= cap
        assert total == pytest.approx(want, rel=1e-9, abs=1e-15)
        assert spring == pytest.approx(hand, rel=1e-9, abs=1e-15)
        below += abs(total) < cap
    assert spring == -direction * cap and total == -direction * cap  # saturated the other way
    assert (below > 0) == (speed < 5e-3)


@pytest.mark.parametrize("v0", [0.05, -0.05, 0.5, -0.5])
def test_a_block_sliding_on_the_support_decelerates_at_mu_g(v0):
    """A square sliding on the support (no rotation, at its equilibrium
    overlap m g = Y A / l with l = a/2) feels the capped friction mu m g while
    it slides, in either direction: v(t) = v0 - sign(v0) mu g t until it stops
    at t* = |v0| / (mu g), x* = v0 |v0| / (2 mu g); after that it sticks (the
    spring, stretched mu m g / k_t = 1e-7 m at the stop, gives that back: 4e-4
    of x* at 0.05 m/s)."""
    a, mu, g = 5e-3, 0.5, 9.81
    m = 2500.0 * a * a
    sim = scene([rectangle(a, a)], [(0, a / 2 - m * g / (2e7), 0, v0, 0, 0)],
                gravity=(0, -g), support=True, rotate=False, youngs_modulus=1e7,
                damping=0.3, support_friction=mu, friction=0.5, integrator="verlet")
    t_stop = abs(v0) / (mu * g)
    sim.run(duration=0.5 * t_stop)
    assert sim.velocity[0, 0] == pytest.approx(v0 - np.sign(v0) * mu * g * sim.time, rel=1e-4)
    force = sim.contacts()["fx"][0]
    assert force == pytest.approx(-np.sign(v0) * mu * m * g, rel=1e-6)
    sim.run(duration=0.5 * t_stop + 0.02)
    assert sim.position[0, 0] == pytest.approx(v0 * abs(v0) / (2 * mu * g), rel=1e-3)
    assert abs(sim.velocity[0, 0]) < 1e-4 * abs(v0)  # stuck


@pytest.mark.parametrize("parallel", [False, True], ids=["serial", "parallel"])
def test_broad_phase_finds_every_close_pair(parallel):
    """Cell list against brute force, including a particle far from the rest,
    in both builds (the serial one serves fewer than 400 particles)."""
    rng = np.random.default_rng(7)
    n = 600
    x = rng.uniform(0, 0.15, n)
    y = rng.uniform(0, 0.15, n)
    x[0], y[0] = 40.0, -3.0
    radius = rng.uniform(2e-3, 4e-3, n)
    skin = 1e-3
    pi, pj = candidate_pairs(x, y, radius, n, skin, parallel)
    d = np.hypot(x[:, None] - x[None], y[:, None] - y[None])
    reach = radius[:, None] + radius[None] + skin
    bi, bj = np.nonzero(np.triu(d < reach, 1))
    assert list(zip(pi, pj)) == list(zip(bi, bj))  # same pairs, same (i, j) order


def brute_force_pairs(x, y, radius, skin):
    """Every pair i < j closer than R_i + R_j + skin, by all distances."""
    d = np.hypot(x[:, None] - x[None], y[:, None] - y[None])
    return np.nonzero(np.triu(d < radius[:, None] + radius[None] + skin, 1))


@pytest.mark.parametrize("n_moved", [1, 2, 7])
def test_refreshing_the_pairs_of_moved_particles_gives_the_list_of_all_references(n_moved):
    """Some particles take new reference centres (one jumps far, others move
    within and beyond reach, two of them neighbours): the refreshed list is
    the brute-force list of all references, in (i, j) order, and each pair
    kept from the old list points at its old row."""
    rng = np.random.default_rng(11 + n_moved)
    n, skin = 300, 1e-3
    x = rng.uniform(0, 0.08, n)
    y = rng.uniform(0, 0.08, n)
    radius = rng.uniform(2e-3, 4e-3, n)
    pi, pj = candidate_pairs(x, y, radius, n, skin)
    moved = np.zeros(n, bool)
    moved[rng.choice(n, n_moved, replace=False)] = True
    first = np.flatnonzero(moved)[0]
    moved[pj[pi == first][:1]] = True          # and one of its partners
    x_ref, y_ref = x.copy(), y.copy()
    x_ref[moved] += rng.normal(0, 4e-3, moved.sum())
    y_ref[moved] += rng.normal(0, 4e-3, moved.sum())
    x_ref[first], y_ref[first] = 0.5, 0.5       # far from everyone
    ri, rj, match = refreshed_pairs(x_ref, y_ref, radius, n, skin, moved, pi, pj)
    bi, bj = brute_force_pairs(x_ref, y_ref, radius, skin)
    assert list(zip(ri, rj)) == list(zip(bi, bj))
    old = {(a, b): k for k, (a, b) in enumerate(zip(pi, pj))}
    assert list(match) == [old.get((a, b), -1) for a, b in zip(ri, rj)]
    assert not np.any((ri == first) | (rj == first))


def test_a_pour_refreshing_few_pairs_keeps_every_touching_pair_listed():
    """Particles dropped onto a heap (the pour's case: few move): at every
    refresh the list holds every pair whose polygons' circumcircles are
    within the skin at the current centres, and most refreshes were of the
    movers' pairs only."""
    from sim import rebuild as rebuilds

    sim = Simulation(make_shapes(np.random.default_rng(3), 40), ModelParams(damping=0.3))
    for k in range(40):
        sim.place(k, 0.012 * (k % 8) - 0.042, 0.004 + 0.008 * (k // 8), 0.0, 0.0, 0.0)
    sim.run(duration=0.02)
    counts = {"refreshed": 0}
    real = rebuilds.refreshed_pairs

    def counted(*args):
        counts["refreshed"] += 1
        return real(*args)

    rebuilds.refreshed_pairs = counted
    try:
        for k in range(30, 40):    # lift the top ten and drop them again, one at a time
            sim.place(k, 0.0, 0.08, 0.3 * k, 0.0, -0.3)
            for _ in range(20):
                sim.run(duration=0.002)
                s = sim.state
                x, y = s.r[0, 0, :s.n], s.r[0, 1, :s.n]
                bi, bj = brute_force_pairs(x, y, sim.scene.shapes.radius[:s.n], 0.0)
                listed = set(zip(s.pi.tolist(), s.pj.tolist()))
                assert set(zip(bi.tolist(), bj.tolist())) <= listed
    finally:
        rebuilds.refreshed_pairs = real
    assert counts["refreshed"] > 10


def test_given_dt_beyond_stability_limit_is_refused():
    shapes = make_shapes(np.random.default_rng(0), 5)
    limit = Simulation(shapes, ModelParams()).bound.dt_limit
    with pytest.raises(ValueError, match="stability limit"):
        Simulation(shapes, ModelParams(dt=1.5 * limit))
    Simulation(shapes, ModelParams(dt=0.9 * limit))


def test_time_step_limit_of_equal_squares_by_hand():
    """Squares of side a, Y = 1e7 N/m, no damping, velocity Verlet.

    Two squares pressed face to face overlap by A = a d, with the force point
    at the middle of both faces: r_i = r_j = a/2, l = r_i r_j / (r_i + r_j) =
    a/4, so F = Y A / l = 4 Y d, a stiffness 4 Y (the rule's Y L_max / l_min
    with L_max = a and l_min = half the inradius a/2).  The lightest contact
    point: 1/m + R^2/I with m = rho a^2, I = m a^2 / 6 and R^2 = a^2 / 2 is
    4/m, twice over for two particles, 8/m.  So omega = sqrt(32 Y / m), and
    Verlet's undamped limit omega dt < 2 gives dt = 2 / omega = sqrt(m / (8 Y)).
    The tangential spring (2/7) Y on the same mass, omega_t = sqrt(16 Y / (7 m)),
    is damped at zeta = 1/2 (limit 0.83): 0.55 sqrt(m / Y), longer than the
    normal mode's 0.354 sqrt(m / Y)."""
    a, y = 5e-3, 1e7
    m = 2500.0 * a * a
    sim = Simulation(shapes_of(rectangle(a, a), rectangle(a, a)),
                     ModelParams(youngs_modulus=y, damping=0.0, integrator="verlet"))
    assert sim.bound.dt_limit == pytest.approx(np.sqrt(m / (8 * y)), rel=1e-12)
    assert sim.bound.mode == "normal"
    assert sim.bound.omega_tangential == pytest.approx(np.sqrt(16 * y / (7 * m)), rel=1e-12)
    assert sim.dt == pytest.approx(ModelParams().dt_safety * np.sqrt(m / (8 * y)), rel=1e-12)


def test_time_step_limit_of_mixed_particles_by_hand():
    """A regular hexagon (circumradius R = 3 mm) and a square (side 8 mm),
    damping 0.3, Gear: the rule takes the longest edge (the square's, L = 8 mm),
    the smallest inradius (the hexagon's, R sqrt(3)/2, so l_min = sqrt(3) R / 4)
    and the lightest contact point, the hexagon's: I = (5/12) m R^2 for a
    regular hexagon (m R^2 (1 + 2 cos^2(pi/6)) / 6), so 1/m + R^2/I = 17 / (5 m),
    q = 34 / (5 m) for two.  omega_n = sqrt(Y L / l_min q) with damping ratio
    zeta_n = (gamma/2) sqrt(L / l_min); omega_t = sqrt((2/7) Y q) at zeta 1/2;
    the limit is the smaller of h*(zeta)/omega with Gear's h* of the
    amplification matrix (0.157 at zeta 1/2; the rule rounds zeta to 1e-3)."""
    r, side, y, gamma = 3e-3, 8e-3, 1e7, 0.3
    m_hex = 2500.0 * 1.5 * np.sqrt(3) * r * r
    sim = Simulation(shapes_of(regular_polygon(6, r), rectangle(side, side)),
                     ModelParams(youngs_modulus=y, damping=gamma, integrator="gear"))
    assert sim.shapes.inertia[0] == pytest.approx(5 / 12 * m_hex * r * r, rel=1e-12)
    q = 34 / (5 * m_hex)
    ratio = side / (np.sqrt(3) * r / 4)
    dt_n = stability_limit("gear", gamma / 2 * np.sqrt(ratio)) / np.sqrt(y * ratio * q)
    dt_t = stability_limit("gear", 0.5) / np.sqrt(2 / 7 * y * q)
    assert stability_limit("gear", 0.5) == pytest.approx(0.157, abs=5e-4)
    assert sim.bound.zeta_normal == pytest.approx(gamma / 2 * np.sqrt(ratio), rel=1e-12)
    assert sim.bound.dt_limit == pytest.approx(min(dt_n, dt_t), rel=2e-3)
    assert sim.bound.mode == ("normal" if dt_n < dt_t else "tangential")


def test_blow_up_is_detected_and_last_good_state_kept():
    """A resting block stepped far beyond its stability (forced past the check) blows up.

    The rule's limit is a bound over the worst contact of two particles; for a
    block on the support the real limit is several times larger, so the step
    is made 40 times the automatic one."""
    sim = scene([rectangle(4e-3, 4e-3)], [(0, 2e-3 - 1e-7, 0, 0, 0, 0)], gravity=(0, -9.81),
                support=True)
    sim.run(steps=200)            # at rest on the support: its contact is evaluated
    sim.dt *= 40.0
    sim.r *= 40.0 ** np.arange(sim.r.shape[0])[:, None, None]
    with pytest.raises(BlowUpError, match="unstable") as err:
        sim.run(steps=20000)
    assert np.all(np.isfinite(sim.r[:, :, :2]))
    assert err.value.last_good.time == sim.time
    # the contacts reported (and saved as *.lastgood.nc) are those of the good
    # state's positions, not of the step that failed
    c = sim.contacts()
    assert len(c["i"]) == 1 and np.all(np.isfinite(c["fx"]))
    x, y = sim.position[0]
    assert np.hypot(c["x"][0] - x, c["y"][0] - y) <= sim.shapes.radius[0]
    assert c["area"][0] <= sim.model.max_overlap_fraction * sim.shapes.area[0]
    assert c["area"][0] == pytest.approx(4e-3 * max(0.0, -float(np.min(
        y + sim.shapes.node_x[:4] * np.sin(sim.theta[0]) + sim.shapes.node_y[:4] *
        np.cos(sim.theta[0])))), rel=0.05)


@pytest.mark.parametrize("section,key,value,message", [
    ("model", "youngs_modulus", -1.0, "model.youngs_modulus = -1.0: must be > 0"),
    ("model", "youngs_modulus", 0.0, "must be > 0"),
    ("model", "friction", -0.1, "model.friction = -0.1: must be >= 0"),
    ("model", "integrator", "rk4", "must be one of 'gear', 'verlet'"),
    ("model", "dt", "1e-6", "must be a number"),
    ("particles", "corners_min", 2, "particles.corners_min = 2: must be >= 3"),
    ("probe", "levels", [1.5], "probe.levels[] = 1.5: must be > 0 and < 1"),
])
def test_bad_settings_are_refused(section, key, value, message):
    with pytest.raises(ConfigError) as err:
        SimConfig.from_dict({section: {key: value}})
    assert message.split(":")[0].split(" = ")[0] in str(err.value)
    assert message.split(": ")[-1] in str(err.value) or message in str(err.value)


def test_unknown_setting_is_refused():
    with pytest.raises(ConfigError, match="unknown setting.*fricton"):
        SimConfig.from_dict({"model": {"fricton": 0.3}})


def test_non_convex_and_self_intersecting_polygons_are_refused():
    arrow = (np.array([0, 2, 1, 2, 0.0]) * 1e-3 - 1e-3, np.array([0, 0, 1, 2, 2.0]) * 1e-3 - 1e-3)
    with pytest.raises(ValueError, match="particle 1"):
        shapes_of(rectangle(2e-3, 2e-3), arrow)
    bowtie = (np.array([-1, 1, -1, 1.0]) * 1e-3, np.array([-1, 1, 1, -1.0]) * 1e-3)
    with pytest.raises(ValueError, match="self-intersect"):
        shapes_of(bowtie)


def test_nan_in_state_file_is_refused(tmp_path):
    import xarray as xr
    sim = scene([rectangle(4e-3, 4e-3)], [(0, 0.01, 0, 0, 0, 0)], gravity=(0, -9.81),
                support=True)
    path = tmp_path / "s.nc"
    save_state(sim, path)
    ds = xr.open_dataset(path).load()
    ds["vy"][0] = np.nan
    bad = tmp_path / "bad.nc"
    ds.to_netcdf(bad)
    with pytest.raises(StateFileError, match="vy holds NaN"):
        load_simulation(bad)


def test_config_defaults_match_the_schema():
    """The simulator's defaults and its schema's (sim/config.schema.yaml) agree, setting by setting."""
    with open("sim/config.schema.yaml") as f:
        schema = yaml.safe_load(f)
    defaults = SimConfig().to_dict()
    for section, values in defaults.items():
        props = schema["$defs"][section]["properties"]
        assert set(props) == set(values), section
        for key, value in values.items():
            assert props[key].get("default") == value, f"{section}.{key}"


@pytest.mark.parametrize("name, small, offset, theta", [
    ("coincident centres, turned", 1.0, 0.0, 0.3),
    ("coincident centres, aligned", 1.0, 0.0, 0.0),
    ("one square inside the other", 0.5, 0.2, 0.2),
])
def test_a_scene_starting_deeply_overlapped_is_refused_at_its_first_step(name, small, offset,
                                                                         theta):
    """Coincident centres put the contact point on both centres (l = r_i r_j / (r_i + r_j)
    is 0/0) and a nested polygon has no contact line: the run stops after one step with
    the blow-up detector's message and the start state kept, instead of a
    ZeroDivisionError inside the kernel or particles thrown apart at 1e9 m/s."""
    w = 4e-3
    sim = scene([rectangle(w, w), rectangle(small * w, small * w)],
                [(0.0, 0.0, 0.0, 0.0, 0.0, 0.0), (offset * w, 0.0, theta, 0.0, 0.0, 0.0)],
                youngs_modulus=1e7)
    start = sim.position.copy()
    with pytest.raises(BlowUpError, match=r"step 1\): an overlap of .* exceeds "
                                          r"model.max_overlap_fraction"):
        sim.run(steps=300)
    np.testing.assert_array_equal(sim.position, start)
    assert sim.time == 0.0


def test_characteristic_length_of_a_contact_point_on_both_centres_is_zero():
    assert characteristic_length(0.0, 0.0) == 0.0
    assert characteristic_length(2.0, 2.0) == pytest.approx(1.0)  # r r / 2r = r / 2
    assert characteristic_length(3.0, np.inf) == 3.0
