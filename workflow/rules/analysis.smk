# Analysis rules: particle states -> per-pile RVE fields -> ensembles -> fits -> figures.
#
# The rules read `study` (workflow/study.py) and the state files {results}/piles/{protocol}/seed{seed}/{stage}.nc (docs/formats.md#state-files).
#
# Every rule passes config["analysis"] as sorted JSON in params, so a change of
# an analysis setting reruns exactly the rules that read it. Figure captions
# live in workflow/report/analysis/ and are not params: editing one reruns nothing.
#
# Every rule here takes seconds (0.5 s for the fields of a 3500-particle pile),
# so under a cluster executor they run on the submitting machine (localrule)
# instead of queueing a cluster job each.

from workflow.analysis_inputs import ANALYSIS_MEM_MB, labelled


rule analysis_fields:
    input:
        relaxed=study.paths.results_path("piles/{protocol}/seed{seed}/relaxed.nc"),
        reduced=study.analysis.fields_reduced,
    output:
        fields=study.paths.results_path("fields/{protocol}/seed{seed}.nc"),
        checks=study.paths.results_path("fields/{protocol}/seed{seed}.checks.json"),
    params:
        code=study.code.analysis,
        cfg=study.analysis.params,
        reduced=study.analysis.reduced_option,
        quantities=study.outputs.field_quantities(),
    log:
        study.paths.results_path("logs/analysis/fields/{protocol}/seed{seed}.log"),
    benchmark:
        study.paths.results_path("benchmarks/analysis/fields/{protocol}/seed{seed}.tsv")
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis fields --relaxed {input.relaxed:q} {params.reduced:q} --quantities {params.quantities:q} "
            "--params {params.cfg:q} --out {output.fields:q} --checks {output.checks:q} > {log:q} 2>&1"
        )


rule analysis_ensemble:
    input:
        fields=study.analysis.fields,
    output:
        study.paths.results_path("ensemble/{protocol}/fields.nc"),
    params:
        code=study.code.analysis,
        cfg=study.analysis.params,
    log:
        study.paths.results_path("logs/analysis/ensemble/{protocol}.log"),
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis ensemble --fields {input.fields:q} --params {params.cfg:q} --out {output:q} > {log:q} 2>&1"
        )


rule analysis_moduli:
    input:
        ensemble=study.paths.results_path("ensemble/{protocol}/fields.nc"),
        fields=study.analysis.fields,
    output:
        study.paths.results_path("ensemble/{protocol}/moduli.nc"),
    params:
        code=study.code.analysis,
        cfg=study.analysis.params,
    log:
        study.paths.results_path("logs/analysis/moduli/{protocol}.log"),
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis moduli --ensemble {input.ensemble:q} --fields {input.fields:q} "
            "--params {params.cfg:q} --out {output:q} > {log:q} 2>&1"
        )


rule analysis_base_pressure_pile:
    input:
        state=lambda wc: study.paths.pile(wc.protocol, wc.seed, study.analysis.setting("base_pressure", "stage", "relaxed")),
    output:
        study.paths.results_path("fields/{protocol}/seed{seed}.base_pressure.nc"),
    params:
        code=study.code.analysis,
        cfg=study.analysis.params,
    log:
        study.paths.results_path("logs/analysis/base_pressure/{protocol}/seed{seed}.log"),
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis base-pressure --states {input.state:q} --params {params.cfg:q} --out {output:q} > {log:q} 2>&1"
        )


rule analysis_base_pressure:
    input:
        piles=study.analysis.base_pressure_piles,
    output:
        study.paths.results_path("ensemble/{protocol}/base_pressure.nc"),
    params:
        code=study.code.analysis,
        cfg=study.analysis.params,
    log:
        study.paths.results_path("logs/analysis/base_pressure/{protocol}.log"),
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis base-pressure --piles {input.piles:q} --params {params.cfg:q} --out {output:q} > {log:q} 2>&1"
        )


rule analysis_invariants:
    input:
        ensemble=study.paths.results_path("ensemble/{protocol}/fields.nc"),
    output:
        study.paths.results_path("ensemble/{protocol}/invariants.nc"),
    params:
        code=study.code.analysis,
        cfg=study.analysis.params,
    log:
        study.paths.results_path("logs/analysis/invariants/{protocol}.log"),
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis invariants --ensemble {input.ensemble:q} --params {params.cfg:q} --out {output:q} > {log:q} 2>&1"
        )


rule analysis_convergence:
    # One pile's fields at fixed points against RVE size (Fig. 1); Fig. 1 asks
    # for it for every pile of its protocol, or for one (analysis.convergence.seed).
    input:
        relaxed=study.paths.pile("{protocol}", "{seed}", "relaxed"),
        reduced=study.paths.pile("{protocol}", "{seed}", "reduced"),
    output:
        study.paths.results_path("fields/{protocol}/seed{seed}.convergence.nc"),
    params:
        code=study.code.analysis,
        cfg=study.analysis.params,
    log:
        study.paths.results_path("logs/analysis/convergence/{protocol}/seed{seed}.log"),
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis convergence --relaxed {input.relaxed:q} --reduced {input.reduced:q} "
            "--params {params.cfg:q} --out {output:q} > {log:q} 2>&1"
        )


rule analysis_figure_convergence:
    input:
        data=study.analysis.convergence_files,
    output:
        png=report(study.paths.results_path("figures/fig1_convergence.png"), caption="../report/analysis/fig1_convergence.rst",
                   category="Analysis", subcategory="Fig. 1"),
        pdf=study.paths.results_path("figures/fig1_convergence.pdf"),
    params:
        code=study.code.analysis,
        cfg=study.analysis.params,
        inputs=lambda wc, input: labelled(input.data, [f"seed{s}" for s in
                                                        study.analysis.convergence_seeds(study.analysis.figure_protocol("convergence_protocol"))]),
    log:
        study.paths.results_path("logs/analysis/figures/fig1_convergence.log"),
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis figure convergence --inputs {params.inputs:q} --params {params.cfg:q} "
            "--out {output.png:q} {output.pdf:q} > {log:q} 2>&1"
        )


rule analysis_figure_vertical_strain:
    input:
        data=expand(study.paths.results_path("ensemble/{protocol}/fields.nc"), protocol=study.piles.protocols),
    output:
        png=report(study.paths.results_path("figures/fig2_vertical_strain.png"), caption="../report/analysis/fig2_vertical_strain.rst",
                   category="Analysis", subcategory="Fig. 2"),
        pdf=study.paths.results_path("figures/fig2_vertical_strain.pdf"),
    params:
        code=study.code.analysis,
        cfg=study.analysis.params,
        inputs=lambda wc, input: labelled(input.data, study.piles.protocols),
    log:
        study.paths.results_path("logs/analysis/figures/fig2_vertical_strain.log"),
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis figure vertical-strain --inputs {params.inputs:q} --params {params.cfg:q} "
            "--out {output.png:q} {output.pdf:q} > {log:q} 2>&1"
        )


rule analysis_figure_fabric:
    input:
        data=lambda wc: study.paths.results_path(f"ensemble/{study.analysis.figure_protocol('fabric_protocol')}/fields.nc"),
    output:
        png=report(study.paths.results_path("figures/fig3_fabric.png"), caption="../report/analysis/fig3_fabric.rst",
                   category="Analysis", subcategory="Fig. 3"),
        pdf=study.paths.results_path("figures/fig3_fabric.pdf"),
    params:
        code=study.code.analysis,
        cfg=study.analysis.params,
        inputs=lambda wc, input: labelled([input.data], [study.analysis.figure_protocol("fabric_protocol")]),
    log:
        study.paths.results_path("logs/analysis/figures/fig3_fabric.log"),
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis figure fabric --inputs {params.inputs:q} --params {params.cfg:q} "
            "--out {output.png:q} {output.pdf:q} > {log:q} 2>&1"
        )


rule analysis_figure_moduli:
    input:
        data=lambda wc: study.paths.results_path(f"ensemble/{study.analysis.figure_protocol('moduli_protocol')}/moduli.nc"),
    output:
        png=report(study.paths.results_path("figures/fig4_moduli.png"), caption="../report/analysis/fig4_moduli.rst",
                   category="Analysis", subcategory="Fig. 4"),
        pdf=study.paths.results_path("figures/fig4_moduli.pdf"),
    params:
        code=study.code.analysis,
        cfg=study.analysis.params,
        inputs=lambda wc, input: labelled([input.data], [study.analysis.figure_protocol("moduli_protocol")]),
    log:
        study.paths.results_path("logs/analysis/figures/fig4_moduli.log"),
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis figure moduli --inputs {params.inputs:q} --params {params.cfg:q} "
            "--out {output.png:q} {output.pdf:q} > {log:q} 2>&1"
        )


rule analysis_figure_invariants:
    input:
        data=lambda wc: study.paths.results_path(f"ensemble/{study.analysis.figure_protocol('invariants_protocol')}/invariants.nc"),
    output:
        png=report(study.paths.results_path("figures/fig5_invariants.png"), caption="../report/analysis/fig5_invariants.rst",
                   category="Analysis", subcategory="Fig. 5"),
        pdf=study.paths.results_path("figures/fig5_invariants.pdf"),
    params:
        code=study.code.analysis,
        cfg=study.analysis.params,
        inputs=lambda wc, input: labelled([input.data], [study.analysis.figure_protocol("invariants_protocol")]),
    log:
        study.paths.results_path("logs/analysis/figures/fig5_invariants.log"),
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis figure invariants --inputs {params.inputs:q} --params {params.cfg:q} "
            "--out {output.png:q} {output.pdf:q} > {log:q} 2>&1"
        )


rule analysis_figure_base_pressure:
    input:
        data=expand(study.paths.results_path("ensemble/{protocol}/base_pressure.nc"), protocol=study.piles.protocols),
    output:
        png=report(study.paths.results_path("figures/base_pressure.png"), caption="../report/analysis/base_pressure.rst",
                   category="Analysis", subcategory="Base pressure"),
        pdf=study.paths.results_path("figures/base_pressure.pdf"),
    params:
        code=study.code.analysis,
        cfg=study.analysis.params,
        inputs=lambda wc, input: labelled(input.data, study.piles.protocols),
    log:
        study.paths.results_path("logs/analysis/figures/base_pressure.log"),
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis figure base-pressure --inputs {params.inputs:q} --params {params.cfg:q} "
            "--out {output.png:q} {output.pdf:q} > {log:q} 2>&1"
        )


# --- the extra probes (probe.tilts, probe.restore): general fit, reversibility


rule analysis_probes:
    # Stress and strain increments of every probe stage of one pile, from its relaxed state.
    input:
        relaxed=study.paths.pile("{protocol}", "{seed}", "relaxed"),
        probes=lambda wc: [study.paths.pile(wc.protocol, wc.seed, st) for st in study.stages.probe_stages() + study.stages.extra_probe_stages()],
    output:
        study.paths.results_path("fields/{protocol}/seed{seed}.probes.nc"),
    params:
        code=study.code.analysis,
        cfg=study.analysis.params,
        probes=lambda wc, input: [f"{st}={path}" for st, path in
                                  zip(study.stages.probe_stages() + study.stages.extra_probe_stages(), input.probes)],
    log:
        study.paths.results_path("logs/analysis/probes/{protocol}_seed{seed}.log"),
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=30,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis probes --relaxed {input.relaxed:q} --probes {params.probes:q} "
            "--params {params.cfg:q} --out {output:q} > {log:q} 2>&1"
        )


rule analysis_general_fit:
    # The general 2D elastic fit of all loading probes over the piles, and reversibility.
    input:
        probes=lambda wc: [study.analysis.pile_result(wc.protocol, s, "probes") for s in study.analysis.analysis_seeds(wc.protocol, "probes")],
        ensemble=study.paths.results_path("ensemble/{protocol}/fields.nc"),
    output:
        study.paths.results_path("ensemble/{protocol}/general_moduli.nc"),
    params:
        code=study.code.analysis,
        cfg=study.analysis.params,
    log:
        study.paths.results_path("logs/analysis/general_fit/{protocol}.log"),
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis general-fit --probes {input.probes:q} --ensemble {input.ensemble:q} "
            "--params {params.cfg:q} --out {output:q} > {log:q} 2>&1"
        )


rule analysis_figure_general:
    input:
        data=expand(study.paths.results_path("ensemble/{protocol}/general_moduli.nc"), protocol=study.analysis.general_fit_protocols()),
    output:
        png=report(study.paths.results_path("figures/general_fit.png"), caption="../report/analysis/general_fit.rst",
                   category="Analysis", subcategory="General fit"),
        pdf=study.paths.results_path("figures/general_fit.pdf"),
    params:
        code=study.code.analysis,
        cfg=study.analysis.params,
        inputs=lambda wc, input: labelled(input.data, study.analysis.general_fit_protocols()),
    log:
        study.paths.results_path("logs/analysis/figures/general_fit.log"),
    localrule: True
    threads: 1
    resources:
        mem_mb=ANALYSIS_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        study.commands.py_shell(
            "-m analysis figure general --inputs {params.inputs:q} --params {params.cfg:q} "
            "--out {output.png:q} {output.pdf:q} > {log:q} 2>&1"
        )
