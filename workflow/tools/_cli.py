"""What every tool's command line shares: the one-line refusal and the checked argument types.

A tool refuses a bad argument or file by raising :class:`Refusal` (or
:func:`refuse`) with one line that names the argument or file, its value and
what is allowed; ``python -m workflow.tools`` prints that line after the
tool's name and exits 2, without a traceback.  :class:`ToolParser` turns argparse's own errors (an
unknown option, a value of the wrong type) into such a line, and the types
here (:func:`positive_int`, :func:`output_file`, ...) check a value when it is
parsed, so that nothing runs before the whole command line is known good.
"""

from __future__ import annotations

import argparse
import json
import math
import re
from pathlib import Path
from typing import NoReturn

REPO = Path(__file__).resolve().parents[2]


class Refusal(SystemExit):
    """A tool's refusal: one line naming the argument or file, its value and what is allowed.

    A :class:`SystemExit`, so that a tool's ``main`` called by other code also
    ends with that line (status 1) and no traceback.
    """


def refuse(message: str) -> NoReturn:
    """Raise :class:`Refusal` with `message` (one line)."""
    raise Refusal(message)


class ToolParser(argparse.ArgumentParser):
    """An argument parser whose errors are a :class:`Refusal` (one line) instead of usage and exit."""

    def error(self, message: str) -> NoReturn:
        """Refuse with argparse's message and a pointer to ``--help``."""
        refuse(f"{message} (--help lists the options)")


def positive_int(text: str) -> int:
    """An argument type: a whole number of at least 1."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: allowed is a whole number of at least 1")
    return value


def seed(text: str) -> int:
    """An argument type: a pile's seed, a whole number from 0 to 2^32 - 1."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value < 2**32:
        raise argparse.ArgumentTypeError(f"{text!r}: allowed is a seed, a whole number from 0 to 4294967295")
    return value


def _number(text: str, allowed: str, ok) -> float:
    """`text` as a number for which ``ok(value)`` holds, else an argparse error saying what is `allowed`."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not ok(value):
        raise argparse.ArgumentTypeError(f"{text!r}: allowed is {allowed}")
    return value


def positive_float(text: str) -> float:
    """An argument type: a finite number above 0."""
    return _number(text, "a finite number above 0", lambda v: math.isfinite(v) and v > 0)


def fraction(text: str) -> float:
    """An argument type: a number from 0 up to, not including, 1."""
    return _number(text, "a number from 0 up to, not including, 1", lambda v: 0 <= v < 1)


def output_file(text: str) -> Path:
    """An argument type: a file to write, in a folder that exists."""
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} is a folder; allowed is a file in an existing folder")
    if not path.absolute().parent.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r}: no folder {str(path.absolute().parent)!r}; allowed is a "
                                         "file in an existing folder")
    return path


def existing_file(text: str) -> Path:
    """An argument type: a file that exists."""
    path = Path(text)
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{text!r}: no such file")
    return path


def existing_folder(text: str) -> Path:
    """An argument type: a folder that exists."""
    path = Path(text)
    if not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r}: no such folder")
    return path


def plain_name(text: str) -> str:
    """An argument type: a name usable as one file or folder name (letters, digits, ``_ . -``)."""
    if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]*", text) or ".." in text:
        raise argparse.ArgumentTypeError(f"{text!r}: allowed is one name of letters, digits and _ . - "
                                         "(no folder, no '..')")
    return text


def analysis_params(text: str) -> dict:
    """An argument type: analysis settings as JSON or YAML flow text (or ``@file``), validated
    (:func:`analysis.params.parse_params`)."""
    from analysis.params import parse_params   # only the tools that take them load the analysis
    try:
        return parse_params(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(" ".join(str(exc).split())) from None


def shown(path: Path) -> str:
    """A path as a page names it: relative to the repository where it lies inside, else absolute."""
    path = Path(path).absolute()
    return str(path.relative_to(REPO)) if path.is_relative_to(REPO) else str(path)


def read_json(path: Path, what: str = "record"):
    """The JSON value of the file `path`; a :class:`Refusal` naming the file when it cannot be read."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        refuse(f"{what} {path}: not readable as JSON ({type(exc).__name__}: {exc})")
