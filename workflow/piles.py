"""The piles of a configuration: their protocols, seeds and stages, the
paths of their files in the configuration's results folder, and the settings
each simulation job of a pile receives.

The rule files (workflow/rules/*.smk) call these through the names that
workflow/rules/common.smk binds (``pile``, ``probe_stages``, ...). The stage
names and files are those of docs/formats.md#state-files.
"""

import json
import re

from sim.config import BOOKKEEPING, SimConfig, result_settings
from sim.preflight import check_piles
from workflow.validation import SIM_SECTIONS

#: The two protocols the simulator knows, in the workflow's fixed order.
ALL_PROTOCOLS = ("wedge", "layered")
#: Stage names of the probes: the gravity reductions, tilts, the restoring
#: probe and the support stretch.
STAGE_PATTERN = r"reduced|reduced\d\d|tilt[pm]\d\d|restored|stretched"
#: Every stage of a pile.
PILE_STAGE_PATTERN = rf"poured|relaxed|{STAGE_PATTERN}"
#: The support-stretch probe (config probe.stretch) and its own settings: only
#: its job reads them, and only it gets them (:meth:`Piles.probe_sim_params`).
STRETCH_STAGE = "stretched"
STRETCH_KEYS = ("stretch", "stretch_time")
#: The rules that make the stages no probe makes (workflow/rules/pour.smk,
#: relax.smk); rule probe (probe.smk) makes every other stage.
STAGE_RULES = {"poured": "pour", "relaxed": "relax"}


class Unrecorded:
    """A rule param that Snakemake does not record, so that changing it re-runs
    nothing: Snakemake records and compares only params of builtin types.

    Parameters
    ----------
    text : str
        What the param reads as in a shell command.
    """

    def __init__(self, text):
        self.text = text

    def __str__(self):
        return self.text


def tilt_stage(tilt):
    """Stage name of the tilted-gravity probe with horizontal component `tilt` g0.

    Parameters
    ----------
    tilt : float
        Signed tilt, in units of g0.

    Returns
    -------
    str
        ``tiltpNN`` for tilt > 0, ``tiltmNN`` for tilt < 0, NN = round(100 |tilt|).
    """
    return f"tilt{'p' if tilt > 0 else 'm'}{round(100 * abs(float(tilt))):02d}"


def stage_rule(stage):
    """The rule that makes `stage`: ``pour``, ``relax``, or ``probe`` for any
    other stage (the rules' wildcard ``"{stage}"`` included)."""
    return STAGE_RULES.get(stage, "probe")


def probe_input_stage(stage):
    """The stage a probe starts from: ``reduced`` for ``restored``, else ``relaxed``."""
    return "reduced" if stage == "restored" else "relaxed"


#: Piles of more particles than this are not drawn by :meth:`Piles.preflight`
#: (about 0.3 ms a particle: 7 s here, every time the workflow is started).
PREFLIGHT_PARTICLES = 20_000


class Piles:
    """The piles of a validated configuration and where their files lie.

    Parameters
    ----------
    config : dict
        The workflow configuration, validated with its defaults filled in
        (:func:`workflow.validation.validate_config`).
    """

    def __init__(self, config):
        self.config = config
        #: Protocols to run, wedge before layered.
        self.protocols = [p for p in ALL_PROTOCOLS if p in config["protocols"]]
        #: The folder of everything this configuration makes (config
        #: ``results``, relative to the working directory).
        self.results = config["results"]
        #: Flag file written by rule compile_kernels; every simulation rule
        #: takes it as input so that no two jobs compile (and write the Numba
        #: cache) at once.
        self.compiled_flag = self.results_path(".numba/compiled.ok")
        #: The table of the simulation jobs' run times (rule run_times_table, in the report).
        self.run_times_table = self.results_path("run_times.html")

    def seeds(self, protocol):
        """Seeds (ints) of the piles of `protocol`, in config order."""
        return [int(s) for s in self.config["protocols"][protocol]["seeds"]]

    def each(self):
        """(protocol, seed) of every pile, protocol by protocol."""
        return [(p, s) for p in self.protocols for s in self.seeds(p)]

    def results_path(self, path):
        """`path` (e.g. ``"piles/{protocol}/seed{seed}/poured.nc"``) in the results folder."""
        return f"{self.results}/{path}"

    # --- files of a pile -------------------------------------------------

    def pile(self, protocol, seed, stage):
        """Path of a particle-state file (docs/formats.md#state-files)."""
        return self.results_path(f"piles/{protocol}/seed{seed}/{stage}.nc")

    def _job_file(self, folder, protocol, seed, stage, suffix):
        """Path of a file of the job making `stage` in `folder` (``logs``,
        ``benchmarks``): ``{folder}/{rule}/{protocol}/seed{seed}.{suffix}``
        for a pour or relaxation, ``seed{seed}_{stage}`` for a probe."""
        rule = stage_rule(stage)
        job = f"seed{seed}_{stage}" if rule == "probe" else f"seed{seed}"
        return self.results_path(f"{folder}/{rule}/{protocol}/{job}.{suffix}")

    def stage_log(self, protocol, seed, stage):
        """The log with the progress lines of the job making `stage`
        (study_progress.py reads them): the rule's ``log:`` for a relaxation
        or a probe, the pile's :meth:`pour_log` for ``poured``. With the
        wildcards ``"{protocol}", "{seed}"`` and a stage (or ``"{stage}"``)
        it is the pattern the rules name."""
        return self._job_file("logs", protocol, seed, stage, "log")

    def stage_benchmark(self, protocol, seed, stage):
        """The benchmark file (the rule's ``benchmark:``) of the job making
        `stage`, also as a pattern with wildcards as :meth:`stage_log`."""
        return self._job_file("benchmarks", protocol, seed, stage, "tsv")

    def pour_log(self, protocol, seed):
        """The pile's pour log: the lines of every run of its pour that held the
        pour's lock, each run from a line "pour P seed S: started by process
        HOST PID" (the simulator's --log; study_progress.py reads its progress
        lines). Not the pour rule's ``log:``, which holds what one job printed."""
        return self.stage_log(protocol, seed, "poured")

    def pour_checkpoint(self, protocol, seed):
        """Checkpoint of a running pour. Deliberately not a Snakemake output: it
        must survive a killed job so that the re-run resumes from it; the
        simulator deletes it when the pour has finished."""
        return self.results_path(f"piles/{protocol}/seed{seed}/pour.checkpoint.nc")

    def pour_finished(self, protocol, seed):
        """Copy of a finished pour (python -m sim pour --finished; its frames
        beside it, ``pour.finished.frames.nc``). Deliberately not a Snakemake
        output: Snakemake, interrupted while a pour ran, marks the outputs of
        the pour that then finishes incomplete, and its rerun deletes them and
        runs the pour again, which takes this copy instead of pouring. Superseded
        by each pour that finishes, removed by one under other settings or code."""
        return self.results_path(f"piles/{protocol}/seed{seed}/pour.finished.nc")

    def pile_frames(self, protocol, seed):
        """Path of the frames of a pile's pour (python -m sim pour --frames; output film)."""
        return self.results_path(f"piles/{protocol}/seed{seed}/frames.nc")

    def pile_film(self, protocol, seed, ext="mp4"):
        """Path of the film of a pile's pour (python -m analysis film): the MP4,
        or with ext="html" the page holding it that the report shows."""
        return self.results_path(f"films/{protocol}_seed{seed}.{ext}")

    def pile_vtk(self, protocol, seed, stage):
        """Path of the VTK file of one pile state's particles (python -m analysis
        export; its contact network is the same name with _contacts)."""
        return self.results_path(f"vtk/{protocol}_seed{seed}_{stage}.vtu")

    def pile_figure(self, protocol, seed, stage):
        """Path of the picture of one pile state."""
        return self.results_path(f"figures/piles/{protocol}_seed{seed}_{stage}.png")

    # --- stages ----------------------------------------------------------

    def stage_for_level(self, level):
        """Stage name of the gravity probe with reduction `level` (Delta).

        The first level in config probe.levels is the stage ``reduced`` of
        docs/formats.md#stages; any other is reducedNN with NN = round(100 * level).
        """
        levels = [float(x) for x in self.config["probe"]["levels"]]
        if float(level) == levels[0]:
            return "reduced"
        return f"reduced{round(100 * float(level)):02d}"

    def level_for_stage(self, stage):
        """Inverse of :meth:`stage_for_level`, for the probe rule's ``stage`` wildcard.

        Raises
        ------
        ValueError
            When `stage` is no configured gravity probe, naming probe.levels.
        """
        for level in self.config["probe"]["levels"]:
            if self.stage_for_level(level) == stage:
                return float(level)
        raise ValueError(
            f"stage {stage!r} is not a configured gravity probe; "
            f"probe.levels {self.config['probe']['levels']} give {self.probe_stages()}"
        )

    def probe_stages(self):
        """Stage names of all configured gravity probes, in config order."""
        return [self.stage_for_level(level) for level in self.config["probe"]["levels"]]

    def signed_tilts(self):
        """Every tilted probe's tilt (config probe.tilts, each with + and - sign)."""
        return [sign * float(t) for t in self.config["probe"]["tilts"] for sign in (1.0, -1.0)]

    def tilt_stages(self):
        """Stage names of the tilted-gravity probes (config probe.tilts)."""
        return [tilt_stage(t) for t in self.signed_tilts()]

    def stretch_stages(self):
        """The support-stretch probe's stage, if config probe.stretch is not 0."""
        return [STRETCH_STAGE] if float(self.config["probe"]["stretch"]) != 0.0 else []

    def extra_probe_stages(self):
        """The probes beyond the gravity reductions: the tilts, the support
        stretch (probe.stretch) and, with probe.restore, the stage ``restored``
        (full gravity after ``reduced``)."""
        restored = ["restored"] if self.config["probe"]["restore"] else []
        return self.tilt_stages() + self.stretch_stages() + restored

    def probe_change(self, stage):
        """The simulator's options of the probe `stage` (python -m sim probe):
        --level Delta, --tilt +-delta, --stretch epsilon or --restore."""
        if stage == "restored":
            return ["--restore"]
        if stage == STRETCH_STAGE:
            return ["--stretch", repr(float(self.config["probe"]["stretch"]))]
        for tilt in self.signed_tilts():
            if stage == tilt_stage(tilt):
                return ["--tilt", repr(tilt)]
        return ["--level", repr(self.level_for_stage(stage))]

    # --- settings of the simulation jobs ---------------------------------

    def sim_params(self, *sections):
        """The given simulator sections of the config as canonical JSON (sorted keys).

        A simulation job receives only the sections it reads, so a changed
        setting re-runs exactly the jobs that depend on it (pouring reads
        model, particles, pour and physics; relaxing model, pour and relax,
        the physics coming with the poured state; probing also probe). Adding
        a gravity level therefore re-runs only the probes, and a change in
        analysis or protocols no simulation. The bookkeeping settings
        (sim.config.BOOKKEEPING: checkpoint and progress intervals) change no
        result and are left out; they travel in :meth:`sim_bookkeeping`.
        """
        return json.dumps(result_settings({k: self.config[k] for k in sections}), sort_keys=True)

    def probe_sim_params(self, stage):
        """The simulator sections of the probe `stage` as canonical JSON
        (``sim_params("model", "pour", "relax", "probe")``), each probe with only
        its own keys of ``probe``: the support stretch its STRETCH_KEYS, the
        gravity probes all others. So a scene that adds the stretch re-runs no
        gravity probe, and one that adds a tilt no stretch."""
        settings = json.loads(self.sim_params("model", "pour", "relax", "probe"))
        stretch = stage == STRETCH_STAGE
        settings["probe"] = {k: v for k, v in settings["probe"].items() if (k in STRETCH_KEYS) == stretch}
        return json.dumps(settings, sort_keys=True)

    def sim_bookkeeping(self):
        """The bookkeeping settings (sim.config.BOOKKEEPING) as JSON for the
        simulator's --bookkeeping option, an :class:`Unrecorded` param: a changed
        checkpoint or progress interval re-pours no pile."""
        settings = {s: {k: self.config[s][k] for k in keys} for s, keys in BOOKKEEPING.items()}
        return Unrecorded(json.dumps(settings, sort_keys=True))

    # --- targets ---------------------------------------------------------

    def all_stages(self):
        """Every stage of a pile: poured, relaxed and every probe."""
        return ["poured", "relaxed"] + self.probe_stages() + self.extra_probe_stages()

    def final_stages(self):
        """The stages a pile makes last, whose files make it finished: every
        probe (:meth:`all_stages` after ``relaxed``), or ``relaxed`` when there
        is none."""
        return self.all_stages()[2:] or ["relaxed"]

    def pile_targets(self, stages=None):
        """All particle-state files of the configured piles (default: every stage)."""
        stages = self.all_stages() if stages is None else stages
        return [self.pile(protocol, seed, stage) for protocol, seed in self.each() for stage in stages]

    def pile_figure_targets(self, stage="relaxed"):
        """Pictures of all configured piles at one stage."""
        return [self.pile_figure(protocol, seed, stage) for protocol, seed in self.each()]

    def pile_benchmarks(self):
        """Benchmark files of every simulation job of the piles (pour, relax, each probe)."""
        return [self.stage_benchmark(protocol, seed, stage)
                for protocol, seed in self.each() for stage in self.all_stages()]

    # --- checks ----------------------------------------------------------

    def problems(self):
        """The workflow's own checks of its stage names and probes, which
        neither the schemas nor the packages' checks (workflow/validation.py)
        express.

        Returns
        -------
        list of str
            One message per problem, naming the settings, their values and
            what is allowed; empty for a usable configuration.
        """
        config, problems = self.config, []
        stages, tilts = self.probe_stages(), self.tilt_stages()
        if len(set(stages)) != len(stages):
            problems.append(
                f"probe.levels {config['probe']['levels']} give repeated stage names "
                f"{stages}: levels must differ at percent resolution"
            )
        if len(set(tilts)) != len(tilts):
            problems.append(
                f"probe.tilts {config['probe']['tilts']} give repeated stage names {tilts}: "
                "tilts must differ at percent resolution"
            )
        problems += self._stretch_problems()
        if config["probe"]["restore"] and not stages:
            problems.append(
                "probe.restore = true with probe.levels = []: restoring gravity needs a "
                "gravity reduction first (give a level)"
            )
        bad = [s for s in stages if not re.fullmatch(STAGE_PATTERN, s)]
        if bad:
            problems.append(
                f"probe.levels {config['probe']['levels']} give stage names {bad} "
                f"outside 'reduced' / 'reducedNN': keep each level in [0.005, 0.995)"
            )
        return problems

    def preflight(self):
        """The simulator's own refusals of these piles, before any job runs.

        :func:`sim.preflight.check_piles` on the first seed (a time step that
        cannot carry the fall from the release height or the relaxation of
        the tallest pile the particles can make, particles the shape recipe
        cannot draw): what the pour or the relaxation would otherwise refuse
        only when it starts, after other jobs. It draws that seed's particles
        (about a second for 3500); above :data:`PREFLIGHT_PARTICLES` it is
        left to the pour, which makes the same checks when it starts.

        Returns
        -------
        list of str
            The refusal, one line naming the settings, their values and what
            is allowed; empty when the piles can run (or there is none).
        """
        first = [self.seeds(p)[0] for p in self.protocols if self.seeds(p)]
        if not first or self.config["pour"]["n_particles"] > PREFLIGHT_PARTICLES:
            return []
        try:
            check_piles(SimConfig.from_dict({k: self.config[k] for k in SIM_SECTIONS}), self.protocols, first[0])
        except ValueError as exc:  # sim.config.ConfigError, or the step rule's refusal of model.dt
            return [str(exc)]
        return []

    def _stretch_problems(self):
        """A support stretch (probe.stretch) without a support, or without its friction."""
        stretch, problems = float(self.config["probe"]["stretch"]), []
        if stretch != 0.0 and not self.config["physics"]["support"]:
            problems.append(
                f"probe.stretch = {stretch} with physics.support = false: the stretch moves the "
                "support's surface; set probe.stretch to 0"
            )
        if stretch != 0.0 and self.config["model"]["support_friction"] == 0:
            problems.append(
                f"probe.stretch = {stretch} with model.support_friction = 0: the support drags the "
                "particles only through friction; give model.support_friction > 0 or set probe.stretch to 0"
            )
        return problems

