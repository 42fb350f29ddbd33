"""The quantities by which two sets of piles are compared, one number per pile.

A pile's shape (the mean of its two flank angles, its height and base width,
from ``python -m sim summary``), the solid fraction of its core, the primary
construction-history statistics (:mod:`analysis.history`) and the core moduli
of its own isotropic fit.  Used by the parameter sweeps
(``workflow/tools/setting_sweep.py``) and by the side-by-side table of a
full-size variant against the study (``workflow/tools/variant_table.py``),
so that both compare the same numbers; with ``stress_column``, the flank fabric and the
numbers it and ``base_pressure_column`` are computed from, they make the record of a calibration
or decision pile (:func:`pile_record`, ``workflow/tools/calibration.py``).
"""

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from analysis.elastic import moduli_dataset
from analysis.fields import read_fields
from analysis.history import (base_pressure_inputs, flank_fabric, pile_history, pile_stress_contrasts, primary_names,
                              stress_column_inputs)

#: The pile's shape: key and heading.
SHAPE = {
    "angle_deg": "angle of repose (deg)",
    "height": "height (m)",
    "width": "base width (m)",
    "solid_fraction": "core solid fraction",
}
#: The pre-registered history statistics (analysis/history.py), per pile: the primary five, in order.
HISTORY = {
    "strain": "strain u_yy centre/shoulders − 1 at {h} cm",
    "base_pressure_column": "base pressure centre/shoulders against a uniform pile − 1",
    "solid_fraction@": "solid fraction centre/shoulders − 1 at {h} cm",
    "gravity_gap": "gravity scaling Δσ_xx/σ_xx ÷ Δσ_yy/σ_yy − 1",
    "stress_fabric": "stress–fabric angle on the flanks (deg)",
}
#: The core moduli of the pile's own isotropic fit (average of both fits, m = 5).
MODULI = {
    "youngs_modulus": "core E (N/m)",
    "bulk_modulus": "core K (N/m)",
}
#: The core: ``|x| <= CORE_X`` and ``y <= CORE_Y`` (m).
CORE_X, CORE_Y = 0.03, 0.05


def quantities(params: dict[str, Any]) -> dict[str, str]:
    """The compared quantities, ``{key: heading}``.

    Parameters
    ----------
    params : dict
        Resolved analysis settings (:func:`analysis.params.parse_params`).

    Returns
    -------
    dict
        The pile's shape, the primary history statistics under
        ``params["history"]`` (their keys from :func:`analysis.history.primary_names`)
        and the core moduli, in that order.
    """
    h = params["history"]
    cm = f"{100 * h['primary_height']:g}"
    history = {k: text.format(h=cm) for k, text in zip(primary_names(h), HISTORY.values())}
    return {**SHAPE, **history, **MODULI}


def relaxed_line(summary: Path) -> dict[str, Any]:
    """The ``relaxed`` stage's line of a pile's ``summary.json`` (one JSON object per line)."""
    lines = [json.loads(s) for s in Path(summary).read_text().splitlines() if s.strip()]
    try:
        return next(line for line in lines if line["stage"] == "relaxed")
    except StopIteration:
        raise ValueError(f"{summary}: no 'relaxed' stage among {[line['stage'] for line in lines]}") from None


def pile_quantities(summary: Path, fields: Path, base_pressure: Path, params: dict[str, Any]) -> dict[str, float]:
    """Every quantity of :func:`quantities` for one pile.

    Parameters
    ----------
    summary : Path
        The pile's ``summary.json`` (``python -m sim summary``).
    fields : Path
        Its RVE fields (``python -m analysis fields``).
    base_pressure : Path
        Its base pressure (``python -m analysis base-pressure``).
    params : dict
        Resolved analysis settings.

    Returns
    -------
    dict
        ``{key: value}``; the angle is the mean of both flanks, the core solid
        fraction and moduli the means over the core RVEs.  For a pile without a
        gravity probe (``probe.levels: []``, fields without the strain) the
        quantities read from the probe, ``strain@h``, ``gravity_xx``,
        ``gravity_yy``, ``gravity_gap`` and the moduli, are NaN; the others are
        those the pile gives with the probe, which runs after the relaxation.
    """
    rel = relaxed_line(summary)
    out = {"angle_deg": 0.5 * (rel["flank_left_deg"] + rel["flank_right_deg"]),
           "height": rel["height"], "width": rel["width"]}
    with xr.open_dataset(fields) as f, xr.open_dataset(base_pressure) as bp:
        f = f.load()
        core = (np.abs(f["x"]) <= CORE_X) & (f["y"] <= CORE_Y)
        out["solid_fraction"] = float(f["solid_fraction"].where(core).mean())
        out.update(pile_history(f, params, params["figures"]["heights"], bp.load()))
        if "strain_increment" not in f:               # no gravity probe: no fit
            return {**out, **dict.fromkeys(MODULI, math.nan)}
        mod = moduli_dataset(f, [], params)
    core = (np.abs(mod["x"]) <= CORE_X) & (mod["y"] <= CORE_Y)
    for k in MODULI:
        out[k] = float(mod[k].sel(fit="average", points=5).where(core).mean())
    return out


def pile_record(summary: Path, fields: Path, base_pressure: Path, params: dict[str, Any]) -> tuple[dict, dict]:
    """The numbers of one pile's calibration or decision record: its quantities, and what ``stress_column`` and ``base_pressure_column``
    are computed from.

    Parameters
    ----------
    summary, fields, base_pressure : Path
        The pile's files, as for :func:`pile_quantities`.
    params : dict
        Resolved analysis settings.

    Returns
    -------
    quantities : dict
        :func:`pile_quantities` (the probe's quantities NaN for a pile without one),
        ``stress_column`` (the σ_yy column contrast of the lowest RVE row,
        :func:`analysis.history.pile_stress_contrasts`) and the flank fabric
        (:func:`analysis.history.flank_fabric`).
    inputs : dict
        ``stress_column``'s grid row (:func:`analysis.history.stress_column_inputs`), ``base_pressure_column``'s support bins
        (:func:`analysis.history.base_pressure_inputs`) and the windows, so that a reader recomputes
        both from the record alone.
    """
    q = pile_quantities(summary, fields, base_pressure, params)
    f = read_fields(str(fields))
    q["stress_column"] = pile_stress_contrasts(f, params)["stress_column"]
    q.update(flank_fabric(f, params["history"]))
    with xr.open_dataset(base_pressure) as bp:
        inputs = {"stress_column": stress_column_inputs(f, params),
                  "base_pressure_column": base_pressure_inputs(bp.load(), f),
                  "windows": {k: params["history"][k] for k in ("centre", "shoulder_inner", "shoulder_outer")}}
    return q, inputs
