"""The error of a pile statistic against the time step: paired bias and the rule that picks a step.

A candidate step is poured on the seeds of a reference step; each seed gives a
paired difference of a statistic, and the reference ensemble's per-pile scatter
is the yardstick.  The rule (docs/reproduction/step_error_plan.md):

* a cell (candidate, arm, statistic) **fails** when its bias is resolved beyond
  ``quarter`` of the scatter, ``|b| - t SE > quarter * sigma``;
* its **bound** ``(|b| + t SE) / sigma`` is the largest bias, in scatters, that
  the data do not exclude at the two-sided ``level``;
* a candidate is admissible when all its piles completed and no cell failed;
  the step chosen is the admissible one with the lowest CPU per pile, when that
  is below the reference's.

Everything here works on plain numbers (``{seed: value}`` mappings and lists):
the records are read by ``workflow/tools/step_error.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats


@dataclass(frozen=True)
class Cell:
    """The paired bias of one statistic of one arm at one candidate step.

    Attributes
    ----------
    n : int
        Seeds poured at both steps (the pairs).
    bias : float
        Mean paired difference, candidate − reference (nan with no pair).
    se : float
        Its standard error, sd of the differences over sqrt(n) (nan below 2 pairs).
    half_width : float
        Student's two-sided interval half-width, ``t(1 - level/2, n - 1) * se``.
    scatter : float
        The reference arm's per-pile standard deviation (the yardstick).
    pairing : float
        sd of the differences over the scatter: about sqrt(2) when the two
        steps give unrelated piles of the same seed, below it when pairing helps.
    """

    n: int
    bias: float
    se: float
    half_width: float
    scatter: float
    pairing: float

    def fails(self, quarter: float) -> bool:
        """Whether the bias is resolved beyond ``quarter`` scatters (the interval lies outside ±quarter σ)."""
        return abs(self.bias) - self.half_width > quarter * self.scatter

    @property
    def bound(self) -> float:
        """The largest bias the data do not exclude, in scatters: ``(|b| + t SE) / σ``."""
        return (abs(self.bias) + self.half_width) / self.scatter


def paired_bias(candidate: dict[int, float], reference: dict[int, float], scatter_values,
                level: float = 0.05) -> Cell:
    """The paired bias of a statistic at a candidate step against the reference step.

    Parameters
    ----------
    candidate, reference : dict
        ``{seed: value}`` of the statistic at each step; pairs are the seeds in
        both with finite values at both.
    scatter_values : sequence of float
        The reference arm's whole ensemble (its finite values give the scatter,
        the sample standard deviation).
    level : float
        Two-sided level of the interval.

    Returns
    -------
    Cell
    """
    seeds = sorted(s for s in set(candidate) & set(reference)
                   if math.isfinite(candidate[s]) and math.isfinite(reference[s]))
    d = np.array([candidate[s] - reference[s] for s in seeds], float)
    pool = np.array([v for v in scatter_values if math.isfinite(v)], float)
    if len(pool) < 2:
        raise ValueError(f"the scatter needs at least 2 reference piles, got {len(pool)}")
    sigma = float(np.std(pool, ddof=1))
    if len(d) < 2:
        bias = float(d.mean()) if len(d) else math.nan
        return Cell(len(d), bias, math.nan, math.nan, sigma, math.nan)
    sd = float(np.std(d, ddof=1))
    se = sd / math.sqrt(len(d))
    half = float(stats.t.ppf(1 - level / 2, len(d) - 1)) * se
    return Cell(len(d), float(d.mean()), se, half, sigma, sd / sigma)


def choose_step(cost: dict[str, float], reference_cost: float, piles: dict[str, tuple[int, int]],
                cells: dict[str, list[Cell]], quarter: float) -> tuple[str | None, list[str]]:
    """The rule of docs/reproduction/step_error_plan.md: the cheapest admissible candidate.

    Parameters
    ----------
    cost : dict
        ``{candidate: CPU s per pile}`` (mean over its arms).
    reference_cost : float
        The reference step's CPU s per pile, the same way.
    piles : dict
        ``{candidate: (piles completed, piles registered)}``; a candidate is
        admissible only with all of them (a refused or failed pile counts against it).
    cells : dict
        ``{candidate: its cells}``.
    quarter : float
        The bias allowed, in scatters.

    Returns
    -------
    tuple
        The candidate chosen (None: the reference stays) and, per candidate,
        a line saying why it is or is not admissible.
    """
    reasons, admissible = [], []
    for name in cost:
        failed = [c for c in cells[name] if c.fails(quarter)]
        done, registered = piles[name]
        if done < registered:
            reasons.append(f"{name}: not admissible, {done} of its {registered} piles completed")
        elif failed:
            reasons.append(f"{name}: not admissible, {len(failed)} cell(s) biased beyond {quarter} scatters")
        else:
            admissible.append(name)
            reasons.append(f"{name}: admissible, {cost[name]:.0f} CPU s per pile")
    cheaper = [n for n in admissible if cost[n] < reference_cost]
    return (min(cheaper, key=cost.get) if cheaper else None), reasons
