# Pictures of pile states: polygons to scale, coloured by the particle
# pressure of Eq. 2, with the contact-force network; and the same states as
# VTK files for ParaView (output vtk).


rule draw_pile:
    input:
        state=pile("{protocol}", "{seed}", "{stage}"),
        code=ANALYSIS_CODE,
    output:
        report(
            pile_figure("{protocol}", "{seed}", "{stage}"),
            caption="../report/pile.rst",
            category="Piles",
            subcategory="{protocol}",
            labels={"protocol": "{protocol}", "seed": "{seed}", "stage": "{stage}"},
        ),
    wildcard_constraints:
        stage=PILE_STAGE_PATTERN,
    log:
        "logs/draw_pile/{protocol}_seed{seed}_{stage}.log",
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
        py_shell("-m analysis draw --input {input.state:q} --out {output:q} > {log:q} 2>&1")


rule export_pile:
    # A pile state as two VTK unstructured grids: the polygons, and the
    # contact network with its forces (analysis/vtk.py).
    input:
        state=pile("{protocol}", "{seed}", "{stage}"),
        code=ANALYSIS_CODE,
    output:
        particles=pile_vtk("{protocol}", "{seed}", "{stage}"),
        contacts=pile_vtk("{protocol}", "{seed}", "{stage}").replace(".vtu", "_contacts.vtu"),
    wildcard_constraints:
        stage=PILE_STAGE_PATTERN,
    log:
        "logs/export_pile/{protocol}_seed{seed}_{stage}.log",
    localrule: True
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell("-m analysis export --input {input.state:q} --vtk {output.particles:q} > {log:q} 2>&1")

