"""Checks of a configuration's piles before any of them runs.

The pour and every stage refuse a run their time step cannot carry when they
start (:func:`sim.pour.check_pour`, :func:`sim.relax.check_stage`), which in
a workflow is after other jobs have run.  :func:`check_piles` applies the same
rules to the settings alone, so that the workflow can refuse them before its
first job: the particles are drawn for one seed (the recipe's failure is
named), each protocol's pour is checked on them, and the relaxation of a pile
as tall as :func:`sim.release.pile_height_bound` allows, at rest.

The check is of the settings, not of every seed's draw: the pour of another
seed checks its own particles again when it starts (their masses and sizes
differ by a few per cent between seeds).
"""

from __future__ import annotations

from .config import SimConfig
from .pour import GRAVITY, check_pour, pile_shapes, rough_base
from .relax import check_stage_run
from .release import pile_height_bound
from .scene import make_scene


def check_piles(cfg: SimConfig, protocols, seed: int) -> None:
    """Refuse settings under which a pile of ``protocols`` cannot be poured and relaxed.

    Parameters
    ----------
    cfg : SimConfig
        The piles' settings.
    protocols : iterable of str
        ``wedge``, ``layered``.
    seed : int
        The seed whose particles are drawn.

    Raises
    ------
    sim.config.ConfigError
        In one line naming the settings, their values and what is allowed.
    """
    shapes = pile_shapes(cfg, seed)
    for protocol in protocols:
        check_pour(cfg, protocol, seed, shapes)
    phys = cfg.physics
    base = rough_base(cfg, seed, shapes)
    scene = make_scene(shapes, cfg.model, phys.support, phys.walls, phys.rotation, base=base)
    top = pile_height_bound(shapes, phys.walls) + (0.0 if base is None else base.top)
    check_stage_run(cfg, scene, f"relaxation of a pile of seed {seed}", 0.0, top, GRAVITY)
