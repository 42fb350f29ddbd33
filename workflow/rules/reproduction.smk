# The study's record: each finished pile's compact results, committed under
# docs/reproduction/ (rule record_pile), and the ensembles, fits, figures and
# per-pile table rebuilt from those files alone (`make reproduction`: config
# `committed`, rule reproduction), without a state file or a simulation.
# The rules read `study` (workflow/study.py). The tables and numbers are made by
# the tools of workflow/tools/ (python -m workflow.tools NAME); each such rule's
# input `tool` is the tool's module, so that changing it remakes its output, and
# its param `code` the digest of the analysis it runs (study.code, as every rule
# of analysis.smk carries it), so that changing analysis/ remakes it too;
# pile_summary carries the simulator's (it runs python -m sim summary).

import os

from workflow.analysis_inputs import ANALYSIS_FIGURES, labelled

RECORD = "docs/reproduction"
# The files of a recorded pile, under RECORD/{protocol}/: the kinds of study.analysis.pile_results,
# the run summary and the pour's benchmark.
RECORD_FILES = {**{kind: committed for kind, (_, committed) in study.analysis.pile_results.items()},
                "pour": "{protocol}/seed{seed}.pour.tsv"}


rule pile_summary:
    # One JSON line per stage: particles, height, width, flank angles,
    # coordination, support reaction against weight (python -m sim summary).
    input:
        states=lambda wc: [study.paths.pile(wc.protocol, wc.seed, s) for s in ["poured", "relaxed"] + study.stages.probe_stages()],
    output:
        study.paths.results_path("fields/{protocol}/seed{seed}.summary.json"),
    params:
        code=study.code.sim,
    log:
        study.paths.results_path("logs/pile_summary/{protocol}/seed{seed}.log"),
    localrule: True
    threads: 1
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.sim_shell("summary {input.states:q} > {output:q} 2> {log:q}", numba=False)


if not config["committed"]:

    rule record_pile:
        # Copies a finished pile's compact results into docs/reproduction/
        # (commit them by hand); the fields, balance checks, base pressure,
        # convergence data, summary and the pour's benchmark, and with the
        # extra probes (config/scenes/elastic_probes.yaml) their increments.
        input:
            **{kind: study.analysis.pile_result("{protocol}", "{seed}", kind) for kind in study.analysis.pile_results},
            pour=study.paths.stage_benchmark("{protocol}", "{seed}", "poured"),
        output:
            **{kind: f"{RECORD}/{name}" for kind, name in RECORD_FILES.items()},
        log:
            study.paths.results_path("logs/record_pile/{protocol}/seed{seed}.log"),
        localrule: True
        threads: 1
        conda:
            "../envs/polypile.yaml"
        shell:
            " && ".join(f"cp -v {{input.{kind}:q}} {{output.{kind}:q}} >> {{log:q}}" for kind in RECORD_FILES)


if config["committed"]:

    # The full-size variants (issue 25): each config/variants/NAME.yaml whose
    # piles are recorded under {committed}/variants/NAME/, compared side by
    # side with the study's piles in {committed}/variants/NAME.md.
    VARIANTS = sorted(p.stem for p in (study.repo / "config" / "variants").glob("*.yaml")
                      if any((study.analysis.committed / "variants" / p.stem).glob("*/seed*.summary.json")))

    # The variants with a pile probed by the support stretch (config/scenes/six_constants.yaml):
    # all six elastic constants, in {committed}/variants/NAME/six_constants.md.
    from analysis.anisotropy import has_stretch  # here: reads netCDF, only `make reproduction` needs it

    SIX_CONSTANT_VARIANTS = [v for v in VARIANTS
                             if any(has_stretch(f) for f in (study.analysis.committed / "variants" / v).glob("*/seed*.probes.nc"))]

    # Issue 44: the calibration of the sources (one record per pile, {committed}/calibration/)
    # and the pre-registered decision (config/decision.yaml, records in {committed}/decision/).
    CALIBRATION_RECORDS = sorted(str(p) for p in (study.analysis.committed / "calibration").glob("*.json"))
    # The levers (config/levers.yaml): calibration arms with one setting changed, records in {committed}/levers/.
    LEVER_RECORDS = sorted(str(p) for p in (study.analysis.committed / "levers").glob("*.json"))
    # The registered decisions (config/NAME.yaml, records in {committed}/NAME/, verdict page
    # {committed}/NAME.md): the first (decision), the equal-slope one and its 3500-particle
    # secondary. A verdict page is made when its plan and records are there (decision verdict
    # refuses an empty or missing folder; short of N piles it writes how far the ensemble is).
    DECISION_RECORDS = {name: sorted(str(p) for p in (study.analysis.committed / name).glob("*.json"))
                        for name in ("decision", "decision_equal_slope", "decision_equal_slope_3500")
                        if (study.repo / "config" / f"{name}.yaml").exists()}
    DECISION_RECORDS = {name: records for name, records in DECISION_RECORDS.items() if records}

    rule reproduction:
        # make reproduction: the figures and the per-pile table, from the
        # committed per-pile results only.
        input:
            study.analysis.targets(),
            figures=expand(str(study.analysis.committed / "figures" / "{stem}.png"),
                           stem=[stem for stem, output in ANALYSIS_FIGURES.items() if study.outputs.wants(output)]
                           + (["general_fit"] if study.analysis.reported_general_protocols() else [])),
            table=str(study.analysis.committed / "piles.md"),
            numbers=str(study.analysis.committed / "numbers.md"),
            variants=expand(str(study.analysis.committed / "variants" / "{variant}.md"), variant=VARIANTS),
            six_constants=expand(str(study.analysis.committed / "variants" / "{variant}" / "six_constants.md"),
                                 variant=SIX_CONSTANT_VARIANTS),
            calibration=[str(study.analysis.committed / "calibration.md")] if CALIBRATION_RECORDS else [],
            levers=[str(study.analysis.committed / "levers.md")] if LEVER_RECORDS else [],
            decisions=[str(study.analysis.committed / f"{name}.md") for name in DECISION_RECORDS],
        localrule: True

    rule reproduction_calibration:
        input:
            records=CALIBRATION_RECORDS,
            config="config/calibration.yaml",
            tool="workflow/tools/calibration.py",
        output:
            str(study.analysis.committed / "calibration.md"),
        params:
            code=study.code.analysis,
            records=str(study.analysis.committed / "calibration"),
        log:
            study.paths.results_path("logs/reproduction/calibration.log"),
        localrule: True
        conda:
            "../envs/polypile.yaml"
        shell:
            study.commands.py_shell("-m workflow.tools calibration --table --config {input.config:q} --records {params.records:q} "
                     "--out {output:q} > {log:q} 2>&1")

    rule reproduction_levers:
        input:
            records=LEVER_RECORDS,
            baseline=CALIBRATION_RECORDS,
            config="config/levers.yaml",
            tool="workflow/tools/calibration.py",
        output:
            str(study.analysis.committed / "levers.md"),
        params:
            code=study.code.analysis,
            records=str(study.analysis.committed / "levers"),
            baseline=str(study.analysis.committed / "calibration"),
        log:
            study.paths.results_path("logs/reproduction/levers.log"),
        localrule: True
        conda:
            "../envs/polypile.yaml"
        shell:
            study.commands.py_shell("-m workflow.tools calibration --table --config {input.config:q} --records {params.records:q} "
                     "--baseline {params.baseline:q} --out {output:q} > {log:q} 2>&1")

    rule reproduction_decision:
        input:
            records=lambda wc: DECISION_RECORDS[wc.name],
            calibration=lambda wc: sorted(str(p) for p in (study.analysis.committed / "calibration").glob("*.json")),
            plan=lambda wc: str(study.repo / "config" / f"{wc.name}.yaml"),
            tool="workflow/tools/decision_pages.py",
        output:
            str(study.analysis.committed / "{name}.md"),
        wildcard_constraints:
            name="|".join(DECISION_RECORDS) or "(?!)",
        params:
            code=study.code.analysis,
            records=lambda wc: str(study.analysis.committed / wc.name),
        log:
            study.paths.results_path("logs/reproduction/{name}.log"),
        localrule: True
        conda:
            "../envs/polypile.yaml"
        shell:
            study.commands.py_shell("-m workflow.tools decision verdict --plan {input.plan:q} --records {params.records:q} "
                                    "--out {output:q} > {log:q} 2>&1")

    rule reproduction_figure:
        input:
            study.paths.results_path("figures/{stem}.png"),
        output:
            str(study.analysis.committed / "figures" / "{stem}.png"),
        log:
            study.paths.results_path("logs/reproduction/{stem}.log"),
        localrule: True
        conda:
            "../envs/polypile.yaml"
        shell:
            "cp -v {input:q} {output:q} > {log:q}"

    rule reproduction_table:
        input:
            summaries=[study.analysis.pile_result(p, s, "summary") for p in study.piles.protocols for s in study.analysis.analysis_seeds(p, "summary")],
            tool="workflow/tools/piles_table.py",
        output:
            str(study.analysis.committed / "piles.md"),
        log:
            study.paths.results_path("logs/reproduction/piles_table.log"),
        localrule: True
        conda:
            "../envs/polypile.yaml"
        shell:
            study.commands.py_shell("-m workflow.tools piles_table {input.summaries:q} > {output:q} 2> {log:q}")

    rule reproduction_numbers:
        # The numbers docs/reproduction.md sets against the paper's, into the
        # committed folder: docs/reproduction/numbers.md under make reproduction.
        input:
            ensembles=expand(study.paths.results_path("ensemble/{protocol}/{name}"), protocol=study.piles.protocols,
                             name=["fields.nc", "base_pressure.nc", "moduli.nc", "invariants.nc"]),
            convergence=[study.analysis.pile_result(p, s, "convergence") for p in study.piles.protocols
                         for s in study.analysis.analysis_seeds(p, "convergence")],
            checks=[study.analysis.pile_result(p, s, "checks") for p in study.piles.protocols for s in study.analysis.analysis_seeds(p, "checks")],
            fields=[study.analysis.pile_result(p, s, "fields") for p in study.piles.protocols for s in study.analysis.analysis_seeds(p, "fields")],
            base_pressure=[study.analysis.pile_result(p, s, "base_pressure") for p in study.piles.protocols
                           for s in study.analysis.analysis_seeds(p, "base_pressure")],
            general=expand(study.paths.results_path("ensemble/{protocol}/general_moduli.nc"), protocol=study.analysis.reported_general_protocols()),
            probes=[path for _, path in study.analysis.reported_probes()],
            tool="workflow/tools/reproduction_numbers.py",
        output:
            str(study.analysis.committed / "numbers.md"),
        params:
            code=study.code.analysis,
            # the folder of the ensembles: {results}/ensemble
            ensemble=lambda wc, input: os.path.dirname(os.path.dirname(input.ensembles[0])),
            protocols=study.piles.protocols,
            heights=config["analysis"]["figures"]["heights"],
            general=lambda wc, input: labelled(input.general, study.analysis.reported_general_protocols()),
            probes=[f"{p}={path}" for p, path in study.analysis.reported_probes()],
            fields=[f"{p}={study.analysis.pile_result(p, s, 'fields')}" for p in study.piles.protocols for s in study.analysis.analysis_seeds(p, "fields")],
            base_pressure=[f"{p}={study.analysis.pile_result(p, s, 'base_pressure')}" for p in study.piles.protocols
                           for s in study.analysis.analysis_seeds(p, "base_pressure")],
            cfg=study.analysis.params,
        log:
            study.paths.results_path("logs/reproduction/numbers.log"),
        localrule: True
        conda:
            "../envs/polypile.yaml"
        shell:
            study.commands.py_shell(
                "-m workflow.tools reproduction_numbers --ensemble {params.ensemble:q} --protocols {params.protocols:q} "
                "--convergence {input.convergence:q} --checks {input.checks:q} --heights {params.heights:q} "
                "--general {params.general:q} --probes {params.probes:q} --fields {params.fields:q} "
                "--base-pressure {params.base_pressure:q} --params {params.cfg:q} > {output:q} 2> {log:q}"
            )

    rule reproduction_variant:
        # A full-size variant against the study, pile by pile and paired by seed.
        wildcard_constraints:
            variant="[^/]+",
        input:
            study=lambda wc: sorted(str(f) for f in study.analysis.committed.glob("*/seed*.*")),
            variant=lambda wc: sorted(str(f) for f in (study.analysis.committed / "variants" / wc.variant).glob("*/seed*.*")),
            overlay="config/variants/{variant}.yaml",
            tool="workflow/tools/variant_table.py",
        output:
            str(study.analysis.committed / "variants" / "{variant}.md"),
        params:
            code=study.code.analysis,
            # relative to the repository, as the table names them
            study=config["committed"],
            variant=lambda wc: f"{config['committed']}/variants/{wc.variant}",
            protocols=study.piles.protocols,
            cfg=study.analysis.params,
        log:
            study.paths.results_path("logs/reproduction/variant_{variant}.log"),
        localrule: True
        conda:
            "../envs/polypile.yaml"
        shell:
            study.commands.py_shell(
                "-m workflow.tools variant_table --study {params.study:q} --variant {params.variant:q} --overlay {input.overlay:q} "
                "--protocols {params.protocols:q} --params {params.cfg:q} > {output:q} 2> {log:q}"
            )

    rule reproduction_six_constants:
        # A variant's piles with the support stretch: the general law per RVE per pile, its
        # conditioning, anisotropy and axes, the Voigt reference and the paper's statements on
        # the choice of law; the study's fields give the scale of the scatter over piles.
        wildcard_constraints:
            variant="[^/]+",
        input:
            probes=lambda wc: sorted(str(f) for f in (study.analysis.committed / "variants" / wc.variant).glob("*/seed*.probes.nc")),
            fields=lambda wc: sorted(str(f) for f in (study.analysis.committed / "variants" / wc.variant).glob("*/seed*.fields.nc")),
            study=lambda wc: sorted(str(f) for f in study.analysis.committed.glob("*/seed*.fields.nc")),
            tool="workflow/tools/six_constants_table.py",
        output:
            table=str(study.analysis.committed / "variants" / "{variant}" / "six_constants.md"),
            figure=str(study.analysis.committed / "variants" / "{variant}" / "six_constants.png"),
        params:
            code=study.code.analysis,
            # relative to the repository, as the table names them
            study=config["committed"],
            variant=lambda wc: f"{config['committed']}/variants/{wc.variant}",
            protocols=study.piles.protocols,
            cfg=study.analysis.params,
        log:
            study.paths.results_path("logs/reproduction/six_constants_{variant}.log"),
        localrule: True
        conda:
            "../envs/polypile.yaml"
        shell:
            study.commands.py_shell(
                "-m workflow.tools six_constants_table --study {params.study:q} --variant {params.variant:q} "
                "--protocols {params.protocols:q} --params {params.cfg:q} --figure {output.figure:q} "
                "> {output.table:q} 2> {log:q}"
            )
