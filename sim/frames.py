"""Snapshots of a pour for a film of how the pile was built (``pour --frames``).

A :class:`FrameRecorder` keeps, every ``pour.frame_interval`` simulated
seconds, the centre, orientation and speed of every released particle, and
writes them with the polygons' body-frame corners to one netCDF file (the
layout is in ``results/README.md``; ``python -m analysis film`` turns it into
a film). It changes nothing in the pour: it only reads the state between two
calls of :meth:`sim.engine.Simulation.run`.

Cost: one frame is four ``float32`` values per particle (56 kB for 3500
particles); at most :data:`MAX_FRAMES` are kept, the interval doubling (every
second frame dropped) when that many are reached, so the file stays under
``MAX_FRAMES`` frames whatever the pour's length. The wall time spent copying
is measured and logged with the file's size.

Beside the frames it keeps where each particle *landed*: its centre and the
time at the end of the first run chunk (one release interval of the pour,
``1 / rate``) in which it touched a particle or a body (``landing_x``,
``landing_y``, ``landing_time``; NaN for a particle that never touched
anything).  Read against where the particle comes to rest, it says whether a
pile was laid down where its particles fell or built by flows
(:func:`analysis.growth.landing_displacement`).  The landing is taken at every
call, not only at frame times, so it is as fine as the pour's chunks whatever
``frame_interval``.

On a table (``pour.line_source: table``) a particle that has left the table
is NaN in every frame from then on (it is parked far away, :mod:`sim.pour`),
and ``released`` still counts it.

While a pour checkpoints, the frames so far are written beside the checkpoint
(:func:`partial_path`) and read back when that checkpoint is resumed, so a
resumed pour's film has no gap; they are deleted with the checkpoint.
"""

from __future__ import annotations

import logging
import time as _time
from pathlib import Path

import numpy as np
import xarray as xr

from .io import atomic_write, cf_attributes
from .release import touching

log = logging.getLogger(__name__)

#: Frames kept at most; beyond it the interval doubles (see the module docstring).
MAX_FRAMES = 1000

FRAME_VARS = {
    "x": ("m", "centre of mass x (NaN: not yet released, or left the table)"),
    "y": ("m", "centre of mass y (NaN: not yet released, or left the table)"),
    "theta": ("rad", "orientation"),
    "speed": ("m/s", "speed of the centre of mass"),
}

#: Where each particle first touched the pile (see the module docstring).
LANDING_VARS = {
    "landing_x": ("m", "centre x at the end of the first chunk in which the particle touched "
                  "a particle or a body (NaN: never)"),
    "landing_y": ("m", "centre y then"),
    "landing_time": ("s", "simulated time then"),
}


def partial_path(checkpoint) -> Path:
    """The file of the frames recorded up to a checkpoint: ``<checkpoint>.frames.nc``."""
    checkpoint = Path(checkpoint)
    return checkpoint.with_name(checkpoint.name.removesuffix(".nc") + ".frames.nc")


class FrameRecorder:
    """Snapshots of the released particles every `interval` simulated seconds.

    Parameters
    ----------
    shapes : sim.shapes.Shapes
        The pour's polygons (all of them, released or not).
    n_particles : int
        Particles the pour will release (the width of every frame).
    interval : float
        Simulated seconds between frames, s (``pour.frame_interval``).
    table_half_width : float, optional
        The table's half-width W of a pour on a table (``pour.line_source:
        table``): a particle whose centre lies beyond it has left the table
        and is NaN in every frame from then on, and lands nowhere.
    """

    def __init__(self, shapes, n_particles: int, interval: float,
                 table_half_width: float | None = None):
        if not interval > 0:
            raise ValueError(f"pour.frame_interval = {interval!r}: must be > 0 s")
        self.shapes = shapes
        self.n_particles = int(n_particles)
        self.interval = float(interval)
        self.table_half_width = table_half_width
        self.times: list[float] = []
        self.released: list[int] = []
        self.frames: list[np.ndarray] = []   # (4, n_particles) float32 each
        self.next_time = 0.0
        self.wall = 0.0
        self.landing = np.full((len(LANDING_VARS), self.n_particles), np.nan)

    def __call__(self, sim) -> None:
        """Take a frame if the simulation has reached the next frame time.

        Frame k is the state at the first call at or after k * interval, so the
        frame times depend only on the run, not on where it was resumed.  Every
        call also takes the landing of the particles that touch something for
        the first time (:meth:`_land`).
        """
        t0 = _time.perf_counter()
        self._land(sim)
        if sim.time < self.next_time:
            self.wall += _time.perf_counter() - t0
            return
        self._take(sim)
        self.next_time = self._after(sim.time)
        self.wall += _time.perf_counter() - t0

    def _after(self, t: float) -> float:
        """The first frame time after `t`: the next multiple of the interval."""
        return (np.floor(t / self.interval) + 1.0) * self.interval

    def _on_table(self, sim) -> np.ndarray:
        """Mask of the active particles that have not left the table (all without one)."""
        if self.table_half_width is None:
            return np.ones(sim.n, bool)
        return np.abs(sim.position[:, 0]) <= self.table_half_width

    def _land(self, sim) -> None:
        """Record centre and time of the particles touching something for the first time."""
        n = sim.n
        new = touching(sim) & self._on_table(sim) & np.isnan(self.landing[2, :n])
        self.landing[0, :n][new] = sim.position[new, 0]
        self.landing[1, :n][new] = sim.position[new, 1]
        self.landing[2, :n][new] = sim.time

    def finish(self, sim) -> None:
        """Take the last frame (the state that is saved), whatever the time, and the last landings."""
        self._land(sim)
        if not self.times or self.times[-1] < sim.time:
            self._take(sim)

    def _take(self, sim) -> None:
        n = sim.n
        frame = np.full((4, self.n_particles), np.nan, np.float32)
        frame[0, :n] = sim.position[:, 0]
        frame[1, :n] = sim.position[:, 1]
        frame[2, :n] = sim.theta
        frame[3, :n] = np.hypot(*sim.velocity.T)
        frame[:, :n][:, ~self._on_table(sim)] = np.nan
        self.times.append(float(sim.time))
        self.released.append(n)
        self.frames.append(frame)
        if len(self.frames) >= MAX_FRAMES:
            self.times, self.frames = self.times[::2], self.frames[::2]
            self.released = self.released[::2]
            self.interval *= 2.0
            log.info("frames: %d reached, interval now %.3g s", MAX_FRAMES, self.interval)

    def resume(self, path, time: float) -> None:
        """Continue the frames of ``path`` (a :func:`partial_path` file) up to `time`.

        A missing or unreadable file leaves the film starting at `time`, with a
        log line.
        """
        try:
            with xr.open_dataset(path, engine="netcdf4") as ds:
                times = np.asarray(ds["time"].values, float)
                keep = times <= time + 1e-12
                stack = np.stack([ds[name].values[keep] for name in FRAME_VARS], axis=1)
                released = ds["released"].values[keep]
                interval = float(ds.attrs["frame_interval"])
                landing = np.stack([ds[name].values for name in LANDING_VARS])
        except (OSError, KeyError, ValueError) as exc:
            log.warning("frames: %s unusable (%s); the film starts at t = %.3f s",
                        path, exc, time)
            return
        if stack.shape[2] != self.n_particles:
            log.warning("frames: %s has %d particles, not %d; the film starts at t = %.3f s",
                        path, stack.shape[2], self.n_particles, time)
            return
        self.times = [float(t) for t in times[keep]]
        self.frames = [f.astype(np.float32) for f in stack]
        self.released = [int(r) for r in released]
        self.interval = interval
        self.next_time = self._after(self.times[-1]) if self.times else 0.0
        self.landing = np.where(landing[2] <= time + 1e-12, landing, np.nan)

    def dataset(self, config: dict | None = None, **attrs) -> xr.Dataset:
        """The frames as a dataset: ``time (frame)``, ``x, y, theta, speed
        (frame, particle)``, ``released (frame)``, the polygons' corners
        (``node_count``, ``node_x``, ``node_y``, as in a state file)."""
        stack = (np.stack(self.frames, axis=1) if self.frames
                 else np.zeros((4, 0, self.n_particles), np.float32))
        sh = self.shapes
        off = int(sh.node_offset[self.n_particles])
        ds = xr.Dataset()
        ds["time"] = xr.DataArray(np.asarray(self.times, float), dims="frame",
                                  attrs={"units": "s", "long_name": "simulated time"})
        for k, (name, (units, long_name)) in enumerate(FRAME_VARS.items()):
            ds[name] = xr.DataArray(stack[k], dims=("frame", "particle"),
                                    attrs={"units": units, "long_name": long_name})
        for row, (name, (units, long_name)) in zip(self.landing, LANDING_VARS.items()):
            ds[name] = xr.DataArray(row, dims="particle", attrs={"units": units,
                                                                 "long_name": long_name})
        ds["released"] = xr.DataArray(
            np.asarray(self.released, np.int32), dims="frame",
            attrs={"units": "1", "long_name": "particles released so far"})
        ds["node_count"] = xr.DataArray(sh.node_count[:self.n_particles].astype(np.int32),
                                        dims="particle", attrs={
                                            "units": "1", "long_name": "corners of each polygon",
                                            "sample_dimension": "node"})
        ds["node_x"] = xr.DataArray(sh.node_x[:off], dims="node", attrs={
            "units": "m", "long_name": "corner x in the body frame (centre of mass, theta = 0)"})
        ds["node_y"] = xr.DataArray(sh.node_y[:off], dims="node", attrs={
            "units": "m", "long_name": "corner y in the body frame"})
        ds.attrs = {**cf_attributes("Frames of a pour (a film of the pile being built)",
                                    config, "written by sim.frames.FrameRecorder"),
                    "frame_interval": self.interval, **attrs}
        return ds

    def save(self, path, config: dict | None = None, **attrs) -> None:
        """Write the frames to ``path`` atomically and log their count, size and cost."""
        atomic_write(self.dataset(config, **attrs), path)
        log.info("frames: %d written to %s (%.2f MB), %.2f s of wall time spent taking them",
                 len(self.frames), path, Path(path).stat().st_size / 1e6, self.wall)
