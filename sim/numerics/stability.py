"""Stability on stiff and extreme cases, and the largest stable time step.

**The suite.**  Each case is a small setup (:data:`CASES`): stiffness from
1e5 to 1e10 N/m, size ratio 1:20, aspect ratio 1:5, 3 and 32 corners, nearly
degenerate shapes (an edge of 0.2 % of the diameter, a 178° corner), impacts
at 10 m/s, a deep initial overlap, a jammed box, μ = 0 and 2, γ = 0, critical
and over-critical damping (a packing, and a single contact at ζ = 10).  The jammed box is made by placing the particles on
a lattice narrower than their diameters between fixed walls (the engine has
no moving walls), so they start compressed.  Each case either runs with the
automatic time step, closed and undriven, for ``steps`` steps and must stay
*stable*: finite, no :class:`sim.blowup.BlowUpError`, overlaps below
``model.max_overlap_fraction`` and a total energy (kinetic + gravitational +
elastic) that never rises above its start by more than ``energy_tolerance``
of the energy scale (start kinetic + elastic + ``Σ m |g| R``); the start's
elastic energy counts with its uncertainty
(:data:`sim.blowup.ELASTIC_UNDERESTIMATE`); or it is
*refused* before it runs by the simulator, with the message it gives.
Anything else is *unstable*, a bug in the time-step rule or the detector.

**The largest stable step.**  For each stiffness and integrator, two setups
(the dataset's ``scene``: :data:`SEARCH_SCENES`) are run with a given ``dt``
(beyond the rule's limit too; the refusal of :func:`sim.timestep.choose_dt` is
bypassed for this measurement only) and the largest ``dt`` that stays stable
over ``search_steps`` steps is bracketed by bisection in ``log dt``:

* ``linear_spring``: a square resting flat on the support, no rotation, no
  damping or friction: a linear spring ``k = Y L / l`` (``L`` the edge,
  ``l = r`` half the side), so the theory is ``h*(0) / sqrt(k/m)`` with
  :func:`sim.integrators.stability_limit` (Gear 0.313, Verlet 2);
* ``packing``: the ``stiffness`` case, twelve of the paper's particles in a box.

The setups of the cases are built in :mod:`sim.numerics.stability_cases`;
this module holds the settings, the runner and the dataset, table and figure.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, replace

import numpy as np
import xarray as xr

from ..blowup import ELASTIC_UNDERESTIMATE, BlowUpError
from ..config import ConfigError, check_setting
from ..integrators import INTEGRATORS
from .command import run_numerics_check, settings_from_dict
from .stability_cases import CASE_NAMES, case_builders, linear_spring, linear_spring_limit, packing

log = logging.getLogger("sim.numerics")


@dataclass(frozen=True)
class StabilitySettings:
    """The ``numerics.stability`` section of the configuration.

    Attributes
    ----------
    integrators : tuple of str
    stiffness : tuple of float
        Young's moduli of the stiffness cases and of the step search, N/m.
    cases : tuple of str
        Other suite cases (:data:`CASE_NAMES`).
    steps : int
        Steps each case runs with the automatic time step.
    search_steps : int
        Steps per trial of the largest-stable-step search.
    search_resolution : float
        The search stops when the bracket's upper end is within this
        fraction above its lower end.
    energy_tolerance : float
        Allowed rise of the total energy, fraction of the energy scale.
    """

    integrators: tuple = ("gear", "verlet")
    stiffness: tuple = (1e5, 1e6, 1e7, 1e8, 1e9, 1e10)
    cases: tuple = CASE_NAMES
    steps: int = 4000
    search_steps: int = 5000
    search_resolution: float = 0.02
    energy_tolerance: float = 0.05

    def __post_init__(self):
        s = "numerics.stability"
        if not self.integrators or set(self.integrators) - set(INTEGRATORS):
            raise ConfigError(f"{s}.integrators = {list(self.integrators)}: must be a "
                              f"non-empty list of {sorted(INTEGRATORS)}")
        if not self.stiffness:
            raise ConfigError(f"{s}.stiffness: must list at least one Young's modulus")
        for y in self.stiffness:
            check_setting(f"{s}.stiffness[]", y,
                          {"type": "number", "minimum": 1e3, "maximum": 1e12})
        unknown = sorted(set(self.cases) - set(CASE_NAMES))
        if unknown:
            raise ConfigError(f"{s}.cases: unknown case(s) {unknown}; known: {list(CASE_NAMES)}")
        check_setting(f"{s}.steps", self.steps, {"type": "integer", "minimum": 10})
        check_setting(f"{s}.search_steps", self.search_steps, {"type": "integer", "minimum": 10})
        check_setting(f"{s}.search_resolution", self.search_resolution,
                      {"type": "number", "exclusiveMinimum": 1e-4, "maximum": 1})
        check_setting(f"{s}.energy_tolerance", self.energy_tolerance,
                      {"type": "number", "exclusiveMinimum": 0, "maximum": 1})
        for name in ("integrators", "stiffness", "cases"):
            object.__setattr__(self, name, tuple(getattr(self, name)))

    @classmethod
    def from_dict(cls, data):
        """Build from the ``stability`` mapping (missing keys take defaults)."""
        return settings_from_dict(cls, "stability", data)

    def suite(self):
        """``[(name, description, builder)]`` of the suite: stiffness cases first."""
        out = [(f"stiffness_{y:.0e}", f"packing, Y = {y:.0e} N/m",
                (lambda y=y: packing(youngs_modulus=y))) for y in self.stiffness]
        builders = case_builders()
        return out + [(name, *builders[name]) for name in self.cases]


@dataclass
class RunResult:
    """Outcome of one run: ``status`` is ``stable``, ``unstable`` or ``refused``;
    ``energy_growth``: the largest energy in the last quarter of the run less
    that in the first quarter, over the largest kinetic energy in the first
    quarter (see :data:`ENERGY_GROWTH`)."""

    status: str
    message: str = ""
    dt: float = math.nan
    energy_gain: float = math.nan
    max_overlap: float = math.nan
    energy_growth: float = math.nan


def energy(sim):
    """Total energy: kinetic + gravitational + elastic (J/m)."""
    return sim.kinetic_energy() + sim.potential_energy() + sim.elastic_energy()


def max_overlap(sim):
    """Largest overlap area over the smaller particle's area (support: the particle's)."""
    c = sim.contacts()
    if not len(c["i"]):
        return 0.0
    area = sim.shapes.area
    j = np.where(c["j"] >= 0, c["j"], c["i"])
    return float(np.max(c["area"] / np.minimum(area[c["i"]], area[j])))


def run_stable(sim, steps, tolerance, chunk=10):
    """Run ``steps`` steps and judge stability (see the module docstring).

    Energy and overlaps are sampled every ``chunk`` steps (often enough to see
    the deepest point of a 10 m/s impact), at most 1000 times.

    Returns
    -------
    RunResult
    """
    sim.run(steps=1)  # forces and contacts of the start
    elastic = sim.elastic_energy()
    e0 = energy(sim) + ELASTIC_UNDERESTIMATE * elastic  # upper bound of the true energy
    n = sim.n
    scale = (sim.kinetic_energy() + elastic +
             float(np.sum(sim.shapes.mass[:n] * np.hypot(*sim.gravity) * sim.shapes.radius[:n])))
    gain = 0.0
    worst = max_overlap(sim)
    early = [-math.inf, 0.0]   # first quarter: largest energy, largest kinetic energy
    late = -math.inf           # last quarter: largest energy
    done = 1
    chunk = max(chunk, steps // 1000)
    try:
        while done < steps:
            done += sim.run(steps=min(chunk, steps - done))
            e = energy(sim)
            gain = max(gain, (e - e0) / scale)
            worst = max(worst, max_overlap(sim))
            if done <= steps // 4:
                early = [max(early[0], e), max(early[1], sim.kinetic_energy())]
            elif done > steps - steps // 4:
                late = max(late, e)
            if not math.isfinite(gain) or gain > tolerance:
                break
    except BlowUpError as exc:
        return RunResult("unstable", str(exc), sim.dt, gain, worst)
    if not math.isfinite(gain) or gain > tolerance:
        return RunResult("unstable", f"total energy rose by {gain:.3g} of its scale "
                         f"(> {tolerance}) after {done} steps", sim.dt, gain, worst)
    if worst > sim.model.max_overlap_fraction:
        return RunResult("unstable", f"overlap {worst:.3g} of a particle's area", sim.dt,
                         gain, worst)
    return RunResult("stable", "", sim.dt, gain, worst,
                     (late - early[0]) / max(early[1], 1e-300))


def run_case(builder, integrator, steps, tolerance):
    """Build a suite case with ``integrator`` and run it with the automatic step.

    A :class:`ValueError` (including :class:`ConfigError`) while building is
    the simulator refusing the case: status ``refused`` with its message.
    """
    try:
        setup = builder()
        setup.model = replace(setup.model, integrator=integrator)
        sim = setup.simulation()
    except ValueError as exc:
        return RunResult("refused", str(exc))
    return run_stable(sim, steps, tolerance)


#: A trial of the step search on an undamped closed oscillator is unstable
#: if its energy grew from the first to the last quarter of the run by more
#: than this fraction of its kinetic energy: a weakly growing mode (Gear just
#: above its undamped limit grows by a fraction of a per mille per step) that
#: no tolerance on the total energy, dominated by the static compression,
#: would see soon.  (The elastic energy of the oscillator's edge contacts is
#: exact, so no allowance for its estimate is needed.)
ENERGY_GROWTH = 0.1


def largest_stable_dt(setup, steps, tolerance, resolution, oscillator=False):
    """Largest stable step of a setup (:class:`~.stability_cases.Setup`), by bisection in log dt.

    A trial is stable if :func:`run_stable` says so and, for an undamped
    closed ``oscillator``, its energy does not grow (:data:`ENERGY_GROWTH`);
    a packing falls and settles, its elastic energy estimate is not exact
    (corners), and its instabilities (damped modes) grow fast.  Starts from the automatic step (which must be stable) and doubles
    until a trial is unstable, then bisects until ``hi / lo < 1 + resolution``.

    Returns
    -------
    float
        The largest step found stable, s (NaN if the automatic step is not).
    """
    lo = setup.simulation().dt

    def stable(dt):
        res = run_stable(setup.simulation(dt), steps, tolerance)
        return res.status == "stable" and not (oscillator and
                                                res.energy_growth > ENERGY_GROWTH)

    if not stable(lo):
        return math.nan
    hi = 2 * lo
    while stable(hi):
        lo, hi = hi, 2 * hi
        if hi > 1e3 * setup.simulation().bound.dt_limit:
            return math.inf
    while hi / lo > 1 + resolution:
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo


SEARCH_SCENES = ("linear_spring", "packing")


def run_suite(settings: StabilitySettings) -> xr.Dataset:
    """The suite and the largest-stable-step search, as one dataset."""
    suite = settings.suite()
    integrators = list(settings.integrators)
    shape = (len(suite), len(integrators))
    status = np.empty(shape, object)
    message = np.empty(shape, object)
    values = {k: np.full(shape, np.nan) for k in ("dt", "energy_gain", "max_overlap")}
    t0 = time.monotonic()
    for c, (name, _, builder) in enumerate(suite):
        for k, integrator in enumerate(integrators):
            res = run_case(builder, integrator, settings.steps, settings.energy_tolerance)
            status[c, k], message[c, k] = res.status, res.message
            for key in values:
                values[key][c, k] = getattr(res, key)
            log.info("stability: %s %s: %s %s (%.0f s)", name, integrator, res.status,
                     res.message, time.monotonic() - t0)
    ys = list(settings.stiffness)
    sshape = (len(SEARCH_SCENES), len(integrators), len(ys))
    found = np.full(sshape, np.nan)
    rule = np.full(sshape, np.nan)
    auto = np.full(sshape, np.nan)
    theory = np.full(sshape, np.nan)
    for s, scene_name in enumerate(SEARCH_SCENES):
        for k, integrator in enumerate(integrators):
            for y, ym in enumerate(ys):
                setup = (linear_spring(ym, integrator) if scene_name == "linear_spring" else
                         packing(youngs_modulus=ym, integrator=integrator))
                sim = setup.simulation()
                rule[s, k, y], auto[s, k, y] = sim.bound.dt_limit, sim.dt
                if scene_name == "linear_spring":
                    theory[s, k, y] = linear_spring_limit(ym, integrator)
                found[s, k, y] = largest_stable_dt(setup, settings.search_steps,
                                                   settings.energy_tolerance,
                                                   settings.search_resolution,
                                                   oscillator=scene_name == "linear_spring")
                log.info("stability: largest stable dt, %s %s Y = %.0e: %.4g s = %.3g x the "
                         "rule's limit (%.0f s)", scene_name, integrator, ym, found[s, k, y],
                         found[s, k, y] / rule[s, k, y], time.monotonic() - t0)
    cdims = ("case", "integrator")
    sdims = ("scene", "integrator", "youngs_modulus")
    return xr.Dataset({
        "description": (("case",), [d for _, d, _ in suite], {"long_name": "what the case is"}),
        "status": (cdims, status.astype(str), {"long_name":
                                               "stable, refused (up front) or unstable"}),
        "message": (cdims, message.astype(str), {"long_name": "why refused or unstable"}),
        "dt": (cdims, values["dt"], {"units": "s", "long_name": "automatic time step"}),
        "energy_gain": (cdims, values["energy_gain"], {
            "units": "1", "long_name": "largest rise of the total energy over its scale"}),
        "max_overlap": (cdims, values["max_overlap"], {
            "units": "1", "long_name": "largest overlap area over the smaller particle's area"}),
        "largest_stable_dt": (sdims, found, {"units": "s", "long_name":
                                             "largest time step found stable"}),
        "rule_dt_limit": (sdims, rule, {"units": "s", "long_name":
                                        "stability limit of the time-step rule"}),
        "auto_dt": (sdims, auto, {"units": "s", "long_name": "automatic time step"}),
        "theory_dt_limit": (sdims, theory, {"units": "s", "long_name":
                                            "h*(0)/omega of the linear spring (NaN: none)"}),
    }, coords={
        "case": ("case", [n for n, _, _ in suite], {"long_name": "suite case"}),
        "integrator": ("integrator", integrators, {"long_name": "integrator"}),
        "scene": ("scene", list(SEARCH_SCENES), {"long_name": "scene of the step search"}),
        "youngs_modulus": ("youngs_modulus", ys, {"units": "N/m",
                                                  "long_name": "particle Young's modulus"}),
    })


def table(ds: xr.Dataset) -> str:
    """Markdown tables: the suite's outcomes and the largest stable steps."""
    lines = ["| case | integrator | status | dt (s) | energy gain | max overlap | message |",
             "|---|---|---|---|---|---|---|"]
    for case in ds.case.values:
        for integrator in ds.integrator.values:
            r = ds.sel(case=case, integrator=integrator)
            lines.append(f"| {case} | {integrator} | {r.status.item()} | {float(r.dt):.3g} | "
                         f"{float(r.energy_gain):.2g} | {float(r.max_overlap):.2g} | "
                         f"{r.message.item()} |")
    lines += ["", "| scene | integrator | Y (N/m) | largest stable dt (s) | / rule's limit | "
              "/ automatic dt | / linear-spring theory |", "|---|---|---|---|---|---|---|"]
    for scene in ds.scene.values:
        for integrator in ds.integrator.values:
            for y in ds.youngs_modulus.values:
                r = ds.sel(scene=scene, integrator=integrator, youngs_modulus=y)
                dt = float(r.largest_stable_dt)
                lines.append(f"| {scene} | {integrator} | {y:.0e} | {dt:.3g} | "
                             f"{dt / float(r.rule_dt_limit):.2f} | {dt / float(r.auto_dt):.2f} | "
                             f"{dt / float(r.theory_dt_limit):.2f} |")
    return "\n".join(lines) + "\n"


def _draw(ds, path):
    from .figures import stable_dt_figure  # matplotlib only when drawing
    stable_dt_figure(ds, path)


def main(argv=None):
    """``python -m sim numerics stability``: suite and step search, then data, figure,
    table; exit status 1 if a case was unstable with the automatic step."""
    ds = run_numerics_check("stability", __doc__.split("\n\n")[0], argv, StabilitySettings,
                            run_suite, "Stability on stiff and extreme cases", _draw,
                            lambda ds, settings: table(ds))
    unstable = [f"{c} ({i})" for c in ds.case.values for i in ds.integrator.values
                if ds.status.sel(case=c, integrator=i).item() == "unstable"]
    if unstable:
        log.error("unstable with the automatic time step: %s", ", ".join(unstable))
        return 1
    return 0
