# Pictures of pile states: polygons to scale, coloured by the particle
# pressure of Eq. 2, with the contact-force network; the same states as
# VTK files for ParaView (output vtk); films of the pours (output film).

from workflow.stages import PILE_STAGE_PATTERN


rule draw_pile:
    input:
        state=study.paths.pile("{protocol}", "{seed}", "{stage}"),
    output:
        report(
            study.paths.pile_figure("{protocol}", "{seed}", "{stage}"),
            caption="../report/pile.rst",
            category="Piles",
            subcategory="{protocol}",
            labels={"protocol": "{protocol}", "seed": "{seed}", "stage": "{stage}"},
        ),
    wildcard_constraints:
        stage=PILE_STAGE_PATTERN,
    params:
        code=study.code.analysis,
    log:
        study.paths.results_path("logs/draw_pile/{protocol}_seed{seed}_{stage}.log"),
    # Seconds per picture: under a cluster executor it runs on the submitting
    # machine instead of queueing a cluster job.
    localrule: True
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell("-m analysis draw --input {input.state:q} --out {output:q} > {log:q} 2>&1")


rule export_pile:
    # A pile state as two VTK unstructured grids: the polygons, and the
    # contact network with its forces (analysis/vtk.py).
    input:
        state=study.paths.pile("{protocol}", "{seed}", "{stage}"),
    output:
        particles=study.paths.pile_vtk("{protocol}", "{seed}", "{stage}"),
        contacts=study.paths.pile_vtk("{protocol}", "{seed}", "{stage}").replace(".vtu", "_contacts.vtu"),
    wildcard_constraints:
        stage=PILE_STAGE_PATTERN,
    params:
        code=study.code.analysis,
    log:
        study.paths.results_path("logs/export_pile/{protocol}_seed{seed}_{stage}.log"),
    localrule: True
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell("-m analysis export --input {input.state:q} --vtk {output.particles:q} > {log:q} 2>&1")



rule film_pile:
    # A film of a pile's pour from the frames the pour wrote (output film):
    # the MP4, and an HTML page holding it that the report shows inline.
    input:
        frames=study.paths.pile_frames("{protocol}", "{seed}"),
    output:
        film=study.paths.pile_film("{protocol}", "{seed}"),
        page=report(
            study.paths.pile_film("{protocol}", "{seed}", "html"),
            caption="../report/film.rst",
            category="Films of the pours",
            subcategory="{protocol}",
            labels={"protocol": "{protocol}", "seed": "{seed}"},
        ),
    params:
        code=study.code.analysis,
    log:
        study.paths.results_path("logs/film_pile/{protocol}_seed{seed}.log"),
    benchmark:
        study.paths.results_path("benchmarks/film_pile/{protocol}_seed{seed}.tsv")
    # Seconds per film (10-20 s at full size): on the submitting machine
    # under a cluster executor, like the pictures.
    localrule: True
    threads: 1
    resources:
        mem_mb=1500,
        runtime=15,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis film --input {input.frames:q} --out {output.film:q}"
            " --html {output.page:q} > {log:q} 2>&1"
        )


rule run_times_table:
    # Wall and CPU time and peak memory of every simulation job, from the
    # benchmark files Snakemake wrote for them, as a table in the report.
    input:
        benchmarks=study.piles.benchmarks(),
    output:
        report(study.paths.run_times_table, caption="../report/run_times.rst", category="Run times"),
    params:
        code=study.code.analysis_numerics,
    log:
        study.paths.results_path("logs/run_times_table.log"),
    localrule: True
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell("-m analysis run-times --benchmarks {input.benchmarks:q} --out {output:q} > {log:q} 2>&1")
