"""Reading a ``numerics`` configuration section, the global attributes of its
netCDF files, and writing text or figure files atomically (a temporary name, then a rename, so a killed job leaves no file
that looks whole)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
from datetime import datetime, timezone
from pathlib import Path

import yaml

from .. import __version__
from ..config import ConfigError
from ..io import atomic_write


def load_section(params, section):
    """The mapping ``numerics.<section>`` of a configuration.

    Parameters
    ----------
    params : str
        ``@FILE`` (YAML or JSON) or JSON text of a whole configuration.
    section : str
        Subsection of ``numerics``, e.g. ``"collisions"``.

    Returns
    -------
    dict
        The subsection, ``{}`` when absent (every setting takes its default).
    """
    if params.startswith("@"):
        path = Path(params[1:])
        if not path.exists():
            raise ConfigError(f"--params {params}: no such file")
        data = yaml.safe_load(path.read_text()) or {}
    else:
        try:
            data = json.loads(params)
        except json.JSONDecodeError as exc:
            raise ConfigError(f"--params is not valid JSON: {exc}") from None
    numerics = data.get("numerics") or {}
    if not isinstance(numerics, dict):
        raise ConfigError(f"numerics = {numerics!r}: must be a mapping of sections")
    sub = numerics.get(section) or {}
    if not isinstance(sub, dict):
        raise ConfigError(f"numerics.{section} = {sub!r}: must be a mapping of settings")
    return sub


def run_command(section, description, argv, settings_class, compute, title, draw, tabulate):
    """``python -m sim numerics <section>``: settings, computation and its three files.

    Parses ``--params`` (the ``numerics.<section>`` mapping) and the output
    paths ``--nc``, ``--figure``, ``--table``; builds the settings, runs
    ``compute(settings)`` (an :class:`xarray.Dataset`), writes it with
    :func:`describe`'s attributes, ``draw(ds, path)`` and
    ``tabulate(ds, settings)`` (Markdown text), each atomically.

    Returns
    -------
    xarray.Dataset
    """
    ap = argparse.ArgumentParser(prog=f"python -m sim numerics {section}",
                                 description=description)
    ap.add_argument("--params", required=True,
                    help=f"@FILE (YAML/JSON) or JSON text with a numerics.{section} section")
    ap.add_argument("--nc", required=True, help="netCDF output")
    ap.add_argument("--figure", required=True, help="PNG output")
    ap.add_argument("--table", required=True, help="Markdown output")
    args = ap.parse_args(argv)
    raw = load_section(args.params, section)
    settings = settings_class.from_dict(raw)
    ds = describe(compute(settings), title, {"numerics": {section: raw}})
    atomic_write(ds, args.nc)
    draw(ds, args.figure)
    atomic_text(tabulate(ds, settings), args.table)
    return ds


def settings_from_dict(cls, section, data):
    """A settings dataclass from its mapping; missing keys take defaults,
    unknown keys are refused with the allowed ones listed."""
    data = dict(data or {})
    allowed = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise ConfigError(f"numerics.{section}: unknown setting(s) {unknown}; "
                          f"allowed: {sorted(allowed)}")
    return cls(**data)


def _temporary(path):
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return path, path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")


def atomic_text(text, path):
    """Write ``text`` to ``path`` through a temporary file and a rename."""
    path, tmp = _temporary(path)
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def atomic_figure(fig, path, **kwargs):
    """Save a matplotlib figure to ``path`` through a temporary file and a rename."""
    path, tmp = _temporary(path)
    try:
        fig.savefig(tmp, **kwargs)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def describe(ds, title, config):
    """Add the global attributes (CF ``Conventions``, ``title``, ``source``,
    ``history``, ``config``) to a dataset of this package."""
    ds.attrs.update({
        "Conventions": "CF-1.10",
        "title": title,
        "source": f"polypile sim {__version__} (python -m sim numerics)",
        "history": f"{datetime.now(timezone.utc).isoformat(timespec='seconds')} "
                   f"python -m sim {' '.join(sys.argv[1:])}".strip(),
        "config": json.dumps(config, sort_keys=True),
    })
    return ds
