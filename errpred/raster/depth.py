"""Depth intervals of triangle meshes in a view, and point membership.

:func:`rasterize_interval` draws any triangle mesh (stock, sweeps) into the
``(bottom, top)`` pair of buffers: per pixel, the smallest depth of a front
face (first entry) and of a back face (first exit) in the depth range, then
``bottom = -inf`` where the exit comes first (see ``raster/meshes.py`` for
the meaning). :class:`StockInterval` keeps the buffers with their view and
answers "is there material at these points".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import constants as K
from . import _kernels as KR
from .camera import View

__all__ = ["StockInterval", "rasterize_interval", "coverage", "material_at", "view_triangles"]

_NO_MASK = np.zeros((1, 1), dtype=np.bool_)


def _prep(view: View, vertices, faces, ids, mask):
    V = np.ascontiguousarray(vertices, dtype=np.float64)
    F = np.ascontiguousarray(faces, dtype=np.int64)
    if ids is None:
        ids = np.arange(F.shape[0], dtype=np.int64)
    else:
        ids = np.ascontiguousarray(ids, dtype=np.int64)
    if mask is None:
        m, use = _NO_MASK, False
    else:
        m = np.ascontiguousarray(mask, dtype=np.bool_)
        if m.shape != view.shape:
            raise ValueError(f"mask: shape {m.shape}, expected {view.shape}")
        use = True
    return V, F, ids, m, use


def rasterize_interval(view: View, vertices, faces, ids=None, depth_range=(0.0, math.inf),
                       mask=None) -> tuple[np.ndarray, np.ndarray]:
    """``(bottom, top)`` buffers (ny, nx) of the triangles ``faces[ids]``.

    Parameters
    ----------
    view : View
    vertices : (nv, 3) float, faces : (nf, 3) int
        World mesh, triangles counter-clockwise seen from outside.
    ids : int array, optional
        Which triangles to draw (all by default; pass the spatial index's
        answer to draw only those near the view).
    depth_range : (dmin, dmax)
    mask : bool (ny, nx), optional
        Draw only into these pixels (others stay ``+inf``).
    """
    V, F, ids, m, use = _prep(view, vertices, faces, ids, mask)
    bottom = np.full(view.shape, np.inf)
    top = np.full(view.shape, np.inf)
    KR.raster_mesh(V, F, ids, view.origin, view.basis, 1.0 / view.pixel_mm,
                   float(view.handedness), float(depth_range[0]), float(depth_range[1]),
                   bottom, top, m, use, False)
    KR.finish_interval(bottom, top)
    return bottom, top


def coverage(view: View, vertices, faces, ids=None, mask=None) -> tuple[np.ndarray, np.ndarray]:
    """How many front / back faces cover each pixel centre (diagnostics, any depth).

    For a closed mesh every ray inside the silhouette crosses as many front
    as back faces; for a convex one exactly one of each.
    """
    V, F, ids, m, use = _prep(view, vertices, faces, ids, mask)
    front = np.zeros(view.shape)
    back = np.zeros(view.shape)
    KR.raster_mesh(V, F, ids, view.origin, view.basis, 1.0 / view.pixel_mm,
                   float(view.handedness), -np.inf, np.inf, front, back, m, use, True)
    return front.astype(np.int64), back.astype(np.int64)


def view_triangles(view: View, vertices, faces, ids=None) -> np.ndarray:
    """Triangles in view coordinates ``(u, v, depth)``, shape (n, 3, 3).

    Vertices are transformed once, then indexed, so shared vertices stay
    bitwise equal (what :func:`errpred.raster._kernels.raster_view_tris`
    needs for a watertight fill).
    """
    V = view.to_view(vertices)
    F = np.asarray(faces, dtype=np.int64)
    if ids is not None:
        F = F[np.asarray(ids, dtype=np.int64)]
    return np.ascontiguousarray(V[F])


def material_at(view: View, bottom, top, points, eps: float | None = None) -> np.ndarray:
    """True where world points lie in their pixel's material interval.

    A point is in material when it projects into the window and
    ``bottom - eps <= depth <= top + eps`` at its pixel (``eps`` default
    ``constants.MEMBERSHIP_EPS_MM``). Points outside the window give False.
    The interval is that of the pixel *centre*'s ray; between centres the
    answer is the nearest-pixel one (error up to the surface's depth change
    across half a pixel).
    """
    e = K.MEMBERSHIP_EPS_MM if eps is None else float(eps)
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    i, j, inside = view.pixel_of(p)
    d = (p - view.origin) @ view.direction
    b = bottom[i, j]
    t = top[i, j]
    return inside & (d >= b - e) & (d <= t + e)


@dataclass(frozen=True, eq=False)
class StockInterval:
    """The stock's depth interval in a view (``Stock.render``).

    Attributes
    ----------
    view : View
    bottom, top : ndarray (ny, nx) [mm]
        First entry / first exit depth (see ``raster/meshes.py``).
    depth_range : (float, float)
    """

    view: View
    bottom: np.ndarray
    top: np.ndarray
    depth_range: tuple[float, float] = (0.0, math.inf)

    @property
    def hit(self) -> np.ndarray:
        """Pixels whose ray meets a surface of the stock in the range (a ray inside the
        material over the whole range, ``-inf`` to ``+inf``, meets none: not a hit)."""
        return np.isfinite(self.top) | np.isfinite(self.bottom)

    def material_at(self, points, eps: float | None = None) -> np.ndarray:
        """See :func:`material_at`."""
        return material_at(self.view, self.bottom, self.top, points, eps)
