"""The decisions on the pressure minimum: the registered rules, and the study's primary tests.

The study's own decision (:func:`primary_tests`: its five primary statistics,
wedge against layered, Welch and Holm; windows fixed after its piles were
read) and the pre-registered ones (docs/reproduction/preregistration.md,
preregistration_equal_slope.md), all on the tests of
:mod:`analysis.ensemble_statistics`.  The registered rules are pure functions
on the per-pile records (one JSON object per pile: ``arm``, ``protocol``,
``seed``, ``growth``, ``quantities``, ``inputs``, ``cpu_s``;
:func:`analysis.pile_quantities.pile_record` computes its numbers):

* :func:`select_arms`: which point source and which layered control the
  decision uses, by the registered rule on the calibration records;
* :func:`piles_required`: the piles per protocol for 80 % power to find a
  difference of :data:`EFFECT` in the first decision statistic at the
  family-wise 5 %, from the pooled scatter of the calibration piles;
* :func:`verdict`: Welch's test per decision statistic, Holm's correction
  over the family, and the registered sentence; it refuses an ensemble
  short of the registered size;
* :func:`shape_check`: what the arms differ in besides the history: their
  mean angles of repose, and the first decision statistic fitted on arm
  plus angle, so that a difference of slope is not read as one of history;
  :func:`covariate_fit` does the same for each of :data:`COVARIATES`
  (height, width, the core's packing), with the fit's conditioning.

Every rule here is the page's; the page is the registration.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .ensemble_statistics import (LEVEL, POWER, mean_sem, piles_for_power, t_power, tost, welch,
                                  welch_family)
from .history import UNITS, primary_names, row_contrast

#: The decision family: the pressure minimum read from the RVE stress (low
#: variance) and from the support's force density.
DECISION = ("stress_column", "base_pressure_column")
#: The secondary statistics, reported with their own Holm correction.
SECONDARY = ("strain@4.5", "solid_fraction@4.5", "gravity_gap", "stress_fabric")
#: The equal-slope decision's secondaries (docs/reproduction/preregistration_equal_slope.md,
#: "Secondary"), one Holm family: base_pressure_column, stress_column in windows scaled to each pile's half width, the
#: interior measure, the centre's share of its own column, then the first decision's.
EQUAL_SLOPE_SECONDARY = ("base_pressure_column", "scaled_stress_column", "interior_share",
                         "centre_column") + SECONDARY
#: The effect the ensemble is powered for, in stress_column (a fraction of the uniform pile's pressure).
EFFECT = 0.05
#: The fewest piles per protocol the decision pours.
MIN_PILES = 10
#: Arms whose mean angles of repose differ by more than this (deg) compare sources as built, not histories.
SLOPE_TOLERANCE = 1.5
#: The equal-slope pick (docs/reproduction/equal_slope.md): a control's mean angle within this
#: of the reference (deg), its interior share above the funnel's by this much, at this Welch t.
PICK_SLOPE, PICK_INTERIOR, PICK_T = 1.0, 0.10, 2.0
#: stress_column's windows as fractions of each pile's half width (``quantities.width / 2``): the fixed
#: windows (centre 3 cm, shoulders 6-15 cm) over the first decision's funnel piles' mean half
#: width, 35.4 cm (:func:`scaled_stress_column`).
SCALED_WINDOWS = {"centre": 0.085, "shoulder_inner": 0.17, "shoulder_outer": 0.42}
#: The layered control's growing flanks must stay this far (deg) below the point source's angle of repose.
REPOSE_MARGIN = 2.0
WEDGE_ARMS = ("wedge drip", "wedge funnel")
LAYERED_ARMS = ("layered top", "layered rain")


#: The differences whose power the study's tables give: relative contrasts 5 and 10 %, the angle 2 and 5 degrees
#: (by the unit of :data:`analysis.history.UNITS`).
DELTAS = {"": (0.05, 0.10), "deg": (2.0, 5.0)}


def primary_tests(values: dict[str, list[dict]], history: dict[str, Any], a: str = "wedge",
                  b: str = "layered") -> list[dict[str, Any]]:
    """The study's decision on its primary statistics (:func:`analysis.history.primary_names`), ``a − b``.

    Not pre-registered (the windows were fixed after the study's piles were
    read): Welch's test per statistic with Holm's correction over the family
    at :data:`analysis.ensemble_statistics.LEVEL`
    (:func:`analysis.ensemble_statistics.welch_family`), and the piles per
    protocol that find a difference with :data:`analysis.ensemble_statistics.POWER`
    (:func:`analysis.ensemble_statistics.piles_for_power`, the scatter taken
    as measured).

    Parameters
    ----------
    values : dict
        ``{protocol: [per-pile statistics]}`` (:func:`analysis.history.pile_history` of each pile).
    history : dict
        The windows' settings (``analysis.history``).
    a, b : str
        The protocols compared.

    Returns
    -------
    list of dict
        Per primary statistic, in order: ``name``, ``t``, ``df``, ``p``, ``diff``, ``se``, ``n`` and ``sd``
        (per protocol), ``holm_p``, ``rejected``, ``t_bonferroni`` (the |t| the family asks at ``df``),
        ``delta`` (5 %, or 2° for the angle, :data:`DELTAS`) and the piles per protocol that find it at the
        family-wise level (``n_delta``) and in one test alone (``n_delta_single``), and that find a
        difference of the measured size at the family-wise level (``n_measured``).
    """
    names = primary_names(history)
    tests = welch_family({name: ([v.get(name, np.nan) for v in values.get(a, [])],
                                 [v.get(name, np.nan) for v in values.get(b, [])]) for name in names}, LEVEL)
    out = []
    for name, r in tests.items():
        sd_a, sd_b = r["a"][2], r["b"][2]
        delta = DELTAS[UNITS.get(name, "")][0]
        out.append({"name": name, "t": r["t"], "df": r["df"], "p": r["p"], "diff": r["diff"], "se": r["se"],
                    "n": (r["a"][3], r["b"][3]), "sd": (sd_a, sd_b), "holm_p": r["p_holm"],
                    "rejected": r["rejected"], "t_bonferroni": r["t_family"], "delta": delta,
                    "n_delta": piles_for_power(sd_a, sd_b, delta, POWER, len(tests), LEVEL),
                    "n_delta_single": piles_for_power(sd_a, sd_b, delta, POWER, 1, LEVEL),
                    "n_measured": piles_for_power(sd_a, sd_b, r["diff"], POWER, len(tests), LEVEL)})
    return out


def _arm_mean(records: list[dict], arm: str, part: str, key: str) -> float:
    """Mean over the arm's piles of ``record[part][key]`` (finite values)."""
    return mean_sem([r[part][key] for r in records if r["arm"] == arm])[0]


def select_arms(records: list[dict]) -> dict[str, Any]:
    """The point source and the layered control, by the registered rule.

    Parameters
    ----------
    records : list of dict
        The calibration records (every arm of :data:`WEDGE_ARMS` and
        :data:`LAYERED_ARMS` with at least two piles).

    Returns
    -------
    dict
        ``point`` (the wedge arm whose flanks flow the larger mean fraction
        of the growth; a tie keeps the first), ``repose_deg`` (its mean angle
        of repose), ``qualified`` (the layered arms whose mean 90th
        percentile growing flank lies at least :data:`REPOSE_MARGIN` below
        it), ``layered`` (of those, the one with the smaller mean flow
        fraction; None when none qualifies) and ``means`` (the numbers the
        rule read, per arm).

    Raises
    ------
    ValueError
        If an arm has fewer than two piles.
    """
    for arm in WEDGE_ARMS + LAYERED_ARMS:
        n = sum(r["arm"] == arm for r in records)
        if n < 2:
            raise ValueError(f"arm {arm!r}: {n} calibration piles, the rule needs at least 2")
    means = {arm: {"flow_fraction": _arm_mean(records, arm, "growth", "flow_fraction"),
                   "flank_p90_deg": _arm_mean(records, arm, "growth", "flank_p90_deg"),
                   "angle_deg": _arm_mean(records, arm, "quantities", "angle_deg")}
             for arm in WEDGE_ARMS + LAYERED_ARMS}
    point = WEDGE_ARMS[0]
    for arm in WEDGE_ARMS[1:]:
        if means[arm]["flow_fraction"] > means[point]["flow_fraction"]:
            point = arm
    repose = means[point]["angle_deg"]
    qualified = [a for a in LAYERED_ARMS if means[a]["flank_p90_deg"] <= repose - REPOSE_MARGIN]
    layered = min(qualified, key=lambda a: means[a]["flow_fraction"]) if qualified else None
    return {"point": point, "layered": layered, "repose_deg": repose, "qualified": qualified, "means": means}


def pooled_sd(a, b) -> tuple[float, int]:
    """Pooled standard deviation of two samples (finite values) and its degrees of freedom."""
    a, b = (np.asarray(v, float) for v in (a, b))
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    df = a.size + b.size - 2
    if a.size < 2 or b.size < 2:
        return math.nan, df
    ss = ((a - a.mean()) ** 2).sum() + ((b - b.mean()) ** 2).sum()
    return float(math.sqrt(ss / df)), int(df)


def statistic(record: dict, key: str) -> float:
    """One pile's statistic `key`: ``quantities[key]``, the interior measure ``growth.interior_share``,
    or stress_column in scaled windows (:func:`scaled_stress_column`, from the record's inputs)."""
    if key == "scaled_stress_column":
        return scaled_stress_column(record)
    if key == "interior_share":
        return record["growth"].get(key, math.nan)
    return record["quantities"].get(key, math.nan)


def values(records: list[dict], arm: str, key: str) -> list[float]:
    """The statistic `key` (:func:`statistic`) of the arm's piles, in seed order."""
    return [statistic(r, key) for r in sorted(records, key=lambda r: r["seed"]) if r["arm"] == arm]


def piles_required(records: list[dict], point: str, layered: str) -> dict[str, Any]:
    """Piles per protocol for the registered power in the first decision statistic.

    Returns ``n`` (at least :data:`MIN_PILES`), the pooled ``sd`` and its
    ``df``, and ``n_power`` (before the floor).
    """
    sd, df = pooled_sd(values(records, point, DECISION[0]), values(records, layered, DECISION[0]))
    n = piles_for_power(sd, sd, EFFECT, POWER, comparisons=len(DECISION), level=LEVEL)
    return {"sd": sd, "df": df, "n_power": n, "n": int(max(MIN_PILES, n)) if np.isfinite(n) else n}


def verdict(records: list[dict], point: str, layered: str, n: int, family: tuple = DECISION,
            margin: float | None = None) -> dict[str, Any]:
    """The registered test and sentence over the decision ensemble.

    Parameters
    ----------
    records : list of dict
        The decision records (missing piles are absent, or carry a NaN).
    point, layered : str
        The arms (as registered).
    n : int
        The registered piles per protocol.
    family : tuple of str
        The primary statistics, tested with Holm's correction over them (the
        first decision: stress_column and base_pressure_column; the equal-slope decision: stress_column alone).
    margin : float, optional
        With a margin, the registered outcomes of the equal-slope decision
        (docs/reproduction/preregistration_equal_slope.md): ``history`` (the
        first primary statistic rejects, point − layered below 0), ``opposite``
        (above 0), ``shape`` (it does not reject and the equivalence test
        :func:`analysis.ensemble_statistics.tost` puts the difference within ``±margin``)
        or ``none`` ("no effect larger than Z", Z the farther bound of its
        95 % interval); the equivalence test is in ``out["equivalence"]``.
        Without one, the first decision's outcomes (``minimum``,
        ``opposite``, ``none``).

    Returns
    -------
    dict
        Per decision and secondary statistic: the means, standard errors and
        counts, the per-pile standard deviations (``sd``), the difference, its
        two-sided 95 % t interval (``ci95``), Welch's t, df and p, Holm's adjusted p and
        rejection; the achieved power at :data:`EFFECT`; ``finding`` (one of
        ``minimum``, ``opposite``, ``none``) and ``sentence``.

    Raises
    ------
    ValueError
        If either protocol has fewer than ``n`` piles with a finite first
        decision statistic (no test on a partial ensemble).
    """
    for arm in (point, layered):
        have = int(np.isfinite(values(records, arm, family[0])).sum())
        if have < n:
            raise ValueError(f"{arm}: {have} of the registered {n} piles; the verdict waits for all of them")
    out: dict[str, Any] = {}
    secondary = SECONDARY if margin is None else EQUAL_SLOPE_SECONDARY
    for part, keys in (("decision", family), ("secondary", secondary)):
        tests = welch_family({k: (values(records, point, k), values(records, layered, k)) for k in keys}, LEVEL)
        out[part] = {k: _arms_row(r, len(keys)) for k, r in tests.items()}
    d = out["decision"]
    lower = [k for k in family if d[k]["rejected"] and d[k]["diff"] < 0]
    higher = [k for k in family if d[k]["rejected"] and d[k]["diff"] > 0]
    pct = lambda v: f"{100 * v:.1f} %"  # noqa: E731
    if margin is not None:
        return _equal_slope_outcome(out, records, point, layered, family[0], margin, lower, higher)
    if lower:
        out["finding"] = "minimum"
        out["sentence"] = "a minimum: " + "; ".join(
            f"{k}: wedge − layered = {pct(d[k]['diff'])} ± {pct(d[k]['se'])} (Holm p {d[k]['p_holm']:.3g}; "
            f"wedge alone {pct(d[k]['point'][0])} ± {pct(d[k]['point'][1])}, layered alone "
            f"{pct(d[k]['layered'][0])} ± {pct(d[k]['layered'][1])})" for k in lower)
    elif higher:
        out["finding"] = "opposite"
        out["sentence"] = "the opposite of a minimum: " + "; ".join(
            f"{k}: wedge − layered = +{pct(d[k]['diff'])} ± {pct(d[k]['se'])} (Holm p {d[k]['p_holm']:.3g})"
            for k in higher)
    else:
        z = -d[DECISION[0]]["ci95"][0]
        lo2 = d[DECISION[1]]["ci95"]
        out["finding"] = "none"
        out["sentence"] = (f"no minimum larger than {pct(max(z, 0.0))} (95 %) in {DECISION[0]}; "
                           f"{DECISION[1]}: 95 % interval of wedge − layered [{pct(lo2[0])}, {pct(lo2[1])}]")
    return out


def _arms_row(test: dict[str, Any], comparisons: int) -> dict[str, Any]:
    """A statistic's row of :func:`verdict` from its :func:`analysis.ensemble_statistics.welch_family`
    row: each arm's (mean, standard error, count), the per-pile scatters ``sd``, the test, and the
    achieved power at :data:`EFFECT` (NaN below two piles an arm)."""
    (ma, sa, da, na), (mb, sb, db, nb) = test["a"], test["b"]
    return {"point": (ma, sa, na), "layered": (mb, sb, nb), "sd": (da, db),
            **{k: test[k] for k in ("diff", "se", "ci95", "t", "df", "p", "p_holm", "rejected")},
            "power": t_power(da, db, EFFECT, min(na, nb), comparisons, LEVEL) if min(na, nb) >= 2 else math.nan}


#: What a pile's record says about its shape and packing (``quantities``), reported per arm
#: beside a verdict (the equal-slope registration's "reported covariates"): the angle of
#: repose (deg), height and base width (m), and the core's solid fraction.
COVARIATES = ("angle_deg", "height", "width", "solid_fraction")


def covariate_fit(records: list[dict], point: str, layered: str, key: str, covariate: str) -> dict[str, Any]:
    """A statistic on arm plus one covariate: ``key = a + b·[point arm] + c·covariate``.

    Least squares over both arms' piles with a finite ``key`` and
    ``covariate`` (both from each record's ``quantities``).  Where arm and
    covariate go together, b is poorly determined: its standard error grows
    by the square root of the variance inflation factor ``1 / (1 − r²)``
    (r: their correlation over the piles), reported with it.

    Returns
    -------
    dict
        ``arms``: per arm (mean, standard error, count) of the covariate;
        ``diff``: point − layered mean; ``arm_effect``, ``arm_se``: b and its
        standard error; ``effect``, ``se``: c and its standard error (per
        unit of the covariate); ``correlation``: r; ``inflation``: the
        variance inflation factor (inf when r = ±1); NaN for the fit when
        fewer than four piles or a rank-deficient design.
    """
    rows = [(r["arm"] == point, r["quantities"].get(covariate, math.nan), r["quantities"].get(key, math.nan))
            for r in records if r["arm"] in (point, layered)]
    arm, cov, y = (np.array(c, float) for c in zip(*rows)) if rows else (np.empty(0),) * 3
    ok = np.isfinite(cov) & np.isfinite(y)
    arm, cov, y = arm[ok], cov[ok], y[ok]
    out: dict[str, Any] = {"arms": {}}
    for name, mask in ((point, arm == 1), (layered, arm == 0)):
        m, se, _, count = mean_sem(cov[mask])
        out["arms"][name] = (m, se, count)
    out["diff"] = out["arms"][point][0] - out["arms"][layered][0]
    x = np.column_stack([np.ones_like(y), arm, cov])
    if y.size <= 3 or np.linalg.matrix_rank(x) < 3:
        out.update(arm_effect=math.nan, arm_se=math.nan, effect=math.nan, se=math.nan,
                   correlation=math.nan, inflation=math.nan)
        return out
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    resid = y - x @ coef
    var = float(resid @ resid) / (y.size - 3) * np.linalg.inv(x.T @ x)
    r = float(np.corrcoef(arm, cov)[0, 1])
    out.update(arm_effect=float(coef[1]), arm_se=float(np.sqrt(var[1, 1])), effect=float(coef[2]),
               se=float(np.sqrt(var[2, 2])), correlation=r,
               inflation=1.0 / (1.0 - r * r) if abs(r) < 1 else math.inf)
    return out


def shape_check(records: list[dict], point: str, layered: str, key: str = DECISION[0]) -> dict[str, Any]:
    """What the arms differ in besides their history: slope, and the statistic on arm plus angle.

    A pile's shape alone moves the column contrast (elastoplastic heap
    theory spreads the load sideways by the shape, without any history), so
    two arms at different slopes cannot tell history from shape: the fit of
    :func:`covariate_fit` on ``angle_deg``.

    Returns
    -------
    dict
        ``angle``: per arm (mean, standard error, count) of ``angle_deg``;
        ``angle_diff``: point − layered mean angle (deg); ``as_built``: whether
        that difference exceeds :data:`SLOPE_TOLERANCE`; ``arm_effect`` and
        ``arm_se``: the arm's coefficient and its standard error; ``slope_effect``,
        ``slope_se``: the angle's (per degree); ``correlation``: of arm and angle.
    """
    fit = covariate_fit(records, point, layered, key, "angle_deg")
    return {"angle": fit["arms"], "angle_diff": fit["diff"],
            "as_built": bool(abs(fit["diff"]) > SLOPE_TOLERANCE),
            "arm_effect": fit["arm_effect"], "arm_se": fit["arm_se"], "slope_effect": fit["effect"],
            "slope_se": fit["se"], "correlation": fit["correlation"]}


def _equal_slope_outcome(out, records, point, layered, key, margin, lower, higher):
    """The registered outcome of the equal-slope decision (see :func:`verdict`), added to `out`."""
    d = out["decision"][key]
    eq = tost(values(records, point, key), values(records, layered, key), margin, LEVEL)
    out["equivalence"] = eq
    pct = lambda v: f"{100 * v:.1f} %"  # noqa: E731
    if lower:
        out["finding"] = "history"
        out["sentence"] = (f"history: at equal slope {key}: point − layered = {pct(d['diff'])} ± {pct(d['se'])} "
                           f"(p {d['p']:.3g}; point alone {pct(d['point'][0])}, layered alone "
                           f"{pct(d['layered'][0])})")
    elif higher:
        out["finding"] = "opposite"
        out["sentence"] = (f"the opposite of a minimum: {key}: point − layered = +{pct(d['diff'])} ± "
                           f"{pct(d['se'])} (p {d['p']:.3g})")
    elif eq["equivalent"]:
        out["finding"] = "shape"
        out["sentence"] = (f"shape: no history effect as large as {pct(margin)} in {key} (equivalence p "
                           f"{eq['p']:.3g}; point − layered = {pct(d['diff'])} ± {pct(d['se'])})")
    else:
        z = max(abs(d["ci95"][0]), abs(d["ci95"][1]))
        out["finding"] = "none"
        out["sentence"] = (f"no effect larger than {pct(z)} (95 %) in {key}, and none shown smaller than "
                           f"{pct(margin)} (equivalence p {eq['p']:.3g})")
    return out


def scaled_stress_column(record: dict) -> float:
    """``stress_column`` of one pile in windows scaled to its own half width (:data:`SCALED_WINDOWS`).

    Read from the record's inputs (``inputs.stress_column``: the row's
    columns, σ_yy and the uniform column's pressure), so that two arms of
    different widths are cut at the same fractions of each pile; NaN for a
    record without inputs or without a qualifying row.
    """
    row = record.get("inputs", {}).get("stress_column")
    half = 0.5 * record["quantities"].get("width", math.nan)
    if not row or not half > 0:
        return math.nan
    windows = {k: f * half for k, f in SCALED_WINDOWS.items()}
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.asarray(row["sigma_yy"], float) / np.asarray(row["p_u"], float)
    return row_contrast(ratio, np.asarray(row["x"], float), windows)


def pick_control(records: list[dict], point: str, reference: list[float]) -> dict[str, Any]:
    """The layered control of the equal-slope decision, by the rule of docs/reproduction/equal_slope.md.

    Parameters
    ----------
    records : list of dict
        The pilot's records: the point source's arm and the candidate layered arms.
    point : str
        The point source's arm.
    reference : list of float
        The angles (deg) of every funnel pile the reference slope is the mean of.

    Returns
    -------
    dict
        ``reference`` (mean angle, deg), per candidate arm in ``arms`` its mean
        ``angle_deg``, ``interior_share``, ``flow_fraction`` (each mean, SE, n),
        the interior contrast's Welch ``t`` against the point source and
        whether it qualifies on ``slope`` and ``interior``; ``control``: the
        qualifying arm nearest the reference (within 0.1°: the smaller mean
        flow fraction), or None.
    """
    ref = float(np.mean(reference))
    point_interior = [r["growth"]["interior_share"] for r in records if r["arm"] == point]
    arms = {}
    for arm in dict.fromkeys(r["arm"] for r in records if r["arm"] != point):
        rs = [r for r in records if r["arm"] == arm]
        angle = mean_sem([r["quantities"]["angle_deg"] for r in rs])
        interior = mean_sem([r["growth"]["interior_share"] for r in rs])
        flow = mean_sem([r["growth"]["flow_fraction"] for r in rs])
        t = welch([r["growth"]["interior_share"] for r in rs], point_interior)["t"]
        arms[arm] = {"angle_deg": (angle[0], angle[1], angle[3]), "interior_share": (interior[0], interior[1], interior[3]),
                     "flow_fraction": (flow[0], flow[1], flow[3]), "interior_t": t,
                     "slope": bool(abs(angle[0] - ref) <= PICK_SLOPE),
                     "interior": bool(interior[0] - mean_sem(point_interior)[0] >= PICK_INTERIOR and t > PICK_T)}
    qualified = [a for a, m in arms.items() if m["slope"] and m["interior"]]
    control = None
    if qualified:
        near = min(abs(arms[a]["angle_deg"][0] - ref) for a in qualified)
        tied = [a for a in qualified if abs(arms[a]["angle_deg"][0] - ref) <= near + 0.1]
        control = min(tied, key=lambda a: arms[a]["flow_fraction"][0])
    return {"reference": ref, "n_reference": len(reference), "arms": arms, "qualified": qualified,
            "control": control}
