"""Figures 1–5 of the paper and the base pressure, from the workflow's netCDF files.

Each function takes datasets (never particle states), draws with the Agg
backend and writes every requested file (PNG, PDF, … by extension)
atomically. Titles give the number of piles and the RVE size.
"""

from __future__ import annotations

import os
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402

from sim.atomic import atomic_path  # noqa: E402

from .elastic import mask_counts  # noqa: E402

COMPONENTS = (("x", "x", "xx"), ("y", "y", "yy"), ("x", "y", "xy"))


def save(fig, outputs: list[str], dpi: int = 150) -> None:
    """Write ``fig`` to every path in ``outputs`` (format from the extension), atomically."""
    for path in outputs:
        ext = os.path.splitext(path)[1].lstrip(".").lower() or "png"
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format=ext, dpi=dpi, bbox_inches="tight")
    plt.close(fig)


def _sci(ax, axis="both"):
    """Plain scientific tick labels without an offset (strains are ~1e-4)."""
    ax.ticklabel_format(axis=axis, style="sci", scilimits=(-3, 4), useOffset=False)


def _rve_label(ds: xr.Dataset) -> str:
    size = ds.attrs.get("rve_size")
    shape = ds.attrs.get("rve_shape", "")
    return f"{shape} RVE {float(size) * 100:.1f} cm" if size is not None else "RVE"


def _npiles(ds: xr.Dataset) -> str:
    n = ds.attrs.get("n_seeds")
    return f"{int(n)} pile{'s' if int(n) != 1 else ''}" if n is not None else "1 pile"


def _rows(ds: xr.Dataset, heights: list[float]) -> list[tuple[int, float]]:
    """Grid rows nearest to the requested heights (index, actual height), duplicates dropped."""
    y = ds["y"].values
    out, seen = [], set()
    for h in heights:
        k = int(np.argmin(np.abs(y - h)))
        if k not in seen:
            seen.add(k)
            out.append((k, float(y[k])))
    return out


def _band(ax, x, mean, sem, **kw):
    """Line ``mean`` with the band ``mean ± sem``; nothing (None, so no legend entry) where no value is finite."""
    if not np.isfinite(mean).any():
        return None
    line, = ax.plot(x, mean, **kw)
    if sem is not None:
        ok = np.isfinite(mean) & np.isfinite(sem)
        ax.fill_between(x, np.where(ok, mean - sem, np.nan), np.where(ok, mean + sem, np.nan),
                        color=line.get_color(), alpha=0.25, linewidth=0)
    return line


def _sem(ds, name, sel=None):
    k = f"{name}_sem"
    if k not in ds:
        return None
    v = ds[k]
    return (v.sel(sel) if sel else v).values


def fig_convergence(convs: xr.Dataset | list[xr.Dataset], outputs: list[str], dpi: int = 150) -> None:
    """Fig. 1: stress (top) and strain increment (bottom) against the particle count of the RVE, over piles.

    Parameters
    ----------
    convs : xarray.Dataset or list of them
        The convergence files (``seed{seed}.convergence.nc``) of one
        protocol's piles, with the same points and RVE sizes.
    outputs : list of str
        Files to write (format from the extension).
    dpi : int
        Resolution of raster outputs.

    Notes
    -----
    One column per fixed point; per component the median over piles at each
    RVE size against the median particle count, the band the 25–75 % range
    over piles (the spread of single piles, which is what an RVE must tame).
    """
    convs = [convs] if isinstance(convs, xr.Dataset) else list(convs)
    first = convs[0]
    sizes = first["rve_size"].values
    for c in convs[1:]:
        if not np.array_equal(c["rve_size"].values, sizes) or c.sizes["point"] != first.sizes["point"]:
            raise ValueError("the convergence files do not share their RVE sizes and points")
    npt = first.sizes["point"]
    fig, axes = plt.subplots(2, npt, figsize=(4.2 * npt + 1, 7.5), sharex=True, squeeze=False, layout="constrained")
    n = np.median(np.stack([c["n_particles"].values for c in convs]), axis=0)          # (size, point)
    seeds = [str(c.attrs.get("seed", "?")) for c in convs]
    for p in range(npt):
        lab = f"({float(first['point_x'][p]):.2f}, {float(first['point_y'][p]):.2f}) m"
        for row, (name, sym) in enumerate((("stress", "σ"), ("strain_increment", "u"))):
            ax = axes[row, p]
            for i, j, c in COMPONENTS:
                v = np.stack([d[name].isel(point=p).sel(i=i, j=j).values for d in convs])   # (pile, size)
                with np.errstate(all="ignore"):
                    lo, med, hi = np.nanpercentile(v, [25, 50, 75], axis=0) if len(convs) > 1 else (None, v[0], None)
                line, = ax.plot(n[:, p], med, marker="o", ms=3, label=f"{sym}_{c}")
                if lo is not None:
                    ax.fill_between(n[:, p], lo, hi, color=line.get_color(), alpha=0.25, linewidth=0)
            ax.set_xscale("log")
            ax.axvspan(100, 200, color="0.9", zorder=0)
            ax.axhline(0, color="0.6", lw=0.5)
            ax.legend(fontsize=7)
            if row == 0:
                ax.set_title(f"point {lab}", fontsize=9)
        axes[1, p].set_xlabel("particles in the RVE (median over piles)")
    axes[0, 0].set_ylabel("a  stress at full gravity (N/m)")
    axes[1, 0].set_ylabel("b  strain increment, relaxed → reduced (1)")
    for ax in axes[1]:
        _sci(ax, "y")
    spread = "lines: median over piles, bands: 25–75 %" if len(convs) > 1 else "one pile"
    fig.suptitle(f"RVE-size convergence, protocol {first.attrs.get('protocol', '')}, {len(convs)} "
                 f"pile{'s' if len(convs) != 1 else ''} (seed{'s' if len(convs) != 1 else ''} {', '.join(seeds)}), "
                 f"{first.attrs.get('rve_shape', '')} RVEs; {spread}; shaded: 100–200 particles", fontsize=10)
    save(fig, outputs, dpi)


def fig_vertical_strain(ensembles: dict[str, xr.Dataset], heights: list[float], outputs: list[str],
                        dpi: int = 150) -> None:
    """Fig. 2: vertical normal strain increment u_yy against x at several heights, one panel per protocol."""
    fig, axes = plt.subplots(1, len(ensembles), figsize=(5.5 * len(ensembles), 4.2), squeeze=False, sharey=True,
                             layout="constrained")
    for ax, (proto, ds) in zip(axes[0], ensembles.items()):
        x = ds["x"].values
        for k, h in _rows(ds, heights):
            sel = {"i": "y", "j": "y"}
            mean = ds["strain_increment"].isel(y=k).sel(sel).values
            sem = _sem(ds, "strain_increment", sel)
            _band(ax, x, mean, sem[k] if sem is not None else None, label=f"y = {h * 100:.1f} cm")
        ax.set_title(f"{proto} ({_npiles(ds)}, {_rve_label(ds)})", fontsize=10)
        ax.set_xlabel("x (m)")
        ax.axhline(0, color="0.6", lw=0.5)
        ax.legend(fontsize=7)
    axes[0][0].set_ylabel("vertical normal strain increment u_yy (1)")
    _sci(axes[0][0], "y")
    fig.suptitle("Vertical normal strain (relaxed → reduced gravity), mean ± standard error over piles",
                 fontsize=10)
    save(fig, outputs, dpi)


def fig_fabric(ds: xr.Dataset, heights: list[float], outputs: list[str], dpi: int = 150, protocol: str = "") -> None:
    """Fig. 3: (a) fabric trace, (b) deviatoric fraction, (c) fabric orientation against x;
    (d) orientation of fabric, stress and strain increment in the two lowest layers."""
    fig, axes = plt.subplots(2, 2, figsize=(11, 8), layout="constrained")
    x = ds["x"].values
    rows = _rows(ds, heights)
    panels = (("fabric_trace", "trace of fabric (1)", "a"),
              ("fabric_deviatoric_fraction", "deviatoric fraction (1)", "b"),
              ("fabric_orientation", "fabric orientation (degree)", "c"))
    for ax, (name, ylab, letter) in zip(axes.ravel()[:3], panels):
        for k, h in rows:
            sem = _sem(ds, name)
            _band(ax, x, ds[name].isel(y=k).values, sem[k] if sem is not None else None,
                  label=f"y = {h * 100:.1f} cm")
        ax.set_ylabel(ylab)
        ax.set_xlabel("x (m)")
        ax.set_title(letter, loc="left")
        ax.legend(fontsize=7)
    ax = axes[1, 1]
    for (k, h), ls in zip(rows[:2], ("-", "--")):
        for name, lab in (("fabric_orientation", "fabric"), ("stress_orientation", "stress"),
                          ("strain_orientation", "strain increment")):
            ax.plot(x, ds[name].isel(y=k).values, ls, label=f"{lab}, y = {h * 100:.1f} cm")
    ax.set_ylabel("orientation from vertical, counter-clockwise (degree)")
    ax.set_xlabel("x (m)")
    ax.set_title("d", loc="left")
    ax.legend(fontsize=7)
    fig.suptitle(f"Fabric, protocol {protocol or ds.attrs.get('protocol', '')} ({_npiles(ds)}, {_rve_label(ds)})",
                 fontsize=10)
    save(fig, outputs, dpi)


#: Fig. 4's panels as in the paper: per row (label, quantity) of the isotropic and the cubic column;
#: the columns' (law, fit, m, title).
MODULI_ROWS = ((("K", "bulk_modulus"), ("K = (λ1 + λ2)/2", "bulk_modulus_cubic")),
               (("E = 3G − G²/K", "youngs_modulus"), ("E_av", "E_av")),
               (("G", "shear_modulus"), ("G_av", "G_av")))
MODULI_COLUMNS = (("isotropic", "modulus", 1, "isotropic, fit of moduli (S′, Eq. 21), m = 1"),
                  ("cubic", "compliance", 5, "cubic, fit of compliances (S̃, Eq. 18), m = 5"))


def _share(reason: np.ndarray, why: str = "masked") -> float:
    """Share of the fits made (:func:`analysis.elastic.mask_counts`) that are masked, or masked for ``why``."""
    counts = mask_counts(reason)
    return counts[why] / counts["fitted"] if counts["fitted"] else np.nan


def fig_moduli(mod: xr.Dataset, heights: list[float], outputs: list[str], dpi: int = 150, protocol: str = "") -> None:
    """Fig. 4: left isotropic K, E, G (S′, m = 1); right cubic K, E_av, G_av (S̃, m = 5).

    Parameters
    ----------
    mod : xarray.Dataset
        ``moduli.nc`` of one protocol.
    heights : list of float
        Layers (m; nearest grid row), the paper's 4.5–27 cm.
    outputs : list of str
        Files to write.
    dpi : int
        Resolution of raster outputs.
    protocol : str
        Name in the title (default: the file's attribute).

    Notes
    -----
    Lines: the mean over piles of the piles' own fits (``<name>_pile_mean``),
    bands ± ``<name>_sem``, the standard error over those piles; dotted: the
    fit of the ensemble mean (``<name>``, the paper's way). With
    ``uncertainty_method`` ``bootstrap`` the line is the fit of the ensemble
    mean and the band its bootstrap spread. Masked fits (``mask_reason``:
    ill-conditioned, not positive definite, too few valid piles) are NaN and
    not drawn; each legend gives per layer the share of its RVEs whose mean
    over piles is masked, heights with nothing to draw are left out. All panels
    share one scale, from the values drawn.
    """
    fig, axes = plt.subplots(3, 2, figsize=(11, 10), sharex=True, sharey=True, layout="constrained")
    x = mod["x"].values
    rows = _rows(mod, heights)
    piles = mod.attrs.get("uncertainty_method", "pile_fits") == "pile_fits" and "bulk_modulus_pile_mean" in mod
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    drawn = []
    for col, (law, fit, m, title) in enumerate(MODULI_COLUMNS):
        sub = mod.sel(fit=fit, points=m)
        reason = sub[f"{law}_mask_reason_pile_mean" if piles else f"{law}_mask_reason"].values
        empty = []
        for r, panels in enumerate(MODULI_ROWS):
            ax = axes[r, col]
            label, name = panels[col]
            for n_row, (k, h) in enumerate(rows):
                colour = colours[n_row % len(colours)]
                main = sub[f"{name}_pile_mean" if piles else name].isel(y=k).values
                sem = sub[f"{name}_sem"].isel(y=k).values
                share = _share(reason[k])
                line = _band(ax, x, main, sem, color=colour, marker="o", ms=2,
                             label=f"y = {h * 100:.1f} cm ({100 * share:.0f} % masked)")
                if line is None and r == 0 and np.isfinite(share):
                    empty.append(f"{h * 100:.1f}")
                if line is not None:
                    drawn.append(main[np.isfinite(main)])
                if piles:
                    ens = sub[name].isel(y=k).values
                    if np.isfinite(ens).any():
                        ax.plot(x, ens, ":", color=colour, lw=1)
                        drawn.append(ens[np.isfinite(ens)])
            ax.set_ylabel(f"{label} (N/m)")
            ax.axhline(0, color="0.6", lw=0.5)
        note = f"masked: {100 * _share(reason):.0f} % of the RVEs fitted"
        if f"{law}_mask_reason_piles" in sub:
            own = sub[f"{law}_mask_reason_piles"].values
            note += (f"\nthe piles' own fits: {100 * _share(own, 'not_positive_definite'):.0f} % not positive "
                     f"definite, {100 * _share(own, 'ill_conditioned'):.0f} % ill-conditioned")
        if empty:
            note += f"\nnothing left to draw at y = {', '.join(empty)} cm"
        axes[0, col].set_title(f"{title}\n{note}", fontsize=8)
        if axes[0, col].get_legend_handles_labels()[0]:
            axes[0, col].legend(fontsize=7, loc="upper right")
    values = np.concatenate(drawn) if drawn else np.zeros(1)
    hi = float(np.percentile(values, 99.5)) if values.size else 1.0
    lo = min(0.0, float(np.percentile(values, 0.5)))
    axes[0, 0].set_ylim(lo - 0.05 * (hi - lo), hi + 0.15 * (hi - lo))
    for ax in axes.ravel():
        _sci(ax, "y")
    for ax in axes[-1]:
        ax.set_xlabel("x (m)")
    what = ("lines: mean over piles of each pile's own fit, bands: ± standard error over piles, dotted: fit of "
            "the ensemble mean" if piles
            else f"fit of the ensemble mean, bands: {mod.attrs.get('uncertainty_method', '')}")
    fig.suptitle(f"Elastic moduli, protocol {protocol or mod.attrs.get('protocol', '')} "
                 f"({_npiles(mod)}, {_rve_label(mod)})\n{what}\nnot drawn (masked): fits with a condition number "
                 f"above {float(mod.attrs.get('max_condition', np.nan)):g} or not positive definite, means over "
                 f"fewer than {100 * float(mod.attrs.get('min_valid_piles', np.nan)):.0f} % of the piles", fontsize=9)
    save(fig, outputs, dpi)


def fig_invariants(inv: xr.Dataset, outputs: list[str], dpi: int = 150, protocol: str = "") -> None:
    """Fig. 5: −tr Δσ against −tr u (loading step) for all RVEs, and the bulk modulus against depth."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), layout="constrained")
    ts, tu, d = (inv[k].values.ravel() for k in ("trace_stress_increment", "trace_strain_increment", "depth"))
    ok = np.isfinite(ts) & np.isfinite(tu)
    sc = axes[0].scatter(tu[ok], ts[ok], c=d[ok], s=6, cmap="viridis")
    fig.colorbar(sc, ax=axes[0], label="depth below surface (m)")
    axes[0].set_xlabel("−tr u (loading reduced → full gravity) (1)")
    _sci(axes[0])
    axes[0].set_ylabel("−tr Δσ (N/m)")
    axes[0].set_title("a", loc="left")
    db = inv["depth_bin"].values
    axes[1].plot(db, inv["differential_bulk_modulus"].values, "o-", label="differential ½ d tr Δσ / d tr u")
    axes[1].plot(db, inv["secant_bulk_modulus"].values, "s--", label="secant ½ tr Δσ / tr u")
    axes[1].set_xlabel("depth below the free surface (m)")
    axes[1].set_ylabel("bulk modulus (N/m)")
    axes[1].set_title("b", loc="left")
    axes[1].legend(fontsize=7)
    fig.suptitle(f"Stress and strain invariants, protocol {protocol or inv.attrs.get('protocol', '')} "
                 f"({_npiles(inv)}, {_rve_label(inv)})", fontsize=10)
    save(fig, outputs, dpi)


def fig_base_pressure(bps: dict[str, xr.Dataset], outputs: list[str], dpi: int = 150) -> None:
    """Normal and shear force per unit length on the support, mean ± standard error, all protocols."""
    fig, axes = plt.subplots(2, 1, figsize=(7.5, 7), sharex=True, layout="constrained")
    for proto, ds in bps.items():
        x = ds["x"].values
        lab = f"{proto} ({_npiles(ds)})"
        _band(axes[0], x, ds["normal_force_density"].values, ds["normal_force_density_sem"].values, label=lab)
        _band(axes[1], x, ds["shear_force_density"].values, ds["shear_force_density_sem"].values, label=lab)
    axes[0].set_ylabel("normal force per length (N/m)")
    axes[1].set_ylabel("shear force per length, +x (N/m)")
    axes[1].set_xlabel("x (m)")
    axes[1].axhline(0, color="0.6", lw=0.5)
    axes[0].legend(fontsize=8)
    bw = next(iter(bps.values())).attrs.get("bin_width", "") if bps else ""
    fig.suptitle(f"Forces on the support at full gravity (bins {float(bw) * 100:.1f} cm), "
                 "mean ± standard error over piles" if bw != "" else "Forces on the support", fontsize=10)
    save(fig, outputs, dpi)


def fig_general(generals: dict[str, xr.Dataset], heights: list[float], outputs: list[str],
                dpi: int = 150) -> None:
    """The general elastic fit (#14), one row per protocol: (a) reversibility of
    the gravity reduction over the pile; (b) stiffness axis (m = 5) against the
    fabric and stress axes in the two lowest layers; (c) fractions of the stress
    increments explained by the general, cubic and isotropic laws (m = 5)."""
    fig, axes = plt.subplots(len(generals), 3, figsize=(15, 4 * len(generals)), layout="constrained",
                             squeeze=False)
    for row, (protocol, ds) in zip(axes, generals.items()):
        x, y = ds["x"].values, ds["y"].values
        mesh = row[0].pcolormesh(x, y, ds["reversibility"].values, vmin=0.0, vmax=1.0, cmap="viridis",
                                 shading="nearest")
        fig.colorbar(mesh, ax=row[0], label="reversibility (1)")
        row[0].set_aspect("equal")
        row[0].set_xlabel("x (m)")
        row[0].set_ylabel("y (m)")
        row[0].set_title(f"a  {protocol}: 1 - |u(restored)| / |u(reduced)|", loc="left", fontsize=9)
        five = ds.sel(points=5)
        for (k, h), ls in zip(_rows(ds, heights)[:2], ("-", "--")):
            for name, lab in (("axis_deg", "stiffest axis"), ("fabric_orientation", "fabric"),
                              ("stress_orientation", "stress")):
                if name in five:
                    row[1].plot(x, five[name].isel(y=k).values, ls, label=f"{lab}, y = {h * 100:.1f} cm")
        row[1].set_ylabel("axis from vertical, counter-clockwise (degree)")
        row[1].set_xlabel("x (m)")
        row[1].set_title("b  stiffness, fabric and stress axes", loc="left", fontsize=9)
        row[1].legend(fontsize=7)
        k, h = _rows(ds, heights)[0]
        for name, lab in (("explained_general", "general"), ("explained_cubic", "cubic"),
                          ("explained_isotropic", "isotropic")):
            _band(row[2], x, five[name].isel(y=k).values, five[f"{name}_sem"].isel(y=k).values, label=lab)
        row[2].set_ylim(-0.1, 1.05)
        row[2].set_xlabel("x (m)")
        row[2].set_ylabel("fraction of the stress increments explained")
        row[2].set_title(f"c  y = {h * 100:.1f} cm; probes {ds.attrs.get('loading_probes', '')}; "
                         f"{ds.attrs.get('n_seeds', '?')} piles", loc="left", fontsize=9)
        row[2].legend(fontsize=7)
    save(fig, outputs, dpi)


FIGURES: dict[str, Any] = {
    "convergence": fig_convergence,
    "vertical-strain": fig_vertical_strain,
    "fabric": fig_fabric,
    "moduli": fig_moduli,
    "invariants": fig_invariants,
    "base-pressure": fig_base_pressure,
    "general": fig_general,
}
