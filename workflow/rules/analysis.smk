# Analysis rules: particle states -> per-pile RVE fields -> ensembles -> fits -> figures.
#
# Helpers live in workflow/rules/analysis_common.smk (included first).
# Expects from workflow/rules/common.smk:
#   PROTOCOLS      list of protocol names of the study
#   seeds(p)       list of int seeds of protocol p
#   probe_stages(), extra_probe_stages()  the gravity reductions, and the tilts and restore
#   ANALYSIS_CODE  list of the analysis/*.py files (an input: code edits rerun the analysis)
#   PY, py_shell   the python executable and the helper that prefixes it to a shell command
#   and the global wildcard_constraints of protocol and seed
# and from workflow/rules/scene.smk has_probes() and field_quantities() (the scene's outputs),
# and the state files results/piles/{protocol}/seed{seed}/{stage}.nc (docs/formats.md#state-files).
#
# Every rule passes config["analysis"] as sorted JSON in params, so a change of
# an analysis setting reruns exactly the rules that read it. Figure captions
# live in workflow/report/analysis/ and are not params: editing one reruns nothing.
#
# Every rule here takes seconds (0.5 s for the fields of a 3500-particle pile),
# so under a cluster executor they run on the submitting machine (localrule)
# instead of queueing a cluster job each.

rule analysis_fields:
    input:
        relaxed="results/piles/{protocol}/seed{seed}/relaxed.nc",
        reduced=_analysis_fields_reduced,
        code=ANALYSIS_CODE,
    output:
        fields="results/fields/{protocol}/seed{seed}.nc",
        checks="results/fields/{protocol}/seed{seed}.checks.json",
    params:
        cfg=ANALYSIS_PARAMS,
        reduced=_analysis_reduced_option,
        quantities=field_quantities(),
    log:
        "logs/analysis/fields/{protocol}/seed{seed}.log",
    benchmark:
        "benchmarks/analysis/fields/{protocol}/seed{seed}.tsv"
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis fields --relaxed {input.relaxed:q} {params.reduced:q} --quantities {params.quantities:q} "
            "--params {params.cfg:q} --out {output.fields:q} --checks {output.checks:q} > {log:q} 2>&1"
        )


rule analysis_ensemble:
    input:
        fields=_analysis_fields,
        code=ANALYSIS_CODE,
    output:
        "results/ensemble/{protocol}/fields.nc",
    params:
        cfg=ANALYSIS_PARAMS,
    log:
        "logs/analysis/ensemble/{protocol}.log",
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis ensemble --fields {input.fields:q} --params {params.cfg:q} --out {output:q} > {log:q} 2>&1"
        )


rule analysis_moduli:
    input:
        ensemble="results/ensemble/{protocol}/fields.nc",
        fields=_analysis_fields,
        code=ANALYSIS_CODE,
    output:
        "results/ensemble/{protocol}/moduli.nc",
    params:
        cfg=ANALYSIS_PARAMS,
    log:
        "logs/analysis/moduli/{protocol}.log",
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis moduli --ensemble {input.ensemble:q} --fields {input.fields:q} "
            "--params {params.cfg:q} --out {output:q} > {log:q} 2>&1"
        )


rule analysis_base_pressure_pile:
    input:
        state=lambda wc: pile(wc.protocol, wc.seed, _analysis_setting("base_pressure", "stage", "relaxed")),
        code=ANALYSIS_CODE,
    output:
        "results/fields/{protocol}/seed{seed}.base_pressure.nc",
    params:
        cfg=ANALYSIS_PARAMS,
    log:
        "logs/analysis/base_pressure/{protocol}/seed{seed}.log",
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis base-pressure --states {input.state:q} --params {params.cfg:q} --out {output:q} > {log:q} 2>&1"
        )


rule analysis_base_pressure:
    input:
        piles=_analysis_base_pressure_piles,
        code=ANALYSIS_CODE,
    output:
        "results/ensemble/{protocol}/base_pressure.nc",
    params:
        cfg=ANALYSIS_PARAMS,
    log:
        "logs/analysis/base_pressure/{protocol}.log",
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis base-pressure --piles {input.piles:q} --params {params.cfg:q} --out {output:q} > {log:q} 2>&1"
        )


rule analysis_invariants:
    input:
        ensemble="results/ensemble/{protocol}/fields.nc",
        code=ANALYSIS_CODE,
    output:
        "results/ensemble/{protocol}/invariants.nc",
    params:
        cfg=ANALYSIS_PARAMS,
    log:
        "logs/analysis/invariants/{protocol}.log",
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis invariants --ensemble {input.ensemble:q} --params {params.cfg:q} --out {output:q} > {log:q} 2>&1"
        )


rule analysis_convergence:
    # One pile's fields at fixed points against RVE size (Fig. 1); Fig. 1 asks
    # for it for every pile of its protocol, or for one (analysis.convergence.seed).
    input:
        relaxed=pile("{protocol}", "{seed}", "relaxed"),
        reduced=pile("{protocol}", "{seed}", "reduced"),
        code=ANALYSIS_CODE,
    output:
        "results/fields/{protocol}/seed{seed}.convergence.nc",
    params:
        cfg=ANALYSIS_PARAMS,
    log:
        "logs/analysis/convergence/{protocol}/seed{seed}.log",
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis convergence --relaxed {input.relaxed:q} --reduced {input.reduced:q} "
            "--params {params.cfg:q} --out {output:q} > {log:q} 2>&1"
        )


rule analysis_figure_convergence:
    input:
        data=_analysis_convergence_files,
        code=ANALYSIS_CODE,
    output:
        png=report("results/figures/fig1_convergence.png", caption="../report/analysis/fig1_convergence.rst",
                   category="Analysis", subcategory="Fig. 1"),
        pdf="results/figures/fig1_convergence.pdf",
    params:
        cfg=ANALYSIS_PARAMS,
        inputs=lambda wc, input: _labelled(input.data, [f"seed{s}" for s in
                                                        _analysis_convergence_seeds(_analysis_protocol("convergence_protocol"))]),
    log:
        "logs/analysis/figures/fig1_convergence.log",
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis figure convergence --inputs {params.inputs:q} --params {params.cfg:q} "
            "--out {output.png:q} {output.pdf:q} > {log:q} 2>&1"
        )


rule analysis_figure_vertical_strain:
    input:
        data=expand("results/ensemble/{protocol}/fields.nc", protocol=PROTOCOLS),
        code=ANALYSIS_CODE,
    output:
        png=report("results/figures/fig2_vertical_strain.png", caption="../report/analysis/fig2_vertical_strain.rst",
                   category="Analysis", subcategory="Fig. 2"),
        pdf="results/figures/fig2_vertical_strain.pdf",
    params:
        cfg=ANALYSIS_PARAMS,
        inputs=lambda wc, input: _labelled(input.data, PROTOCOLS),
    log:
        "logs/analysis/figures/fig2_vertical_strain.log",
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis figure vertical-strain --inputs {params.inputs:q} --params {params.cfg:q} "
            "--out {output.png:q} {output.pdf:q} > {log:q} 2>&1"
        )


rule analysis_figure_fabric:
    input:
        data=lambda wc: f"results/ensemble/{_analysis_protocol('fabric_protocol')}/fields.nc",
        code=ANALYSIS_CODE,
    output:
        png=report("results/figures/fig3_fabric.png", caption="../report/analysis/fig3_fabric.rst",
                   category="Analysis", subcategory="Fig. 3"),
        pdf="results/figures/fig3_fabric.pdf",
    params:
        cfg=ANALYSIS_PARAMS,
        inputs=lambda wc, input: _labelled([input.data], [_analysis_protocol("fabric_protocol")]),
    log:
        "logs/analysis/figures/fig3_fabric.log",
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis figure fabric --inputs {params.inputs:q} --params {params.cfg:q} "
            "--out {output.png:q} {output.pdf:q} > {log:q} 2>&1"
        )


rule analysis_figure_moduli:
    input:
        data=lambda wc: f"results/ensemble/{_analysis_protocol('moduli_protocol')}/moduli.nc",
        code=ANALYSIS_CODE,
    output:
        png=report("results/figures/fig4_moduli.png", caption="../report/analysis/fig4_moduli.rst",
                   category="Analysis", subcategory="Fig. 4"),
        pdf="results/figures/fig4_moduli.pdf",
    params:
        cfg=ANALYSIS_PARAMS,
        inputs=lambda wc, input: _labelled([input.data], [_analysis_protocol("moduli_protocol")]),
    log:
        "logs/analysis/figures/fig4_moduli.log",
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis figure moduli --inputs {params.inputs:q} --params {params.cfg:q} "
            "--out {output.png:q} {output.pdf:q} > {log:q} 2>&1"
        )


rule analysis_figure_invariants:
    input:
        data=lambda wc: f"results/ensemble/{_analysis_protocol('invariants_protocol')}/invariants.nc",
        code=ANALYSIS_CODE,
    output:
        png=report("results/figures/fig5_invariants.png", caption="../report/analysis/fig5_invariants.rst",
                   category="Analysis", subcategory="Fig. 5"),
        pdf="results/figures/fig5_invariants.pdf",
    params:
        cfg=ANALYSIS_PARAMS,
        inputs=lambda wc, input: _labelled([input.data], [_analysis_protocol("invariants_protocol")]),
    log:
        "logs/analysis/figures/fig5_invariants.log",
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis figure invariants --inputs {params.inputs:q} --params {params.cfg:q} "
            "--out {output.png:q} {output.pdf:q} > {log:q} 2>&1"
        )


rule analysis_figure_base_pressure:
    input:
        data=expand("results/ensemble/{protocol}/base_pressure.nc", protocol=PROTOCOLS),
        code=ANALYSIS_CODE,
    output:
        png=report("results/figures/base_pressure.png", caption="../report/analysis/base_pressure.rst",
                   category="Analysis", subcategory="Base pressure"),
        pdf="results/figures/base_pressure.pdf",
    params:
        cfg=ANALYSIS_PARAMS,
        inputs=lambda wc, input: _labelled(input.data, PROTOCOLS),
    log:
        "logs/analysis/figures/base_pressure.log",
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis figure base-pressure --inputs {params.inputs:q} --params {params.cfg:q} "
            "--out {output.png:q} {output.pdf:q} > {log:q} 2>&1"
        )


# --- the extra probes (probe.tilts, probe.restore): general fit, reversibility


rule analysis_probes:
    # Stress and strain increments of every probe stage of one pile, from its relaxed state.
    input:
        relaxed=pile("{protocol}", "{seed}", "relaxed"),
        probes=lambda wc: [pile(wc.protocol, wc.seed, st) for st in probe_stages() + extra_probe_stages()],
        code=ANALYSIS_CODE,
    output:
        "results/fields/{protocol}/seed{seed}.probes.nc",
    params:
        cfg=ANALYSIS_PARAMS,
        probes=lambda wc, input: [f"{st}={path}" for st, path in
                                  zip(probe_stages() + extra_probe_stages(), input.probes)],
    log:
        "logs/analysis/probes/{protocol}_seed{seed}.log",
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=30,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis probes --relaxed {input.relaxed:q} --probes {params.probes:q} "
            "--params {params.cfg:q} --out {output:q} > {log:q} 2>&1"
        )


rule analysis_general_fit:
    # The general 2D elastic fit of all loading probes over the piles, and reversibility.
    input:
        probes=lambda wc: [pile_result(wc.protocol, s, "probes") for s in analysis_seeds(wc.protocol, "probes")],
        ensemble="results/ensemble/{protocol}/fields.nc",
        code=ANALYSIS_CODE,
    output:
        "results/ensemble/{protocol}/general_moduli.nc",
    params:
        cfg=ANALYSIS_PARAMS,
    log:
        "logs/analysis/general_fit/{protocol}.log",
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis general-fit --probes {input.probes:q} --ensemble {input.ensemble:q} "
            "--params {params.cfg:q} --out {output:q} > {log:q} 2>&1"
        )


rule analysis_figure_general:
    input:
        data=expand("results/ensemble/{protocol}/general_moduli.nc", protocol=general_fit_protocols()),
        code=ANALYSIS_CODE,
    output:
        png=report("results/figures/general_fit.png", caption="../report/analysis/general_fit.rst",
                   category="Analysis", subcategory="General fit"),
        pdf="results/figures/general_fit.pdf",
    params:
        cfg=ANALYSIS_PARAMS,
        inputs=lambda wc, input: _labelled(input.data, general_fit_protocols()),
    log:
        "logs/analysis/figures/general_fit.log",
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m analysis figure general --inputs {params.inputs:q} --params {params.cfg:q} "
            "--out {output.png:q} {output.pdf:q} > {log:q} 2>&1"
        )
