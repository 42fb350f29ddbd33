"""The per-pile records of ``python -m workflow.tools calibration``: read whole, checked against their registration.

A record (``ARM-seedS.json``, one per pile) is read only whole
(:func:`read_records`: every field of :data:`FIELDS` of its type) and only
together with the settings file that registered its pile
(:func:`check_registered`: ``config/calibration.yaml``, ``config/levers.yaml``,
a decision's plan ``config/decision*.yaml``).  Each check refuses in one line
naming the record (:func:`workflow.tools._cli.refuse`), so that a copied, added
or altered record never enters a table or a verdict as a pile.
"""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

from sim.settings_file import merge_settings, read_settings_file

from ._cli import read_json, refuse

REPO = Path(__file__).resolve().parents[2]

#: The fields every record holds, and their types.
FIELDS = {"arm": str, "protocol": str, "seed": int, "n_particles": int, "settings": dict, "commit": str,
          "growth": dict, "quantities": dict, "cpu_s": dict}
#: The fields of numbers, a number (or NaN: not measured) each.
NUMBERS = ("growth", "quantities", "cpu_s")


def _shape_error(record) -> str | None:
    """What makes `record` no record (a field missing or of another type), or None."""
    if not isinstance(record, dict):
        return f"a JSON {type(record).__name__}, allowed is an object with {', '.join(FIELDS)}"
    for key, kind in FIELDS.items():
        value = record.get(key)
        if not isinstance(value, kind) or isinstance(value, bool):
            return f"{key} = {value!r}; allowed is a {kind.__name__}"
    for part in NUMBERS:
        for key, value in record[part].items():
            if not isinstance(value, (int, float)) or isinstance(value, bool):
                return f"{part}.{key} = {value!r}; allowed is a number"
    return None


def read_records(folder: Path, option: str = "--records") -> dict[Path, dict]:
    """Every record (``*.json``) of a folder, by file.

    Parameters
    ----------
    folder : Path
        The records' folder.
    option : str
        The argument that named it, for the messages.

    Returns
    -------
    dict
        Each record, by its file, in the order of the file names.

    Raises
    ------
    workflow.tools._cli.Refusal
        The folder is missing or holds no record; a file is no JSON, or a
        record lacks a field of :data:`FIELDS` or holds one of another type.
    """
    folder = Path(folder)
    if not folder.is_dir():
        refuse(f"{option} {folder}: no such folder")
    paths = sorted(folder.glob("*.json"))
    if not paths:
        refuse(f"{option} {folder}: no record (*.json) in it; allowed is a folder of pile records")
    records = {}
    for path in paths:
        record = read_json(path)
        error = _shape_error(record)
        if error:
            refuse(f"record {path}: {error}")
        records[path] = record
    return records


def check_unique(records: dict[Path, dict]) -> None:
    """Refuse a record whose pile another record is: the same arm and seed, or the same numbers.

    Two piles never grow alike to the last digit, so a record whose growth and
    quantities equal another's is a copy, whatever seed it names.
    """
    seen, numbers = {}, {}
    for path, r in records.items():
        other = seen.setdefault((r["arm"], r["seed"]), path)
        if other != path:
            refuse(f"record {path}: arm {r['arm']!r} seed {r['seed']} again (also {other.name}); "
                   "allowed is one record per pile")
        key = json.dumps([r["growth"], r["quantities"]], sort_keys=True)
        other = numbers.setdefault(key, path)
        if other != path:
            refuse(f"record {path}: seed {r['seed']} has the numbers of {other.name} (a copy under another "
                   "seed's name); allowed is one record per pile")


def registration_commit(plan: Path) -> str:
    """The commit that first added the settings file `plan` (what registered its piles).

    Raises
    ------
    workflow.tools._cli.Refusal
        Git is not there or no commit of this checkout adds the file.
    """
    try:
        log = subprocess.run(["git", "-C", str(REPO), "log", "--diff-filter=A", "--format=%H", "--",
                              str(Path(plan).absolute())], capture_output=True, text=True)
    except OSError as exc:
        refuse(f"{plan}: the commit that registered it is unknown: git cannot run ({exc})")
    commits = log.stdout.split()
    if log.returncode != 0 or not commits:
        refuse(f"{plan}: no commit of {REPO} adds it ({log.stderr.strip() or 'not committed'}); "
               "allowed is a committed registration")
    return commits[-1]


def _descends(commit: str, registered: str) -> bool | None:
    """Whether `commit` is `registered` or a descendant of it; None when git does not know it."""
    done = subprocess.run(["git", "-C", str(REPO), "merge-base", "--is-ancestor", registered, commit],
                          capture_output=True, text=True)
    return {0: True, 1: False}.get(done.returncode)


def read_registration(plan: Path) -> dict:
    """The settings file `plan` that registers piles: ``piles``, ``seeds`` and ``arms``, each arm a
    ``protocol`` and ``settings``; a :class:`workflow.tools._cli.Refusal` naming what it lacks."""
    reg = read_settings_file(plan)
    for key, kind in (("piles", str), ("seeds", list), ("arms", dict)):
        if not isinstance(reg.get(key), kind) or not reg[key]:
            refuse(f"{plan}: {key} = {reg.get(key)!r}; allowed is a registration of piles (a settings file), "
                   "seeds (a list) and arms (a mapping)")
    for arm, spec in reg["arms"].items():
        if not (isinstance(spec, dict) and isinstance(spec.get("protocol"), str)
                and isinstance(spec.get("settings"), dict)):
            refuse(f"{plan}: arm {arm!r} = {spec!r}; allowed is a protocol and settings")
    return reg


def check_registered(records: dict[Path, dict], plan: Path, replaces: str | None = None) -> None:
    """Refuse every record that the registration `plan` does not hold as one of its piles.

    Parameters
    ----------
    records : dict
        The records by file (:func:`read_records`).
    plan : Path
        The settings file that registered the piles (:func:`read_registration`;
        ``piles`` are merged over ``config/config.yaml``).
    replaces : str, optional
        A quantity whose NaN marks a missing pile, which the next seed after
        the registered ones replaces (the decision's rule); without it only
        the registered seeds are piles.

    Raises
    ------
    workflow.tools._cli.Refusal
        Naming the first record that is a copy of another (:func:`check_unique`),
        is of an arm the plan does not name, or of another protocol or settings
        than its arm, of another particle count or gravity probes
        (``definitions.probe_levels``, where the record says), of a seed outside the
        registered ones (and their replacements), or poured at a commit that is
        not the registration's (:func:`registration_commit`) or a later one.
    """
    reg = read_registration(plan)
    check_unique(records)
    registered = registration_commit(plan)
    base = merge_settings(read_settings_file(REPO / "config" / "config.yaml"), read_settings_file(REPO / reg["piles"]))
    seeds = list(reg["seeds"])
    descends = {}
    for path, r in records.items():
        arm = r["arm"]
        spec = reg["arms"].get(arm)
        if spec is None:
            refuse(f"record {path}: arm {arm!r} is not registered in {plan}; allowed: {', '.join(reg['arms'])}")
        if (r["protocol"], r["settings"]) != (spec["protocol"], spec["settings"]):
            refuse(f"record {path}: protocol {r['protocol']!r} with settings {r['settings']} is not arm {arm!r} "
                   f"of {plan} (protocol {spec['protocol']!r}, settings {spec['settings']})")
        arm_settings = merge_settings(base, spec["settings"])
        n, levels = arm_settings["pour"]["n_particles"], arm_settings["probe"]["levels"]
        if r["n_particles"] != n:
            refuse(f"record {path}: {r['n_particles']} particles; {plan} registers piles of {n}")
        if r["definitions"].get("probe_levels", levels) != levels:
            refuse(f"record {path}: probe.levels {r['definitions']['probe_levels']}; {plan} registers "
                   f"probe.levels {levels}")
        missing = sum(not math.isfinite(q["quantities"].get(replaces, math.nan))
                      for q in records.values() if q["arm"] == arm) if replaces else 0
        if r["seed"] not in seeds and not seeds[-1] < r["seed"] <= seeds[-1] + missing:
            refuse(f"record {path}: seed {r['seed']}; {plan} registers seeds {seeds[0]}-{seeds[-1]}"
                   + (f" and {missing} after them for the missing piles of {arm}" if missing else ""))
        if r["commit"] not in descends:
            descends[r["commit"]] = _descends(r["commit"], registered)
        if not descends[r["commit"]]:
            refuse(f"record {path}: poured at commit {r['commit']!r}, "
                   + ("unknown to git" if descends[r["commit"]] is None else "before")
                   + f" the registration of {plan} ({registered[:7]}); allowed is that commit or a later one")
