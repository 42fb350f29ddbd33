# Settings and helpers of the pile and ensemble numerics (workflow/rules/numerics_piles.smk,
# which includes this file). No rules here (snakemake --lint wants functions and rules apart).

NUMERICS_PILES = config["numerics"]["piles"]
NUMERICS_ENSEMBLE = config["numerics"]["ensemble"]
NUMERICS_DIR = results_path("numerics")


def _numerics_factor_label(factor):
    """Directory label of a dt factor: the shortest exact decimal (0.125 -> '0.125')."""
    return f"{float(factor):g}"


def numerics_pile(integrator, factor_label, seed, stage):
    """State file of a small pile of the accuracy study."""
    return f"{NUMERICS_DIR}/piles/{integrator}/dt_factor{factor_label}/seed{seed}/{stage}.nc"


def numerics_pile_summary(integrator, factor_label, seed, stage):
    """Summary line (python -m sim summary) of one state of a small pile."""
    return f"{NUMERICS_DIR}/piles/{integrator}/dt_factor{factor_label}/seed{seed}/{stage}.summary.json"


def numerics_pile_benchmark(integrator, factor_label, seed, step):
    """Benchmark file (wall time) of one simulation job of a small pile."""
    return results_path(f"benchmarks/numerics/piles/{integrator}/dt_factor{factor_label}/seed{seed}_{step}.tsv")


def numerics_pile_cpu(integrator, factor_label, seed, step):
    """CPU time (bash `times`) of one simulation job of a small pile: unlike the
    wall time it does not grow when other processes share the cores."""
    return results_path(f"benchmarks/numerics/piles/{integrator}/dt_factor{factor_label}/seed{seed}_{step}.times")


def numerics_pile_runs():
    """(integrator, dt factor label, seed) of every small pile, in config order."""
    p = NUMERICS_PILES
    return [(i, _numerics_factor_label(f), int(s))
            for i in p["integrators"] for f in p["dt_factors"] for s in p["seeds"]]


def numerics_pile_params(wildcards, sections):
    """The simulator sections of one small pile as canonical JSON.

    The config's sections with pour.n_particles from numerics.piles, the
    integrator of the run and its time step scaled by the dt factor; the
    bookkeeping settings travel apart (sim_bookkeeping()).
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
    return json.dumps(result_settings(cfg), sort_keys=True)


def _numerics_pile_inputs(kind):
    runs = numerics_pile_runs()
    if kind == "states":
        return [numerics_pile(i, f, s, "relaxed") for i, f, s in runs]
    if kind == "summaries":
        return [numerics_pile_summary(i, f, s, "relaxed") for i, f, s in runs]
    if kind.endswith("_cpu"):
        return [numerics_pile_cpu(i, f, s, kind[:-4]) for i, f, s in runs]
    return [numerics_pile_benchmark(i, f, s, kind) for i, f, s in runs]


def _numerics_ensemble_inputs(kind):
    if kind == "fields":
        return [results_path(f"fields/{p}/seed{s}.nc") for p in PROTOCOLS for s in seeds(p)]
    if kind == "base_pressure":
        return [results_path(f"ensemble/{p}/base_pressure.nc") for p in PROTOCOLS]
    if kind == "probe":
        return [results_path(f"benchmarks/probe/{p}/seed{s}_{st}.tsv")
                for p in PROTOCOLS for s in seeds(p) for st in probe_stages()]
    return [results_path(f"benchmarks/{kind}/{p}/seed{s}.tsv") for p in PROTOCOLS for s in seeds(p)]


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


def _numerics_ensemble_args(wildcards, input):
    """Per-protocol arguments of `ensemble_cost data`, in PROTOCOLS order (a list)."""
    args = []
    for p in PROTOCOLS:
        s = seeds(p)
        args += ["--protocol", p, "--seeds", *map(str, s),
                 "--fields", *[f for f in input.fields if f.startswith(results_path(f"fields/{p}/"))],
                 "--base-pressure", results_path(f"ensemble/{p}/base_pressure.nc")]
        for kind in ("pour", "relax", "probe"):
            files = [f for f in getattr(input, kind) if f.startswith(results_path(f"benchmarks/{kind}/{p}/"))]
            args += [f"--{kind}-benchmarks", *files]
    return args
