"""The run loop: steps in chunks between pair-list rebuilds and blow-up checks,
and a run's stop on SIGTERM or SIGINT (:func:`stop_on_signals`).

Between two chunks the loop calls the simulation's ``heartbeat`` (a run's
progress lines, :class:`sim.progress.Progress`) and ends the run with
:class:`Interrupted` once a signal came: a chunk is at most
``check_every`` steps (1 ms of simulated time), so neither waits for the end
of a long ``run``.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading

from .blowup import BlowUpError, check
from .state import Snapshot, restore

#: The signals that end a run cleanly (:func:`stop_on_signals`).
SIGNALS = (signal.SIGINT, signal.SIGTERM)

#: The signals received while :func:`stop_on_signals` holds, first first.
_received = []


class Interrupted(KeyboardInterrupt):
    """A run ended by a signal between two chunks of steps.

    A KeyboardInterrupt (for SIGTERM too), so that no handler of errors
    takes it for a failure of the run, and the command line ends with its
    :attr:`status` as with Ctrl-C.

    Attributes
    ----------
    name : str
        The signal, e.g. ``"SIGTERM"``.
    status : int
        The conventional exit status, 128 + the signal's number (130 for
        SIGINT, 143 for SIGTERM).
    """

    def __init__(self, signum):
        self.name = signal.Signals(signum).name
        self.status = 128 + int(signum)
        super().__init__(f"stopped by {self.name}")


def _handler(signum, frame):
    """Note the signal for the loop; a second one ends the process at once,
    as it would without this handler."""
    if _received:
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)
    _received.append(signum)


@contextlib.contextmanager
def stop_on_signals():
    """While in the block, SIGTERM and SIGINT end the run at the loop's next
    chunk with :class:`Interrupted` (:func:`stop_if_signalled`) instead of
    killing the process where it stands; the handlers before are restored
    after.  Nothing changes outside the main thread (where Python runs no
    signal handler) or inside another such block."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGTERM) is _handler):
        yield
        return
    before = {s: signal.signal(s, _handler) for s in SIGNALS}
    try:
        yield
    finally:
        for s, handler in before.items():
            signal.signal(s, handler)
        _received.clear()


def stop_if_signalled():
    """Raise :class:`Interrupted` if a signal came within :func:`stop_on_signals`."""
    if _received:
        raise Interrupted(_received[0])


def run(state, scene, steps, advance, rebuild, energy, check_every, heartbeat=None):
    """Advance `state` by ``steps`` steps, checking it every ``check_every``.

    A chunk of steps ends at the next check or when the pair list needs a
    rebuild (:mod:`sim.rebuild`).  A scene's first step is checked at once,
    with :func:`sim.blowup.check`'s ``start``.  On a failed check the state
    returns to the last one that passed and the energy check restarts.
    After each chunk ``heartbeat()`` is called (unless None); before each, a
    signal caught by :func:`stop_on_signals` ends the run.

    Parameters
    ----------
    state : sim.state.State
    scene : sim.scene.Scene
    steps : int
    advance : callable
        ``advance(n_steps) -> int``: the integrator's step
        (:func:`sim.integrate.integrator`) on `state`, up to ``n_steps`` steps.
    rebuild : callable
        ``rebuild()`` rebuilds the pair list of `state`.
    energy : sim.blowup.EnergyReference
        The energy check's reference.
    check_every : int
        Steps between blow-up checks.
    heartbeat : callable or None
        ``heartbeat()``, called after each chunk.

    Returns
    -------
    int
        Steps done.

    Raises
    ------
    BlowUpError
        On a failed check, carrying the last good snapshot.
    Interrupted
        On a signal (:func:`stop_on_signals`), with the state after the last chunk.
    """
    if state.n == 0:
        state.time += steps * scene.dt
        state.step += steps
        return steps
    done = 0
    # time from the steps done in this call, not summed chunk by chunk: the
    # chunks end at pair-list rebuilds, which a resumed run has elsewhere
    start_time = state.time
    last_good = Snapshot(state)
    while done < steps:
        if state.stale or state.moved:
            rebuild()
        chunk = min(steps - done, check_every - state.step % check_every)
        if state.step == 0:
            # a scene's first step is checked at once: the particle overlaps it
            # starts with (coincident centres, one polygon inside another) are
            # seen before their forces have thrown the particles apart (a start
            # inside the support or a wall is resolved: it pushes them out)
            chunk = 1
        stop_if_signalled()
        done += advance(chunk)
        state.time = start_time + done * scene.dt
        if heartbeat is not None:
            heartbeat()
        if state.step % check_every == 0 or done == steps or state.step == 1:
            problem = check(state, scene, energy, start=state.step == 1)
            if problem:
                failed_at = (state.time, state.step)
                restore(state, last_good)
                energy.reset()
                raise BlowUpError(
                    f"unstable at t = {failed_at[0]:.6g} s (step {failed_at[1]}): {problem}; "
                    f"dt = {scene.dt:.4g} s ({scene.model.integrator}, limit "
                    f"{scene.bound.dt_limit:.4g} s). The last good state is kept "
                    f"(t = {last_good.time:.6g} s).", last_good)
            last_good = Snapshot(state)
    return done
