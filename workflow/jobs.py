"""What the workflow adds to the settings of a simulation job: a probe's own
keys of ``probe``, and the bookkeeping settings as a param Snakemake does not
record.

The settings themselves are written by the simulator
(:meth:`sim.config.SimConfig.job_params`): the rules read them from
``study.sim``, the validated :class:`sim.config.SimConfig`.
"""

import json

from sim.config import STAGE_SECTIONS
from workflow.stages import STRETCH_KEYS, STRETCH_STAGE


class Unrecorded:
    """A rule param that Snakemake does not record, so that changing it re-runs
    nothing: Snakemake records and compares only params of builtin types.

    Parameters
    ----------
    text : str
        What the param reads as in a shell command.
    """

    def __init__(self, text):
        self.text = text

    def __str__(self):
        return self.text


class JobSettings:
    """The workflow's part of the simulation jobs' settings.

    Parameters
    ----------
    sim : sim.config.SimConfig
        The simulator's sections of the validated configuration.
    """

    def __init__(self, sim):
        self.sim = sim

    def probe_job_params(self, stage):
        """The ``--params`` of the probe `stage`: the settings of
        ``sim.job_params("probe")`` (its object, :meth:`sim.config.SimConfig.result_dict`,
        filtered before it is written), each probe with only its own keys of
        ``probe``: the support stretch its STRETCH_KEYS, the gravity probes all
        others. So a scene that adds the stretch re-runs no gravity probe, and
        one that adds a tilt no stretch."""
        settings = self.sim.result_dict(STAGE_SECTIONS["probe"])
        stretch = stage == STRETCH_STAGE
        probe = {k: v for k, v in settings["probe"].items() if (k in STRETCH_KEYS) == stretch}
        return json.dumps({**settings, "probe": probe}, sort_keys=True)

    def job_bookkeeping(self):
        """The ``--bookkeeping`` of every simulation job
        (:meth:`sim.config.SimConfig.job_bookkeeping`), an :class:`Unrecorded`
        param: a changed checkpoint or progress interval re-pours no pile."""
        return Unrecorded(self.sim.job_bookkeeping())
