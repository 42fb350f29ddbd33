# Letting a poured pile come to rest under full gravity g0.


rule relax:
    input:
        state=study.paths.pile("{protocol}", "{seed}", "poured"),
        compiled=study.paths.compiled_flag,
    output:
        study.paths.pile("{protocol}", "{seed}", "relaxed"),
    params:
        code=study.code.sim,
        sim=study.sim.job_params("relax"),
        bookkeeping=study.jobs.job_bookkeeping(),
    log:
        study.paths.stage_log("{protocol}", "{seed}", "relaxed"),
    benchmark:
        study.paths.stage_benchmark("{protocol}", "{seed}", "relaxed")
    threads: study.resources.threads
    resources:
        mem_mb=study.resources.sim_mem_mb,
        runtime=study.resources.relax_runtime_min,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.sim_shell(
            "relax --params {params.sim:q} --bookkeeping {params.bookkeeping:q}"
            " --input {input.state:q} --out {output:q} > {log:q} 2>&1"
        )
