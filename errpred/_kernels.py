"""Numba kernels: is a point inside the volume a tool swept along a straight move?

A tool solid is the set of points within ``r`` (corner radius) of its
*core* ``C = {rho <= R - r, r <= z <= L}`` (tool frame; see
``errpred/tool.py``), ``L`` the flute length: above it the shank does not
cut, so material there is not removed. Moving the tool along a segment
``d`` with a constant axis ``w`` sweeps the set of points within ``r`` of
``C + [0, 1] d``. So a point ``q`` is inside the sweep when
``min_s dist(q - s d, C) <= r``; the distance is convex in ``s``.

* Ball end mill (``R - r = 0``): the core is a half-line (the ball centre and
  up the axis); the swept core is a planar half-strip and the distance has a
  closed form (:func:`_dist_half_strip`).
* Radius and flat end mills: golden-section search over ``s`` of the
  closed-form distance to the half-cylinder core.

All kernels take plain float64 arrays so they run without the GIL.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .constants import (CLUSTER_COARSE, CLUSTER_RECENT, CLUSTER_SUPER, HOT_SEED_POINTS,
                        HOT_SEED_SWEEPS)

__all__ = ["inside_any_sweep", "sweep_distance", "sweeps_within", "interval_membership",
           "cells_smooth", "GOLDEN_ITERATIONS"]

#: Golden-section iterations for non-ball tools: the bracket shrinks to
#: 0.618^40 = 4e-9 of the segment, far below any micrometre.
GOLDEN_ITERATIONS = 40
_INV_PHI = (math.sqrt(5.0) - 1.0) / 2.0


@njit(cache=True, inline="always")
def _core_dist(x, y, z, px, py, pz, wx, wy, wz, c, r, top):
    """Distance from (x,y,z) to the core of a tool with tip p, axis w, flute top."""
    vx, vy, vz = x - px, y - py, z - pz
    h = vx * wx + vy * wy + vz * wz
    ex, ey, ez = vx - h * wx, vy - h * wy, vz - h * wz
    rho = math.sqrt(ex * ex + ey * ey + ez * ez)
    dr = rho - c
    if dr < 0.0:
        dr = 0.0
    dz = r - h
    if dz < 0.0:
        dz = h - top
        if dz < 0.0:
            dz = 0.0
    return math.sqrt(dr * dr + dz * dz)


@njit(cache=True, inline="always")
def _dist_half_strip(ax, ay, az, dx, dy, dz, wx, wy, wz, lmax):
    """Distance from a to {s d + l w : 0 <= s <= 1, 0 <= l <= lmax} (|w| = 1)."""
    dd = dx * dx + dy * dy + dz * dz
    dw = dx * wx + dy * wy + dz * wz
    ad = ax * dx + ay * dy + az * dz
    aw = ax * wx + ay * wy + az * wz
    best = 1e300
    # interior of the strip
    det = dd - dw * dw
    if det > 1e-14 * (dd + 1e-300):
        s = (ad - dw * aw) / det
        lam = (dd * aw - dw * ad) / det
        if 0.0 <= s <= 1.0 and 0.0 <= lam <= lmax:
            qx, qy, qz = ax - s * dx - lam * wx, ay - s * dy - lam * wy, az - s * dz - lam * wz
            return math.sqrt(qx * qx + qy * qy + qz * qz)
    # edge s = 0: the axis segment from the start centre up
    lam = aw if aw > 0.0 else 0.0
    if lam > lmax:
        lam = lmax
    qx, qy, qz = ax - lam * wx, ay - lam * wy, az - lam * wz
    v = qx * qx + qy * qy + qz * qz
    if v < best:
        best = v
    # edge s = 1: from the end centre
    bx, by, bz = ax - dx, ay - dy, az - dz
    bw = bx * wx + by * wy + bz * wz
    lam = bw if bw > 0.0 else 0.0
    if lam > lmax:
        lam = lmax
    qx, qy, qz = bx - lam * wx, by - lam * wy, bz - lam * wz
    v = qx * qx + qy * qy + qz * qz
    if v < best:
        best = v
    # edge l = 0: the segment of centres
    if dd > 0.0:
        s = ad / dd
        if s < 0.0:
            s = 0.0
        elif s > 1.0:
            s = 1.0
        qx, qy, qz = ax - s * dx, ay - s * dy, az - s * dz
        v = qx * qx + qy * qy + qz * qz
        if v < best:
            best = v
        # edge l = lmax: the segment of the flute tops
        tx, ty, tz = ax - lmax * wx, ay - lmax * wy, az - lmax * wz
        s = (tx * dx + ty * dy + tz * dz) / dd
        if s < 0.0:
            s = 0.0
        elif s > 1.0:
            s = 1.0
        qx, qy, qz = tx - s * dx, ty - s * dy, tz - s * dz
        v = qx * qx + qy * qy + qz * qz
        if v < best:
            best = v
    return math.sqrt(best)


@njit(cache=True, inline="always")
def _golden(x, y, z, p0, d, w, c, r, top, lim):
    """Golden-section search over s of the core distance of (x, y, z) - s d: the
    smaller of its last two values, or the first value within ``lim`` (``-inf``:
    never stops early; the search keeps its best value, so the final one would be
    within ``lim`` too)."""
    lo, hi = 0.0, 1.0
    m1 = hi - _INV_PHI * (hi - lo)
    m2 = lo + _INV_PHI * (hi - lo)
    f1 = _core_dist(x - m1 * d[0], y - m1 * d[1], z - m1 * d[2], p0[0], p0[1], p0[2],
                    w[0], w[1], w[2], c, r, top)
    f2 = _core_dist(x - m2 * d[0], y - m2 * d[1], z - m2 * d[2], p0[0], p0[1], p0[2],
                    w[0], w[1], w[2], c, r, top)
    if f1 <= lim:
        return f1
    if f2 <= lim:
        return f2
    for _ in range(GOLDEN_ITERATIONS):
        if f1 <= f2:
            hi = m2
            m2, f2 = m1, f1
            m1 = hi - _INV_PHI * (hi - lo)
            f1 = _core_dist(x - m1 * d[0], y - m1 * d[1], z - m1 * d[2], p0[0], p0[1], p0[2],
                            w[0], w[1], w[2], c, r, top)
            if f1 <= lim:
                return f1
        else:
            lo = m1
            m1, f1 = m2, f2
            m2 = lo + _INV_PHI * (hi - lo)
            f2 = _core_dist(x - m2 * d[0], y - m2 * d[1], z - m2 * d[2], p0[0], p0[1], p0[2],
                            w[0], w[1], w[2], c, r, top)
            if f2 <= lim:
                return f2
    return f1 if f1 < f2 else f2


@njit(cache=True)
def sweep_distance(x, y, z, p0, d, w, c, r, top):
    """Distance from a point to the swept core of one sweep [mm].

    Parameters
    ----------
    x, y, z : float [mm]
    p0, d, w : ndarray, shape (3,)
        Tip at the start [mm], tip displacement [mm], unit axis.
    c, r : float [mm]
        Core radius ``R - r`` and corner radius ``r``.
    top : float [mm]
        Flute length: the core's top above the tip.
    """
    if c == 0.0:
        return _dist_half_strip(x - (p0[0] + r * w[0]), y - (p0[1] + r * w[1]),
                                z - (p0[2] + r * w[2]), d[0], d[1], d[2], w[0], w[1], w[2],
                                top - r)
    best = _golden(x, y, z, p0, d, w, c, r, top, -math.inf)
    # the ends are candidates too (the minimum may sit at s = 0 or 1)
    e0 = _core_dist(x, y, z, p0[0], p0[1], p0[2], w[0], w[1], w[2], c, r, top)
    e1 = _core_dist(x - d[0], y - d[1], z - d[2], p0[0], p0[1], p0[2], w[0], w[1], w[2], c, r, top)
    if e0 < best:
        best = e0
    if e1 < best:
        best = e1
    return best


@njit(cache=True, inline="always")
def _strip_bound(x, y, z, px, py, pz, dx, dy, dz, wx, wy, wz, c, r, top):
    """The distance from (x, y, z) to the swept axis strip minus ``c`` [mm]: a lower
    bound of the distance to the swept core (the core lies within ``c`` of its axis
    segment), exact for ball end mills (``c = 0``); 1-Lipschitz in the point."""
    return _dist_half_strip(x - (px + r * wx), y - (py + r * wy), z - (pz + r * wz), dx, dy,
                            dz, wx, wy, wz, top - r) - c


@njit(cache=True, inline="always")
def _split_bound(x, y, z, px, py, pz, dx, dy, dz, wx, wy, wz, c, r, top):
    """``(bound, exact)``: a lower bound of the distance from (x, y, z) to the swept
    core of a tool with ``c > 0``, and whether it is the distance itself.

    In the sweep's frame the distance at ``s`` is ``sqrt(A(s)^2 + B(s)^2)``, ``A``
    radial (beyond ``c``) and ``B`` axial (outside ``[r, top]``), so it is at least
    ``sqrt(min A^2 + min B^2)``, both minima closed form; where the move is square
    to the axis ``B`` is constant and the bound is the distance.
    """
    vx, vy, vz = x - px, y - py, z - pz
    h0 = vx * wx + vy * wy + vz * wz
    dw = dx * wx + dy * wy + dz * wz
    ex, ey, ez = vx - h0 * wx, vy - h0 * wy, vz - h0 * wz
    qx, qy, qz = dx - dw * wx, dy - dw * wy, dz - dw * wz
    qq = qx * qx + qy * qy + qz * qz
    t = 0.0
    if qq > 0.0:
        t = (ex * qx + ey * qy + ez * qz) / qq
        if t < 0.0:
            t = 0.0
        elif t > 1.0:
            t = 1.0
    fx, fy, fz = ex - t * qx, ey - t * qy, ez - t * qz
    a = math.sqrt(fx * fx + fy * fy + fz * fz) - c
    if a < 0.0:
        a = 0.0
    h1 = h0 - dw
    hlo = h0 if h0 < h1 else h1
    hhi = h0 if h0 > h1 else h1
    b = 0.0
    if hhi < r:
        b = r - hhi
    elif hlo > top:
        b = hlo - top
    return math.sqrt(a * a + b * b), dw == 0.0


@njit(cache=True)
def sweep_lower_bound(x, y, z, p0, d, w, c, r, top):
    """A lower bound of :func:`sweep_distance` [mm], closed form.

    The core lies within ``c`` of its axis segment, so the distance to the
    swept core is at least the distance to the swept axis strip minus ``c``
    (exact for ball end mills, ``c = 0``); for ``c > 0`` also at least the
    radial and axial parts' separate minima (:func:`_split_bound`): the larger
    of the two.
    """
    lb = _strip_bound(x, y, z, p0[0], p0[1], p0[2], d[0], d[1], d[2], w[0], w[1], w[2], c,
                      r, top)
    if c != 0.0:
        lb2 = _split_bound(x, y, z, p0[0], p0[1], p0[2], d[0], d[1], d[2], w[0], w[1], w[2],
                           c, r, top)[0]
        if lb2 > lb:
            lb = lb2
    return lb


@njit(cache=True)
def sweep_within(x, y, z, p0, d, w, c, r, top, lim):
    """``sweep_distance(...) <= lim``, with early answers.

    The same answer, but where the distance is within rounding (~1e-15 mm) of
    ``lim`` and the lower bound is tight.

    Ball end mills: the closed form. Others: a cutter location at either end
    within ``lim`` answers yes; the closed-form lower bound
    (:func:`sweep_lower_bound`) above ``lim`` answers no; a move square to the
    axis is answered by the closed form (:func:`_split_bound`, the distance
    there); otherwise the same
    golden-section search as :func:`sweep_distance`, stopping at the first
    value within ``lim`` (the search keeps its best value, so the final
    minimum would be within ``lim`` too).
    """
    if c == 0.0:
        return sweep_distance(x, y, z, p0, d, w, c, r, top) <= lim
    if _core_dist(x, y, z, p0[0], p0[1], p0[2], w[0], w[1], w[2], c, r, top) <= lim:
        return True
    if _core_dist(x - d[0], y - d[1], z - d[2], p0[0], p0[1], p0[2], w[0], w[1], w[2], c, r,
                  top) <= lim:
        return True
    # :func:`sweep_lower_bound` above ``lim`` (the larger of its two bounds), its
    # split bound computed once and kept for the square-move answer
    if _strip_bound(x, y, z, p0[0], p0[1], p0[2], d[0], d[1], d[2], w[0], w[1], w[2], c, r,
                    top) > lim:
        return False
    bound, exact = _split_bound(x, y, z, p0[0], p0[1], p0[2], d[0], d[1], d[2], w[0], w[1],
                                w[2], c, r, top)
    if bound > lim:
        return False
    if exact:
        return True  # a move square to the axis: the bound, within lim, is the distance
    return _golden(x, y, z, p0, d, w, c, r, top, lim) <= lim


@njit(cache=True, parallel=False)
def inside_any_sweep(points, candidates, p0, d, w, lo, hi, c, r, top, eps):
    """For each point: is it inside any of the sweeps?

    Parameters
    ----------
    points : ndarray, shape (k, 3) [mm]
    candidates : ndarray, shape (k,), bool
        Only these points are tested; the others come back False.
    p0, d, w : ndarray, shape (n, 3)
        Sweeps: start tip [mm], displacement [mm], unit axis. Test order is
        array order: put the likeliest containers first.
    lo, hi : ndarray, shape (n, 3) [mm]
        Axis-aligned bounds of each sweep (for a cheap first rejection).
    c, r, top : float [mm]
        Core radius, corner radius and flute length of the tool.
    eps : float [mm]
        A point this close to a sweep's boundary counts as inside.

    Returns
    -------
    ndarray, shape (k,), bool
    """
    k = points.shape[0]
    n = p0.shape[0]
    out = np.zeros(k, dtype=np.bool_)
    lim = r + eps
    for i in range(k):
        if not candidates[i]:
            continue
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        for j in range(n):
            if (x < lo[j, 0] or x > hi[j, 0] or y < lo[j, 1] or y > hi[j, 1]
                    or z < lo[j, 2] or z > hi[j, 2]):
                continue
            if sweep_within(x, y, z, p0[j], d[j], w[j], c, r, top, lim):
                out[i] = True
                break
    return out


@njit(cache=True)
def _sphere(points, idx, order, s, e):
    """Centre and radius of the bounding sphere of points idx[order[s:e]]."""
    cx = cy = cz = 0.0
    for t in range(s, e):
        i = idx[order[t]]
        cx += points[i, 0]
        cy += points[i, 1]
        cz += points[i, 2]
    cnt = e - s
    cx /= cnt
    cy /= cnt
    cz /= cnt
    rad = 0.0
    for t in range(s, e):
        i = idx[order[t]]
        dx, dy, dz = points[i, 0] - cx, points[i, 1] - cy, points[i, 2] - cz
        v = math.sqrt(dx * dx + dy * dy + dz * dz)
        if v > rad:
            rad = v
    return cx, cy, cz, rad


@njit(cache=True, inline="always")
def _in_box(j, cx, cy, cz, reach, lo, hi):
    """Does the ball of radius ``reach`` around (cx, cy, cz) meet sweep j's bounds?"""
    return not (cx + reach < lo[j, 0] or cx - reach > hi[j, 0] or cy + reach < lo[j, 1]
                or cy - reach > hi[j, 1] or cz + reach < lo[j, 2] or cz - reach > hi[j, 2])


@njit(cache=True, inline="always")
def _reach_bound(j, cx, cy, cz, p0, d, w, c, r, top, lim):
    """A lower bound of the distance from (cx, cy, cz) to sweep j's swept core [mm]:
    the swept axis strip's minus ``c`` (exact for ball end mills), for ``c > 0`` the
    larger of that and :func:`_split_bound`, computed only where the first is within
    ``lim``. 1-Lipschitz in the point (both are)."""
    lb = _strip_bound(cx, cy, cz, p0[j, 0], p0[j, 1], p0[j, 2], d[j, 0], d[j, 1], d[j, 2],
                      w[j, 0], w[j, 1], w[j, 2], c, r, top)
    if lb > lim or c == 0.0:
        return lb
    lb2 = _split_bound(cx, cy, cz, p0[j, 0], p0[j, 1], p0[j, 2], d[j, 0], d[j, 1], d[j, 2],
                       w[j, 0], w[j, 1], w[j, 2], c, r, top)[0]
    return lb2 if lb2 > lb else lb


@njit(cache=True)
def _may_reach(j, cx, cy, cz, reach, p0, d, w, lo, hi, c, r, top):
    """Can sweep j come within ``reach`` of the point (cx, cy, cz)?

    Axis-aligned bounds first, then a lower bound of the distance: the swept
    core lies within ``c`` of the swept axis strip (exact for ball end mills);
    for ``c > 0`` then the radial and axial parts' minima (:func:`_split_bound`).
    """
    if not _in_box(j, cx, cy, cz, reach, lo, hi):
        return False
    return _reach_bound(j, cx, cy, cz, p0, d, w, c, r, top, r + reach) <= r + reach


@njit(cache=True)
def sweeps_within(ids, cx, cy, cz, reach, p0, d, w, lo, hi, c, r, top):
    """Those of sweeps ``ids`` that may come within ``reach`` of the point (cx, cy, cz).

    The same test as the per-bin pruning of :func:`inside_any_sweep_clustered`
    (bounds, then a lower bound of the distance to the swept solid), done once
    for a ball around everything a prediction point will test: a sweep left
    out cannot contain, nor come within ``reach`` minus the ball's radius of,
    any point in the ball.

    Parameters
    ----------
    ids : ndarray, shape (k,), int
        Candidate sweeps (indices into the sweep arrays).
    cx, cy, cz : float [mm]
    reach : float [mm]
    p0, d, w, lo, hi : ndarray, shape (n, 3)
    c, r, top : float [mm]

    Returns
    -------
    ndarray, shape (k,), bool
    """
    out = np.zeros(ids.shape[0], dtype=np.bool_)
    for t in range(ids.shape[0]):
        out[t] = _may_reach(ids[t], cx, cy, cz, reach, p0, d, w, lo, hi, c, r, top)
    return out


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
    big = 1 << 14  # super cubes either side of the origin (cell 0.2 mm: 105 m)
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
    order = np.argsort(keys[:m])
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


@njit(cache=True)
def _shortlists(points, idx, order, keys, m, p0, d, w, lo, hi, c, r, top, reach, out,
                decide):
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

    With ``decide``, membership is decided here and the lists are not kept (every
    bin's comes back empty): each bin's points go first against the sweeps that
    held points of the bins before (``CLUSTER_RECENT`` of them, :func:`_recent_pass`),
    and only a bin with a point none of them holds gets its list and the exact
    tests (:func:`_list_pass`); ``out`` (bool, one per point) is set where a
    point lies inside a sweep (within ``r + reach`` of its core). The same
    answers: a point is inside when a sweep holds it, whichever sweep that is.
    """
    n = p0.shape[0]
    cx, cy, cz, rad = _sphere(points, idx, order, 0, m)
    near = np.empty(n, dtype=np.int64)
    g1 = np.empty(n)
    nn = 0
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
    nrec = 0
    b0 = 0
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
                if total + k > buf.shape[0]:
                    bigger = np.empty(2 * (total + k), dtype=np.int64)
                    bigger[:total] = buf[:total]
                    buf = bigger
                buf[total:total + k] = lists[2, :k]
                total += k
                offsets[b + 1] = total
            c0 = c1
        b0 = s1
    return bstart[:nb + 1], offsets, buf[:total], nb


@njit(cache=True)
def _hot_sweep(points, candidates, p0, d, w, c, r, top, lim):
    """A sweep likely to hold many of the points within ``lim`` of its core, or -1.

    The first of the first ``HOT_SEED_SWEEPS`` sweeps (callers order them
    nearest first) to hold one of the first ``HOT_SEED_POINTS`` candidates: in
    finishing, the move just behind the tool holds most of the tool.
    """
    tried = 0
    for i in range(points.shape[0]):
        if not candidates[i]:
            continue
        if tried >= HOT_SEED_POINTS:
            break
        tried += 1
        for j in range(min(p0.shape[0], HOT_SEED_SWEEPS)):
            if sweep_within(points[i, 0], points[i, 1], points[i, 2], p0[j], d[j], w[j], c, r,
                            top, lim):
                return j
    return -1


@njit(cache=True)
def inside_any_sweep_clustered(points, candidates, p0, d, w, lo, hi, c, r, top, eps, cell):
    """:func:`inside_any_sweep`, pruning sweeps per cluster of nearby points.

    Points are binned into cubes of side ``cell`` [mm]. For each bin, a sweep
    can only contain one of its points if the swept core passes within
    ``r + eps + bin radius`` of the bin's centre (triangle inequality), so the
    exact test runs against that short list only. Same result as
    :func:`inside_any_sweep`, much faster when many sweeps are near but few
    reach the points (finishing: the neighbouring passes).
    """
    k = points.shape[0]
    out = np.zeros(k, dtype=np.bool_)
    if k == 0 or p0.shape[0] == 0:
        return out
    lim = r + eps
    # first, every point against one sweep that holds many (:func:`_hot_sweep`): only
    # the others are binned
    rest = candidates.copy()
    hot = _hot_sweep(points, candidates, p0, d, w, c, r, top, lim)
    if hot >= 0:
        for i in range(k):
            if candidates[i] and sweep_within(points[i, 0], points[i, 1], points[i, 2], p0[hot],
                                              d[hot], w[hot], c, r, top, lim):
                out[i] = True
                rest[i] = False
    idx, order, keys, m = _bins(points, rest, cell)
    if m == 0:
        return out
    _shortlists(points, idx, order, keys, m, p0, d, w, lo, hi, c, r, top, eps, out, True)
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
    hot = _hot_sweep(points, candidates, p0, d, w, c, r, top, r + floor)
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
                                             False)
    for b in range(nb):
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


@njit(cache=True, inline="always")
def _bilinear(a, i0, j0, tx, ty):
    v00, v01 = a[i0, j0], a[i0, j0 + 1]
    v10, v11 = a[i0 + 1, j0], a[i0 + 1, j0 + 1]
    out = (1 - ty) * ((1 - tx) * v00 + tx * v01) + ty * ((1 - tx) * v10 + tx * v11)
    if math.isnan(out):
        return v00  # all-same infinities
    return out


@njit(cache=True)
def interval_membership(xyz, top, bottom, smooth_top, smooth_bottom, pixel, depth_offset, eps):
    """Stock membership of tool-frame points from a view's material interval.

    The interval (``bottom``, ``top`` depths per pixel centre, (n, n)) is
    interpolated bilinearly between the four centres around each point;
    points in a cell that is not smooth on both sides (a steep wall, a
    silhouette) are marked unsure, for the mesh to decide
    (:meth:`errpred.bottomview.BottomTemplate.in_stock_local`).

    Parameters
    ----------
    xyz : ndarray, shape (k, 3) [mm]
        Tool-frame points (depth along the axis is ``z + depth_offset``).
    top, bottom : ndarray, shape (n, n) [mm]
    smooth_top, smooth_bottom : ndarray, shape (n - 1, n - 1), bool
    pixel, depth_offset, eps : float [mm]

    Returns
    -------
    inside, unsure : ndarray, shape (k,), bool
    """
    k = xyz.shape[0]
    n = top.shape[0]
    inside = np.zeros(k, dtype=np.bool_)
    unsure = np.zeros(k, dtype=np.bool_)
    half = 0.5 * n * pixel
    for q in range(k):
        fx = (xyz[q, 0] + half) / pixel - 0.5
        fy = (xyz[q, 1] + half) / pixel - 0.5
        j0 = min(max(int(math.floor(fx)), 0), n - 2)
        i0 = min(max(int(math.floor(fy)), 0), n - 2)
        tx = min(max(fx - j0, 0.0), 1.0)
        ty = min(max(fy - i0, 0.0), 1.0)
        depth = xyz[q, 2] + depth_offset
        t = _bilinear(top, i0, j0, tx, ty)
        b = _bilinear(bottom, i0, j0, tx, ty)
        inside[q] = (b - eps <= depth) and (depth <= t + eps)
        unsure[q] = not (smooth_top[i0, j0] and smooth_bottom[i0, j0])
    return inside, unsure


@njit(cache=True)
def cells_smooth(a, limit):
    """For each 2 x 2 cell of pixel centres: may ``a`` be interpolated there?

    True where the four values are all finite and span at most ``limit``
    [mm], or are all the same infinity (no surface there). ``a``: (n, n);
    returns (n - 1, n - 1), bool.
    """
    n0, n1 = a.shape
    out = np.zeros((n0 - 1, n1 - 1), dtype=np.bool_)
    for i in range(n0 - 1):
        for j in range(n1 - 1):
            v0, v1, v2, v3 = a[i, j], a[i + 1, j], a[i, j + 1], a[i + 1, j + 1]
            f0, f1 = math.isfinite(v0), math.isfinite(v1)
            f2, f3 = math.isfinite(v2), math.isfinite(v3)
            if f0 and f1 and f2 and f3:
                out[i, j] = max(max(v0, v1), max(v2, v3)) - min(min(v0, v1), min(v2, v3)) <= limit
            elif not (f0 or f1 or f2 or f3):
                out[i, j] = v0 == v1 and v0 == v2 and v0 == v3
    return out
