# The scene: what the configuration asks the workflow to build (config
# `outputs`) and the physics it declares (model.friction, model.damping,
# physics, probe.levels). Only the targets of the asked outputs are built, so
# a stress-only scene never runs a gravity probe, a strain fit or a figure.
# Functions only (snakemake --lint wants functions and rules apart); included
# after common.smk.

OUTPUTS = set(config["outputs"])

# Outputs that need the piles (pour and relax), and what each output needs.
PILE_OUTPUTS = {"states", "fields", "strain", "fabric", "fits", "vtk", "film"}
OUTPUT_NEEDS = {"strain": "fields", "fabric": "fields", "fits": "strain"}


def wants(output):
    """Whether the scene asks for `output` (one of the names of config `outputs`)."""
    return output in OUTPUTS


def has_probes():
    """Whether the scene has gravity probes (config probe.levels not empty)."""
    return bool(config["probe"]["levels"])


def field_quantities():
    """The optional quantities of the per-pile fields besides the stress
    (`python -m analysis fields --quantities`), in the analysis' order."""
    return [q for q in ("fabric", "strain") if wants(q)]


def _check_scene():
    """Outputs the scene's physics or other outputs cannot give; fail before
    any job runs, naming the settings."""
    problems = []
    asked = config["outputs"]
    for output, needed in OUTPUT_NEEDS.items():
        if wants(output) and not wants(needed):
            problems.append(
                f"outputs {asked}: {output} needs {needed}; add {needed!r} or leave "
                f"{output!r} out"
            )
    if wants("strain") and not has_probes():
        problems.append(
            f"outputs {asked}: strain is the response to a gravity probe but "
            f"probe.levels is {config['probe']['levels']}; give a level (e.g. [0.10]) "
            "or leave strain (and fits) out"
        )
    if not config["physics"]["support"] and OUTPUTS & PILE_OUTPUTS:
        problems.append(
            f"physics.support = false with outputs {asked}: the piles are poured onto "
            f"the support; without it the only allowed output is [numerics]"
        )
    seed = config["analysis"]["convergence"]["seed"]
    if wants("strain") and seed is not None:
        for protocol in PROTOCOLS:
            if seed not in seeds(protocol):
                problems.append(
                    f"analysis.convergence.seed = {seed} is not a seed of protocol "
                    f"{protocol} (seeds {seeds(protocol)}): the convergence study would "
                    "pour a pile outside the study; give one of its seeds or null (every pile)"
                )
    n, least = config["pour"]["n_particles"], config["analysis"]["rve"]["min_particles"]
    if wants("fields") and n < least:
        problems.append(
            f"pour.n_particles = {n} is fewer than analysis.rve.min_particles = {least}: no RVE of "
            f"such a pile can hold enough particles, so the fields would be empty; pour at least "
            f"{least} particles, lower analysis.rve.min_particles, or ask only outputs [states]"
        )
    stage = config["analysis"]["base_pressure"]["stage"]
    if wants("fields") and stage not in ["poured", "relaxed"] + probe_stages():
        problems.append(
            f"analysis.base_pressure.stage = {stage!r} is not a stage of this scene "
            f"(poured, relaxed and the probes {probe_stages()})"
        )
    if config["committed"]:
        folder = REPO / config["committed"]
        if not folder.is_dir():
            problems.append(f"committed = {config['committed']!r}: no such folder under {REPO}")
        if OUTPUTS & {"states", "vtk", "film", "numerics"}:
            problems.append(
                f"committed = {config['committed']!r} with outputs {asked}: committed results "
                "replace the simulation, so states, vtk, film and numerics cannot be asked for; "
                "leave them out of outputs"
            )
    if problems:
        raise ValueError("invalid scene:\n  " + "\n  ".join(problems))


_check_scene()


def scene_targets():
    """Everything the scene asks for, the input of `all`. The pile states, the
    pictures of the relaxed piles and the table of the simulation jobs' run
    times (not from committed results: they need the states), the VTK files,
    the films, the analysis (analysis_targets()) and the numerical checks. Called from the Snakefile after every rule file is
    included, so the numerics rules exist."""
    targets = pile_targets() if wants("states") else []
    if wants("figures") and OUTPUTS & PILE_OUTPUTS and not config["committed"]:
        targets += pile_figure_targets("relaxed") + [RUN_TIMES_TABLE]
    if wants("vtk"):
        targets += [pile_vtk(protocol, seed, "relaxed") for protocol in PROTOCOLS for seed in seeds(protocol)]
    if wants("film"):
        targets += [pile_film(protocol, seed, ext) for protocol in PROTOCOLS
                    for seed in seeds(protocol) for ext in ("mp4", "html")]
    if wants("numerics"):
        targets += list(rules.numerics.input) + numerics_piles_targets()
    return targets + analysis_targets()


def made_targets():
    """The scene's targets (scene_targets()) that exist now, the input of rule
    `made`: `make report` reports those, so that the report of a study half
    run (or not run at all) shows what there is instead of failing on a
    figure not yet drawn."""
    return [path for path in scene_targets() if os.path.exists(path)]


def _shown_path(path):
    """A configuration file's path as the report names it: relative to the
    repository, else to the working directory, else absolute."""
    path = Path(path).absolute()
    for base in (REPO, Path.cwd()):
        try:
            return str(path.relative_to(base))
        except ValueError:
            pass
    return str(path)


def configuration_files():
    """The configuration files of this run, as given (--configfile, in order),
    or config/config.yaml when none is, and the --config settings
    (`key=value`): what the report and its description name."""
    files = [_shown_path(f) for f in workflow.overwrite_configfiles] or ["config/config.yaml"]
    settings = [f"{key}={value}" for key, value in workflow.config_settings.config.items()]
    return files + (["--config " + " ".join(settings)] if settings else [])


def report_description():
    """What the report describes, in words for its first paragraph
    (workflow/report/workflow.rst): the configuration files, the results
    folder and how many of the configuration's piles are there; committed
    results (config `committed`) are named with the piles recorded there."""
    piles = [(p, s) for p in PROTOCOLS for s in seeds(p)]
    if config["committed"]:
        there = sum(len(analysis_seeds(p)) for p in PROTOCOLS)
        made = (f"from the per-pile results committed under {config['committed']}/ "
                f"({there} of the {len(piles)} piles recorded)")
    else:
        last = probe_stages() + extra_probe_stages() or ["relaxed"]   # as make progress counts
        there = sum(all(os.path.exists(pile(p, s, st)) for st in last) for p, s in piles)
        made = (f"{there} of {len(piles)} piles of {config['pour']['n_particles']} particles "
                "made so far")
    return {"configfiles": ", ".join(configuration_files()), "results": f"{RESULTS}/", "piles": made,
            "freshness": Freshness() if _report_path() else ""}


class Freshness:
    """The report's sentence on whether its results are up to date, by
    Snakemake's own judgement: the jobs it would run (what a dry run with the
    same options lists) among those that made the report's files. It is
    rendered into the report's first paragraph (workflow/report/workflow.rst)
    once Snakemake has built the jobs, and a report with stale results is
    warned about on the terminal too."""

    #: Why a job would run, in words: (attribute of Snakemake's reason, words);
    #: the code of sim/ and analysis/ travels as a param (workflow/digest.py).
    REASONS = (("params_changed", "code or settings changed"),
               ("code_changed", "a rule's command changed"),
               ("input_changed", "inputs changed"), ("updated_input", "inputs changed"),
               ("software_stack_changed", "software changed"),
               ("incomplete_output", "a job was killed while making them"),
               ("missing_output", "files they need are missing"))

    def __init__(self):
        self._text = None

    def __str__(self):
        if self._text is None:
            self._text = self._judge(workflow.dag)
        return self._text

    def _judge(self, dag):
        """The sentence; warns on the terminal when results are out of date."""
        jobs = [job for job in dag.needrun_jobs() if job.output]
        stale = [str(f) for job in jobs for f in job.output if os.path.exists(f)]
        if not stale:
            return ("Up to date: Snakemake would remake none of these results (their code, "
                    "settings and inputs have not changed since they were made).")
        rules = {}
        for job in jobs:
            rules[job.rule.name] = rules.get(job.rule.name, 0) + 1
        why = sorted({words for job in jobs for attribute, words in self.REASONS
                      if getattr(dag.reason(job), attribute)})
        text = (f"OUT OF DATE: {len(stale)} files of these results do not show what the "
                f"workflow makes now ({'; '.join(why)} since they were made): "
                f"Snakemake would run {len(jobs)} jobs again ("
                + ", ".join(f"{n} {rule}" for rule, n in sorted(rules.items()))
                + f"), for example for {stale[0]}. To refresh them, run the workflow with the "
                "options of this report but without --report (make run for the study; add -n "
                "to list the jobs and their reasons), then make the report again.")
        logger.warning(f"Report: {text}")
        return text


def _report_path():
    """The path given to --report on this Snakemake's command line; None
    without one (and in the jobs, which never get it)."""
    for k, arg in enumerate(sys.argv):
        if arg.startswith("--report="):
            value = arg.split("=", 1)[1]
        elif arg == "--report" and k + 1 < len(sys.argv):
            value = sys.argv[k + 1]
        else:
            continue
        if value.endswith((".html", ".zip")):
            return value
    return None


def _check_report_path():
    """Refuse a report written under results/ but outside this
    configuration's results folder: it would overwrite or sit among another
    configuration's files (make report and make smoke once wrote the same
    results/report.html). A report outside results/ is the user's choice."""
    value = _report_path()
    if value is None:
        return
    path = (Path.cwd() / value).resolve()
    ours, top = (Path.cwd() / RESULTS).resolve(), (Path.cwd() / "results").resolve()
    if path.is_relative_to(top) and not path.is_relative_to(ours):
        raise ValueError(
            f"--report {value}: this configuration ({', '.join(configuration_files())}) writes "
            f"its results to {RESULTS}/ (config `results`); write its report there, e.g. "
            f"--report {RESULTS}/report.html, so that the reports of two configurations never "
            "overwrite each other")
