"""Exceptions raised by the analysis: each message names the file, setting or
value at fault and what would be accepted."""


class AnalysisError(Exception):
    """Base class of all errors the command line reports without a traceback."""


class ParamError(AnalysisError, ValueError):
    """An invalid setting in the ``analysis`` configuration section."""


class StateError(AnalysisError, ValueError):
    """A particle-state file that does not follow docs/formats.md#state-files."""


class InputError(AnalysisError, ValueError):
    """Input files that do not fit together (grids, seeds, variables)."""


class BalanceError(AnalysisError):
    """A balance-law check on a pile failed beyond its tolerance."""
