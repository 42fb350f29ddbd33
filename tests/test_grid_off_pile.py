"""A grid or a convergence point off the pile is refused by name (issue 28): before, the
fields came out NaN everywhere and the command exited 0."""

import numpy as np
import pytest
from synthetic_states import as_state, displaced, step_pyramid

from analysis.convergence import convergence_dataset
from analysis.errors import InputError
from analysis.fields import compute_fields
from analysis.params import resolve_params

A = 0.006  # a heap of squares 101 wide: x within ±0.3 m, y up to about 0.18 m


@pytest.fixture(scope="module")
def heap():
    s = step_pyramid(101, A, slope=0.6)
    r = displaced(s, np.column_stack([s["x"], s["y"]]) @ np.diag([1e-5, 2e-4]), 0.9, 0.9 * 9.81)
    return as_state(s, "relaxed.nc"), as_state(r, "reduced.nc")


def test_a_grid_beside_the_pile_is_refused_before_any_rve(heap):
    relaxed, reduced = heap
    params = resolve_params({"grid": {"x_min": 2.0, "x_max": 3.0, "y_min": 0.015, "y_max": 0.1, "spacing": 0.1}})
    with pytest.raises(InputError, match=r"analysis.grid lies off the pile.*grid centres x 2\.\.3 m.*"
                                         r"the pile's particles x -0\.3\.\.0\.3 m"):
        compute_fields(relaxed, reduced, params)


def test_a_grid_whose_rves_reach_the_pile_s_edge_but_hold_too_few_particles_is_refused(heap):
    relaxed, reduced = heap
    # centres 4 cm beside the outermost column: each RVE of 10 cm reaches one or two columns of the
    # heap's thin foot, far fewer than the 30 particles it needs
    params = resolve_params({"grid": {"x_min": 0.34, "x_max": 0.34, "y_min": 0.003, "y_max": 0.003,
                                      "spacing": 0.01}, "rve": {"size": 0.1, "min_particles": 30}})
    with pytest.raises(InputError, match="none of the 1 RVEs holds analysis.rve.min_particles = 30 particles"):
        compute_fields(relaxed, reduced, params)


def test_a_grid_on_the_pile_still_computes(heap):
    relaxed, reduced = heap
    params = resolve_params({"grid": {"x_min": -0.06, "x_max": 0.06, "y_min": 0.03, "y_max": 0.06,
                                      "spacing": 0.03}})
    ds = compute_fields(relaxed, reduced, params)
    assert int((ds["mask_reason"] == 0).sum()) == ds["mask_reason"].size


def test_a_convergence_point_off_the_pile_is_named(heap):
    relaxed, reduced = heap
    params = resolve_params({"convergence": {"points": [[0.0, 0.045], [1.5, 0.045]], "sizes": [0.03, 0.06]}})
    with pytest.raises(InputError, match=r"analysis.convergence.points\[1\] = \(1.5, 0.045\) m lies off the pile"):
        convergence_dataset(relaxed, reduced, params)
