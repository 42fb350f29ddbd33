"""The run loop: steps in chunks between pair-list rebuilds and blow-up checks."""

from __future__ import annotations

from .blowup import BlowUpError
from .rebuild import rebuild_distance_sq


def run(sim, steps, step, rebuild):
    """Advance `sim` by ``steps`` steps of ``step``, checking it every ``sim.check_every``.

    A chunk of steps ends at the next check or when the pair list needs a
    rebuild (:mod:`sim.rebuild`).  A scene's first step is checked at once,
    with :meth:`sim.engine.Simulation.check`'s ``start``.  On a failed check
    the simulation returns to the last state that passed.

    Parameters
    ----------
    sim : sim.engine.Simulation
    steps : int
    step : callable
        The integrator's step (:func:`sim.integrate.integrator`).
    rebuild : callable
        ``rebuild()`` rebuilds the pair list of ``sim.state``.

    Returns
    -------
    int
        Steps done.

    Raises
    ------
    BlowUpError
        On a failed check, carrying the last good snapshot.
    """
    if sim.n == 0:
        sim.time += steps * sim.dt
        sim.step += steps
        return steps
    done = 0
    # time from the steps done in this call, not summed chunk by chunk: the
    # chunks end at pair-list rebuilds, which a resumed run has elsewhere
    start_time = sim.time
    last_good = sim.snapshot()
    rebuild_sq = rebuild_distance_sq(sim.skin)
    while done < steps:
        if sim.state.stale or sim.state.moved:
            rebuild()
        chunk = min(steps - done, sim.check_every - sim.step % sim.check_every)
        if sim.step == 0:
            # a scene's first step is checked at once: the particle overlaps it
            # starts with (coincident centres, one polygon inside another) are
            # seen before their forces have thrown the particles apart (a start
            # inside the support or a wall is resolved: it pushes them out)
            chunk = 1
        parallel = sim.parallel_kernels()
        done += step(sim.state, chunk, sim.kernel_state(), parallel, rebuild_sq)
        sim.time = start_time + done * sim.dt
        if sim.step % sim.check_every == 0 or done == steps or sim.step == 1:
            problem = sim.check(start=sim.step == 1)
            if problem:
                failed_at = (sim.time, sim.step)
                sim.restore(last_good)
                raise BlowUpError(
                    f"unstable at t = {failed_at[0]:.6g} s (step {failed_at[1]}): {problem}; "
                    f"dt = {sim.dt:.4g} s ({sim.model.integrator}, limit "
                    f"{sim.bound.dt_limit:.4g} s). The last good state is kept "
                    f"(t = {last_good.time:.6g} s).", last_good)
            last_good = sim.snapshot()
    return done
