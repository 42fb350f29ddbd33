# Pictures of pile states: polygons to scale, coloured by the particle
# pressure of Eq. 2, with the contact-force network.


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
