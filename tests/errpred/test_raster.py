"""Tests of errpred.raster: views, the depth-interval rasterizer, the stock and its index."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from errpred.frames import tool_frame
from errpred.meshio import MeshFileError
from errpred.probe import StockProbe
from errpred.raster import Stock, TriangleGrid, View, coverage, material_at, rasterize_interval
from nc.errors import InputError

TOL = 1e-9  # float rounding on depths of tens of mm


def _unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _rotation(rng) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def _frames(seed: int, n: int = 4):
    """n random right-handed tool frames and one mirrored (counter-clockwise) frame."""
    rng = np.random.default_rng(seed)
    out = [_rotation(rng) for _ in range(n)]
    m = _rotation(rng)
    m[0] = -m[0]
    out.append(m)
    return rng, out


def _place(mesh: trimesh.Trimesh, tip, frame, centre_tool, rot_obj) -> trimesh.Trimesh:
    """Mesh rotated by rot_obj, centred at centre_tool in the tool frame, in world."""
    local = mesh.vertices @ rot_obj.T + centre_tool
    return trimesh.Trimesh(tip + local @ frame, mesh.faces.copy(), process=False)


def _same(a, b, tol=TOL):
    a, b = np.asarray(a), np.asarray(b)
    with np.errstate(invalid="ignore"):
        return (a == b) | (np.abs(a - b) <= tol)


# --- views -----------------------------------------------------------------

def test_view_along_axis_geometry():
    F = tool_frame(_unit([0.3, -0.2, 0.9]), [1.0, 0.5, 0.0])
    tip = np.array([10.0, -4.0, 7.0])
    v = View.along_axis(tip, F, 12.0, 12.0 / 64, depth_offset_mm=2.0)
    assert (v.nx, v.ny) == (64, 64) and v.handedness == 1
    np.testing.assert_allclose(v.direction, F[2])
    # tip projects onto the window centre, at depth = offset
    q = v.to_view(tip[None])[0]
    np.testing.assert_allclose(q, [6.0, 6.0, 2.0], atol=1e-12)
    # pixel (i, j) centre -> that pixel
    c = v.pixel_centres_world(depth=3.0)
    i, j, inside = v.pixel_of(c.reshape(-1, 3))
    assert inside.all()
    np.testing.assert_array_equal(i, np.repeat(np.arange(64), 64))
    np.testing.assert_array_equal(j, np.tile(np.arange(64), 64))
    # a point in tool coordinates (x', y') lands at u = x' + 6, v = y' + 6
    p = tip + np.array([1.0, -2.0, 0.5]) @ F
    np.testing.assert_allclose(v.to_view(p[None])[0], [7.0, 4.0, 2.5], atol=1e-12)
    _, _, out = v.pixel_of(tip[None] + 7.0 * F[0])
    assert not out[0]
    # non-integer window: rounds up, stays centred
    w = View.along_axis(tip, F, 10.0, 0.3, 0.0)
    assert w.nx == 34
    np.testing.assert_allclose(w.to_view(tip[None])[0, :2], [5.1, 5.1], atol=1e-12)
    # a mirrored frame gives a mirrored view
    Fm = tool_frame([0, 0, 1], [1, 0, 0], rotation_sign=-1)
    assert View.along_axis(tip, Fm, 4.0, 0.5, 1.0).handedness == -1


def test_view_side_geometry():
    F = tool_frame([0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    tip = np.array([1.0, 2.0, 3.0])
    az = math.radians(90.0)  # camera on +x', looking toward -x'
    v = View.side(tip, F, az, width_mm=6.0, height_mm=2.0, pixel_mm=0.5)
    np.testing.assert_allclose(v.direction, [-1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(v.v_axis, [0.0, 0.0, 1.0], atol=1e-12)
    assert v.handedness == 1 and (v.nx, v.ny) == (12, 4)
    # the tip is at the bottom edge of the window, laterally centred, at depth W/2
    np.testing.assert_allclose(v.to_view(tip[None])[0], [3.0, 0.0, 3.0], atol=1e-12)
    # the flute point at phi = az, radius 3 is at depth 0 (camera plane tangent)
    p = tip + np.array([3.0 * math.sin(az), 3.0 * math.cos(az), 1.0]) @ F
    np.testing.assert_allclose(v.to_view(p[None])[0], [3.0, 1.0, 0.0], atol=1e-12)
    with pytest.raises(ValueError):
        View(np.zeros(3), np.diag([1.0, 2.0, 1.0]), 0.1, 4, 4)


def test_zoomed_view_keeps_plane_and_direction():
    F = tool_frame(_unit([0.2, 0.1, 1.0]), [0.0, 1.0, 0.0])
    v = View.along_axis([0.0, 0.0, 0.0], F, 10.0, 10 / 64, 1.0)
    c = np.array([1.0, 0.5, 0.2])
    z = v.zoomed(c, 1.0, 1.0 / 64)
    np.testing.assert_allclose(z.basis, v.basis)
    np.testing.assert_allclose(z.to_view(c[None])[0], [0.5, 0.5, v.to_view(c[None])[0, 2]],
                               atol=1e-12)


# --- 1. analytic shapes in arbitrary tool frames -------------------------------

def _ray_sphere(o, d, c, r):
    oc = o - c
    b = oc @ d
    disc = b * b - (np.sum(oc * oc, axis=-1) - r * r)
    s = np.sqrt(np.maximum(disc, 0.0))
    return disc > 0, -b - s, -b + s


def test_sphere_entry_exit_within_chord_bound():
    """Icosphere (subdivisions 4) vs the analytic sphere, at pixel centres.

    Bound: the icosphere is a convex polyhedron with its vertices on the
    sphere of radius r, so it contains the ball of radius r_min = the least
    distance from the centre to a face plane (chord error r - r_min = 4.6 um
    for r = 4) and lies inside the ball of radius r. Along any ray that
    meets the inner ball, the mesh entry therefore lies between the entries
    of the two balls and the exit between their exits; we compare at pixel
    centres (where the rays are cast), so the only error is this mesh
    approximation: depth error <= sqrt(r^2 - rho^2) - sqrt(r_min^2 - rho^2)
    (rho the ray's distance from the centre). Excluded: rays that meet the
    outer ball but miss the inner one (the silhouette band, r - r_min wide,
    far less than one pixel), where the mesh may or may not be hit.
    Rays missing the outer ball must see nothing.
    """
    r = 4.0
    ico = trimesh.creation.icosphere(subdivisions=4, radius=r)
    rng, frames = _frames(11)
    for F in frames:
        tip = rng.uniform(-50, 50, 3)
        c_tool = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), 6.0])
        mesh = _place(ico, tip, F, c_tool, _rotation(rng))
        centre = tip + c_tool @ F
        r_min = np.min(np.abs(np.sum(mesh.face_normals * (mesh.triangles[:, 0] - centre), axis=1)))
        assert 0 < r - r_min < 1e-2
        view = View.along_axis(tip, F, 12.0, 12.0 / 64, depth_offset_mm=2.0)
        bottom, top = Stock.from_mesh(mesh).interval(view)
        o = view.ray_origins_world()
        hit_out, in_out, ex_out = _ray_sphere(o, view.direction, centre, r)
        hit_in, in_in, ex_in = _ray_sphere(o, view.direction, centre, r_min)
        assert np.all(np.isinf(bottom[~hit_out]) & np.isinf(top[~hit_out]))
        m = hit_in
        assert m.sum() > 1000
        assert np.all((bottom[m] >= in_out[m] - TOL) & (bottom[m] <= in_in[m] + TOL))
        assert np.all((top[m] <= ex_out[m] + TOL) & (top[m] >= ex_in[m] - TOL))
        band = hit_out & ~hit_in
        assert band.sum() < 0.05 * m.sum()


def _ray_cylinder(o, d, r, h):
    """Ray vs the solid cylinder x^2 + y^2 <= r^2, |z| <= h/2 (local coordinates)."""
    a = d[0] ** 2 + d[1] ** 2
    b = o[..., 0] * d[0] + o[..., 1] * d[1]
    c = o[..., 0] ** 2 + o[..., 1] ** 2 - r * r
    disc = b * b - a * c
    s = np.sqrt(np.maximum(disc, 0.0))
    t0, t1 = (-b - s) / a, (-b + s) / a
    z0, z1 = (-h / 2 - o[..., 2]) / d[2], (h / 2 - o[..., 2]) / d[2]
    entry = np.maximum(t0, np.minimum(z0, z1))
    exit_ = np.minimum(t1, np.maximum(z0, z1))
    return (disc > 0) & (entry < exit_), entry, exit_


def test_cylinder_entry_exit_within_chord_bound():
    """Cylinder with 64 sections vs the analytic cylinder, at pixel centres.

    Bound: the mesh is the prism over the inscribed 64-gon, so it contains
    the cylinder of radius r_min = r cos(pi/64) (chord error r (1 - cos(pi/64))
    = 3.6 um for r = 3) and lies inside the cylinder of radius r, with the same
    caps. Both solids are convex, so along a ray meeting the inner one the
    mesh entry lies between the two entries and the exit between the two
    exits (pixel centres only: the mesh approximation is the only error).
    Excluded: rays meeting the outer cylinder but not the inner one (the
    silhouette band, narrower than a pixel).
    """
    r, h, sections = 3.0, 8.0, 64
    cyl = trimesh.creation.cylinder(radius=r, height=h, sections=sections)
    rad = np.hypot(cyl.vertices[:, 0], cyl.vertices[:, 1])
    assert np.allclose(rad[rad > 1e-9], r)
    r_min = r * math.cos(math.pi / sections)
    rng, frames = _frames(12)
    for F in frames:
        tip = rng.uniform(-50, 50, 3)
        c_tool = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), 7.0])
        R = _rotation(rng)
        mesh = _place(cyl, tip, F, c_tool, R)
        view = View.along_axis(tip, F, 12.0, 12.0 / 64, depth_offset_mm=1.0)
        bottom, top = Stock.from_mesh(mesh).interval(view)
        # rays in the cylinder's local coordinates: world = centre + R_w @ local
        centre = tip + c_tool @ F
        R_w = F.T @ R
        o = (view.ray_origins_world() - centre) @ R_w
        d = view.direction @ R_w
        hit_out, in_out, ex_out = _ray_cylinder(o, d, r, h)
        hit_in, in_in, ex_in = _ray_cylinder(o, d, r_min, h)
        assert np.all(np.isinf(bottom[~hit_out]) & np.isinf(top[~hit_out]))
        m = hit_in
        assert m.sum() > 500
        assert np.all((bottom[m] >= in_out[m] - TOL) & (bottom[m] <= in_in[m] + TOL))
        assert np.all((top[m] <= ex_out[m] + TOL) & (top[m] >= ex_in[m] - TOL))
        assert (hit_out & ~hit_in).sum() < 0.05 * m.sum()


def _grid_plane(side: float, n: int) -> trimesh.Trimesh:
    x = np.linspace(-side / 2, side / 2, n + 1)
    xx, yy = np.meshgrid(x, x, indexing="ij")
    V = np.column_stack([xx.ravel(), yy.ravel(), np.zeros(xx.size)])
    idx = np.arange(V.shape[0]).reshape(n + 1, n + 1)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return trimesh.Trimesh(V, F, process=False)  # normal +z


def test_plane_depth_exact_both_sides():
    """A tilted plane (open mesh, 40x40 grid, larger than the window: no silhouette).

    A plane has no approximation error, so depths match the analytic ray to
    rounding. Facing the camera it is an entry (bottom = t, top = +inf);
    facing away an exit (top = t, bottom = -inf: material from the start).
    """
    plane = _grid_plane(200.0, 40)
    rng, frames = _frames(13)
    for k, F in enumerate(frames):
        tip = rng.uniform(-50, 50, 3)
        # plane normal in the tool frame, at least 0.3 along the axis
        n = rng.normal(size=3)
        n[2] = (1 if k % 2 else -1) * max(abs(n[2]), 0.3 * np.linalg.norm(n[:2]) + 0.5)
        n /= np.linalg.norm(n)
        # rotation taking +z to n
        a = np.cross([0.0, 0.0, 1.0], n)
        s, c = np.linalg.norm(a), n[2]
        K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
        R = np.eye(3) + K + K @ K * ((1 - c) / s ** 2)
        mesh = _place(plane, tip, F, np.array([0.3, -0.2, 5.0]), R)
        view = View.along_axis(tip, F, 12.0, 12.0 / 64, depth_offset_mm=60.0)
        bottom, top = Stock.from_mesh(mesh, allow_open=True).interval(view)
        n_w = mesh.face_normals[0]  # (a mirrored frame mirrors the mesh too)
        p0 = tip + np.array([0.3, -0.2, 5.0]) @ F
        o = view.ray_origins_world()
        t = ((p0 - o) @ n_w) / (view.direction @ n_w)
        assert np.all(t > 0)
        if n_w @ view.direction < 0:
            assert np.all(_same(bottom, t)) and np.all(np.isposinf(top))
        else:
            assert np.all(_same(top, t)) and np.all(np.isneginf(bottom))


# --- 2. closed non-convex STL vs trimesh ray casting ---------------------------

def _heightfield_solid(h, nx=45, ny=47, size=(20.0, 20.0)) -> trimesh.Trimesh:
    """Closed solid 0 <= z <= h(x, y) over a rectangle, as a watertight mesh."""
    x = np.linspace(0, size[0], nx + 1)
    y = np.linspace(0, size[1], ny + 1)
    xx, yy = np.meshgrid(x, y, indexing="ij")
    top = np.column_stack([xx.ravel(), yy.ravel(), h(xx, yy).ravel()])
    bot = np.column_stack([xx.ravel(), yy.ravel(), np.zeros(xx.size)])
    V = np.concatenate([top, bot])
    nb = top.shape[0]
    idx = np.arange(nb).reshape(nx + 1, ny + 1)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    faces = [np.column_stack([a, b, c]), np.column_stack([a, c, d]),
             np.column_stack([a, c, b]) + nb, np.column_stack([a, d, c]) + nb]
    loop = ([idx[i, 0] for i in range(nx)] + [idx[nx, j] for j in range(ny)]
            + [idx[i, ny] for i in range(nx, 0, -1)] + [idx[0, j] for j in range(ny, 0, -1)])
    p = np.array(loop)
    q = np.roll(p, -1)
    faces += [np.column_stack([p + nb, q + nb, q]), np.column_stack([p + nb, q, p])]
    mesh = trimesh.Trimesh(V, np.concatenate(faces), process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    return mesh


def _height(x, y):
    return (8.0 + 3.0 * np.exp(-((x - 6) ** 2 + (y - 7) ** 2) / 8.0)
            - 2.5 * np.exp(-((x - 13) ** 2 + (y - 11) ** 2) / 4.0) + 0.4 * np.sin(0.9 * x + y))


def _seg_dist(p, a, b):
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, axis=1) / np.maximum(np.sum(ab * ab, axis=1), 1e-300), 0, 1)
    return np.linalg.norm(a + t[:, None] * ab - p, axis=1)


@pytest.mark.parametrize("camera_z", [1.0, -3.0])
def test_stl_top_surface_matches_trimesh_rays(tmp_path, camera_z):
    """Top surface seen from below (the ``top`` buffer) = first back-face hit of trimesh rays.

    camera_z = 1: the camera is inside the solid (bottom = -inf); -3: below
    it (bottom = the base, 3 mm away). Tolerance 1e-6 mm; pixels whose ray
    passes within 1e-6 mm of a mesh edge (grazing) may differ.
    """
    path = tmp_path / "stock.stl"
    _heightfield_solid(_height).export(path)
    stock = Stock.from_stl(path)
    mesh = stock.mesh
    tip = np.array([9.37, 10.21, camera_z + 0.5])
    view = View.along_axis(tip, np.eye(3), 12.0, 12.0 / 64, depth_offset_mm=0.5)
    bottom, top = stock.interval(view)
    o = view.ray_origins_world().reshape(-1, 3)
    d = np.tile(view.direction, (o.shape[0], 1))
    loc, ray, tri = mesh.ray.intersects_location(o, d, multiple_hits=True)
    depth = np.sum((loc - o[ray]) * d[ray], axis=1)
    back = mesh.face_normals[tri] @ view.direction > 0
    want_top = np.full(o.shape[0], np.inf)
    np.minimum.at(want_top, ray[back], depth[back])
    want_bottom = np.full(o.shape[0], np.inf)
    np.minimum.at(want_bottom, ray[~back], depth[~back])
    want_bottom[want_top < want_bottom] = -np.inf
    got_top, got_bottom = top.ravel(), bottom.ravel()
    assert np.all(np.isfinite(want_top))
    bad = ~(_same(got_top, want_top, 1e-6) & _same(got_bottom, want_bottom, 1e-6))
    if bad.any():  # only grazing rays may differ
        e = mesh.edges_unique
        a, b = mesh.vertices[e[:, 0], :2], mesh.vertices[e[:, 1], :2]
        for k in np.nonzero(bad)[0]:
            assert _seg_dist(np.broadcast_to(o[k, :2], a.shape), a, b).min() < 1e-6
    assert bad.sum() <= 5
    if camera_z > 0:
        assert np.all(np.isneginf(bottom))
    else:
        assert np.allclose(bottom, 3.0, atol=1e-12)
    np.testing.assert_allclose(top.ravel(), _height(o[:, 0], o[:, 1]) - camera_z, atol=0.2)


# --- 3. watertight fill ----------------------------------------------------------

@pytest.mark.parametrize("mirror", [False, True])
def test_fill_rule_pixel_centres_on_edges_and_vertices(mirror):
    """Vertices on pixel centres, edges through them: each centre is covered exactly once.

    A 4 mm box subdivided to 0.25 mm triangles, viewed along +Z with 0.25 mm
    pixels whose centres are the vertices' x, y: every centre inside the
    silhouette lies on a shared edge or vertex. A strict inside test would
    leave cracks (+inf), an inclusive one would count twice.
    """
    mesh = trimesh.creation.box(extents=[4.0, 4.0, 4.0])
    mesh.apply_translation([2.0, 2.0, 2.0])
    for _ in range(4):
        mesh = mesh.subdivide()
    assert mesh.is_watertight
    basis = np.eye(3)
    origin = np.array([-1.125, -1.125, -5.0])
    if mirror:
        basis[0] = -basis[0]
        origin[0] = 5.125
    view = View(origin, basis, 0.25, 26, 26)
    c = view.pixel_centres_world()
    inner = (c[..., 0] > 1e-9) & (c[..., 0] < 4 - 1e-9) & (c[..., 1] > 1e-9) & (c[..., 1] < 4 - 1e-9)
    outer = (c[..., 0] < -1e-9) | (c[..., 0] > 4 + 1e-9) | (c[..., 1] < -1e-9) | (c[..., 1] > 4 + 1e-9)
    front, back = coverage(view, mesh.vertices, mesh.faces)
    assert np.all(front[inner] == 1) and np.all(back[inner] == 1)
    assert np.all(front[outer] == 0) and np.all(back[outer] == 0)
    bottom, top = Stock.from_mesh(mesh).interval(view)
    assert np.all(bottom[inner] == 5.0) and np.all(top[inner] == 9.0)


def test_shared_edge_through_centres_within_rounding():
    """Two triangles share an edge that passes within rounding error of pixel centres.

    The edge runs along Y = 3 X (pixel space), its endpoints rounded, so the
    edge function at the centres (k, 3k) is of the order of the rounding
    error: evaluated in the two triangles' own vertex orders its sign would
    disagree (cracks or double cover at ~25% of them). The canonical
    evaluation makes each centre covered exactly once.
    """
    from errpred.raster import _kernels as KR

    rng = np.random.default_rng(3)
    no_mask = np.zeros((1, 1), dtype=bool)
    n = np.array([-3.0, 1.0]) / math.sqrt(10.0)
    tested = 0
    for _ in range(300):
        xa, xb = np.sort(rng.uniform(0.5, 19.5, 2))
        if xb - xa < 3:
            continue
        A, B = np.array([xa + 0.5, 3 * xa + 0.5]), np.array([xb + 0.5, 3 * xb + 0.5])
        C, D = (A + B) / 2 + 20 * n, (A + B) / 2 - 20 * n
        tris = np.array([[[*A, 1.0], [*B, 1.0], [*C, 1.0]], [[*B, 1.0], [*A, 1.0], [*D, 1.0]]])
        f, b = np.zeros((64, 24)), np.zeros((64, 24))
        KR.raster_view_tris(tris, 1.0, 1.0, -np.inf, np.inf, f, b, no_mask, False, True)
        for k in range(int(np.ceil(xa + 1e-6)), int(np.floor(xb - 1e-6)) + 1):
            assert f[3 * k, k] + b[3 * k, k] == 1
            tested += 1
    assert tested > 1000


def test_no_cracks_random_views():
    """Convex closed meshes in random views: every ray crosses exactly as many
    front as back faces (0 or 1 each), and every pixel inside the silhouette
    has finite bottom and top."""
    rng, frames = _frames(21)
    box = trimesh.creation.box(extents=[5.0, 3.0, 4.0])
    for _ in range(3):
        box = box.subdivide()
    shapes = [trimesh.creation.icosphere(subdivisions=3, radius=4.0), box]
    for F in frames:
        for shape in shapes:
            mesh = _place(shape, np.zeros(3), F, np.array([0.1, 0.2, 5.0]), _rotation(rng))
            view = View.along_axis(np.zeros(3), F, 12.0, rng.uniform(0.05, 0.2), 1.0)
            front, back = coverage(view, mesh.vertices, mesh.faces)
            assert np.array_equal(front, back)
            assert front.max() == 1 and front.sum() > 100
            bottom, top = Stock.from_mesh(mesh).interval(view)
            covered = front == 1
            assert np.all(np.isfinite(bottom[covered]) & np.isfinite(top[covered]))
            assert np.all(np.isinf(bottom[~covered]) & np.isinf(top[~covered]))
    # the box, analytically: rays meeting the (slightly shrunk) box are covered
    lo, hi = np.array([-2.5, -1.5, -2.0]), np.array([2.5, 1.5, 2.0])
    shrunk = Stock.from_box(lo + 1e-6, hi - 1e-6)
    for F in frames:
        view = View.along_axis(-6.0 * F[2], F, 12.0, 0.1, 1.0)
        front, back = coverage(view, box.vertices, box.faces)
        inside = np.isfinite(shrunk.interval(view)[1])
        assert inside.sum() > 100 and np.all(front[inside] == 1) and np.all(back[inside] == 1)


# --- 4. analytic box vs box mesh ---------------------------------------------------

def test_box_stock_equals_box_mesh():
    lo, hi = np.array([-3.0, -2.0, -1.0]), np.array([4.0, 5.0, 3.0])
    box = Stock.from_box(lo, hi)
    mesh = trimesh.creation.box(bounds=np.stack([lo, hi])).subdivide().subdivide()
    as_mesh = Stock.from_mesh(mesh)
    grown, shrunk = Stock.from_box(lo - 1e-7, hi + 1e-7), Stock.from_box(lo + 1e-7, hi - 1e-7)
    rng, frames = _frames(31)
    checked = 0
    for F in frames:
        tip = rng.uniform(-2, 2, 3)
        view = View.along_axis(tip, F, 12.0, 12.0 / 64, depth_offset_mm=8.0)
        mid = float(view.to_view(tip[None])[0, 2])
        for rng_ in [(0.0, math.inf), (mid, math.inf), (0.0, mid), (-math.inf, math.inf)]:
            b0, t0 = box.interval(view, rng_)
            b1, t1 = as_mesh.interval(view, rng_)
            # definite pixels: same answer for the box grown and shrunk by 1e-7
            # (not grazing an edge), and no surface within 1e-7 of dmin / dmax
            bg, tg = grown.interval(view, rng_)
            bs, ts = shrunk.interval(view, rng_)
            definite = (np.isfinite(bg) == np.isfinite(bs)) & (np.isfinite(tg) == np.isfinite(ts))
            definite &= (np.isneginf(bg) == np.isneginf(bs))
            assert definite.sum() > 0.9 * definite.size
            assert np.all(_same(b0, b1)[definite]) and np.all(_same(t0, t1)[definite])
            checked += int(np.isfinite(t0[definite]).sum())
        # rays starting inside the box (at depth mid) begin in material
        start_in = box.contains(view.pixel_centres_world(mid).reshape(-1, 3), eps=-1e-6)
        b_mid = as_mesh.interval(view, (mid, math.inf))[0].ravel()
        assert start_in.sum() > 100 and np.all(np.isneginf(b_mid[start_in]))
    assert checked > 10000


def test_a_ray_inside_the_material_over_its_whole_range_is_material():
    """A view buried in a block (camera and range end both inside): every pixel in the
    block's silhouette is material over the whole range, -inf..+inf, for the box and its
    mesh alike; beside the block, a miss; with the range reaching the block's top, the
    top is found, with the range ending there or open."""
    lo, hi = np.array([0.0, 0.0, -50.0]), np.array([40.0, 40.0, 0.0])
    box = Stock.from_box(lo, hi)
    as_mesh = Stock.from_mesh(trimesh.creation.box(bounds=np.stack([lo, hi])))
    F = tool_frame(np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
    view = View.along_axis(np.array([2.0, 20.0, -30.0]), F, 12.0, 12.0 / 64, 5.0)
    x = view.pixel_centres_world(0.0)[..., 0]        # world x of each pixel centre
    inside, outside = x > 1e-6, x < -1e-6
    assert inside.sum() > 1000 and outside.sum() > 1000
    for stock in (box, as_mesh):
        b, t = stock.interval(view, (0.0, 25.0))     # camera at z -35, range end at -10
        assert np.all(np.isneginf(b[inside])) and np.all(np.isposinf(t[inside]))
        assert np.all(np.isposinf(b[outside])) and np.all(np.isposinf(t[outside]))
        for end in (40.0, math.inf):                  # the range reaches the top (z 0)
            b, t = stock.interval(view, (0.0, end))
            assert np.all(np.isneginf(b[inside]))
            np.testing.assert_allclose(t[inside], 35.0, atol=1e-9)
            assert np.all(np.isposinf(t[outside]))
        # the points of the buried range are in the material
        pts = view.pixel_centres_world(10.0)
        np.testing.assert_array_equal(
            material_at(view, *stock.interval(view, (0.0, 25.0)), pts.reshape(-1, 3)),
            inside.ravel())
    # a side view from inside the block, as of a ball in a slot (errpred.probe): the probe
    # answers as the exact membership test does
    side = View.side(np.array([3.0, 20.0, -30.0]), F, 0.7, 12.0, 8.0, 12.0 / 64)
    pts = np.random.default_rng(5).uniform([-9.0, 8.0, -32.0], [15.0, 32.0, -20.0], (8000, 3))
    for stock in (box, as_mesh):
        probe = StockProbe(stock, side, (0.0, 12.0))
        # (away from the face x = 0 by a pixel: a point between pixel centres gets its
        # pixel's answer)
        seen = side.pixel_of(pts)[2] & (side.to_view(pts)[:, 2] >= 0.0) \
            & (side.to_view(pts)[:, 2] <= 12.0) & (np.abs(pts[:, 0]) > 12.0 / 64)
        exact = as_mesh.contains(pts[seen])
        assert exact.sum() > 200 and (~exact).sum() > 200
        np.testing.assert_array_equal(probe(pts[seen]), exact)


# --- 5. spatial index ----------------------------------------------------------------

def test_grid_index_superset_and_selective():
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=10.0)
    big = trimesh.creation.box(extents=[30.0, 30.0, 2.0])  # 12 large triangles
    mesh = trimesh.util.concatenate([sphere, big])
    V, F = mesh.vertices, mesh.faces
    tv = V[F]
    tlo, thi = tv.min(axis=1), tv.max(axis=1)
    rng = np.random.default_rng(5)
    for grid in (TriangleGrid(V, F), TriangleGrid(V, F, max_span=1)):
        assert len(grid.big) >= 12
        for _ in range(60):
            c = rng.uniform(-16, 16, 3)
            half = rng.uniform(0.0, 4.0, 3) * rng.choice([0.1, 1.0])
            qlo, qhi = c - half, c + half
            got = grid.query(qlo, qhi)
            assert len(np.unique(got)) == len(got)
            want = np.nonzero(np.all(tlo <= qhi, axis=1) & np.all(thi >= qlo, axis=1))[0]
            assert set(got.tolist()) == set(want.tolist())
    # a small query near the surface sees a tiny part of the mesh
    grid = TriangleGrid(V, F)
    p = sphere.vertices[17]
    got = grid.query(p - 0.5, p + 0.5)
    assert 0 < len(got) < 0.01 * len(F)
    # and a small view over a large mesh draws only triangles near the window
    stock = Stock.from_mesh(trimesh.creation.icosphere(subdivisions=6, radius=30.0))
    view = View.along_axis(np.array([0.0, 0.0, -35.0]), np.eye(3), 2.0, 2.0 / 64, 0.0)
    ids = stock.triangles_near(view)
    assert 0 < len(ids) < 0.01 * len(stock.faces)
    full = rasterize_interval(view, stock.vertices, stock.faces)
    part = stock.interval(view)
    assert np.array_equal(full[0], part[0]) and np.array_equal(full[1], part[1])


# --- 6. errors -------------------------------------------------------------------------

def test_from_stl_errors_name_the_file(tmp_path):
    missing = tmp_path / "nope.stl"
    with pytest.raises(MeshFileError, match="nope.stl.*not found"):
        Stock.from_stl(missing)
    box = trimesh.creation.box(extents=[1.0, 1.0, 1.0])
    open_mesh = trimesh.Trimesh(box.vertices, box.faces[:-1])
    path = tmp_path / "open_part.stl"
    open_mesh.export(path)
    with pytest.raises(MeshFileError, match="open_part.stl.*not watertight"):
        Stock.from_stl(path)
    s = Stock.from_stl(path, allow_open=True)
    assert not s.is_box and s.faces.shape[0] == 11
    bad = tmp_path / "garbage.stl"
    bad.write_text("this is not an stl")
    with pytest.raises(MeshFileError, match="garbage.stl"):
        Stock.from_stl(bad)
    assert issubclass(MeshFileError, InputError)


# --- masks, membership ---------------------------------------------------------------

def test_mask_renders_only_masked_pixels():
    rng, frames = _frames(41, n=2)
    mesh = _heightfield_solid(_height)
    stock, box = Stock.from_mesh(mesh), Stock.from_box([0, 0, 0], [20, 20, 9])
    for F in frames:
        view = View.along_axis(np.array([10.0, 10.0, 5.0]), F, 8.0, 0.125, 20.0)
        mask = rng.random(view.shape) < 0.2
        mask[:10] = False
        for s in (stock, box):
            b, t = s.interval(view)
            bm, tm = s.interval(view, mask=mask)
            assert np.array_equal(bm[mask], b[mask]) and np.array_equal(tm[mask], t[mask])
            assert np.all(np.isposinf(bm[~mask]) & np.isposinf(tm[~mask]))


def test_contains_and_material_at():
    rng = np.random.default_rng(8)
    mesh = _heightfield_solid(_height)
    stock = Stock.from_mesh(mesh)
    pts = np.column_stack([rng.uniform(-1, 21, 1500), rng.uniform(-1, 21, 1500),
                           rng.uniform(-1, 13, 1500)])
    assert np.array_equal(stock.contains(pts), mesh.contains(pts))
    # on the boundary (within MEMBERSHIP_EPS_MM = 1e-6) counts as inside, also on
    # the vertical walls that a vertical ray runs along; 2e-6 off is decided
    v = mesh.vertices
    on_top = v[:, 2] > 1.0
    assert stock.contains(v).all()
    assert np.array_equal(stock.contains(v + [0, 0, 2e-6]), ~on_top)
    assert np.array_equal(stock.contains(v - [0, 0, 2e-6]), on_top)
    wall = np.column_stack([np.zeros(50), rng.uniform(1, 19, 50), rng.uniform(0.5, 5, 50)])
    assert stock.contains(wall).all() and not stock.contains(wall - [2e-6, 0, 0]).any()
    box = Stock.from_box([0, 0, 0], [1, 2, 3])
    assert box.contains([[0.5, 1, 1], [0.5, 1, 3 + 1e-7], [1.1, 1, 1]]).tolist() == [True, True, False]
    # material_at: bottom view of the box from inside it
    view = View.along_axis(np.array([0.5, 1.0, 1.0]), np.eye(3), 0.8, 0.05, 0.5)
    si = box.render(view)
    assert np.all(np.isneginf(si.bottom)) and np.allclose(si.top, 2.5)
    q = np.array([[0.5, 1.0, 2.9], [0.5, 1.0, 3.1], [0.5, 1.0, 0.2], [0.95, 1.0, 1.0]])
    assert si.material_at(q).tolist() == [True, False, True, False]
