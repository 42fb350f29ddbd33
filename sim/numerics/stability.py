"""Stability on stiff and extreme cases, and the largest stable time step.

**The suite.**  Each case is a small scene (:data:`CASES`): stiffness from
1e5 to 1e10 N/m, size ratio 1:20, aspect ratio 1:5, 3 and 32 corners, nearly
degenerate shapes (an edge of 0.2 % of the diameter, a 178° corner), impacts
at 10 m/s, a deep initial overlap, a jammed box, μ = 0 and 2, γ = 0, critical
and over-critical damping (a packing, and a single contact at ζ = 10).  The jammed box is made by placing the particles on
a lattice narrower than their diameters between fixed walls (the engine has
no moving walls), so they start compressed.  Each case either runs with the
automatic time step, closed and undriven, for ``steps`` steps and must stay
*stable*: finite, no :class:`sim.engine.BlowUpError`, overlaps below
``model.max_overlap_fraction`` and a total energy (kinetic + gravitational +
elastic) that never rises above its start by more than ``energy_tolerance``
of the energy scale (start kinetic + elastic + ``Σ m |g| R``); the start's
elastic energy counts with its uncertainty
(:data:`sim.engine.ELASTIC_UNDERESTIMATE`); or it is
*refused* before it runs by the simulator, with the message it gives.
Anything else is *unstable*, a bug in the time-step rule or the detector.

**The largest stable step.**  For each stiffness and integrator, two scenes
are run with a given ``dt`` (beyond the rule's limit too; the refusal of
:func:`sim.timestep.choose_dt` is bypassed for this measurement only) and the
largest ``dt`` that stays stable over ``search_steps`` steps is bracketed by
bisection in ``log dt``:

* ``linear_spring``: a square resting flat on the support, no rotation, no
  damping or friction: a linear spring ``k = Y L / l`` (``L`` the edge,
  ``l = r`` half the side), so the theory is ``h*(0) / sqrt(k/m)`` with
  :func:`sim.integrators.stability_limit` (Gear 0.313, Verlet 2);
* ``packing``: the ``stiffness`` case, twelve of the paper's particles in a box.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, replace

import numpy as np
import xarray as xr

from ..config import ConfigError, ModelParams, check_number
from ..engine import ELASTIC_UNDERESTIMATE, BlowUpError, Simulation
from ..integrators import INTEGRATORS, stability_limit
from ..shapes import make_shapes
from .command import run_numerics_check, settings_from_dict
from .polygons import centred, ellipse_polygon, rectangle, regular_polygon, shapes_of

log = logging.getLogger("sim.numerics")

#: Mean semi-axis of the paper's particles, m.
SIZE = 3.4e-3


@dataclass
class Scene:
    """A scene before it is simulated.

    Attributes
    ----------
    shapes : sim.shapes.Shapes
    states : list of tuple
        ``(x, y, theta, vx, vy, omega)`` per particle.
    model : ModelParams
    gravity : tuple
    support : bool
    walls : tuple or None
    rotate : bool
    """

    shapes: object
    states: list
    model: ModelParams
    gravity: tuple = (0.0, -9.81)
    support: bool = True
    walls: tuple | None = None
    rotate: bool = True

    def simulation(self, dt=None):
        """The :class:`Simulation` with the particles placed.

        ``dt`` given: that step is used even above the stability limit (the
        largest-stable-step search needs it; the model's own ``dt`` rule is
        bypassed by setting the step before any particle is placed).
        """
        sim = Simulation(self.shapes, self.model, gravity=self.gravity, support=self.support,
                         walls=self.walls, rotate=self.rotate)
        if dt is not None:
            sim.dt = float(dt)
        for k, state in enumerate(self.states):
            sim.place(k, *state)
        return sim


def _box(polygons, spacing, columns, rng, speed=0.05, **model):
    """Polygons on a square lattice of ``spacing`` in a box on the support.

    Walls half a spacing beyond the outer columns; random orientations and
    velocities up to ``speed`` (m/s).  A spacing below the particles'
    diameters starts them compressed against each other and the walls.
    """
    n = len(polygons)
    width = columns * spacing
    states = []
    for k in range(n):
        row, col = divmod(k, columns)
        states.append((-0.5 * width + (col + 0.5) * spacing, (row + 0.5) * spacing,
                       rng.uniform(0, 2 * np.pi), *rng.uniform(-speed, speed, 2),
                       rng.uniform(-speed, speed) / spacing))
    return Scene(shapes_of(*polygons), states, ModelParams(**model),
                 walls=(-0.5 * width, 0.5 * width))


def _paper_polygons(n, seed):
    """``n`` of the paper's particles (6-8 corners, 3.4 mm ± 30 %)."""
    shapes = make_shapes(np.random.default_rng(seed), n)
    return [tuple(np.array(a) for a in shapes.corners(i)) for i in range(n)]


def packing(youngs_modulus=1.0e7, spacing=0.95, seed=1, **model):
    """Twelve paper particles, 4 columns, lattice ``spacing`` × mean circumdiameter."""
    polygons = _paper_polygons(12, seed)
    d = 2 * np.mean([np.max(np.hypot(*p)) for p in polygons])
    return _box(polygons, spacing * d, 4, np.random.default_rng(seed),
                youngs_modulus=youngs_modulus, **model)


#: Compression of the linear spring's square by each wall, fraction of its half side.
SPRING_COMPRESSION = 1e-3


def linear_spring(youngs_modulus=1.0e7, integrator="gear"):
    """A square of side 2·SIZE squeezed between two walls, oscillating sideways.

    Zero gravity, no support, no rotation, damping or friction: each wall is
    a linear spring (:func:`linear_spring_stiffness`) that never opens, since
    the oscillation's amplitude is a tenth of the static compression (Verlet
    enlarges the amplitude of positions by ``ω dt / sin θ`` with
    ``cos θ = 1 − (ω dt)²/2``, tenfold only at 0.995 of its limit).  The square
    starts at the equilibrium, where the engine's starting acceleration (zero,
    free flight) is exact.
    """
    sq = rectangle(2 * SIZE, 2 * SIZE)
    shapes = shapes_of(sq)
    model = ModelParams(youngs_modulus=youngs_modulus, damping=0.0, friction=0.0,
                        support_friction=0.0, integrator=integrator)
    depth = SPRING_COMPRESSION * SIZE
    omega = math.sqrt(2 * linear_spring_stiffness(youngs_modulus) / shapes.mass[0])
    return Scene(shapes, [(0.0, 0.0, 0.0, 0.1 * depth * omega, 0.0, 0.0)], model,
                 gravity=(0.0, 0.0), support=False, walls=(-SIZE + depth, SIZE - depth),
                 rotate=False)


def linear_spring_stiffness(youngs_modulus):
    """``k = Y L / l`` of an edge ``L = 2 SIZE`` on a wall, ``l = r = SIZE (1 − compression)``."""
    return youngs_modulus * 2 * SIZE / (SIZE * (1 - SPRING_COMPRESSION))


def linear_spring_limit(youngs_modulus, integrator):
    """Theoretical stability limit ``h*(0) / ω`` of :func:`linear_spring`, ``ω² = 2k/m``, s."""
    shapes = shapes_of(rectangle(2 * SIZE, 2 * SIZE))
    omega = math.sqrt(2 * linear_spring_stiffness(youngs_modulus) / shapes.mass[0])
    return stability_limit(integrator, 0.0) / omega


def _nearly_degenerate(edge_fraction, flat_angle_deg):
    """A heptagon with one edge of ``edge_fraction`` of its diameter and one
    corner of interior angle ``flat_angle_deg``."""
    x, y = regular_polygon(6, SIZE)
    # split corner 0 into two corners an edge_fraction of the diameter apart
    half = edge_fraction * SIZE
    pts = [(x[0], y[0] - half), (x[0], y[0] + half)] + list(zip(x[1:], y[1:]))
    # push the midpoint of the edge between corners 3 and 4 out to the given angle
    a, b = np.array(pts[3]), np.array(pts[4])
    mid = 0.5 * (a + b)
    out = mid / np.linalg.norm(mid)
    bulge = 0.5 * np.linalg.norm(b - a) * math.tan(math.radians(90 - flat_angle_deg / 2))
    pts.insert(4, tuple(mid + bulge * out))
    return centred(*np.array(pts).T)


def _size_ratio(ratio=20.0, speed=0.5):
    """A hexagon on the support; two hexagons ``ratio`` times smaller hit its
    top edge and its side corner at ``speed``."""
    big, small = 5e-3, 5e-3 / ratio
    h = big * math.sin(math.pi / 3)
    hs = small * math.sin(math.pi / 3)
    states = [(0.0, h, 0.0, 0.0, 0.0, 0.0),
              (0.2 * big, 2 * h + hs, 0.0, 0.0, -speed, 0.0),
              (-big - small, h, 0.0, speed, 0.0, 0.0)]
    polygons = [regular_polygon(6, big), regular_polygon(6, small), regular_polygon(6, small)]
    return Scene(shapes_of(*polygons), states, ModelParams())


def _stacked_elongated(aspect=5.0, layers=3):
    """Octagons in ``aspect``:1 ellipses lying flat on each other and the support,
    each pressed 2 % of its thickness into the one below."""
    a, b = 5e-3, 5e-3 / aspect
    poly = ellipse_polygon(8, a, b)
    thick = float(np.max(poly[1]))   # half thickness: corners at ±b on the minor axis
    states = [(0.1 * a * k, thick * (1 + 2 * k) * 0.98, 0.0, 0.0, 0.0, 0.0)
              for k in range(layers)]
    return Scene(shapes_of(*[poly] * layers), states, ModelParams())


def _impact(speed, **model):
    """A paper particle hitting the support and one hitting a resting particle, at ``speed``."""
    polygons = _paper_polygons(3, 2)
    r = [np.max(np.hypot(*p)) for p in polygons]
    states = [(0.0, r[0] + 1e-4, 0.3, 0.0, -speed, 0.0),
              (0.03, r[1], 0.0, 0.0, 0.0, 0.0),
              (0.03, 2 * r[1] + r[2] + 1e-4, 1.1, 0.0, -speed, 0.0)]
    return Scene(shapes_of(*polygons), states, ModelParams(**model))


def _deep_overlap(fraction):
    """Two squares overlapping edge-on-edge by ``fraction`` of their area, at rest."""
    sq = rectangle(2 * SIZE, 2 * SIZE)
    gap = 2 * SIZE * (1 - fraction)
    return Scene(shapes_of(sq, sq), [(0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
                                     (gap, 0.1 * SIZE, 0.0, 0.0, 0.0, 0.0)],
                 ModelParams(damping=0.0, friction=0.0), gravity=(0.0, 0.0), support=False)


def _overdamped_spring(damping):
    """:func:`linear_spring` with normal damping γ (its contacts' ζ = γ sqrt(L/l) / 2)."""
    scene = linear_spring()
    scene.model = replace(scene.model, damping=damping)
    return scene


def _critical_damping():
    """γ making the rule's stiffest normal mode critically damped, ζ⊥ = (γ/2) sqrt(L/l) = 1."""
    sim = packing().simulation()
    ratio = (sim.bound.zeta_normal / (0.5 * sim.model.damping)) ** 2
    return 2.0 / math.sqrt(ratio)


def _case_builders():
    """Name → (description, function returning a :class:`Scene`) of every suite case
    other than the stiffness ones."""
    rng = np.random.default_rng
    return {
        "size_ratio_20": ("hexagons of circumradius 5 mm and 0.25 mm (1:20), impacts at "
                          "0.5 m/s", _size_ratio),
        "aspect_ratio_5": ("three octagons in 5:1 ellipses stacked flat, long edges in contact",
                           _stacked_elongated),
        "corners_3": ("equilateral triangles", lambda: _box(
            [regular_polygon(3, SIZE)] * 9, 1.9 * SIZE, 3, rng(5))),
        "corners_32": ("32-gons", lambda: _box(
            [regular_polygon(32, SIZE)] * 9, 1.95 * SIZE, 3, rng(6))),
        "nearly_degenerate": ("an edge of 0.2 % of the diameter and a 178° corner", lambda: _box(
            [_nearly_degenerate(2e-3, 178.0)] * 9, 1.95 * SIZE, 3, rng(7))),
        "degenerate_refused": ("a 179.8° corner (beyond the shapes' 179° limit)", lambda: _box(
            [_nearly_degenerate(2e-3, 179.8)] * 4, 2.1 * SIZE, 2, rng(8))),
        "impact_10_m_s": ("10 m/s onto the support and onto a particle", lambda: _impact(10.0)),
        "deep_overlap": ("two squares overlapping by 15 % of their area, undamped",
                         lambda: _deep_overlap(0.15)),
        "jammed_box": ("packing on a lattice 0.8 of the mean diameter between walls",
                       lambda: packing(spacing=0.8)),
        "friction_zero": ("packing with mu = 0", lambda: packing(friction=0.0,
                                                                 support_friction=0.0)),
        "friction_2": ("packing with mu = 2", lambda: packing(friction=2.0,
                                                              support_friction=2.0)),
        "damping_zero": ("packing with gamma = 0", lambda: packing(damping=0.0)),
        "damping_critical": ("packing, stiffest normal mode critically damped",
                             lambda: packing(damping=_critical_damping())),
        "damping_overcritical": ("packing with gamma = 10", lambda: packing(damping=10.0)),
        "spring_overcritical": ("the linear spring (a square between walls) with gamma = 10, "
                                "zeta = 10", lambda: _overdamped_spring(10.0)),
        "dt_above_limit": ("packing with model.dt twice Verlet's (the larger) limit",
                           lambda: packing(dt=2 * packing(integrator="verlet").simulation()
                                           .bound.dt_limit)),
    }


CASE_NAMES = tuple(_case_builders())


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
            check_number(s, "stiffness[]", y, lo=1e3, hi=1e12)
        unknown = sorted(set(self.cases) - set(CASE_NAMES))
        if unknown:
            raise ConfigError(f"{s}.cases: unknown case(s) {unknown}; known: {list(CASE_NAMES)}")
        check_number(s, "steps", self.steps, lo=10, integer=True)
        check_number(s, "search_steps", self.search_steps, lo=10, integer=True)
        check_number(s, "search_resolution", self.search_resolution, lo=1e-4, hi=1,
                      lo_open=True)
        check_number(s, "energy_tolerance", self.energy_tolerance, lo=0, hi=1, lo_open=True)
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
        builders = _case_builders()
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
        scene = builder()
        scene.model = replace(scene.model, integrator=integrator)
        sim = scene.simulation()
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


def largest_stable_dt(scene, steps, tolerance, resolution, oscillator=False):
    """Largest stable step of a scene, bracketed by bisection in log dt.

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
    lo = scene.simulation().dt

    def stable(dt):
        res = run_stable(scene.simulation(dt), steps, tolerance)
        return res.status == "stable" and not (oscillator and
                                                res.energy_growth > ENERGY_GROWTH)

    if not stable(lo):
        return math.nan
    hi = 2 * lo
    while stable(hi):
        lo, hi = hi, 2 * hi
        if hi > 1e3 * scene.simulation().bound.dt_limit:
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
                scene = (linear_spring(ym, integrator) if scene_name == "linear_spring" else
                         packing(youngs_modulus=ym, integrator=integrator))
                sim = scene.simulation()
                rule[s, k, y], auto[s, k, y] = sim.bound.dt_limit, sim.dt
                if scene_name == "linear_spring":
                    theory[s, k, y] = linear_spring_limit(ym, integrator)
                found[s, k, y] = largest_stable_dt(scene, settings.search_steps,
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
