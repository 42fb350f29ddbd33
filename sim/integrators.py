"""Predictor–corrector integrators for the equations of motion (Eq. 1).

Both integrators share one representation: for each particle and each degree
of freedom (x, y, θ) the *scaled* derivatives ``r_k = dt^k / k! · d^k q / dt^k``
are stored in an array of shape ``(n_values, 3, n_particles)``.  A step is

1. predict:  ``r ← P r`` with the Pascal-triangle matrix ``P_{kj} = C(j, k)``;
2. evaluate the forces at the predicted positions and velocities, giving the
   new ``r2_new = a dt² / 2``;
3. correct:  ``r_k ← r_k + c_k (r2_new − r2_pred)``.

* The **5th-order Gear predictor–corrector** (paper, Section 2; Gear 1971) uses
  six values and ``c = (3/16, 251/360, 1, 11/18, 1/6, 1/60)``, Gear's
  coefficients for second-order equations whose forces depend on velocity
  (3/20 would be the choice for purely positional forces).
* **Velocity Verlet** is exactly the three-value member of the family with
  ``c = (0, 1, 1)``: ``x ← x + v dt + a dt²/2``, forces are evaluated with the
  velocity estimate ``v + a dt``, and ``v ← v + (a + a_new) dt / 2``.

The stability limit of each scheme, the largest ``ω dt`` for which the
harmonic oscillator ``q'' = −ω² q`` does not grow, is computed from the
scheme's amplification matrix (:func:`stability_limit`).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from .kernel_cache import njit

GEAR_COEFFICIENTS = np.array([3.0 / 16.0, 251.0 / 360.0, 1.0, 11.0 / 18.0,
                              1.0 / 6.0, 1.0 / 60.0])
VERLET_COEFFICIENTS = np.array([0.0, 1.0, 1.0])

INTEGRATORS = {"gear": GEAR_COEFFICIENTS, "verlet": VERLET_COEFFICIENTS}


#: Magnitude below which a scaled derivative is flushed to zero by the corrector.
#: Without contacts Gear's higher derivatives decay geometrically into subnormal
#: numbers, whose arithmetic is many times slower; values this small are far
#: below the rounding of any position (``|x| ~ 1e-3`` m has an ulp of ~1e-19).
FLUSH_BELOW = 1e-200


@njit(cache=True, inline="always")
def nordsieck_predicted(r, i, pred):
    """The predicted values and scaled rates of particle i, leaving ``r`` as it is.

    Writes ``pred[i] = (x, y, θ, r_1x, r_1y, r_1θ)``: ``r_0`` and ``r_1`` of the
    prediction, by the additions of :func:`nordsieck_step`'s sweeps in
    their order, written out for the two schemes (three values: velocity
    Verlet; six: Gear), so that they are bit for bit the values the corrector
    starts from.  (A loop over a scratch copy instead made Gear's predictor
    2-3 times slower.)
    """
    nv = r.shape[0]
    for d in range(3):
        if nv == 3:
            r1 = r[1, d, i] + r[2, d, i]
            pred[i, d] = r[0, d, i] + r1
            pred[i, 3 + d] = r1 + r[2, d, i]
        else:
            _, _, _, w1, w0 = _pascal6(r[0, d, i], r[1, d, i], r[2, d, i], r[3, d, i],
                                       r[4, d, i], r[5, d, i])
            pred[i, d] = w0
            pred[i, 3 + d] = w1


@njit(cache=True, inline="always")
def nordsieck_step(r, i, d, new, coeffs, pred, predict_next):
    """Predictor ``r ← P r``, corrector and, with ``predict_next``, the next
    prediction of degree of freedom d of particle i.

    The predictor is the Pascal triangle applied as repeated in-place sweeps
    ``r_k += r_{k+1}`` (top down), the corrector ``r_k ← r_k + c_k (new −
    r2_pred)`` with ``new`` the evaluated ``a dt² / 2`` and ``coeffs`` the
    integrator's ``c_k`` (:func:`corrector_coefficients`); values of the third
    and higher derivatives below :data:`FLUSH_BELOW` become zero (no subnormal
    arithmetic in particles without contacts).  The next prediction is that of
    :func:`nordsieck_predicted`, with the same additions in the same order.
    All of it is done on the values held in registers and written once: through
    ``r`` between the phases, every store would force the next phase to read
    ``r`` again (the compiler cannot tell ``r`` from ``pred``).  Written out
    for the two schemes (three values: velocity Verlet, six: Gear).

    Parameters
    ----------
    r : numpy.ndarray, shape (n_values, 3, capacity)
        Scaled derivatives; particle i's of d are replaced by the corrected ones.
    i, d : int
        Particle, degree of freedom (0, 1, 2: x, y, θ).
    new : float
        Evaluated ``a dt² / 2`` of d.
    coeffs : numpy.ndarray
        Corrector coefficients.
    pred : numpy.ndarray, shape (capacity, 6)
        With ``predict_next``, ``pred[i, d]`` and ``pred[i, 3 + d]`` receive the
        next step's prediction of d and its scaled rate.
    predict_next : bool
    """
    if r.shape[0] == 3:
        v0 = r[0, d, i]
        v1 = r[1, d, i]
        v2 = r[2, d, i]
        v1 += v2
        v0 += v1
        v1 += v2
        delta = new - v2
        v0 = v0 + coeffs[0] * delta
        v1 = v1 + coeffs[1] * delta
        v2 = v2 + coeffs[2] * delta
        r[0, d, i] = v0
        r[1, d, i] = v1
        r[2, d, i] = v2
        if predict_next:
            w1 = v1 + v2
            pred[i, d] = v0 + w1
            pred[i, 3 + d] = w1 + v2
    else:
        v0 = r[0, d, i]
        v1 = r[1, d, i]
        v2 = r[2, d, i]
        v3 = r[3, d, i]
        v4 = r[4, d, i]
        v5 = r[5, d, i]
        v4, v3, v2, v1, v0 = _pascal6(v0, v1, v2, v3, v4, v5)
        delta = new - v2
        v0 = v0 + coeffs[0] * delta
        v1 = v1 + coeffs[1] * delta
        v2 = v2 + coeffs[2] * delta
        v3 = _flushed(v3 + coeffs[3] * delta)
        v4 = _flushed(v4 + coeffs[4] * delta)
        v5 = _flushed(v5 + coeffs[5] * delta)
        r[0, d, i] = v0
        r[1, d, i] = v1
        r[2, d, i] = v2
        r[3, d, i] = v3
        r[4, d, i] = v4
        r[5, d, i] = v5
        if predict_next:
            w4, w3, w2, w1, w0 = _pascal6(v0, v1, v2, v3, v4, v5)
            pred[i, d] = w0
            pred[i, 3 + d] = w1


@njit(cache=True, inline="always")
def _pascal6(v0, v1, v2, v3, v4, v5):
    """``P r`` of six values by the sweeps ``r_k += r_{k+1}``; returns r4 .. r0
    (r5 is unchanged)."""
    v4 += v5
    v3 += v4
    v4 += v5
    v2 += v3
    v3 += v4
    v4 += v5
    v1 += v2
    v2 += v3
    v3 += v4
    v4 += v5
    v0 += v1
    v1 += v2
    v2 += v3
    v3 += v4
    v4 += v5
    return v4, v3, v2, v1, v0


@njit(cache=True, inline="always")
def _flushed(v):
    """``v``, or 0 where ``|v|`` is below :data:`FLUSH_BELOW`."""
    return 0.0 if abs(v) < FLUSH_BELOW else v


def corrector_coefficients(name: str) -> np.ndarray:
    """Corrector coefficients ``c_k`` of the named integrator.

    Parameters
    ----------
    name : {"gear", "verlet"}

    Returns
    -------
    numpy.ndarray
        One coefficient per stored derivative; its length is the number of
        values the scheme keeps.
    """
    try:
        return INTEGRATORS[name].copy()
    except KeyError:
        raise ValueError(f"integrator = {name!r}: must be one of {sorted(INTEGRATORS)}")


def predictor_matrix(n_values: int) -> np.ndarray:
    """Pascal-triangle Taylor predictor ``P_{kj} = C(j, k)`` for scaled derivatives."""
    p = np.zeros((n_values, n_values))
    for k in range(n_values):
        for j in range(k, n_values):
            p[k, j] = math.comb(j, k)
    return p


def amplification_matrix(name: str, omega_dt: float, zeta: float = 0.0) -> np.ndarray:
    """One step of the scheme applied to ``q'' = −ω² q − 2ζω q'``.

    Parameters
    ----------
    name : {"gear", "verlet"}
    omega_dt : float
        ``ω dt``.
    zeta : float
        Damping ratio.

    Returns
    -------
    numpy.ndarray
        The matrix ``M`` with ``r(t + dt) = M r(t)``.
    """
    c = corrector_coefficients(name)
    n = len(c)
    h = omega_dt
    p = predictor_matrix(n)
    # r2_new = dt²/2 · a(r0p, r1p) with a = -ω² q - 2ζω q', q = r0, q' = r1/dt
    e = np.zeros(n)
    e[0] = -0.5 * h * h
    e[1] = -zeta * h
    e[2] = -1.0
    return (np.eye(n) + np.outer(c, e)) @ p


@functools.lru_cache(maxsize=None)
def stability_limit(name: str, zeta: float = 0.0) -> float:
    """Largest ``ω dt`` for which the scheme keeps the oscillator bounded.

    Found by scanning the spectral radius of :func:`amplification_matrix` and
    bisecting its first crossing of 1 (with a 1e-9 tolerance for the neutral
    modes of undamped schemes).

    Parameters
    ----------
    name : {"gear", "verlet"}
    zeta : float
        Damping ratio of the test oscillator.

    Returns
    -------
    float
        The limit ``h*``; a time step is stable for ``ω dt < h*``.
    """
    def unstable(h):
        return max(abs(np.linalg.eigvals(amplification_matrix(name, h, zeta)))) > 1 + 1e-9

    h_prev = 0.0
    for h in np.arange(1e-3, 4.0, 1e-3):
        if unstable(h):
            lo, hi = h_prev, h
            for _ in range(50):
                mid = 0.5 * (lo + hi)
                lo, hi = (lo, mid) if unstable(mid) else (mid, hi)
            return lo
        h_prev = h
    return h_prev


def scale_derivatives(derivs: np.ndarray, dt: float) -> np.ndarray:
    """Time derivatives ``d^k q/dt^k`` → scaled values ``dt^k/k! d^k q/dt^k``."""
    out = np.empty_like(derivs)
    for k in range(derivs.shape[0]):
        out[k] = derivs[k] * dt ** k / math.factorial(k)
    return out


def unscale_derivatives(r: np.ndarray, dt: float) -> np.ndarray:
    """Inverse of :func:`scale_derivatives`."""
    out = np.empty_like(r)
    for k in range(r.shape[0]):
        out[k] = r[k] * math.factorial(k) / dt ** k
    return out
