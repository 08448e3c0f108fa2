"""Numba kernels of the sweep height map (:mod:`errpred.zmap`).

A ball end mill moving along a straight move with its axis vertical (+z)
sweeps a convex solid; a vertical line meets it in one interval. The lower
end ``a(x, y)`` is the lower boundary of the *capsule* of the ball centres
(radius ``r`` around the segment of centres, :func:`capsule_low`), a convex
function of (x, y) on the capsule's shadow; the upper end lies at least the
flute length above the lower of the two tips.

Per cell of a horizontal grid the map keeps, over the sweeps inserted so far:

* **one sweep that holds the cell**: the values of its ``a`` at the cell's four
  corners (each rounded up) and its ceiling. ``a`` is convex, so inside the
  cell it lies below the bilinear interpolation of its corner values (a point
  of the cell is the convex combination of the corners with the bilinear
  weights): a point at or above that, and below the ceiling, is inside the
  sweep. Of the sweeps whose shadow holds all four corners, the one with the
  lowest mean of them.
* **bounds from below** of every sweep's ``a`` over the cell: the tangent
  planes at the cell centre of the ``PLANES`` sweeps lowest there (a convex
  function lies above its tangent planes), one plane below all the planes let
  go (two planes merge into the plane of their mean slopes lowered until it
  is below both at the four corners, so below both over the cell), and one
  number below the sweeps with no usable plane (each
  sweep's tangent plane's minimum over the cell, or, where the centre is not
  in its shadow, the capsule grown by the cell's half diagonal at the centre:
  any point of the cell is within that of the centre). A point below both is
  inside none.

Every number is a bound, so a point the map classifies is classified as the
exact test (:func:`errpred._kernels.sweep_within`, within ``r`` plus its
tolerance of the segment) would; the guard covers the rounding of both.
Corner, centre and bound values are ``inf`` where a sweep's shadow misses.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["capsule_low", "insert_sweeps", "classify", "tiles_of", "empty_tile", "FIELDS",
           "PLANES"]

#: Tangent planes kept per cell (the sweeps lowest at its centre): where passes
#: lie close in height (steep flanks of a raster), a sample below them all is
#: known only from their planes; the constant bound of the rest is a plane's
#: minimum over the cell, off by slope x cell there.
PLANES = 3
#: Per-cell values: 4 corners (x0y0, x1y0, x0y1, x1y1), ceiling, the constant
#: lower bound, the merged plane (value at the centre, two slopes), then per
#: kept plane the same three.
FIELDS = 9 + 3 * PLANES
_C00, _C10, _C01, _C11, _CEIL, _LOC, _M = range(7)
_P0 = 9
#: Relative size of the rounding allowance on the quadratics' discriminants.
_ROUND = 1e-12
#: Segments whose horizontal extent is below this share of their length are
#: treated as vertical (the cylinder's quadratic degenerates).
_STEEP = 1e-8
#: Tangent planes only where the boundary is at most this steep, ``|n_z|`` at
#: least this share of the normal, and the cylinder's quadratic well posed
#: (its leading coefficient, the squared horizontal share of the segment, at
#: least ``_PLANE_QA``): elsewhere a slope's rounding, times half a cell,
#: could exceed the guard; the constant bound is used there.
_PLANE_NZ = 0.05
_PLANE_QA = 0.01


@njit(cache=True)
def capsule_low(x, y, c0x, c0y, c0z, dx, dy, dz, rho, side):
    """Lowest z on the vertical line through (x, y) within ``rho`` of the segment
    from ``c0`` to ``c0 + d`` [mm], and the slopes of that lower boundary there:
    ``(z, dz/dx, dz/dy)``.

    ``z`` is a bound: ``side`` < 0 a lower bound, > 0 an upper bound (``inf``: the
    line misses the capsule, or may, for an upper bound). The end spheres, and the
    cylinder where its lower crossing's foot lies on the segment, each with an
    allowance for rounding on the side asked for. A segment within ``_STEEP`` of
    vertical: its ends alone for an upper bound; for a lower bound the lower
    centre minus ``rho`` wherever the line comes within reach (slopes ``nan``:
    not a tangent).
    """
    dd = dx * dx + dy * dy + dz * dz
    hh = dx * dx + dy * dy
    steep = not (dd > 0.0 and hh > _STEEP * _STEEP * dd)
    if steep and side < 0 and dd > 0.0:
        ex, ey = x - c0x, y - c0y
        if ex * ex + ey * ey > (rho + math.sqrt(hh)) ** 2:
            return math.inf, math.nan, math.nan
        return min(c0z, c0z + dz) - rho, math.nan, math.nan
    tol = _ROUND * rho * rho
    best, gx, gy = math.inf, math.nan, math.nan
    for e in range(2):
        cx = c0x + e * dx
        cy = c0y + e * dy
        cz = c0z + e * dz
        ex, ey = x - cx, y - cy
        h2 = rho * rho - ex * ex - ey * ey
        if side < 0:
            if h2 < -tol:
                continue
            h = math.sqrt(max(h2, 0.0) + tol)
        else:
            if h2 < tol:
                continue
            h = math.sqrt(h2 - tol)
        z = cz - h
        if z < best:
            if h >= _PLANE_NZ * rho:
                best, gx, gy = z, ex / h, ey / h
            else:
                best, gx, gy = z, math.nan, math.nan
    if steep:
        return best, gx, gy
    a = x - c0x
    b = y - c0y
    k = a * dx + b * dy
    qa = hh / dd
    qb = -2.0 * k * dz / dd
    qc = a * a + b * b - k * k / dd - rho * rho
    disc = qb * qb - 4.0 * qa * qc
    tol = _ROUND * (qb * qb + 4.0 * qa * abs(qc) + rho * rho)
    if side < 0:
        if disc < -tol:
            return best, gx, gy
        root = math.sqrt(max(disc, 0.0) + tol)
        lo_t, hi_t = -1e-9, 1.0 + 1e-9
    else:
        if disc < tol:
            return best, gx, gy
        root = math.sqrt(disc - tol)
        lo_t, hi_t = 1e-9, 1.0 - 1e-9
    e = (-qb - root) / (2.0 * qa)
    t = (k + e * dz) / dd
    if lo_t <= t <= hi_t:
        z = c0z + e
        if z < best:
            # the normal: from the nearest centre on the segment to the point
            nx = a - t * dx
            ny = b - t * dy
            nz = e - t * dz
            if -nz >= _PLANE_NZ * rho and qa >= _PLANE_QA:
                best, gx, gy = z, -nx / nz, -ny / nz
            else:
                best, gx, gy = z, math.nan, math.nan
    return best, gx, gy


@njit(cache=True, inline="always")
def _merge(v, z, gx, gy, half):
    """Merge the plane (z at the cell centre, slopes gx, gy) into the cell's merged
    plane: mean slopes, lowered to lie below both at the corners."""
    mz, mx, my = v[_M], v[_M + 1], v[_M + 2]
    if not math.isfinite(mz):
        v[_M], v[_M + 1], v[_M + 2] = z, gx, gy
        return
    above = True  # the new plane above the merged one at every corner: nothing to do
    under = True  # ... below it at every corner: it replaces it
    for sx in (-half, half):
        for sy in (-half, half):
            dn = (z + gx * sx + gy * sy) - (mz + mx * sx + my * sy)
            if dn < 0.0:
                above = False
            if dn > 0.0:
                under = False
    if above:
        return
    if under:
        v[_M], v[_M + 1], v[_M + 2] = z, gx, gy
        return
    nx, ny = 0.5 * (gx + mx), 0.5 * (gy + my)
    best = math.inf
    for sx in (-half, half):
        for sy in (-half, half):
            both = min(z + gx * sx + gy * sy, mz + mx * sx + my * sy)
            c = both - nx * sx - ny * sy
            if c < best:
                best = c
    v[_M], v[_M + 1], v[_M + 2] = best, nx, ny


@njit(cache=True)
def insert_sweeps(ids, p0, d, rc, lim, top, cell, size, vals, tile_index, origin):
    """Insert sweeps ``ids`` (vertical axis, ball end mill) into the allocated tiles.

    Parameters
    ----------
    ids : ndarray of int
    p0, d : ndarray, shape (n, 3) [mm]
        Tip at the start and tip displacement of every sweep.
    rc, lim, top : float [mm]
        Ball radius, the membership distance (ball radius plus tolerance) and
        the flute length.
    cell : float [mm]
    size : int
        Cells a tile side.
    vals : ndarray, shape (slots, size, size, FIELDS)
    tile_index : ndarray, shape (tx, ty), int
        Slot of each tile, -1 where none is allocated.
    origin : ndarray, shape (2,) [mm]
    """
    delta = cell * math.sqrt(0.5)
    reach = lim + delta
    half = 0.5 * cell
    tx, ty = tile_index.shape
    span = cell * size
    node = np.empty((size + 1, size + 1))
    for q in range(ids.shape[0]):
        j = ids[q]
        c0x, c0y, c0z = p0[j, 0], p0[j, 1], p0[j, 2] + rc
        dx, dy, dz = d[j, 0], d[j, 1], d[j, 2]
        ceil = min(p0[j, 2], p0[j, 2] + dz) + top
        x0 = min(c0x, c0x + dx) - reach
        x1 = max(c0x, c0x + dx) + reach
        y0 = min(c0y, c0y + dy) - reach
        y1 = max(c0y, c0y + dy) + reach
        a0 = max(int(math.floor((x0 - origin[0]) / span)), 0)
        a1 = min(int(math.floor((x1 - origin[0]) / span)), tx - 1)
        b0 = max(int(math.floor((y0 - origin[1]) / span)), 0)
        b1 = min(int(math.floor((y1 - origin[1]) / span)), ty - 1)
        for ta in range(a0, a1 + 1):
            for tb in range(b0, b1 + 1):
                s = tile_index[ta, tb]
                if s < 0:
                    continue
                bx = origin[0] + ta * span
                by = origin[1] + tb * span
                i0 = max(int(math.floor((x0 - bx) / cell)), 0)
                i1 = min(int(math.floor((x1 - bx) / cell)), size - 1)
                k0 = max(int(math.floor((y0 - by) / cell)), 0)
                k1 = min(int(math.floor((y1 - by) / cell)), size - 1)
                if i0 > i1 or k0 > k1:
                    continue
                # the lower boundary at the corner nodes, rounded up: only where the
                # sweep may hold the cell better (by convexity, the mean of the
                # corners is at least the centre's value), computed once a node
                for i in range(i0, i1 + 2):
                    for k in range(k0, k1 + 2):
                        node[i, k] = math.nan
                for i in range(i0, i1 + 1):
                    xc = bx + (i + 0.5) * cell
                    for k in range(k0, k1 + 1):
                        yc = by + (k + 0.5) * cell
                        v = vals[s, i, k]
                        # bounds from below
                        z, gx, gy = capsule_low(xc, yc, c0x, c0y, c0z, dx, dy, dz, lim, -1)
                        if math.isfinite(z) and math.isfinite(gx) and math.isfinite(gy):
                            # replace the highest kept plane if this one is lower there;
                            # the plane let go leaves its minimum over the cell
                            worst = _P0
                            for f in range(_P0 + 3, _P0 + 3 * PLANES, 3):
                                if v[f] > v[worst]:
                                    worst = f
                            if z < v[worst]:
                                oz, ox, oy = v[worst], v[worst + 1], v[worst + 2]
                                v[worst], v[worst + 1], v[worst + 2] = z, gx, gy
                            else:
                                oz, ox, oy = z, gx, gy
                            if math.isfinite(oz):
                                _merge(v, oz, ox, oy, half)
                        else:
                            low = capsule_low(xc, yc, c0x, c0y, c0z, dx, dy, dz, reach, -1)[0]
                            if low < v[_LOC]:
                                v[_LOC] = low
                        # the one sweep that holds the cell
                        mo = v[_C00] + v[_C10] + v[_C01] + v[_C11]
                        if not 4.0 * z < mo:
                            continue  # cannot hold it lower (nor missed: z is finite)
                        for ci in range(2):
                            for ck in range(2):
                                if math.isnan(node[i + ci, k + ck]):
                                    node[i + ci, k + ck] = capsule_low(
                                        bx + (i + ci) * cell, by + (k + ck) * cell, c0x, c0y,
                                        c0z, dx, dy, dz, lim, 1)[0]
                        u00, u10 = node[i, k], node[i + 1, k]
                        u01, u11 = node[i, k + 1], node[i + 1, k + 1]
                        if (math.isfinite(u00) and math.isfinite(u10) and math.isfinite(u01)
                                and math.isfinite(u11)):
                            m = u00 + u10 + u01 + u11
                            if m < mo or (m == mo and ceil > v[_CEIL]):
                                v[_C00], v[_C10], v[_C01], v[_C11] = u00, u10, u01, u11
                                v[_CEIL] = ceil


@njit(cache=True)
def tiles_of(points, origin, cell, size, shape):
    """Sorted unique flat indices (``a * ty + b``) of the tiles holding ``points``;
    points outside the map's extent are skipped. The tile of a point is found as
    :func:`classify` finds it (its cell, then the cell's tile), so that the two agree on
    a point at a tile's edge whatever the tile's size."""
    tx, ty = shape[0], shape[1]
    keys = np.empty(points.shape[0], dtype=np.int64)
    n = 0
    for q in range(points.shape[0]):
        fx = (points[q, 0] - origin[0]) / cell
        fy = (points[q, 1] - origin[1]) / cell
        if not (0.0 <= fx < tx * size and 0.0 <= fy < ty * size):
            continue
        keys[n] = (int(fx) // size) * ty + int(fy) // size
        n += 1
    return np.unique(keys[:n])


@njit(cache=True)
def classify(points, vals, tile_index, origin, cell, size, guard):
    """Per point: -1 inside none of the inserted sweeps, 1 inside one, 0 unknown.

    Points outside the map or in a tile not allocated are unknown.
    """
    k = points.shape[0]
    out = np.zeros(k, dtype=np.int8)
    tx, ty = tile_index.shape
    for q in range(k):
        fx = (points[q, 0] - origin[0]) / cell
        fy = (points[q, 1] - origin[1]) / cell
        if not (0.0 <= fx < tx * size and 0.0 <= fy < ty * size):
            continue
        ix, iy = int(fx), int(fy)
        s = tile_index[ix // size, iy // size]
        if s < 0:
            continue
        i, j = ix % size, iy % size
        v = vals[s, i, j]
        z = points[q, 2]
        u, w = fx - ix, fy - iy
        up = ((1.0 - u) * (1.0 - w) * v[_C00] + u * (1.0 - w) * v[_C10]
              + (1.0 - u) * w * v[_C01] + u * w * v[_C11])
        if up + guard <= z <= v[_CEIL] - guard:
            out[q] = 1
            continue
        if z < v[_LOC] - guard:
            below = True
            for f in range(_M, _P0 + 3 * PLANES, 3):
                lo = v[f] + v[f + 1] * (u - 0.5) * cell + v[f + 2] * (w - 0.5) * cell
                if lo <= z + guard:  # (false for a plane not set: inf)
                    below = False
                    break
            if below:
                out[q] = -1
    return out


@njit(cache=True)
def empty_tile(size):
    """A tile's values before any sweep: no holder, bounds at +inf."""
    v = np.empty((size, size, FIELDS))
    for i in range(size):
        for k in range(size):
            for f in range(FIELDS):
                v[i, k, f] = math.inf
            v[i, k, _CEIL] = -math.inf
            for f in range(_M, _P0 + 3 * PLANES, 3):
                v[i, k, f + 1] = 0.0
                v[i, k, f + 2] = 0.0
    return v
