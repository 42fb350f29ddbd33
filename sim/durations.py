"""Durations as a person reads them: ``h:mm:ss``.

The progress lines of the simulator (:class:`sim.progress.Progress`) and of
the study (``workflow/tools/study_progress.py``) both write their times
left with :func:`hms`, and the study reads the simulator's back with
:func:`parse_hms`.  This module imports nothing heavy, so that the workflow's
scripts can use it cheaply.
"""

from __future__ import annotations

import math
import re

#: What :func:`hms` writes for a duration that is not known (NaN, infinite, None).
UNKNOWN = "unknown"

_HMS = re.compile(r"(-?)(\d+):([0-5]\d):([0-5]\d)")


def hms(seconds):
    """A duration as ``h:mm:ss``, rounded to the nearest second.

    Parameters
    ----------
    seconds : float or None
        The duration, s.  The hours are not wrapped into days: 25 hours are
        ``25:00:00``.

    Returns
    -------
    str
        E.g. ``0:00:00``, ``0:01:00`` (59.5 s: halves round up), ``1:00:00``,
        ``27:46:40``; a negative duration has a leading ``-``; :data:`UNKNOWN`
        for NaN, an infinity, None or anything that is no number.

    Examples
    --------
    >>> hms(397.2)
    '0:06:37'
    >>> hms(float("nan"))
    'unknown'
    """
    try:
        value = float(seconds)
    except (TypeError, ValueError):
        return UNKNOWN
    if not math.isfinite(value):
        return UNKNOWN
    total = math.floor(abs(value) + 0.5)
    hours, rest = divmod(total, 3600)
    minutes, secs = divmod(rest, 60)
    sign = "-" if value < 0 and total > 0 else ""
    return f"{sign}{hours}:{minutes:02d}:{secs:02d}"


def parse_hms(text):
    """The seconds of an ``h:mm:ss`` duration as :func:`hms` writes it.

    Parameters
    ----------
    text : str

    Returns
    -------
    float or None
        Seconds; None when `text` is no ``h:mm:ss`` (e.g. :data:`UNKNOWN`).
    """
    match = _HMS.fullmatch(text.strip())
    if match is None:
        return None
    sign, hours, minutes, secs = match.groups()
    value = 3600.0 * int(hours) + 60.0 * int(minutes) + int(secs)
    return -value if sign else value
