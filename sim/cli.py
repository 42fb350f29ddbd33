"""Command line: ``python -m sim COMMAND [options]``, COMMAND one of pour, relax, probe,
warmup, bench, summary and numerics.

Run parameters come as ``--params`` (JSON or YAML text, or ``@file`` with
either; given again, each is merged over the ones before, later wins) holding
any of the sections ``model``, ``particles``, ``pour``, ``relax``,
``probe``, ``physics`` (see :mod:`sim.config`; missing settings take their defaults).  A
setting with a wrong type or value is refused before anything runs, with a
message naming the setting, the value and what is allowed.  ``--bookkeeping``
(JSON) carries the settings that change no result (checkpoint and progress
intervals), which the workflow passes apart so that changing them re-runs
nothing.  ``relax`` and ``probe`` take ``model.integrator`` and ``model.dt``
of the state file they read where ``--params`` sets neither.  No output may
be an input or another output, nor a file the run derives from one (a
checkpoint's lock, a state's last good state): such a command line is refused
in one line before anything runs (:mod:`sim.distinct_paths`), as are a
``--seed`` outside 0 to 2^32 - 1 and ``bench --threads`` beyond Numba's.
"""

from __future__ import annotations

import argparse
import json
import logging
import re
import sys
from pathlib import Path

from . import __version__
from .config import BOOKKEEPING, SECTIONS, ConfigError, SimConfig
from .checkpoint import last_good_path
from .frames import partial_path
from .atomic import OutputError
from .io import code_version, model_from_attrs, read_state
from .lock import lock_path
from .distinct_paths import PathRoles, at_file, check_distinct_paths
from .settings_file import SettingsFileError, merge_settings, read_settings


def _each(texts):
    """The ``--params`` given, as a list: `texts` itself, ``[texts]`` for one text, none for None."""
    return [texts] if isinstance(texts, str) else list(texts or ())


def _load_params(texts):
    """The settings dict of ``--params``: each one given, merged over those before.

    Parameters
    ----------
    texts : str, list of str or None
        ``--params`` (a list when the option is repeated): JSON or YAML text,
        or ``@FILE``, each read by :func:`sim.settings_file.read_settings`
        (one line naming the option or file, and the line, for an empty file,
        a list, a repeated key or a syntax error) and laid over the ones
        before it by :func:`sim.settings_file.merge_settings` (later wins,
        setting by setting).

    Returns
    -------
    dict
        Of a whole workflow configuration, only the simulator's sections.
    """
    data = {}
    for text in _each(texts):
        try:
            data = merge_settings(data, read_settings(text, "--params"))
        except SettingsFileError as exc:
            raise ConfigError(str(exc)) from None
    return {k: v for k, v in data.items()
            if k in SECTIONS}


#: Settings of ``model`` that fix the physics of a pile: relax and probe take
#: them from the state file they read, and refuse another value in ``--params``
#: (a stage goes on with the pile as it was poured; another modulus or friction
#: makes another pile, which is poured again).
PHYSICS = ("youngs_modulus", "damping", "friction", "support_friction", "density")

#: Settings of ``model`` that relax and probe take from the state file they
#: read unless ``--params`` sets them: a pile goes on as it was poured.  The
#: step and integrator may be set otherwise (a numerical choice), the
#: :data:`PHYSICS` not.
INHERITED = ("integrator", "dt") + PHYSICS


def _inherit(data, input_path):
    """Fill in the :data:`INHERITED` settings of the state file `input_path`.

    Parameters
    ----------
    data : dict
        The settings of ``--params``; its ``model`` section gets each setting
        of :data:`INHERITED` it lacks, with the value the file was made with
        (:func:`sim.io.model_from_attrs`).  One log line names them.
    input_path : path
        The state file that relax or probe reads.

    Raises
    ------
    ConfigError
        When ``--params`` sets one of :data:`PHYSICS` to another value than
        the file's.
    """
    model = data.get("model") or {}
    if not isinstance(model, dict):
        return  # SimConfig.from_dict names the bad section
    data["model"] = model
    stored = model_from_attrs(read_state(input_path))
    for k in PHYSICS:
        if k in model and isinstance(model[k], (int, float)) and float(model[k]) != getattr(stored, k):
            raise ConfigError(
                f"model.{k} = {model[k]:.4g} in --params, but {input_path} was poured with "
                f"model.{k} = {getattr(stored, k):.4g}; relax and probe go on with the physics of the pile "
                f"they start from: leave model.{k} out of --params (it is taken from the file), or pour "
                "the pile again with the new value")
    taken = [k for k in INHERITED if k not in model]
    if not taken:
        return
    model.update({k: getattr(stored, k) for k in taken})
    logging.getLogger("sim").info(
        "%s taken from the input %s (not set by --params)", ", ".join(
            f"model.{k} = {model[k]}" if k == "integrator" else f"model.{k} = {model[k]:.4g}{' s' if k == 'dt' else ''}"
            for k in taken), input_path)


def _params(text, bookkeeping=None, input_path=None):
    """The run's :class:`SimConfig` from ``--params`` and ``--bookkeeping``.

    ``--bookkeeping`` (JSON) holds only settings of :data:`BOOKKEEPING`; they
    override those of ``--params``.  With `input_path` (the state file of
    relax and probe) the settings :data:`INHERITED` that ``--params`` leaves
    out are that file's (:func:`_inherit`).
    """
    data = _load_params(text)
    if input_path is not None:
        _inherit(data, input_path)
    if bookkeeping is not None:
        try:
            extra = json.loads(bookkeeping)
        except json.JSONDecodeError as exc:
            raise ConfigError(f"--bookkeeping is not valid JSON: {exc}") from None
        if not isinstance(extra, dict):
            raise ConfigError(f"--bookkeeping = {bookkeeping!r}: must be a JSON object")
        for section, values in extra.items():
            allowed = BOOKKEEPING.get(section, ())
            if not isinstance(values, dict) or set(values) - set(allowed):
                raise ConfigError(
                    f"--bookkeeping: {section} = {values!r} holds settings that change the "
                    f"result; only {dict(BOOKKEEPING)} may come here, the rest in --params")
            data.setdefault(section, {}).update(values)
    try:
        return SimConfig.from_dict(data)
    except ConfigError as exc:  # name the files the settings came from
        files = [t for t in _each(text) if t.startswith("@")]
        raise ConfigError(f"--params {' '.join(files)}: {exc}" if files else str(exc)) from None


def _int_list(option, text):
    """Comma-separated positive integers of a command-line option."""
    try:
        values = tuple(int(v) for v in text.split(","))
    except ValueError:
        values = ()
    if not values or min(values) < 1:
        raise ValueError(f"{option} {text!r}: give positive integers separated by commas")
    return values


def _threads(text):
    """The thread counts of ``bench --threads``, each at most what Numba may start."""
    import numba

    values = _int_list("--threads", text)
    most = numba.config.NUMBA_NUM_THREADS
    if max(values) > most:
        raise ValueError(f"--threads {text!r}: at most {most} threads on this machine "
                         f"(NUMBA_NUM_THREADS = {most}); give counts from 1 to {most}")
    return values


def _seed(seed):
    """`seed` (``pour --seed``) if the generator and the state file take it, else ValueError."""
    from .pour import SEED_MAX

    if not 0 <= seed <= SEED_MAX:
        raise ValueError(f"--seed {seed}: must be an integer from 0 to {SEED_MAX} (2^32 - 1), "
                         "as the workflow's protocols.<protocol>.seeds")
    return seed


def _state_outputs(path):
    """The file a run beside its state ``path`` may write: the last good state of a blow-up."""
    return [("last good state", last_good_path(path))]


#: The files each subcommand reads and writes (:func:`sim.distinct_paths.check_distinct_paths`):
#: ``--params @FILE`` is read; the pour's checkpoint brings its lock and its frames so far.
PATHS = {
    "pour": PathRoles(inputs=("--params",),
                      outputs=("--out", "--checkpoint", "--frames", "--log", "--finished"),
                      read={"--params": at_file},
                      derived={"--out": _state_outputs,
                               "--checkpoint": lambda path: [("lock", lock_path(path)),
                                                             ("frames so far", partial_path(path))],
                               "--finished": lambda path: [("frames", partial_path(path))]}),
    "relax": PathRoles(inputs=("--params", "--input"), outputs=("--out",),
                       read={"--params": at_file}, derived={"--out": _state_outputs}),
    "probe": PathRoles(inputs=("--params", "--input"), outputs=("--out",),
                       read={"--params": at_file}, derived={"--out": _state_outputs}),
    "warmup": PathRoles(),
    "bench": PathRoles(inputs=("--state", "--scenes"), outputs=("--cache",)),
    "summary": PathRoles(inputs=("states",)),
}


_REST = re.compile(r":[a-z]+:`~?([^`]+)`|``([^`]+)``")


def plain(text):
    """`text` without its reST markup, for ``--help``.

    Parameters
    ----------
    text : str
        A docstring: ``code`` and roles such as :func:`name` (``~`` too).

    Returns
    -------
    str
        The same text with each of those replaced by the words inside.
    """
    return _REST.sub(lambda m: m.group(1) or m.group(2), text)


def version():
    """The line of ``--version``: the package's version and :func:`sim.io.code_version`."""
    return (f"polypile sim {__version__}, code_version {code_version()} (the digest of "
            "sim/*.py that every state file records)")


def _parser():
    ap = argparse.ArgumentParser(prog="python -m sim", description=plain(__doc__),
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--version", action="version", version=version())
    sub = ap.add_subparsers(dest="command", required=True)
    params_help = ("run parameters: JSON or YAML text, or @FILE (JSON or YAML config); "
                   "given again, merged over the earlier ones (later wins)")
    bookkeeping_help = ("settings that change no result (checkpoint, progress and "
                        "frame intervals) as JSON, e.g. '{\"pour\": {\"progress_interval\": 5}}'; "
                        "--params takes them too, this keeps them apart from the settings that "
                        "decide the result (the workflow re-runs a job when those change)")

    p = sub.add_parser("pour", help="pour a pile (wedge: point source, layered: line source)")
    p.add_argument("--params", action="append", help=params_help)
    p.add_argument("--bookkeeping", help=bookkeeping_help)
    p.add_argument("--protocol", required=True, choices=["wedge", "layered"])
    p.add_argument("--seed", required=True, type=int)
    p.add_argument("--out", required=True, help="state file of the poured pile (.nc)")
    p.add_argument("--checkpoint", help="checkpoint file to resume from and write to")
    p.add_argument("--frames", nargs="?", const=None, metavar="FILE",
                   help="also write frames of the pour for a film, every "
                   "pour.frame_interval simulated seconds, to FILE (.nc; python -m analysis "
                   "film); without FILE, or empty, no frames. The interval's default, 0.5 s, "
                   "gives 3 frames of a 1 s pour (a pour lasts about pour.n_particles / "
                   "pour.rate s): for a film set it to about a thirtieth of that, e.g. "
                   "--bookkeeping '{\"pour\": {\"frame_interval\": 0.05}}'")
    p.add_argument("--log", metavar="FILE",
                   help="also append the log to FILE, the pile's log over all runs of its pour, "
                   "once this run holds the pour's lock (a run the lock refuses leaves it as it is)")
    p.add_argument("--finished", metavar="FILE",
                   help="also keep a copy of the finished pour in FILE (its frames beside it), "
                   "where a workflow that deletes the outputs of a run it counts as incomplete "
                   "leaves it; a rerun that finds one made for this pile by this code under "
                   "these settings takes it instead of pouring again, and removes one made "
                   "otherwise")

    p = sub.add_parser("relax", help="relax a pile to rest")
    p.add_argument("--params", action="append", help=params_help)
    p.add_argument("--bookkeeping", help=bookkeeping_help)
    p.add_argument("--input", required=True)
    p.add_argument("--out", required=True)

    p = sub.add_parser("probe", help="change gravity (lower, tilt or restore it), or stretch the "
                                     "support, and relax again")
    p.add_argument("--params", action="append", help=params_help)
    p.add_argument("--bookkeeping", help=bookkeeping_help)
    p.add_argument("--input", required=True, help="relaxed state file (reduced for --restore)")
    change = p.add_mutually_exclusive_group(required=True)
    change.add_argument("--level", type=float, help="relative gravity reduction Delta, in (0, 1)")
    change.add_argument("--tilt", type=float,
                        help="horizontal component of gravity added, delta |g|, in (-0.5, 0.5)")
    change.add_argument("--restore", action="store_true",
                        help="restore full gravity g0 (from a reduced state)")
    change.add_argument("--stretch", type=float,
                        help="stretch the support instead: its surface point at x moves by "
                             "STRETCH * x, in (-0.01, 0.01), over probe.stretch_time")
    p.add_argument("--out", required=True)
    p.add_argument("--stage", default=None,
                   help="stage name stored in the file (default: from the output name)")

    sub.add_parser("warmup", help="compile and cache all Numba kernels")

    p = sub.add_parser("bench", help="ns per particle-step in settled, loaded piles")
    p.add_argument("--sizes", default="3000,10000",
                   help="comma-separated particle counts of the loaded piles")
    p.add_argument("--steps", type=int, default=200, help="steps per timing")
    p.add_argument("--repeats", type=int, default=5, help="timings per figure (median)")
    p.add_argument("--integrators", default="verlet,gear", help="comma-separated")
    p.add_argument("--threads", default="1,2", help="comma-separated thread counts")
    p.add_argument("--cache", default=".bench", help="folder of the built piles")
    p.add_argument("--state", help="time this state file instead of the built piles")
    p.add_argument("--peer", choices=["lammps", "lammps-polygons"], action="append",
                   help="also time, in this run, a LAMMPS disk pile of each N (lammps) or "
                        "LAMMPS's rounded polygons of each pile (lammps-polygons), and print "
                        "the ratios; repeatable (needs LAMMPS: make bench-peers)")
    p.add_argument("--scenes", metavar="STATE",
                   help="instead: time the pile of this state file under each scene "
                        "variant (friction 0, damping 0, no rotation, no support)")

    p = sub.add_parser("summary", help="one JSON line per state file: particles, height, "
                       "width, flank angles, coordination, support reaction against weight")
    p.add_argument("states", nargs="+", help="state files (.nc)")

    sub.add_parser("numerics", help="numerical checks: " + " | ".join(NUMERICS) +
                   "; see python -m sim numerics WHAT --help", add_help=False)
    return ap


# python -m sim numerics WHAT ...: the checks by name (each a module of sim.numerics with
# main(argv)), with what each does in the words of python -m sim numerics --help
NUMERICS = {"collisions": "error against run time of binary collisions, over the time step",
            "stability": "stiff and extreme scenes, and the largest stable time step",
            "kernel-profile": "where a kernel's time goes, per instruction (needs perf)"}


def _numerics(argv):
    """Run ``python -m sim numerics WHAT [options]``; returns the exit status.

    ``--help`` (or ``-h``) alone prints the checks on stdout and returns 0;
    no check, or an unknown one, prints the usage on stderr and returns 2.
    """
    usage = f"usage: python -m sim numerics {{{','.join(NUMERICS)}}} [--help]"
    if argv[:1] in (["--help"], ["-h"]):
        print(usage + "\n\nnumerical checks (python -m sim numerics WHAT --help for one's "
              "options):\n" + "".join(f"  {k:<16}{v}\n" for k, v in NUMERICS.items()), end="")
        return 0
    if not argv or argv[0] not in NUMERICS:
        print(usage, file=sys.stderr)
        return 2
    logging.basicConfig(level=logging.INFO, stream=sys.stderr,
                        format="%(asctime)s %(levelname)s %(message)s")
    # imported here: the checks load what a pour never needs
    from .numerics import collisions, kernel_profile, stability
    main = {"collisions": collisions.main, "stability": stability.main,
            "kernel-profile": kernel_profile.main}[argv[0]]
    try:
        return main(argv[1:])
    except (ConfigError, ValueError) as exc:
        logging.getLogger("sim").error("%s", exc)
        return 2


def _announce_compile(log):
    """Say so in the log when the kernels have no compiled copy yet: their first
    run compiles them, about a minute without a progress line."""
    import numba

    if not any(Path(numba.config.CACHE_DIR).rglob("*.nbi")):
        log.info("compiling the simulator's kernels into %s first (no compiled copy of this code yet: "
                 "about a minute, once per version of the kernels' sources; python -m sim warmup "
                 "compiles them ahead)", numba.config.CACHE_DIR)


def main(argv=None):
    """Run the command line; returns the exit status."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["numerics"]:
        return _numerics(argv[1:])
    args = _parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO, stream=sys.stderr,
                        format="%(asctime)s %(levelname)s %(message)s")
    log = logging.getLogger("sim")
    try:
        check_distinct_paths(args, PATHS[args.command])
        if args.command == "pour":
            _seed(args.seed)
        if args.command == "warmup":
            from .warmup import warmup
            warmup()
            return 0
        if args.command == "bench":
            from .numerics.bench import main as bench_main, main_scenes
            if args.scenes:
                main_scenes(args.scenes, args.steps, args.repeats)
            else:
                bench_main(_int_list("--sizes", args.sizes), args.steps, args.repeats,
                           tuple(args.integrators.split(",")),
                           _threads(args.threads), Path(args.cache),
                           args.state, args.peer)
            return 0
        if args.command == "summary":
            from .io import load_simulation
            from .measure import pile_summary
            for path in args.states:
                sim, ds = load_simulation(path)
                n = sim.n
                row = pile_summary(sim.position, sim.shapes.radius[:n], sim.shapes.mass[:n],
                                   sim.gravity[1], ds["contact_i"].values,
                                   ds["contact_j"].values, ds["force_y"].values)
                print(json.dumps({"state": str(path), "stage": ds.attrs.get("stage", ""),
                                  "code_version": ds.attrs.get("code_version", ""), **row}),
                      flush=True)
            return 0
        cfg = _params(args.params, args.bookkeeping,
                      args.input if args.command in ("relax", "probe") else None)
        from . import pour, probe, relax
        from .run_loop import stop_on_signals
        _announce_compile(log)
        # from here on, not only from the run loop: a signal while the shapes
        # are drawn or the kernels compile ends the run at its first chunk, in one line
        with stop_on_signals():
            if args.command == "pour":
                pour.pour(cfg, args.protocol, args.seed, args.out, args.checkpoint,
                          frames=args.frames, run_log=args.log, finished=args.finished)
            elif args.command == "relax":
                relax.relax_file(cfg, args.input, args.out)
            elif args.command == "probe":
                stage = args.stage or Path(args.out).stem
                if args.stretch is not None:
                    probe.stretch_file(cfg, args.input, args.stretch, args.out, stage)
                elif args.tilt is not None:
                    probe.tilt_file(cfg, args.input, args.tilt, args.out, stage)
                elif args.restore:
                    probe.restore_file(cfg, args.input, args.out, stage)
                else:
                    probe.probe_file(cfg, args.input, args.level, args.out, stage)
        return 0
    except (ConfigError, ValueError, FileNotFoundError) as exc:
        log.error("%s", exc)
        return 2
    except OutputError as exc:
        log.error("%s", exc)
        return 3
    except RuntimeError as exc:
        log.error("%s", exc)
        return 1
    except KeyboardInterrupt as exc:   # the run logged what it saved (sim.run_loop.Interrupted)
        return getattr(exc, "status", 130)
