# Building a pile: particles poured from a point source (wedge) or from a line
# source following the width of the pile's top (layered).

from workflow.jobs import Unrecorded
from workflow.resources import per_attempt


rule compile_kernels:
    # Compile (and cache in .numba_cache) every Numba kernel once, before the
    # simulation jobs fan out, so that parallel jobs do not race on the cache.
    # The message says so when it starts: the first time the terminal stays
    # silent while it compiles.
    output:
        touch(study.paths.compiled_flag),
    message:
        "Compiling the simulator's Numba kernels into .numba_cache/ (unless this code's are there "
        "already): about a minute the first time (47 s on a loaded 2-core AMD EPYC host), with "
        "nothing printed meanwhile; its log: {log}"
    params:
        code=study.code.sim,
    log:
        study.paths.results_path("logs/compile_kernels.log"),
    benchmark:
        study.paths.results_path("benchmarks/compile_kernels.tsv")
    threads: study.resources.threads
    resources:
        mem_mb=study.resources.sim_mem_mb,
        runtime=per_attempt(15),
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.sim_shell(
            "warmup > {log:q} 2>&1"
        )


rule pour:
    input:
        compiled=study.paths.compiled_flag,
    output:
        poured=study.paths.pile("{protocol}", "{seed}", "poured"),
        # the frames of a film of the pour, only when the scene asks for one
        **({"frames": study.paths.pile_frames("{protocol}", "{seed}")} if study.outputs.wants("film") else {}),
    params:
        code=study.code.sim,
        sim=study.sim.job_params("pour"),
        bookkeeping=study.jobs.job_bookkeeping(),
        checkpoint=lambda wildcards: study.paths.pour_checkpoint(wildcards.protocol, wildcards.seed),
        # the finished pour kept apart (PilePaths.pour_finished): Snakemake,
        # interrupted while the pour ran, marks the outputs of the pour that
        # then finishes incomplete, and its rerun deletes them; the rerun's
        # pour takes this copy instead of pouring again.
        # Unrecorded, as run_log: where the copy lies changes no result
        finished=lambda wildcards: Unrecorded(study.paths.pour_finished(wildcards.protocol, wildcards.seed)),
        # empty: no frames (an empty :q field vanishes, leaving --frames without
        # a value, which the simulator reads as none); Unrecorded, so that a
        # scene without film re-pours nothing that a scene with film poured
        frames=lambda wildcards, output: Unrecorded(output.frames if study.outputs.wants("film") else ""),
        # the pile's log over every run of its pour (study.paths.pour_log())
        run_log=lambda wildcards: Unrecorded(study.paths.pour_log(wildcards.protocol, wildcards.seed)),
    log:
        # what this job printed. Not the pile's log: Snakemake deletes a job's
        # log before the job runs, so a second run of the pour (a --nolock
        # Snakemake, a rerun beside a pour left running) deleted the running
        # pour's log before the simulator's lock refused it
        study.paths.results_path("logs/pour/{protocol}/seed{seed}.job.log"),
    benchmark:
        study.paths.stage_benchmark("{protocol}", "{seed}", "poured")
    threads: study.resources.threads
    resources:
        mem_mb=study.resources.sim_mem_mb,
        runtime=study.resources.pour_runtime_min,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.sim_shell(
            "pour --params {params.sim:q} --bookkeeping {params.bookkeeping:q}"
            " --protocol {wildcards.protocol} --seed {wildcards.seed}"
            " --out {output.poured:q} --checkpoint {params.checkpoint:q} --frames {params.frames:q}"
            " --finished {params.finished:q} --log {params.run_log:q} > {log:q} 2>&1"
        )
