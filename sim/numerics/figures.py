"""Figures of the numerical checks (matplotlib, Agg backend)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..io import atomic_figure  # noqa: E402
from .collision_scenes import OBSERVABLES  # noqa: E402

COLOURS = {"gear": "tab:blue", "verlet": "tab:orange"}


def collision_figure(ds, path):
    """Error against wall time per collision, one panel per observable and case.

    One curve per integrator (points: the time steps, from the stability limit
    down); the run at the stability limit is circled and a dotted vertical
    line marks its wall time.  Errors that are exactly zero (no tangential
    force without friction) are not drawn.
    """
    names = list(OBSERVABLES)
    cases = list(ds.case.values)
    fig, axes = plt.subplots(len(names), len(cases), figsize=(2.6 * len(cases) + 1, 2.4 * len(names)),
                             squeeze=False, sharex="col", constrained_layout=True)
    for col, case in enumerate(cases):
        for row, name in enumerate(names):
            ax = axes[row, col]
            drawn = False
            for integrator in ds.integrator.values:
                sel = ds.sel(case=case, integrator=integrator)
                wall = 1e6 * sel.wall_time.values
                err = sel[f"error_{name}"].values
                good = err > 0
                colour = COLOURS.get(str(integrator))
                if good.any():
                    drawn = True
                    ax.loglog(wall[good], err[good], "o-", ms=3, color=colour, label=str(integrator))
                    if good[0]:
                        ax.loglog(wall[:1], err[:1], "o", ms=9, mfc="none", color=colour)
                ax.axvline(wall[0], color=colour, ls=":", lw=1)
            if not drawn:
                ax.text(0.5, 0.5, "error exactly 0", transform=ax.transAxes, ha="center")
            if row == 0:
                ax.set_title(str(case), fontsize=9)
            if col == 0:
                units, long_name, kind = OBSERVABLES[name]
                ax.set_ylabel(f"{kind} error\n{name.replace('_', ' ')}", fontsize=8)
            if row == len(names) - 1:
                ax.set_xlabel("wall time per collision (µs)", fontsize=8)
            ax.tick_params(labelsize=7)
    axes[0, 0].legend(fontsize=7, title="circled, dotted:\nstability limit", title_fontsize=6)
    fig.suptitle("Binary collisions: error against wall time (2 particles: per-step overhead "
                 "dominates the time)", fontsize=10)
    atomic_figure(fig, path, dpi=110)
    plt.close(fig)


def stable_dt_figure(ds, path):
    """Largest stable time step against stiffness, per search scene and integrator.

    Markers: measured; solid: the rule's stability limit; dashed: the
    automatic step (``dt_safety`` × limit); dotted: the linear spring's
    theoretical limit ``h*(0)/ω`` where there is one.
    """
    scenes = list(ds.scene.values)
    fig, axes = plt.subplots(1, len(scenes), figsize=(5 * len(scenes), 4), squeeze=False,
                             constrained_layout=True)
    y = ds.youngs_modulus.values
    for ax, scene in zip(axes[0], scenes):
        for integrator in ds.integrator.values:
            r = ds.sel(scene=scene, integrator=integrator)
            colour = COLOURS.get(str(integrator))
            ax.loglog(y, r.largest_stable_dt, "o", color=colour,
                      label=f"{integrator}: largest stable dt")
            ax.loglog(y, r.rule_dt_limit, "-", color=colour, label=f"{integrator}: rule's limit")
            ax.loglog(y, r.auto_dt, "--", color=colour, label=f"{integrator}: automatic dt")
            if np.isfinite(r.theory_dt_limit).any():
                ax.loglog(y, r.theory_dt_limit, ":", color=colour, lw=2,
                          label=f"{integrator}: h*(0)/ω, linear spring")
        ax.set_xlabel("Young's modulus Y (N/m)")
        ax.set_ylabel("time step (s)")
        ax.set_title(str(scene))
        ax.legend(fontsize=7)
    fig.suptitle("Largest stable time step against the time-step rule", fontsize=10)
    atomic_figure(fig, path, dpi=110)
    plt.close(fig)
