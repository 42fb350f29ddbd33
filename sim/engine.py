"""The simulation object: state, bodies, the run loop and blow-up detection.

State is a structure of flat arrays sized for a fixed *capacity* of particles,
of which the first ``n`` are active (pouring activates them one by one, so
nothing is reallocated while a pile grows):

* ``r``: scaled derivatives of (x, y, θ), shape ``(n_values, 3, capacity)``
  (see :mod:`sim.integrators`);
* shapes: CSR body-frame corners and mass properties (:class:`sim.shapes.Shapes`);
* the candidate pair list ``pi, pj`` with one tangential spring per pair
  (:mod:`sim.broadphase`), and one spring per particle and fixed body.

Fixed bodies are half-planes: the support ``y < 0`` and, optionally, side walls
``x < x_left`` and ``x > x_right``.  In state files a contact with a body has
``contact_j = -1`` (support), ``-2`` (left wall) or ``-3`` (right wall).

The step does only the work the run needs (see :mod:`sim.forces`): no damping
force when ``model.damping`` is 0, no tangential force or spring history
between particles when ``model.friction`` is 0 (nor with the bodies when
``model.support_friction`` is 0), no body contacts without bodies, and no
orientation update when rotation is fixed.  ``Simulation.full_law = True``
computes every term anyway (tests compare both).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numba
import numpy as np

from .broadphase import candidate_pairs, carry_history, particle_pair_index
from .config import ModelParams
from .contact_law import tangential_stiffness
from .forces import (BLOCK, KERNELS_PARALLEL, KERNELS_SERIAL, PRED_SIZE, ROW,
                     ROW_SIZE, Bodies, Law, Motion, Pairs, Particles, Workspace, advance)
from .geometry import make_scratch
from .integrators import corrector_coefficients, scale_derivatives, unscale_derivatives
from .timestep import choose_dt, stability_bound

log = logging.getLogger(__name__)

BODY_SUPPORT, BODY_LEFT, BODY_RIGHT = -1, -2, -3

#: Length of each thread's narrow-phase output row (it needs GEOMETRY_SIZE):
#: 512 bytes, so that no two threads write into one cache line (with rows of
#: 10 values they did, at every contact).
THREAD_ROW = 64

#: How much :meth:`Simulation.elastic_energy` can underestimate the stored
#: energy, as a fraction of itself.  For an overlap of area ``A ∝ d^p`` at
#: depth d (contact line ``L = dA/dd``) the work of ``F⊥ = Y A / l`` is
#: ``∫F⊥ dd = p/(p+1) · F⊥ A / L``; the estimate ``F⊥ A / (2L)`` is exact for
#: an edge (p = 1) and 3/4 of it for a corner (p = 2), i.e. low by 1/3.
ELASTIC_UNDERESTIMATE = 1.0 / 3.0


class BlowUpError(RuntimeError):
    """The run became unstable; ``last_good`` holds the last state that passed the checks."""

    def __init__(self, message, last_good=None):
        super().__init__(message)
        self.last_good = last_good


@dataclass
class Snapshot:
    """A copy of everything needed to continue a run (see :meth:`Simulation.snapshot`),
    and of the contact rows of its last force evaluation (``pout``, ``bout``),
    so that a restored state reports its own contacts."""

    n: int
    r: np.ndarray
    time: float
    step: int
    gravity: tuple
    pi: np.ndarray
    pj: np.ndarray
    spring: np.ndarray
    bspring: np.ndarray
    pout: np.ndarray
    bout: np.ndarray
    axis: np.ndarray
    cross: np.ndarray


class Simulation:
    """A 2D DEM of soft convex polygons (paper, Section 2 and Appendix).

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
    rotate : bool
        Integrate rotations (False fixes every particle's orientation: its
        angular velocity is zero and θ never changes).
    skin : float or None
        Verlet skin of the pair list, m (default: 0.3 × mean circumradius).

    Attributes
    ----------
    drag : float
        Background drag, 1/s, on translation and rotation (``−drag·m·v``,
        ``−drag·I·ω``); set while relaxing (``relax.drag``), 0 otherwise.
    spin_drag : float
        Further drag on the rotation alone, 1/s; ``pour.spin_drag`` while
        pouring, 0 otherwise.
    """

    def __init__(self, shapes, model: ModelParams, gravity=(0.0, -9.81), support=True,
                 walls=None, rotate=True, skin=None):
        self.shapes = shapes
        self.model = model
        self.capacity = len(shapes.mass)
        self.n = 0
        self.coeffs = corrector_coefficients(model.integrator)
        self.r = np.zeros((len(self.coeffs), 3, self.capacity))
        self.bound = stability_bound(model.youngs_modulus, model.damping,
                                     model.integrator, shapes.mass, shapes.inertia,
                                     shapes.radius, shapes.inradius, _max_edge(shapes))
        self.dt = choose_dt(self.bound, model.dt, model.dt_safety, model.integrator)
        self.time = 0.0
        self.step = 0
        self.gravity = (float(gravity[0]), float(gravity[1]))
        self.rotate = bool(rotate)
        self.size = float(np.mean(shapes.radius))
        self.eps = 1e-9 * self.size
        self.skin = 0.3 * self.size if skin is None else float(skin)
        self.inv_mass = 1.0 / shapes.mass
        self.inv_inertia = 1.0 / shapes.inertia
        bodies, ids = [], []
        if support:
            bodies.append((0.0, 0.0, 0.0, 1.0))
            ids.append(BODY_SUPPORT)
        if walls is not None:
            xl, xr = walls
            if not xl < xr:
                raise ValueError(f"walls = {walls!r}: x_left must be < x_right")
            bodies += [(xl, 0.0, 1.0, 0.0), (xr, 0.0, -1.0, 0.0)]
            ids += [BODY_LEFT, BODY_RIGHT]
        b = np.array(bodies, float).reshape(-1, 4)
        self.body_p = np.ascontiguousarray(b[:, :2])
        self.body_m = np.ascontiguousarray(b[:, 2:])
        self.body_ids = np.array(ids, np.int64)
        self.walls = walls
        self.body_friction = np.full(len(ids), model.support_friction)
        self.bspring = np.zeros((len(ids), self.capacity))
        self.bout = np.zeros((len(ids), self.capacity, ROW_SIZE))
        self.wx = np.zeros_like(shapes.node_x)
        self.wy = np.zeros_like(shapes.node_y)
        self.box = np.zeros((self.capacity, 4))
        max_corners = int(np.max(shapes.node_count)) if self.capacity else 3
        n_threads = numba.config.NUMBA_NUM_THREADS
        self.work = Workspace(
            np.stack([make_scratch(max_corners) for _ in range(n_threads)]),
            np.zeros((n_threads, THREAD_ROW)),
            np.zeros(self.capacity // BLOCK + 1))
        self.pred = np.zeros((self.capacity, PRED_SIZE))
        self.full_law = False
        self.pi = np.empty(0, np.int64)
        self.pj = np.empty(0, np.int64)
        self.spring = np.empty(0)
        self.axis = np.empty(0, np.int64)
        self.cross = np.empty((0, 4), np.int64)
        self._stale = True
        self.check_every = max(50, int(round(1e-3 / self.dt)))
        self.energy_tolerance = 0.25
        self.parallel_threshold = 400
        self.drag = 0.0
        self.spin_drag = 0.0
        self._reset_energy_reference()

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
        self.r[:, :, k] = 0.0
        self.r[0, :, k] = (x, y, theta)
        self.r[1, :, k] = (vx * self.dt, vy * self.dt, omega * self.dt)
        # start from the free-flight acceleration, so free fall is exact from step 1
        self.r[2, :2, k] = 0.5 * self.dt ** 2 * np.asarray(self.gravity)
        self.bspring[:, k] = 0.0
        its_pairs = (self.pi == k) | (self.pj == k)
        self.spring[its_pairs] = 0.0
        self.axis[its_pairs] = -1
        self.cross[its_pairs] = -1
        if k == self.n:
            self.n += 1
        self._stale = True
        self._reset_energy_reference()

    def set_gravity(self, gx, gy):
        """Change the gravity vector (m/s²); restarts the energy check."""
        self.gravity = (float(gx), float(gy))
        self._reset_energy_reference()

    def scaled_derivatives(self):
        """The integrator's values ``dt^k/k! d^k q/dt^k``, shape (n_values, 3, n)."""
        return self.r[:, :, :self.n].copy()

    def set_scaled_derivatives(self, r, dt):
        """Set the integrator's values, saved with time step ``dt``.

        With the same ``dt`` they are taken bit for bit, so a restart retraces
        the run; otherwise they are rescaled to this simulation's step.
        """
        n = r.shape[2]
        if n > self.capacity:
            raise ValueError(f"{n} particles exceed the capacity {self.capacity}")
        keep = min(r.shape[0], len(self.coeffs))
        self.r[:] = 0.0
        if dt == self.dt:
            self.r[:keep, :, :n] = r[:keep]
        else:
            self.r[:keep, :, :n] = scale_derivatives(unscale_derivatives(r, dt),
                                                     self.dt)[:keep]
        self.n = n
        self._stale = True
        self._reset_energy_reference()

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

    # ------------------------------------------------------------------ energy
    def kinetic_energy(self):
        """Translational plus rotational kinetic energy of the active particles, J/m."""
        v = self.velocity
        w = self.omega
        n = self.n
        return 0.5 * float(np.sum(self.shapes.mass[:n] * np.sum(v * v, axis=1)) +
                           np.sum(self.shapes.inertia[:n] * w * w))

    def potential_energy(self):
        """Gravitational energy ``−Σ m g·x`` of the active particles, J/m."""
        n = self.n
        x = self.r[0, :2, :n]
        return -float(np.sum(self.shapes.mass[:n] *
                             (self.gravity[0] * x[0] + self.gravity[1] * x[1])))

    def elastic_energy(self):
        """Stored contact energy (estimate), J/m.

        Normal: ``F⊥ A / (2 L)``, exact for an edge-on-edge contact
        (``A = L d``, ``F⊥ ∝ d``); tangential: ``F∥*² / (2 k∥)``.
        """
        e = 0.0
        kt = tangential_stiffness(self.model.youngs_modulus)
        for rows, spring in ((self._pair_rows(), self.spring),
                             (self.bout[:, :self.n].reshape(-1, ROW_SIZE),
                              self.bspring[:, :self.n].ravel())):
            act = rows[:, ROW["active"]] > 0
            a = rows[act, ROW["area"]]
            length = np.maximum(rows[act, ROW["length"]], np.sqrt(a))
            f = np.hypot(rows[act, ROW["fx"]], rows[act, ROW["fy"]])
            e += float(np.sum(f * a / (2.0 * np.maximum(length, self.eps))))
            e += float(np.sum(spring[act] ** 2)) / (2.0 * kt)
        return e

    def _pair_rows(self):
        return self.pout if self.pi.shape[0] else np.zeros((0, ROW_SIZE))

    def _energy_scale(self):
        n = max(self.n, 1)
        g = np.hypot(*self.gravity)
        lift = float(np.sum(self.shapes.mass[:n] * g * self.shapes.radius[:n]))
        return max(lift, self._energy_ref_movable, 1e-300)

    def _reset_energy_reference(self):
        self._energy_ref = None
        self._energy_ref_movable = 0.0

    # ------------------------------------------------------------------ running
    def _law_flags(self):
        """``(damped, tangential, body_tangential)``: the terms of the contact law
        that can be nonzero (all of them with ``full_law``)."""
        m = self.model
        return (self.full_law or m.damping > 0.0, self.full_law or m.friction > 0.0,
                self.full_law or m.support_friction > 0.0)

    def parallel_kernels(self):
        """Whether the kernels run their parallel builds: with at least
        ``parallel_threshold`` particles and more than one thread.

        Asking Numba for its thread count first also starts its threading
        layer, which the serial builds need too (their ``numba.get_thread_id``
        does not link before it: "LLVM ERROR: Symbol not found")."""
        return numba.get_num_threads() > 1 and self.n >= self.parallel_threshold

    def _rebuild(self):
        n = self.n
        x = np.ascontiguousarray(self.r[0, 0, :n])
        y = np.ascontiguousarray(self.r[0, 1, :n])
        pi, pj = candidate_pairs(x, y, self.shapes.radius, n, self.skin, self.parallel_kernels())
        if self._law_flags()[1]:
            self.spring = carry_history(self.pi, self.pj, self.spring, pi, pj)
        else:
            self.spring = np.zeros(len(pi))
        # the witnesses stay with their pairs, so that no result depends on when
        # the list was rebuilt (nor on a restart, which rebuilds it)
        self.axis = carry_history(self.pi, self.pj, self.axis, pi, pj, fill=-1)
        self.cross = carry_history(self.pi, self.pj, self.cross, pi, pj, fill=-1)
        if not self.rotate:
            # orientations are fixed: no angular velocity (so θ's prediction is θ)
            self.r[1:, 2, :n] = 0.0
        self.pi, self.pj = pi, pj
        self.pair_offset, self.pair_index = particle_pair_index(pi, pj, n)
        self.pout = np.zeros((len(pi), ROW_SIZE))
        self.pforce = np.zeros((len(pi), 4))
        self.x_ref = x.copy()
        self.y_ref = y.copy()
        self._stale = False

    def kernel_state(self):
        """The state as the kernels take it: particles, pairs, bodies, law, motion, work."""
        damped, tangential, body_tangential = self._law_flags()
        m = self.model
        sh = self.shapes
        return (Particles(self.r, self.pred, sh.node_offset, sh.node_x, sh.node_y, self.wx,
                          self.wy, self.box, sh.mass, self.inv_mass,
                          self.inv_inertia, sh.area),
                Pairs(self.pi, self.pj, self.spring, self.axis, self.cross, self.pout,
                      self.pforce, self.pair_offset, self.pair_index),
                Bodies(self.body_p, self.body_m, self.body_friction, self.bspring, self.bout),
                Law(float(m.youngs_modulus), float(m.damping), float(m.friction), self.eps,
                    bool(damped), bool(tangential), bool(body_tangential)),
                Motion(self.dt, self.coeffs, self.gravity[0], self.gravity[1],
                       float(self.drag), float(self.drag + self.spin_drag), self.rotate),
                self.work)

    def snapshot(self) -> Snapshot:
        """A copy of the dynamic state, enough to continue the run exactly."""
        return Snapshot(self.n, self.r.copy(), self.time, self.step, self.gravity,
                        self.pi.copy(), self.pj.copy(), self.spring.copy(),
                        self.bspring.copy(), self._pair_rows().copy(), self.bout.copy(),
                        self.axis.copy(), self.cross.copy())

    def restore(self, snap: Snapshot):
        """Return to a :class:`Snapshot`."""
        self.n, self.r, self.time, self.step = snap.n, snap.r.copy(), snap.time, snap.step
        self.gravity = snap.gravity
        self.pi, self.pj, self.spring = snap.pi.copy(), snap.pj.copy(), snap.spring.copy()
        self.bspring = snap.bspring.copy()
        self.pout, self.bout = snap.pout.copy(), snap.bout.copy()
        self.axis, self.cross = snap.axis.copy(), snap.cross.copy()
        self._stale = True
        self._reset_energy_reference()

    def run(self, duration=None, steps=None):
        """Advance by a simulated ``duration`` (s) or a number of ``steps``.

        Every ``check_every`` steps the state is checked (:meth:`check`); on a
        failure the simulation returns to the last state that passed and
        :class:`BlowUpError` is raised (carrying that snapshot too).

        Returns
        -------
        int
            Steps done.
        """
        if steps is None:
            if duration is None:
                raise ValueError("give a duration or a number of steps")
            steps = int(round(duration / self.dt))
        if self.n == 0:
            self.time += steps * self.dt
            self.step += steps
            return steps
        done = 0
        # time from the steps done in this call, not summed chunk by chunk: the
        # chunks end at pair-list rebuilds, which a resumed run has elsewhere
        start_time = self.time
        last_good = self.snapshot()
        rebuild_sq = (0.45 * self.skin) ** 2
        while done < steps:
            if self._stale:
                self._rebuild()
            chunk = min(steps - done, self.check_every - self.step % self.check_every)
            if self.step == 0:
                # a scene's first step is checked at once: the particle overlaps it
                # starts with (coincident centres, one polygon inside another) are
                # seen before their forces have thrown the particles apart (a start
                # inside the support or a wall is resolved: it pushes them out)
                chunk = 1
            kernels = KERNELS_PARALLEL if self.parallel_kernels() else KERNELS_SERIAL
            k, stale = advance(kernels, chunk, self.n, *self.kernel_state(), self.x_ref,
                               self.y_ref, rebuild_sq)
            done += k
            self.step += k
            self.time = start_time + done * self.dt
            if stale:
                self._stale = True
            if self.step % self.check_every == 0 or done == steps or self.step == 1:
                problem = self.check(start=self.step == 1)
                if problem:
                    failed_at = (self.time, self.step)
                    self.restore(last_good)
                    raise BlowUpError(
                        f"unstable at t = {failed_at[0]:.6g} s (step {failed_at[1]}): {problem}; "
                        f"dt = {self.dt:.4g} s ({self.model.integrator}, limit "
                        f"{self.bound.dt_limit:.4g} s). The last good state is kept "
                        f"(t = {last_good.time:.6g} s).", last_good)
                last_good = self.snapshot()
        return done

    def check(self, start=False):
        """Blow-up detector: a description of the first problem found, or ``None``.

        Checks non-finite positions or velocities; an overlap above
        ``max_overlap_fraction`` of the smaller particle's area; total energy
        (kinetic + gravitational + elastic) rising by more than 25 % of the
        energy scale (well above the bounded energy error of a stable step,
        about ``(ω dt)² / 8`` for Verlet) since the last insertion or gravity
        change, although no work is done.  The scale is ``Σ m |g| R`` or the
        kinetic plus elastic energy at the reference, whichever is larger.
        The elastic energy is an estimate that can be low by up to
        :data:`ELASTIC_UNDERESTIMATE` of itself, so the reference is the
        lowest *upper* bound of the true energy seen and the current energy
        its lower bound: releasing compressed corner contacts is not a rise.

        With ``start`` (after a new simulation's first step) only the first
        two, and only between particles: a start inside the support or a wall
        is resolved (it pushes the particle out), and the energy reference is
        taken at the first full check, once such a start has relaxed.
        """
        n = self.n
        if not np.all(np.isfinite(self.r[:, :, :n])):
            bad = int(np.argmax(~np.all(np.isfinite(self.r[:, :, :n]), axis=(0, 1))))
            return f"non-finite position or velocity of particle {bad}"
        ratio = 0.0
        rows = self._pair_rows()
        if rows.shape[0]:
            ratio = float(np.max(rows[:, ROW["ratio"]] * rows[:, ROW["active"]]))
        if not start and self.bout.shape[0]:
            b = self.bout[:, :n]
            ratio = max(ratio, float(np.max(b[..., ROW["ratio"]] * b[..., ROW["active"]])))
        if ratio > self.model.max_overlap_fraction:
            return (f"an overlap of {ratio:.3g} of a particle's area exceeds "
                    f"model.max_overlap_fraction = {self.model.max_overlap_fraction}")
        if start:
            return None
        elastic = self.elastic_energy()
        energy = self.kinetic_energy() + self.potential_energy() + elastic
        # the true energy lies in [energy, energy + ELASTIC_UNDERESTIMATE * elastic]
        upper = energy + ELASTIC_UNDERESTIMATE * elastic
        if self._energy_ref is None:
            self._energy_ref = upper
            self._energy_ref_movable = self.kinetic_energy() + elastic
            return None
        scale = self._energy_scale()
        if energy - self._energy_ref > self.energy_tolerance * scale:
            return (f"total energy rose by {energy - self._energy_ref:.3g} J/m "
                    f"(> {self.energy_tolerance:.0%} of the energy scale {scale:.3g} J/m) "
                    "with no work done")
        self._energy_ref = min(self._energy_ref, upper)
        return None

    # ------------------------------------------------------------------ contacts
    def contacts(self):
        """The active contacts of the last force evaluation (docs/formats.md#state-files).

        Returns
        -------
        dict of numpy.ndarray
            ``i``, ``j`` (j < 0: a body), ``x``, ``y`` (force point), ``fx``,
            ``fy`` (total force on i), ``nx``, ``ny`` (normal from i to j),
            ``area``, ``spring`` (tangential history), ``witness`` (n, 4): the
            crossing edges the narrow phase starts from next step
            (:mod:`sim.warmstart`; -1 for bodies).
        """
        rows = self._pair_rows()
        act = np.flatnonzero(rows[:, ROW["active"]] > 0) if rows.shape[0] else np.empty(0, int)
        parts_i = [self.pi[act]]
        parts_j = [self.pj[act]]
        parts_rows = [rows[act]]
        parts_spring = [self.spring[act]]
        parts_witness = [self.cross[act]]
        for b, body in enumerate(self.body_ids):
            brow = self.bout[b, :self.n]
            bact = np.flatnonzero(brow[:, ROW["active"]] > 0)
            parts_i.append(bact)
            parts_j.append(np.full(len(bact), body, np.int64))
            parts_rows.append(brow[bact])
            parts_spring.append(self.bspring[b, bact])
            parts_witness.append(np.full((len(bact), 4), -1, np.int64))
        allrows = np.concatenate(parts_rows) if parts_rows else np.zeros((0, ROW_SIZE))
        return {
            "i": np.concatenate(parts_i).astype(np.int64),
            "j": np.concatenate(parts_j).astype(np.int64),
            "x": allrows[:, ROW["sx"]], "y": allrows[:, ROW["sy"]],
            "fx": allrows[:, ROW["fx"]], "fy": allrows[:, ROW["fy"]],
            "nx": allrows[:, ROW["nx"]], "ny": allrows[:, ROW["ny"]],
            "area": allrows[:, ROW["area"]],
            "spring": np.concatenate(parts_spring),
            "witness": np.concatenate(parts_witness),
        }

    def set_springs(self, ci, cj, spring, witness=None):
        """Load the history of contacts ``(ci, cj)`` (j < 0: a body, i < j otherwise).

        ``spring`` is their tangential springs, ``witness`` (n_contacts, 4)
        their narrow-phase witnesses (:mod:`sim.warmstart`; as from
        :meth:`contacts`), which a restart needs to retrace the run bit for bit.
        """
        body = cj < 0
        for b, bid in enumerate(self.body_ids):
            sel = cj == bid
            self.bspring[b, ci[sel]] = spring[sel]
        pair = ~body
        lo = np.minimum(ci[pair], cj[pair])
        hi = np.maximum(ci[pair], cj[pair])
        order = np.lexsort((hi, lo))
        self._rebuild()
        self.spring = carry_history(lo[order], hi[order], spring[pair][order],
                                    self.pi, self.pj)
        if witness is not None:
            self.cross = carry_history(lo[order], hi[order], witness[pair][order],
                                       self.pi, self.pj, fill=-1)

    def stretch_body(self, body_id, strain):
        """Stretch the surface of a half-plane body by ``strain`` along itself.

        The surface point at ``q`` moves tangentially by ``strain (q − p)·t t``
        (``p`` the body's point, ``t`` its tangent), which in the contact law
        is a move of each tangential spring's anchor: the spring of every
        particle touching the body in the last force evaluation changes by
        ``−(2/7) Y strain (s − p)·t`` at its force point ``s`` (the spring
        opposes the particle's displacement relative to the surface).  The
        Coulomb cap applies at the next step, as for any spring.  The body
        itself stays where it is: a half-plane is the same after a move along
        its surface, so nothing but the springs remembers the stretch (state
        files and restarts need nothing new).  For the support (``p = 0``,
        ``t = x̂``) a contact at ``x`` is dragged by ``strain · x``.

        Parameters
        ----------
        body_id : int
            ``BODY_SUPPORT`` (-1), ``BODY_LEFT`` or ``BODY_RIGHT``.
        strain : float
            The increment of the surface's tangential strain (dimensionless,
            > 0 stretches).

        Returns
        -------
        int
            The contacts whose spring was moved.

        Raises
        ------
        ValueError
            If the scene has no such body, or its contacts carry no
            tangential springs (``model.support_friction`` = 0).
        """
        hits = np.flatnonzero(self.body_ids == body_id)
        if not hits.size:
            raise ValueError(f"body {body_id}: not a body of this scene (bodies {list(self.body_ids)})")
        if not self._law_flags()[2]:
            raise ValueError("a body's surface can only drag the particles through friction: "
                             f"model.support_friction = {self.model.support_friction}; give it > 0")
        b = int(hits[0])
        rows = self.bout[b, :self.n]
        act = np.flatnonzero(rows[:, ROW["active"]] > 0)
        tx, ty = -rows[act, ROW["ny"]], rows[act, ROW["nx"]]
        along = ((rows[act, ROW["sx"]] - self.body_p[b, 0]) * tx
                 + (rows[act, ROW["sy"]] - self.body_p[b, 1]) * ty)
        self.bspring[b, act] -= tangential_stiffness(self.model.youngs_modulus) * strain * along
        return int(act.size)

    def net_forces(self):
        """Net force (n, 2) on each active particle from the last evaluation plus gravity."""
        c = self.contacts()
        f = np.zeros((self.n, 2))
        np.add.at(f[:, 0], c["i"], c["fx"])
        np.add.at(f[:, 1], c["i"], c["fy"])
        pair = c["j"] >= 0
        np.add.at(f[:, 0], c["j"][pair], -c["fx"][pair])
        np.add.at(f[:, 1], c["j"][pair], -c["fy"][pair])
        m = self.shapes.mass[:self.n]
        f[:, 0] += m * self.gravity[0]
        f[:, 1] += m * self.gravity[1]
        return f


def _max_edge(shapes):
    """Longest polygon edge over all particles, m."""
    longest = 0.0
    off = shapes.node_offset
    for i in range(len(shapes.mass)):
        x = shapes.node_x[off[i]:off[i + 1]]
        y = shapes.node_y[off[i]:off[i + 1]]
        longest = max(longest, float(np.max(np.hypot(np.roll(x, -1) - x,
                                                     np.roll(y, -1) - y))))
    return longest
