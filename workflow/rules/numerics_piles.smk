# Numerics of whole piles (issue #5): the error of pile observables against
# run time, and the standard error of the headline results against compute
# time as the number of seeds grows. Target: numerics_piles.
#
# Small piles: one job per (integrator, dt factor, seed) pours and one relaxes,
# each with a benchmark file that supplies its wall time; the time step is
# dt_factor times the automatic step of the integrator (model.dt_safety scaled
# by the factor; with model.dt given, dt scaled by the factor).
# Ensemble: reads the configured study's piles (protocols section), their
# fields and base pressure, and the benchmark files of their simulations.
#
# Expects from common.smk: config (validated, defaults filled), PROTOCOLS,
# seeds(), pile(), probe_stages(), sim_shell(), py_shell(), SIM_KERNEL_CODE,
# ANALYSIS_CODE, COMPILED_FLAG, SIM_THREADS, SIM_MEM_MB.

NUMERICS_PILES = config["numerics"]["piles"]
NUMERICS_ENSEMBLE = config["numerics"]["ensemble"]
NUMERICS_CODE = sorted(str(p) for p in (REPO / "sim" / "numerics").glob("*.py"))
NUMERICS_DIR = "results/numerics"


def _numerics_factor_label(factor):
    """Directory label of a dt factor: the shortest exact decimal (0.125 -> '0.125')."""
    return f"{float(factor):g}"


def numerics_pile(integrator, factor_label, seed, stage):
    """State file of a small pile of the accuracy study."""
    return f"{NUMERICS_DIR}/piles/{integrator}/dt_factor{factor_label}/seed{seed}/{stage}.nc"


def numerics_pile_benchmark(integrator, factor_label, seed, step):
    """Benchmark file (wall time) of one simulation job of a small pile."""
    return f"benchmarks/numerics/piles/{integrator}/dt_factor{factor_label}/seed{seed}_{step}.tsv"


def numerics_pile_cpu(integrator, factor_label, seed, step):
    """CPU time (bash `times`) of one simulation job of a small pile: unlike the
    wall time it does not grow when other processes share the cores."""
    return f"benchmarks/numerics/piles/{integrator}/dt_factor{factor_label}/seed{seed}_{step}.times"


def numerics_pile_runs():
    """(integrator, dt factor label, seed) of every small pile, in config order."""
    p = NUMERICS_PILES
    return [(i, _numerics_factor_label(f), int(s))
            for i in p["integrators"] for f in p["dt_factors"] for s in p["seeds"]]


def numerics_pile_params(wildcards, sections):
    """The simulator sections of one small pile as canonical JSON.

    The config's sections with pour.n_particles from numerics.piles, the
    integrator of the run and its time step scaled by the dt factor.
    """
    factor = float(wildcards.factor)
    model = dict(config["model"], integrator=wildcards.integrator)
    if model["dt"] is None:
        model["dt_safety"] = model["dt_safety"] * factor
    else:
        model["dt"] = model["dt"] * factor
    cfg = {"model": model, "pour": dict(config["pour"], n_particles=NUMERICS_PILES["n_particles"])}
    for k in sections:
        cfg.setdefault(k, config[k])
    return json.dumps(cfg, sort_keys=True)


def _numerics_pile_inputs(kind):
    runs = numerics_pile_runs()
    if kind == "states":
        return [numerics_pile(i, f, s, "relaxed") for i, f, s in runs]
    if kind.endswith("_cpu"):
        return [numerics_pile_cpu(i, f, s, kind[:-4]) for i, f, s in runs]
    return [numerics_pile_benchmark(i, f, s, kind) for i, f, s in runs]


def _numerics_ensemble_inputs(kind):
    if kind == "fields":
        return [f"results/fields/{p}/seed{s}.nc" for p in PROTOCOLS for s in seeds(p)]
    if kind == "base_pressure":
        return [f"results/ensemble/{p}/base_pressure.nc" for p in PROTOCOLS]
    if kind == "probe":
        return [f"benchmarks/probe/{p}/seed{s}_{st}.tsv"
                for p in PROTOCOLS for s in seeds(p) for st in probe_stages()]
    return [f"benchmarks/{kind}/{p}/seed{s}.tsv" for p in PROTOCOLS for s in seeds(p)]


def numerics_piles_targets():
    """Every final output of the pile and ensemble numerics."""
    return [f"{NUMERICS_DIR}/{name}" for name in
            ("piles.nc", "ensemble.nc", "piles.md", "pile_error.png", "pile_error.pdf",
             "ensemble_error.png", "ensemble_error.pdf")]


def _check_numerics_piles():
    """Checks the schema cannot express; fail before any job runs."""
    p = NUMERICS_PILES
    problems = []
    if p["reference_integrator"] not in p["integrators"]:
        problems.append(f"numerics.piles.reference_integrator = {p['reference_integrator']!r} is not in "
                        f"numerics.piles.integrators = {p['integrators']}")
    labels = [_numerics_factor_label(f) for f in p["dt_factors"]]
    if len(set(labels)) != len(labels):
        problems.append(f"numerics.piles.dt_factors = {p['dt_factors']} repeat a factor at 6 significant digits")
    if problems:
        raise ValueError("invalid configuration:\n  " + "\n  ".join(problems))


_check_numerics_piles()


wildcard_constraints:
    integrator="gear|verlet",
    factor=r"[0-9.e+-]+",


rule numerics_pile_pour:
    input:
        code=SIM_KERNEL_CODE,
        compiled=COMPILED_FLAG,
    output:
        state=numerics_pile("{integrator}", "{factor}", "{seed}", "poured"),
        cpu=numerics_pile_cpu("{integrator}", "{factor}", "{seed}", "pour"),
    params:
        sim=lambda wildcards: numerics_pile_params(wildcards, ("particles",)),
        protocol=NUMERICS_PILES["protocol"],
        checkpoint=lambda wildcards: numerics_pile(wildcards.integrator, wildcards.factor, wildcards.seed,
                                                   "pour.checkpoint"),
    log:
        "logs/numerics/piles/{integrator}/dt_factor{factor}/seed{seed}_pour.log",
    benchmark:
        numerics_pile_benchmark("{integrator}", "{factor}", "{seed}", "pour")
    threads: SIM_THREADS
    resources:
        mem_mb=SIM_MEM_MB,
        runtime=30,
    conda:
        "../envs/polypile.yaml"
    shell:
        sim_shell(
            "pour --params {params.sim:q}"
            " --protocol {params.protocol} --seed {wildcards.seed}"
            " --out {output.state:q} --checkpoint {params.checkpoint:q} > {log:q} 2>&1"
        )
        + "; times > {output.cpu:q}"


rule numerics_pile_relax:
    input:
        state=numerics_pile("{integrator}", "{factor}", "{seed}", "poured"),
        code=SIM_KERNEL_CODE,
        compiled=COMPILED_FLAG,
    output:
        state=numerics_pile("{integrator}", "{factor}", "{seed}", "relaxed"),
        cpu=numerics_pile_cpu("{integrator}", "{factor}", "{seed}", "relax"),
    params:
        sim=lambda wildcards: numerics_pile_params(wildcards, ("relax",)),
    log:
        "logs/numerics/piles/{integrator}/dt_factor{factor}/seed{seed}_relax.log",
    benchmark:
        numerics_pile_benchmark("{integrator}", "{factor}", "{seed}", "relax")
    threads: SIM_THREADS
    resources:
        mem_mb=SIM_MEM_MB,
        runtime=30,
    conda:
        "../envs/polypile.yaml"
    shell:
        sim_shell(
            "relax --params {params.sim:q}"
            " --input {input.state:q} --out {output.state:q} > {log:q} 2>&1"
        )
        + "; times > {output.cpu:q}"


def _numerics_ensemble_args(wildcards, input):
    """Per-protocol options of `ensemble_cost data`, in PROTOCOLS order."""
    args = []
    for p in PROTOCOLS:
        s = seeds(p)
        args += ["--protocol", p, "--seeds", *map(str, s),
                 "--fields", *[f for f in input.fields if f.startswith(f"results/fields/{p}/")],
                 "--base-pressure", f"results/ensemble/{p}/base_pressure.nc"]
        for kind in ("pour", "relax", "probe"):
            files = [f for f in getattr(input, kind) if f.startswith(f"benchmarks/{kind}/{p}/")]
            args += [f"--{kind}-benchmarks", *files]
    return " ".join(shlex.quote(a) for a in args)


rule numerics_piles_data:
    # Observables of every small pile and their errors against the reference.
    input:
        states=_numerics_pile_inputs("states"),
        pour=_numerics_pile_inputs("pour"),
        relax=_numerics_pile_inputs("relax"),
        pour_cpu=_numerics_pile_inputs("pour_cpu"),
        relax_cpu=_numerics_pile_inputs("relax_cpu"),
        code=NUMERICS_CODE + ANALYSIS_CODE,
    output:
        f"{NUMERICS_DIR}/piles.nc",
    params:
        cfg=json.dumps(NUMERICS_PILES, sort_keys=True),
    log:
        "logs/numerics/piles_data.log",
    threads: 1
    resources:
        mem_mb=SIM_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m sim.numerics.pile_precision data --params {params.cfg:q} --states {input.states:q}"
            " --pour-benchmarks {input.pour:q} --relax-benchmarks {input.relax:q}"
            " --pour-cpu {input.pour_cpu:q} --relax-cpu {input.relax_cpu:q} --out {output:q} > {log:q} 2>&1"
        )


rule numerics_ensemble:
    # Headline results per pile of the study, their standard error against n and compute time.
    input:
        fields=_numerics_ensemble_inputs("fields"),
        base_pressure=_numerics_ensemble_inputs("base_pressure"),
        pour=_numerics_ensemble_inputs("pour"),
        relax=_numerics_ensemble_inputs("relax"),
        probe=_numerics_ensemble_inputs("probe"),
        code=NUMERICS_CODE + ANALYSIS_CODE,
    output:
        f"{NUMERICS_DIR}/ensemble.nc",
    params:
        cfg=json.dumps(NUMERICS_ENSEMBLE, sort_keys=True),
        analysis=ANALYSIS_PARAMS,
        protocols=_numerics_ensemble_args,
    log:
        "logs/numerics/ensemble.log",
    threads: 1
    resources:
        mem_mb=SIM_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m sim.numerics.ensemble_cost data --params {params.cfg:q} --analysis-params {params.analysis:q}"
            " {params.protocols} --out {output:q} > {log:q} 2>&1"
        )


rule numerics_piles_figures:
    input:
        piles=f"{NUMERICS_DIR}/piles.nc",
        ensemble=f"{NUMERICS_DIR}/ensemble.nc",
        code=NUMERICS_CODE,
    output:
        piles=report(f"{NUMERICS_DIR}/pile_error.png", caption="../report/numerics/pile_error.rst",
                     category="Numerics", subcategory="Piles"),
        piles_pdf=f"{NUMERICS_DIR}/pile_error.pdf",
        ensemble=report(f"{NUMERICS_DIR}/ensemble_error.png", caption="../report/numerics/ensemble_error.rst",
                        category="Numerics", subcategory="Ensemble"),
        ensemble_pdf=f"{NUMERICS_DIR}/ensemble_error.pdf",
    log:
        "logs/numerics/piles_figures.log",
    threads: 1
    resources:
        mem_mb=SIM_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        "("
        + py_shell("-m sim.numerics.pile_precision figure --data {input.piles:q} "
                   "--out {output.piles:q} {output.piles_pdf:q}")
        + " && "
        + py_shell("-m sim.numerics.ensemble_cost figure --data {input.ensemble:q} "
                   "--out {output.ensemble:q} {output.ensemble_pdf:q}")
        + ") > {log:q} 2>&1"


rule numerics_piles_table:
    # The markdown tables for the report.
    input:
        piles=f"{NUMERICS_DIR}/piles.nc",
        ensemble=f"{NUMERICS_DIR}/ensemble.nc",
        code=NUMERICS_CODE,
    output:
        report(f"{NUMERICS_DIR}/piles.md", caption="../report/numerics/piles_table.rst",
               category="Numerics", subcategory="Tables"),
    params:
        model=json.dumps(config["model"], sort_keys=True),
    log:
        "logs/numerics/piles_table.log",
    threads: 1
    resources:
        mem_mb=SIM_MEM_MB,
        runtime=10,
    conda:
        "../envs/polypile.yaml"
    shell:
        py_shell(
            "-m sim.numerics.piles_report --piles {input.piles:q} --ensemble {input.ensemble:q}"
            " --model {params.model:q} --out {output:q} > {log:q} 2>&1"
        )


rule numerics_piles:
    # Error of pile observables against run time and of the ensemble against compute time.
    input:
        numerics_piles_targets(),
    localrule: True
