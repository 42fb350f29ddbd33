"""Stability on stiff and extreme cases (sim.numerics.stability): every case
runs stably with the automatic time step or is refused up front; the largest
stable step against the time-step rule and the linear spring's theory; the
blow-up detector; the workflow target."""

import math
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from sim.blowup import BlowUpError
from sim.config import ConfigError
from sim.numerics.stability import StabilitySettings, largest_stable_dt, main, run_case
from sim.numerics.stability_cases import CASE_NAMES, linear_spring, linear_spring_limit, packing

REPO = Path(__file__).resolve().parents[1]
REFUSED = {"degenerate_refused": ["too flat", "179.8", "maximum allowed 179"],
           "dt_above_limit": ["exceeds the stability limit", "use dt <="]}


@pytest.mark.parametrize("integrator", ["gear", "verlet"])
def test_every_case_is_stable_with_the_automatic_step_or_refused(integrator):
    """All suite cases, 1000 steps each: finite, energy within 5 % of its scale,
    overlaps bounded; the two that cannot work are refused with a message that
    says why and what would work."""
    settings = StabilitySettings(stiffness=(1e5, 1e10), steps=1000)
    for name, _, builder in settings.suite():
        res = run_case(builder, integrator, settings.steps, settings.energy_tolerance)
        if name in REFUSED:
            assert res.status == "refused", (name, res)
            for text in REFUSED[name]:
                assert text in res.message, (name, res.message)
        else:
            assert res.status == "stable", (name, res)
            assert res.energy_gain <= settings.energy_tolerance
            assert 0 < res.max_overlap < 0.2, name  # in contact, below the detector's bound


@pytest.mark.parametrize("integrator, low, high", [("verlet", 0.95, 1.02),
                                                   ("gear", 1.0, 1.35)])
def test_linear_spring_is_stable_up_to_its_theoretical_limit(integrator, low, high):
    """A square squeezed between two walls is a linear spring: its largest
    stable step is h*(0)/ω (Verlet 2, Gear 0.313), found within the search's
    2 % for Verlet; for Gear within 35 % above, since just beyond 0.313 its
    undamped instability grows by less than 1e-4 per step (spectral radius
    of the amplification matrix) and needs more than the search's 5000 steps
    to show.  Either is well above the automatic step."""
    y = 1e7
    setup = linear_spring(y, integrator)
    found = largest_stable_dt(setup, 5000, 0.05, 0.02, oscillator=True)
    ratio = found / linear_spring_limit(y, integrator)
    assert low <= ratio <= high
    assert found >= setup.simulation().bound.dt_limit


def test_largest_stable_step_scales_as_one_over_root_stiffness():
    """Dimensional analysis: all contact frequencies scale as sqrt(Y), so the
    largest stable step of the same setup at 1e5 and 1e10 N/m differs by
    sqrt(1e5), within the search's resolution."""
    steps = [largest_stable_dt(linear_spring(y, "verlet"), 2000, 0.05, 0.02,
                               oscillator=True)
             for y in (1e5, 1e10)]
    assert steps[0] / steps[1] == pytest.approx(math.sqrt(1e5), rel=0.05)


@pytest.mark.parametrize("integrator", ["gear", "verlet"])
def test_packing_is_stable_beyond_the_rules_limit(integrator):
    """The rule bounds the stiffest conceivable contact, so real packings stay
    stable above its limit (at 1e10 N/m, the stiffest of the suite)."""
    setup = packing(youngs_modulus=1e10, integrator=integrator)
    found = largest_stable_dt(setup, 2000, 0.05, 0.1)
    assert found >= setup.simulation().bound.dt_limit


def test_detector_still_stops_a_real_blow_up():
    """Verlet at three times its limit on the linear spring: the engine's
    detector (not the suite's check) stops the run."""
    setup = linear_spring(1e7, "verlet")
    sim = setup.simulation(3 * linear_spring_limit(1e7, "verlet"))
    with pytest.raises(BlowUpError):
        sim.run(steps=5000)
    assert np.all(np.isfinite(sim.position))  # back at the last good state


@pytest.mark.parametrize("settings, message", [
    ({"cases": ["corners_64"]}, "unknown case(s) ['corners_64']"),
    ({"stiffness": [1e13]}, "numerics.stability.stiffness[] = 10000000000000.0: must be >= 1000.0"),
    ({"integrators": []}, "numerics.stability.integrators = []"),
    ({"steps": 5}, "numerics.stability.steps = 5"),
])
def test_bad_settings_are_refused_with_the_setting_named(settings, message):
    with pytest.raises(ConfigError) as err:
        StabilitySettings.from_dict(settings)
    assert message in str(err.value)


def test_command_writes_data_figure_and_table(tmp_path):
    out = {k: tmp_path / f"s.{k}" for k in ("nc", "png", "md")}
    params = ('{"numerics": {"stability": {"stiffness": [1e7], "cases": ["dt_above_limit"], '
              '"integrators": ["verlet"], "steps": 100, "search_steps": 200, '
              '"search_resolution": 0.3}}}')
    assert main(["--params", params, "--nc", str(out["nc"]), "--figure", str(out["png"]),
                 "--table", str(out["md"])]) == 0
    with xr.open_dataset(out["nc"]) as ds:
        assert ds.attrs["Conventions"].startswith("CF")
        assert list(ds.case.values) == ["stiffness_1e+07", "dt_above_limit"]
        assert ds.status.sel(case="dt_above_limit").item() == "refused"
        assert ds.largest_stable_dt.attrs["units"] == "s"
        assert np.all(ds.largest_stable_dt >= ds.auto_dt)
    assert out["png"].read_bytes()[:4] == b"\x89PNG"
    assert "| dt_above_limit | verlet | refused |" in out["md"].read_text()


def test_workflow_target_dry_run(tmp_path):
    """snakemake numerics with the CI config schedules both checks after the
    kernels are compiled, each with its own config section."""
    for name in ("Snakefile",):
        shutil.copy2(REPO / name, tmp_path / name)
    for name in ("workflow", "config", "sim", "analysis"):
        shutil.copytree(REPO / name, tmp_path / name,
                        ignore=shutil.ignore_patterns("__pycache__"))
    proc = subprocess.run([sys.executable, "-m", "snakemake", "-n", "-p", "--cores", "2",
                           "numerics", "--configfile", "config/config.yaml",
                           "config/numerics_ci.yaml"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out
    for rule in ("compile_kernels", "numerics_collisions", "numerics_stability"):
        # the job table's row (a rule with a message prints it instead of "rule NAME:")
        assert re.search(rf"^{rule}\s+1\b", out, re.M), rule
    assert "numerics collisions --params" in out and "numerics stability --params" in out
    assert '"stiffness": [100000.0, 10000000000.0]' in out
    assert "results/study/numerics/stable_dt.png" in out
    assert set(CASE_NAMES) >= {"jammed_box", "impact_10_m_s"}


@pytest.mark.parametrize("integrator", ["gear", "verlet"])
def test_rule_resolves_over_critical_damping(integrator):
    """An edge contact with γ = 10 (ζ⊥ = 10): the step the rule gave when it
    capped ζ⊥ at 1 blows up; the uncapped rule's automatic step is stable."""
    from dataclasses import replace

    from sim.integrators import stability_limit
    from sim.numerics.stability import run_stable

    setup = linear_spring(1e7, integrator)
    setup.model = replace(setup.model, damping=10.0)
    bound = setup.simulation().bound
    assert bound.zeta_normal == pytest.approx(10.0)
    capped = 0.5 * min(stability_limit(integrator, 1.0) / bound.omega_normal,
                       stability_limit(integrator, 0.5) / bound.omega_tangential)
    assert run_stable(setup.simulation(capped), 2000, 0.05).status == "unstable"
    assert run_stable(setup.simulation(), 2000, 0.05).status == "stable"


@pytest.mark.parametrize("case", ["corners_32", "friction_zero"])
def test_detector_does_not_take_released_corners_for_a_blow_up(case):
    """Packings that start with compressed corner contacts lose energy at any
    step, but the elastic estimate F A / (2L) is 3/4 of a corner's stored work;
    the engine's detector alone (Gear, automatic step) used to stop these runs
    within 1000 steps with "total energy rose"."""
    builder = dict((name, b) for name, _, b in StabilitySettings().suite())[case]
    sim = builder().simulation()
    sim.run(steps=1000)  # raises BlowUpError on a (false) alarm
    assert sim.step == 1000
