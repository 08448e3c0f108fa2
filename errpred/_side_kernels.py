"""Numba kernels of the side view (:meth:`errpred.geometry.GeometryModel._side_view`).

The side view looks across the tool axis at the finished surface (``docs/method.md``
§3). Per pixel it needs where the pixel's ray first meets the tool's envelope and whether
that point lies in the stock (in the material interval the view rendered,
:func:`interval_contains`); the side view asks both at once and keeps only the pixels
whose hit is in the stock (:func:`side_stock_hits`; about one in eight on the bundled
mold-ball program, nearly all on a flat end mill's wall in a box stock), as the cutting
and finished regions are made of those alone. The numpy code these replace made about thirty passes
over the view's ~55,000 pixels and kept every pixel's arrays; each kernel is one pass.

Their numpy twins are, for :func:`side_stock_hits`, :func:`errpred.surface.envelope_hits`
(its side-view branch) with the stock probe's test, and :func:`interval_contains_numpy`
(what :class:`errpred.probe.StockProbe` did for a mesh). They are compared in
``tests/errpred/test_side_kernels.py``: the same IEEE operations, but numpy forms its
matrix products in BLAS (another order of the sums) and evaluates ``arctan2`` and
``arccos`` with its own routines, so the coordinates agree within a few ulps of the
world coordinates they are formed from (``constants.SIDE_HITS_TOL_MM``,
``SIDE_HITS_TOL_RAD``), not to the bit, and a pixel's flags could differ only for a
ray within rounding of the envelope's silhouette or a hit within rounding of the
stock's surface ``± MEMBERSHIP_EPS_MM`` (on the real views of the tests, and on the
376 views of 600 blocks of the planned mold-core program: none).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["side_stock_hits", "interval_contains", "interval_contains_numpy"]


@njit(cache=True, nogil=True, inline="always")
def _ray_hit(origin, basis, si, sj, tip, f00, f01, f02, f10, f11, f12, f20, f21, f22, vx, vy,
             R, r, c, top):
    """The ray of the pixel whose centre is ``sj``, ``si`` [mm] along ``u``, ``v`` from
    the view's origin, against the envelope: (hit?, x', y', z') of the hit in the tool
    frame (not hit: the ray's point nearest the axis)."""
    w0 = origin[0] + sj * basis[0, 0] + si * basis[1, 0] - tip[0]
    w1 = origin[1] + sj * basis[0, 1] + si * basis[1, 1] - tip[1]
    w2 = origin[2] + sj * basis[0, 2] + si * basis[1, 2] - tip[2]
    ox = w0 * f00 + w1 * f01 + w2 * f02
    oy = w0 * f10 + w1 * f11 + w2 * f12
    z = w0 * f20 + w1 * f21 + w2 * f22
    b = ox * vx + oy * vy
    ok = False
    disc = 0.0
    if 0.0 <= z <= top:
        if z >= r:
            rad = R
        else:
            q = r - z
            rad = c + math.sqrt(max(r * r - q * q, 0.0))
        disc = b * b - (ox * ox + oy * oy - rad * rad)
        ok = disc >= 0.0
    t = -b - math.sqrt(disc) if ok else -b
    return ok, ox + t * vx, oy + t * vy, z


@njit(cache=True, nogil=True, inline="always")
def _ray_direction(basis, frame):
    """The view direction in the tool frame, its ``x', y'`` part made unit."""
    d0, d1, d2 = basis[2, 0], basis[2, 1], basis[2, 2]
    vx = frame[0, 0] * d0 + frame[0, 1] * d1 + frame[0, 2] * d2
    vy = frame[1, 0] * d0 + frame[1, 1] * d1 + frame[1, 2] * d2
    nv = math.sqrt(vx * vx + vy * vy)
    return vx / nv, vy / nv


@njit(cache=True, nogil=True, inline="always")
def _in_interval(x, y, z, origin, basis, inv, nx, ny, bottom, top, eps):
    """Is the world point in its pixel's material interval (:func:`interval_contains`)?"""
    w0 = x - origin[0]
    w1 = y - origin[1]
    w2 = z - origin[2]
    u = w0 * basis[0, 0] + w1 * basis[0, 1] + w2 * basis[0, 2]
    v = w0 * basis[1, 0] + w1 * basis[1, 1] + w2 * basis[1, 2]
    jf = math.floor(u * inv)
    if_ = math.floor(v * inv)
    if not (jf >= 0 and jf < nx and if_ >= 0 and if_ < ny):
        return False
    i, j = int(if_), int(jf)
    depth = w0 * basis[2, 0] + w1 * basis[2, 1] + w2 * basis[2, 2]
    return bottom[i, j] - eps <= depth and depth <= top[i, j] + eps


@njit(cache=True, nogil=True)
def side_stock_hits(origin, basis, pixel, nx, ny, tip, frame, R, r, c, top, box, lo, hi,
                    bottom, top_depth, eps):
    """The pixels of a side view whose first hit on the tool's cutting envelope lies in
    the stock, and their hits: what the side view's cutting and finished regions are
    made of. The rows returned are the first of arrays sized for every pixel (views, not
    copies), so the memory of the whole view is held as long as they are.

    The view (``origin`` (3,) [mm], ``basis`` (3, 3) rows ``u, v, d``, ``pixel``
    [mm], ``nx`` x ``ny`` pixels; see :class:`errpred.raster.camera.View`) must look
    across the tool axis (``d`` normal to ``frame[2]``; the caller checks). Pixel
    ``(i, j)`` is flat index ``i * nx + j``; its ray starts at its centre on the
    depth-0 plane and runs along ``d``. ``tip`` (3,) [mm], ``frame`` (3, 3) the tool
    frame (rows ``x', y', z'``); ``R``, ``r``, ``c``, ``top`` [mm] the tool radius,
    corner radius, core radius ``R - r`` and flute length.

    The stock test is the stock probe's (:class:`errpred.probe.StockProbe`): with
    ``box``, the box ``[lo, hi]`` (3,) [mm] grown by ``eps``; else the view's material
    interval ``bottom``, ``top_depth`` (ny, nx) [mm] (:func:`interval_contains`).

    Returns
    -------
    index : ndarray, shape (k,), int64
        Flat pixel index (``i * nx + j``) of each such pixel, ascending.
    tool_xyz, world : ndarray, shape (k, 3) [mm]
        Their hits in the tool frame and in the world.
    """
    p = nx * ny
    index = np.empty(p, dtype=np.int64)
    xyz = np.empty((p, 3))
    world = np.empty((p, 3))
    f00, f01, f02 = frame[0, 0], frame[0, 1], frame[0, 2]
    f10, f11, f12 = frame[1, 0], frame[1, 1], frame[1, 2]
    f20, f21, f22 = frame[2, 0], frame[2, 1], frame[2, 2]
    vx, vy = _ray_direction(basis, frame)
    inv = 1.0 / pixel
    m = 0
    for i in range(ny):
        si = (i + 0.5) * pixel
        for j in range(nx):
            ok, x, y, z = _ray_hit(origin, basis, si, (j + 0.5) * pixel, tip, f00, f01, f02,
                                   f10, f11, f12, f20, f21, f22, vx, vy, R, r, c, top)
            if not ok:
                continue
            wx = tip[0] + (x * f00 + y * f10 + z * f20)
            wy = tip[1] + (x * f01 + y * f11 + z * f21)
            wz = tip[2] + (x * f02 + y * f12 + z * f22)
            if box:
                inside = (lo[0] - eps <= wx <= hi[0] + eps and lo[1] - eps <= wy <= hi[1] + eps
                          and lo[2] - eps <= wz <= hi[2] + eps)
            else:
                inside = _in_interval(wx, wy, wz, origin, basis, inv, nx, ny, bottom, top_depth,
                                      eps)
            if not inside:
                continue
            index[m] = i * nx + j
            xyz[m, 0] = x
            xyz[m, 1] = y
            xyz[m, 2] = z
            world[m, 0] = wx
            world[m, 1] = wy
            world[m, 2] = wz
            m += 1
    # the kept rows as views of the arrays filled (no copy: on the flower mold's 2 million
    # pixel side views, 97 % kept, the copies were 30 % of the kernel's time; the rows
    # after them are held only as long as the view's arrays are)
    return index[:m], xyz[:m], world[:m]


@njit(cache=True, nogil=True)
def interval_contains(points, origin, basis, pixel, nx, ny, bottom, top, eps):
    """Which world points lie in their pixel's material interval of a view.

    A point's pixel is the one it projects into; it is in material when its depth
    lies within ``[bottom - eps, top + eps]`` of that pixel. Points projecting
    outside the window are not.

    Parameters
    ----------
    points : ndarray, shape (k, 3) [mm]
    origin, basis, pixel, nx, ny
        The view (see :func:`side_stock_hits`).
    bottom, top : ndarray, shape (ny, nx) [mm]
        Depths of the first entry into and exit from the stock per pixel.
    eps : float [mm]

    Returns
    -------
    ndarray, shape (k,), bool
    """
    k = points.shape[0]
    out = np.zeros(k, dtype=np.bool_)
    inv = 1.0 / pixel
    for q in range(k):
        out[q] = _in_interval(points[q, 0], points[q, 1], points[q, 2], origin, basis, inv, nx,
                              ny, bottom, top, eps)
    return out


def interval_contains_numpy(points: np.ndarray, view, bottom: np.ndarray, top: np.ndarray,
                            eps: float) -> np.ndarray:
    """The numpy twin of :func:`interval_contains` (what the stock probe did before).

    Parameters
    ----------
    points : ndarray, shape (k, 3) [mm]
    view : errpred.raster.camera.View
    bottom, top : ndarray, shape (ny, nx) [mm]
    eps : float [mm]
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    i, j, inside = view.pixel_of(pts)
    depth = view.to_view(pts)[:, 2]
    out = np.zeros(pts.shape[0], dtype=bool)
    ii, jj = i[inside], j[inside]
    d = depth[inside]
    out[inside] = (bottom[ii, jj] - eps <= d) & (d <= top[ii, jj] + eps)
    return out
