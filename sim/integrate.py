"""The integrator as jax-md's pair of functions over the state: ``init, step = integrator(scene)``.

``init(state, k, position, velocity)`` starts particle ``k`` in the scaled
derivatives of the scene's integrator (:mod:`sim.integrators`);
``step(state, n_steps, arrays, motion, parallel)`` advances the state by up
to ``n_steps`` steps with the force kernels of :mod:`sim.step` under the
scene's contact law (``scene.law``, built once with the scene) and returns
the steps done.  Both read the scene's time step when called, so a scene
built for a time-step study may set its own step first.
"""

from __future__ import annotations

import numpy as np

from .integrators import scale_derivatives, unscale_derivatives
from .rebuild import rebuild_distance_sq
from .step import ADVANCE_PARALLEL, ADVANCE_SERIAL


def integrator(scene):
    """``init, step``: the integrator of `scene` (``scene.model.integrator``).

    Parameters
    ----------
    scene : sim.scene.Scene

    Returns
    -------
    init : callable
        ``init(state, k, position, velocity)`` with ``position`` (x, y, θ) and
        ``velocity`` (vx, vy, ω): particle ``k``'s values, its acceleration
        that of gravity (so free fall is exact from the first step), higher
        derivatives zero.
    step : callable
        ``step(state, n_steps, arrays, motion, parallel) -> int``: run up to
        ``n_steps`` steps of ``state.n`` particles on the kernels' tuples of
        arrays ``arrays`` (:meth:`sim.engine.Simulation.kernel_state`) under
        the run's :class:`sim.step.Motion` ``motion``, with their parallel
        builds or not; count them in ``state.step``; stop early, marking the
        state ``moved``, once a particle moved past the rebuild distance of
        the scene's skin from its reference centre (:mod:`sim.rebuild`).
    """
    law = scene.law

    def init(state, k, position, velocity):
        dt = scene.dt
        state.r[:, :, k] = 0.0
        state.r[0, :, k] = position
        state.r[1, :, k] = (velocity[0] * dt, velocity[1] * dt, velocity[2] * dt)
        state.r[2, :2, k] = 0.5 * dt ** 2 * np.asarray(state.gravity)

    def step(state, n_steps, arrays, motion, parallel):
        advance = ADVANCE_PARALLEL if parallel else ADVANCE_SERIAL
        done, moved = advance(n_steps, state.n, *arrays, law, motion, state.work, state.x_ref,
                              state.y_ref, rebuild_distance_sq(scene.skin))
        state.step += done
        state.moved = state.moved or moved
        return done

    return init, step


def load_derivatives(state, scene, r, dt):
    """Set the scaled derivatives of `state` from ``r``, saved with time step ``dt``.

    With the scene's ``dt`` they are taken bit for bit, so a restart retraces
    the run; otherwise they are rescaled to the scene's step.  The values
    beyond those of the scene's integrator are dropped, missing ones are 0.

    Raises
    ------
    ValueError
        If ``r`` holds more particles than the scene's capacity.
    """
    n = r.shape[2]
    if n > scene.capacity:
        raise ValueError(f"{n} particles exceed the capacity {scene.capacity}")
    keep = min(r.shape[0], len(scene.coeffs))
    state.r[:] = 0.0
    if dt == scene.dt:
        state.r[:keep, :, :n] = r[:keep]
    else:
        state.r[:keep, :, :n] = scale_derivatives(unscale_derivatives(r, dt), scene.dt)[:keep]
    state.n = n
    state.stale = True
