"""Broad phase: O(N) candidate pairs from a cell list with a Verlet skin.

Every particle is enclosed by its circumcircle (radius ``R_i``, invariant under
rotation).  Two particles are *candidates* when their centres are closer than
``R_i + R_j + skin`` at their reference centres.  A particle's pairs are
tested anew only when it has moved more than 0.45 ``skin`` from its
reference (:mod:`sim.rebuild`; :func:`refreshed_pairs` for a few such
particles, :func:`candidate_pairs` for all), so the list always contains
every overlapping pair; each step then tests only the candidates (bounding
boxes, then the exact narrow phase of :mod:`sim.geometry`).

The build sorts particles into square cells of side ``2 R_max + skin`` (a
counting sort, O(N)) and scans the 3 × 3 neighbourhood of each particle's cell,
so its cost grows linearly with N and does not depend on corner counts.  The
list is ordered by ``(i, j)`` with ``i < j``; that order, and the per-particle
index built by :func:`particle_pair_index`, make force sums deterministic, so
a restarted run retraces the same trajectory.
"""

from __future__ import annotations

import numpy as np
from numba import prange

from .builds import build
from .kernel_cache import njit


@njit(cache=True)
def _cell_grid(x, y, n, cell):
    """Origin, cell counts and cell index of each of the first n particles."""
    xmin = x[0]
    xmax = x[0]
    ymin = y[0]
    ymax = y[0]
    for i in range(1, n):
        xmin = min(xmin, x[i])
        xmax = max(xmax, x[i])
        ymin = min(ymin, y[i])
        ymax = max(ymax, y[i])
    # never more cells than a few per particle, however far particles spread
    while ((xmax - xmin) / cell + 1.0) * ((ymax - ymin) / cell + 1.0) > 4.0 * n + 64.0:
        cell *= 2.0
    nx = int((xmax - xmin) / cell) + 1
    ny = int((ymax - ymin) / cell) + 1
    cx = np.empty(n, np.int64)
    cy = np.empty(n, np.int64)
    for i in range(n):
        cx[i] = min(int((x[i] - xmin) / cell), nx - 1)
        cy[i] = min(int((y[i] - ymin) / cell), ny - 1)
    return nx, ny, cx, cy


@njit(cache=True, inline="always")
def _neighbours(i, x, y, radius, skin, cx, cy, nx, ny, start, order, pj, k0, write):
    """Count (and with ``write`` store, in ascending order from ``pj[k0]``) the
    partners ``j > i`` of particle i within reach, scanning its 3 × 3 cells."""
    k = k0
    for gy in range(max(cy[i] - 1, 0), min(cy[i] + 2, ny)):
        for gx in range(max(cx[i] - 1, 0), min(cx[i] + 2, nx)):
            c = gx + nx * gy
            for q in range(start[c], start[c + 1]):
                j = order[q]
                if j <= i:
                    continue
                reach = radius[i] + radius[j] + skin
                dx = x[j] - x[i]
                dy = y[j] - y[i]
                if dx * dx + dy * dy < reach * reach:
                    if write:
                        # insertion sort keeps each particle's partners ordered
                        m = k
                        while m > k0 and pj[m - 1] > j:
                            pj[m] = pj[m - 1]
                            m -= 1
                        pj[m] = j
                    k += 1
    return k - k0


def candidate_pairs(x, y, radius, n, skin, parallel=False):
    """All pairs ``i < j`` of the first ``n`` particles closer than ``R_i + R_j + skin``.

    Parameters
    ----------
    x, y : numpy.ndarray
        Centres, m.
    radius : numpy.ndarray
        Circumradii, m.
    n : int
        Number of active particles (the first n entries).
    skin : float
        Verlet skin, m.
    parallel : bool
        Use the parallel build (the same pairs; worth it for a few hundred
        particles and more, as the force kernels, :mod:`sim.builds`).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        ``pi``, ``pj`` (int64), sorted by ``(pi, pj)``.
    """
    return (_PAIRS_PARALLEL if parallel else _PAIRS_SERIAL)(x, y, radius, n, skin)


def _candidate_pairs(x, y, radius, n, skin):
    """:func:`candidate_pairs`, to be built serial and parallel."""
    if n < 2:
        return np.empty(0, np.int64), np.empty(0, np.int64)
    rmax = 0.0
    for i in range(n):
        rmax = max(rmax, radius[i])
    nx, ny, cx, cy = _cell_grid(x, y, n, 2.0 * rmax + skin)
    ncell = nx * ny
    start = np.zeros(ncell + 1, np.int64)
    for i in range(n):
        start[cx[i] + nx * cy[i] + 1] += 1
    for c in range(ncell):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(n, np.int64)
    for i in range(n):
        c = cx[i] + nx * cy[i]
        order[fill[c]] = i
        fill[c] += 1

    count = np.zeros(n + 1, np.int64)
    unused = np.empty(0, np.int64)
    for i in prange(n):
        count[i + 1] = _neighbours(i, x, y, radius, skin, cx, cy, nx, ny, start, order,
                                   unused, 0, False)
    for i in range(n):
        count[i + 1] += count[i]
    total = count[n]
    pi = np.empty(total, np.int64)
    pj = np.empty(total, np.int64)
    for i in prange(n):
        _neighbours(i, x, y, radius, skin, cx, cy, nx, ny, start, order, pj, count[i], True)
        pi[count[i]:count[i + 1]] = i
    return pi, pj


_PAIRS_PARALLEL = build(_candidate_pairs, True)
_PAIRS_SERIAL = build(_candidate_pairs, False)


@njit(cache=True)
def refreshed_pairs(x_ref, y_ref, radius, n, skin, moved, pi, pj):
    """The candidate pairs after the particles ``moved`` took new reference centres.

    The list ``(pi, pj)`` holds the pairs closer than ``R_i + R_j + skin`` at
    the reference centres ``x_ref, y_ref`` (each particle's centre when it
    last took one); the particles of the mask ``moved`` have just taken
    theirs.  Their pairs are tested anew against every other particle's
    reference (O(n) per moved particle, with the test of
    :func:`candidate_pairs`); the pairs of two particles that kept theirs
    stay as they are.  So the result is :func:`candidate_pairs` of the
    reference centres, pair for pair, at the cost of a merge when few
    particles moved (in a pour, mostly one falling or rolling particle).

    Parameters
    ----------
    x_ref, y_ref : numpy.ndarray
        Reference centres, the moved particles' already new, m.
    radius : numpy.ndarray
        Circumradii, m.
    n : int
        Active particles.
    skin : float
        Verlet skin, m.
    moved : numpy.ndarray of bool
        The particles with new reference centres.
    pi, pj : numpy.ndarray
        The list at the old references, sorted by ``(pi, pj)``.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        ``pi``, ``pj`` (sorted) and, for each pair, its index in the old list
        or -1 (the ``match`` of :func:`carry_history`).
    """
    # the moved particles' pairs, as keys i * n + j, found by a scan of all
    found = []
    for i in range(n):
        if not moved[i]:
            continue
        for k in range(n):
            if k == i or (moved[k] and k < i):
                continue  # a pair of two moved particles is found from the first
            a = min(i, k)
            b = max(i, k)
            reach = radius[a] + radius[b] + skin
            dx = x_ref[b] - x_ref[a]
            dy = y_ref[b] - y_ref[a]
            if dx * dx + dy * dy < reach * reach:
                found.append(a * n + b)
    new_keys = np.sort(np.array(found, np.int64)) if found else np.empty(0, np.int64)
    old_keys = pi * n + pj
    kept = 0
    for p in range(pi.shape[0]):
        if not (moved[pi[p]] or moved[pj[p]]):
            kept += 1
    total = kept + new_keys.shape[0]
    out_i = np.empty(total, np.int64)
    out_j = np.empty(total, np.int64)
    match = np.empty(total, np.int64)
    # merge the kept pairs (in the old order) with the found ones
    p = 0
    q = 0
    for m in range(total):
        while p < pi.shape[0] and (moved[pi[p]] or moved[pj[p]]):
            p += 1
        if q == new_keys.shape[0] or (p < pi.shape[0] and old_keys[p] < new_keys[q]):
            key = old_keys[p]
            match[m] = p
            p += 1
        else:
            key = new_keys[q]
            old = np.searchsorted(old_keys, key)
            match[m] = old if old < old_keys.shape[0] and old_keys[old] == key else -1
            q += 1
        out_i[m] = key // n
        out_j[m] = key % n
    return out_i, out_j, match


@njit(cache=True)
def particle_pair_index(pi, pj, n):
    """CSR index of the pairs each particle belongs to, in pair order.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        ``offset`` (n + 1) and ``pairs``: the pairs of particle ``p`` are
        ``pairs[offset[p]:offset[p + 1]]``, each as ``2 q`` where ``p`` is the
        pair's ``i`` and as ``2 q + 1`` where it is its ``j`` (so the force
        sums need not read the pair list, and take the side from the low bit
        without a branch).
    """
    offset = np.zeros(n + 1, np.int64)
    for p in range(pi.shape[0]):
        offset[pi[p] + 1] += 1
        offset[pj[p] + 1] += 1
    for i in range(n):
        offset[i + 1] += offset[i]
    fill = offset[:-1].copy()
    pairs = np.empty(offset[n], np.int64)
    for p in range(pi.shape[0]):
        pairs[fill[pi[p]]] = 2 * p
        fill[pi[p]] += 1
        pairs[fill[pj[p]]] = 2 * p + 1
        fill[pj[p]] += 1
    return offset, pairs


@njit(cache=True)
def match_pairs(old_i, old_j, new_i, new_j):
    """For each pair of a new sorted pair list, its index in an old one (-1: absent).

    Both lists must be sorted by ``(i, j)``; a merge, O(old + new).
    """
    out = np.full(new_i.shape[0], -1, np.int64)
    a = 0
    for b in range(new_i.shape[0]):
        while a < old_i.shape[0] and (old_i[a] < new_i[b] or
                                      (old_i[a] == new_i[b] and old_j[a] < new_j[b])):
            a += 1
        if a < old_i.shape[0] and old_i[a] == new_i[b] and old_j[a] == new_j[b]:
            out[b] = a
    return out


def carry_history(match, old_value, fill=0.0):
    """Carry per-pair history from an old sorted pair list to a new one.

    Parameters
    ----------
    match : numpy.ndarray
        For each new pair its index in the old list, -1 where absent
        (:func:`match_pairs`; one match serves every kind of history).
    old_value : numpy.ndarray, shape (n_old,) or (n_old, k)
        History per old pair (tangential springs, narrow-phase witnesses).
    fill : scalar
        Value of pairs absent from the old list: 0 for a spring (a new
        contact's spring is unloaded, Appendix), -1 for a witness (none).

    Returns
    -------
    numpy.ndarray
        One row of history per new pair, of ``old_value``'s dtype.
    """
    old_value = np.asarray(old_value)
    out = np.full((len(match),) + old_value.shape[1:], fill, dtype=old_value.dtype)
    found = match >= 0
    out[found] = old_value[match[found]]
    return out
