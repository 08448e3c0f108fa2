"""Stock.contains (numba ``contains_mesh`` through the grid's columns) against a numpy
twin that tests every triangle, and the columns' order the kernel relies on."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from errpred import constants as K
from errpred.raster import Stock
from errpred.raster import _kernels as KR


def _edge(ax, ay, bx, by, px, py):
    """numpy twin of ``_kernels._edge`` (the same arithmetic, elementwise)."""
    fwd = (ax < bx) | ((ax == bx) & (ay < by))
    return np.where(fwd, (bx - ax) * (py - ay) - (by - ay) * (px - ax),
                    -((ax - bx) * (py - by) - (ay - by) * (px - bx)))


def _owns(w, dx, dy):
    return (w > 0.0) | ((w == 0.0) & ((dy < 0.0) | ((dy == 0.0) & (dx > 0.0))))


def contains_twin(V, F, points, eps):
    """Every triangle against every point: the first surface a +Z ray from ``eps``
    below the point meets is an exit (or an entry within ``eps``), or a triangle is
    within ``eps`` (its distance by the kernel's own closest-point function, in Python)."""
    T = V[F]  # (m, 3, 3)
    lo, hi = T.min(axis=1), T.max(axis=1)
    out = np.zeros(len(points), dtype=bool)
    dist2 = KR._dist2_point_triangle.py_func
    for k, (px, py, pz) in enumerate(points):
        use = ~((hi[:, 2] < pz - eps) | (lo[:, 0] > px) | (hi[:, 0] < px)
                | (lo[:, 1] > py) | (hi[:, 1] < py))
        t = T[use] - [px, py, pz]
        x0, y0, z0 = t[:, 0].T
        x1, y1, z1 = t[:, 1].T
        x2, y2, z2 = t[:, 2].T
        area = _edge(x0, y0, x1, y1, x2, y2)
        front = area < 0.0
        x1, x2 = np.where(front, x2, x1), np.where(front, x1, x2)
        y1, y2 = np.where(front, y2, y1), np.where(front, y1, y2)
        z1, z2 = np.where(front, z2, z1), np.where(front, z1, z2)
        w0 = _edge(x1, y1, x2, y2, 0.0, 0.0)
        w1 = _edge(x2, y2, x0, y0, 0.0, 0.0)
        w2 = _edge(x0, y0, x1, y1, 0.0, 0.0)
        s = w0 + w1 + w2
        hit = ((area != 0.0) & _owns(w0, x2 - x1, y2 - y1) & _owns(w1, x0 - x2, y0 - y2)
               & _owns(w2, x1 - x0, y1 - y0) & (s > 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            z = (w0 * z0 + w1 * z1 + w2 * z2) / s
        hit &= z >= -eps
        first_front = np.min(z[hit & front], initial=np.inf)
        first_back = np.min(z[hit & ~front], initial=np.inf)
        inside = first_back < first_front or first_front <= eps
        if not inside and eps > 0.0:
            near = ~((lo[:, 0] > px + eps) | (hi[:, 0] < px - eps) | (lo[:, 1] > py + eps)
                     | (hi[:, 1] < py - eps) | (lo[:, 2] > pz + eps) | (hi[:, 2] < pz - eps))
            inside = any(dist2(px, py, pz, *T[j].ravel()) <= eps * eps
                         for j in np.flatnonzero(near))
        out[k] = inside
    return out


def _meshes():
    tilt = trimesh.transformations.rotation_matrix(0.4, [1.0, 0.3, 0.0])
    box = trimesh.creation.box(extents=[30.0, 12.0, 8.0])
    box.apply_transform(tilt)
    cyl = trimesh.creation.cylinder(radius=6.0, height=20.0, sections=48)
    cyl.apply_transform(trimesh.transformations.rotation_matrix(1.3, [0.0, 1.0, 0.2]))
    return {"tilted box": box, "lying cylinder": cyl, "sphere": trimesh.creation.icosphere(2, 7.0)}


@pytest.mark.parametrize("name", ["tilted box", "lying cylinder", "sphere"])
def test_contains_matches_numpy_twin(name):
    mesh = _meshes()[name]
    stock = Stock.from_mesh(mesh)
    rng = np.random.default_rng(17)
    lo, hi = mesh.bounds
    v = mesh.vertices
    surf, _ = trimesh.sample.sample_surface(mesh, 300, seed=3)
    e = K.MEMBERSHIP_EPS_MM
    pts = np.concatenate([rng.uniform(lo - 1.0, hi + 1.0, (1200, 3)), v, v + [0, 0, 2 * e],
                          v - [0, 0, 2 * e], surf, surf + rng.normal(0.0, e, surf.shape)])
    got = stock.contains(pts)
    assert np.array_equal(got, contains_twin(stock.vertices, stock.faces, pts, e))
    # closed meshes: the random points well off the surface agree with trimesh
    far = np.abs(trimesh.proximity.signed_distance(mesh, pts[:1200])) > 1e-3
    assert far.sum() > 1000
    assert np.array_equal(got[:1200][far], mesh.contains(pts[:1200][far]))
    assert 0 < got[:1200].sum() < 1200


def test_columns_list_triangles_highest_first():
    stock = Stock.from_mesh(_meshes()["lying cylinder"])
    g = stock.grid
    top = g.tri_hi[g.column_items, 2]
    col = np.repeat(np.arange(len(g.column_offsets) - 1), np.diff(g.column_offsets))
    same = col[1:] == col[:-1]
    assert same.sum() > 1000 and np.all(top[1:][same] <= top[:-1][same])
