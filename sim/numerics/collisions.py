"""Error against run time for binary collisions: the time-step sweep.

For every collision case (:mod:`sim.numerics.collision_scenes`) and integrator the
step runs from the rule's stability limit ``dt_limit`` of the particle pair
(:func:`sim.timestep.stability_bound`) down to a hundredth of it.  Each run is
measured against the solve_ivp reference (:mod:`sim.numerics.reference`) and
timed: the wall time of ``Simulation.run`` over the steps of the collision
(placement to separation), the median of ``repeats`` runs after the kernels
are compiled.  With two particles a step costs a few microseconds, almost all
of it fixed per-step overhead (three kernel launches, the loop, the periodic
state check), not contact work, so the times compare integrators at equal
overhead; in a pile the contact work dominates instead.

``python -m sim numerics collisions --params @config/numerics.yaml --nc ... --figure ... --table ...``
writes the netCDF data, the figure and a Markdown table.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np
import xarray as xr

from ..config import ConfigError, check_setting
from ..integrators import INTEGRATORS
from .collision_scenes import CONTACTS, OBSERVABLES, CollisionCase, measure, reference, scene
from .command import run_numerics_check, settings_from_dict

log = logging.getLogger("sim.numerics")

@dataclass(frozen=True)
class CollisionSettings:
    """The ``numerics.collisions`` section of the configuration.

    Attributes
    ----------
    integrators : tuple of str
    youngs_modulus : float
        Y of every case, N/m.
    normal_speed, tangential_speed : float
        Relative speeds at touch-down, m/s.
    largest_fraction, smallest_fraction : float
        Range of ``dt / dt_limit``.
    steps_per_decade : int
        Time steps per decade of ``dt`` (log-spaced).
    repeats : int
        Timed repeats per run (the median is kept).
    target_error : float
        Accuracy at which the table compares the integrators' cost.
    cases : tuple of dict
        ``{name, contact, damping, friction}`` per collision.
    """

    integrators: tuple = ("gear", "verlet")
    youngs_modulus: float = 1.0e7
    normal_speed: float = 0.1
    tangential_speed: float = 0.1
    largest_fraction: float = 1.0
    smallest_fraction: float = 0.01
    steps_per_decade: int = 4
    repeats: int = 5
    target_error: float = 1.0e-4
    cases: tuple = field(default_factory=lambda: tuple(DEFAULT_CASES))

    def __post_init__(self):
        s = "numerics.collisions"
        for name in self.integrators:
            if name not in INTEGRATORS:
                raise ConfigError(f"{s}.integrators: {name!r} is not one of "
                                  f"{sorted(INTEGRATORS)}")
        if not self.integrators:
            raise ConfigError(f"{s}.integrators: must name at least one integrator")
        number = {"type": "number"}
        fraction = {"type": "number", "exclusiveMinimum": 0, "maximum": 1}
        check_setting(f"{s}.youngs_modulus", self.youngs_modulus, {**number, "exclusiveMinimum": 0})
        check_setting(f"{s}.normal_speed", self.normal_speed, {**number, "exclusiveMinimum": 0})
        check_setting(f"{s}.tangential_speed", self.tangential_speed, number)
        check_setting(f"{s}.largest_fraction", self.largest_fraction, fraction)
        check_setting(f"{s}.smallest_fraction", self.smallest_fraction,
                      {**number, "minimum": 1e-4, "maximum": self.largest_fraction})
        check_setting(f"{s}.steps_per_decade", self.steps_per_decade,
                      {"type": "integer", "minimum": 1, "maximum": 20})
        check_setting(f"{s}.repeats", self.repeats,
                      {"type": "integer", "minimum": 1, "maximum": 100})
        check_setting(f"{s}.target_error", self.target_error, fraction)
        if not self.cases:
            raise ConfigError(f"{s}.cases: must list at least one collision")
        names = [c.get("name") for c in self.cases]
        if len(set(names)) != len(names):
            raise ConfigError(f"{s}.cases: names {names} must be unique")
        for c in self.cases:
            unknown = sorted(set(c) - {"name", "contact", "damping", "friction"})
            if unknown or not {"name", "contact"} <= set(c):
                raise ConfigError(f"{s}.cases: {c!r} must have name and contact and may "
                                  f"have damping and friction (unknown: {unknown})")
            if c["contact"] not in CONTACTS:
                raise ConfigError(f"{s}.cases[{c['name']}].contact = {c['contact']!r}: "
                                  f"must be one of {list(CONTACTS)}")
            for name in ("damping", "friction"):
                check_setting(f"{s}.cases[{c['name']}].{name}", c.get(name, 0.0),
                              {**number, "minimum": 0, "maximum": 10})
        object.__setattr__(self, "integrators", tuple(self.integrators))
        object.__setattr__(self, "cases", tuple(dict(c) for c in self.cases))

    @classmethod
    def from_dict(cls, data):
        """Build from the ``collisions`` mapping (missing keys take defaults)."""
        return settings_from_dict(cls, "collisions", data)

    def collision_cases(self):
        """The :class:`CollisionCase` of every configured collision."""
        return [CollisionCase(c["name"], c["contact"], float(c.get("damping", 0.0)),
                              float(c.get("friction", 0.0)), self.normal_speed,
                              self.tangential_speed, self.youngs_modulus)
                for c in self.cases]

    def fractions(self):
        """``dt / dt_limit`` of the sweep, largest first, log-spaced."""
        decades = math.log10(self.largest_fraction / self.smallest_fraction)
        count = max(2, int(round(decades * self.steps_per_decade)) + 1)
        return np.geomspace(self.largest_fraction, self.smallest_fraction, count)


DEFAULT_CASES = [
    {"name": "edge_elastic", "contact": "edge", "damping": 0.0, "friction": 0.0},
    {"name": "edge_damped", "contact": "edge", "damping": 0.3, "friction": 0.0},
    {"name": "edge_friction", "contact": "edge", "damping": 0.0, "friction": 0.5},
    {"name": "edge_damped_friction", "contact": "edge", "damping": 0.3, "friction": 0.5},
    {"name": "corner_elastic", "contact": "corner", "damping": 0.0, "friction": 0.0},
    {"name": "corner_damped", "contact": "corner", "damping": 0.3, "friction": 0.0},
    {"name": "corner_friction", "contact": "corner", "damping": 0.0, "friction": 0.5},
    {"name": "corner_damped_friction", "contact": "corner", "damping": 0.3, "friction": 0.5},
]


def wall_time(case, integrator, dt, steps, repeats):
    """Median wall time (s) of ``Simulation.run(steps=steps)`` from the collision's
    start, over ``repeats`` runs after an untimed one (the first run of a new
    simulation object pays one-off costs)."""
    sim = scene(case, integrator, dt)
    start = sim.snapshot()
    sim.run(steps=steps)
    times = []
    for _ in range(repeats):
        sim.restore(start)
        t0 = time.perf_counter()
        sim.run(steps=steps)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def error(measured, ref, kind):
    """Error of a measured value: ``|m − r|`` (absolute) or ``|m − r| / |r|`` (relative)."""
    diff = np.abs(np.asarray(measured) - ref)
    return diff if kind == "absolute" else diff / abs(ref)


def sweep(settings: CollisionSettings) -> xr.Dataset:
    """Measure and time every case, integrator and time step.

    Returns
    -------
    xarray.Dataset
        Dimensions ``case``, ``integrator``, ``dt_fraction``; see
        :data:`sim.numerics.collision_scenes.OBSERVABLES` for the measured
        variables and their errors.
    """
    cases = settings.collision_cases()
    fractions = settings.fractions()
    shape = (len(cases), len(settings.integrators), len(fractions))
    out = {name: np.full(shape, np.nan) for name in OBSERVABLES}
    dt = np.full(shape, np.nan)
    steps = np.zeros(shape, np.int64)
    wall = np.full(shape, np.nan)
    limit = np.full(shape[:2], np.nan)
    refs = {name: np.full(len(cases), np.nan) for name in OBSERVABLES}
    t_start = time.monotonic()
    for c, case in enumerate(cases):
        ref = reference(case)
        for name in OBSERVABLES:
            refs[name][c] = getattr(ref, name)
        for k, integrator in enumerate(settings.integrators):
            limit[c, k] = scene(case, integrator).bound.dt_limit
            for f, fraction in enumerate(fractions):
                dt[c, k, f] = fraction * limit[c, k]
                outcome, steps[c, k, f] = measure(case, integrator, dt[c, k, f])
                for name in OBSERVABLES:
                    out[name][c, k, f] = getattr(outcome, name)
                wall[c, k, f] = wall_time(case, integrator, dt[c, k, f], steps[c, k, f],
                                          settings.repeats)
            log.info("collisions: %s %s done (%d of %d), %.0f s", case.name, integrator,
                     c * len(settings.integrators) + k + 1,
                     len(cases) * len(settings.integrators), time.monotonic() - t_start)
    dims = ("case", "integrator", "dt_fraction")
    data = {
        "contact": (("case",), [c.contact for c in cases],
                    {"long_name": "edge: a square's edge on the plate; corner: a 90 degree corner"}),
        "damping": (("case",), [c.damping for c in cases],
                    {"units": "1", "long_name": "normal damping coefficient gamma"}),
        "friction": (("case",), [c.friction for c in cases],
                     {"units": "1", "long_name": "Coulomb friction coefficient mu"}),
        "dt_limit": (dims[:2], limit, {"units": "s", "long_name":
                                       "stability limit of the time-step rule for the pair"}),
        "dt": (dims, dt, {"units": "s", "long_name": "time step"}),
        "steps": (dims, steps, {"units": "1", "long_name": "steps from start to separation"}),
        "wall_time": (dims, wall, {"units": "s", "long_name":
                                   "wall time of Simulation.run per collision (median)"}),
    }
    for name, (units, long_name, kind) in OBSERVABLES.items():
        data[name] = (dims, out[name], {"units": units, "long_name": f"measured {long_name}"})
        data[f"reference_{name}"] = (("case",), refs[name], {
            "units": units, "long_name": f"{long_name}, solve_ivp reference (rtol 1e-12)"})
        data[f"error_{name}"] = (dims, error(out[name], refs[name][:, None, None], kind), {
            "units": "1", "long_name": f"{kind} error of the {long_name}"})
    return xr.Dataset(data, coords={
        "case": ("case", [c.name for c in cases], {"long_name": "collision case"}),
        "integrator": ("integrator", list(settings.integrators), {"long_name": "integrator"}),
        "dt_fraction": ("dt_fraction", fractions, {
            "units": "1", "long_name": "time step over the stability limit dt_limit"}),
    })


def observed_order(dt, err, floor=1e-10):
    """Least-squares slope of ``log err`` against ``log dt`` over the finer half of the steps.

    Points with ``err <= floor`` (the reference's accuracy) are left out; NaN
    with fewer than three points.
    """
    dt = np.asarray(dt)
    err = np.asarray(err)
    order = np.argsort(dt)
    dt, err = dt[order], err[order]
    keep = np.arange(len(dt)) < max(3, (len(dt) + 1) // 2)
    keep &= err > floor
    if keep.sum() < 3:
        return math.nan
    return float(np.polyfit(np.log(dt[keep]), np.log(err[keep]), 1)[0])


def time_to_reach(wall, err, target):
    """Least wall time after which every finer step keeps the error at or below ``target``.

    ``wall`` and ``err`` are ordered from the largest step down; NaN if even
    the finest step misses the target.
    """
    ok = np.asarray(err) <= target
    if not ok[-1]:
        return math.nan
    first = len(ok) - int(np.argmin(ok[::-1])) if not ok.all() else 0
    return float(np.asarray(wall)[first])


def table(ds: xr.Dataset, target: float) -> str:
    """Markdown table: per case, observable and integrator the error at the
    stability limit and at the smallest step, the observed order and the wall
    time per collision needed for an error of ``target``."""
    lines = [
        f"| case | observable | integrator | error at dt_limit | error at "
        f"{float(ds.dt_fraction[-1]):.2g} dt_limit | order | steps at dt_limit | "
        f"µs per collision for error ≤ {target:.0e} |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for case in ds.case.values:
        for name in OBSERVABLES:
            for integrator in ds.integrator.values:
                sel = ds.sel(case=case, integrator=integrator)
                err = sel[f"error_{name}"].values
                t = time_to_reach(sel.wall_time.values, err, target)
                lines.append(
                    f"| {case} | {name} | {integrator} | {err[0]:.2e} | {err[-1]:.2e} | "
                    f"{observed_order(sel.dt.values, err):.2f} | {int(sel.steps[0])} | "
                    f"{'–' if math.isnan(t) else f'{1e6 * t:.0f}'} |")
    return "\n".join(lines) + "\n"


def _draw(ds, path):
    from .figures import collision_figure  # matplotlib only when drawing
    collision_figure(ds, path)


def main(argv=None):
    """``python -m sim numerics collisions``: sweep, then write data, figure and table."""
    run_numerics_check("collisions", __doc__.split("\n\n")[0], argv, CollisionSettings, sweep,
                       "Binary collisions: error against wall time", _draw,
                       lambda ds, settings: table(ds, settings.target_error))
    return 0
