"""Reading a ``numerics`` configuration section, the global attributes of its
netCDF files, and writing text or figure files atomically (a temporary name, then a rename, so a killed job leaves no file
that looks whole)."""

from __future__ import annotations

import json
import os
import sys
from datetime import datetime, timezone
from pathlib import Path

import yaml

from .. import __version__
from ..config import ConfigError


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


def describe(ds: xr.Dataset, title: str, config: dict) -> xr.Dataset:
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
