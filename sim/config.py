"""Run parameters of the simulator, with validation and defaults.

Every parameter that changes between runs lives here and is passed to the
kernels as an argument; nothing is a module global that Numba could freeze into
compiled code.

The defaults and the allowed values (bounds, integers, choices) are not
written here: they are read, when this module is imported, from the one place
that holds them, the sections ``model``, ``particles``, ``pour``, ``relax``,
``probe`` and ``physics`` of ``sim/config.schema.yaml`` (:data:`SCHEMA_FILE`),
which ships inside the package and which the workflow's configuration schema
refers to, so the command line and the workflow agree by construction
(tests/test_settings_single_source.py probes it).  Each dataclass below names
a section's settings and their types; :func:`_settings` gives each its
default from the schema and refuses a class whose fields are not the section's
settings.  Every setting is checked against the schema by jsonschema
(:func:`check_setting`, the simulator's one schema checker on
:mod:`sim.schema`, which also serves :mod:`sim.numerics`).  What a
schema cannot express (``corners_max >= corners_min``, ``hold_time <=
max_time``, the walls' order and spacing) is checked in the dataclasses below.

Units are SI in two dimensions: lengths in m, masses in kg, the particle
Young's modulus in N/m, 2D densities in kg/m².
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from .schema import BOUND_OPS, bounds_text, is_real, number_kind, schema_error, schema_types


class ConfigError(ValueError):
    """A setting has a wrong type or a value outside what is allowed."""


#: Settings that change how a run reports and saves its progress, never its
#: result: a checkpoint made under other values is resumed, and the workflow
#: passes them outside the rule params so that changing them re-runs nothing.
BOOKKEEPING = {"pour": ("checkpoint_interval", "progress_interval", "frame_interval")}

#: The settings sections of a configuration the simulator reads (the fields of :class:`SimConfig`).
SECTIONS = ("model", "particles", "pour", "relax", "probe", "physics")

#: The sections each stage's run reads, the one map of them (docs/workflow.md): the
#: pour makes the particles and the physics; relax and probe take those from the state
#: they start from (a changed ``physics`` re-pours, so it reaches them through it).
STAGE_SECTIONS = {"pour": ("model", "particles", "pour", "physics"),
                  "relax": ("model", "pour", "relax"),
                  "probe": ("model", "pour", "relax", "probe")}

#: Settings added after the study's piles were poured (issue 44), each at its
#: default doing what the code did before it: at their default they are left
#: out of the result settings (:func:`result_settings`), so those piles keep
#: their pour digest and the workflow re-runs none of them.
LATER_SETTINGS = {"particles": ("aspect_ratio",),
                  "pour": ("point_source", "outlet_width", "outlet_height", "line_source",
                           "table_slope_deg"),
                  "physics": ("rough_base", "rough_base_slope_deg")}

#: The JSON schema (YAML) of the simulator's sections of a configuration: the
#: source of every default and bound of the simulator's settings.
SCHEMA_FILE = Path(__file__).resolve().parent / "config.schema.yaml"

_SCHEMA = yaml.safe_load(SCHEMA_FILE.read_text(encoding="utf-8"))

#: What each list setting must be, in words, for the message when it is not a
#: list or has the wrong length (:func:`check_setting`).
LIST_SHAPES = {"probe.levels": "a list of numbers in (0, 1) (empty: no gravity probe)",
               "probe.tilts": "a list of numbers in (0, 0.5) (empty: no tilted probe)",
               "physics.walls": "null or [x_left, x_right] in m"}


def setting_schema(section: str, name: str) -> dict:
    """The schema of the setting ``section.name`` (type, bounds, default, ...).

    Parameters
    ----------
    section, name : str
        E.g. ``"particles"``, ``"corners_max"``.

    Returns
    -------
    dict
        The setting's entry of :data:`SCHEMA_FILE` (do not modify it).
    """
    try:
        return _SCHEMA["$defs"][section]["properties"][name]
    except KeyError:
        raise KeyError(f"{section}.{name} is not a setting of {SCHEMA_FILE}") from None


def setting_bounds(schema: dict) -> dict:
    """The bounds of a numeric schema.

    Parameters
    ----------
    schema : dict
        A numeric setting's schema (e.g. from :func:`setting_schema`).

    Returns
    -------
    dict
        ``lo``, ``hi`` (None when unbounded), ``lo_open`` and ``hi_open``.
    """
    for a, b in (("minimum", "exclusiveMinimum"), ("maximum", "exclusiveMaximum")):
        if a in schema and b in schema:
            raise ValueError(f"a setting's schema gives both {a} and {b}: {schema}")
    return {"lo": schema.get("minimum", schema.get("exclusiveMinimum")),
            "hi": schema.get("maximum", schema.get("exclusiveMaximum")),
            "lo_open": "exclusiveMinimum" in schema,
            "hi_open": "exclusiveMaximum" in schema}


def check_setting(key: str, value: Any, schema: dict, shape: str | None = None) -> None:
    """The simulator's check of one setting against its JSON schema.

    Parameters
    ----------
    key : str
        The setting's dotted name, for the message (``"model.friction"``).
    value : object
        Its value.
    schema : dict
        Its schema (:func:`setting_schema`, or one written for the setting).
    shape : str, optional
        For a list: what it must be, in words, when it is not a list or has
        the wrong length.

    Raises
    ------
    ConfigError
        ``KEY = VALUE: must be ...``: one of the ``enum``, true or false, a
        number or an integer, finite, within the bounds (all named), a string;
        for a list the shape, an item (``KEY[] = ITEM: ...``), or unique.
    """
    error = schema_error(value, schema)
    if error is None:
        return
    if error.relative_path:
        key, value, schema = f"{key}[]", error.instance, error.schema
    elif error.validator == "uniqueItems":
        raise ConfigError(f"{key} = {list(value)!r}: must be unique")
    elif "array" in schema_types(schema):
        raise ConfigError(f"{key} = {value!r}: must be {shape}")
    kinds = schema_types(schema)
    if "enum" in schema:
        allowed = "one of " + ", ".join(repr(c) for c in schema["enum"])
    elif "boolean" in kinds:
        allowed = "true or false"
    elif "number" not in kinds and "integer" not in kinds:
        allowed = "a string"
    elif error.validator in BOUND_OPS:
        allowed = bounds_text(schema)
    elif not is_real(value) or (number_kind(schema) == "an integer"
                                 and not isinstance(value, int)):
        allowed = number_kind(schema)
    else:
        allowed = "finite"
    raise ConfigError(f"{key} = {value!r}: must be {allowed}")


def _default(section: str, name: str) -> Any:
    """The schema default of ``section.name`` (a list as a tuple: dataclass defaults are
    immutable)."""
    value = setting_schema(section, name)["default"]
    return tuple(value) if isinstance(value, list) else value


def _check_fields(params: Any, section: str) -> None:
    """Check every field of the dataclass ``params`` against the schema of ``section``
    (:func:`check_setting`, in the order of the fields)."""
    for f in dataclasses.fields(params):
        key = f"{section}.{f.name}"
        check_setting(key, getattr(params, f.name), setting_schema(section, f.name),
                      LIST_SHAPES.get(key))


def _settings(section: str):
    """The decorated class as the frozen dataclass of the settings of ``section``: a field
    for each annotation, whose default is the setting's default in the schema
    (:func:`_default`).

    The class names the settings and their types; their defaults and bounds are
    the schema's alone.  A field that is no setting of ``section``, or a setting
    without a field, is refused when this module is imported (:class:`TypeError`).
    """
    def make(cls):
        fields, settings = set(cls.__annotations__), set(_SCHEMA["$defs"][section]["properties"])
        if fields != settings:
            raise TypeError(f"{cls.__name__}: fields {sorted(fields - settings)} are no settings of "
                            f"{section} in {SCHEMA_FILE}, and settings {sorted(settings - fields)} "
                            "have no field")
        for name in cls.__annotations__:
            setattr(cls, name, _default(section, name))
        return dataclass(frozen=True)(cls)
    return make


@_settings("model")
class ModelParams:
    """Contact law, material and integration parameters.

    Attributes
    ----------
    youngs_modulus : float
        Particle Young's modulus Y in N/m (2D), F⊥ = Y·A/l (paper, Appendix).
    damping : float
        Dimensionless normal damping coefficient γ of the Appendix.
    friction : float
        Coulomb coefficient μ between particles (static = dynamic).
    support_friction : float
        Coulomb coefficient between particles and the support and walls.
    density : float
        2D mass density in kg/m² (mass = density × polygon area).
    integrator : str
        ``"gear"`` (5th-order Gear predictor–corrector, the paper's) or
        ``"verlet"`` (velocity Verlet).
    dt : float or None
        Time step in s; ``None`` selects it by the rule of :mod:`sim.timestep`.
    dt_safety : float
        Fraction of the integrator's stability limit that the automatic rule
        uses, and beyond which a given ``dt`` is refused.
    max_overlap_fraction : float
        Blow-up detector: an overlap area above this fraction of the smaller
        particle's area stops the run.
    """

    youngs_modulus: float
    damping: float
    friction: float
    support_friction: float
    density: float
    integrator: str
    dt: float | None
    dt_safety: float
    max_overlap_fraction: float

    def __post_init__(self):
        _check_fields(self, "model")


@_settings("particles")
class ParticleParams:
    """How particle shapes are drawn (paper, Section 3.1).

    Attributes
    ----------
    corners_min, corners_max : int
        Range of the corner count, drawn uniformly.
    semi_axis_mean : float
        Mean semi-axis of the circumscribing ellipse in m (3.4 mm in the paper).
    semi_axis_spread : float
        Both semi-axes are uniform in ``mean·(1 ± spread)`` (0.3 in the paper).
    min_edge_fraction : float
        Shortest allowed edge as a fraction of the smaller ellipse diameter.
    min_angle_deg : float
        Interior angles must lie in ``[min_angle_deg, 180 - min_angle_deg]``.
    aspect_ratio : float or None
        ``None``: the semi-axes as above (the paper's draw).  A number ``r``:
        one size ``s`` uniform in ``mean·(1 ± spread)`` and the semi-axes
        ``s·√r`` and ``s/√r`` (:func:`sim.shapes.make_shapes`).
    """

    corners_min: int
    corners_max: int
    semi_axis_mean: float
    semi_axis_spread: float
    min_edge_fraction: float
    min_angle_deg: float
    aspect_ratio: float | None

    def __post_init__(self):
        _check_fields(self, "particles")
        if self.corners_max < self.corners_min:
            raise ConfigError(f"particles.corners_max = {self.corners_max}: must be >= "
                              f"particles.corners_min = {self.corners_min}")


@_settings("pour")
class PourParams:
    """Pouring protocols (wedge: point source; layered: line source).

    Attributes
    ----------
    n_particles : int
        Particles to pour.
    rate : float
        Release rate in particles per second.
    release_height : float
        Height of the release point above the current top of the pile, m.
    release_speed : float
        Downward speed given to a released particle, m/s.
    spin_drag : float
        Drag on the rotation alone while pouring, 1/s (``−spin_drag·I·ω``).
    jitter : float
        Half-width of the uniform horizontal jitter of the point source, m.
    line_margin : float
        Layered sequence: extra length on each side of the measured top width, m.
    top_band : float
        Layered sequence: the top width is the horizontal extent of the settled
        particles whose tops lie within this band below the pile's top, m.
    layered_slope_deg : float
        Layered sequence: the line never extends beyond the flanks of a pile
        of this slope, in degrees (below the angle of repose).
    point_source : {"drip", "funnel"}
        Wedge sequence: one particle at a time from a point, or a 2D hopper
        outlet at the Beverloo flux (:mod:`sim.release`).
    outlet_width : float
        Funnel: outlet width in mean particle diameters.
    outlet_height : float
        Funnel: outlet height above the tip in mean particle diameters.
    line_source : {"top", "rain", "table"}
        Layered sequence: a line as wide as the measured top, a rain over
        the plateau of the target pile, or a rain over a finite table whose
        leavers are removed (:mod:`sim.release`).
    table_slope_deg : float
        Table: the slope of the pile whose base is the table (:func:`sim.release.table_half_width`).
    checkpoint_interval : float
        Wall-clock seconds between checkpoints.
    progress_interval : float
        Wall-clock seconds between progress lines.
    frame_interval : float
        Simulated seconds between the frames of a pour's film (``pour --frames``).
    """

    n_particles: int
    rate: float
    release_height: float
    release_speed: float
    spin_drag: float
    jitter: float
    line_margin: float
    top_band: float
    layered_slope_deg: float
    point_source: str
    outlet_width: float
    outlet_height: float
    line_source: str
    table_slope_deg: float
    checkpoint_interval: float
    progress_interval: float
    frame_interval: float

    def __post_init__(self):
        _check_fields(self, "pour")


@_settings("relax")
class RelaxParams:
    """Criterion for "at rest" and the cap on relaxation time.

    Attributes
    ----------
    kinetic_energy_fraction : float
        Mean kinetic energy per particle must fall below this fraction of
        ``m g d`` (mean mass, gravity, mean diameter).
    max_speed : float
        No particle may move faster than this, m/s.
    unbalanced_force : float
        The unbalanced force, the sum over particles of the magnitude of
        contact force plus gravity, must fall below this fraction of the
        weight.  It bounds the error of every balance law of the state (the
        support reaction against the weight, Love's sum rule), which kinetic
        energy alone does not: a pile can pass the energy criterion while
        still ringing.  After a gravity probe all three criteria apply to the
        change of load (:func:`sim.relax.relax`).
    hold_time : float
        The criteria must hold for this long, s.
    max_time : float
        Simulated time after which relaxation fails loudly, s.
    drag : float
        Background damping rate while relaxing, 1/s: every particle feels
        ``−drag·m·v`` and ``−drag·I·ω``.  It shortens the relaxation of the
        pile as a whole; it vanishes at rest, so the static state it leads to
        satisfies the same force balance.  Too strong a drag slows a flank
        that is still flowing to a creep: polygons rolling down a wedge pile
        at its angle of repose reach a terminal speed (3 cm/s at 100/s) and
        take many seconds to reach the foot, while at 20/s the same pile
        (3500 particles) is calm within 0.4 s.  0 turns it off.
    rocking_drag : float
        Drag used instead of ``drag`` once the kinetic-energy criterion holds,
        1/s.  The contact law leaves a polygon rocking on an edge undamped,
        and since the elastic force acts at the midpoint of the contact line,
        whose distance from the centre changes as the polygon tilts, it is not
        conservative: an isolated polygon on the support can keep rocking (a
        limit cycle with speeds of a few mm/s that 20/s of drag does not stop
        and 100/s does).  The switch comes after the pile itself is calm, so
        it cannot freeze a flowing flank.
    drag_time : float
        Simulated time after which ``rocking_drag`` takes over even if the
        kinetic-energy criterion does not hold yet, s.  In a small pile a
        single rocking polygon keeps the mean kinetic energy above the
        criterion, so without this cap the switch would never come.
    """

    kinetic_energy_fraction: float
    max_speed: float
    unbalanced_force: float
    hold_time: float
    max_time: float
    drag: float
    rocking_drag: float
    drag_time: float

    def __post_init__(self):
        _check_fields(self, "relax")
        if self.hold_time > self.max_time:
            raise ConfigError(f"relax.hold_time = {self.hold_time!r}: must be <= "
                              f"relax.max_time = {self.max_time!r} (the rest criteria "
                              "could never hold long enough)")


@_settings("probe")
class ProbeParams:
    """The gravity probe: lower gravity by each level Δ and relax again.

    Attributes
    ----------
    levels : tuple of float
        Relative gravity reductions Δ, each in (0, 1); the first one's stage is
        called ``reduced``.  Empty: the scene has no gravity probe.
    tilts : tuple of float
        Tilted-gravity probes δ, each in (0, 0.5): gravity gets a horizontal
        component ±δ g0 (stages ``tiltpNN``, ``tiltmNN``).
    restore : bool
        Restore full gravity after the first reduction (stage ``restored``).
    mode : str
        ``"step"`` changes gravity at once, ``"ramp"`` linearly over ``ramp_time``.
    ramp_time : float
        Duration of the ramp, s.
    stretch : float
        Strain of the support-stretch probe (stage ``stretched``,
        :func:`sim.probe.stretch_file`), in (−0.01, 0.01); 0: none.
    stretch_time : float
        Duration of the stretch, s.
    """

    levels: tuple
    tilts: tuple
    restore: bool
    mode: str
    ramp_time: float
    stretch: float
    stretch_time: float

    def __post_init__(self):
        _check_fields(self, "probe")
        for key in ("levels", "tilts"):
            object.__setattr__(self, key, tuple(float(v) for v in getattr(self, key)))
        if self.restore and not self.levels:
            raise ConfigError("probe.restore = true with probe.levels = []: restoring "
                              "gravity needs a gravity reduction first (give a level)")


@_settings("physics")
class PhysicsParams:
    """Which bodies and degrees of freedom a scene has.

    Attributes
    ----------
    support : bool
        The frictional support ``y < 0`` exists (the pile protocols need it).
    walls : tuple of float or None
        ``(x_left, x_right)``: frictional side walls ``x < x_left`` and
        ``x > x_right`` (m), or None for none.
    rotation : bool
        Orientations are integrated; False fixes each particle's orientation
        at the one it was released with.
    rough_base : bool
        Fixed polygons lie on the support (:class:`sim.scene.RoughBase`).
    rough_base_slope_deg : float
        Without walls, the base spans the base of a triangular pile of all
        the particles with flanks at this angle (:func:`sim.pour.rough_base`).
    """

    support: bool
    walls: tuple | None
    rotation: bool
    rough_base: bool
    rough_base_slope_deg: float

    def __post_init__(self):
        _check_fields(self, "physics")
        if self.rough_base and not self.support:
            raise ConfigError("physics.rough_base = True: the base lies on the support, but "
                              "physics.support = False (allowed with a rough base: true)")
        if self.walls is not None:
            if not self.walls[0] < self.walls[1]:
                raise ConfigError(f"physics.walls = {list(self.walls)!r}: x_left must be "
                                  "< x_right")
            object.__setattr__(self, "walls", tuple(float(w) for w in self.walls))


@dataclass(frozen=True)
class SimConfig:
    """All simulator sections of a run configuration."""

    model: ModelParams = field(default_factory=ModelParams)
    particles: ParticleParams = field(default_factory=ParticleParams)
    pour: PourParams = field(default_factory=PourParams)
    relax: RelaxParams = field(default_factory=RelaxParams)
    probe: ProbeParams = field(default_factory=ProbeParams)
    physics: PhysicsParams = field(default_factory=PhysicsParams)

    def __post_init__(self):
        if self.physics.walls is not None:
            width = self.physics.walls[1] - self.physics.walls[0]
            p = self.particles
            largest = 2.0 * p.semi_axis_mean * (1.0 + p.semi_axis_spread)
            stretch = ""
            if p.aspect_ratio is not None:
                largest *= math.sqrt(p.aspect_ratio)
                stretch = " x sqrt(aspect_ratio)"
            if width <= largest:
                raise ConfigError(
                    f"physics.walls = {list(self.physics.walls)!r}: {width:.4g} m apart, "
                    f"but the largest particle is {largest:.4g} m across (2 x "
                    f"particles.semi_axis_mean x (1 + semi_axis_spread){stretch}); the walls "
                    "must be farther apart than that")

    @classmethod
    def from_dict(cls, data: dict | None) -> "SimConfig":
        """Build from a nested dict (missing keys take defaults, unknown keys fail).

        Parameters
        ----------
        data : dict or None
            Mapping of section name to a mapping of settings.

        Returns
        -------
        SimConfig
        """
        data = dict(data or {})
        sections = {}
        for f in dataclasses.fields(cls):
            sub = data.pop(f.name, None) or {}
            if not isinstance(sub, dict):
                raise ConfigError(f"{f.name} = {sub!r}: must be a mapping of settings")
            klass = f.default_factory
            known = {g.name for g in dataclasses.fields(klass)}
            unknown = sorted(set(sub) - known)
            if unknown:
                raise ConfigError(f"{f.name}: unknown setting(s) {unknown}; allowed: "
                                  f"{sorted(known)}")
            sections[f.name] = klass(**sub)
        return cls(**sections)

    def to_dict(self) -> dict:
        """Plain nested dict of all settings (JSON-serialisable)."""
        out = dataclasses.asdict(self)
        out["probe"]["levels"] = list(out["probe"]["levels"])
        out["probe"]["tilts"] = list(out["probe"]["tilts"])
        if out["physics"]["walls"] is not None:
            out["physics"]["walls"] = list(out["physics"]["walls"])
        return out

    def result_dict(self, sections=None) -> dict:
        """The settings that fix a run's result (see :func:`result_settings`)."""
        return result_settings(self.to_dict(), sections)

    def job_params(self, stage: str) -> str:
        """The ``--params`` text of a ``python -m sim STAGE`` job: the settings of
        the sections `stage` reads (:data:`STAGE_SECTIONS`) that fix its result
        (:meth:`result_dict`), as canonical JSON (sorted keys).

        The command line reads it back with :meth:`from_dict`, so the simulator
        writes and reads this text itself. The workflow records it as a rule
        param: a changed setting re-runs exactly the jobs of the stages that
        read its section, and a changed :data:`BOOKKEEPING` setting none
        (those travel in :meth:`job_bookkeeping`).

        Parameters
        ----------
        stage : str
            ``pour``, ``relax`` or ``probe``.

        Returns
        -------
        str
        """
        return json.dumps(self.result_dict(STAGE_SECTIONS[stage]), sort_keys=True)

    def job_bookkeeping(self) -> str:
        """The ``--bookkeeping`` text of a job: the :data:`BOOKKEEPING`
        settings (checkpoint, progress and frame intervals) as JSON, which
        change how a run reports and saves, never its result."""
        return json.dumps({s: {k: getattr(getattr(self, s), k) for k in keys}
                           for s, keys in BOOKKEEPING.items()}, sort_keys=True)


def result_settings(settings: dict, sections=None) -> dict:
    """A settings dict (as :meth:`SimConfig.to_dict`) without its :data:`BOOKKEEPING` keys
    and its :data:`LATER_SETTINGS` at their default.

    Parameters
    ----------
    settings : dict
        Mapping of section name to a mapping of settings.
    sections : iterable of str, optional
        Keep only these sections (default: all).

    Returns
    -------
    dict
        A new dict; sections that are not mappings are kept as they are.
    """
    out = {}
    for section, values in settings.items():
        if sections is not None and section not in sections:
            continue
        drop = BOOKKEEPING.get(section, ())
        later = LATER_SETTINGS.get(section, ())
        out[section] = ({k: v for k, v in values.items()
                         if k not in drop and not (k in later and v == _default(section, k))}
                        if isinstance(values, dict) else values)
    return out
