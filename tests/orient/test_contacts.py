"""Nearest points of the design to ball centres (``orient.contacts.closest_points``): FCL's
answer is trimesh's exact one, on a dense free-form mesh (errpred's mold-ball design) and
for points on, in and far from it."""

from __future__ import annotations

import numpy as np
import trimesh

from errpred.scenario import bundled_scenario, load_scenario
from orient.contacts import closest_points


def test_closest_points_agree_with_trimesh_on_a_dense_free_form_mesh():
    design = load_scenario(bundled_scenario("mold-ball")).stock.load_design()
    rng = np.random.default_rng(7)
    # ball centres 5 mm above the surface, a few far away, on it, and inside the solid
    on = design.vertices[rng.choice(len(design.vertices), 60)]
    faces = rng.choice(len(design.faces), 60)
    normals = design.face_normals[faces]
    tri = design.triangles[faces].mean(axis=1)
    pts = np.vstack([tri + 5.0 * normals, tri - 0.05 * normals, on,
                     rng.uniform([-20, -20, 20], [80, 60, 40], (20, 3))])
    near, dist = closest_points(design, pts)
    p, d, _ = trimesh.proximity.closest_point(design, pts)
    assert np.allclose(dist, d, atol=1e-7)
    # the nearest point is unique except where several are equally near: compare distances
    assert np.allclose(np.linalg.norm(pts - near, axis=1), d, atol=1e-7)
    assert np.allclose(near, p, atol=1e-6)


def test_closest_points_of_nothing():
    box = trimesh.creation.box()
    near, dist = closest_points(box, np.zeros((0, 3)))
    assert near.shape == (0, 3) and dist.shape == (0,)


def test_ball_centres_inside_the_design_are_gouges():
    from nc.path import CutterLocations
    from orient.contacts import ball_contacts

    box = trimesh.creation.box(extents=(100.0, 100.0, 20.0))       # top face at z = 10
    n = 407
    x = np.linspace(-40, 40, n)
    # centres alternately 2 mm inside the box and 5 mm above its top (touching, R = 5)
    z = np.where(np.arange(n) % 2 == 0, 8.0, 15.0) - 5.0
    cl = CutterLocations.from_arrays(np.c_[x, np.zeros(n), z], np.tile([0, 0, 1.0], (n, 1)),
                                     1000.0, 10000.0, rapid=np.zeros(n, bool))
    c = ball_contacts(cl, 5.0, box)
    np.testing.assert_allclose(c.gap_mm[0::2], -2.0 - 5.0, atol=1e-9)
    np.testing.assert_allclose(c.gap_mm[1::2], 0.0, atol=1e-9)
    assert c.touching[1::2].all() and not c.touching[0::2].any()
    np.testing.assert_allclose(c.normal[1::2], np.tile([0, 0, 1.0], (n // 2, 1)), atol=1e-9)


def test_inside_test_agrees_with_trimesh_on_a_free_form_part():
    """The ball centres' inside test (errpred's grid of +Z rays) gives trimesh's ray-test
    answer on a curved closed mesh, at random points and 1e-3 of the radius inside and
    outside its surface; on the surface itself (its vertices) it says inside, as errpred's
    stock test does within its eps (trimesh's answer there is not defined)."""
    from orient.contacts import _contains

    mesh = trimesh.creation.icosphere(subdivisions=3, radius=10.0)
    mesh.apply_scale([1.0, 0.7, 0.5])                          # an ellipsoid
    rng = np.random.default_rng(3)
    pts = rng.uniform(-11, 11, (3000, 3))
    on = mesh.vertices[rng.choice(len(mesh.vertices), 50)] * (1 - 1e-3)   # just inside
    pts = np.vstack([pts, on, mesh.vertices[:50] * (1 + 1e-3)])           # and just outside
    got = _contains(mesh, pts)
    np.testing.assert_array_equal(got, mesh.contains(pts))
    assert got[3000:3050].all() and not got[3050:].any()
    assert _contains(mesh, mesh.vertices[::7]).all()
