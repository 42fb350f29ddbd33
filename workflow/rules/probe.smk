# Gravity probes: lower gravity of a relaxed pile to (1 - Delta) g0 and let it
# come to rest again. One stage per level in config probe.levels: the first is
# `reduced` (docs/formats.md), the others reducedNN (NN = round(100 Delta)). With
# probe.tilts, gravity of the relaxed pile also gets a horizontal component
# +-delta g0 (stages tiltpNN, tiltmNN); with probe.restore, full gravity comes
# back after `reduced` (stage restored). With probe.stretch, the support of the
# relaxed pile is stretched by that strain instead (stage stretched), a load
# that no change of gravity makes.


rule probe:
    input:
        state=lambda wc: pile(wc.protocol, wc.seed, probe_input_stage(wc.stage)),
        compiled=COMPILED_FLAG,
    output:
        pile("{protocol}", "{seed}", "{stage}"),
    wildcard_constraints:
        stage=STAGE_PATTERN,
    params:
        code=SIM_DIGEST,
        sim=lambda wildcards: probe_sim_params(wildcards.stage),
        bookkeeping=sim_bookkeeping(),
        change=lambda wildcards: probe_change(wildcards.stage),
    log:
        stage_log("{protocol}", "{seed}", "{stage}"),
    benchmark:
        stage_benchmark("{protocol}", "{seed}", "{stage}")
    threads: SIM_THREADS
    resources:
        mem_mb=sim_mem_mb,
        runtime=probe_runtime_min,
    conda:
        "../envs/polypile.yaml"
    shell:
        sim_shell(
            "probe --params {params.sim:q} --bookkeeping {params.bookkeeping:q}"
            " --input {input.state:q} {params.change:q}"
            " --out {output:q} > {log:q} 2>&1"
        )
