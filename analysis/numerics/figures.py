"""Figures of the pile and ensemble numerics: error against run time per pile
(:mod:`analysis.numerics.pile_precision`) and standard error against compute time
(:mod:`analysis.numerics.ensemble_cost`), written atomically (:func:`analysis.figures.save`)."""

from __future__ import annotations

import numpy as np
import xarray as xr
from matplotlib.ticker import NullFormatter

from ..figures import plt, save


def log_axes(ax) -> None:
    """Log scales on both axes of a panel, or a note instead when no drawn point is positive and finite."""
    pts = [np.column_stack([np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float)])
           for line in ax.get_lines()]
    pts = np.concatenate(pts) if pts else np.empty((0, 2))
    if np.any(np.all(np.isfinite(pts) & (pts > 0), axis=1)):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())  # labelled minor ticks overlap on short ranges
    else:
        ax.text(0.5, 0.5, "no finite values", transform=ax.transAxes, ha="center")


def pile_error_figure(ds: xr.Dataset, outputs: list[str], observables: tuple[str, ...]) -> None:
    """Log-log error against wall time per pile, one curve per integrator, one panel per observable.

    Each point is one dt factor (labelled); error bars are the seed scatter
    of the error. The dashed line is the seed scatter of the reference's own
    mean (the smallest error this number of seeds can resolve) and the dotted
    line its wall time. ``observables``: the names of the panels
    (:data:`analysis.numerics.pile_precision.OBSERVABLES`), four.
    """

    ref_i = list(ds.integrator.values).index(ds.attrs["reference_integrator"])
    ref_f = int(np.argmin(ds.dt_factor.values))
    fig, axes = plt.subplots(2, 2, figsize=(9, 7), constrained_layout=True)
    for ax, name in zip(axes.flat, observables):
        for a, integ in enumerate(ds.integrator.values):
            t = ds["cpu_time_mean"].values[a]
            e = ds[f"{name}_error"].values[a]
            bar = ds[f"{name}_error_bar"].values[a]
            keep = ~((a == ref_i) & (np.arange(t.size) == ref_f)) & (e > 0)
            # on a log axis the lower bar stops at a tenth of the error (it would reach zero)
            yerr = [np.minimum(bar[keep], 0.9 * e[keep]), bar[keep]]
            ax.errorbar(t[keep], e[keep], yerr=yerr, marker="o", capsize=3, label=str(integ))
            for ti, ei, f in zip(t[keep], e[keep], ds.dt_factor.values[keep]):
                ax.annotate(f"{f:g}", (ti, ei), textcoords="offset points", xytext=(4, 4), fontsize=7)
        log_axes(ax)
        ref_scatter = ds[f"{name}_error_bar"].values[ref_i, ref_f] / np.sqrt(2.0)
        if ref_scatter > 0:
            ax.axhline(ref_scatter, ls="--", color="0.4", lw=1, label="reference seed scatter")
        ax.axvline(ds["cpu_time_mean"].values[ref_i, ref_f], ls=":", color="0.4", lw=1,
                   label=f"reference ({ds.attrs['reference_integrator']}, dt x {ds.attrs['reference_dt_factor']:g})")
        ax.set_xlabel("run time per pile (CPU, pour + relax), s")
        unit = ds[f"{name}_error"].attrs["units"]
        ax.set_ylabel(f"error of {name.replace('_', ' ')}" + ("" if unit == "1" else f" ({unit})"))
        ax.grid(True, which="both", alpha=0.3)
    axes.flat[0].legend(fontsize=7)
    fig.suptitle(f"{ds.attrs['n_particles']}-particle {ds.attrs['protocol']} piles, "
                 f"{ds.sizes['seed']} seeds per point; labels: dt factor")
    save(fig, outputs)


def ensemble_error_figure(ds: xr.Dataset, outputs: list[str], headlines: tuple[str, ...]) -> None:
    """Relative standard error against cumulative compute time, one panel per headline result.

    Solid: the first n piles (n labelled); dashed: the extrapolation
    ``s_N / (sqrt(n) |mean_N|)`` at the mean compute time per pile.
    ``headlines``: the names of the panels
    (:data:`analysis.numerics.ensemble_cost.HEADLINES`), three.
    """

    fig, axes = plt.subplots(1, 3, figsize=(12, 4), constrained_layout=True)
    n = ds["n"].values
    for ax, name in zip(axes, headlines):
        for a, proto in enumerate(ds.protocol.values):
            t = ds["cumulative_compute_time"].values[a]
            mean = ds[f"{name}_mean"].values[a]
            rel = ds[f"{name}_se"].values[a] / np.abs(mean)
            ok = np.isfinite(rel) & np.isfinite(t)
            line, = ax.plot(t[ok], rel[ok], marker="o", label=str(proto))
            for ti, ri, k in zip(t[ok], rel[ok], n[ok]):
                ax.annotate(str(k), (ti, ri), textcoords="offset points", xytext=(3, 3), fontsize=7)
            last = np.flatnonzero(ok)
            if last.size:
                m = last[-1]
                nn = np.arange(2, 4 * (m + 1) + 1)
                per_pile = t[m] / (m + 1)
                ax.plot(nn * per_pile, rel[m] * np.sqrt((m + 1) / nn), ls="--", color=line.get_color(), lw=1,
                        label=f"{proto}: 1/sqrt(n)")
        log_axes(ax)
        ax.set_xlabel("CPU time of the n piles, s")
        ax.set_ylabel(f"relative standard error of {name.replace('_', ' ')}")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle(f"core ({ds.attrs['core_x']:g}, {ds.attrs['core_y']:g}) m; labels: piles n")
    save(fig, outputs)
