# Letting a poured pile come to rest under full gravity g0.


rule relax:
    input:
        state=pile("{protocol}", "{seed}", "poured"),
        compiled=COMPILED_FLAG,
    output:
        pile("{protocol}", "{seed}", "relaxed"),
    params:
        code=SIM_DIGEST,
        sim=sim_params("model", "pour", "relax"),
        bookkeeping=sim_bookkeeping(),
    log:
        stage_log("{protocol}", "{seed}", "relaxed"),
    benchmark:
        stage_benchmark("{protocol}", "{seed}", "relaxed")
    threads: SIM_THREADS
    resources:
        mem_mb=sim_mem_mb,
        runtime=relax_runtime_min,
    conda:
        "../envs/polypile.yaml"
    shell:
        sim_shell(
            "relax --params {params.sim:q} --bookkeeping {params.bookkeeping:q}"
            " --input {input.state:q} --out {output:q} > {log:q} 2>&1"
        )
