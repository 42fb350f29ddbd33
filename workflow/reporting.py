"""What the report (``snakemake --report``) says about its configuration: the
first paragraph of workflow/report/workflow.rst names the configuration
files, the results folder, how many piles are there and whether the results
are up to date (:class:`Freshness`); the captions say how many piles of each
protocol the scene has, for any set of protocols (:func:`piles_per_protocol`);
and where a report may be written.  The words come to the report's pages as
``config["_report"]`` (:func:`report_words`).
"""

import os
from pathlib import Path


def shown_path(path, repo):
    """A configuration file's path as the report names it: relative to the
    repository `repo`, else to the working directory, else absolute."""
    path = Path(path).absolute()
    for base in (repo, Path.cwd()):
        try:
            return str(path.relative_to(base))
        except ValueError:
            pass
    return str(path)


def configuration_files(configfiles, settings, repo):
    """The configuration of a run as the report and its description name it.

    Parameters
    ----------
    configfiles : list of path-like
        The ``--configfile`` files, in order; none means config/config.yaml.
    settings : dict
        The ``--config`` settings.
    repo : pathlib.Path
        The repository.

    Returns
    -------
    list of str
        The files (:func:`shown_path`) and, with settings, one item
        ``--config key=value ...``.
    """
    files = [shown_path(f, repo) for f in configfiles] or ["config/config.yaml"]
    given = [f"{key}={value}" for key, value in settings.items()]
    return files + (["--config " + " ".join(given)] if given else [])


def report_path(argv):
    """The path given to --report on the command line `argv`.

    Returns
    -------
    str or None
        The ``.html`` or ``.zip`` path; None without one (and in the jobs,
        which never get it).
    """
    for k, arg in enumerate(argv):
        if arg.startswith("--report="):
            value = arg.split("=", 1)[1]
        elif arg == "--report" and k + 1 < len(argv):
            value = argv[k + 1]
        else:
            continue
        if value.endswith((".html", ".zip")):
            return value
    return None


def check_report_path(value, results, files):
    """Refuse a report written under results/ but outside the configuration's
    results folder: it would overwrite or sit among another configuration's
    files (make report and make smoke once wrote the same results/report.html).
    A report outside results/ is the user's choice.

    Parameters
    ----------
    value : str or None
        The --report path (:func:`report_path`), relative to the working directory.
    results : str
        The configuration's results folder (config ``results``).
    files : list of str
        The configuration (:func:`configuration_files`), for the message.

    Raises
    ------
    ValueError
        Naming the report, the configuration and its folder.
    """
    if value is None:
        return
    path = (Path.cwd() / value).resolve()
    ours, top = (Path.cwd() / results).resolve(), (Path.cwd() / "results").resolve()
    if path.is_relative_to(top) and not path.is_relative_to(ours):
        raise ValueError(
            f"--report {value}: this configuration ({', '.join(files)}) writes "
            f"its results to {results}/ (config `results`); write its report there, e.g. "
            f"--report {results}/report.html, so that the reports of two configurations never "
            "overwrite each other")


def piles_made(piles, analysis_seeds):
    """How many of the configuration's piles are there, in words.

    Parameters
    ----------
    piles : workflow.piles.Piles
        The piles of the configuration (``piles.config``).
    analysis_seeds : callable
        The seeds of a protocol whose results enter the ensembles
        (:meth:`workflow.analysis_inputs.AnalysisInputs.analysis_seeds`).

    Returns
    -------
    str
        Under config ``committed``, how many piles are recorded there;
        else how many piles have their last stage (as make progress counts).
    """
    config, total = piles.config, len(piles.each())
    if config["committed"]:
        there = sum(len(analysis_seeds(p)) for p in piles.protocols)
        return (f"from the per-pile results committed under {config['committed']}/ "
                f"({there} of the {total} piles recorded)")
    there = sum(all(os.path.exists(piles.paths.pile(p, s, st)) for st in piles.stages.final_stages())
                for p, s in piles.each())
    return f"{there} of {total} piles of {config['pour']['n_particles']} particles made so far"


def piles_per_protocol(protocols):
    """The piles of each protocol, in words: ``"2 wedge and 2 layered"``, ``"6 wedge"``.

    Parameters
    ----------
    protocols : dict
        Config ``protocols``: each protocol of the scene (one at least) with its ``seeds``.

    Returns
    -------
    str
        The number of seeds and the name of each protocol, in the configuration's order.
    """
    counts = [f"{len(spec['seeds'])} {protocol}" for protocol, spec in protocols.items()]
    return ", ".join(counts[:-1]) + " and " + counts[-1] if len(counts) > 1 else counts[0]


def report_words(configuration, results, piles, freshness, protocols):
    """``config["_report"]``: what the report's pages (workflow/report/*.rst) say of the run.

    Parameters
    ----------
    configuration : list of str
        The configuration (:func:`configuration_files`).
    results : str
        The results folder (config ``results``).
    piles : str
        How many piles are made (:func:`piles_made`).
    freshness : Freshness or str
        Whether the results are up to date (:class:`Freshness`; empty without --report).
    protocols : dict
        Config ``protocols`` (:func:`piles_per_protocol`).

    Returns
    -------
    dict
        ``configfiles``, ``results``, ``piles``, ``freshness`` (workflow.rst)
        and ``protocols``, the piles per protocol (the captions).
    """
    return {"configfiles": ", ".join(configuration), "results": f"{results}/", "piles": piles,
            "freshness": freshness, "protocols": piles_per_protocol(protocols)}


class Freshness:
    """The report's sentence on whether its results are up to date, by
    Snakemake's own judgement: the jobs it would run (what a dry run with the
    same options lists) among those that made the report's files. It is
    rendered into the report's first paragraph (workflow/report/workflow.rst)
    once Snakemake has built the jobs, and said on the terminal too: a report
    with stale results as a warning. A configuration that has made none of
    its results yet is not up to date: it is told so.

    Parameters
    ----------
    dag : callable
        Returns Snakemake's DAG of jobs, once built (``lambda: workflow.dag``).
    warn : callable
        Called with the sentence when the results are out of date.
    say : callable
        Called with the sentence otherwise (up to date, or nothing made yet).
    made : callable
        Whether any of the configuration's results exists.
    """

    #: Why a job would run, in words: (attribute of Snakemake's reason, words);
    #: the code of sim/ and analysis/ travels as a param (sim/digest.py).
    REASONS = (("params_changed", "code or settings changed"),
               ("code_changed", "a rule's command changed"),
               ("input_changed", "inputs changed"), ("updated_input", "inputs changed"),
               ("software_stack_changed", "software changed"),
               ("incomplete_output", "a job was killed while making them"),
               ("missing_output", "files they need are missing"))

    def __init__(self, dag, warn, say, made):
        self._dag = dag
        self._warn = warn
        self._say = say
        self._made = made
        self._text = None

    def __str__(self):
        if self._text is None:
            self._text = self.judge(self._dag())
        return self._text

    def judge(self, dag):
        """The sentence on the jobs of `dag`, said on the terminal (a warning when
        results are out of date)."""
        if not self._made():
            text = ("Nothing made yet: none of this configuration's results exists, so there is "
                    "nothing to be up to date. Run the workflow (make run for the study), then "
                    "make the report again.")
            self._say(f"Report: {text}")
            return text
        jobs = [job for job in dag.needrun_jobs() if job.output]
        stale = [str(f) for job in jobs for f in job.output if os.path.exists(f)]
        if not stale:
            text = ("Up to date: Snakemake would remake none of these results (their code, "
                    "settings and inputs have not changed since they were made).")
            self._say(f"Report: {text}")
            return text
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
        self._warn(f"Report: {text}")
        return text
