"""Statistics over an ensemble of piles: one number per pile in, a comparison out.

Each pile gives its numbers (:mod:`analysis.history`,
:mod:`analysis.pile_quantities`); here two sets of piles (two protocols, two
arms) are compared in one such number: the mean over the piles with its
standard error (:func:`mean_sem`), the difference of two sets with the power
to see it (:func:`compare`, :func:`t_power`, :func:`piles_for_power`),
Welch's test (:func:`welch`), Schuirmann's equivalence test (:func:`tost`),
Holm's correction over a family of tests (:func:`holm`) and the family
itself (:func:`welch_family`), and the differences paired by seed
(:func:`paired_difference`).  The registered decisions
(:mod:`analysis.decision`) and the tools' pages call these; none of them
tests anything of its own.

The tests that decide (:func:`welch`, :func:`holm`, :func:`piles_for_power`)
use Student's t at Welch's degrees of freedom, not the normal quantiles of
:func:`bonferroni_z` and :func:`detection_factor`: with 8-10 piles per
protocol the degrees of freedom are 12-15.  The registrations
(docs/reproduction/preregistration*.md) cite these functions as
``analysis.history.welch``, ``.holm``, ``.tost`` and ``.piles_for_power``:
they lived there when the registrations were committed, and moved here
unchanged.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
from scipy.stats import mannwhitneyu, nct, norm
from scipy.stats import t as student_t

#: The family-wise level of the tests and the power asked of an ensemble.
LEVEL, POWER = 0.05, 0.8


def mean_sem(values) -> tuple[float, float, float, int]:
    """Mean, standard error, standard deviation and count of the finite ``values``."""
    a = np.asarray(values, float)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return math.nan, math.nan, math.nan, 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sd = float(a.std(ddof=1)) if a.size > 1 else math.nan
    return float(a.mean()), sd / math.sqrt(a.size), sd, int(a.size)


def piles_needed(sd_a: float, sd_b: float, delta: float, z: float) -> float:
    """Piles per protocol for a difference ``delta`` to stand ``z`` standard errors
    from zero, ``z^2 (sd_a^2 + sd_b^2) / delta^2`` (equal numbers in both)."""
    if not (np.isfinite(sd_a) and np.isfinite(sd_b)):
        return math.nan
    return float(math.ceil(z * z * (sd_a ** 2 + sd_b ** 2) / delta ** 2))


def detection_factor(level: float = 0.05, power: float = 0.8) -> float:
    """``z_{1-level/2} + z_power``: a difference of this many standard errors is seen
    at the two-sided ``level`` with probability ``power`` (2.80 for 5 % and 80 %)."""
    return float(norm.ppf(1 - level / 2) + norm.ppf(power))


def bonferroni_z(comparisons: int, level: float = 0.05) -> float:
    """The |z| each of ``comparisons`` tests must pass for a family-wise two-sided ``level``."""
    return float(norm.ppf(1 - level / (2 * comparisons)))


def compare(a, b, deltas=(0.05, 0.10), level: float = 0.05, power: float = 0.8) -> dict[str, Any]:
    """Protocol ``a`` against protocol ``b`` in one per-pile statistic.

    Returns the mean, standard error, SD and count of each; the difference
    ``a - b``, its standard error ``sqrt(se_a^2 + se_b^2)`` and ``z`` (the
    difference in standard errors); each mean against zero in standard
    errors; the *minimum detectable difference*: ``2 se`` (a difference of
    that size stands at 2 SE) and ``(z_{1-level/2} + z_power) se`` (seen at the
    two-sided ``level`` with probability ``power``); and, for each of
    ``deltas``, the piles per protocol that put it at 2 SE
    (``n_2se``) and that see it with that power (``n_power``).
    """
    ma, sa, da, na = mean_sem(a)
    mb, sb, db, nb = mean_sem(b)
    se = math.hypot(sa, sb)
    k = detection_factor(level, power)
    return {"a": (ma, sa, da, na), "b": (mb, sb, db, nb), "diff": ma - mb, "se": se,
            "z": (ma - mb) / se if se > 0 else math.nan,
            "z_a": ma / sa if sa > 0 else math.nan, "z_b": mb / sb if sb > 0 else math.nan,
            "mdd_2se": 2 * se, "mdd_power": k * se, "k_power": k,
            "n_2se": {d: piles_needed(da, db, d, 2.0) for d in deltas},
            "n_power": {d: piles_needed(da, db, d, k) for d in deltas}}


def welch(a, b) -> dict[str, float]:
    """Welch's two-sided test of ``mean(a) == mean(b)`` over the finite values.

    Returns ``t`` (the difference over its standard error
    ``sqrt(s_a^2/n_a + s_b^2/n_b)``), ``df`` (Welch-Satterthwaite) and the
    two-sided ``p`` from Student's t at ``df``; NaN with fewer than two values
    on a side.
    """
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    if a.size < 2 or b.size < 2:
        return {"t": math.nan, "df": math.nan, "p": math.nan}
    va, vb = a.var(ddof=1) / a.size, b.var(ddof=1) / b.size
    if not va + vb > 0:
        return {"t": math.nan, "df": math.nan, "p": math.nan}
    t = float((a.mean() - b.mean()) / math.sqrt(va + vb))
    df = float((va + vb) ** 2 / (va ** 2 / (a.size - 1) + vb ** 2 / (b.size - 1)))
    return {"t": t, "df": df, "p": float(2 * student_t.sf(abs(t), df))}


def tost(a, b, margin: float, level: float = 0.05) -> dict[str, float]:
    """Two one-sided Welch tests that ``mean(a) - mean(b)`` lies within ``±margin``.

    Schuirmann's equivalence test: the difference ``d`` (finite values) with
    Welch's standard error ``se`` and degrees of freedom ``df`` (as
    :func:`welch`); ``p_low`` from ``t = (d + margin) / se`` against
    ``d <= -margin`` and ``p_high`` from ``t = (d - margin) / se`` against
    ``d >= margin``, each one-sided from Student's t at ``df``.  The two sides
    are equivalent at ``level`` when ``p = max(p_low, p_high) < level``, which
    is when the ``1 - 2·level`` interval of ``d`` lies inside ``±margin``.

    Returns
    -------
    dict
        ``diff``, ``se``, ``df``, ``p_low``, ``p_high``, ``p`` and
        ``equivalent`` (bool); NaN and False with fewer than two values on a side.
    """
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    w = welch(a, b)
    if not np.isfinite(w["df"]):
        return {"diff": math.nan, "se": math.nan, "df": math.nan, "p_low": math.nan, "p_high": math.nan,
                "p": math.nan, "equivalent": False}
    d = float(a.mean() - b.mean())
    se = math.sqrt(a.var(ddof=1) / a.size + b.var(ddof=1) / b.size)
    p_low = float(student_t.sf((d + margin) / se, w["df"]))
    p_high = float(student_t.cdf((d - margin) / se, w["df"]))
    p = max(p_low, p_high)
    return {"diff": d, "se": se, "df": w["df"], "p_low": p_low, "p_high": p_high, "p": p,
            "equivalent": bool(p < level)}


def holm(p_values, level: float = 0.05) -> tuple[list[float], list[bool]]:
    """Holm's step-down correction of a family of two-sided ``p_values``.

    Returns the adjusted p values (``max`` over the steps up to each of
    ``(m - rank) p``, capped at 1, in the order given) and whether each test
    is rejected at the family-wise ``level`` (adjusted p below it).  A NaN p
    stays NaN and is not rejected; it counts in the family size ``m``.
    """
    p = np.asarray(p_values, float)
    m = p.size
    order = np.argsort(np.where(np.isfinite(p), p, np.inf), kind="stable")
    adjusted = np.full(m, math.nan)
    running = 0.0
    for rank, k in enumerate(order):
        if not np.isfinite(p[k]):
            break
        running = max(running, min(1.0, (m - rank) * p[k]))
        adjusted[k] = running
    return [float(v) for v in adjusted], [bool(np.isfinite(v) and v < level) for v in adjusted]


def t_threshold(df: float, comparisons: int = 1, level: float = 0.05) -> float:
    """The |t| a test at ``df`` degrees of freedom must pass for a two-sided
    ``level`` shared by ``comparisons`` tests (Bonferroni: ``level /
    comparisons`` each; Holm's first, strictest step)."""
    return float(student_t.isf(level / (2 * comparisons), df))


def welch_df_equal(sd_a: float, sd_b: float, n: int) -> float:
    """Welch's degrees of freedom for ``n`` piles per protocol at the scatters ``sd_a``, ``sd_b``."""
    va, vb = sd_a ** 2, sd_b ** 2
    return (va + vb) ** 2 * (n - 1) / (va ** 2 + vb ** 2)


def t_power(sd_a: float, sd_b: float, delta: float, n: int, comparisons: int = 1,
            level: float = 0.05) -> float:
    """Probability that Welch's test with ``n`` piles per protocol finds a true
    difference ``delta`` at the two-sided ``level / comparisons`` (noncentral t
    at the Welch degrees of freedom, the per-pile scatters taken as known)."""
    df = welch_df_equal(sd_a, sd_b, n)
    crit = t_threshold(df, comparisons, level)
    shift = abs(delta) / math.sqrt((sd_a ** 2 + sd_b ** 2) / n)
    return float(nct.sf(crit, df, shift) + nct.cdf(-crit, df, shift))


def piles_for_power(sd_a: float, sd_b: float, delta: float, power: float = 0.8, comparisons: int = 1,
                    level: float = 0.05, most: int = 100000) -> float:
    """The fewest piles per protocol (equal numbers, at least 2) with which
    Welch's test finds a difference ``delta`` with probability ``power`` at
    the family-wise two-sided ``level`` over ``comparisons`` tests (Bonferroni,
    which Holm's first step equals: a bound for Holm).  NaN where a scatter is
    unknown, inf beyond ``most``."""
    if not (np.isfinite(sd_a) and np.isfinite(sd_b)) or not delta or sd_a ** 2 + sd_b ** 2 == 0:
        return math.nan
    lo, hi = 2, 2
    while t_power(sd_a, sd_b, delta, hi, comparisons, level) < power:
        lo, hi = hi, 2 * hi
        if hi > most:
            return math.inf
    while lo < hi:  # power rises with n: the smallest n reaching it
        mid = (lo + hi) // 2
        if t_power(sd_a, sd_b, delta, mid, comparisons, level) >= power:
            hi = mid
        else:
            lo = mid + 1
    return float(hi)


def welch_family(samples: dict[str, tuple], level: float = LEVEL) -> dict[str, dict[str, Any]]:
    """Welch's test of each statistic of a family, with Holm's correction over the family.

    Parameters
    ----------
    samples : dict
        ``{name: (a, b)}``: per statistic the per-pile values of the two sets
        (NaN: a pile without it).
    level : float
        The family-wise two-sided level.

    Returns
    -------
    dict
        ``{name: row}`` in the order of `samples`.  Each row: ``a`` and ``b``
        (mean, standard error, standard deviation and count, :func:`mean_sem`),
        ``diff`` (mean of a − mean of b), ``se`` (its standard error,
        ``sqrt(se_a^2 + se_b^2)``), ``ci95`` (its two-sided 95 % interval from
        Student's t at Welch's degrees of freedom), ``t``, ``df`` and ``p``
        (:func:`welch`), ``t_family`` (the |t| that Bonferroni over the family
        asks at those degrees of freedom, Holm's first step,
        :func:`t_threshold`), ``p_holm`` and ``rejected`` (:func:`holm`).
    """
    rows = {}
    for name, (a, b) in samples.items():
        sa, sb = mean_sem(a), mean_sem(b)
        diff, se = sa[0] - sb[0], math.hypot(sa[1], sb[1])
        w = welch(a, b)
        half = student_t.isf(0.025, w["df"]) * se if np.isfinite(w["df"]) else math.nan
        rows[name] = {"a": sa, "b": sb, "diff": diff, "se": se, "ci95": (diff - half, diff + half), **w,
                      "t_family": t_threshold(w["df"], len(samples), level)}
    adjusted, rejected = holm([r["p"] for r in rows.values()], level)
    for r, p, rej in zip(rows.values(), adjusted, rejected):
        r["p_holm"], r["rejected"] = p, rej
    return rows


def paired_difference(a: dict, b: dict) -> tuple[float, float, float, int]:
    """``a − b`` paired by seed: :func:`mean_sem` of the per-seed differences over the seeds both hold.

    Parameters
    ----------
    a, b : dict
        ``{seed: value}`` of two sets of piles (a seed draws the same particles in both).

    Returns
    -------
    tuple
        Mean, standard error, standard deviation and count of the differences
        (NaN and 0 without a common seed).
    """
    return mean_sem([a[s] - b[s] for s in sorted(set(a) & set(b))])


def rank_test(a, b) -> float:
    """The exact two-sided Mann–Whitney p of two sets of per-pile numbers (finite values).

    A rank test needs no standard error, and so holds at two or three piles a
    set; NaN when either set is empty.
    """
    a, b = ([x for x in v if np.isfinite(x)] for v in (a, b))
    if not a or not b:
        return math.nan
    return float(mannwhitneyu(a, b, alternative="two-sided", method="exact").pvalue)


def against_reference(a, reference) -> dict[str, Any]:
    """A set of piles `a` (a variant) against a reference set (the study) in one per-pile number.

    Returns
    -------
    dict
        ``a`` and ``reference`` (:func:`mean_sem`), ``diff`` (mean of a −
        mean of the reference), ``se`` (its standard error,
        ``sqrt(se_a^2 + se_ref^2)``; with one pile in `a`, whose scatter is
        not measured, the reference's standard deviation stands for that
        pile's: ``sqrt(se_ref^2 + sd_ref^2)``) and ``single`` (whether `a`
        has one pile).
    """
    ma, sa, _, na = stats_a = mean_sem(a)
    mr, sr, _, nr = stats_r = mean_sem(reference)
    single = na == 1
    se = math.hypot(sr, sr * math.sqrt(nr)) if single else math.hypot(sr, sa)
    return {"a": stats_a, "reference": stats_r, "diff": ma - mr, "se": se, "single": single}
