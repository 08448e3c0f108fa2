"""The stock: a closed triangle mesh (STL) or an analytic box, and its depth interval.

``Stock.interval(view)`` gives per pixel the depth interval ``[bottom, top]``
of the stock's material along the pixel ray (``docs/method.md`` §3: from
below one sees the stock's top surface from inside): ``bottom`` is the depth
of the first front-facing surface (first entry), ``top`` of the first
back-facing surface (first exit), within the depth range ``[dmin, dmax]``.

* ``+inf`` in both where no surface is met in the range;
* ``bottom = -inf`` where the first surface met is an exit (the ray starts
  inside the material: the camera is inside the solid, or the mesh is an
  open top-surface-only sheet seen from below);
* ``top = +inf`` with a finite ``bottom`` where an entry has no exit in
  range (open mesh, or the exit lies beyond ``dmax``).

* ``bottom = -inf`` and ``top = +inf`` where the ray is inside the material over
  the whole range (a tool buried deeper than its view reaches): with a finite
  ``dmax``, a pixel that meets no surface in range is drawn again beyond ``dmax``,
  and is inside where the first surface there is an exit.

The analytic box follows the same rules exactly, so a box and its triangle mesh
give the same buffers.

Only the triangles near the view are drawn: a :class:`TriangleGrid` (uniform
grid of triangle bounding boxes) is queried with the bounding box of the
view's window prism (window rectangle x depth range clipped to the stock).
"""

from __future__ import annotations

import math
import os

import numpy as np

from ..constants import COLUMN_ENTRIES, COLUMNS_PER_AXIS
from ..meshio import MeshFileError, check_closed
from . import _kernels as KR
from .camera import View
from .depth import _NO_MASK, StockInterval, rasterize_interval

__all__ = ["Stock", "TriangleGrid"]


class TriangleGrid:
    """Uniform 3D grid over triangle bounding boxes, in CSR form.

    Cells are cubes of side ``cell``; a triangle is listed in every cell its
    bounding box touches. Triangles spanning more than ``max_span`` cells are
    kept in a separate short list and tested by bounding box on each query.
    :meth:`query` returns exactly the triangles whose bounding boxes overlap
    the query box (a superset of the triangles that meet it), each once.
    """

    def __init__(self, vertices, faces, cell_mm: float | None = None,
                 max_cells_per_triangle: float = 4.0, max_span: int = 64):
        V = np.ascontiguousarray(vertices, dtype=np.float64)
        F = np.ascontiguousarray(faces, dtype=np.int64)
        nt = F.shape[0]
        tv = V[F]  # (nt, 3, 3)
        self.tri_lo = np.ascontiguousarray(tv.min(axis=1))
        self.tri_hi = np.ascontiguousarray(tv.max(axis=1))
        if nt == 0:
            glo, ghi = np.zeros(3), np.ones(3)
        else:
            glo, ghi = self.tri_lo.min(axis=0), self.tri_hi.max(axis=0)
        ext = np.maximum(ghi - glo, 0.0)
        scale = max(float(ext.max()), 1e-9)
        if cell_mm is None:
            size = (self.tri_hi - self.tri_lo).max(axis=1) if nt else np.ones(1)
            cell = 2.0 * float(np.median(size)) if nt else scale
            cell = max(cell, scale * 1e-6)
            max_cells = max(64.0, max_cells_per_triangle * nt)
            for _ in range(60):
                dims = np.maximum(np.ceil(ext / cell), 1.0)
                if float(np.prod(dims)) <= max_cells:
                    break
                cell *= 1.25
        else:
            cell = float(cell_mm)
        dims = np.maximum(np.ceil(ext / cell), 1.0).astype(np.int64)
        self.glo = np.ascontiguousarray(glo, dtype=np.float64)
        self.cell = float(cell)
        self.dims = np.ascontiguousarray(dims, dtype=np.int64)
        hi_idx = (dims - 1).astype(float)
        cl = np.clip(np.floor((self.tri_lo - glo) / cell), 0.0, hi_idx).astype(np.int64)
        ch = np.clip(np.floor((self.tri_hi - glo) / cell), 0.0, hi_idx).astype(np.int64)
        self.tri_cl = np.ascontiguousarray(cl)
        span = ch - cl + 1
        counts = np.prod(span, axis=1)
        is_big = counts > max_span
        self.big = np.ascontiguousarray(np.nonzero(is_big)[0], dtype=np.int64)
        small = np.nonzero(~is_big)[0]
        cnt = counts[small]
        total = int(cnt.sum())
        tri = np.repeat(small, cnt)
        start = np.repeat(np.cumsum(cnt) - cnt, cnt)
        k = np.arange(total, dtype=np.int64) - start
        sp = span[tri]
        c2 = k % sp[:, 2]
        c1 = (k // sp[:, 2]) % sp[:, 1]
        c0 = k // (sp[:, 2] * sp[:, 1])
        cells = ((cl[tri, 0] + c0) * dims[1] + (cl[tri, 1] + c1)) * dims[2] + (cl[tri, 2] + c2)
        order = np.argsort(cells, kind="stable")
        self.items = np.ascontiguousarray(tri[order], dtype=np.int64)
        ncell = int(np.prod(dims))
        self.offsets = np.zeros(ncell + 1, dtype=np.int64)
        np.cumsum(np.bincount(cells, minlength=ncell), out=self.offsets[1:])
        self.n_triangles = nt
        # columns seen from above: every triangle in each (x, y) column its bounds
        # touch, for vertical rays (Stock.contains); their own cell size, as fine as
        # COLUMN_ENTRIES allows (a ray then meets only the triangles over its column)
        col_cell = max(float(ext[:2].max()) / COLUMNS_PER_AXIS, scale * 1e-6)
        for _ in range(60):
            col_dims = np.maximum(np.ceil(ext[:2] / col_cell), 1.0).astype(np.int64)
            hi_col = (col_dims - 1).astype(float)
            ccl = np.clip(np.floor((self.tri_lo[:, :2] - glo[:2]) / col_cell), 0.0,
                          hi_col).astype(np.int64)
            cch = np.clip(np.floor((self.tri_hi[:, :2] - glo[:2]) / col_cell), 0.0,
                          hi_col).astype(np.int64)
            span_xy = cch - ccl + 1
            cnt = span_xy[:, 0] * span_xy[:, 1]
            if int(cnt.sum()) <= COLUMN_ENTRIES:
                break
            col_cell *= 1.25
        # each column's triangles by their top, highest first (the stable sort by
        # column keeps this order): a ray stops at the first one below its start
        by_top = np.argsort(-self.tri_hi[:, 2], kind="stable")
        cnt_top = cnt[by_top]
        tri = np.repeat(by_top, cnt_top)
        k = np.arange(int(cnt.sum()), dtype=np.int64) - np.repeat(np.cumsum(cnt_top) - cnt_top,
                                                                  cnt_top)
        cols = (ccl[tri, 0] + k // span_xy[tri, 1]) * col_dims[1] + (ccl[tri, 1]
                                                                     + k % span_xy[tri, 1])
        order = np.argsort(cols, kind="stable")
        self.column_items = np.ascontiguousarray(tri[order])
        self.column_cell = float(col_cell)
        self.column_dims = np.ascontiguousarray(col_dims, dtype=np.int64)
        ncol = int(col_dims[0] * col_dims[1])
        self.column_offsets = np.zeros(ncol + 1, dtype=np.int64)
        np.cumsum(np.bincount(cols, minlength=ncol), out=self.column_offsets[1:])

    def query(self, lo, hi) -> np.ndarray:
        """Triangle ids (int64, unsorted) whose bounding boxes overlap [lo, hi]."""
        qlo = np.ascontiguousarray(lo, dtype=np.float64).reshape(3)
        qhi = np.ascontiguousarray(hi, dtype=np.float64).reshape(3)
        return KR.grid_query(self.glo, self.cell, self.dims, self.offsets, self.items,
                             self.tri_cl, self.tri_lo, self.tri_hi, self.big, qlo, qhi)

    def _args(self):
        return (self.glo, self.cell, self.dims, self.offsets, self.items, self.tri_cl,
                self.tri_lo, self.tri_hi, self.big)

    def _column_args(self):
        return (self.glo, self.column_cell, self.column_dims, self.column_offsets,
                self.column_items, self.tri_lo, self.tri_hi)


def _check_mesh(mesh, name: str, allow_open: bool):
    import trimesh

    if not isinstance(mesh, trimesh.Trimesh):
        raise TypeError(f"{name}: expected a trimesh.Trimesh, got {type(mesh).__name__}")
    if len(mesh.faces) == 0:
        raise MeshFileError(name, "the stock mesh has no triangles")
    if not mesh.is_watertight:
        if not allow_open:
            raise MeshFileError(
                name, "the stock mesh is not watertight (closed); material inside it is "
                "undefined. Repair the STL, or pass allow_open=True for a surface whose "
                "back side (against its normals) counts as material")
        return mesh
    check_closed(mesh, name)
    if mesh.volume < 0:
        mesh = mesh.copy()
        mesh.invert()
    return mesh


class Stock:
    """The raw material: a triangle mesh or an axis-aligned box (analytic).

    Use the constructors :meth:`from_stl`, :meth:`from_mesh`, :meth:`from_box`.

    Attributes
    ----------
    bounds : ndarray, shape (2, 3) [mm]
    is_box : bool
    vertices, faces : ndarray or None
        Mesh arrays (None for a box).
    grid : TriangleGrid or None
    name : str
        Where it came from (file name), for messages.
    """

    def __init__(self, *, box=None, mesh=None, name: str = "stock"):
        self.name = name
        self._mesh = mesh
        if box is not None:
            b = np.asarray(box, dtype=float)
            self.bounds = b
            self.is_box = True
            self.vertices = None
            self.faces = None
            self.grid = None
        else:
            self.is_box = False
            self.vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
            self.faces = np.ascontiguousarray(mesh.faces, dtype=np.int64)
            self.bounds = np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])
            self.grid = TriangleGrid(self.vertices, self.faces)
        self.bounds.flags.writeable = False
        lo, hi = self.bounds
        self._corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                                  for z in (lo[2], hi[2])])

    # --- constructors -----------------------------------------------------
    @classmethod
    def from_box(cls, min_mm, max_mm) -> "Stock":
        """An axis-aligned box ``[min_mm, max_mm]`` (rendered analytically)."""
        lo = np.asarray(min_mm, dtype=float).reshape(-1)
        hi = np.asarray(max_mm, dtype=float).reshape(-1)
        if lo.shape != (3,) or hi.shape != (3,) or not np.all(np.isfinite(lo)) \
                or not np.all(np.isfinite(hi)):
            raise ValueError(f"stock box: expected two finite 3-vectors, got {min_mm!r}, {max_mm!r}")
        if np.any(hi <= lo):
            raise ValueError(f"stock box: max {hi.tolist()} must exceed min {lo.tolist()} "
                             "on every axis")
        return cls(box=np.stack([lo, hi]), name="box")

    @classmethod
    def from_mesh(cls, mesh, allow_open: bool = False, name: str = "mesh") -> "Stock":
        """From a ``trimesh.Trimesh``.

        A closed mesh must be consistently oriented; an inside-out one is
        inverted. An open mesh is refused unless ``allow_open``: then the side
        its normals point away from counts as material (see module doc).
        """
        return cls(mesh=_check_mesh(mesh, name, allow_open), name=name)

    @classmethod
    def from_stl(cls, path, allow_open: bool = False) -> "Stock":
        """From an STL (or any mesh file trimesh reads); see :meth:`from_mesh`."""
        from ..meshio import load_mesh

        p = os.fspath(path)
        return cls.from_mesh(load_mesh(p, what="stock mesh", closed=not allow_open),
                             allow_open=allow_open, name=p)

    # --- geometry ---------------------------------------------------------
    @property
    def mesh(self):
        """The stock as a ``trimesh.Trimesh`` (a box is meshed on demand)."""
        if self._mesh is None:
            import trimesh

            self._mesh = trimesh.creation.box(bounds=self.bounds)
        return self._mesh

    def _depth_extent(self, view: View) -> tuple[float, float]:
        d = (self._corners - view.origin) @ view.direction
        return float(d.min()), float(d.max())

    def triangles_near(self, view: View, depth_range=(0.0, math.inf), mask=None) -> np.ndarray:
        """Ids of the triangles whose boxes overlap the view's window prism."""
        if self.is_box:
            return np.empty(0, dtype=np.int64)
        dmin, dmax = float(depth_range[0]), float(depth_range[1])
        s0, s1 = self._depth_extent(view)
        pad = 1e-9 * max(1.0, float(np.abs(self.bounds).max()))
        d0, d1 = max(dmin, s0 - pad), min(dmax, s1 + pad)
        if d0 > d1:
            return np.empty(0, dtype=np.int64)
        sub = view
        if mask is not None:
            rows = np.nonzero(mask.any(axis=1))[0]
            cols = np.nonzero(mask.any(axis=0))[0]
            if rows.size == 0:
                return np.empty(0, dtype=np.int64)
            p = view.pixel_mm
            origin = view.origin + cols[0] * p * view.u_axis + rows[0] * p * view.v_axis
            sub = View(origin, view.basis, p, int(cols[-1] - cols[0] + 1),
                       int(rows[-1] - rows[0] + 1))
        box = sub.aabb(d0, d1)
        return self.grid.query(box[0] - pad, box[1] + pad)

    def interval(self, view: View, depth_range=(0.0, math.inf),
                 mask=None) -> tuple[np.ndarray, np.ndarray]:
        """Depth interval ``(bottom, top)`` of the material per pixel, each (ny, nx).

        Parameters
        ----------
        view : View
        depth_range : (dmin, dmax) [mm]
            Part of the pixel rays considered; default from the camera plane on.
        mask : bool ndarray (ny, nx), optional
            Only these pixels are rendered; the others stay ``+inf``.
        """
        dmin, dmax = float(depth_range[0]), float(depth_range[1])
        if mask is not None:
            mask = np.ascontiguousarray(mask, dtype=np.bool_)
            if mask.shape != view.shape:
                raise ValueError(f"mask: shape {mask.shape}, expected {view.shape}")
        if self.is_box:
            return _box_interval(self.bounds, view, dmin, dmax, mask)
        ids = self.triangles_near(view, (dmin, dmax), mask)
        bottom, top = rasterize_interval(view, self.vertices, self.faces, ids, (dmin, dmax),
                                         mask)
        if math.isfinite(dmax):
            self._inside_throughout(view, dmax, bottom, top, mask)
        return bottom, top

    def _inside_throughout(self, view: View, dmax: float, bottom: np.ndarray,
                           top: np.ndarray, mask) -> None:
        """Mark the pixels whose ray met no surface up to ``dmax`` but is inside the
        material all along (the first surface beyond ``dmax`` is an exit): ``bottom``
        becomes ``-inf`` (``top`` stays ``+inf``), in place."""
        miss = np.isposinf(bottom) & np.isposinf(top)
        if mask is not None:
            miss &= mask
        if not miss.any():
            return
        ids = self.triangles_near(view, (dmax, math.inf), miss)
        if ids.size == 0:
            return
        beyond, _ = rasterize_interval(view, self.vertices, self.faces, ids,
                                       (dmax, math.inf), miss)
        bottom[miss & np.isneginf(beyond)] = -np.inf

    def render(self, view: View, depth_range=(0.0, math.inf), mask=None) -> StockInterval:
        """:meth:`interval` wrapped with its view (for ``material_at``)."""
        b, t = self.interval(view, depth_range, mask)
        return StockInterval(view, b, t, (float(depth_range[0]), float(depth_range[1])))

    def contains(self, points, eps: float | None = None) -> np.ndarray:
        """True where world points (n, 3) are inside the stock (boundary within eps counts).

        Box: analytic. Mesh: one ray per point along +Z (a one-pixel view
        centred on the point, from ``eps`` below it), with the rasterizer's
        fill rule: inside when the first surface met is an exit, or an entry
        within ``eps``; points within ``eps`` of any triangle (walls along the
        ray included) also count. Exact for closed meshes; for an open mesh
        (``allow_open``) "inside" means "behind the sheet seen from below".
        """
        from .. import constants as K

        e = K.MEMBERSHIP_EPS_MM if eps is None else float(eps)
        p = np.ascontiguousarray(np.asarray(points, dtype=float).reshape(-1, 3))
        if self.is_box:
            lo, hi = self.bounds
            return np.all((p >= lo - e) & (p <= hi + e), axis=1)
        return KR.contains_mesh(self.vertices, self.faces, *self.grid._column_args(), p, e)


def _box_interval(bounds, view: View, dmin: float, dmax: float, mask):
    """Slab method per pixel centre, with the same range rules as the mesh path."""
    bottom = np.full(view.shape, np.inf)
    top = np.full(view.shape, np.inf)
    m, use = (mask, True) if mask is not None else (_NO_MASK, False)
    KR.box_interval(view.origin, view.basis, view.pixel_mm, np.ascontiguousarray(bounds[0]),
                    np.ascontiguousarray(bounds[1]), dmin, dmax, bottom, top, m, use)
    return bottom, top
