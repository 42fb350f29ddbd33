"""The run-time model takes a pour's own flux (issue 59, item 7): the funnel releases at the
2D Beverloo rate of its outlet, not at pour.rate, so its pour asks for the time that takes."""

import math
from pathlib import Path
from types import SimpleNamespace

from sim.config import SimConfig
from sim.pour import GRAVITY, pile_shapes
from sim.release import beverloo_rate
from sim.settings_file import read_settings_file
from workflow.resources import PARTICLE_STEP_S, POUR_TIME_FACTOR, SimResources
from workflow.validation import merge_configs, validate_config

REPO = Path(__file__).resolve().parents[1]


def study(layer):
    """The study's validated configuration with `layer` over it, 300 particles a pile."""
    cfg = merge_configs(read_settings_file(REPO / "config" / "config.yaml"),
                        merge_configs({"pour": {"n_particles": 300}}, layer))
    validate_config(cfg)
    return cfg


def test_a_narrow_funnel_asks_for_the_time_its_flux_takes():
    """At outlet_width 2 the funnel passes about 19 polygons/s against pour.rate's 100/s: the
    pour's request covers releasing every particle at that flux."""
    cfg = study({"pour": {"point_source": "funnel", "outlet_width": 2}})
    model = SimResources(cfg)
    sim = SimConfig.from_dict({k: cfg[k] for k in ("model", "particles", "pour")})
    seed = cfg["protocols"]["wedge"]["seeds"][0]
    flux = beverloo_rate(pile_shapes(sim, seed), 2, GRAVITY)
    assert 15 < flux < 25
    n, dt = cfg["pour"]["n_particles"], model.estimated_dt()
    releasing_min = n / flux / dt * n / 2 * PARTICLE_STEP_S / 60   # CPU minutes of the release alone
    wedge = model.pour_runtime_min(SimpleNamespace(protocol="wedge", seed=str(seed)), 1)
    layered = model.pour_runtime_min(SimpleNamespace(protocol="layered", seed=str(seed)), 1)
    assert wedge >= releasing_min * POUR_TIME_FACTOR and wedge > layered
    assert model.particle_steps("poured", "wedge") > 4 * model.particle_steps("poured", "layered")
    assert model.pour_runtime_min(None, 1) == wedge   # without wildcards: the slowest source
    assert math.isclose(model.pour_rate("wedge"), flux)
    assert model.pour_rate("layered") == cfg["pour"]["rate"]   # the line source keeps pour.rate
    assert "the funnel's Beverloo rate" in model.rate_text()


def test_a_wide_funnel_asks_for_less_than_pour_rate_would_take():
    model = SimResources(study({"pour": {"point_source": "funnel", "outlet_width": 6}}))
    assert model.pour_rate("wedge") > 400
    assert model.stage_cpu_s("poured", "wedge") < model.stage_cpu_s("poured", "layered")
