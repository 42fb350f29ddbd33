# Numerics of whole piles (issue #5): the error of pile observables against
# run time, and the standard error of the headline results against compute
# time as the number of seeds grows. Target: numerics_piles.
#
# Small piles: one job per (integrator, dt factor, seed) pours and one relaxes,
# each with a benchmark file (wall time) and the output of bash `times` (CPU
# time, which does not grow when other processes share the cores); the step is
# dt_factor times the automatic step of the integrator (model.dt_safety scaled
# by the factor; with model.dt given, dt scaled by the factor).
# Ensemble: reads the configured study's piles (protocols section), their
# fields and base pressure, and the benchmark files of their simulations.
#
# The rules read `study` (workflow/study.py): study.numerics is workflow/numerics_piles.py.

import json


wildcard_constraints:
    integrator="gear|verlet",
    factor=r"[0-9.e+-]+",


rule numerics_pile_pour:
    input:
        compiled=study.paths.compiled_flag,
    output:
        state=study.numerics.pile("{integrator}", "{factor}", "{seed}", "poured"),
        cpu=study.numerics.cpu("{integrator}", "{factor}", "{seed}", "pour"),
    params:
        code=study.code.sim,
        sim=lambda wildcards: study.numerics.job_params(wildcards, "pour"),
        bookkeeping=study.jobs.job_bookkeeping(),
        protocol=study.numerics.settings["protocol"],
        checkpoint=lambda wildcards: study.numerics.pile(wildcards.integrator, wildcards.factor, wildcards.seed,
                                                   "pour.checkpoint"),
    log:
        study.paths.results_path("logs/numerics/piles/{integrator}/dt_factor{factor}/seed{seed}_pour.log"),
    benchmark:
        study.numerics.benchmark("{integrator}", "{factor}", "{seed}", "pour")
    threads: study.resources.threads
    resources:
        mem_mb=study.resources.sim_mem_mb,
        runtime=30,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.sim_shell(
            "pour --params {params.sim:q} --bookkeeping {params.bookkeeping:q}"
            " --protocol {params.protocol:q} --seed {wildcards.seed}"
            " --out {output.state:q} --checkpoint {params.checkpoint:q} > {log:q} 2>&1"
        )
        + "; times > {output.cpu:q}"


rule numerics_pile_relax:
    input:
        state=study.numerics.pile("{integrator}", "{factor}", "{seed}", "poured"),
        compiled=study.paths.compiled_flag,
    output:
        state=study.numerics.pile("{integrator}", "{factor}", "{seed}", "relaxed"),
        cpu=study.numerics.cpu("{integrator}", "{factor}", "{seed}", "relax"),
    params:
        code=study.code.sim,
        sim=lambda wildcards: study.numerics.job_params(wildcards, "relax"),
        bookkeeping=study.jobs.job_bookkeeping(),
    log:
        study.paths.results_path("logs/numerics/piles/{integrator}/dt_factor{factor}/seed{seed}_relax.log"),
    benchmark:
        study.numerics.benchmark("{integrator}", "{factor}", "{seed}", "relax")
    threads: study.resources.threads
    resources:
        mem_mb=study.resources.sim_mem_mb,
        runtime=30,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.sim_shell(
            "relax --params {params.sim:q} --bookkeeping {params.bookkeeping:q}"
            " --input {input.state:q} --out {output.state:q} > {log:q} 2>&1"
        )
        + "; times > {output.cpu:q}"


rule numerics_pile_summary:
    # Shape of a relaxed small pile (flank angles, coordination) as the
    # simulator measures it: one JSON line.
    input:
        state=study.numerics.pile("{integrator}", "{factor}", "{seed}", "relaxed"),
    output:
        study.numerics.summary("{integrator}", "{factor}", "{seed}", "relaxed"),
    log:
        study.paths.results_path("logs/numerics/piles/{integrator}/dt_factor{factor}/seed{seed}_summary.log"),
    localrule: True
    threads: 1
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.sim_shell("summary {input.state:q} > {output:q} 2> {log:q}", numba=False)


rule numerics_piles_data:
    # Observables of every small pile and their errors against the reference.
    input:
        states=study.numerics.pile_inputs("states"),
        summaries=study.numerics.pile_inputs("summaries"),
        pour=study.numerics.pile_inputs("pour"),
        relax=study.numerics.pile_inputs("relax"),
        pour_cpu=study.numerics.pile_inputs("pour_cpu"),
        relax_cpu=study.numerics.pile_inputs("relax_cpu"),
    output:
        f"{study.numerics.folder}/piles.nc",
    params:
        code=study.code.analysis_numerics,
        cfg=json.dumps(study.numerics.settings, sort_keys=True),
    log:
        study.paths.results_path("logs/numerics/piles_data.log"),
    threads: 1
    resources:
        mem_mb=study.resources.sim_mem_mb,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis.numerics.pile_precision data --params {params.cfg:q} --states {input.states:q}"
            " --summaries {input.summaries:q}"
            " --pour-benchmarks {input.pour:q} --relax-benchmarks {input.relax:q}"
            " --pour-cpu {input.pour_cpu:q} --relax-cpu {input.relax_cpu:q} --out {output:q} > {log:q} 2>&1"
        )


rule numerics_ensemble:
    # Headline results per pile of the study, their standard error against n and compute time.
    input:
        fields=study.numerics.ensemble_inputs("fields"),
        base_pressure=study.numerics.ensemble_inputs("base_pressure"),
        pour=study.numerics.ensemble_inputs("pour"),
        relax=study.numerics.ensemble_inputs("relax"),
        probe=study.numerics.ensemble_inputs("probe"),
    output:
        f"{study.numerics.folder}/ensemble.nc",
    params:
        code=study.code.analysis_numerics,
        cfg=json.dumps(study.numerics.ensemble, sort_keys=True),
        analysis=study.analysis.params,
        protocols=study.numerics.ensemble_args(),
    log:
        study.paths.results_path("logs/numerics/ensemble.log"),
    threads: 1
    resources:
        mem_mb=study.resources.sim_mem_mb,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis.numerics.ensemble_cost data --params {params.cfg:q} --analysis-params {params.analysis:q}"
            " {params.protocols:q} --out {output:q} > {log:q} 2>&1"
        )


rule numerics_piles_figures:
    input:
        piles=f"{study.numerics.folder}/piles.nc",
        ensemble=f"{study.numerics.folder}/ensemble.nc",
    output:
        piles=report(f"{study.numerics.folder}/pile_error.png", caption="../report/numerics/pile_error.rst",
                     category="Numerics", subcategory="Piles"),
        piles_pdf=f"{study.numerics.folder}/pile_error.pdf",
        ensemble=report(f"{study.numerics.folder}/ensemble_error.png", caption="../report/numerics/ensemble_error.rst",
                        category="Numerics", subcategory="Ensemble"),
        ensemble_pdf=f"{study.numerics.folder}/ensemble_error.pdf",
    params:
        code=study.code.analysis_numerics,
    log:
        study.paths.results_path("logs/numerics/piles_figures.log"),
    threads: 1
    resources:
        mem_mb=study.resources.sim_mem_mb,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        "("
        + study.commands.py_shell("-m analysis.numerics.pile_precision figure --data {input.piles:q} "
                   "--out {output.piles:q} {output.piles_pdf:q}")
        + " && "
        + study.commands.py_shell("-m analysis.numerics.ensemble_cost figure --data {input.ensemble:q} "
                   "--out {output.ensemble:q} {output.ensemble_pdf:q}")
        + ") > {log:q} 2>&1"


rule numerics_piles_table:
    # The markdown tables for the report.
    input:
        piles=f"{study.numerics.folder}/piles.nc",
        ensemble=f"{study.numerics.folder}/ensemble.nc",
    output:
        report(f"{study.numerics.folder}/piles.md", caption="../report/numerics/piles_table.rst",
               category="Numerics", subcategory="Tables"),
    params:
        code=study.code.analysis_numerics,
        model=json.dumps(config["model"], sort_keys=True),
    log:
        study.paths.results_path("logs/numerics/piles_table.log"),
    threads: 1
    resources:
        mem_mb=study.resources.sim_mem_mb,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis.numerics.piles_report --piles {input.piles:q} --ensemble {input.ensemble:q}"
            " --model {params.model:q} --out {output:q} > {log:q} 2>&1"
        )


rule numerics_piles:
    # Error of pile observables against run time and of the ensemble against compute time.
    input:
        study.numerics.targets(),
    localrule: True
