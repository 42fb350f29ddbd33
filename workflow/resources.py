"""What a cluster executor requests per simulation job, estimated from the
configuration (SLURM: --cpus-per-task = threads, --mem = mem_mb, --time =
runtime in minutes; docs/cluster.md); locally they only matter with
--resources limits. The runtimes are

    minutes = START_MIN + RUNTIME_MARGIN * steps * particles * PARTICLE_STEP_S
              / speedup(threads) / 60,   steps = simulated time / dt,

a pour's simulated time set by its source's own flux (:meth:`SimResources.pour_rate`:
the funnel's Beverloo rate, which pour.rate does not set),

multiplied by the attempt number, so a job that SLURM killed at its time
limit asks for twice the time when --retries resubmits it (a pour resumes
from its checkpoint, so it needs less; relaxations start again).  The same
cost model, without the margin and the start, estimates the CPU seconds of a
pile before any has finished (:meth:`SimResources.stage_cpu_s`, for
workflow/tools/study_progress.py). PARTICLE_STEP_S is one measurement of the
run-time table, workflow/run_times.json (its row ``cost_model``), which
docs/run_times.md and the README show.
"""

import json
import math
import os
from pathlib import Path

from sim.config import SECTIONS, SimConfig
from sim.release import funnel, source
from sim.timestep import MAX_STEPS
from workflow.stages import STRETCH_STAGE

#: The run-time table: every measured time of the targets and piles, with its
#: command, host, date and commit (python -m workflow.tools run_times writes
#: docs/run_times.md from it).
RUN_TIMES = Path(__file__).with_name("run_times.json")


def cost_basis(path=RUN_TIMES):
    """The measurement the cost model's price of a particle-step comes from.

    Parameters
    ----------
    path : path-like
        The run-time table (JSON): its ``cost_model`` names the row, a pour
        with ``cpu_s``, ``steps`` and ``particles``.

    Returns
    -------
    dict
        That row, with ``ns_per_particle_step``: its CPU time over steps × N/2
        (a pour holds half its particles on average).
    """
    table = json.loads(Path(path).read_text(encoding="utf-8"))
    row = next(r for r in table["rows"] if r["id"] == table["cost_model"])
    return {**row, "ns_per_particle_step": 1e9 * row["cpu_s"] / (row["steps"] * row["particles"] / 2)}


#: The measured pour the cost model is priced by (:func:`cost_basis`).
COST_BASIS = cost_basis()
#: CPU seconds of one particle-step on one thread, from that pour.
PARTICLE_STEP_S = COST_BASIS["ns_per_particle_step"] * 1e-9
# Safety factor on the step cost of a cluster job's time limit: a slow hour of
# a shared host doubled the cost per particle-step (223 to 494 ns on the same
# bench heap, docs/performance.md), and half as much again for a slower node.
RUNTIME_MARGIN = 3.0
# Python start, loading the compiled kernels, reading and writing state files.
START_MIN = 2
# Automatic time step of the default particles (semi-axis 3.4 mm, density
# 2500 kg/m2, Y = 1e7 N/m, dt_safety 0.5; docs/model.md, time-step rule). It scales
# like sqrt(mass / stiffness), i.e. like semi-axis * sqrt(density / Y).
DT_REFERENCE_S = {"gear": 1.9e-6, "verlet": 6.9e-6}
# A release waits while its spot is not clear, so pouring takes longer than
# n_particles / rate: 35.6 s (layered) and 41 s (wedge) instead of 35 s for the
# study's pours (docs/performance.md, "How long").
POUR_TIME_FACTOR = 1.5
# Simulated time a relaxation or gravity probe typically needs: a 3500-particle
# pile relaxed in 0.42-0.83 s (at most relax.max_time, after which the simulator
# gives up by itself).
RELAX_TYPICAL_S = 2.0
# Peak memory measured for 150 and for 3500 particles: 230-250 MB (Python,
# Numba and netCDF dominate; the particle arrays take about 1.3 kB each).
SIM_MEM_BASE_MB = 1000
SIM_MEM_PER_PARTICLE_MB = 0.1
# Largest memory (MB) a cluster node is assumed to have when no --resources
# mem_mb says otherwise: 4 TB.
CLUSTER_NODE_MEM_MB = 4_000_000
# Run-time estimate (min) of one pour beyond which the plan is called absurd: a week.
ABSURD_RUNTIME_MIN = 7 * 24 * 60


def per_attempt(value):
    """Resource callable: `value` times the attempt number."""
    return lambda wildcards, attempt: value * attempt


class SimResources:
    """Runtime and memory of the simulation jobs of a configuration.

    The ``*_min`` and ``sim_mem_mb`` methods are Snakemake resource callables
    (``wildcards, attempt``).

    Parameters
    ----------
    config : dict
        The validated workflow configuration.
    """

    def __init__(self, config):
        self.config = config
        #: Threads of every simulation job (config ``threads``).
        self.threads = int(config["threads"])
        self._rates = {}

    def pour_rate(self, protocol=None):
        """Releases per second of a pour: its source's own flux (:func:`sim.release.source`).

        The funnel (a wedge pour with ``pour.point_source: funnel``) releases
        at the 2D Beverloo rate of its outlet for the particles of the
        protocol's first seed (:func:`sim.release.beverloo_rate`; 213/s at the
        default 4 d, 19/s at 2 d), whatever ``pour.rate``; the drip and the
        line sources at ``pour.rate`` or a little below it (86-100 % measured,
        docs/model.md), which POUR_TIME_FACTOR covers.

        Parameters
        ----------
        protocol : str, optional
            The pour's protocol; None: the slowest source of the
            configuration's protocols (an estimate that holds for every pile).
        """
        return self._source(protocol)[0]

    def rate_text(self, protocol=None):
        """:meth:`pour_rate` in words, with the setting that sets it (for messages)."""
        return self._source(protocol)[1]

    def _source(self, protocol):
        """(:meth:`pour_rate`, :meth:`rate_text`) of `protocol`, or of the slowest source for None."""
        if protocol is None:
            return min((self._source(p) for p in self.config["protocols"]), key=lambda found: found[0])
        if protocol not in self._rates:
            cfg = SimConfig.from_dict({k: self.config[k] for k in SECTIONS})
            if funnel(cfg, protocol):
                from sim.pour import GRAVITY, pile_shapes   # the draw of the particles, for the funnel alone
                seed = self.config["protocols"][protocol]["seeds"][0]
                rate = source(cfg, pile_shapes(cfg, seed), protocol, GRAVITY).rate
                self._rates[protocol] = (rate, f"the funnel's Beverloo rate {rate:.4g}/s "
                                               f"(pour.outlet_width = {cfg.pour.outlet_width:g})")
            else:
                self._rates[protocol] = (float(cfg.pour.rate), f"pour.rate = {cfg.pour.rate:.4g}/s")
        return self._rates[protocol]

    def estimated_dt(self):
        """Time step (s) of the simulations: model.dt if set, else the automatic
        step of the reference particles scaled to the configured ones."""
        model, particles = self.config["model"], self.config["particles"]
        if model["dt"] is not None:
            return float(model["dt"])
        # the ratios in this order neither overflow nor underflow to 0 / 0 for the schema's ranges
        scale = (particles["semi_axis_mean"] / 3.4e-3) * math.sqrt(
            model["density"] / model["youngs_modulus"] * (1e7 / 2500.0))
        return DT_REFERENCE_S[model["integrator"]] * scale * model["dt_safety"] / 0.5

    def steps(self, stage, protocol=None):
        """Time steps of the job making `stage` by the cost model
        (:meth:`particle_steps` over the particles); ``inf`` for a step of 0."""
        n = self.config["pour"]["n_particles"]
        return self.particle_steps(stage, protocol) / (n / 2 if stage == "poured" else n)

    def relax_simulated_s(self):
        """Simulated time (s) of a relaxation: RELAX_TYPICAL_S, at most relax.max_time."""
        return min(RELAX_TYPICAL_S, self.config["relax"]["max_time"])

    def particle_steps(self, stage, protocol=None):
        """Particle-steps of the job making `stage`, by the cost model.

        Parameters
        ----------
        stage : str
            ``"poured"``: the release time at the source's flux
            (:meth:`pour_rate`), stretched by POUR_TIME_FACTOR, plus
            the settling time, with half the particles on average;
            ``"relaxed"``: :meth:`relax_simulated_s` of the full pile; a probe: that, plus the gravity ramp, if any, or the support
            stretch.
        protocol : str, optional
            The pile's protocol (:meth:`pour_rate`; None: the slowest).

        Returns
        -------
        float
            Simulated time over :meth:`estimated_dt`, times the particles:
            what the configuration alone fixes, on any host.
        """
        pour, dt = self.config["pour"], self.estimated_dt()
        if stage == "poured":
            simulated = POUR_TIME_FACTOR * pour["n_particles"] / self.pour_rate(protocol) + 0.1
            return (simulated / dt if dt > 0 else math.inf) * pour["n_particles"] / 2
        probe = self.config["probe"]
        simulated = self.relax_simulated_s()
        if stage == STRETCH_STAGE:
            simulated += probe["stretch_time"]
        elif stage != "relaxed" and probe["mode"] == "ramp":
            simulated += probe["ramp_time"]
        return (simulated / dt if dt > 0 else math.inf) * pour["n_particles"]

    def stage_cpu_s(self, stage, protocol=None):
        """CPU seconds of the job making `stage` by the cost model:
        :meth:`particle_steps` times PARTICLE_STEP_S (no margin, no start)."""
        return self.particle_steps(stage, protocol) * PARTICLE_STEP_S

    def stage_runtime_min(self, stage, attempt, protocol=None):
        """Wall-clock minutes to request for the job making `stage`: its
        :meth:`stage_cpu_s` on the configured threads (the parallel kernels are
        assumed to scale with 80 % efficiency), with the margin and the start."""
        speedup = 1.0 + 0.8 * (self.threads - 1)
        seconds = self.stage_cpu_s(stage, protocol) / speedup
        return attempt * math.ceil(START_MIN + RUNTIME_MARGIN * seconds / 60.0)

    def pour_runtime_min(self, wildcards, attempt):
        """Runtime (min) of the pour of ``wildcards.protocol`` (:meth:`stage_runtime_min`; without
        wildcards, of the slowest source)."""
        return self.stage_runtime_min("poured", attempt, getattr(wildcards, "protocol", None))

    def relax_runtime_min(self, wildcards, attempt):
        """Runtime (min) of relaxing the full pile (:meth:`stage_runtime_min`)."""
        return self.stage_runtime_min("relaxed", attempt)

    def probe_runtime_min(self, wildcards, attempt):
        """Runtime (min) of the probe ``wildcards.stage`` (:meth:`stage_runtime_min`)."""
        return self.stage_runtime_min(wildcards.stage, attempt)

    def sim_mem_mb(self, wildcards, attempt):
        """Memory (MB) of a simulation job, growing with the attempt (a job killed
        for memory asks for more when resubmitted)."""
        n = self.config["pour"]["n_particles"]
        return attempt * math.ceil(SIM_MEM_BASE_MB + SIM_MEM_PER_PARTICLE_MB * n)

    def check_size(self, mem_mb, local, warn):
        """Refuse a pile whose job cannot fit in memory; warn about an absurdly long pour.

        Parameters
        ----------
        mem_mb : float, Snakemake resource or None
            Snakemake's ``--resources mem_mb`` (its number, or the resource
            holding it as ``value``), if given: the limit.
        local : bool
            Whether the jobs run on this machine (its memory is the limit
            without `mem_mb`) or on a cluster (CLUSTER_NODE_MEM_MB).
        warn : callable
            Called with the warning's text when a pour is estimated to take
            longer than ABSURD_RUNTIME_MIN.

        Raises
        ------
        ValueError
            Naming pour.n_particles, the memory a job needs and the limit; or
            naming the settings of a job that the cost model puts above the
            simulator's :data:`sim.timestep.MAX_STEPS` steps (the simulator
            refuses it when it starts; the workflow before any job).
        """
        need, where = self.sim_mem_mb(None, 1), "--resources mem_mb"
        mem_mb = getattr(mem_mb, "value", mem_mb)
        if mem_mb is None and local:
            mem_mb = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**20
            where = "the memory of this machine"
        elif mem_mb is None:
            mem_mb, where = CLUSTER_NODE_MEM_MB, "the largest cluster node assumed"
        n = self.config["pour"]["n_particles"]
        if need > mem_mb:
            raise ValueError(
                f"pour.n_particles = {n}: a simulation job would need about {need:.0f} MB "
                f"({SIM_MEM_BASE_MB} MB + {SIM_MEM_PER_PARTICLE_MB} MB per particle), more than "
                f"{where} ({mem_mb:.0f} MB); pour fewer particles")
        pour, model = self.config["pour"], self.config["model"]
        for stage in ("poured", "relaxed"):
            steps = self.steps(stage)
            if not steps <= MAX_STEPS:
                step = (f"model.dt = {model['dt']:.4g} s" if model["dt"] is not None else
                        f"an automatic step of about {self.estimated_dt():.4g} s (model.youngs_modulus = "
                        f"{model['youngs_modulus']:.4g}, model.density = {model['density']:.4g}, "
                        f"particles.semi_axis_mean = {self.config['particles']['semi_axis_mean']:.4g})")
                what = (f"pour.n_particles = {pour['n_particles']} at {self.rate_text()}"
                        if stage == "poured" else f"relaxing for about {self.relax_simulated_s():.4g} s")
                raise ValueError(f"{what} with {step} needs about {steps:.4g} steps, more than the "
                                 f"simulator's {MAX_STEPS:.0e}; give a larger step or a shorter run")
        minutes = self.pour_runtime_min(None, 1)
        if minutes > ABSURD_RUNTIME_MIN:
            warn(f"pour.n_particles = {n}, {self.rate_text()}: the slowest pour is "
                 f"estimated to take {minutes / 1440:.0f} days on {self.threads} threads")
