"""The piles of a configuration: their protocols and seeds, the files that
make them (targets), and the checks of them before any job.

Their stages are :class:`workflow.stages.Stages`, the paths of their files
:class:`workflow.pile_paths.PilePaths`; the settings each simulation job receives
are :class:`workflow.jobs.JobSettings`. The rule files reach all of them
through :class:`workflow.study.Study`.
"""

from sim.preflight import check_piles
from workflow.pile_paths import PilePaths
from workflow.stages import Stages

#: The two protocols the simulator knows, in the workflow's fixed order.
ALL_PROTOCOLS = ("wedge", "layered")
#: Piles of more particles than this are not drawn by :meth:`Piles.preflight`
#: (about 0.3 ms a particle: 7 s here, every time the workflow is started).
PREFLIGHT_PARTICLES = 20_000


class Piles:
    """The piles of a validated configuration, their stages and where their files lie.

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
        #: The stages of every pile (config ``probe``).
        self.stages = Stages(config)
        #: The paths of the piles' files in the results folder (config ``results``).
        self.paths = PilePaths(config["results"])

    def seeds(self, protocol):
        """Seeds (ints) of the piles of `protocol`, in config order."""
        return [int(s) for s in self.config["protocols"][protocol]["seeds"]]

    def each(self):
        """(protocol, seed) of every pile, protocol by protocol."""
        return [(p, s) for p in self.protocols for s in self.seeds(p)]

    # --- targets ---------------------------------------------------------

    def targets(self, stages=None):
        """All particle-state files of the configured piles (default: every stage)."""
        stages = self.stages.all_stages() if stages is None else stages
        return [self.paths.pile(protocol, seed, stage) for protocol, seed in self.each() for stage in stages]

    def figure_targets(self, stage="relaxed"):
        """Pictures of all configured piles at one stage."""
        return [self.paths.pile_figure(protocol, seed, stage) for protocol, seed in self.each()]

    def benchmarks(self):
        """Benchmark files of every simulation job of the piles (pour, relax, each probe)."""
        return [self.paths.stage_benchmark(protocol, seed, stage)
                for protocol, seed in self.each() for stage in self.stages.all_stages()]

    # --- checks ----------------------------------------------------------

    def problems(self):
        """The workflow's own checks of the piles' stages and probes
        (:meth:`workflow.stages.Stages.problems`), which neither the schemas
        nor the packages' checks (workflow/validation.py) express.

        Returns
        -------
        list of str
            One message per problem; empty for a usable configuration.
        """
        return self.stages.problems()

    def preflight(self, sim):
        """The simulator's own refusals of these piles, before any job runs.

        :func:`sim.preflight.check_piles` on the first seed (a time step that
        cannot carry the fall from the release height or the relaxation of
        the tallest pile the particles can make, particles the shape recipe
        cannot draw): what the pour or the relaxation would otherwise refuse
        only when it starts, after other jobs. It draws that seed's particles
        (about a second for 3500); above :data:`PREFLIGHT_PARTICLES` it is
        left to the pour, which makes the same checks when it starts.

        Parameters
        ----------
        sim : sim.config.SimConfig
            The simulator's sections of this configuration, as validated
            (:func:`workflow.validation.validate_config`).

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
            check_piles(sim, self.protocols, first[0])
        except ValueError as exc:  # sim.config.ConfigError, or the step rule's refusal of model.dt
            return [str(exc)]
        return []
