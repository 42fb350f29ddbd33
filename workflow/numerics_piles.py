"""Paths, settings and inputs of the pile and ensemble numerics
(workflow/rules/numerics_piles.smk): small piles poured and relaxed per
(integrator, dt factor, seed), and the study's piles, fields and benchmarks
that the ensemble's error against compute time reads.
"""

from sim.config import SECTIONS, SimConfig


def factor_label(factor):
    """Folder label of a dt factor: the shortest exact decimal (0.125 -> '0.125')."""
    return f"{float(factor):g}"


class NumericsPiles:
    """The numerics of whole piles of a validated configuration (config ``numerics``).

    Parameters
    ----------
    piles : workflow.piles.Piles
        The study's piles, with their configuration (``piles.config``).
    """

    def __init__(self, piles):
        self.piles = piles
        self.config = config = piles.config
        #: Settings of the small piles (numerics.piles) and of the ensemble study.
        self.settings = config["numerics"]["piles"]
        self.ensemble = config["numerics"]["ensemble"]
        #: Their folder in the results folder.
        self.folder = piles.paths.results_path("numerics")

    def _run(self, integrator, factor, seed):
        """The folder part of one small pile: ``{integrator}/dt_factor{factor}/seed{seed}``."""
        return f"{integrator}/dt_factor{factor}/seed{seed}"

    def pile(self, integrator, factor, seed, stage):
        """State file of a small pile of the accuracy study (`factor`: its label)."""
        return f"{self.folder}/piles/{self._run(integrator, factor, seed)}/{stage}.nc"

    def summary(self, integrator, factor, seed, stage):
        """Summary line (python -m sim summary) of one state of a small pile."""
        return f"{self.folder}/piles/{self._run(integrator, factor, seed)}/{stage}.summary.json"

    def benchmark(self, integrator, factor, seed, step):
        """Benchmark file (wall time) of one simulation job of a small pile."""
        return self.piles.paths.results_path(f"benchmarks/numerics/piles/{self._run(integrator, factor, seed)}_{step}.tsv")

    def cpu(self, integrator, factor, seed, step):
        """CPU time (bash ``times``) of one simulation job of a small pile: unlike the
        wall time it does not grow when other processes share the cores."""
        return self.piles.paths.results_path(f"benchmarks/numerics/piles/{self._run(integrator, factor, seed)}_{step}.times")

    def runs(self):
        """(integrator, dt factor label, seed) of every small pile, in config order."""
        p = self.settings
        return [(i, factor_label(f), int(s)) for i in p["integrators"] for f in p["dt_factors"] for s in p["seeds"]]

    def job_params(self, wildcards, stage):
        """The simulator sections of one small pile as canonical JSON.

        The config's sections with pour.n_particles from numerics.piles, the
        integrator of the run and its time step scaled by the dt factor; the
        bookkeeping settings travel apart (:meth:`workflow.jobs.JobSettings.job_bookkeeping`).

        Parameters
        ----------
        wildcards : snakemake.io.Wildcards
            ``integrator`` and ``factor`` of the run.
        stage : str
            ``pour`` or ``relax``: the simulator writes the job's sections
            (:meth:`sim.config.SimConfig.job_params`).

        Returns
        -------
        str
        """
        config, factor = self.config, float(wildcards.factor)
        model = dict(config["model"], integrator=wildcards.integrator)
        if model["dt"] is None:
            model["dt_safety"] = model["dt_safety"] * factor
        else:
            model["dt"] = model["dt"] * factor
        cfg = {k: config[k] for k in SECTIONS}
        cfg.update(model=model, pour=dict(config["pour"], n_particles=self.settings["n_particles"]))
        return SimConfig.from_dict(cfg).job_params(stage)

    def pile_inputs(self, kind):
        """The files of every small pile of one kind: ``states``, ``summaries``
        (of the relaxed piles), a step's benchmarks (``pour``, ``relax``) or
        CPU times (``pour_cpu``, ``relax_cpu``)."""
        runs = self.runs()
        if kind == "states":
            return [self.pile(i, f, s, "relaxed") for i, f, s in runs]
        if kind == "summaries":
            return [self.summary(i, f, s, "relaxed") for i, f, s in runs]
        if kind.endswith("_cpu"):
            return [self.cpu(i, f, s, kind[:-4]) for i, f, s in runs]
        return [self.benchmark(i, f, s, kind) for i, f, s in runs]

    def protocol_files(self, kind, protocol):
        """The study's files of one kind and protocol for the ensemble study:
        ``fields`` (per pile), ``base_pressure`` (one), or a simulation step's
        benchmarks (``pour``, ``relax``, ``probe``: the gravity probes)."""
        piles, seeds = self.piles, self.piles.seeds(protocol)
        if kind == "fields":
            return [piles.paths.results_path(f"fields/{protocol}/seed{s}.nc") for s in seeds]
        if kind == "base_pressure":
            return [piles.paths.results_path(f"ensemble/{protocol}/base_pressure.nc")]
        stages = {"pour": ["poured"], "relax": ["relaxed"], "probe": piles.stages.probe_stages()}[kind]
        return [piles.paths.stage_benchmark(protocol, s, st) for s in seeds for st in stages]

    def ensemble_inputs(self, kind):
        """The files of one kind (:meth:`protocol_files`) of every protocol, in protocol order."""
        return [f for p in self.piles.protocols for f in self.protocol_files(kind, p)]

    def ensemble_args(self):
        """Per-protocol arguments of ``ensemble_cost data``, in protocol order (a list)."""
        args = []
        for p in self.piles.protocols:
            args += ["--protocol", p, "--seeds", *map(str, self.piles.seeds(p)),
                     "--fields", *self.protocol_files("fields", p),
                     "--base-pressure", *self.protocol_files("base_pressure", p)]
            for kind in ("pour", "relax", "probe"):
                args += [f"--{kind}-benchmarks", *self.protocol_files(kind, p)]
        return args

    def targets(self):
        """Every final output of the pile and ensemble numerics."""
        return [f"{self.folder}/{name}" for name in
                ("piles.nc", "ensemble.nc", "piles.md", "pile_error.png", "pile_error.pdf",
                 "ensemble_error.png", "ensemble_error.pdf")]

    def problems(self):
        """What the schema cannot express: the reference integrator among the
        integrators, and dt factors that differ as folder labels.

        Returns
        -------
        list of str
            One message per problem, naming the settings and their values.
        """
        p, problems = self.settings, []
        if p["reference_integrator"] not in p["integrators"]:
            problems.append(f"numerics.piles.reference_integrator = {p['reference_integrator']!r} is not in "
                            f"numerics.piles.integrators = {p['integrators']}")
        labels = [factor_label(f) for f in p["dt_factors"]]
        if len(set(labels)) != len(labels):
            problems.append(f"numerics.piles.dt_factors = {p['dt_factors']} repeat a factor at 6 significant digits")
        return problems
