"""The fast engagement of orient (LocalCut) against hand results, brute force and errpred."""

from __future__ import annotations

import math

import numpy as np
import pytest

from errpred.frames import tool_frame
from errpred.geometry import GeometryModel, Resolution
from errpred.tool import Tool, core_distance
from nc import parse_program
from nc.path import cutter_locations
from orient.engagement import (
    LocalCut,
    cutting_intervals,
    engagement,
    from_errpred,
    geometry_vector,
    place,
)
from orient.gain import gain_from_engagement, process_gain
from orient.geometry import lead_tilt_of, posture_axis

from ..errpred.cases import STEEL, plane_raster, plane_stock

R = 5.0
BALL = Tool("ball", 2 * R, flutes=2, helix_deg=30.0, flute_length_mm=15.0)
Z, X = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])


def test_local_cut_validation():
    LocalCut(0.2, 0.5, 1, 0.05, 0.01, -0.02)
    for kwargs, name in [({"depth_mm": -0.1}, "depth_mm"), ({"pick_mm": math.nan}, "pick_mm"),
                         ({"previous_side": 2}, "previous_side"), ({"fz_mm": 0.0}, "fz_mm"),
                         ({"curvature_b_1_mm": -20.0}, "curvature_b_1_mm")]:
        args = {"depth_mm": 0.2, "pick_mm": 0.5, "previous_side": 1, "fz_mm": 0.05}
        args.update(kwargs)
        with pytest.raises(ValueError, match=name):
            LocalCut(**args)
    with pytest.raises(ValueError, match="gouge"):
        LocalCut(0.2, 0.5, 1, 0.05, -0.25).check_tool(BALL)


@pytest.mark.parametrize("kind", ["ball", "radius", "flat"])
@pytest.mark.parametrize("lead,tilt", [(0.0, 0.0), (20.0, -10.0), (-5.0, 35.0)])
def test_tool_touches_the_surface_at_the_contact(kind, lead, tilt):
    """The origin is on the tool's envelope and its envelope normal there is -n."""
    tool = Tool(kind, 10.0, corner_radius_mm=2.0, flutes=3)
    n = np.array([0.3, -0.2, 1.0])
    n /= np.linalg.norm(n)
    u = posture_axis(n, [1.0, 0.5, 0.0], math.radians(lead), math.radians(tilt))
    pl = place(tool, u, n, [1.0, 0.5, 0.0])
    np.testing.assert_allclose(pl.frame, tool_frame(u, pl.f, tool.rotation_sign), atol=1e-15)
    p = pl.frame @ (np.zeros(3) - pl.tip)                  # contact in the tool frame
    d = core_distance(np.hypot(p[0], p[1]), p[2], tool.core_radius_mm, tool.corner_radius_mm)
    assert float(d) == pytest.approx(tool.corner_radius_mm, abs=1e-12)
    if kind != "flat" and (lead, tilt) != (0.0, 0.0):
        # outward normal of the envelope at the contact, from the core circle
        rho = np.hypot(p[0], p[1])
        core = np.array([p[0], p[1], 0.0]) * (tool.core_radius_mm / rho) + [0, 0, tool.corner_radius_mm]
        normal_tool = (p - core) / tool.corner_radius_mm
        np.testing.assert_allclose(normal_tool @ pl.frame, -n, atol=1e-12)
    if kind == "ball":
        np.testing.assert_allclose(pl.tip, R * n - R * u, atol=1e-12)


@pytest.mark.parametrize("rotation", ["cw", "ccw"])
def test_kernel_frame_equals_errpred(rotation):
    tool = Tool("ball", 10.0, rotation=rotation)
    rng = np.random.default_rng(5)
    for _ in range(10):
        n = rng.normal(size=3)
        f = rng.normal(size=3)
        lead, tilt = rng.uniform(-0.6, 0.6, 2)
        u = posture_axis(n, f, lead, tilt)
        pl = place(tool, u, n, f)
        geo = geometry_vector(tool, u, n, f, LocalCut(0.2, 0.5, 1, 0.05))
        # the feed of the cut is the local f (tangent to the surface)
        np.testing.assert_allclose(geo[:9].reshape(3, 3),
                                   tool_frame(u, pl.f, tool.rotation_sign), atol=1e-13)


def test_vertical_ball_slot_engages_the_front_half_below_the_depth():
    """Classic reference: axis along the normal, no previous pass, depth a: the
    engaged edge points are those below z = a on the front half (sin phi > 0),
    each micro edge for the analytic half revolution."""
    a = 0.8
    edges = BALL.micro_edges(40)
    cut = LocalCut(a, 0.0, 0, 0.05)
    eng = engagement(BALL, edges, Z, Z, X, cut, n_angles=360)
    sp = np.sin(eng.phi)
    expected = (edges.z < a)[None, None, :] & (sp > 1e-9)
    clear = np.abs(sp) > 1e-9                       # samples not on the boundary
    assert np.array_equal(eng.cutting[clear], expected[clear])
    np.testing.assert_allclose(eng.h[eng.cutting],
                               0.05 * (sp * np.sin(edges.kappa))[eng.cutting], atol=1e-15)
    iv = cutting_intervals(BALL, edges, Z, Z, X, cut)
    for j in range(len(edges)):
        if edges.z[j] < a:
            assert len(iv[j]) == 1
            lo, hi = iv[j][0]
            assert hi - lo == pytest.approx(math.pi, abs=1e-9)
            assert math.remainder(lo, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
        else:
            assert len(iv[j]) == 0


def _brute_material(tool, pl, cut, p):
    """Point-in-material written independently of orient's kernels.

    Below the stock top (the quadric offset by the depth) and farther than R
    from the previous pass's swept ball-and-flank core: the axis segment from
    the ball centre to the flute top, swept along the infinite line of the
    pass, i.e. normal to f the distance from a point to a segment.
    """
    kf = cut.curvature_f_1_mm / (1 + cut.curvature_f_1_mm * cut.depth_mm)
    kb = cut.curvature_b_1_mm / (1 + cut.curvature_b_1_mm * cut.depth_mm)
    below = p @ pl.n < cut.depth_mm - 0.5 * (kf * (p @ pl.f) ** 2 + kb * (p @ pl.b) ** 2)
    if cut.previous_side == 0:
        return below
    centre = pl.tip + R * pl.axis + cut.previous_side * cut.pick_mm * pl.b
    q = p - centre
    q = q - np.outer(q @ pl.f, pl.f)
    seg = (tool.flute_length_mm - R) * (pl.axis - (pl.axis @ pl.f) * pl.f)
    t = np.clip((q @ seg) / (seg @ seg), 0.0, 1.0)
    return below & (np.linalg.norm(q - np.outer(t, seg), axis=1) > R + 1e-6)


@pytest.mark.parametrize("seed", range(4))
def test_exact_intervals_match_a_brute_force_material_test(seed):
    rng = np.random.default_rng(seed)
    lead, tilt = np.radians(rng.uniform(-30, 30, 2))
    n = rng.normal(size=3) * [0.3, 0.3, 1.0]
    n /= np.linalg.norm(n)
    feed = np.array([1.0, rng.uniform(-1, 1), 0.0])
    u = posture_axis(n, feed, lead, tilt)
    cut = LocalCut(rng.uniform(0.1, 0.5), rng.uniform(0.2, 0.9), int(rng.choice([-1, 1])),
                   0.05, rng.uniform(-0.04, 0.04), rng.uniform(-0.04, 0.04))
    edges = BALL.micro_edges(40)
    iv = cutting_intervals(BALL, edges, u, n, feed, cut)
    pl = place(BALL, u, n, feed)
    phi = np.linspace(0, 2 * np.pi, 721)[:-1] + 1e-4
    f_tool = pl.frame @ pl.f
    agree = total = engaged = 0
    for j in range(len(edges)):
        pts_tool = np.stack([edges.rho[j] * np.sin(phi), edges.rho[j] * np.cos(phi),
                             np.full(phi.size, edges.z[j])], axis=1)
        p = pl.tip + pts_tool @ pl.frame
        sk, ck = math.sin(edges.kappa[j]), math.cos(edges.kappa[j])
        h = f_tool[0] * sk * np.sin(phi) + f_tool[1] * sk * np.cos(phi) - f_tool[2] * ck
        brute = _brute_material(BALL, pl, cut, p) & (h > 1e-12)
        fast = np.zeros(phi.size, dtype=bool)
        near = np.zeros(phi.size, dtype=bool)
        for lo, hi in iv[j]:
            d = (phi - lo) % (2 * np.pi)
            fast |= d < hi - lo
            near |= (np.abs(np.remainder(phi - lo + np.pi, 2 * np.pi) - np.pi) < 2e-3)
            near |= (np.abs(np.remainder(phi - hi + np.pi, 2 * np.pi) - np.pi) < 2e-3)
        ok = ~near
        agree += int(np.sum(fast[ok] == brute[ok]))
        total += int(ok.sum())
        engaged += int(brute.sum())
    assert engaged > 200
    assert agree / total > 0.9995


def _raster_case(axis):
    """errpred's geometry stage on a flat plane (mesh stock, depth buffer) in
    two raster passes 0.6 mm apart; the point in the middle of the second."""
    tool = Tool("ball", 2 * R, helix_deg=30.0, flute_length_mm=15.0)
    prog = parse_program(plane_raster(0.0, R, passes=2, pick=0.6, length=16.0, step=0.5,
                                      axis=axis))
    cl = cutter_locations(prog)
    model = GeometryModel(tool, plane_stock(0.0, 0.3), cl, Resolution(pixel_mm=2 * R / 64))
    for block in range(len(prog)):
        rng = model.block_points(block)
        if rng is None or cl.rapid[rng[1]]:
            continue
        contact = cl.tip[rng[1]] + R * cl.axis[rng[1]] - R * Z
        if abs(contact[1] - 0.6) < 1e-3 and 7.0 < contact[0] < 9.0:
            (g,) = model.geometry(block)
            return tool, model, g
    raise AssertionError("no block in the middle of the second pass")


@pytest.mark.parametrize("axis", [None, (math.sin(math.radians(15)), -math.sin(math.radians(10)),
                                         1.0)])
def test_fast_mask_agrees_with_errpred_rasterizer(axis):
    """Same cut through errpred (stock mesh in a depth buffer, exact sweeps of the
    previous pass and of this pass up to one tooth before): the engaged samples
    (errpred's sub-sampled weights, positive chip only) agree within 3 %."""
    if axis is not None:
        axis = np.asarray(axis) / np.linalg.norm(axis)
    tool, model, g = _raster_case(axis)
    assert g.cuts
    f = g.feed_per_tooth_world / np.linalg.norm(g.feed_per_tooth_world)
    b = np.cross(Z, f)
    side = int(np.sign(np.array([0.0, -0.6, 0.0]) @ b))     # the first pass lies at y = 0
    cut = LocalCut(0.3, 0.6, side, float(np.linalg.norm(g.feed_per_tooth_world)))
    theirs = from_errpred(g, tool, model.edges, Z)
    mine = engagement(tool, model.edges, g.axis, Z, f, cut, n_angles=g.cutting0.shape[0])
    assert theirs.cutting.shape == mine.cutting.shape
    weighted = float((theirs.weight * theirs.cutting)[:, 0].sum())
    count = int(mine.cutting[:, 0].sum())
    assert count > 300
    assert abs(weighted / count - 1) < 0.03
    # where both are sure (weight 1 in errpred), they agree sample by sample
    sure = (theirs.weight[:, 0] == 1) | ~theirs.cutting[:, 0]
    assert np.mean(theirs.cutting[:, 0][sure] == mine.cutting[:, 0][sure]) > 0.995
    # the gain from errpred's engagement (fixed micro edges, sampled rotation,
    # sub-sampled boundary weights) against the exact-interval gain
    ge = gain_from_engagement(tool, model.edges, STEEL, theirs)
    gx = process_gain(tool, STEEL, g.axis, Z, f, cut)
    assert np.linalg.norm(ge.P - gx.P) / np.linalg.norm(gx.P) < 0.02
    assert ge.cut_sense == pytest.approx(gx.cut_sense, abs=0.01)
    assert ge.engaged_fraction == pytest.approx(gx.engaged_fraction, abs=0.01)
    if axis is not None:
        lead, tilt = lead_tilt_of(g.axis, Z, f)
        assert abs(lead) > 0.1 and abs(tilt) > 0.1          # a real 5-axis posture


@pytest.mark.parametrize("axis", [None, (math.sin(math.radians(15)), -math.sin(math.radians(10)),
                                         1.0)])
def test_trailing_edges_are_errpreds_sliver(axis):
    """errpred's rasterizer keeps the material behind the first-order chip's zero (a ball's
    sliver -fz/2 < (p - c).f <= 0, chip clamped to 0); ``trailing=True`` adds exactly
    those edges: every one is in errpred's sliver, and where errpred is sure the two
    engagements agree cell by cell (without them they do not: the simulated machine had
    no edge force where the surface is generated)."""
    if axis is not None:
        axis = np.asarray(axis) / np.linalg.norm(axis)
    tool, model, g = _raster_case(axis)
    f = g.feed_per_tooth_world / np.linalg.norm(g.feed_per_tooth_world)
    b = np.cross(Z, f)
    side = int(np.sign(np.array([0.0, -0.6, 0.0]) @ b))
    cut = LocalCut(0.3, 0.6, side, float(np.linalg.norm(g.feed_per_tooth_world)))
    n = g.cutting0.shape[0]
    theirs = from_errpred(g, tool, model.edges, Z, positive_chip_only=False)
    plain = engagement(tool, model.edges, g.axis, Z, f, cut, n_angles=n)
    mine = engagement(tool, model.edges, g.axis, Z, f, cut, n_angles=n, trailing=True)
    assert np.all(mine.cutting >= plain.cutting)
    extra = mine.cutting[:, 0] & ~plain.cutting[:, 0]
    assert extra.sum() >= 10 and np.all(mine.h[:, 0][extra] == 0.0)
    sliver = theirs.cutting[:, 0] & (theirs.h[:, 0] <= 0.0)
    assert np.all(sliver[extra])
    sure = (theirs.weight[:, 0] == 1) | ~theirs.cutting[:, 0]
    assert np.array_equal(mine.cutting[:, 0][sure], theirs.cutting[:, 0][sure])
    assert not np.array_equal(plain.cutting[:, 0][sure], theirs.cutting[:, 0][sure])


def test_adapter_keeps_only_positive_chips_and_expands_flutes():
    tool, model, g = _raster_case(None)
    raw = from_errpred(g, tool, model.edges, Z, positive_chip_only=False)
    kept = from_errpred(g, tool, model.edges, Z)
    assert raw.cutting.shape == (g.cutting0.shape[0], tool.flutes, len(model.edges))
    assert np.array_equal(raw.cutting[:, 0], g.cutting0)
    assert kept.cutting.sum() < raw.cutting.sum()
    assert np.all(kept.h[kept.cutting] > 0)
    n = g.cutting0.shape[0]
    np.testing.assert_array_equal(raw.cutting[:, 1], np.roll(g.cutting0, -n // 2, axis=0))


def test_nothing_cuts_without_material():
    edges = BALL.micro_edges(40)
    u = posture_axis(Z, X, 0.3, 0.2)
    for cut in (LocalCut(0.0, 0.5, 1, 0.05), LocalCut(0.3, 0.0, 1, 0.05)):
        eng = engagement(BALL, edges, u, Z, X, cut, n_angles=90)
        assert not eng.cutting.any()
        assert all(len(iv) == 0 for iv in cutting_intervals(BALL, edges, u, Z, X, cut))


def test_refuses_axis_into_the_workpiece():
    with pytest.raises(ValueError, match="posture_axis"):
        place(BALL, [0.0, 0.0, -1.0], Z, X)
    with pytest.raises(ValueError, match="cut"):
        engagement(BALL, BALL.micro_edges(8), Z, Z, X, "deep")
