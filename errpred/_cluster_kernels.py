"""Numba kernels: many points against many sweeps, pruned per cluster of points.

The exact single-sweep tests (:func:`errpred._kernels.sweep_within`,
:func:`errpred._kernels.sweep_distance`) run only against the sweeps a bin of
nearby points can reach: each bin gets its short list from closed-form
bounds on the swept core's distance, carried from coarse cubes down to the
bin. Same answers as :func:`errpred._kernels.inside_any_sweep` over the full
list (``tests/errpred/test_sweeps.py`` compares them).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._kernels import (_in_box, _reach_bound, _sphere, sweep_distance, sweep_lower_bound,
                       sweep_within)
from ._sort_kernels import argsort_stable, grown
from .constants import (CLUSTER_COARSE, CLUSTER_RECENT, CLUSTER_SUPER, FEW_SWEEPS,
                        HOT_ROUNDS, HOT_ROUNDS_BALL, HOT_SEED_POINTS, HOT_SEED_POINTS_BALL,
                        HOT_SEED_SWEEPS, HOT_SEED_SWEEPS_BALL, MARGIN_SEED_POINTS)

__all__ = ["inside_any_sweep_clustered", "read_only", "sweep_margin_clustered"]


def read_only(*arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    """The sweep arrays (``p0, d, w, lo, hi``, and T1's sweep ids) flagged read-only:
    T1 and T2 as :meth:`errpred.geometry.GeometryModel` keeps its last answer (which
    must not change), every subset of them handed to the kernels, and other packages'
    sweeps handed to the membership tests (``errpred.sweeps.read_only``: the same
    specializations as errpred's, its callees compiled once). Numba compiles
    a kernel once per argument type and a read-only array is another type: a subset of
    T1 or T2 made writeable cost a second specialization of
    :func:`inside_any_sweep_clustered`, 14 s of compiling on a fresh cache."""
    for a in arrays:
        a.flags.writeable = False
    return arrays


@njit(cache=True)
def _bins(points, candidates, cell):
    """Candidate points binned into cubes: (idx, order, keys, count).

    A bin's key holds its super cube (``CLUSTER_SUPER`` coarse cubes a side) in
    its high bits, then its coarse cube within it (``CLUSTER_COARSE`` bins a
    side), so that sorting by key keeps the bins of a coarse cube, and the
    coarse cubes of a super cube, together.
    """
    k = points.shape[0]
    idx = np.empty(k, dtype=np.int64)
    keys = np.empty(k, dtype=np.int64)
    m = 0
    big = 1 << 14  # super cubes either side of the origin (cell 0.05 mm: 26 m)
    span = 2 * big
    q = CLUSTER_COARSE
    sq = CLUSTER_SUPER
    for i in range(k):
        if candidates[i]:
            ix = int(math.floor(points[i, 0] / cell))
            iy = int(math.floor(points[i, 1] / cell))
            iz = int(math.floor(points[i, 2] / cell))
            cx, cy, cz = ix // q, iy // q, iz // q
            sx, sy, sz = cx // sq, cy // sq, cz // sq
            sup = ((sx + big) * span + (sy + big)) * span + (sz + big)
            coarse = ((cx - sx * sq) * sq + (cy - sy * sq)) * sq + (cz - sz * sq)
            fine = ((ix - cx * q) * q + (iy - cy * q)) * q + (iz - cz * q)
            keys[m] = (sup * (sq * sq * sq) + coarse) * (q * q * q) + fine
            idx[m] = i
            m += 1
    order = argsort_stable(keys[:m])
    return idx, order, keys, m


#: Slack of the short lists' Lipschitz shortcuts [mm]: a shortcut answers only where
#: the bound clears the limit by more than this (far above the bounds' rounding), so
#: every answer is the one the full test gives.
_LIP_SLACK = 1e-9


@njit(cache=True)
def _group_sphere(sph, bstart, b0, b1):
    """A sphere holding the spheres of bins ``b0:b1``: centre (their centres' mean
    weighted by their point counts) and radius."""
    gx = gy = gz = 0.0
    cnt = 0
    for b in range(b0, b1):
        e = bstart[b + 1] - bstart[b]
        gx += sph[b, 0] * e
        gy += sph[b, 1] * e
        gz += sph[b, 2] * e
        cnt += e
    gx /= cnt
    gy /= cnt
    gz /= cnt
    grad = 0.0
    for b in range(b0, b1):
        v = math.sqrt((sph[b, 0] - gx) ** 2 + (sph[b, 1] - gy) ** 2
                      + (sph[b, 2] - gz) ** 2) + sph[b, 3]
        if v > grad:
            grad = v
    return gx, gy, gz, grad


@njit(cache=True)
def _level(src, src_lo, src_hi, ns, delta, gx, gy, gz, grad, p0, d, w, lo, hi, c, r, top,
           reach, dst, dst_lo, dst_hi):
    """Those of the ``ns`` sweeps ``src`` that may come within ``reach`` of the sphere
    (gx, gy, gz, grad), into ``dst`` in the same order, with an interval holding each
    one's distance bound at the centre (``dst_lo``, ``dst_hi``); returns how many.

    ``src_lo``, ``src_hi``: intervals holding the bounds at a centre ``delta`` away:
    the bound here lies within ``delta`` of them (1-Lipschitz), so where that clears
    the limit by more than ``_LIP_SLACK`` the answer needs no closed form (the
    bounds' box test still runs).
    """
    lim = r + reach + grad
    slack = _LIP_SLACK
    nc = 0
    for q in range(ns):
        if src_lo[q] - delta > lim + slack:
            continue
        j = src[q]
        if not _in_box(j, gx, gy, gz, reach + grad, lo, hi):
            continue
        if src_hi[q] + delta < lim - slack:
            lo_v, hi_v = src_lo[q] - delta, src_hi[q] + delta
        else:
            v = _reach_bound(j, gx, gy, gz, p0, d, w, c, r, top, lim)
            if v > lim:
                continue
            lo_v, hi_v = v, v
        dst[nc] = j
        dst_lo[nc] = lo_v
        dst_hi[nc] = hi_v
        nc += 1
    return nc


@njit(cache=True)
def _recent_pass(points, idx, order, s, e, recent, nrec, p0, d, w, lo, hi, c, r, top, lim,
                 out):
    """The points ``idx[order[s:e]]`` against the sweeps that held points lately
    (``recent[:nrec]``, latest first): those inside one set in ``out`` (the sweep
    moved to the front); returns how many are left."""
    left = 0
    for t in range(s, e):
        i = idx[order[t]]
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        hit = -1
        for u in range(nrec):
            j = recent[u]
            if (x < lo[j, 0] or x > hi[j, 0] or y < lo[j, 1] or y > hi[j, 1]
                    or z < lo[j, 2] or z > hi[j, 2]):
                continue
            if sweep_within(x, y, z, p0[j], d[j], w[j], c, r, top, lim):
                hit = u
                break
        if hit < 0:
            left += 1
            continue
        out[i] = True
        j = recent[hit]
        for v in range(hit, 0, -1):
            recent[v] = recent[v - 1]
        recent[0] = j
    return left


@njit(cache=True)
def _list_pass(points, idx, order, s, e, lst, k, recent, nrec, p0, d, w, c, r, top, lim,
               out):
    """The points ``idx[order[s:e]]`` not yet in ``out`` against their bin's list
    ``lst[:k]`` (a sweep that holds one moves to the list's front: the bin's next
    points are likely inside it too, and to the front of ``recent``); returns the
    new length of ``recent``."""
    for t in range(s, e):
        i = idx[order[t]]
        if out[i]:
            continue
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        for q in range(k):
            j = lst[q]
            if sweep_within(x, y, z, p0[j], d[j], w[j], c, r, top, lim):
                out[i] = True
                lst[q] = lst[0]
                lst[0] = j
                pos = -1
                for u in range(nrec):
                    if recent[u] == j:
                        pos = u
                        break
                if pos < 0:
                    if nrec < recent.shape[0]:
                        nrec += 1
                    pos = nrec - 1
                for v in range(pos, 0, -1):
                    recent[v] = recent[v - 1]
                recent[0] = j
                break
    return nrec


@njit(cache=True, inline="always")
def _point_margin(x, y, z, lst, g_lo, k, delta, p0, d, w, lo, hi, c, r, top, reach):
    """``min_j dist_j - r`` over the sweeps ``lst[:k]`` for one point, clipped to
    ``[-reach, reach]``, stopping at the first sweep it lies ``reach`` deep in. ``g_lo``:
    lower bounds of each sweep's distance at a centre ``delta`` from the point (a sweep
    whose bound minus ``delta`` clears ``r`` plus the margin so far, at most ``reach``,
    cannot lower the clipped value: recorded margin calls of the mold-ball contour slice
    1.17 -> 1.05 ms, the same values)."""
    best = 1e300
    for q in range(k):
        if g_lo[q] - delta > r + min(best, reach) + _LIP_SLACK:
            continue
        j = lst[q]
        if not _in_box(j, x, y, z, reach, lo, hi):
            continue
        if c != 0.0 and (sweep_lower_bound(x, y, z, p0[j], d[j], w[j], c, r, top) - r
                         >= min(best, reach)):
            continue
        v = sweep_distance(x, y, z, p0[j], d[j], w[j], c, r, top) - r
        if v < best:
            best = v
            if best <= -reach:
                break
    if best < -reach:
        best = -reach
    elif best > reach:
        best = reach
    return best


@njit(cache=True)
def _shortlists(points, idx, order, keys, m, p0, d, w, lo, hi, c, r, top, reach, out,
                margins):
    """Per bin: (start, end, sweeps that may reach it), as flat arrays.

    Sweeps that cannot come within ``reach`` of any point are dropped first
    (one bounding sphere for all points), then per super cube of bins, per
    coarse cube within it and per bin (each level a sphere holding its bins'
    spheres, picking from the level above's list, :func:`_level`). A bin's
    list is the same, in the same order, as if every sweep were tested
    against the bin alone: a sweep that may reach a bin's sphere may reach any
    sphere holding it (the tests are 1-Lipschitz in the centre).

    The distance bound of a sweep at a level's centre is kept (as an interval)
    for the next level, so most picks need no closed form: the lists are those
    the tests give, at a fraction of the cost where hundreds of sweeps are near.

    With ``margins`` (one float per point; empty otherwise), a bin of one point gets
    its margin (:func:`_point_margin`, clipped to ``[-reach, reach]``) from its coarse
    cube's list and bounds directly, and its list comes back empty: its own list would
    cost as many closed forms as the margin (a ball's bound is its distance), and the
    margin would compute them again (the finished surface's pixels lie one to a bin).
    The same values: a sweep left out of a bin's list lies farther than ``reach``.

    With ``out`` (bool, one per point; empty otherwise), membership is decided here
    and the lists are not kept (every bin's comes back empty): each bin's points go
    first against the sweeps that held points of the bins before (``CLUSTER_RECENT`` of
    them, :func:`_recent_pass`), and only a bin with a point none of them holds gets its
    list and the exact tests (:func:`_list_pass`); ``out`` is set where a point lies
    inside a sweep (within ``r + reach`` of its core). The same answers: a point is
    inside when a sweep holds it, whichever sweep that is.

    Which of the three a call does follows from its arrays' sizes, not from a flag: a
    constant is a literal type to numba, which compiles a callee once per literal it
    sees, and a counter set to 0 before a loop is one while numba infers its type. The
    flag's two values compiled this function and everything under it twice; the
    counters (``nn``, ``nrec``, ``b0``) compiled ``_level``, ``_recent_pass``,
    ``_list_pass``, ``_group_sphere`` and ``_sphere`` a second time each, for a zero
    that never reaches them. So they start from a typed zero: the job's warm-up of the
    prediction compiles for 31 s instead of 41 s on an empty cache.
    """
    n = p0.shape[0]
    zero = np.int64(0)      # counters start from a typed zero (see the docstring)
    cx, cy, cz, rad = _sphere(points, idx, order, zero, m)
    near = np.empty(n, dtype=np.int64)
    g1 = np.empty(n)
    nn = zero
    for j in range(n):
        if not _in_box(j, cx, cy, cz, reach + rad, lo, hi):
            continue
        lim = r + reach + rad
        v = _reach_bound(j, cx, cy, cz, p0, d, w, c, r, top, lim)
        if v <= lim:
            near[nn] = j
            g1[nn] = v
            nn += 1
    # the bins: runs of equal keys
    bstart = np.empty(m + 1, dtype=np.int64)
    nb = 0
    s = 0
    while s < m:
        bstart[nb] = s
        key = keys[order[s]]
        while s < m and keys[order[s]] == key:
            s += 1
        nb += 1
    bstart[nb] = m
    sph = np.empty((nb, 4))
    for b in range(nb):
        sph[b, 0], sph[b, 1], sph[b, 2], sph[b, 3] = _sphere(points, idx, order, bstart[b],
                                                             bstart[b + 1])
    cell_count = CLUSTER_COARSE * CLUSTER_COARSE * CLUSTER_COARSE
    super_count = cell_count * CLUSTER_SUPER * CLUSTER_SUPER * CLUSTER_SUPER
    offsets = np.zeros(nb + 1, dtype=np.int64)
    total = 0
    size = max(nn, 1)
    buf = np.empty(size * 8, dtype=np.int64)
    lists = np.empty((3, size), dtype=np.int64)  # super, coarse, bin
    g_lo = np.empty((3, size))
    g_hi = np.empty((3, size))
    recent = np.empty(CLUSTER_RECENT, dtype=np.int64)
    nrec = zero
    direct = margins.shape[0] > 0
    decide = out.shape[0] > 0
    b0 = zero
    while b0 < nb:
        # the bins of one super cube
        skey = keys[order[bstart[b0]]] // super_count
        s1 = b0
        while s1 < nb and keys[order[bstart[s1]]] // super_count == skey:
            s1 += 1
        sx, sy, sz, srad = _group_sphere(sph, bstart, b0, s1)
        delta = math.sqrt((sx - cx) ** 2 + (sy - cy) ** 2 + (sz - cz) ** 2)
        ns = _level(near, g1, g1, nn, delta, sx, sy, sz, srad, p0, d, w, lo, hi, c, r, top,
                    reach, lists[0], g_lo[0], g_hi[0])
        c0 = b0
        while c0 < s1:
            # the bins of one coarse cube
            ckey = keys[order[bstart[c0]]] // cell_count
            c1 = c0
            while c1 < s1 and keys[order[bstart[c1]]] // cell_count == ckey:
                c1 += 1
            gx, gy, gz, grad = _group_sphere(sph, bstart, c0, c1)
            delta = math.sqrt((gx - sx) ** 2 + (gy - sy) ** 2 + (gz - sz) ** 2)
            nc = _level(lists[0], g_lo[0], g_hi[0], ns, delta, gx, gy, gz, grad, p0, d, w,
                        lo, hi, c, r, top, reach, lists[1], g_lo[1], g_hi[1])
            for b in range(c0, c1):
                if direct and bstart[b + 1] - bstart[b] == 1:
                    i = idx[order[bstart[b]]]
                    x, y, z = points[i, 0], points[i, 1], points[i, 2]
                    db = math.sqrt((x - gx) ** 2 + (y - gy) ** 2 + (z - gz) ** 2)
                    margins[i] = _point_margin(x, y, z, lists[1], g_lo[1], nc, db, p0, d, w,
                                               lo, hi, c, r, top, reach)
                    offsets[b + 1] = total
                    continue
                if decide and nrec > 0 and _recent_pass(points, idx, order, bstart[b],
                                                        bstart[b + 1], recent, nrec, p0, d, w,
                                                        lo, hi, c, r, top, r + reach,
                                                        out) == 0:
                    offsets[b + 1] = total
                    continue
                bx, by, bz, brad = sph[b, 0], sph[b, 1], sph[b, 2], sph[b, 3]
                db = math.sqrt((bx - gx) ** 2 + (by - gy) ** 2 + (bz - gz) ** 2)
                k = _level(lists[1], g_lo[1], g_hi[1], nc, db, bx, by, bz, brad, p0, d, w,
                           lo, hi, c, r, top, reach, lists[2], g_lo[2], g_hi[2])
                if decide:
                    nrec = _list_pass(points, idx, order, bstart[b], bstart[b + 1], lists[2],
                                      k, recent, nrec, p0, d, w, c, r, top, r + reach, out)
                    offsets[b + 1] = total
                    continue
                # an element loop, not a slice assignment: that compiles a broadcast and
                # its error message (1.4 s on an empty cache)
                if total + k > buf.shape[0]:
                    buf = grown(buf, total, 2 * (total + k))
                for t in range(k):
                    buf[total + t] = lists[2, t]
                total += k
                offsets[b + 1] = total
            c0 = c1
        b0 = s1
    return bstart[:nb + 1], offsets, buf[:total], nb


@njit(cache=True)
def _hot_sweep(points, candidates, p0, d, w, c, r, top, lim, n_sweeps, n_points, enough):
    """Of the first ``n_sweeps`` sweeps (callers order them nearest first), the one
    holding the most of ``n_points`` candidates spread over them (every ``stride``-th
    candidate; fewer where there are fewer), or -1 where none holds any: in finishing,
    the moves just behind the tool hold most of it, the pass before much of the rest.
    With ``enough`` > 0 the first sweep to hold that many of them is taken at once
    (``enough = 1``: the first to hold one, the sampled points in order)."""
    n = points.shape[0]
    ns = min(p0.shape[0], n_sweeps)
    count = np.zeros(max(ns, 1), dtype=np.int64)
    left = 0
    for i in range(n):
        if candidates[i]:
            left += 1
    want = max(n_points, 1)
    stride = max(1, (left + want - 1) // want)
    seen = -1
    for i in range(n):
        if not candidates[i]:
            continue
        seen += 1
        if seen % stride:
            continue
        for j in range(ns):
            if sweep_within(points[i, 0], points[i, 1], points[i, 2], p0[j], d[j], w[j], c, r,
                            top, lim):
                count[j] += 1
                if enough > 0 and count[j] >= enough:
                    return j
    best = -1
    most = 0
    for j in range(ns):
        if count[j] > most:
            most = count[j]
            best = j
    return best


@njit(cache=True)
def inside_any_sweep_clustered(points, candidates, p0, d, w, lo, hi, c, r, top, eps, cell):
    """:func:`inside_any_sweep`, pruning sweeps per cluster of nearby points.

    Points are binned into cubes of side ``cell`` [mm]. For each bin, a sweep
    can only contain one of its points if the swept core passes within
    ``r + eps + bin radius`` of the bin's centre (triangle inequality), so the
    exact test runs against that short list only. Same result as
    :func:`inside_any_sweep`, much faster when many sweeps are near but few
    reach the points (finishing: the neighbouring passes). Against at most
    ``FEW_SWEEPS`` sweeps, each point is tested against each (no binning).
    """
    k = points.shape[0]
    out = np.zeros(k, dtype=np.bool_)
    if k == 0 or p0.shape[0] == 0:
        return out
    lim = r + eps
    if p0.shape[0] <= FEW_SWEEPS:
        # a few sweeps (the move the tool is on, past the sweeps' height map): each point
        # against each, in the order given; binning and its short lists cost more
        for i in range(k):
            if not candidates[i]:
                continue
            x, y, z = points[i, 0], points[i, 1], points[i, 2]
            for j in range(p0.shape[0]):
                if _in_box(j, x, y, z, eps, lo, hi) and sweep_within(x, y, z, p0[j], d[j],
                                                                      w[j], c, r, top, lim):
                    out[i] = True
                    break
        return out
    # first, every point against a few sweeps that hold many (:func:`_hot_sweep`, one
    # a round, from the points left): only the others are binned
    rest = candidates.copy()
    if c == 0.0:
        rounds, n_sweeps = HOT_ROUNDS_BALL, HOT_SEED_SWEEPS_BALL
        n_points = HOT_SEED_POINTS_BALL
    else:
        rounds, n_sweeps, n_points = HOT_ROUNDS, HOT_SEED_SWEEPS, HOT_SEED_POINTS
    # (typed, not literal ints: numba compiles a callee once per literal it is given, and
    # sweep_margin_clustered's call below is then the same specialization)
    none = np.int64(0)
    for _round in range(rounds):
        hot = _hot_sweep(points, rest, p0, d, w, c, r, top, lim, n_sweeps, n_points, none)
        if hot < 0:
            break
        for i in range(k):
            if rest[i] and sweep_within(points[i, 0], points[i, 1], points[i, 2], p0[hot],
                                        d[hot], w[hot], c, r, top, lim):
                out[i] = True
                rest[i] = False
    idx, order, keys, m = _bins(points, rest, cell)
    if m == 0:
        return out
    _shortlists(points, idx, order, keys, m, p0, d, w, lo, hi, c, r, top, eps, out,
                np.zeros(0))
    return out


@njit(cache=True)
def sweep_margin_clustered(points, candidates, p0, d, w, lo, hi, c, r, top, floor, cell):
    """How far each point lies outside all sweeps, ``min_j dist_j - r`` [mm].

    Negative inside a sweep. The value is clipped to ``[floor, -floor]``
    (``floor`` < 0): a point deeper inside than ``-floor`` is decided and the
    search stops there, and sweeps that cannot come closer than ``-floor``
    are pruned, so points farther out than that read ``-floor``. Points not
    in ``candidates`` get ``floor``. Uses the same per-bin pruning as
    :func:`inside_any_sweep_clustered`.
    """
    k = points.shape[0]
    out = np.full(k, floor)
    if k == 0:
        return out
    # first, every point against one sweep many lie deep inside (:func:`_hot_sweep`):
    # those read ``floor``; only the others are binned
    rest = candidates.copy()
    # (the first of them to hold one of a few points, as before the membership test's
    # rounds: those were measured on membership calls only)
    hot = _hot_sweep(points, candidates, p0, d, w, c, r, top, r + floor,
                     np.int64(HOT_SEED_SWEEPS), np.int64(MARGIN_SEED_POINTS), np.int64(1))
    if hot >= 0:
        for i in range(k):
            if candidates[i] and sweep_distance(points[i, 0], points[i, 1], points[i, 2],
                                                p0[hot], d[hot], w[hot], c, r, top) - r <= floor:
                rest[i] = False
    idx, order, keys, m = _bins(points, rest, cell)
    if m == 0:
        return out
    starts, offsets, lists, nb = _shortlists(points, idx, order, keys, m, p0, d, w, lo, hi,
                                             c, r, top, -floor, np.zeros(0, dtype=np.bool_),
                                             out)
    for b in range(nb):
        if starts[b + 1] - starts[b] == 1:
            continue  # its margin came with the lists
        for t in range(starts[b], starts[b + 1]):
            i = idx[order[t]]
            x, y, z = points[i, 0], points[i, 1], points[i, 2]
            best = 1e300
            first = offsets[b]
            for q in range(first, offsets[b + 1]):
                j = lists[q]
                if c != 0.0 and (sweep_lower_bound(x, y, z, p0[j], d[j], w[j], c, r, top) - r
                                 >= min(best, -floor)):
                    continue  # cannot lower the margin (the search would not go below it)
                v = sweep_distance(x, y, z, p0[j], d[j], w[j], c, r, top) - r
                if v < best:
                    best = v
                    if best <= floor:
                        # deep inside this sweep: the bin's next points likely too
                        lists[q] = lists[first]
                        lists[first] = j
                        break
            if best < floor:
                best = floor
            elif best > -floor:
                best = -floor
            out[i] = best
    return out
