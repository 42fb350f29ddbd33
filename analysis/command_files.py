"""The files each ``python -m analysis`` command reads and writes, so that none
writes over a file it reads or over another of its outputs (``fields --relaxed
R.nc --out R.nc`` replaced the state it computed from): :func:`check_paths`
refuses such a command line in one line before anything is read, with the
simulator's :func:`sim.distinct_paths.check_distinct_paths`, which the
simulator's own command line uses too; so do the command lines of the pile
numerics (:data:`NUMERICS_PATHS`).
"""

from __future__ import annotations

import argparse

from sim.distinct_paths import PathCollision, PathRoles, at_file, check_distinct_paths

from .errors import ParamError
from .vtk import contacts_path, series_folder


class PathsError(ParamError):
    """An output of the command line is an input or another output (exit status 2, as a
    bad setting: nothing was read)."""


def labelled(item: str) -> str:
    """The path of a ``label=path`` item (``--probes``, ``--inputs``), or the item itself
    when it is a bare path: the part after ``=`` when the part before holds no ``/``."""
    label, sep, path = item.partition("=")
    return path if sep and "/" not in label else item


def _vtk_outputs(path: str) -> list[tuple[str, str]]:
    """What ``export --vtk`` writes besides its path: the contact network (with ``--input``)
    and the folder of the frames (with ``--frames``)."""
    return [("contact network", contacts_path(path)), ("folder of frames", series_folder(path))]


def _roles(inputs: tuple[str, ...], outputs: tuple[str, ...], **kwargs) -> PathRoles:
    """A command's :class:`~sim.distinct_paths.PathRoles`, with the ``--params @FILE`` that every
    command reads."""
    return PathRoles(inputs=("--params", *inputs), outputs=outputs,
                     read={"--params": at_file, **kwargs.pop("read", {})}, **kwargs)


#: The files of each command of ``python -m analysis`` (:func:`check_paths`).
PATHS = {
    "params": _roles((), ()),
    "fields": _roles(("--relaxed", "--reduced"), ("--out", "--checks")),
    "ensemble": _roles(("--fields",), ("--out",)),
    "probes": _roles(("--relaxed", "--probes"), ("--out",), read={"--probes": labelled}),
    "general-fit": _roles(("--probes", "--ensemble"), ("--out",)),
    "moduli": _roles(("--ensemble", "--fields"), ("--out",)),
    "voigt": _roles(("--fields",), ("--out",)),
    "base-pressure": _roles(("--states", "--piles"), ("--out",)),
    "invariants": _roles(("--ensemble",), ("--out",)),
    "convergence": _roles(("--relaxed", "--reduced"), ("--out",)),
    "draw": _roles(("--input",), ("--out",)),
    "export": _roles(("--input", "--frames"), ("--vtk",), derived={"--vtk": _vtk_outputs}),
    "film": _roles(("--input",), ("--out", "--html")),
    "run-times": _roles(("--benchmarks",), ("--out",)),
    "figure": _roles(("--inputs",), ("--out",), read={"--inputs": labelled}),
}


_FIGURE = PathRoles(inputs=("--data",), outputs=("--out",))

#: The files of the command lines of the pile numerics (:mod:`analysis.numerics`), by
#: program and subcommand (None: it has none); ``--params`` and ``--model`` there are JSON text.
NUMERICS_PATHS = {
    ("python -m analysis.numerics.pile_precision", "data"): PathRoles(
        inputs=("--states", "--summaries", "--pour-benchmarks", "--pour-cpu", "--relax-benchmarks",
                "--relax-cpu"), outputs=("--out",)),
    ("python -m analysis.numerics.pile_precision", "figure"): _FIGURE,
    ("python -m analysis.numerics.ensemble_cost", "data"): PathRoles(
        inputs=("--analysis-params", "--fields", "--pour-benchmarks", "--relax-benchmarks",
                "--probe-benchmarks", "--base-pressure"), outputs=("--out",),
        read={"--analysis-params": at_file}),
    ("python -m analysis.numerics.ensemble_cost", "figure"): _FIGURE,
    ("python -m analysis.numerics.piles_report", None): PathRoles(inputs=("--piles", "--ensemble"),
                                                                  outputs=("--out",)),
}


def check_paths(args: argparse.Namespace, program: str | None = None) -> None:
    """Refuse a command line whose output is one of its inputs or another output.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line: of ``python -m analysis`` (``args.command``
        one of :data:`PATHS`), or of `program`.
    program : str, optional
        A command line of :data:`NUMERICS_PATHS` (its ``prog``), whose
        subcommand is ``args.command`` if it has any.

    Raises
    ------
    PathsError
        One line naming both options and the file.
    """
    roles = (PATHS[args.command] if program is None else
             NUMERICS_PATHS[program, getattr(args, "command", None)])
    try:
        check_distinct_paths(args, roles)
    except PathCollision as exc:
        raise PathsError(str(exc)) from None
