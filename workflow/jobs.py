"""The settings each simulation job of a pile receives: the simulator's
sections it reads, as canonical JSON (a Snakemake param, so that a changed
setting re-runs exactly the jobs that read it), and the bookkeeping settings
that change no result.
"""

import json

from sim.config import BOOKKEEPING, STAGE_SECTIONS, result_settings
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
    """The simulator settings of the simulation jobs of a validated configuration.

    Parameters
    ----------
    config : dict
        The workflow configuration, validated with its defaults filled in.
    """

    def __init__(self, config):
        self.config = config

    def sim_params(self, stage):
        """The simulator sections the job of ``stage`` reads, as canonical JSON (sorted keys).

        ``stage`` is ``pour``, ``relax`` or ``probe``; its sections are the
        simulator's map of them (:data:`sim.config.STAGE_SECTIONS`). A job
        receives only the sections it reads, so a changed setting re-runs
        exactly the jobs that depend on it (pouring reads model, particles,
        pour and physics; relaxing model, pour and relax, the physics coming
        with the poured state; probing also probe). Adding
        a gravity level therefore re-runs only the probes, and a change in
        analysis or protocols no simulation. The bookkeeping settings
        (sim.config.BOOKKEEPING: checkpoint and progress intervals) change no
        result and are left out; they travel in :meth:`sim_bookkeeping`.
        """
        return json.dumps(result_settings({k: self.config[k] for k in STAGE_SECTIONS[stage]}), sort_keys=True)

    def probe_sim_params(self, stage):
        """The simulator sections of the probe `stage` as canonical JSON
        (``sim_params("probe")``), each probe with only
        its own keys of ``probe``: the support stretch its STRETCH_KEYS, the
        gravity probes all others. So a scene that adds the stretch re-runs no
        gravity probe, and one that adds a tilt no stretch."""
        settings = json.loads(self.sim_params("probe"))
        stretch = stage == STRETCH_STAGE
        settings["probe"] = {k: v for k, v in settings["probe"].items() if (k in STRETCH_KEYS) == stretch}
        return json.dumps(settings, sort_keys=True)

    def sim_bookkeeping(self):
        """The bookkeeping settings (sim.config.BOOKKEEPING) as JSON for the
        simulator's --bookkeeping option, an :class:`Unrecorded` param: a changed
        checkpoint or progress interval re-pours no pile."""
        settings = {s: {k: self.config[s][k] for k in keys} for s, keys in BOOKKEEPING.items()}
        return Unrecorded(json.dumps(settings, sort_keys=True))

