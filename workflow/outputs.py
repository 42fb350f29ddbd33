"""The outputs a scene asks the workflow to build (config ``outputs``),
checked against the physics it declares (model.friction, model.damping,
physics, probe.levels). Only the targets of the asked outputs are built, so a
stress-only scene never runs a gravity probe, a strain fit or a figure.
"""

#: Outputs that need the piles (pour and relax).
PILE_OUTPUTS = {"states", "fields", "strain", "fabric", "fits", "vtk", "film"}
#: What each output needs among the others.
OUTPUT_NEEDS = {"strain": "fields", "fabric": "fields", "fits": "strain"}


class Outputs:
    """The outputs a validated configuration (a scene) asks for.

    Parameters
    ----------
    piles : workflow.piles.Piles
        The piles of the configuration, which hold it (``piles.config``).
    """

    def __init__(self, piles):
        self.piles = piles
        self.config = piles.config
        self.asked = set(self.config["outputs"])

    def wants(self, output):
        """Whether the scene asks for `output` (one of the names of config ``outputs``)."""
        return output in self.asked

    def has_probes(self):
        """Whether the scene has gravity probes (config probe.levels not empty)."""
        return bool(self.config["probe"]["levels"])

    def field_quantities(self):
        """The optional quantities of the per-pile fields besides the stress
        (``python -m analysis fields --quantities``), in the analysis' order."""
        return [q for q in ("fabric", "strain") if self.wants(q)]

    def targets(self, analysis, numerics):
        """Everything the scene asks for, the input of rule ``all``.

        Parameters
        ----------
        analysis : list of str
            The analysis' targets (:meth:`workflow.analysis_inputs.AnalysisInputs.targets`).
        numerics : list of str
            The files of the numerical checks, asked for with output numerics.

        Returns
        -------
        list of str
            The pile states (output states); the pictures of the relaxed piles
            and the table of the simulation jobs' run times (output figures,
            with piles and not from committed results: they need the states);
            the VTK files; the films; the numerics; then `analysis`.
        """
        piles = self.piles
        targets = piles.targets() if self.wants("states") else []
        if self.wants("figures") and self.asked & PILE_OUTPUTS and not self.config["committed"]:
            targets += piles.figure_targets("relaxed") + [piles.paths.run_times_table]
        if self.wants("vtk"):
            targets += [piles.paths.pile_vtk(protocol, seed, "relaxed") for protocol, seed in piles.each()]
        if self.wants("film"):
            targets += [piles.paths.pile_film(protocol, seed, ext) for protocol, seed in piles.each()
                        for ext in ("mp4", "html")]
        if self.wants("numerics"):
            targets += list(numerics)
        return targets + list(analysis)

    def problems(self, repo):
        """Outputs the scene's physics or other outputs cannot give.

        Parameters
        ----------
        repo : pathlib.Path
            The repository, which config ``committed`` is relative to.

        Returns
        -------
        list of str
            One message per problem, naming the settings, their values and
            what to change; empty for a usable scene.
        """
        config, asked = self.config, self.config["outputs"]
        problems = [f"outputs {asked}: {output} needs {needed}; add {needed!r} or leave {output!r} out"
                    for output, needed in OUTPUT_NEEDS.items() if self.wants(output) and not self.wants(needed)]
        if self.wants("strain") and not self.has_probes():
            problems.append(
                f"outputs {asked}: strain is the response to a gravity probe but "
                f"probe.levels is {config['probe']['levels']}; give a level (e.g. [0.10]) "
                "or leave strain (and fits) out"
            )
        if not config["physics"]["support"] and self.asked & PILE_OUTPUTS:
            problems.append(
                f"physics.support = false with outputs {asked}: the piles are poured onto "
                f"the support; without it the only allowed output is [numerics]"
            )
        return problems + self._analysis_problems() + self._committed_problems(repo)

    def _analysis_problems(self):
        """Analysis settings that name a pile or stage outside the scene, or fields no RVE can hold."""
        config, problems = self.config, []
        seed = config["analysis"]["convergence"]["seed"]
        if self.wants("strain") and seed is not None:
            for protocol in self.piles.protocols:
                seeds = self.piles.seeds(protocol)
                if seed not in seeds:
                    problems.append(
                        f"analysis.convergence.seed = {seed} is not a seed of protocol "
                        f"{protocol} (seeds {seeds}): the convergence study would "
                        "pour a pile outside the study; give one of its seeds or null (every pile)"
                    )
        n, least = config["pour"]["n_particles"], config["analysis"]["rve"]["min_particles"]
        if self.wants("fields") and n < least:
            problems.append(
                f"pour.n_particles = {n} is fewer than analysis.rve.min_particles = {least}: no RVE of "
                f"such a pile can hold enough particles, so the fields would be empty; pour at least "
                f"{least} particles, lower analysis.rve.min_particles, or ask only outputs [states]"
            )
        stage, probes = config["analysis"]["base_pressure"]["stage"], self.piles.stages.probe_stages()
        if self.wants("fields") and stage not in ["poured", "relaxed"] + probes:
            problems.append(
                f"analysis.base_pressure.stage = {stage!r} is not a stage of this scene "
                f"(poured, relaxed and the probes {probes})"
            )
        return problems

    def _committed_problems(self, repo):
        """Committed results (config ``committed``) that are not there, or asked with outputs they cannot give."""
        committed, problems = self.config["committed"], []
        if not committed:
            return problems
        if not (repo / committed).is_dir():
            problems.append(f"committed = {committed!r}: no such folder under {repo}")
        if self.asked & {"states", "vtk", "film", "numerics"}:
            problems.append(
                f"committed = {committed!r} with outputs {self.config['outputs']}: committed results "
                "replace the simulation, so states, vtk, film and numerics cannot be asked for; "
                "leave them out of outputs"
            )
        return problems
