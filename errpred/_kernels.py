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

All kernels take plain float64 arrays so they run without the GIL. The same
tests for many points at once, pruned per cluster of points, are in
``_cluster_kernels.py``; the stock's depth-interval test in
``_interval_kernels.py``.

The helpers that take only scalars (``_core_dist``, ``_dist_half_strip``,
``_golden``, ``_strip_bound``, ``_split_bound``) are inlined by LLVM
(``forceinline``); the wrappers given array rows (``sweep_distance``,
``sweep_within``, ``sweep_lower_bound``, ``_in_box``, ``_reach_bound``) by numba
(``inline="always"``): forced into LLVM's inlining, a ball's exact test of every point
was 3 times slower (the rows' views, likely). Numba's inlining of the
helpers too copied them into every call site and ran its passes there again: 33 s of
the prediction's 82 s of compiling on an empty cache (``docs/architecture.md``, "A
numba kernel").
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["inside_any_sweep", "sweep_distance", "sweep_lower_bound", "sweep_within",
           "sweeps_within", "GOLDEN_ITERATIONS"]

#: Golden-section iterations for non-ball tools: the bracket shrinks to
#: 0.618^40 = 4e-9 of the segment, far below any micrometre.
GOLDEN_ITERATIONS = 40
_INV_PHI = (math.sqrt(5.0) - 1.0) / 2.0


@njit(cache=True, forceinline=True)
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


@njit(cache=True, forceinline=True)
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


@njit(cache=True, forceinline=True)
def _golden(x, y, z, px, py, pz, dx, dy, dz, wx, wy, wz, c, r, top, lim):
    """Golden-section search over s of the core distance of (x, y, z) - s d: the
    smaller of its last two values, or the first value within ``lim`` (``-inf``:
    never stops early; the search keeps its best value, so the final one would be
    within ``lim`` too). The sweep as scalars (see :func:`_search_distance`)."""
    lo, hi = 0.0, 1.0
    m1 = hi - _INV_PHI * (hi - lo)
    m2 = lo + _INV_PHI * (hi - lo)
    f1 = _core_dist(x - m1 * dx, y - m1 * dy, z - m1 * dz, px, py, pz,
                    wx, wy, wz, c, r, top)
    f2 = _core_dist(x - m2 * dx, y - m2 * dy, z - m2 * dz, px, py, pz,
                    wx, wy, wz, c, r, top)
    if f1 <= lim:
        return f1
    if f2 <= lim:
        return f2
    for _ in range(GOLDEN_ITERATIONS):
        if f1 <= f2:
            hi = m2
            m2, f2 = m1, f1
            m1 = hi - _INV_PHI * (hi - lo)
            f1 = _core_dist(x - m1 * dx, y - m1 * dy, z - m1 * dz, px, py, pz,
                            wx, wy, wz, c, r, top)
            if f1 <= lim:
                return f1
        else:
            lo = m1
            m1, f1 = m2, f2
            m2 = lo + _INV_PHI * (hi - lo)
            f2 = _core_dist(x - m2 * dx, y - m2 * dy, z - m2 * dz, px, py, pz,
                            wx, wy, wz, c, r, top)
            if f2 <= lim:
                return f2
    return f1 if f1 < f2 else f2


@njit(cache=True, inline="always")
def sweep_distance(x, y, z, p0, d, w, c, r, top):
    """Distance from a point to the swept core of one sweep [mm].

    Inlined where a kernel calls it (numba's ``inline="always"``): a ball end mill's
    closed form costs less than the call (measured, the exact tests of a 5-axis
    prediction: 8 times faster inlined); other tools' search stays one call
    (:func:`_search_distance`).

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
    return _search_distance(x, y, z, p0[0], p0[1], p0[2], d[0], d[1], d[2], w[0], w[1],
                            w[2], c, r, top)


@njit(cache=True)
def _search_distance(x, y, z, px, py, pz, dx, dy, dz, wx, wy, wz, c, r, top):
    """:func:`sweep_distance` of a tool with ``c > 0``: golden-section search and the
    two ends. The sweep as scalars (tip, displacement, axis): numba types an array
    argument as read-only or writable according to the caller's array, so array
    arguments compiled this once for errpred's read-only sweeps and again for orient's,
    built writable inside its kernels."""
    best = _golden(x, y, z, px, py, pz, dx, dy, dz, wx, wy, wz, c, r, top, -math.inf)
    # the ends are candidates too (the minimum may sit at s = 0 or 1)
    e0 = _core_dist(x, y, z, px, py, pz, wx, wy, wz, c, r, top)
    e1 = _core_dist(x - dx, y - dy, z - dz, px, py, pz, wx, wy, wz, c, r, top)
    if e0 < best:
        best = e0
    if e1 < best:
        best = e1
    return best


@njit(cache=True, forceinline=True)
def _strip_bound(x, y, z, px, py, pz, dx, dy, dz, wx, wy, wz, c, r, top):
    """The distance from (x, y, z) to the swept axis strip minus ``c`` [mm]: a lower
    bound of the distance to the swept core (the core lies within ``c`` of its axis
    segment), exact for ball end mills (``c = 0``); 1-Lipschitz in the point."""
    return _dist_half_strip(x - (px + r * wx), y - (py + r * wy), z - (pz + r * wz), dx, dy,
                            dz, wx, wy, wz, top - r) - c


@njit(cache=True, forceinline=True)
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


@njit(cache=True, inline="always")
def sweep_lower_bound(x, y, z, p0, d, w, c, r, top):
    """A lower bound of :func:`sweep_distance` [mm], closed form.

    Inlined where a kernel calls it, as :func:`sweep_distance` is: the margins call it
    per point and sweep with rows of the sweep arrays, which a call that is not inlined
    makes views, whose reference counts cost more than the bound (the margins of 300
    finished surfaces of the wall-radius program: 226 ms called, 124 ms inlined).

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


@njit(cache=True, inline="always")
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
    return _search_within(x, y, z, p0[0], p0[1], p0[2], d[0], d[1], d[2], w[0], w[1], w[2],
                          c, r, top, lim)


@njit(cache=True)
def _search_within(x, y, z, px, py, pz, dx, dy, dz, wx, wy, wz, c, r, top, lim):
    """:func:`sweep_within` of a tool with ``c > 0``. The sweep as scalars (tip,
    displacement, axis), as :func:`_search_distance` takes it: an array row given to
    a kernel that is not inlined is made a view, and the view and its reference count
    cost more than the test (a flat end mill's membership tests of the flower mold's
    slice, 2.9 million against the nearest sweep: 342 ms with rows, 78 ms with scalars);
    one compiled version for read-only and writable sweeps alike."""
    if _core_dist(x, y, z, px, py, pz, wx, wy, wz, c, r, top) <= lim:
        return True
    if _core_dist(x - dx, y - dy, z - dz, px, py, pz, wx, wy, wz, c, r, top) <= lim:
        return True
    # :func:`sweep_lower_bound` above ``lim`` (the larger of its two bounds), its
    # split bound computed once and kept for the square-move answer
    if _strip_bound(x, y, z, px, py, pz, dx, dy, dz, wx, wy, wz, c, r, top) > lim:
        return False
    bound, exact = _split_bound(x, y, z, px, py, pz, dx, dy, dz, wx, wy, wz, c, r, top)
    if bound > lim:
        return False
    if exact:
        return True  # a move square to the axis: the bound, within lim, is the distance
    return _golden(x, y, z, px, py, pz, dx, dy, dz, wx, wy, wz, c, r, top, lim) <= lim


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
