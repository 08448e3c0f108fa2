"""Numba kernels: the stock's depth interval at points, and its smooth cells.

The bottom view (``errpred/bottomview.py``) keeps the stock as a top and a
bottom depth per pixel; :func:`interval_membership` says whether points lie
between them (bilinear inside cells whose corners are smooth, else
undecided), :func:`cells_smooth` which cells are smooth; :func:`box_membership`
the same question for a box stock, in one pass over tool-frame points.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["box_membership", "interval_membership", "cells_smooth"]


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


@njit(cache=True)
def box_membership(xyz, tip, frame, lo, hi, eps):
    """Which tool-frame points lie in a box stock: ``tip + xyz @ frame`` within
    ``[lo - eps, hi + eps]`` on every axis.

    One pass without the world points' array (numpy made five temporaries of the
    points' size; the flower mold's flat end mill asks about 100,000 points a call).
    Each world coordinate is formed as ``tip[c] + (x f0c + y f1c + z f2c)``; numpy's
    matrix product may round that sum otherwise, so an answer could differ from the
    numpy twin's (``tests/errpred/test_bottomview.py``) only for a point within
    rounding (~1e-13 mm) of a face grown by ``eps``.

    Parameters
    ----------
    xyz : ndarray, shape (k, 3) [mm]
        Tool-frame points.
    tip : ndarray, shape (3,) [mm]
    frame : ndarray, shape (3, 3)
        Rows: the tool frame's axes in the world.
    lo, hi : ndarray, shape (3,) [mm]
        The box's corners.
    eps : float [mm]

    Returns
    -------
    ndarray, shape (k,), bool
    """
    k = xyz.shape[0]
    out = np.zeros(k, dtype=np.bool_)
    for q in range(k):
        x, y, z = xyz[q, 0], xyz[q, 1], xyz[q, 2]
        inside = True
        for c in range(3):
            v = tip[c] + (x * frame[0, c] + y * frame[1, c] + z * frame[2, c])
            if not (v >= lo[c] - eps and v <= hi[c] + eps):
                inside = False
                break
        out[q] = inside
    return out
