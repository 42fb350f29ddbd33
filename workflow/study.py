"""The study of a configuration: the one object the rule files read.

workflow/rules/common.smk builds it (:meth:`Study.of_workflow`) before any
rule, and every rule file calls its parts by name: ``study.sim`` (the
simulator's settings, which write each simulation job's ``--params``),
``study.piles`` (which piles), ``study.stages`` (their stages),
``study.paths`` (where their files lie), ``study.jobs`` (what the workflow
adds to a job's settings: a probe's own keys, the unrecorded bookkeeping),
``study.resources`` (runtime and memory of those jobs), ``study.outputs`` (the
outputs asked for), ``study.analysis`` (the analysis' inputs and targets),
``study.numerics`` (the pile numerics), ``study.commands`` (the command
lines) and ``study.code`` (the digests of the code the jobs run). Building it
runs every check of the configuration, in order, so that a refusal comes
before any job; tests/test_config_fuzz.py builds the same object.
"""

import sys
from functools import cached_property
from pathlib import Path

from sim.digest import code_digest
from workflow.analysis_inputs import AnalysisInputs
from workflow.commands import Commands
from workflow.jobs import JobSettings
from workflow.numerics_piles import NumericsPiles
from workflow.piles import Piles
from workflow.resources import SimResources
from workflow.outputs import Outputs
from workflow.validation import check_config_files, check_problems, validate_config


class CodeDigests:
    """The digests of the code the jobs run, each a rule's param ``code``.

    Snakemake does not look inside the packages a command imports, but it
    re-runs a job whose recorded params changed. Each rule that runs the
    simulator carries :attr:`sim` (sim/*.py), each that runs the analysis
    :attr:`analysis` (analysis/*.py), so an edit of sim/ re-runs the
    simulations and an edit of analysis/ only the analysis, and the log lists
    a job's files, not the package's sources. A file only touched (same
    content) re-runs nothing. The numerical checks (sim/numerics/) and the
    analysis' numerics (analysis/numerics/) add their own digest to the rules
    that run them. Each digest is computed when first asked for.

    Parameters
    ----------
    repo : pathlib.Path
        The repository holding sim/ and analysis/.
    """

    def __init__(self, repo):
        self.repo = repo

    @cached_property
    def sim(self):
        """Digest of the simulator's sources, sim/*.py."""
        return code_digest(self.repo / "sim")

    @cached_property
    def analysis(self):
        """Digest of the analysis' sources, analysis/*.py."""
        return code_digest(self.repo / "analysis")

    @cached_property
    def analysis_numerics(self):
        """The analysis' digest and that of its numerics (analysis/numerics/: run
        times, precision and cost of piles)."""
        return f"{self.analysis}-{code_digest(self.repo / 'analysis' / 'numerics')}"

    @cached_property
    def numerics(self):
        """The simulator's digest and that of its numerical checks (sim/numerics/)."""
        return f"{self.sim}-{code_digest(self.repo / 'sim' / 'numerics')}"


class Study:
    """A validated configuration and everything the rules read of it.

    Building it validates `config` (filling in every default of the schemas,
    in place, so the rules see a complete config) and runs the checks in this
    order, each raising ``ValueError`` with its refusal: the piles' stages
    and probes, the simulator's preflight of the first pile, the size of a
    simulation job, the scene's outputs, and the pile numerics.

    Parameters
    ----------
    config : dict
        The workflow configuration as merged from its files.
    repo : pathlib.Path
        The repository: the code of the digests, config ``committed`` and the Numba cache lie there.
    python : str
        The interpreter of the jobs (:class:`workflow.commands.Commands`).
    mem_mb : float, Snakemake resource or None
        Snakemake's ``--resources mem_mb``, if given
        (:meth:`workflow.resources.SimResources.check_size`).
    local : bool
        Whether the jobs run on this machine rather than on a cluster.
    warn : callable
        Called with the text of a warning (an absurdly long pour).

    Raises
    ------
    ValueError
        The first refusal, naming the settings, their values and what is allowed.
    """

    def __init__(self, config, repo, python, mem_mb=None, local=True, warn=print):
        #: The simulator's sections (:class:`sim.config.SimConfig`), the one
        #: object built from them here: validated, drawn by the preflight, and
        #: the writer of each simulation job's ``--params``
        #: (:meth:`sim.config.SimConfig.job_params`).
        self.sim = validate_config(config)
        self.config = config
        self.repo = Path(repo)
        self.piles = Piles(config)
        check_problems(self.piles.problems())
        check_problems(self.piles.preflight(self.sim))
        self.stages, self.paths = self.piles.stages, self.piles.paths
        self.jobs = JobSettings(self.sim)
        self.resources = SimResources(config)
        self.resources.check_size(mem_mb, local, warn)
        self.outputs = Outputs(self.piles)
        check_problems(self.outputs.problems(self.repo), "scene")
        self.analysis = AnalysisInputs(self.outputs, self.repo)
        self.numerics = NumericsPiles(self.piles)
        check_problems(self.numerics.problems())
        #: A project-local Numba cache, filled once by rule compile_kernels
        #: before the jobs fan out.
        self.commands = Commands(python, self.repo / ".numba_cache")
        self.code = CodeDigests(self.repo)

    @classmethod
    def of_workflow(cls, workflow, config, warn):
        """The study of the running Snakemake workflow.

        First the ``--configfile`` files read again strictly
        (:func:`workflow.validation.check_config_files`): a repeated key,
        which YAML reads as its last value, and an empty section laid over
        another file, which the merge ignores, are refused naming the file
        and line. The jobs run with the interpreter running Snakemake, so
        they see the same packages without activating anything; under
        ``--software-deployment-method conda`` the rule's conda environment
        provides ``python``.

        Parameters
        ----------
        workflow : snakemake.workflow.Workflow
            The workflow (``workflow`` of a Snakefile).
        config : dict
            Its configuration (``config``).
        warn : callable
            Called with the text of a warning (Snakemake's ``logger.warning``).

        Returns
        -------
        Study

        Raises
        ------
        ValueError
            The first refusal of the files or of the configuration.
        """
        # here, not above: the modules of workflow/ import where Snakemake is not
        from snakemake.settings.types import DeploymentMethod

        check_config_files(workflow.overwrite_configfiles)
        conda = DeploymentMethod.CONDA in workflow.deployment_settings.deployment_method
        return cls(config, Path(workflow.basedir).resolve(), "python" if conda else sys.executable,
                   workflow.global_resources.get("mem_mb"), workflow.local_exec, warn)
