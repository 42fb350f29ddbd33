"""The stages of a pile: their names, the probe each stands for and the
simulator's options that make it (docs/formats.md#stages).

``poured`` and ``relaxed`` come from the pour and the relaxation; every other
stage is a probe of the relaxed pile (config ``probe``).
"""

import re

#: Stage names of the probes: the gravity reductions, tilts, the restoring
#: probe and the support stretch.
STAGE_PATTERN = r"reduced|reduced\d\d|tilt[pm]\d\d|restored|stretched"
#: Every stage of a pile.
PILE_STAGE_PATTERN = rf"poured|relaxed|{STAGE_PATTERN}"
#: The support-stretch probe (config probe.stretch) and its own settings: only
#: its job reads them, and only it gets them (:meth:`workflow.jobs.JobSettings.probe_job_params`).
STRETCH_STAGE = "stretched"
STRETCH_KEYS = ("stretch", "stretch_time")
#: The rules that make the stages no probe makes (workflow/rules/pour.smk,
#: relax.smk); rule probe (probe.smk) makes every other stage.
STAGE_RULES = {"poured": "pour", "relaxed": "relax"}


def tilt_stage(tilt):
    """Stage name of the tilted-gravity probe with horizontal component `tilt` g0.

    Parameters
    ----------
    tilt : float
        Signed tilt, in units of g0.

    Returns
    -------
    str
        ``tiltpNN`` for tilt > 0, ``tiltmNN`` for tilt < 0, NN = round(100 |tilt|).
    """
    return f"tilt{'p' if tilt > 0 else 'm'}{round(100 * abs(float(tilt))):02d}"


def stage_rule(stage):
    """The rule that makes `stage`: ``pour``, ``relax``, or ``probe`` for any
    other stage (the rules' wildcard ``"{stage}"`` included)."""
    return STAGE_RULES.get(stage, "probe")


def probe_input_stage(stage):
    """The stage a probe starts from: ``reduced`` for ``restored``, else ``relaxed``."""
    return "reduced" if stage == "restored" else "relaxed"


class Stages:
    """The stages of the piles of a validated configuration (config ``probe``).

    Parameters
    ----------
    config : dict
        The workflow configuration, validated with its defaults filled in
        (:func:`workflow.validation.validate_config`).
    """

    def __init__(self, config):
        self.config = config

    def stage_for_level(self, level):
        """Stage name of the gravity probe with reduction `level` (Delta).

        The first level in config probe.levels is the stage ``reduced`` of
        docs/formats.md#stages; any other is reducedNN with NN = round(100 * level).
        """
        levels = [float(x) for x in self.config["probe"]["levels"]]
        if float(level) == levels[0]:
            return "reduced"
        return f"reduced{round(100 * float(level)):02d}"

    def level_for_stage(self, stage):
        """Inverse of :meth:`stage_for_level`, for the probe rule's ``stage`` wildcard.

        Raises
        ------
        ValueError
            When `stage` is no configured gravity probe, naming probe.levels.
        """
        for level in self.config["probe"]["levels"]:
            if self.stage_for_level(level) == stage:
                return float(level)
        raise ValueError(
            f"stage {stage!r} is not a configured gravity probe; "
            f"probe.levels {self.config['probe']['levels']} give {self.probe_stages()}"
        )

    def probe_stages(self):
        """Stage names of all configured gravity probes, in config order."""
        return [self.stage_for_level(level) for level in self.config["probe"]["levels"]]

    def signed_tilts(self):
        """Every tilted probe's tilt (config probe.tilts, each with + and - sign)."""
        return [sign * float(t) for t in self.config["probe"]["tilts"] for sign in (1.0, -1.0)]

    def tilt_stages(self):
        """Stage names of the tilted-gravity probes (config probe.tilts)."""
        return [tilt_stage(t) for t in self.signed_tilts()]

    def stretch_stages(self):
        """The support-stretch probe's stage, if config probe.stretch is not 0."""
        return [STRETCH_STAGE] if float(self.config["probe"]["stretch"]) != 0.0 else []

    def extra_probe_stages(self):
        """The probes beyond the gravity reductions: the tilts, the support
        stretch (probe.stretch) and, with probe.restore, the stage ``restored``
        (full gravity after ``reduced``)."""
        restored = ["restored"] if self.config["probe"]["restore"] else []
        return self.tilt_stages() + self.stretch_stages() + restored

    def probe_change(self, stage):
        """The simulator's options of the probe `stage` (python -m sim probe):
        --level Delta, --tilt +-delta, --stretch epsilon or --restore."""
        if stage == "restored":
            return ["--restore"]
        if stage == STRETCH_STAGE:
            return ["--stretch", repr(float(self.config["probe"]["stretch"]))]
        for tilt in self.signed_tilts():
            if stage == tilt_stage(tilt):
                return ["--tilt", repr(tilt)]
        return ["--level", repr(self.level_for_stage(stage))]

    def all_stages(self):
        """Every stage of a pile: poured, relaxed and every probe."""
        return ["poured", "relaxed"] + self.probe_stages() + self.extra_probe_stages()

    def final_stages(self):
        """The stages a pile makes last, whose files make it finished: every
        probe (:meth:`all_stages` after ``relaxed``), or ``relaxed`` when there
        is none."""
        return self.all_stages()[2:] or ["relaxed"]

    def problems(self):
        """The workflow's own checks of its stage names and probes, which
        neither the schemas nor the packages' checks (workflow/validation.py)
        express.

        Returns
        -------
        list of str
            One message per problem, naming the settings, their values and
            what is allowed; empty for a usable configuration.
        """
        config, problems = self.config, []
        stages, tilts = self.probe_stages(), self.tilt_stages()
        if len(set(stages)) != len(stages):
            problems.append(
                f"probe.levels {config['probe']['levels']} give repeated stage names "
                f"{stages}: levels must differ at percent resolution"
            )
        if len(set(tilts)) != len(tilts):
            problems.append(
                f"probe.tilts {config['probe']['tilts']} give repeated stage names {tilts}: "
                "tilts must differ at percent resolution"
            )
        problems += self._stretch_problems()
        if config["probe"]["restore"] and not stages:
            problems.append(
                "probe.restore = true with probe.levels = []: restoring gravity needs a "
                "gravity reduction first (give a level)"
            )
        bad = [s for s in stages if not re.fullmatch(STAGE_PATTERN, s)]
        if bad:
            problems.append(
                f"probe.levels {config['probe']['levels']} give stage names {bad} "
                f"outside 'reduced' / 'reducedNN': keep each level in [0.005, 0.995)"
            )
        return problems

    def _stretch_problems(self):
        """A support stretch (probe.stretch) without a support, or without its friction."""
        stretch, problems = float(self.config["probe"]["stretch"]), []
        if stretch != 0.0 and not self.config["physics"]["support"]:
            problems.append(
                f"probe.stretch = {stretch} with physics.support = false: the stretch moves the "
                "support's surface; set probe.stretch to 0"
            )
        if stretch != 0.0 and self.config["model"]["support_friction"] == 0:
            problems.append(
                f"probe.stretch = {stretch} with model.support_friction = 0: the support drags the "
                "particles only through friction; give model.support_friction > 0 or set probe.stretch to 0"
            )
        return problems

