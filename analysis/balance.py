"""Balance-law checks on a pile at rest.

Gravity ``g = (0, -g)`` with ``g`` the state's ``gravity`` attribute (or the
vector ``(gravity_x, gravity_y)`` when the file carries both attributes; the
formulas below are written for the vertical case, the code uses the vector). With
``F^p = sum_c f^c`` the contact force on particle ``p`` (support included):

1. **Support reaction.** At rest ``F^p + m_p g = 0`` for every particle;
   summing, the contact forces between particles cancel pairwise, so the
   support's vertical force on the pile equals the weight:
   ``R_y = sum_{c: j=-1} force_y^c = M g`` (and ``R_x = 0``).

2. **Love's sum rule (area integral of stress).** With branch vectors
   ``x^c = r^c - r_p`` (``r^c`` the contact point),
   ``sum_p sum_c x_i^c f_j^c = sum_p sum_c r_i^c f_j^c - sum_p r_{p,i} F_j^p``.
   In the first sum each particle–particle contact appears twice with
   opposite forces at the same point and cancels, leaving the support
   contacts; in the second ``F^p = -m_p g``. Hence, exactly at rest,
   ``sum_p sum_c x_i^c f_j^c = sum_{c: j=-1} r_i^c f_j^c + sum_p m_p r_{p,i} g_j``,
   whose yy component is ``sum_p sum_c x_y f_y = -M g y_cm + sum_{support} y^c f_y^c``.
   The support term vanishes when the contact points lie on y = 0 (we keep
   it: contact points of soft overlaps may sit a little below). Both sides
   are the area integral of the Eq. 2 stress over the whole pile. The
   check compares the yy component relative to ``M g y_cm``; all four
   components are reported.

3. **Per-particle force balance.** ``max_p |F^p + m_p g| / (m_p g)``.

4. **The increment.** The gravity probe's stress increment is the
   difference of two states, so its balance is checked on the difference:
   the change of support reaction against the change of weight, and the yy
   component of Love's sum rule for the difference, each relative to the
   increment's own load (``|ΔW|``, ``|ΔW| y_cm``).  Both stages can balance to
   1e-6 of their weights and the increment still be off by 1e-5 of its load;
   this is what the fits of the increment use.

Tolerances come from ``analysis.checks`` (the increment uses the same ones,
relative to its load); :func:`enforce` raises
:class:`~analysis.errors.BalanceError` naming every violated check.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .errors import BalanceError
from .states import State
from .stress import particle_stress_moment


def net_contact_force(state: State) -> np.ndarray:
    """Sum of the contact forces on each particle (support included), ``(n, 2)``."""
    n = state.n_particles
    pp = state.contact_j >= 0
    fx = np.bincount(state.contact_i, weights=state.force_x, minlength=n)
    fy = np.bincount(state.contact_i, weights=state.force_y, minlength=n)
    fx -= np.bincount(state.contact_j[pp], weights=state.force_x[pp], minlength=n)
    fy -= np.bincount(state.contact_j[pp], weights=state.force_y[pp], minlength=n)
    return np.column_stack([fx, fy])


def love_sum_rule(state: State) -> tuple[np.ndarray, np.ndarray]:
    """Both sides of Love's sum rule (module docstring, item 2), each a 2×2 array (N m).

    Returns ``(lhs, rhs)`` with ``lhs = sum_p sum_c x_i f_j`` and
    ``rhs = sum_support r_i f_j + sum_p m_p r_{p,i} g_j``.
    """
    lhs = particle_stress_moment(state).sum(axis=0)
    s = state.support
    r = np.column_stack([state.contact_x[s], state.contact_y[s]])
    f = np.column_stack([state.force_x[s], state.force_y[s]])
    gvec = state.gravity_vector
    pos = np.column_stack([state.x, state.y])
    rhs = r.T @ f + np.outer(state.mass @ pos, gvec)
    return lhs, rhs


def balance_report(state: State, checks: dict[str, Any]) -> dict[str, Any]:
    """All checks for one state, as a JSON-ready dict with values, tolerances and pass/fail."""
    gvec = state.gravity_vector
    g = float(np.hypot(*gvec))
    M = float(state.mass.sum())
    weight = M * g
    s = state.support
    rep: dict[str, Any] = {"file": state.path, "gravity": g, "total_mass": M, "weight": weight,
                           "n_particles": state.n_particles, "n_contacts": int(state.contact_i.size),
                           "n_support_contacts": int(s.sum())}
    if weight <= 0:
        rep["skipped"] = "gravity is zero: weight-relative checks are undefined"
        return _not_checked(rep)
    ry = float(state.force_y[s].sum())
    rx = float(state.force_x[s].sum())
    rep["support_reaction_y"] = ry
    rep["support_reaction_x"] = rx
    rep["support_reaction_rel_error"] = (ry + M * gvec[1]) / weight
    rep["support_horizontal_rel"] = (rx + M * gvec[0]) / weight
    lhs, rhs = love_sum_rule(state)
    y_cm = float(state.mass @ state.y / M)
    x_cm = float(state.mass @ state.x / M)
    rep["y_cm"], rep["x_cm"] = y_cm, x_cm
    rep["love_lhs"] = lhs.tolist()
    rep["love_rhs"] = rhs.tolist()
    rep["love_expected_yy_minus_M_g_ycm"] = M * gvec[1] * y_cm
    rep["love_rel_error_yy"] = float((lhs[1, 1] - rhs[1, 1]) / (weight * y_cm)) if y_cm > 0 else float("nan")
    scale = weight * max(y_cm, float(np.abs(state.x - x_cm).max()) if state.n_particles else 0.0, 1e-300)
    rep["love_rel_error_max"] = float(np.abs(lhs - rhs).max() / scale)
    net = net_contact_force(state) + state.mass[:, None] * gvec
    ratio = np.hypot(net[:, 0], net[:, 1]) / (state.mass * g)
    rep["net_force_ratio_max"] = float(ratio.max())
    rep["net_force_ratio_p99"] = float(np.percentile(ratio, 99))
    rep["net_force_ratio_worst_particle"] = int(ratio.argmax())
    fails = []
    tol = checks["support_reaction_rtol"]
    if not abs(rep["support_reaction_rel_error"]) <= tol:
        fails.append(f"support reaction {ry:.6g} N vs weight -M g_y = {-M * gvec[1]:.6g} N: relative error "
                     f"{rep['support_reaction_rel_error']:.3g} exceeds analysis.checks.support_reaction_rtol = {tol}")
    tol = checks["love_rtol"]
    if not abs(rep["love_rel_error_yy"]) <= tol:
        fails.append(f"Love's sum rule: sum_p sum_c x_y f_y = {lhs[1, 1]:.6g} N m vs "
                     f"-M g y_cm + sum_support y f_y = {rhs[1, 1]:.6g} N m: relative error "
                     f"{rep['love_rel_error_yy']:.3g} exceeds analysis.checks.love_rtol = {tol}")
    tol = checks["max_net_force_ratio"]
    if not rep["net_force_ratio_max"] <= tol:
        fails.append(f"net force on particle {rep['net_force_ratio_worst_particle']} is "
                     f"{rep['net_force_ratio_max']:.3g} of its weight, above "
                     f"analysis.checks.max_net_force_ratio = {tol} (the pile is not at rest)")
    rep["failures"] = fails
    rep["passed"] = not fails
    return rep


def increment_report(relaxed: State, reduced: State, checks: dict[str, Any]) -> dict[str, Any]:
    """Balance of the increment ``reduced − relaxed`` (module docstring, item 4), JSON-ready.

    Both states must hold the same particles (:func:`analysis.states.check_same_particles`).
    ``weight_change`` is ``ΔW = W_reduced − W_relaxed`` (negative for a gravity
    reduction), ``support_reaction_rel_error`` is ``(ΔR − ΔW) / |ΔW|``.
    """
    rep: dict[str, Any] = {"file": f"{reduced.path} minus {relaxed.path}"}
    g_a, g_b = relaxed.gravity_vector, reduced.gravity_vector
    M = float(relaxed.mass.sum())
    dweight = M * (g_a[1] - g_b[1])
    rep["weight_change"] = dweight
    if dweight == 0.0:
        rep["skipped"] = "gravity is the same in both states: the increment carries no load"
        return _not_checked(rep)
    dry = float(reduced.force_y[reduced.support].sum() - relaxed.force_y[relaxed.support].sum())
    rep["support_reaction_change"] = dry
    rep["support_reaction_rel_error"] = (dry - dweight) / abs(dweight)
    (lhs_a, rhs_a), (lhs_b, rhs_b) = love_sum_rule(relaxed), love_sum_rule(reduced)
    d = (lhs_b - lhs_a) - (rhs_b - rhs_a)
    y_cm = float(relaxed.mass @ relaxed.y / M)
    rep["love_rel_error_yy"] = float(d[1, 1] / (abs(dweight) * y_cm)) if y_cm > 0 else float("nan")
    fails = []
    tol = checks["support_reaction_rtol"]
    if not abs(rep["support_reaction_rel_error"]) <= tol:
        fails.append(f"increment: the support reaction changes by {dry:.6g} N for a weight change of "
                     f"{dweight:.6g} N: relative error {rep['support_reaction_rel_error']:.3g} exceeds "
                     f"analysis.checks.support_reaction_rtol = {tol}")
    tol = checks["love_rtol"]
    if not abs(rep["love_rel_error_yy"]) <= tol:
        fails.append(f"increment: Love's sum rule (yy) is off by {d[1, 1]:.6g} N m, relative error "
                     f"{rep['love_rel_error_yy']:.3g} of |ΔW| y_cm exceeds analysis.checks.love_rtol = {tol}")
    rep["failures"] = fails
    rep["passed"] = not fails
    return rep


def _not_checked(rep: dict[str, Any]) -> dict[str, Any]:
    """A report whose checks could not be made (``skipped`` says why): failed, since nothing was shown."""
    rep["failures"] = [f"not checked: {rep['skipped']}"]
    rep["passed"] = False
    return rep


def enforce(reports: list[dict[str, Any]]) -> None:
    """Raise :class:`BalanceError` naming, in one line, every failed check of ``reports``."""
    lines = [f"{r['file']}: {msg}" for r in reports for msg in r.get("failures", [])]
    if lines:
        raise BalanceError("balance-law check(s) failed (set analysis.checks.enforce: false to only report): "
                           + "; ".join(lines))
