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
# Expects from common.smk: config (validated, defaults filled), sim_shell(),
# py_shell(), results_path(), SIM_DIGEST, ANALYSIS_NUMERICS_DIGEST, COMPILED_FLAG,
# SIM_THREADS, sim_mem_mb, sim_bookkeeping(), ANALYSIS_PARAMS, and pile_numerics,
# NUMERICS_PILES, NUMERICS_ENSEMBLE, NUMERICS_DIR (workflow/numerics_piles.py).


wildcard_constraints:
    integrator="gear|verlet",
    factor=r"[0-9.e+-]+",


rule numerics_pile_pour:
    input:
        compiled=COMPILED_FLAG,
    output:
        state=pile_numerics.pile("{integrator}", "{factor}", "{seed}", "poured"),
        cpu=pile_numerics.cpu("{integrator}", "{factor}", "{seed}", "pour"),
    params:
        code=SIM_DIGEST,
        sim=lambda wildcards: pile_numerics.sim_params(wildcards, ("particles",)),
        bookkeeping=sim_bookkeeping(),
        protocol=NUMERICS_PILES["protocol"],
        checkpoint=lambda wildcards: pile_numerics.pile(wildcards.integrator, wildcards.factor, wildcards.seed,
                                                   "pour.checkpoint"),
    log:
        results_path("logs/numerics/piles/{integrator}/dt_factor{factor}/seed{seed}_pour.log"),
    benchmark:
        pile_numerics.benchmark("{integrator}", "{factor}", "{seed}", "pour")
    threads: SIM_THREADS
    resources:
        mem_mb=sim_mem_mb,
        runtime=30,
    conda:
        "../envs/polypile.yaml"
    shell:
        sim_shell(
            "pour --params {params.sim:q} --bookkeeping {params.bookkeeping:q}"
            " --protocol {params.protocol:q} --seed {wildcards.seed}"
            " --out {output.state:q} --checkpoint {params.checkpoint:q} > {log:q} 2>&1"
        )
        + "; times > {output.cpu:q}"


rule numerics_pile_relax:
    input:
        state=pile_numerics.pile("{integrator}", "{factor}", "{seed}", "poured"),
        compiled=COMPILED_FLAG,
    output:
        state=pile_numerics.pile("{integrator}", "{factor}", "{seed}", "relaxed"),
        cpu=pile_numerics.cpu("{integrator}", "{factor}", "{seed}", "relax"),
    params:
        code=SIM_DIGEST,
        sim=lambda wildcards: pile_numerics.sim_params(wildcards, ("relax",)),
        bookkeeping=sim_bookkeeping(),
    log:
        results_path("logs/numerics/piles/{integrator}/dt_factor{factor}/seed{seed}_relax.log"),
    benchmark:
        pile_numerics.benchmark("{integrator}", "{factor}", "{seed}", "relax")
    threads: SIM_THREADS
    resources:
        mem_mb=sim_mem_mb,
        runtime=30,
    conda:
        "../envs/polypile.yaml"
    shell:
        sim_shell(
            "relax --params {params.sim:q} --bookkeeping {params.bookkeeping:q}"
            " --input {input.state:q} --out {output.state:q} > {log:q} 2>&1"
        )
        + "; times > {output.cpu:q}"


rule numerics_pile_summary:
    # Shape of a relaxed small pile (flank angles, coordination) as the
    # simulator measures it: one JSON line.
    input:
        state=pile_numerics.pile("{integrator}", "{factor}", "{seed}", "relaxed"),
    output:
        pile_numerics.summary("{integrator}", "{factor}", "{seed}", "relaxed"),
    log:
        results_path("logs/numerics/piles/{integrator}/dt_factor{factor}/seed{seed}_summary.log"),
    localrule: True
    threads: 1
    conda:
        "../envs/polypile.yaml"
    shell:
        sim_shell("summary {input.state:q} > {output:q} 2> {log:q}", numba=False)


rule numerics_piles_data:
    # Observables of every small pile and their errors against the reference.
    input:
        states=pile_numerics.pile_inputs("states"),
        summaries=pile_numerics.pile_inputs("summaries"),
        pour=pile_numerics.pile_inputs("pour"),
        relax=pile_numerics.pile_inputs("relax"),
        pour_cpu=pile_numerics.pile_inputs("pour_cpu"),
        relax_cpu=pile_numerics.pile_inputs("relax_cpu"),
    output:
        f"{NUMERICS_DIR}/piles.nc",
    params:
        code=ANALYSIS_NUMERICS_DIGEST,
        cfg=json.dumps(NUMERICS_PILES, sort_keys=True),
    log:
        results_path("logs/numerics/piles_data.log"),
    threads: 1
    resources:
        mem_mb=sim_mem_mb,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis.numerics.pile_precision data --params {params.cfg:q} --states {input.states:q}"
            " --summaries {input.summaries:q}"
            " --pour-benchmarks {input.pour:q} --relax-benchmarks {input.relax:q}"
            " --pour-cpu {input.pour_cpu:q} --relax-cpu {input.relax_cpu:q} --out {output:q} > {log:q} 2>&1"
        )


rule numerics_ensemble:
    # Headline results per pile of the study, their standard error against n and compute time.
    input:
        fields=pile_numerics.ensemble_inputs("fields"),
        base_pressure=pile_numerics.ensemble_inputs("base_pressure"),
        pour=pile_numerics.ensemble_inputs("pour"),
        relax=pile_numerics.ensemble_inputs("relax"),
        probe=pile_numerics.ensemble_inputs("probe"),
    output:
        f"{NUMERICS_DIR}/ensemble.nc",
    params:
        code=ANALYSIS_NUMERICS_DIGEST,
        cfg=json.dumps(NUMERICS_ENSEMBLE, sort_keys=True),
        analysis=ANALYSIS_PARAMS,
        protocols=pile_numerics.ensemble_args(),
    log:
        results_path("logs/numerics/ensemble.log"),
    threads: 1
    resources:
        mem_mb=sim_mem_mb,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis.numerics.ensemble_cost data --params {params.cfg:q} --analysis-params {params.analysis:q}"
            " {params.protocols:q} --out {output:q} > {log:q} 2>&1"
        )


rule numerics_piles_figures:
    input:
        piles=f"{NUMERICS_DIR}/piles.nc",
        ensemble=f"{NUMERICS_DIR}/ensemble.nc",
    output:
        piles=report(f"{NUMERICS_DIR}/pile_error.png", caption="../report/numerics/pile_error.rst",
                     category="Numerics", subcategory="Piles"),
        piles_pdf=f"{NUMERICS_DIR}/pile_error.pdf",
        ensemble=report(f"{NUMERICS_DIR}/ensemble_error.png", caption="../report/numerics/ensemble_error.rst",
                        category="Numerics", subcategory="Ensemble"),
        ensemble_pdf=f"{NUMERICS_DIR}/ensemble_error.pdf",
    params:
        code=ANALYSIS_NUMERICS_DIGEST,
    log:
        results_path("logs/numerics/piles_figures.log"),
    threads: 1
    resources:
        mem_mb=sim_mem_mb,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        "("
        + py_shell("-m analysis.numerics.pile_precision figure --data {input.piles:q} "
                   "--out {output.piles:q} {output.piles_pdf:q}")
        + " && "
        + py_shell("-m analysis.numerics.ensemble_cost figure --data {input.ensemble:q} "
                   "--out {output.ensemble:q} {output.ensemble_pdf:q}")
        + ") > {log:q} 2>&1"


rule numerics_piles_table:
    # The markdown tables for the report.
    input:
        piles=f"{NUMERICS_DIR}/piles.nc",
        ensemble=f"{NUMERICS_DIR}/ensemble.nc",
    output:
        report(f"{NUMERICS_DIR}/piles.md", caption="../report/numerics/piles_table.rst",
               category="Numerics", subcategory="Tables"),
    params:
        code=ANALYSIS_NUMERICS_DIGEST,
        model=json.dumps(config["model"], sort_keys=True),
    log:
        results_path("logs/numerics/piles_table.log"),
    threads: 1
    resources:
        mem_mb=sim_mem_mb,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis.numerics.piles_report --piles {input.piles:q} --ensemble {input.ensemble:q}"
            " --model {params.model:q} --out {output:q} > {log:q} 2>&1"
        )


rule numerics_piles:
    # Error of pile observables against run time and of the ensemble against compute time.
    input:
        pile_numerics.targets(),
    localrule: True
