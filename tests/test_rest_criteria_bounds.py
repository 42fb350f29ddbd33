"""The rest criteria have upper bounds (issue 59, item 5).

A typo such as ``1e6`` for ``1e-6`` used to be taken, and a pile moving at
0.1 m/s was then declared at rest. Each criterion is refused above the bound
its description in sim/config.schema.yaml argues from physics, in one line
naming the setting, its value and what is allowed, before anything runs.
"""

import pytest

from sim.config import ConfigError, SimConfig


@pytest.mark.parametrize("key, value, says", [
    ("kinetic_energy_fraction", 1e6, "relax.kinetic_energy_fraction = 1000000.0: must be > 0 and <= 0.001"),
    ("kinetic_energy_fraction", 0.0011, "relax.kinetic_energy_fraction = 0.0011: must be > 0 and <= 0.001"),
    ("max_speed", 0.1, "relax.max_speed = 0.1: must be > 0 and <= 0.01"),
    ("unbalanced_force", 1.0, "relax.unbalanced_force = 1.0: must be > 0 and <= 0.01"),
])
def test_a_criterion_above_its_bound_is_refused_in_one_line(key, value, says):
    with pytest.raises(ConfigError) as err:
        SimConfig.from_dict({"relax": {key: value}})
    assert str(err.value).startswith(says) and "\n" not in str(err.value)


@pytest.mark.parametrize("key, value", [("kinetic_energy_fraction", 1e-3), ("max_speed", 0.01),
                                        ("unbalanced_force", 0.01)])
def test_a_criterion_at_its_bound_is_taken(key, value):
    assert getattr(SimConfig.from_dict({"relax": {key: value}}).relax, key) == value
