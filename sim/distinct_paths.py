"""Files of a command line that must not be one file: no output of ``python -m sim`` or
``python -m analysis`` may be an input or another output.

A run whose ``--out`` is its ``--checkpoint`` ends by removing the checkpoint,
which is then the pile; frames written to the state file's path are replaced by
the state; an analysis writing its fields over the state it read loses the
state.  :func:`check_distinct_paths` refuses such a command line in one line,
before anything runs; both command lines call it with a :class:`PathRoles` per
subcommand (``sim.cli.PATHS``, ``analysis.command_files.PATHS``), and tests walk
every option of every subcommand through it.

Two paths are one file when they resolve to the same path (relative or
absolute, through symbolic links, :func:`os.path.realpath`) or, both existing,
are the same file (a hard link).  Besides the paths given, an output's files
that the code derives from it take part (:attr:`PathRoles.derived`: a
checkpoint's ``.lock`` and frames, a state's ``.lastgood.nc``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Callable


class PathCollision(ValueError):
    """An output path that is an input's or another output's (one line, naming both options)."""


def at_file(value: str) -> str | None:
    """The file of a settings option given as ``@FILE`` (``--params @config.yaml``), else None."""
    return value[1:] if value.startswith("@") else None


@dataclass(frozen=True)
class PathRoles:
    """Which options of a subcommand name files it reads and which it writes.

    Parameters
    ----------
    inputs, outputs : tuple of str
        Options as written on the command line (``"--out"``; a positional
        argument by its name, ``"states"``).  An option given several times or
        with several values contributes each; None or an empty value none.
    read : dict of str to callable
        For an option whose value is not a bare path: ``read[option](value)``
        gives the path, or None when the value names no file (``--params``
        text that is not ``@FILE``: :func:`at_file`).
    derived : dict of str to callable
        For an output: ``derived[option](path)`` gives ``(words, path)`` pairs
        of the further files written beside it (``("lock", "c.nc.lock")``).
    """

    inputs: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()
    read: dict[str, Callable[[str], str | None]] = field(default_factory=dict)
    derived: dict[str, Callable[[str], list[tuple[str, str]]]] = field(default_factory=dict)

    @property
    def options(self) -> set[str]:
        """Every option of the subcommand that names files."""
        return set(self.inputs) | set(self.outputs)


def _dest(option: str) -> str:
    """The attribute of the parsed arguments that holds `option` (argparse's dest)."""
    return option.lstrip("-").replace("-", "_")


def _values(value) -> list[str]:
    """The strings of an option's value: itself, or each of a (nested) list."""
    if value is None:
        return []
    if isinstance(value, (list, tuple)):
        return [v for item in value for v in _values(item)]
    return [str(value)]


def _identity(path: str):
    """What makes two paths one file: the file's device and inode when it exists, else its
    resolved path (symbolic links followed)."""
    real = os.path.realpath(path)
    try:
        st = os.stat(real)
    except OSError:
        return ("path", real)
    return ("inode", st.st_dev, st.st_ino)


def check_distinct_paths(args, roles: PathRoles) -> None:
    """Refuse a command line where an output is an input or another output.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    roles : PathRoles
        Its subcommand's inputs, outputs and derived files.

    Raises
    ------
    PathCollision
        One line naming both options, the path and what is allowed, for the
        first output found to be the file of an input or of an earlier output
        (derived files included, named as such).
    """
    seen = {}   # identity of a file -> the words naming where it came from
    for kind, options in (("input", roles.inputs), ("output", roles.outputs)):
        for option in options:
            read = roles.read.get(option, lambda v: v)
            for value in _values(getattr(args, _dest(option), None)):
                path = read(value)
                if not path:
                    continue
                files = [(f"{option} {value}", path)]
                if kind == "output" and option in roles.derived:
                    files += [(f"the {words} {extra} of {option} {value}", extra)
                              for words, extra in roles.derived[option](path)]
                mine = set()
                for words, each in files:
                    key = _identity(each)
                    if kind == "output" and key in seen and key not in mine:
                        raise PathCollision(
                            f"{words} and {seen[key]} are the same file, {os.path.realpath(each)}: "
                            "an output must be neither an input nor another output (it would "
                            "be overwritten or removed); give it a path of its own")
                    mine.add(key)
                    seen.setdefault(key, words)
