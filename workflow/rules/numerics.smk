# Numerical checks of the simulator (docs/numerics.md,
# "Numerics: accuracy against run time and stability"); part of `all` only when config `outputs` lists numerics;
# otherwise run `snakemake numerics`.
#   numerics_collisions: error against wall time of binary collisions
#     (python -m sim numerics collisions: sim/numerics/collisions.py)
#   numerics_stability: stiff and extreme cases, largest stable time step
#     (python -m sim numerics stability: sim/numerics/stability.py)
# Each rule receives only its own section of config["numerics"] (sorted JSON),
# so changing one re-runs only that rule. Param `code`: the digests of the
# kernels' sources sim/*.py and of the sim/numerics/ sources.

import json


rule numerics_collisions:
    input:
        compiled=study.paths.compiled_flag,
    output:
        nc=study.paths.results_path("numerics/collisions.nc"),
        figure=report(
            study.paths.results_path("numerics/collisions.png"),
            caption="../report/numerics_collisions.rst",
            category="Numerics",
        ),
        table=study.paths.results_path("numerics/collisions.md"),
    params:
        code=study.code.numerics,
        numerics=json.dumps(
            {"numerics": {"collisions": config["numerics"]["collisions"]}}, sort_keys=True
        ),
    log:
        study.paths.results_path("logs/numerics/collisions.log"),
    benchmark:
        study.paths.results_path("benchmarks/numerics/collisions.tsv")
    # one thread: the wall times are those of a serial run
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.sim_shell(
            "numerics collisions --params {params.numerics:q} --nc {output.nc:q}"
            " --figure {output.figure:q} --table {output.table:q} > {log:q} 2>&1"
        )


rule numerics_stability:
    input:
        compiled=study.paths.compiled_flag,
    output:
        nc=study.paths.results_path("numerics/stability.nc"),
        figure=report(
            study.paths.results_path("numerics/stable_dt.png"),
            caption="../report/numerics_stability.rst",
            category="Numerics",
        ),
        table=study.paths.results_path("numerics/stability.md"),
    params:
        code=study.code.numerics,
        numerics=json.dumps(
            {"numerics": {"stability": config["numerics"]["stability"]}}, sort_keys=True
        ),
    log:
        study.paths.results_path("logs/numerics/stability.log"),
    benchmark:
        study.paths.results_path("benchmarks/numerics/stability.tsv")
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.sim_shell(
            "numerics stability --params {params.numerics:q} --nc {output.nc:q}"
            " --figure {output.figure:q} --table {output.table:q} > {log:q} 2>&1"
        )


rule numerics:
    # Both numerical checks: data, figures and tables under {results}/numerics/.
    input:
        rules.numerics_collisions.output,
        rules.numerics_stability.output,
    localrule: True
