"""The inputs, settings and targets of the analysis rules
(workflow/rules/analysis.smk, reproduction.smk): which per-pile results enter
the ensembles, fits and figures, computed from state files or, under config
``committed``, read from the per-pile results committed there.
"""

import os

from analysis.params import params_flow_text

#: Memory (MB) of an analysis job.
ANALYSIS_MEM_MB = 2000
#: Each figure and the output (config ``outputs``) whose data it draws.
ANALYSIS_FIGURES = {"fig1_convergence": "strain", "fig2_vertical_strain": "strain", "fig3_fabric": "fabric",
                    "fig4_moduli": "fits", "fig5_invariants": "fits", "base_pressure": "fields"}
#: The ensemble files of each output.
ANALYSIS_ENSEMBLE = {"fields": ("fields.nc", "base_pressure.nc"), "fits": ("moduli.nc", "invariants.nc")}
#: A pile's compact results, by kind: its file under {results}/fields/ and,
#: under ``committed``, under that folder (docs/reproduction/ as committed).
PILE_RESULTS = {"fields": ("{protocol}/seed{seed}.nc", "{protocol}/seed{seed}.fields.nc"),
                "checks": ("{protocol}/seed{seed}.checks.json", "{protocol}/seed{seed}.checks.json"),
                "base_pressure": ("{protocol}/seed{seed}.base_pressure.nc", "{protocol}/seed{seed}.base_pressure.nc"),
                "convergence": ("{protocol}/seed{seed}.convergence.nc", "{protocol}/seed{seed}.convergence.nc"),
                "summary": ("{protocol}/seed{seed}.summary.json", "{protocol}/seed{seed}.summary.json")}
#: The increments of every probe of a pile (rule analysis_probes), a result
#: of the piles with the extra probes (probe.tilts, probe.restore, probe.stretch).
PROBES_RESULT = ("{protocol}/seed{seed}.probes.nc", "{protocol}/seed{seed}.probes.nc")


def labelled(files, protocols):
    """The ``--inputs`` of a figure: one PROTOCOL=FILE argument per file."""
    return [f"{p}={f}" for p, f in zip(protocols, files)]


class AnalysisInputs:
    """The analysis of a validated configuration's piles.

    Parameters
    ----------
    outputs : workflow.outputs.Outputs
        The outputs of the configuration, with its piles (``outputs.piles``).
    repo : pathlib.Path
        The repository, which config ``committed`` is relative to.
    """

    def __init__(self, outputs, repo):
        self.outputs = outputs
        self.piles = piles = outputs.piles
        self.config = config = outputs.config
        #: The analysis section.
        self.cfg = config.get("analysis", {}) or {}
        #: One line of YAML flow text, keys sorted ({rve: {size: 0.08}, ...}):
        #: the analysis reads it like JSON, and the report shows it under "Job
        #: parameters" as it is (Snakemake shows the double quotes of JSON
        #: params backslash-escaped).
        self.params = params_flow_text(self.cfg)
        #: PILE_RESULTS, with the probes' increments when the piles have extra probes.
        self.pile_results = dict(PILE_RESULTS)
        if piles.stages.extra_probe_stages():
            self.pile_results["probes"] = PROBES_RESULT
        #: Folder of committed per-pile results that the analysis reads instead
        #: of computing them from state files (config ``committed``; None: compute them).
        self.committed = repo / config["committed"] if config["committed"] else None

    # --- per-pile results ------------------------------------------------

    def pile_result(self, protocol, seed, kind):
        """The file of one pile's compact result of `kind` (a key of :attr:`pile_results`)."""
        computed, committed = self.pile_results[kind]
        if self.committed is None:
            return self.piles.paths.results_path(f"fields/{computed.format(protocol=protocol, seed=seed)}")
        return str(self.committed / committed.format(protocol=protocol, seed=seed))

    def recorded_seeds(self, protocol, kind):
        """The seeds of the study whose `kind` result is there (computed or committed)."""
        return [s for s in self.piles.seeds(protocol) if os.path.exists(self.pile_result(protocol, s, kind))]

    def analysis_seeds(self, protocol, kind="fields"):
        """The seeds whose `kind` result enters the ensembles.

        Returns
        -------
        list of int
            All seeds of the study, or under ``committed`` those of them whose
            file is there.

        Raises
        ------
        ValueError
            Under ``committed``, when no pile of `protocol` has its file there,
            naming the folder, the protocol, its seeds and the file.
        """
        if self.committed is None:
            return self.piles.seeds(protocol)
        found = self.recorded_seeds(protocol, kind)
        if not found:
            raise ValueError(
                f"committed = {self.config['committed']!r}: no pile of protocol {protocol} (seeds "
                f"{self.piles.seeds(protocol)}) has its {kind} file there ({self.pile_results[kind][1]}); "
                "commit one or leave the outputs that need it out"
            )
        return found

    # --- the general fit -------------------------------------------------

    def general_fit_protocols(self):
        """The protocols of the general fit: none without the extra probes; all of
        the study, or under ``committed`` those with at least one pile's probes
        file there."""
        if not self.piles.stages.extra_probe_stages():
            return []
        if self.committed is None:
            return self.piles.protocols
        return [p for p in self.piles.protocols if self.recorded_seeds(p, "probes")]

    def reported_general_protocols(self):
        """The protocols whose general fit is built and reported: those of
        :meth:`general_fit_protocols` when the scene wants the fits, else none."""
        return self.general_fit_protocols() if self.outputs.wants("fits") else []

    def reported_probes(self):
        """(protocol, probes file) of every pile whose extra probes enter the
        reported general fit."""
        return [(p, self.pile_result(p, s, "probes")) for p in self.reported_general_protocols()
                for s in self.analysis_seeds(p, "probes")]

    # --- settings of the figures -----------------------------------------

    def setting(self, section, key, default):
        """The analysis setting `section`.`key`, or `default` where it is not given."""
        return (self.cfg.get(section) or {}).get(key, default)

    def figure_protocol(self, key):
        """Protocol drawn in a single-protocol figure (analysis.figures.`key`):
        the configured one, else the first of the study."""
        p = self.setting("figures", key, "wedge")
        return p if p in self.piles.protocols else self.piles.protocols[0]

    def convergence_seeds(self, protocol):
        """The piles of Fig. 1: every pile of the protocol (analysis.convergence.seed null), else the one given."""
        s = self.setting("convergence", "seed", None)
        return self.analysis_seeds(protocol, "convergence") if s is None else [s]

    # --- input functions of the rules (wildcards: protocol, seed) --------

    def fields(self, wildcards):
        """The fields of every pile of the protocol that enters its ensemble."""
        return [self.pile_result(wildcards.protocol, s, "fields") for s in self.analysis_seeds(wildcards.protocol)]

    def base_pressure_piles(self, wildcards):
        """The base pressure of every pile of the protocol that enters its ensemble."""
        p = wildcards.protocol
        return [self.pile_result(p, s, "base_pressure") for s in self.analysis_seeds(p, "base_pressure")]

    def convergence_files(self, wildcards=None):
        """The convergence files of Fig. 1's piles (:meth:`convergence_seeds`)."""
        p = self.figure_protocol("convergence_protocol")
        return [self.pile_result(p, s, "convergence") for s in self.convergence_seeds(p)]

    def fields_reduced(self, wildcards):
        """The reduced state of a pile's fields: with a gravity probe only (the stress increment and strain)."""
        return self.piles.paths.pile(wildcards.protocol, wildcards.seed, "reduced") if self.outputs.has_probes() else []

    @staticmethod
    def reduced_option(wildcards, input):
        """The arguments ``--reduced FILE`` of ``analysis fields`` when the pile has a reduced state, else none."""
        return ["--reduced", input.reduced] if input.reduced else []

    # --- targets ---------------------------------------------------------

    def targets(self):
        """The final outputs of the analysis that the scene asks for (for rule ``all``):
        with the piles' states (output ``states``, not from committed results) each
        pile's run summary, its height, width and flanks per stage."""
        wants, results_path = self.outputs.wants, self.piles.paths.results_path
        names = [name for output, files in ANALYSIS_ENSEMBLE.items() if wants(output) for name in files]
        targets = [results_path(f"ensemble/{p}/{name}") for p in self.piles.protocols for name in names]
        if wants("states") and self.committed is None:
            targets += [self.pile_result(p, s, "summary") for p, s in self.piles.each()]
        if wants("strain"):
            targets += self.convergence_files()
        if wants("figures"):
            targets += [results_path(f"figures/{stem}.{ext}") for stem, output in ANALYSIS_FIGURES.items()
                        if wants(output) for ext in ("png", "pdf")]
        general = self.reported_general_protocols()
        if general:
            targets += [results_path(f"ensemble/{p}/general_moduli.nc") for p in general]
            if wants("figures"):
                targets += [results_path(f"figures/general_fit.{ext}") for ext in ("png", "pdf")]
        return targets
