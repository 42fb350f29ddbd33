"""How the pour's sources grow a small pile: flank angle, moving particles and flux.

Pours a small pile (``--n`` particles, several seeds) from each source of
docs/model.md#protocols (wedge: drip, funnel; layered: top, rain) with a film
(:class:`sim.frames.FrameRecorder`, one frame every ``--frame`` s) and prints
one table row per source, medians over the frames of the growth (from
``--from`` of the particles released to the last release) of all seeds:

* the flank angle: the slope of a straight line fitted, on each side, to the
  surface profile (highest ``y + R`` of the settled particles in bins one mean
  diameter wide) where it lies between 20 % and 80 % of the tip's height,
  the mean of both sides (:func:`analysis.growth.flank_angle`);
* the moving particles: those faster than :data:`sim.release.SETTLED_SPEED`
  whose centre lies below the tip (particles of the pile, not falling ones),
  and among them those released more than :data:`OLD` s before (the pile set
  in motion, an avalanche, not a particle landing);
* the measured flux: particles released per second over the growth, against
  the source's (:func:`sim.release.source`).

Usage (docs/model.md, the table of the protocols)::

    python -m workflow.tools source_growth --n 300 --seeds 1 2 --out /tmp/growth
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import xarray as xr

from analysis.growth import OLD, flank_angle, growth
from sim.config import SimConfig
from sim.pour import GRAVITY, pile_shapes, pour
from sim.release import SETTLED_SPEED, mean_diameter, source
from sim.settings_file import yaml_value

from ._cli import ToolParser, fraction, positive_float, positive_int, refuse, seed

#: (protocol, pour settings) of each source measured.
SOURCES = {
    "wedge drip": ("wedge", {"point_source": "drip"}),
    "wedge funnel": ("wedge", {"point_source": "funnel"}),
    "layered top": ("layered", {"line_source": "top"}),
    "layered rain": ("layered", {"line_source": "rain"}),
}


def pour_setting(text: str) -> tuple[str, object]:
    """An argument type: one pour setting, ``KEY=VALUE`` (the value read as YAML)."""
    key, sep, value = text.partition("=")
    if not (sep and key):
        raise argparse.ArgumentTypeError(f"{text!r}: allowed is KEY=VALUE, a setting of pour")
    return key, yaml_value(value)


def source_config(n: int, frame: float, pour_settings: dict, settings: dict) -> SimConfig:
    """The simulator's settings of one source's pours: `n` particles, a frame every `frame` s."""
    try:
        return SimConfig.from_dict({"pour": {"n_particles": n, "frame_interval": frame,
                                             "progress_interval": 1e9, **pour_settings, **settings}})
    except ValueError as exc:   # the simulator's one line naming the setting
        refuse(f"--pour {pour_settings}: {' '.join(str(exc).split())}")


def frames_stem(out: Path, name: str, pour_items: list[str], n: int, frame: float, seed: int) -> Path:
    """Where one pour and its frames are kept (``.nc``, ``.frames.nc``): named by everything that makes
    them, so that a run of other settings never reuses another run's pour."""
    return out / "_".join([*name.split(), *pour_items, f"n{n}", f"frame{frame:g}", str(seed)])


def main(argv=None):
    """Command line: pour, then print one table row per source."""
    ap = ToolParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=positive_int, default=300, help="particles of each pile")
    ap.add_argument("--seeds", type=seed, nargs="+", default=[1, 2])
    ap.add_argument("--frame", type=positive_float, default=0.02, help="simulated s between frames")
    ap.add_argument("--from", dest="start", type=fraction, default=0.3,
                    help="the growth starts at this fraction of the particles released")
    ap.add_argument("--out", type=Path, required=True, help="folder of the pours (kept, reused by a rerun)")
    ap.add_argument("--sources", nargs="+", choices=list(SOURCES), default=list(SOURCES))
    ap.add_argument("--pour", nargs="*", type=pour_setting, default=[], metavar="KEY=VALUE",
                    help="pour settings for every source, e.g. release_speed=0.2")
    args = ap.parse_args(argv)
    if args.out.exists() and not args.out.is_dir():
        refuse(f"--out {args.out}: a file; allowed is a folder")
    extra = dict(args.pour)
    items = [f"{k}={v}" for k, v in args.pour]
    configs = {name: source_config(args.n, args.frame, extra, SOURCES[name][1]) for name in args.sources}
    args.out.mkdir(parents=True, exist_ok=True)
    print("| source | flank angle (deg): median [10-90 %] | moving particles: median [max] "
          f"| of them released > {OLD} s before: median [max] "
          "| flux measured / set (1/s) | final flank (deg), each seed |")
    print("|---|---|---|---|---|---|")
    for name in args.sources:
        protocol, cfg = SOURCES[name][0], configs[name]
        rows, fluxes, finals = [], [], []
        for s in args.seeds:
            stem = frames_stem(args.out, name, items, args.n, args.frame, s)
            frames = stem.with_suffix(".frames.nc")
            if not frames.exists():  # else poured by an earlier run of the same settings
                pour(cfg, protocol, s, stem.with_suffix(".nc"), frames=frames)
            shapes = pile_shapes(cfg, s)
            radius = shapes.radius[:args.n]
            d = mean_diameter(shapes)
            g = growth(frames, radius, d, args.start, SETTLED_SPEED)
            rows.append(g)
            fluxes.append((g[-1, 1] - g[0, 1]) / (g[-1, 0] - g[0, 0]))
            with xr.open_dataset(stem.with_suffix(".nc")) as st:
                finals.append(flank_angle(st.x.values, st.y.values + radius, d))
        g = np.concatenate(rows)
        angle = g[np.isfinite(g[:, 2]), 2]
        rate = source(cfg, shapes, protocol, GRAVITY).rate
        print(f"| {name} | {np.median(angle):.1f} [{np.percentile(angle, 10):.1f}-"
              f"{np.percentile(angle, 90):.1f}] | {np.median(g[:, 3]):.0f} [{g[:, 3].max():.0f}] "
              f"| {np.median(g[:, 4]):.0f} [{g[:, 4].max():.0f}] "
              f"| {np.mean(fluxes):.0f} / {rate:.0f} | "
              f"{' '.join(f'{a:.1f}' for a in finals)} |", flush=True)
