"""Interference checks (orient/interference.py) against analytic geometry.

References are closed forms (gaps of a vertical tool above a face, the tilt
angle at which a cylinder's side meets a wall edge, the distance of a
cylinder from a line edge) and a brute-force distance: the workpiece surface
sampled on a fine barycentric grid, each sample's exact distance to the solid
cylinder in closed form.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from errpred.tool import Holder, Tool
from orient.interference import DISTANCE_ACCURACY_MM as ACC
from orient.interference import InterferenceChecker, Part, ToolAssembly

R = 3.0            # ball radius [mm]
FLUTE = 12.0
OVERHANG = 30.0
RNG_SEED = 20240611


def ball(shank_d=6.0, overhang=OVERHANG, holder=None, flute=FLUTE):
    return Tool("ball", 2 * R, flute_length_mm=flute, overhang_mm=overhang,
                shank_diameter_mm=shank_d, holder=holder)


def block(x0, x1, y0, y1, z0, z1):
    b = trimesh.creation.box(extents=(x1 - x0, y1 - y0, z1 - z0))
    b.apply_translation([(x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2])
    return b


def floor_and_wall(w, H):
    """Floor top at z = 0; wall block x in [w, w + 20], top at z = H."""
    return trimesh.util.concatenate([block(-40, 40, -30, 30, -10, 0),
                                     block(w, w + 20, -30, 30, -10, H)])


def bumpy(n=30, size=60.0, amp=4.0):
    x = np.linspace(-size / 2, size / 2, n + 1)
    X, Y = np.meshgrid(x, x)
    Z = amp * np.sin(X / 6.0) * np.cos(Y / 8.0)
    V = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), \
        idx[:-1, 1:].ravel()
    F = np.vstack([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return trimesh.Trimesh(V, F, process=False)


def tilted(theta):
    """Axis tilted by theta from +z toward +x; ball centre at (0, 0, R)."""
    u = np.array([math.sin(theta), 0.0, math.cos(theta)])
    return np.array([0.0, 0.0, R]) - R * u, u


# --- the assembly ------------------------------------------------------------------
def test_assembly_parts_from_tool():
    asm = ToolAssembly.from_tool(ball(8.0, holder=Holder(32.0, 40.0)), clearance_mm=0.3)
    assert asm.names == ("flank", "shank", "holder")
    f, s, h = asm.parts
    assert (f.radius_mm, f.z0_mm, f.z1_mm) == (R, R, FLUTE)   # ball excluded: from its centre
    assert (s.radius_mm, s.z0_mm, s.z1_mm) == (4.0, FLUTE, OVERHANG)
    assert (h.radius_mm, h.z0_mm, h.z1_mm) == (16.0, OVERHANG, OVERHANG + 40.0)
    assert asm.clearance_mm == 0.3 and asm.cutting_top_mm == R
    # no flank when the flutes end at the ball's equator, no shank without overhang
    assert ToolAssembly.from_tool(ball(flute=R)).names == ("shank",)
    assert ToolAssembly.from_tool(ball(overhang=FLUTE)).names == ("flank",)
    with pytest.raises(ValueError, match="clearance_mm"):
        ToolAssembly.from_tool(ball(), clearance_mm=-1.0)
    with pytest.raises(ValueError, match="z0_mm < z1_mm"):
        ToolAssembly((Part("shank", 3.0, 5.0, 5.0),), R)


# --- gaps above a face -------------------------------------------------------------
@pytest.mark.parametrize("prefilter", [False, True])
def test_vertical_tool_above_top_face_distances_are_the_gaps(prefilter):
    asm = ToolAssembly.from_tool(ball(holder=Holder(32.0, 40.0)), clearance_mm=0.5)
    ch = InterferenceChecker(block(-50, 50, -50, 50, -20, 0), asm, prefilter=prefilter,
                             distance_horizon_mm=100.0)
    gaps = np.array([0.0, 0.37, 2.0, 7.3])
    tips = np.column_stack([np.full(4, 4.2), np.full(4, -6.1), gaps])
    res = ch.check(tips, np.tile([0.0, 0.0, 1.0], (4, 1)), distances=True)
    assert res.exact.all()
    np.testing.assert_allclose(res.distance("flank"), gaps + R, atol=ACC)
    np.testing.assert_allclose(res.distance("shank"), gaps + FLUTE, atol=ACC)
    np.testing.assert_allclose(res.distance("holder"), gaps + OVERHANG, atol=ACC)
    assert res.feasible.all() and (res.part == -1).all()


def test_clearance_beside_a_wall_and_no_clearance_into_the_cutting_zone():
    """Vertical tool beside a wall face: the shank (r 4) collides iff its gap is
    below the clearance. The clearance never reaches below the flank's start:
    a tool without flank (flutes end at the equator) standing on a floor with a
    clearance larger than R does not collide."""
    c = 0.5
    wall = block(0, 20, -30, 30, -30, 30)
    ch = InterferenceChecker(wall, ToolAssembly.from_tool(ball(8.0)), clearance_mm=c)
    gap = np.array([c - 0.01, c + 0.01])
    res = ch.check(np.column_stack([-4.0 - gap, np.zeros(2), np.zeros(2)]),
                   np.tile([0.0, 0.0, 1.0], (2, 1)), distances=True)
    np.testing.assert_allclose(res.distance("shank"), gap, atol=ACC)
    np.testing.assert_allclose(res.distance("flank"), gap + 1.0, atol=ACC)
    assert res.collides.tolist() == [True, False] and not res.gouges.any()
    assert res.part_label.tolist() == ["shank", ""]
    no_flank = InterferenceChecker(block(-30, 30, -30, 30, -10, 0),
                                   ToolAssembly.from_tool(ball(flute=R)), clearance_mm=4.0)
    res = no_flank.check(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), distances=True)
    assert res.part_names == ("shank",) and not res.collides[0]
    assert res.distance("shank")[0] == pytest.approx(R, abs=ACC)


# --- tilting toward a wall edge ----------------------------------------------------
W_EDGE, H_WALL, R_SHANK = 12.0, 20.0, 4.0


def edge_angle(r):
    """Tilt at which a cylinder of radius r about the axis through the ball centre
    touches the wall's top edge: w cos t - (H - R) sin t = r."""
    a, b = W_EDGE, H_WALL - R
    return math.acos(r / math.hypot(a, b)) - math.atan2(b, a)


@pytest.fixture(scope="module")
def wall_checker():
    asm = ToolAssembly.from_tool(ball(2 * R_SHANK))   # no holder
    return InterferenceChecker(floor_and_wall(W_EDGE, H_WALL), asm, clearance_mm=0.0,
                               distance_horizon_mm=100.0)


def test_shank_distance_to_wall_edge_closed_form(wall_checker):
    th = np.radians(np.linspace(2.0, 23.0, 12))
    tips, axes = zip(*(tilted(t) for t in th))
    res = wall_checker.check(np.array(tips), np.array(axes), distances=True)
    expected = W_EDGE * np.cos(th) - (H_WALL - R) * np.sin(th) - R_SHANK
    # the edge's projection lies inside the shank's range, away from its ends
    t_axial = W_EDGE * np.sin(th) + (H_WALL - R) * np.cos(th) + R
    assert np.all((t_axial > FLUTE + 1) & (t_axial < OVERHANG - 1))
    np.testing.assert_allclose(res.distance("shank"), expected, atol=ACC)
    assert not res.collides.any() and not res.gouges.any()


@pytest.mark.parametrize("clearance", [0.0, 0.5])
def test_tilt_toward_wall_collides_beyond_the_edge_angle(clearance):
    asm = ToolAssembly.from_tool(ball(2 * R_SHANK))
    ch = InterferenceChecker(floor_and_wall(W_EDGE, H_WALL), asm, clearance_mm=clearance)
    theta_star = edge_angle(R_SHANK + clearance)     # side contact: enlarged radius

    def collides(t):
        tip, u = tilted(t)
        r = ch.check(tip[None], u[None], distances=False)
        return bool(r.collides[0]), int(r.part[0])

    assert collides(theta_star - math.radians(0.5)) == (False, -1)
    assert collides(theta_star + math.radians(0.5)) == (True, 1)      # the shank
    lo, hi = 0.0, math.radians(40.0)
    assert not collides(lo)[0] and collides(hi)[0]
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if collides(mid)[0] else (mid, hi)
    assert abs(math.degrees(0.5 * (lo + hi) - theta_star)) < 0.01


# --- holder -------------------------------------------------------------------------
def test_short_overhang_holder_collides_but_not_shank():
    """Vertical tool 10 mm from a tall wall: shank (r 3) clear by 7 mm, holder (r 16)
    intersects. With a long overhang the holder clears the wall top."""
    mesh = floor_and_wall(10.0, 50.0)
    tip, u = np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]])
    short = ToolAssembly.from_tool(ball(6.0, overhang=20.0, holder=Holder(32.0, 40.0)), 0.5)
    res = InterferenceChecker(mesh, short, distance_horizon_mm=10.0).check(tip, u, distances=True)
    assert res.collides[0] and res.part_label[0] == "holder"
    assert res.part_violates[0].tolist() == [False, False, True]
    assert res.distance("shank")[0] == pytest.approx(10.0 - 3.0, abs=ACC)
    assert res.distance("holder")[0] == 0.0
    long = ToolAssembly.from_tool(ball(6.0, overhang=55.0, holder=Holder(32.0, 40.0)), 0.5)
    res = InterferenceChecker(mesh, long, distance_horizon_mm=10.0).check(tip, u, distances=True)
    assert not res.collides[0]
    assert res.distance("holder")[0] == pytest.approx(55.0 - 50.0, abs=ACC)


def test_part_reports_the_offending_part_nearest_the_tip():
    """Shank and holder both in a wall: the shank is reported."""
    mesh = floor_and_wall(2.0, 50.0)
    asm = ToolAssembly.from_tool(ball(10.0, overhang=20.0, holder=Holder(32.0, 40.0)), 0.5)
    res = InterferenceChecker(mesh, asm).check(np.array([[-2.5, 0.0, 0.0]]),
                                               np.array([[0.0, 0.0, 1.0]]))
    assert res.part_violates[0].tolist() == [False, True, True]
    assert res.part_label[0] == "shank" and res.collides[0] and not res.gouges[0]


# --- the cutting zone and gouges ----------------------------------------------------
def test_ball_touching_the_surface_is_not_a_collision():
    """Ball centre R above a face, axis tilted up to 80 deg any way: the ball
    touches the face, nothing else does (the shank's lowest point stays
    > 0.25 mm above it with its 0.5 mm clearance)."""
    asm = ToolAssembly.from_tool(ball(), clearance_mm=0.5)
    ch = InterferenceChecker(block(-60, 60, -60, 60, -20, 0), asm, distance_horizon_mm=10.0)
    rng = np.random.default_rng(RNG_SEED)
    th = np.radians(rng.uniform(0.0, 80.0, 40))
    ph = rng.uniform(0, 2 * np.pi, 40)
    u = np.column_stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
    tips = np.array([0.0, 0.0, R]) - R * u        # ball centre R above the face
    res = ch.check(tips, u, distances=True)
    assert res.feasible.all()
    # the flank's bottom rim (at the ball's equator) is R (1 - sin t) above the face
    np.testing.assert_allclose(res.distance("flank"), R * (1 - np.sin(th)), atol=ACC)
    assert ch.feasible(tips, u).all()


def test_flank_on_a_steep_wall_gouges_only_beyond_the_tolerance():
    """Vertical tool, ball cutting a vertical wall (face x = 0) at its equator: the
    flank is tangent to the wall. Pushed in by more than the tolerance it gouges."""
    tol = 0.01
    wall = block(0, 20, -30, 30, -30, 30)
    # necked shank (r 2, 1 mm from the wall): a straight shank would rub the wall, a
    # collision; the clearance is below that 1 mm (the test is about the flank)
    ch = InterferenceChecker(wall, ToolAssembly.from_tool(ball(4.0), clearance_mm=0.5),
                             gouge_tol_mm=tol)
    push = np.array([-5.0, 0.0, 0.5, 0.9, 1.1, 1.5, 5.0]) * tol   # into the wall
    tips = np.column_stack([-R + push, np.zeros(7), np.zeros(7)])
    res = ch.check(tips, np.tile([0.0, 0.0, 1.0], (7, 1)), distances=True)
    assert res.gouges.tolist() == [False, False, False, False, True, True, True]
    assert not res.collides.any()
    straight = InterferenceChecker(wall, ToolAssembly.from_tool(ball(6.0)), gouge_tol_mm=tol)
    res_s = straight.check(tips[1:2], np.array([[0.0, 0.0, 1.0]]))
    assert res_s.collides[0] and not res_s.gouges[0] and res_s.part_label[0] == "shank"
    assert res.part_label.tolist() == [""] * 4 + ["flank"] * 3
    np.testing.assert_allclose(res.distance("flank")[:1], [5 * tol], atol=ACC)
    assert (res.distance("flank")[4:] == 0).all()


def test_flat_end_mill_bottom_face_on_floor_is_not_a_gouge():
    """Flat end mill: the flank starts at the bottom face (r = 0); the gouge test
    lifts it by the tolerance, so a tool standing on the floor is fine."""
    tol = 0.01
    asm = ToolAssembly.from_tool(Tool("flat", 6.0, flute_length_mm=12.0, overhang_mm=30.0))
    assert asm.parts[0].z0_mm == 0.0
    ch = InterferenceChecker(block(-30, 30, -30, 30, -10, 0), asm, gouge_tol_mm=tol)
    res = ch.check(np.array([[0, 0, 0.0], [0, 0, -0.5 * tol], [0, 0, -1.5 * tol]]),
                   np.tile([0.0, 0.0, 1.0], (3, 1)))
    assert res.gouges.tolist() == [False, False, True]


def test_flank_gouge_against_the_design_surface_not_the_stock():
    """In-process stock = design floor + an uncut slab at x >= 1: the flank of a
    vertical tool (reaching x = 3) is inside the slab, which is cutting, not a
    gouge; against the stock alone it would be flagged. A taller slab reaches
    the shank (from z = 12): a collision with the stock."""
    design = block(-30, 30, -30, 30, -10, 0)
    low = trimesh.util.concatenate([design, block(1, 20, -30, 30, -10, 5)])
    tall = trimesh.util.concatenate([design, block(1, 20, -30, 30, -10, 15)])
    asm = ToolAssembly.from_tool(ball(), clearance_mm=0.5)
    tip, u = np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]])
    assert InterferenceChecker(low, asm).check(tip, u).gouges[0]
    res = InterferenceChecker(low, asm, design_mesh=design).check(tip, u)
    assert res.feasible[0]
    res = InterferenceChecker(tall, asm, design_mesh=design).check(tip, u)
    assert res.collides[0] and not res.gouges[0] and res.part_label[0] == "shank"


# --- brute force ------------------------------------------------------------------------
def cylinder_distance(p, tip, u, r, z0, z1):
    """Exact distance of points p (m, 3) from the solid cylinder (closed form)."""
    d = p - tip
    t = d @ u
    rho = np.linalg.norm(d - t[:, None] * u, axis=1)
    dr = np.maximum(rho - r, 0.0)
    dz = np.maximum(np.maximum(z0 - t, t - z1), 0.0)
    return np.hypot(dr, dz)


def fine_samples(mesh, faces, step):
    """Barycentric grid points of the given faces; every point of a face is within
    its sub-triangles' longest edge (<= step) of a sample."""
    out = []
    for f in faces:
        A, B, C = mesh.vertices[mesh.faces[f]]
        k = max(1, math.ceil(max(np.linalg.norm(B - A), np.linalg.norm(C - B),
                                 np.linalg.norm(A - C)) / step))
        i, j = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
        keep = i + j <= k
        a, b = i[keep] / k, j[keep] / k
        out.append(A + a[:, None] * (B - A) + b[:, None] * (C - A))
    return np.concatenate(out)


@pytest.mark.parametrize("which", ["icosphere", "bumpy"])
def test_distances_agree_with_brute_force(which):
    rng = np.random.default_rng(RNG_SEED + (which == "bumpy"))
    if which == "icosphere":
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=20.0)
    else:
        mesh = bumpy()
    asm = ToolAssembly.from_tool(ball(8.0, holder=Holder(20.0, 30.0)), clearance_mm=0.0)
    ch = InterferenceChecker(mesh, asm, prefilter=False)
    n = 6
    faces = rng.choice(len(mesh.faces), n)
    cc, nrm = mesh.triangles_center[faces], mesh.face_normals[faces]
    nrm = nrm * np.sign(nrm[:, 2:3] + 1e-9) if which == "bumpy" else nrm
    tilt = rng.normal(size=(n, 3)) * 1.2
    u = nrm + tilt - np.sum(tilt * nrm, 1, keepdims=True) * nrm
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    tips = cc + (R + rng.uniform(0.3, 2.0, n))[:, None] * nrm - R * u
    res = ch.check(tips, u, distances=True)
    step = 0.02
    longest = mesh.edges_unique_length.max()
    checked = 0
    for i in range(n):
        for j, p in enumerate(asm.parts):
            d = res.min_distance_mm[i, j]
            if d <= 0 or d > 8:
                continue
            # faces near the part: a vertex within d + (longest edge) of it
            vd = cylinder_distance(mesh.vertices, tips[i], u[i], p.radius_mm, p.z0_mm,
                                   p.z1_mm)
            near = np.nonzero(vd[mesh.faces].min(axis=1) < d + longest)[0]
            assert len(near) > 0
            brute = cylinder_distance(fine_samples(mesh, near, step), tips[i], u[i],
                                      p.radius_mm, p.z0_mm, p.z1_mm).min()
            # brute is an upper bound within the sampling step of the true distance
            assert brute - step - ACC <= d <= brute + ACC, (i, p.name, d, brute)
            checked += 1
    assert checked >= n


def test_prefilter_bounds_are_sound_and_decisions_unchanged():
    mesh = bumpy()
    asm = ToolAssembly.from_tool(ball(8.0, holder=Holder(32.0, 40.0)), clearance_mm=0.5)
    exact = InterferenceChecker(mesh, asm, prefilter=False)
    fast = InterferenceChecker(mesh, asm, distance_horizon_mm=1.0)
    rng = np.random.default_rng(RNG_SEED)
    n = 150
    th = np.radians(rng.uniform(0, 70, n))
    ph = rng.uniform(0, 2 * np.pi, n)
    u = np.column_stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
    xy = rng.uniform(-20, 20, (n, 2))
    z = 4.0 * np.sin(xy[:, 0] / 6.0) * np.cos(xy[:, 1] / 8.0) + rng.uniform(-1, 8, n)
    tips = np.column_stack([xy, z])
    a, b = exact.check(tips, u, distances=True), fast.check(tips, u, distances=True)
    assert a.exact.all()
    assert (b.collides == a.collides).all() and (b.gouges == a.gouges).all()
    assert 0 < a.collides.sum() < n and a.gouges.any()
    # lower bounds never exceed the exact distance; exact ones agree
    assert np.all(b.min_distance_mm <= a.min_distance_mm + ACC)
    np.testing.assert_allclose(b.min_distance_mm[b.exact], a.min_distance_mm[b.exact],
                               atol=1e-9)
    assert (~b.exact).any()
    # decisions only: same decisions, lower bounds everywhere
    for ch in (fast, exact):
        q = ch.check(tips, u)
        assert (q.collides == a.collides).all() and (q.gouges == a.gouges).all()
        assert np.all(q.min_distance_mm <= a.min_distance_mm + ACC)
        assert np.all(q.min_distance_mm[q.exact] == 0.0)
    assert (fast.feasible(tips, u) == a.feasible).all()


# --- refused input -----------------------------------------------------------------------
@pytest.fixture(scope="module")
def small_checker():
    return InterferenceChecker(block(-10, 10, -10, 10, -5, 0), ToolAssembly.from_tool(ball()))


def test_non_finite_tips_and_axes_are_refused(small_checker):
    u = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    with pytest.raises(ValueError, match=r"tips: expected finite values.*row 1"):
        small_checker.check(np.array([[0, 0, 1.0], [np.nan, 0, 1.0]]), u)
    with pytest.raises(ValueError, match="tips: expected finite"):
        small_checker.feasible(np.array([[0, 0, 1.0], [0, np.inf, 1.0]]), u)
    with pytest.raises(ValueError, match="axes: expected finite"):
        small_checker.check(np.zeros((2, 3)), np.array([[0, 0, 1.0], [0, -np.inf, 1.0]]))
    with pytest.raises(ValueError, match="axes: expected non-zero"):
        small_checker.check(np.zeros((2, 3)), np.array([[0, 0, 1.0], [0, 0, 0.0]]))


def test_wrong_shapes_are_refused(small_checker):
    with pytest.raises(ValueError, match=r"tips: expected shape \(n, 3\)"):
        small_checker.check(np.zeros(3), np.array([[0, 0, 1.0]]))
    with pytest.raises(ValueError, match=r"axes: expected shape \(n, 3\)"):
        small_checker.check(np.zeros((2, 3)), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="different numbers"):
        small_checker.check(np.zeros((2, 3)), np.tile([0, 0, 1.0], (3, 1)))
    with pytest.raises(TypeError, match="mesh"):
        InterferenceChecker("box.stl", ToolAssembly.from_tool(ball()))
    with pytest.raises(ValueError, match="gouge_tol_mm"):
        InterferenceChecker(block(0, 1, 0, 1, 0, 1), ToolAssembly.from_tool(ball()),
                            gouge_tol_mm=R)
    empty = small_checker.check(np.zeros((0, 3)), np.zeros((0, 3)))
    assert empty.min_distance_mm.shape == (0, 2) and empty.feasible.shape == (0,)
