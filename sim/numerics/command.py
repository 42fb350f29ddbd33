"""The ``python -m sim numerics <section>`` commands: reading their section of
the configuration into settings and running a check (:func:`run_numerics_check`).

The files are written by :mod:`sim.io` (atomically, with the CF global
attributes of every file of ``sim``)."""

from __future__ import annotations

import argparse
import dataclasses
import sys

from ..config import ConfigError
from ..io import atomic_text, atomic_write, cf_attributes
from ..distinct_paths import PathRoles, at_file, check_distinct_paths
from ..settings_file import SettingsFileError, read_settings


def load_section(params, section):
    """The mapping ``numerics.<section>`` of a configuration.

    Parameters
    ----------
    params : str
        ``@FILE`` (YAML or JSON) or JSON or YAML text of a whole configuration,
        read by :func:`sim.settings_file.read_settings`.
    section : str
        Subsection of ``numerics``, e.g. ``"collisions"``.

    Returns
    -------
    dict
        The subsection, ``{}`` when absent (every setting takes its default).
    """
    try:
        data = read_settings(params, "--params")
    except SettingsFileError as exc:
        raise ConfigError(str(exc)) from None
    numerics = data.get("numerics") or {}
    if not isinstance(numerics, dict):
        raise ConfigError(f"numerics = {numerics!r}: must be a mapping of sections")
    sub = numerics.get(section) or {}
    if not isinstance(sub, dict):
        raise ConfigError(f"numerics.{section} = {sub!r}: must be a mapping of settings")
    return sub


#: The files of a check's command line (:func:`sim.distinct_paths.check_distinct_paths`).
PATHS = PathRoles(inputs=("--params",), outputs=("--nc", "--figure", "--table"),
                  read={"--params": at_file})


def parser(section, description):
    """The command line of ``python -m sim numerics <section>``: ``--params`` and the three outputs."""
    ap = argparse.ArgumentParser(prog=f"python -m sim numerics {section}",
                                 description=description)
    ap.add_argument("--params", required=True,
                    help=f"@FILE (YAML/JSON) or JSON/YAML text with a numerics.{section} section")
    ap.add_argument("--nc", required=True, help="netCDF output")
    ap.add_argument("--figure", required=True, help="PNG output")
    ap.add_argument("--table", required=True, help="Markdown output")
    return ap


def run_numerics_check(section, description, argv, settings_class, compute, title, draw,
                       tabulate):
    """``python -m sim numerics <section>``: settings, computation and its three files.

    Parses ``--params`` (the ``numerics.<section>`` mapping) and the output
    paths ``--nc``, ``--figure``, ``--table`` (:func:`parser`; no two of them
    one file, nor the ``--params`` file: :data:`PATHS`); builds the settings, runs
    ``compute(settings)`` (an :class:`xarray.Dataset`), writes it with the
    CF global attributes (:func:`sim.io.cf_attributes`), ``draw(ds, path)``
    and ``tabulate(ds, settings)`` (Markdown text), each atomically
    (:mod:`sim.io`).

    Returns
    -------
    xarray.Dataset
    """
    args = parser(section, description).parse_args(argv)
    check_distinct_paths(args, PATHS)
    raw = load_section(args.params, section)
    settings = settings_class.from_dict(raw)
    ds = compute(settings)
    ds.attrs.update(cf_attributes(title, {"numerics": {section: raw}},
                                  f"python -m sim {' '.join(sys.argv[1:])}",
                                  source="python -m sim numerics"))
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
