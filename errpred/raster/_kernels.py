"""Numba kernels of the rasterizer and of the triangle grid.

Pixel space: a view coordinate ``(u, v)`` maps to ``X = u / p - 0.5``,
``Y = v / p - 0.5`` so that the centre of pixel ``(i, j)`` is at ``(X, Y) =
(j, i)``; a triangle covers a pixel when the pixel centre is inside it.

Watertightness. Edge functions are evaluated in a canonical vertex order
(the lexicographically smaller endpoint first) and negated as needed, so the
two triangles that share an edge compute bitwise-opposite values at every
pixel centre. A centre exactly on an edge (value 0) belongs to the triangle
for which the edge, taken counter-clockwise, points in the half-open
half-plane of directions ``dy < 0 or (dy == 0 and dx > 0)`` (a "top-left"
rule): of two triangles on either side of an edge exactly one owns it, and a
centre on a shared vertex is owned by exactly one triangle of the fan.
Vertices must be transformed per vertex (same float ops for the same world
point), which the kernels do.

Front / back: with the triangle's normal ``n`` from its vertex order
(counter-clockwise seen from outside, as trimesh orients closed meshes), a
face is front (faces the camera) when ``n . d < 0``; in pixel space that is
``handedness * area < 0`` (``area`` the signed area of the projected
triangle). Edge-on triangles (area exactly 0) are skipped; their neighbours
cover their pixels.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_JIT = dict(cache=True, nogil=True)


@njit(**_JIT)
def _edge(ax, ay, bx, by, px, py):
    """cross(b - a, p - a), evaluated the same way for (a, b) and (b, a)."""
    if ax < bx or (ax == bx and ay < by):
        return (bx - ax) * (py - ay) - (by - ay) * (px - ax)
    return -((ax - bx) * (py - by) - (ay - by) * (px - bx))


@njit(**_JIT)
def _owns(w, dx, dy):
    """Inside test of one edge (counter-clockwise direction dx, dy) with the tie rule."""
    if w > 0.0:
        return True
    if w < 0.0:
        return False
    return dy < 0.0 or (dy == 0.0 and dx > 0.0)


@njit(**_JIT)
def _raster_tri(x0, y0, z0, x1, y1, z1, x2, y2, z2, handed, dmin, dmax,
                out_front, out_back, mask, use_mask, count):
    """Rasterize one triangle given in pixel space (X, Y, depth).

    ``count`` False: keep the minimum depth in ``dmin <= depth <= dmax`` of
    front faces in ``out_front`` and of back faces in ``out_back``.
    ``count`` True: add 1 per covered pixel instead (diagnostics).
    """
    ny, nx = out_front.shape
    if not count:
        if z0 < dmin and z1 < dmin and z2 < dmin:
            return
        if z0 > dmax and z1 > dmax and z2 > dmax:
            return
    xmin = min(x0, x1, x2)
    xmax = max(x0, x1, x2)
    ymin = min(y0, y1, y2)
    ymax = max(y0, y1, y2)
    if xmax < 0.0 or ymax < 0.0 or xmin > nx - 1.0 or ymin > ny - 1.0:
        return
    area = _edge(x0, y0, x1, y1, x2, y2)
    if area == 0.0:
        return
    front = handed * area < 0.0
    if area < 0.0:  # make counter-clockwise in pixel space
        x1, y1, z1, x2, y2, z2 = x2, y2, z2, x1, y1, z1
    j0 = int(np.ceil(max(xmin, 0.0)))
    j1 = int(np.floor(min(xmax, nx - 1.0)))
    i0 = int(np.ceil(max(ymin, 0.0)))
    i1 = int(np.floor(min(ymax, ny - 1.0)))
    # counter-clockwise edge directions, opposite vertex 0, 1, 2
    dx0, dy0 = x2 - x1, y2 - y1
    dx1, dy1 = x0 - x2, y0 - y2
    dx2, dy2 = x1 - x0, y1 - y0
    out = out_front if front else out_back
    for i in range(i0, i1 + 1):
        py = float(i)
        for j in range(j0, j1 + 1):
            if use_mask and not mask[i, j]:
                continue
            px = float(j)
            w0 = _edge(x1, y1, x2, y2, px, py)
            if not _owns(w0, dx0, dy0):
                continue
            w1 = _edge(x2, y2, x0, y0, px, py)
            if not _owns(w1, dx1, dy1):
                continue
            w2 = _edge(x0, y0, x1, y1, px, py)
            if not _owns(w2, dx2, dy2):
                continue
            if count:
                out[i, j] += 1.0
                continue
            s = w0 + w1 + w2
            if s <= 0.0:
                continue
            z = (w0 * z0 + w1 * z1 + w2 * z2) / s
            if z < dmin or z > dmax:
                continue
            if z < out[i, j]:
                out[i, j] = z


@njit(**_JIT)
def raster_mesh(V, F, ids, origin, basis, inv_pixel, handed, dmin, dmax,
                out_front, out_back, mask, use_mask, count):
    """Rasterize triangles ``F[ids]`` of world vertices ``V`` into the buffers.

    ``origin`` (3,), ``basis`` (3, 3) of the view; ``inv_pixel = 1 / pixel_mm``.
    See :func:`_raster_tri` for the buffers; they must be initialised by the
    caller (``+inf`` for depths, 0 for counts).
    """
    ox, oy, oz = origin[0], origin[1], origin[2]
    c = np.empty((3, 3))
    for k in range(ids.shape[0]):
        t = ids[k]
        for a in range(3):
            vi = F[t, a]
            qx = V[vi, 0] - ox
            qy = V[vi, 1] - oy
            qz = V[vi, 2] - oz
            u = qx * basis[0, 0] + qy * basis[0, 1] + qz * basis[0, 2]
            v = qx * basis[1, 0] + qy * basis[1, 1] + qz * basis[1, 2]
            c[a, 0] = u * inv_pixel - 0.5
            c[a, 1] = v * inv_pixel - 0.5
            c[a, 2] = qx * basis[2, 0] + qy * basis[2, 1] + qz * basis[2, 2]
        _raster_tri(c[0, 0], c[0, 1], c[0, 2], c[1, 0], c[1, 1], c[1, 2],
                    c[2, 0], c[2, 1], c[2, 2], handed, dmin, dmax,
                    out_front, out_back, mask, use_mask, count)


@njit(**_JIT)
def raster_view_tris(tris, inv_pixel, handed, dmin, dmax, out_front, out_back,
                     mask, use_mask, count):
    """Rasterize triangles given in view coordinates, ``tris`` (n, 3, 3) of (u, v, depth).

    Shared vertices must carry bitwise-equal coordinates for the fill to be
    watertight (transform vertices, then index them).
    """
    for k in range(tris.shape[0]):
        _raster_tri(tris[k, 0, 0] * inv_pixel - 0.5, tris[k, 0, 1] * inv_pixel - 0.5,
                    tris[k, 0, 2],
                    tris[k, 1, 0] * inv_pixel - 0.5, tris[k, 1, 1] * inv_pixel - 0.5,
                    tris[k, 1, 2],
                    tris[k, 2, 0] * inv_pixel - 0.5, tris[k, 2, 1] * inv_pixel - 0.5,
                    tris[k, 2, 2], handed, dmin, dmax,
                    out_front, out_back, mask, use_mask, count)


@njit(**_JIT)
def finish_interval(bottom, top):
    """Where the first exit comes before any entry, the material starts before the range."""
    ny, nx = bottom.shape
    for i in range(ny):
        for j in range(nx):
            if top[i, j] < bottom[i, j]:
                bottom[i, j] = -np.inf


@njit(**_JIT)
def box_interval(origin, basis, pixel, lo, hi, dmin, dmax, bottom, top, mask, use_mask):
    """Analytic interval of the box [lo, hi] (slab method at each pixel centre).

    Same rules as the mesh path: the entry counts when in [dmin, dmax], so
    does the exit; :func:`finish_interval` is applied; a ray inside the box over
    the whole range gets ``-inf`` and ``+inf``. Buffers must be +inf.
    """
    ny, nx = bottom.shape
    d = basis[2]
    for i in range(ny):
        for j in range(nx):
            if use_mask and not mask[i, j]:
                continue
            su = (j + 0.5) * pixel
            sv = (i + 0.5) * pixel
            tnear = -np.inf
            tfar = np.inf
            hit = True
            for a in range(3):
                o = origin[a] + su * basis[0, a] + sv * basis[1, a]
                if d[a] == 0.0:
                    if o < lo[a] or o > hi[a]:
                        hit = False
                        break
                    continue
                t1 = (lo[a] - o) / d[a]
                t2 = (hi[a] - o) / d[a]
                tnear = max(tnear, min(t1, t2))
                tfar = min(tfar, max(t1, t2))
            if not hit or tnear > tfar:
                continue
            if dmin <= tnear <= dmax:
                bottom[i, j] = tnear
            if dmin <= tfar <= dmax:
                top[i, j] = tfar
            if top[i, j] < bottom[i, j] or (tnear < dmin and tfar > dmax):
                bottom[i, j] = -np.inf


# --- uniform grid of triangle bounding boxes --------------------------------

@njit(**_JIT)
def _cell_range(glo, cell, dims, qlo, qhi, out):
    """Cell index range of a box into out (2, 3); False if it misses the grid."""
    for a in range(3):
        top = glo[a] + dims[a] * cell
        if qhi[a] < glo[a] or qlo[a] > top:
            return False
        lo = np.floor((qlo[a] - glo[a]) / cell)
        hi = np.floor((qhi[a] - glo[a]) / cell)
        lo = min(max(lo, 0.0), dims[a] - 1.0)
        hi = min(max(hi, 0.0), dims[a] - 1.0)
        out[0, a] = int(lo)
        out[1, a] = int(hi)
    return True


@njit(**_JIT)
def _apart(tri_lo, tri_hi, t, qlo, qhi):
    """Triangle t's bounds and the query box do not overlap."""
    return (tri_lo[t, 0] > qhi[0] or tri_hi[t, 0] < qlo[0]
            or tri_lo[t, 1] > qhi[1] or tri_hi[t, 1] < qlo[1]
            or tri_lo[t, 2] > qhi[2] or tri_hi[t, 2] < qlo[2])


@njit(**_JIT)
def grid_query(glo, cell, dims, offsets, items, tri_cl, tri_lo, tri_hi, big, qlo, qhi):
    """Ids of the triangles whose bounding boxes overlap the box [qlo, qhi].

    Each triangle is reported once: from the first cell (per axis) of the
    overlap of its cell range and the query's. Exactly the bounding-box
    overlaps are returned (a superset of the triangles meeting the box).
    """
    r = np.empty((2, 3), dtype=np.int64)
    if not _cell_range(glo, cell, dims, qlo, qhi, r):
        return np.empty(0, dtype=np.int64)
    d1 = dims[1]
    d2 = dims[2]
    bound = big.shape[0]
    for ix in range(r[0, 0], r[1, 0] + 1):
        for iy in range(r[0, 1], r[1, 1] + 1):
            base = (ix * d1 + iy) * d2
            bound += offsets[base + r[1, 2] + 1] - offsets[base + r[0, 2]]
    out = np.empty(bound, dtype=np.int64)
    n = 0
    for ix in range(r[0, 0], r[1, 0] + 1):
        for iy in range(r[0, 1], r[1, 1] + 1):
            base = (ix * d1 + iy) * d2
            for iz in range(r[0, 2], r[1, 2] + 1):
                c = base + iz
                for k in range(offsets[c], offsets[c + 1]):
                    t = items[k]
                    if max(tri_cl[t, 0], r[0, 0]) != ix:
                        continue
                    if max(tri_cl[t, 1], r[0, 1]) != iy:
                        continue
                    if max(tri_cl[t, 2], r[0, 2]) != iz:
                        continue
                    if _apart(tri_lo, tri_hi, t, qlo, qhi):
                        continue
                    out[n] = t
                    n += 1
    for k in range(big.shape[0]):
        t = big[k]
        if _apart(tri_lo, tri_hi, t, qlo, qhi):
            continue
        out[n] = t
        n += 1
    return out[:n]


@njit(**_JIT)
def _dist2_point_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Squared distance from p to triangle abc (closest-point regions, Ericson 5.1.5)."""
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        qx, qy, qz = ax, ay, az
    else:
        bpx, bpy, bpz = px - bx, py - by, pz - bz
        d3 = abx * bpx + aby * bpy + abz * bpz
        d4 = acx * bpx + acy * bpy + acz * bpz
        cpx, cpy, cpz = px - cx, py - cy, pz - cz
        d5 = abx * cpx + aby * cpy + abz * cpz
        d6 = acx * cpx + acy * cpy + acz * cpz
        vc = d1 * d4 - d3 * d2
        vb = d5 * d2 - d1 * d6
        va = d3 * d6 - d5 * d4
        if d3 >= 0.0 and d4 <= d3:
            qx, qy, qz = bx, by, bz
        elif d6 >= 0.0 and d5 <= d6:
            qx, qy, qz = cx, cy, cz
        elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
            t = d1 / (d1 - d3)
            qx, qy, qz = ax + t * abx, ay + t * aby, az + t * abz
        elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
            t = d2 / (d2 - d6)
            qx, qy, qz = ax + t * acx, ay + t * acy, az + t * acz
        elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
            t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
            qx, qy, qz = bx + t * (cx - bx), by + t * (cy - by), bz + t * (cz - bz)
        else:
            den = va + vb + vc
            if den <= 0.0:  # degenerate triangle: nearest of its vertices
                qx, qy, qz = ax, ay, az
            else:
                v = vb / den
                w = vc / den
                qx = ax + abx * v + acx * w
                qy = ay + aby * v + acy * w
                qz = az + abz * v + acz * w
    return (px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2


@njit(**_JIT)
def _column(glo, cell, dims, x, a):
    """Grid column index of coordinate x along axis a, or -1 outside the grid."""
    top = glo[a] + dims[a] * cell
    if x < glo[a] or x > top:
        return -1
    return min(max(int(np.floor((x - glo[a]) / cell)), 0), dims[a] - 1)


@njit(**_JIT)
def contains_mesh(V, F, glo, cell, dims, col_offsets, col_items, tri_lo, tri_hi, points, eps):
    """Inside test of points by a vertical ray (+Z) each: a one-pixel view per point.

    The ray of point ``p`` starts at depth ``-eps`` below ``p``; the point is
    inside when the first surface the ray meets is a back face (exit), or a
    front face within ``eps`` of the point, or when any triangle is within
    ``eps`` of it (on the boundary, also on walls parallel to the ray). Same
    fill rule as the rasterizer, so shared edges are crossed exactly once.
    The triangles come from the grid's (x, y) columns (``col_offsets``,
    ``col_items``: every triangle whose bounds touch the column), each column
    ordered by the triangles' tops (``tri_hi[:, 2]``) from the highest down: a
    ray stops reading its column at the first top more than ``eps`` below it.
    """
    n = points.shape[0]
    res = np.zeros(n, dtype=np.bool_)
    d1 = dims[1]
    for k in range(n):
        px, py, pz = points[k, 0], points[k, 1], points[k, 2]
        first_front = np.inf
        first_back = np.inf
        ix = _column(glo, cell, dims, px, 0)
        iy = _column(glo, cell, dims, py, 1)
        if ix >= 0 and iy >= 0:
            col = ix * d1 + iy
            for m in range(col_offsets[col], col_offsets[col + 1]):
                t = col_items[m]
                if tri_hi[t, 2] < pz - eps:
                    break  # this one and the rest of the column lie below the ray
                if tri_lo[t, 0] > px or tri_hi[t, 0] < px or tri_lo[t, 1] > py or tri_hi[t, 1] < py:
                    continue
                a, b, c = F[t, 0], F[t, 1], F[t, 2]
                x0, y0, z0 = V[a, 0] - px, V[a, 1] - py, V[a, 2] - pz
                x1, y1, z1 = V[b, 0] - px, V[b, 1] - py, V[b, 2] - pz
                x2, y2, z2 = V[c, 0] - px, V[c, 1] - py, V[c, 2] - pz
                area = _edge(x0, y0, x1, y1, x2, y2)
                if area == 0.0:
                    continue
                front = area < 0.0
                if area < 0.0:
                    x1, y1, z1, x2, y2, z2 = x2, y2, z2, x1, y1, z1
                w0 = _edge(x1, y1, x2, y2, 0.0, 0.0)
                if not _owns(w0, x2 - x1, y2 - y1):
                    continue
                w1 = _edge(x2, y2, x0, y0, 0.0, 0.0)
                if not _owns(w1, x0 - x2, y0 - y2):
                    continue
                w2 = _edge(x0, y0, x1, y1, 0.0, 0.0)
                if not _owns(w2, x1 - x0, y1 - y0):
                    continue
                s = w0 + w1 + w2
                if s <= 0.0:
                    continue
                z = (w0 * z0 + w1 * z1 + w2 * z2) / s
                if z < -eps:
                    continue
                if front:
                    if z < first_front:
                        first_front = z
                elif z < first_back:
                    first_back = z
        inside = first_back < first_front or first_front <= eps
        if not inside and eps > 0.0:  # on the boundary within eps (e.g. a wall along the ray)
            x0c = _column(glo, cell, dims, max(px - eps, glo[0]), 0)
            x1c = _column(glo, cell, dims, min(px + eps, glo[0] + dims[0] * cell), 0)
            y0c = _column(glo, cell, dims, max(py - eps, glo[1]), 1)
            y1c = _column(glo, cell, dims, min(py + eps, glo[1] + dims[1] * cell), 1)
            near_grid = (px + eps >= glo[0] and px - eps <= glo[0] + dims[0] * cell
                         and py + eps >= glo[1] and py - eps <= glo[1] + dims[1] * cell)
            if near_grid:
                for cx in range(x0c, x1c + 1):
                    for cy in range(y0c, y1c + 1):
                        col = cx * d1 + cy
                        for m in range(col_offsets[col], col_offsets[col + 1]):
                            t = col_items[m]
                            if tri_hi[t, 2] < pz - eps:
                                break  # the rest of this column lies lower still
                            if (tri_lo[t, 0] > px + eps or tri_hi[t, 0] < px - eps
                                    or tri_lo[t, 1] > py + eps or tri_hi[t, 1] < py - eps
                                    or tri_lo[t, 2] > pz + eps):
                                continue
                            a, b, c = F[t, 0], F[t, 1], F[t, 2]
                            if _dist2_point_triangle(px, py, pz, V[a, 0], V[a, 1], V[a, 2],
                                                     V[b, 0], V[b, 1], V[b, 2],
                                                     V[c, 0], V[c, 1], V[c, 2]) <= eps * eps:
                                inside = True
                                break
                        if inside:
                            break
                    if inside:
                        break
        res[k] = inside
    return res
