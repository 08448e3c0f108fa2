"""Numba kernels of the side view (:meth:`errpred.geometry.GeometryModel._side_view`).

The side view looks across the tool axis at the finished surface (``docs/method.md``
§3). Per pixel it needs where the pixel's ray first meets the tool's envelope
(:func:`side_hits`) and whether that point lies in the stock's material interval the
view rendered (:func:`interval_contains`). The numpy code these replace made about
thirty passes over the view's ~55,000 pixels; each kernel is one pass.

Their numpy twins are :func:`errpred.surface.envelope_hits` (its side-view branch)
and :func:`interval_contains_numpy` (what :class:`errpred.probe.StockProbe` did for
a mesh). They are compared in ``tests/errpred/test_side_kernels.py``: the same
IEEE operations, but numpy forms its matrix products in BLAS (another order of the
sums, fused multiply-adds) and evaluates ``arctan2``/``arccos`` with its own
routines, so the coordinates agree within a few ulps
(:data:`SIDE_HITS_TOL_MM`, :data:`SIDE_HITS_TOL_RAD`), and a pixel's flags could
differ only for a ray within rounding of the envelope's silhouette or a hit within
rounding of the stock's surface ``± MEMBERSHIP_EPS_MM`` (on the real views of the
tests: none).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["side_hits", "interval_contains", "interval_contains_numpy",
           "SIDE_HITS_TOL_MM", "SIDE_HITS_TOL_RAD"]

#: How far the kernels' hit coordinates may lie from their numpy twins' [mm]: a few
#: ulps of world coordinates up to ~1 m (ulp 1.1e-13 mm), far below any pixel.
SIDE_HITS_TOL_MM = 1e-11
#: How far the kernels' angles may lie from their numpy twins' [rad] (``arctan2`` and
#: ``arccos`` of the same arguments within an ulp or two; ``arccos`` near 1 magnifies
#: the arguments' rounding: sqrt(2 * 1e-16) ~ 1.5e-8 at worst).
SIDE_HITS_TOL_RAD = 1e-7


@njit(cache=True, nogil=True)
def side_hits(origin, basis, pixel, nx, ny, tip, frame, R, r, c, top):
    """First hits of a side view's pixel rays on a tool's cutting envelope.

    The view (``origin`` (3,) [mm], ``basis`` (3, 3) rows ``u, v, d``, ``pixel``
    [mm], ``nx`` x ``ny`` pixels; see :class:`errpred.raster.camera.View`) must look
    across the tool axis (``d`` normal to ``frame[2]``; the caller checks). Pixel
    ``(i, j)`` is flat index ``i * nx + j``; its ray starts at its centre on the
    depth-0 plane and runs along ``d``.

    Parameters
    ----------
    origin : ndarray, shape (3,) [mm]
    basis : ndarray, shape (3, 3)
    pixel : float [mm]
    nx, ny : int
    tip : ndarray, shape (3,) [mm]
    frame : ndarray, shape (3, 3)
        Tool frame (rows ``x', y', z'``).
    R, r, c, top : float [mm]
        Tool radius, corner radius, core radius ``R - r`` and flute length.

    Returns
    -------
    valid : ndarray, shape (p,), bool
        The ray meets the envelope (within the flute length).
    tool_xyz : ndarray, shape (p, 3) [mm]
        Hit in the tool frame (where not valid: the ray's point nearest the axis).
    world : ndarray, shape (p, 3) [mm]
        Hit in the world (``tip`` where not valid).
    phi, kappa : ndarray, shape (p,) [rad]
        Angular position (``atan2(x', y')``) and contact angle of the envelope there.
    """
    p = nx * ny
    valid = np.zeros(p, dtype=np.bool_)
    xyz = np.empty((p, 3))
    world = np.empty((p, 3))
    phi = np.empty(p)
    kappa = np.empty(p)
    f00, f01, f02 = frame[0, 0], frame[0, 1], frame[0, 2]
    f10, f11, f12 = frame[1, 0], frame[1, 1], frame[1, 2]
    f20, f21, f22 = frame[2, 0], frame[2, 1], frame[2, 2]
    d0, d1, d2 = basis[2, 0], basis[2, 1], basis[2, 2]
    vx = f00 * d0 + f01 * d1 + f02 * d2
    vy = f10 * d0 + f11 * d1 + f12 * d2
    nv = math.sqrt(vx * vx + vy * vy)
    vx /= nv
    vy /= nv
    half_pi = math.pi / 2
    rr = r * r
    for i in range(ny):
        si = (i + 0.5) * pixel
        # the row's height on the tool (every pixel of a row has the same z')
        for j in range(nx):
            sj = (j + 0.5) * pixel
            k = i * nx + j
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
                    rad = c + math.sqrt(max(rr - q * q, 0.0))
                disc = b * b - (ox * ox + oy * oy - rad * rad)
                ok = disc >= 0.0
            t = -b - math.sqrt(disc) if ok else -b
            x = ox + t * vx
            y = oy + t * vy
            valid[k] = ok
            xyz[k, 0] = x
            xyz[k, 1] = y
            xyz[k, 2] = z
            phi[k] = math.atan2(x, y)
            if z >= r:
                kappa[k] = half_pi
            else:
                a = (r - z) / r if r > 0 else 0.0
                kappa[k] = math.acos(min(max(a, -1.0), 1.0))
            if ok:
                world[k, 0] = tip[0] + (x * f00 + y * f10 + z * f20)
                world[k, 1] = tip[1] + (x * f01 + y * f11 + z * f21)
                world[k, 2] = tip[2] + (x * f02 + y * f12 + z * f22)
            else:
                world[k, 0] = tip[0]
                world[k, 1] = tip[1]
                world[k, 2] = tip[2]
    return valid, xyz, world, phi, kappa


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
        The view (see :func:`side_hits`).
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
        w0 = points[q, 0] - origin[0]
        w1 = points[q, 1] - origin[1]
        w2 = points[q, 2] - origin[2]
        u = w0 * basis[0, 0] + w1 * basis[0, 1] + w2 * basis[0, 2]
        v = w0 * basis[1, 0] + w1 * basis[1, 1] + w2 * basis[1, 2]
        jf = math.floor(u * inv)
        if_ = math.floor(v * inv)
        if not (jf >= 0 and jf < nx and if_ >= 0 and if_ < ny):
            continue
        i, j = int(if_), int(jf)
        depth = w0 * basis[2, 0] + w1 * basis[2, 1] + w2 * basis[2, 2]
        out[q] = bottom[i, j] - eps <= depth and depth <= top[i, j] + eps
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
