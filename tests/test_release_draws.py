"""A line source lays a particle at the first clear spot of its draws; a particle's
contacts read from the rows' flags are those the contact list names.

A line releases its particles anywhere along it, so when the first spot drawn
for a particle is taken by one still falling it tries the next draw
(``sim.release.LINE_DRAWS`` in all) instead of waiting; a point source has one
spot and waits.  The draws come from generators seeded by the particle, so a
pour resumed from a checkpoint draws the same places.
"""

import numpy as np

from sim.config import SimConfig
from sim.engine import Simulation
from sim.pour import _release, pile_shapes
from sim.release import LINE_DRAWS, release_point


def _rain(n=400):
    cfg = SimConfig.from_dict({"pour": {"n_particles": n, "line_source": "rain",
                                        "release_speed": 0.2, "release_height": 0.005}})
    return cfg, Simulation(pile_shapes(cfg, 1), cfg.model)


def test_a_line_draws_its_candidates_from_the_particle_s_own_generators():
    cfg, sim = _rain()
    first = release_point(sim, cfg, "layered", 1, 0, LINE_DRAWS)
    again = release_point(sim, cfg, "layered", 1, 0, LINE_DRAWS)
    assert first == again and len(first) == LINE_DRAWS
    assert len({x for x, _ in first}) == LINE_DRAWS           # distinct places along the line
    assert release_point(sim, cfg, "layered", 1, 0)[0] == first[0]   # draw 0 as a single draw


def test_a_taken_spot_sends_the_particle_to_the_next_clear_draw():
    cfg, sim = _rain()
    k = 1
    points = release_point(sim, cfg, "layered", 1, k, LINE_DRAWS)
    # particle 0 sits in flight exactly on the first candidate of particle 1
    sim.place(0, points[0][0], points[0][1], 0.0, 0.0, -0.2)
    (x0, y0), = release_point(sim, cfg, "layered", 1, k)
    assert (x0, y0) == points[0]
    after = _release(sim, cfg, "layered", 1, 0.0, 0.01, 0.2)
    assert sim.n == 2 and after == 0.01                        # released, on schedule
    clear = next(p for p in points[1:] if np.hypot(p[0] - x0, p[1] - y0)
                 > sim.shapes.radius[0] + sim.shapes.radius[1])
    assert sim.position[1, 0] == clear[0]


def test_a_point_source_waits_for_its_one_spot():
    cfg = SimConfig.from_dict({"pour": {"n_particles": 50}})
    sim = Simulation(pile_shapes(cfg, 1), cfg.model)
    (x, y), = release_point(sim, cfg, "wedge", 1, 1)
    sim.place(0, x, y, 0.0, 0.0, -1.0)
    after = _release(sim, cfg, "wedge", 1, 0.0, 0.01, 1.0)
    assert sim.n == 1 and after == sim.time + 0.001            # waits a tenth of an interval


def test_touching_is_the_contact_list_s_particles():
    """A few polygons dropped onto each other and the support: the flags say
    who touches as the listed contacts do, at every check."""
    cfg = SimConfig.from_dict({"pour": {"n_particles": 12}})
    sim = Simulation(pile_shapes(cfg, 3), cfg.model)
    for k in range(12):
        sim.place(k, 0.011 * (k % 4), 0.006 + 0.011 * (k // 4), 0.3 * k)
    for _ in range(20):
        sim.run(duration=0.005)
        c = sim.contacts()
        listed = np.zeros(sim.n, bool)
        listed[c["i"]] = True
        listed[c["j"][c["j"] >= 0]] = True
        assert np.array_equal(sim.touching(), listed)
    assert sim.touching().sum() >= 4          # the bottom row rests on the support
