# Gravity probes: lower gravity of a relaxed pile to (1 - Delta) g0 and let it
# come to rest again. One stage per level in config probe.levels: the first is
# `reduced` (docs/formats.md), the others reducedNN (NN = round(100 Delta)). With
# probe.tilts, gravity of the relaxed pile also gets a horizontal component
# +-delta g0 (stages tiltpNN, tiltmNN); with probe.restore, full gravity comes
# back after `reduced` (stage restored). With probe.stretch, the support of the
# relaxed pile is stretched by that strain instead (stage stretched), a load
# that no change of gravity makes.

from workflow.stages import STAGE_PATTERN, probe_input_stage


rule probe:
    input:
        state=lambda wc: study.paths.pile(wc.protocol, wc.seed, probe_input_stage(wc.stage)),
        compiled=study.paths.compiled_flag,
    output:
        study.paths.pile("{protocol}", "{seed}", "{stage}"),
    wildcard_constraints:
        stage=STAGE_PATTERN,
    params:
        code=study.code.sim,
        sim=lambda wildcards: study.jobs.probe_job_params(wildcards.stage),
        bookkeeping=study.jobs.job_bookkeeping(),
        change=lambda wildcards: study.stages.probe_change(wildcards.stage),
    log:
        study.paths.stage_log("{protocol}", "{seed}", "{stage}"),
    benchmark:
        study.paths.stage_benchmark("{protocol}", "{seed}", "{stage}")
    threads: study.resources.threads
    resources:
        mem_mb=study.resources.sim_mem_mb,
        runtime=study.resources.probe_runtime_min,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.sim_shell(
            "probe --params {params.sim:q} --bookkeeping {params.bookkeeping:q}"
            " --input {input.state:q} {params.change:q}"
            " --out {output:q} > {log:q} 2>&1"
        )
