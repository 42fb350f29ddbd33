"""The command lines of the pile and ensemble numerics
(``python -m analysis.numerics.pile_precision``, ``python -m analysis.numerics.ensemble_cost``):
two subcommands, ``data`` (compute and write a netCDF file) and ``figure``
(draw it)."""

from __future__ import annotations

import argparse
import logging
import os
import sys
from typing import Callable

import xarray as xr

from ..command_files import check_paths

log = logging.getLogger("analysis.numerics")


def module_command(module: str) -> str:
    """The command line that is running, as ``python -m <module> <arguments>`` (for ``history``)."""
    return " ".join([os.path.basename(sys.executable), "-m", module, *sys.argv[1:]])


def data_or_figure(argv: list[str] | None, parser: argparse.ArgumentParser,
                   data: Callable[[argparse.Namespace], None],
                   figure: Callable[[xr.Dataset, list[str]], None]) -> int:
    """Run the subcommand ``data`` or ``figure`` that ``argv`` names.

    Parameters
    ----------
    argv : list of str or None
        The arguments (``None``: ``sys.argv[1:]``).
    parser : argparse.ArgumentParser
        With the subcommands ``data`` (``--out``) and ``figure`` (``--data``, ``--out``).
    data : callable
        ``data(args)`` computes and writes the dataset.
    figure : callable
        ``figure(ds, outputs)`` draws the dataset read from ``--data``.

    Returns
    -------
    int
        0, or 2 after logging a ValueError or FileNotFoundError (bad input;
        an output that is an input or another output, :func:`analysis.command_files.check_paths`).
    """
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, stream=sys.stderr, format="%(asctime)s %(levelname)s %(message)s")
    try:
        check_paths(args, parser.prog)
        if args.command == "data":
            data(args)
            log.info("wrote %s", args.out)
        else:
            with xr.open_dataset(args.data) as ds:
                figure(ds.load(), args.out)
        return 0
    except (ValueError, FileNotFoundError) as exc:
        log.error("%s", exc)
        return 2
