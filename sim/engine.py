"""The simulation object: a facade over the state, the scene and the functions that run them.

The pieces, each a module: the state as a plain structure of arrays
(:mod:`sim.state`) and the fixed scene (:mod:`sim.scene`); the integrator as
an ``init, step`` pair over the state (:mod:`sim.integrate`) on the force
kernels (:mod:`sim.step`); the run loop (:mod:`sim.run_loop`), the
pair-list rebuild policy (:mod:`sim.rebuild`), the blow-up detector
(:mod:`sim.blowup`), the energies (:mod:`sim.energy`) and the contacts
(:mod:`sim.contacts`).  :class:`Simulation` ties them together for callers
(the protocols, the state files, the numerical checks, the tests).

The step does only the work the run needs (see :mod:`sim.step`): no damping
force when ``model.damping`` is 0, no tangential force or spring history
between particles when ``model.friction`` is 0 (nor with the bodies when
``model.support_friction`` is 0), no body contacts without bodies, and no
orientation update when rotation is fixed.  ``Simulation(..., full_law=True)``
computes every term anyway (tests compare both).
"""

from __future__ import annotations

import dataclasses
import functools

import numba
import numpy as np

from . import blowup, contacts, energy, state as states
from .config import ModelParams
from .integrate import integrator, load_derivatives
from .rebuild import rebuild
from .run_loop import run
from .scene import Scene, make_scene
from .state import Snapshot, State
from .step import Bodies, Motion, Pairs, Particles


class _Field:
    """An attribute of :class:`Simulation` kept in its ``state`` or ``scene`` (read and set)."""

    def __init__(self, where, field):
        self.where, self.field = where, field

    def __get__(self, sim, owner=None):
        return self if sim is None else getattr(getattr(sim, self.where), self.field)

    def __set__(self, sim, value):
        setattr(getattr(sim, self.where), self.field, value)


def _with_fields(cls):
    """Give `cls` every field of :class:`State` and :class:`Scene` as an attribute."""
    for where, structure in (("state", State), ("scene", Scene)):
        for field in dataclasses.fields(structure):
            if hasattr(cls, field.name):
                raise TypeError(f"{cls.__name__}.{field.name} would hide the field of {structure.__name__}")
            setattr(cls, field.name, _Field(where, field.name))
    return cls


@_with_fields
class Simulation:
    """A 2D DEM of soft convex polygons (paper, Section 2 and Appendix).

    Every field of its :class:`sim.state.State` (``n``, ``r``, ``time``,
    ``step``, ``gravity``, ``pi``, ``spring``, ``bspring``, ...) and of its
    :class:`sim.scene.Scene` (``shapes``, ``model``, ``dt``, ``bound``,
    ``walls``, ``body_ids``, ...) is also an attribute of the simulation.

    Parameters
    ----------
    shapes : sim.shapes.Shapes
        All particles that may take part (the capacity).
    model : sim.config.ModelParams
        Contact law, density, integrator and time-step settings.
    gravity : tuple of float
        Gravity vector (g_x, g_y) in m/s²; may be changed at run time.
    support : bool
        Whether the frictional support ``y < 0`` exists.
    walls : tuple of float or None
        ``(x_left, x_right)`` positions of frictional side walls, or None.
    base : sim.scene.RoughBase or None
        Fixed polygons on the support (``physics.rough_base``), or None.
    rotate : bool
        Integrate rotations (False fixes every particle's orientation: its
        angular velocity is zero and θ never changes).
    skin : float or None
        Verlet skin of the pair list, m (default: 0.3 × mean circumradius).
    full_law : bool
        Compute every term of the contact law, also those that are zero
        (``scene.law``, fixed for the simulation's life).

    Attributes
    ----------
    state : sim.state.State
    scene : sim.scene.Scene
    drag : float
        Background drag, 1/s, on translation and rotation (``−drag·m·v``,
        ``−drag·I·ω``); set while relaxing (``relax.drag``), 0 otherwise.
    spin_drag : float
        Further drag on the rotation alone, 1/s; ``pour.spin_drag`` while
        pouring, 0 otherwise.
    heartbeat : callable or None
        ``heartbeat(sim)``, called between the chunks of steps of a run
        (:func:`sim.run_loop.run`): a run's progress lines; None: nothing.
    check_every : int
        Steps between blow-up checks (1 ms of simulated time, at least 50).
    parallel_threshold : int
        Particles from which the kernels run their parallel builds.
    threads : int
        Numba's thread count when the simulation was made (asked once:
        every ``numba.get_num_threads()`` takes a lock shared between
        processes, which a forked worker killed while holding it would leave
        held for the others).  A caller that changes it with
        ``numba.set_num_threads`` makes its simulations afterwards.
    """

    _stale = _Field("state", "stale")

    def __init__(self, shapes, model: ModelParams, gravity=(0.0, -9.81), support=True,
                 walls=None, rotate=True, skin=None, base=None, full_law=False):
        self.scene = make_scene(shapes, model, support, walls, rotate, skin, base, full_law)
        self.state = states.new_state(self.scene, gravity)
        self._base = _base_arrays(base, int(shapes.node_offset[-1]))
        self._init, self._step = integrator(self.scene)
        self.check_every = max(50, int(round(1e-3 / self.dt)))
        self.parallel_threshold = 400
        # also starts Numba's threading layer, which the serial builds need too
        # (their numba.get_thread_id does not link before it: "LLVM ERROR:
        # Symbol not found")
        self.threads = numba.get_num_threads()
        self.drag = 0.0
        self.spin_drag = 0.0
        self.heartbeat = None
        self._energy = blowup.EnergyReference()

    # ------------------------------------------------------------------ state
    def place(self, k, x, y, theta=0.0, vx=0.0, vy=0.0, omega=0.0):
        """Set particle ``k``'s position and velocity; ``k == n`` activates one more.

        The acceleration starts at gravity, higher derivatives at zero.  The
        particle starts afresh: its contact history, the tangential springs and
        narrow-phase witnesses of its pairs with other particles and with the
        support and walls, is cleared, as for contacts that were never made.
        Any change of the particle set forces a pair-list rebuild and restarts
        the energy check.
        """
        if not 0 <= k <= self.n or k >= self.capacity:
            raise IndexError(f"particle {k}: only 0..{min(self.n, self.capacity - 1)} "
                             "can be placed")
        self._init(self.state, k, (x, y, theta), (vx, vy, omega))
        states.forget_particle(self.state, k)
        if k == self.n:
            self.n += 1
        self.state.stale = True
        self._energy.reset()

    def set_gravity(self, gx, gy):
        """Change the gravity vector (m/s²); restarts the energy check."""
        self.gravity = (float(gx), float(gy))
        self._energy.reset()

    def scaled_derivatives(self):
        """The integrator's values ``dt^k/k! d^k q/dt^k``, shape (n_values, 3, n)."""
        return self.r[:, :, :self.n].copy()

    def set_scaled_derivatives(self, r, dt):
        """Set the integrator's values, saved with time step ``dt``
        (:func:`sim.integrate.load_derivatives`); restarts the energy check."""
        load_derivatives(self.state, self.scene, r, dt)
        self._energy.reset()

    @property
    def position(self):
        """Centres (n, 2), m."""
        return self.r[0, :2, :self.n].T.copy()

    @property
    def velocity(self):
        """Velocities (n, 2), m/s."""
        return self.r[1, :2, :self.n].T / self.dt

    @property
    def theta(self):
        """Orientations (n,), rad."""
        return self.r[0, 2, :self.n].copy()

    @property
    def omega(self):
        """Angular velocities (n,), rad/s."""
        return self.r[1, 2, :self.n] / self.dt

    def kinetic_energy(self):
        """Translational plus rotational kinetic energy (:func:`sim.energy.kinetic_energy`), J/m."""
        return energy.kinetic_energy(self.state, self.scene)

    def potential_energy(self):
        """Gravitational energy (:func:`sim.energy.potential_energy`), J/m."""
        return energy.potential_energy(self.state, self.scene)

    def elastic_energy(self):
        """Stored contact energy (:func:`sim.energy.elastic_energy`), J/m."""
        return energy.elastic_energy(self.state, self.scene)

    # ------------------------------------------------------------------ running
    def parallel_kernels(self):
        """Whether the kernels run their parallel builds: with at least
        ``parallel_threshold`` particles and more than one thread."""
        return self.threads > 1 and self.n >= self.parallel_threshold

    def _rebuild(self):
        rebuild(self.state, self.scene, self.law.tangential, self.parallel_kernels())

    def kernel_state(self):
        """The arrays as the kernels take them: :class:`sim.step.Particles`,
        :class:`sim.step.Pairs` and :class:`sim.step.Bodies`, wrapped anew
        for each chunk of steps (a rebuild replaces the pairs' arrays, a
        return to a snapshot those of the particles and the bodies)."""
        sh, st = self.shapes, self.state
        return (Particles(st.r, st.pred, sh.node_offset, sh.node_x, sh.node_y, st.wx,
                          st.wy, st.box, sh.mass, self.inv_mass,
                          self.inv_inertia, sh.area),
                Pairs(st.pi, st.pj, st.spring, st.pdamping, st.axis, st.cross, st.pout,
                      st.pforce, st.pair_offset, st.pair_index),
                Bodies(self.body_p, self.body_m, self.body_friction, st.bspring, st.bout,
                       *self._base, st.base_owner, st.base_axis, st.base_cross))

    def motion(self):
        """The :class:`sim.step.Motion` of a run: time step, gravity and drags
        as they are set when it starts."""
        return Motion(self.dt, self.coeffs, self.gravity[0], self.gravity[1],
                      float(self.drag), float(self.drag + self.spin_drag), self.rotate)

    def snapshot(self) -> Snapshot:
        """A copy of the dynamic state, enough to continue the run exactly."""
        return states.Snapshot(self.state)

    def restore(self, snap: Snapshot):
        """Return to a :class:`sim.state.Snapshot`; restarts the energy check."""
        states.restore(self.state, snap)
        self._energy.reset()

    def run(self, duration=None, steps=None):
        """Advance by a simulated ``duration`` (s) or a number of ``steps``
        (:func:`sim.run_loop.run`).

        Every ``check_every`` steps the state is checked (:meth:`check`); on a
        failure the simulation returns to the last state that passed and
        :class:`sim.blowup.BlowUpError` is raised (carrying that snapshot too).

        Returns
        -------
        int
            Steps done.
        """
        if steps is None:
            if duration is None:
                raise ValueError("give a duration or a number of steps")
            steps = int(round(duration / self.dt))
        heartbeat = None if self.heartbeat is None else functools.partial(self.heartbeat, self)
        return run(self.state, self.scene, steps,
                   functools.partial(self._advance, self.motion(), self.parallel_kernels()),
                   self._rebuild, self._energy, self.check_every, heartbeat)

    def _advance(self, motion, parallel, n_steps):
        """The integrator's step over up to ``n_steps`` steps on the current
        arrays (:meth:`kernel_state`): :func:`sim.run_loop.run`'s ``advance``."""
        return self._step(self.state, n_steps, self.kernel_state(), motion, parallel)

    def check(self, start=False):
        """Blow-up detector (:func:`sim.blowup.check`): a description of the
        first problem found, or ``None``."""
        return blowup.check(self.state, self.scene, self._energy, start)

    # ------------------------------------------------------------------ contacts
    def contacts(self):
        """The active contacts of the last force evaluation (:func:`sim.contacts.contacts`)."""
        return contacts.contacts(self.state, self.scene)

    def touching(self):
        """Mask of the active particles touching a particle or a body (:func:`sim.contacts.touching`)."""
        return contacts.touching(self.state, self.scene)

    def set_springs(self, ci, cj, spring, witness=None):
        """Rebuild the pair list and load the history of contacts ``(ci, cj)``
        (:func:`sim.contacts.load_history`)."""
        self._rebuild()
        contacts.load_history(self.state, self.scene, ci, cj, spring, witness)

    def stretch_body(self, body_id, strain):
        """Stretch the surface of a half-plane body by ``strain`` along itself
        (:func:`sim.contacts.stretch_body`); returns the contacts whose spring moved.

        Raises
        ------
        ValueError
            If the scene has no such body, or its contacts carry no
            tangential springs (``model.support_friction`` = 0).
        """
        if body_id not in self.body_ids:
            raise ValueError(f"body {body_id}: not a body of this scene (bodies {list(self.body_ids)})")
        if not self.law.body_tangential:
            raise ValueError("a body's surface can only drag the particles through friction: "
                             f"model.support_friction = {self.model.support_friction}; give it > 0")
        return contacts.stretch_body(self.state, self.scene, body_id, strain)

    def net_forces(self):
        """Net force (n, 2) on each active particle from the last evaluation plus gravity."""
        return contacts.net_forces(self.state, self.scene)


def _base_arrays(base, corners):
    """The rough base's fixed fields of :class:`sim.step.Bodies` (empty arrays
    without a base): the offsets of its polygons' world corners in the
    state's ``wx``, ``wy``, after the particles' `corners`
    (:func:`sim.state.new_state`), their boxes, centres, areas and the top."""
    if base is None:
        return (np.zeros(1, np.int64), np.empty((0, 4)), np.empty((0, 2)), np.empty(0), 0.0)
    return (base.shapes.node_offset + corners, base.box,
            np.ascontiguousarray(np.column_stack([base.x, base.y])), base.shapes.area,
            float(base.top))
