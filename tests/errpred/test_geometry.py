"""Engagement, generation point and wear from the geometry stage, against hand results."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from nc import parse_program
from nc.path import cutter_locations
from errpred.force import chip_thickness, tool_forces
from errpred.engagement import expand_flutes
from errpred.geometry import GeometryModel, Resolution
from errpred.predict import Predictor
from errpred.raster.meshes import Stock
from errpred.tool import Tool

from .cases import STEEL, plane_raster, plane_stock, stiff_tool

D, R = 10.0, 5.0


def side_cut(mode: str, a: float, *, flutes=2, angle_step_deg=2.0, helix=0.0):
    """A flat end mill feeding +X through a box; material on +Y (up), -Y (down) or both."""
    tool = Tool("flat", D, flutes=flutes, helix_deg=helix, flute_length_mm=6.0)
    lo_y, hi_y = {"up": (R - a, 30.0), "down": (-30.0, -(R - a)), "slot": (-30.0, 30.0)}[mode]
    stock = Stock.from_box([-20.0, lo_y, 0.001], [20.0, hi_y, 2.0])
    # the block of interest is the short middle one (one prediction point, at X0)
    prog = parse_program("G21 G90 G94\nS6000 M3\nG0 X-30 Y0 Z0\nG1 X-2 F600\nG1 X2\n"
                         "G1 X30\nM30\n")
    res = Resolution(pixel_mm=D / 64, angle_step_rad=math.radians(angle_step_deg))
    model = GeometryModel(tool, stock, cutter_locations(prog), res)
    (g,) = model.geometry(2)
    return tool, model, g


def _cut_angles(model, g):
    flank = (model.edges.segment == 2) & (model.edges.z < 2.0)
    cut = g.cutting0[:, flank].any(axis=1)
    return np.degrees(model.theta[cut])


@pytest.mark.parametrize("a", [1.0, 2.5, 4.0])
def test_side_cut_entry_exit_angles(a):
    step = 2.0
    expected = math.degrees(math.acos(1 - 2 * a / D))
    _, model, g = side_cut("up", a, angle_step_deg=step)
    ang = _cut_angles(model, g)
    ang = np.where(ang > 270, ang - 360, ang)
    assert abs(ang.min() - 0.0) <= step and abs(ang.max() - expected) <= step
    _, model, g = side_cut("down", a, angle_step_deg=step)
    ang = _cut_angles(model, g)
    assert abs(ang.min() - (180 - expected)) <= step and abs(ang.max() - 180) <= step


def test_slot_engages_half_a_revolution():
    _, model, g = side_cut("slot", 0.0)
    ang = _cut_angles(model, g)
    ang = np.where(ang > 270, ang - 360, ang)
    assert abs(ang.min()) <= 2.0 and abs(ang.max() - 180.0) <= 2.0
    assert 88 <= ang.size <= 92  # contiguous: 180 deg in 2 deg steps


def _altintas_mean(phi_st, phi_ex, N, a, f, K):
    """Mean forces per revolution of a straight flat end mill (Altintas, Manufacturing
    Automation, 2nd ed., 2012, section 2.3), in this project's sign (Fz' = -Fa)."""
    def fx(p):
        return (N * a * f / (8 * math.pi) * (K.Ktc_N_mm2 * math.cos(2 * p)
                - K.Krc_N_mm2 * (2 * p - math.sin(2 * p)))
                + N * a / (2 * math.pi) * (-K.Kte0_N_mm * math.sin(p) + K.Kre0_N_mm * math.cos(p)))

    def fy(p):
        return (N * a * f / (8 * math.pi) * (K.Ktc_N_mm2 * (2 * p - math.sin(2 * p))
                + K.Krc_N_mm2 * math.cos(2 * p))
                - N * a / (2 * math.pi) * (K.Kte0_N_mm * math.cos(p) + K.Kre0_N_mm * math.sin(p)))

    def fz(p):
        return -N * a / (2 * math.pi) * (-K.Kac_N_mm2 * f * math.cos(p) + K.Kae0_N_mm * p)

    return np.array([g(phi_ex) - g(phi_st) for g in (fx, fy, fz)])


@pytest.mark.parametrize("mode,a", [("up", 2.0), ("down", 2.0), ("slot", 0.0)])
def test_side_cut_mean_forces_equal_closed_form(mode, a):
    """Engagement from the geometry stage + force model = closed form, within 2%."""
    tool, model, g = side_cut(mode, a, angle_step_deg=0.5)
    phi, cutting = expand_flutes(model.theta, g.cutting0, model.edges, tool.flutes)
    f_tool = g.frame @ g.feed_per_tooth_world
    h = np.where(cutting, chip_thickness(model.edges, phi, f_tool), 0.0)
    F = tool_forces(model.edges, STEEL, phi, h, cutting, np.zeros(len(model.edges)))
    flank = (model.edges.segment == 2) & (model.edges.z < 2.0)
    ap = float(model.edges.db[flank].sum())
    assert ap == pytest.approx(2.0)
    fz = 600.0 / (6000.0 * 2)
    ex = math.acos(1 - 2 * a / D) if mode != "slot" else math.pi
    lo, hi = {"up": (0.0, ex), "down": (math.pi - ex, math.pi), "slot": (0.0, math.pi)}[mode]
    ref = _altintas_mean(lo, hi, 2, ap, fz, STEEL)
    mean = F.mean(axis=0)
    assert np.linalg.norm(mean - ref) <= 0.02 * np.linalg.norm(ref), (mean, ref)


def test_flat_end_mill_wall_is_generated_where_the_flute_is_normal_to_it():
    for mode, phi_expected, n_expected in (("up", 0.0, (0, -1, 0)), ("down", 180.0, (0, 1, 0))):
        tool, model, g = side_cut(mode, 1.0, flutes=3)
        assert g.status == "predicted" and g.view == "side"
        assert math.degrees(g.gen.kappa_rad) == pytest.approx(90.0, abs=1e-6)
        pitch = 120.0
        d = (math.degrees(g.gen.theta_rad) - phi_expected) % pitch
        assert min(d, pitch - d) <= 2.0
        np.testing.assert_allclose(g.gen.normal_world, n_expected, atol=0.02)


def test_a_wall_the_flank_finishes_beside_a_floor_is_predicted_too():
    """A flat end mill ramping down along a shoulder (1 mm radial, material on +Y and
    below): the bottom face finishes the floor and the flank the wall at once. The floor
    stays the point's generation point (the correction's), and the wall gets its own:
    kappa 90 deg, normal -Y, and its error is the one the point has with the wall as its
    generation point; the tool is pushed away from the wall, so material is left. Level,
    the floor is not finished and the wall is the generation point, as before."""
    from errpred.physics import WearState, evaluate
    from errpred.report import summary

    tool = Tool("flat", D, flutes=3, helix_deg=0.0, flute_length_mm=6.0)
    stock = Stock.from_box([-40.0, R - 1.0, -5.0], [40.0, 30.0, 2.0])
    res = Resolution(pixel_mm=D / 64, angle_step_rad=math.radians(2.0))
    ramp = parse_program("G21 G90 G94\nS6000 M3\nG0 X-30 Y0 Z0\nG1 X-2 Z-0.28 F600\n"
                         "G1 X2 Z-0.32\nG1 X30 Z-0.6\nM30\n")
    pred = Predictor(tool, stock, ramp, STEEL, stiff_tool(), resolution=res)
    out = pred.run()
    pts = [p for p in out.points if p.status == "predicted"]
    assert len(pts) == 3
    for p in pts:
        g, r = p.geometry, p.result
        assert g.view.startswith("bottom") and math.degrees(g.gen.kappa_rad) < 1.0
        assert g.wall is not None and math.degrees(g.wall.kappa_rad) == pytest.approx(90.0,
                                                                                     abs=1e-6)
        np.testing.assert_allclose(g.wall.normal_world, (0, -1, 0), atol=0.02)
        assert r.E_wall_um > 0.5                      # deflected away: material left
    # stage 2 again, block by block: each point with the wall as its generation point
    wear = WearState.new(pred.edges)
    checked = 0
    for b in range(len(ramp)):
        for g in pred.model.geometry(b):
            if g.cutting0 is None:
                continue
            before = WearState(wear.cl_mm.copy())
            r = evaluate(tool, pred.edges, pred.coefficients, pred.compliance, pred.shape,
                         pred.theta, g, wear)
            if g.wall is None:
                continue
            alone = evaluate(tool, pred.edges, pred.coefficients, pred.compliance,
                             pred.shape, pred.theta, dataclasses.replace(g, gen=g.wall,
                                                                         wall=None), before)
            assert alone.E_um == pytest.approx(r.E_wall_um, abs=1e-9)
            assert r.E_wall_um == pytest.approx(
                [p.result.E_wall_um for p in pts if p.block == b][0], abs=1e-9)
            checked += 1
    assert checked == 3
    s = summary(out)
    w = max(pts, key=lambda p: abs(p.result.E_wall_um))
    assert s["walls"]["points"] == 3 and s["walls"]["line"] == w.line
    assert s["walls"]["max_abs_error_um"] == pytest.approx(abs(w.result.E_wall_um), abs=1e-3)
    level = parse_program("G21 G90 G94\nS6000 M3\nG0 X-30 Y0 Z0\nG1 X-2 F600\nG1 X2\n"
                          "G1 X30\nM30\n")
    flat_out = Predictor(tool, stock, level, STEEL, stiff_tool(), resolution=res).run()
    got = [p for p in flat_out.points if p.status == "predicted"]
    assert got and all(p.geometry.view == "side" and p.geometry.wall is None for p in got)
    assert "walls" not in summary(flat_out)


@pytest.mark.parametrize("slope", [15.0, 30.0, 45.0])
def test_ball_raster_on_inclined_plane_kappa_and_normal(slope):
    prog = parse_program(plane_raster(slope, R, passes=4))
    pred = Predictor(Tool("ball", D, flute_length_mm=15), plane_stock(slope, 0.2), prog,
                     STEEL, stiff_tool())
    rows = [b for b in range(len(prog)) if prog.line[b] > 0]
    mid_pass = [b for b in rows if 45 <= prog.line[b] <= 60]  # inside the third pass
    out = pred.run(mid_pass)
    n = np.array([math.sin(math.radians(slope)), 0.0, math.cos(math.radians(slope))])
    got = [p for p in out.points if p.status == "predicted"]
    assert len(got) >= 10
    for p in got:
        # the finished strip straddles the cusp line: kappa within the scallop's span
        assert math.degrees(p.geometry.gen.kappa_rad) == pytest.approx(slope, abs=2.5)
        assert float(p.geometry.gen.normal_world @ n) > math.cos(math.radians(2.5))


def test_the_verification_sees_a_move_into_the_wall():
    """The shoulder ramp above, predicted again with the path moved 5 um toward the wall
    (+Y): against the original path, each wall's error takes the move along its normal
    (-Y: 5 um less material), the floors' (normal +Z) nothing; the comparison with the
    original finds the walls worse (beyond the overcut limit) and refuses the program."""
    from errpred.verification import compare, error_field

    tool = Tool("flat", D, flutes=3, helix_deg=0.0, flute_length_mm=6.0)
    stock = Stock.from_box([-40.0, R - 1.0, -5.0], [40.0, 30.0, 2.0])
    res = Resolution(pixel_mm=D / 64, angle_step_rad=math.radians(2.0))
    text = ("G21 G90 G94\nS6000 M3\nG0 X-30 Y{y} Z0\nG1 X-2 Z-0.28 F600\n"
            "G1 X2 Z-0.32\nG1 X30 Z-0.6\nM30\n")
    ref_prog = parse_program(text.format(y=0))
    ref_cl = cutter_locations(ref_prog)
    preds = [Predictor(tool, stock, parse_program(text.format(y=y)), STEEL, stiff_tool(),
                       resolution=res).run() for y in (0, 0.005)]
    before = error_field(preds[0], ref_cl, moved=False)
    after = error_field(preds[1], ref_cl)
    assert len(before.walls) == len(after.walls) == 3
    np.testing.assert_allclose(after.walls.shift_um, -5.0, atol=0.1)
    np.testing.assert_allclose(after.shift_um, 0.0, atol=0.1)
    E_wall = [p.result.E_wall_um for p in preds[1].predicted()]
    np.testing.assert_allclose(after.walls.E_um, np.add(E_wall, after.walls.shift_um))
    c = compare(before, after)
    assert not c.worse.any() and not c.walls.ok and not c.ok
    assert c.reason().startswith("the walls beside the floors: worse than the original")
    # the original against itself: the walls no worse
    assert compare(before, error_field(preds[0], ref_cl)).ok


def test_flat_floor_under_the_ball_tip_is_not_predicted():
    prog = parse_program(plane_raster(0.0, R, passes=4))
    pred = Predictor(Tool("ball", D, flute_length_mm=15), plane_stock(0.0, 0.2), prog,
                     STEEL, stiff_tool())
    out = pred.run([b for b in range(len(prog)) if 45 <= prog.line[b] <= 60])
    statuses = {p.status for p in out.points}
    assert statuses == {"axis-normal"}
    assert all(p.result is not None for p in out.points)  # forces still computed


@pytest.mark.parametrize("lead,tilt", [(15.0, 0.0), (0.0, 20.0), (10.0, -15.0)])
def test_tilted_ball_end_mill_contact_angle_is_the_inclination(lead, tilt):
    """5-axis: on an inclined plane the contact angle is the tool's inclination."""
    slope = 20.0
    s = math.radians(slope)
    n = np.array([math.sin(s), 0.0, math.cos(s)])       # plane normal
    f = np.array([math.cos(s), 0.0, -math.sin(s)])      # feed (along +X, down the slope)
    b = np.cross(n, f)                                   # cross-feed
    u = n.copy()
    for ang, about in ((lead, b), (tilt, f)):            # method.md section 1
        a = math.radians(ang)
        u = (u * math.cos(a) + np.cross(about, u) * math.sin(a)
             + about * (about @ u) * (1 - math.cos(a)))
    prog = parse_program(plane_raster(slope, R, passes=4, axis=u))
    pred = Predictor(Tool("ball", D, flute_length_mm=15), plane_stock(slope, 0.2), prog,
                     STEEL, stiff_tool())
    out = pred.run([b for b in range(len(prog)) if 45 <= prog.line[b] <= 60])
    got = [p for p in out.points if p.status == "predicted"]
    assert len(got) >= 10
    incl = math.degrees(math.acos(float(u @ n)))
    for p in got:
        assert math.degrees(p.geometry.gen.kappa_rad) == pytest.approx(incl, abs=2.5)
        assert float(p.geometry.gen.normal_world @ n) > math.cos(math.radians(2.5))


def test_cutting_distance_of_a_straight_slot():
    """Each flank micro edge rubs through half a revolution per revolution."""
    tool = Tool("flat", D, flutes=2, helix_deg=0.0, flute_length_mm=6.0)
    stock = Stock.from_box([-40.0, -30.0, 0.001], [40.0, 30.0, 2.0])
    L, F, S = 30.0, 600.0, 6000.0
    prog = parse_program(f"G21 G90 G94\nS{S:g} M3\nG0 X-15 Y0 Z0\nG1 X15 F{F:g}\nM30\n")
    res = Resolution(pixel_mm=D / 64, angle_step_rad=math.radians(1.0))
    pred = Predictor(tool, stock, prog, STEEL, stiff_tool(), resolution=res)
    out = pred.run()
    flank = (pred.edges.segment == 2) & (pred.edges.z < 2.0)
    analytic = math.pi * R * S * L / F  # [mm]: half a turn of radius R per revolution
    np.testing.assert_allclose(out.wear_mm[flank], analytic, rtol=math.radians(1.0) / math.pi
                               + 5e-3)
    assert np.all(out.wear_mm[~flank & (pred.edges.z > 2.0)] == 0.0)


def test_a_stretch_whose_middle_is_a_station_takes_that_stations_count(monkeypatch):
    """A slot's 12.5 mm block cuts at all five of its pre-check stations (a quarter
    diameter apart); its cutting stretch's middle is the third station: the point's
    stretch length is the stations' counts over that count, the middle not tested a
    second time."""
    tool = Tool("flat", D, flutes=2, helix_deg=0.0, flute_length_mm=6.0)
    stock = Stock.from_box([-40.0, -30.0, 0.001], [40.0, 30.0, 2.0])
    prog = parse_program("G21 G90 G94\nS6000 M3\nG0 X-20 Y0 Z0\nG1 X-10 F600\nG1 X2.5\n"
                         "M30\n")
    res = Resolution(pixel_mm=D / 32, angle_step_rad=math.radians(4.0))
    model = GeometryModel(tool, stock, cutter_locations(prog), res, sensitivity=False)
    block = 2                   # the program's blocks: G0 X-20, G1 X-10, G1 X2.5
    i0, i1 = model.block_points(block)
    start, end = float(model.path[i0 - 1]), float(model.path[i1])
    stations = model._stations(start, end)
    mid = 0.5 * (start + end)
    assert (start, end) == (10.0, 22.5) and len(stations) == 5 and mid == stations[2]
    real = GeometryModel._material_at
    calls = []

    def spy(self, L, block_start, rapid=False):
        count = real(self, L, block_start, rapid)
        calls.append((L, count))
        return count

    monkeypatch.setattr(GeometryModel, "_material_at", spy)
    (g,) = model.geometry(block)
    assert g.status != "no-cut"
    assert [L for L, _ in calls] == stations.tolist()       # the middle is not tested again
    counts = [c for _, c in calls]
    assert all(c > 0 for c in counts)
    step = (end - start) / len(stations)
    assert g.cut_length_mm == sum(counts) * step / real(model, mid, start)


def test_a_block_that_repeats_the_position_is_no_cut_and_wears_nothing():
    """A plunge, then a G1 to where the plunge ended (as LinuxCNC's arcspiral.ngc has),
    then a slot: the repeated position removes nothing and adds no wear; the slot's
    point is as without it."""
    tool = Tool("flat", D, flutes=2, helix_deg=0.0, flute_length_mm=6.0)
    stock = Stock.from_box([-40.0, -30.0, 0.001], [40.0, 30.0, 2.0])
    res = Resolution(pixel_mm=D / 64, angle_step_rad=math.radians(2.0))
    head = "G21 G90 G94\nS3000 M3\nG0 X-15 Y0 Z5\nG1 Z0 F300\n"

    def run(extra):
        prog = parse_program(head + extra + "G1 X15 F600\nM30\n")
        return prog, Predictor(tool, stock, prog, STEEL, stiff_tool(), resolution=res).run()

    prog, pred = run("G1 X-15 Y0\n")
    (still,) = [p for p in pred.points if p.line == 5]
    assert still.status == "no-cut" and still.result is None
    assert np.allclose(still.geometry.tip, [-15.0, 0.0, 0.0])
    _, ref = run("")
    slot = [p for p in pred.points if p.line == 6]
    slot_ref = [p for p in ref.points if p.line == 5]
    assert [p.status for p in slot] == [p.status for p in slot_ref] == ["predicted"]
    assert slot[0].E_um == slot_ref[0].E_um
    np.testing.assert_array_equal(pred.wear_mm, ref.wear_mm)
    # densely (the verification's points, block ends included) the corner where the
    # slot starts is still predicted, by the slot, as without the repeated position
    dense = res.dense()
    tips = []
    for extra in ("G1 X-15 Y0\n", ""):
        prog = parse_program(head + extra + "G1 X15 F600\nM30\n")
        out = Predictor(tool, stock, prog, STEEL, stiff_tool(), resolution=dense).run()
        tips.append([tuple(np.round(p.geometry.tip, 6)) for p in out.points
                     if p.status == "predicted"])
    assert (-15.0, 0.0, 0.0) in tips[1] and tips[0] == tips[1]


def test_point_geometry_ships_its_arrays_exactly_and_smaller():
    """Stage-1 results cross to stage 2 by pickle (worker processes): the packed
    per-revolution arrays come back identical, dtype included, and smaller."""
    import pickle

    _, _, g = side_cut("up", 2.5)
    back = pickle.loads(pickle.dumps(g))
    for name in ("cutting0", "weight0", "shift0", "cl_per_rev", "frame", "tip"):
        a, b = getattr(g, name), getattr(back, name)
        assert a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b)
    assert g.sensitivity is not None
    for a, b in zip(g.sensitivity[1:], back.sensitivity[1:], strict=True):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    raw = sum(getattr(g, n).nbytes for n in ("cutting0", "weight0", "shift0"))
    assert len(pickle.dumps(g)) < 0.8 * 2 * raw


def test_removed_memo_answers_as_the_kernel_in_any_order():
    """The T1 memo of a point gives the kernel's own answer for every sample, however
    the samples are split between calls and repeated."""
    from errpred import constants as K
    from errpred._cluster_kernels import inside_any_sweep_clustered
    from errpred.t1memo import RemovedMemo as _RemovedMemo

    tool, model, g = side_cut("slot", 0.0)
    t1, _, _ = model._near_sweeps(g.tip, g.axis, g.path_mm, 0.05)
    rng = np.random.default_rng(11)
    world = g.tip + rng.uniform([-6, -6, -1], [6, 6, 3], (4000, 3))
    ref = inside_any_sweep_clustered(world, np.ones(4000, dtype=np.bool_), *t1,
                                     tool.core_radius_mm, tool.corner_radius_mm,
                                     tool.flute_length_mm, K.MEMBERSHIP_EPS_MM,
                                     K.CLUSTER_CELL_MM)
    assert 0 < ref.sum() < 4000
    memo = _RemovedMemo(tool, t1)
    keys = np.arange(4000) * 7
    for part in (rng.permutation(4000)[:2500], rng.permutation(4000)[:2500], np.arange(4000)):
        got = memo("grid", keys[part], world[part])
        assert np.array_equal(got, ref[part])


def test_prediction_without_sensitivity_has_the_same_error():
    """The sensitivity pass (what a correction needs) changes no error: without it the
    points are the same, E identical, and the gain is not computed (0)."""
    prog = parse_program(plane_raster(30.0, R, passes=4))
    mid_pass = [b for b in range(len(prog)) if 45 <= prog.line[b] <= 52]
    out = []
    for sens in (True, False):
        pred = Predictor(Tool("ball", D, flute_length_mm=15), plane_stock(30.0, 0.2), prog,
                         STEEL, stiff_tool(), sensitivity=sens)
        out.append(pred.run(mid_pass))
    with_s, without = out
    assert [q.status for q in with_s.points] == [q.status for q in without.points]
    got = [(a.E_um, b.E_um) for a, b in zip(with_s.points, without.points) if a.result]
    assert got and all(a == b for a, b in got)
    assert any(q.result.gain != 0.0 for q in with_s.predicted())
    assert all(q.result.gain == 0.0 for q in without.predicted())


def test_blocks_sharing_the_last_blocks_look_up_give_what_their_own_give(monkeypatch):
    """A block whose box lies inside the last block's grown look-up box takes its sweeps
    from it (:class:`errpred.sweeps.BlockLookup`, kept across blocks): every point the
    same, bit for bit, as from a model that looks each block up alone; and the look-up
    is shared (fewer grid look-ups than blocks)."""
    import pickle

    from errpred.sweeps import Sweeps

    prog = parse_program(plane_raster(30.0, R, passes=4))
    blocks = [b for b in range(len(prog)) if 40 <= prog.line[b] <= 70]
    tool, stock = Tool("ball", D, flute_length_mm=15), plane_stock(30.0, 0.2)
    cl = cutter_locations(prog)
    res = Resolution.default(tool)
    queries = []
    query = Sweeps.query
    monkeypatch.setattr(Sweeps, "query", lambda self, lo, hi: queries.append(1) or
                        query(self, lo, hi))
    shared = GeometryModel(tool, stock, cl, res)
    got = [pickle.dumps(g) for b in blocks for g in shared.geometry(b)]
    assert len(queries) < len(blocks) // 2
    alone = []
    for b in blocks:
        model = GeometryModel(tool, stock, cl, res)
        alone += [pickle.dumps(g) for g in model.geometry(b)]
    assert len(got) == len(alone) >= len(blocks) and got == alone


def test_two_worker_processes_predict_as_one():
    """Stage 1 in two worker processes (chunks of a few blocks, results shipped packed)
    gives the same points and errors, in the same order, as in this process."""
    prog = parse_program(plane_raster(30.0, R, passes=4))
    blocks = [b for b in range(len(prog)) if 45 <= prog.line[b] <= 60]
    pred = Predictor(Tool("ball", D, flute_length_mm=15), plane_stock(30.0, 0.2), prog,
                     STEEL, stiff_tool())
    one = pred.run(blocks)
    two = pred.run(blocks, workers=2)
    assert len(blocks) >= 8 and len(one.points) == len(two.points)
    for a, b in zip(one.points, two.points, strict=True):
        assert (a.block, a.status) == (b.block, b.status)
        assert (a.E_um == b.E_um) or (math.isnan(a.E_um) and math.isnan(b.E_um))
        if a.result is not None:
            assert a.result.gain == b.result.gain
    np.testing.assert_array_equal(one.wear_mm, two.wear_mm)


def test_compiled_engagement_gives_the_numpy_twins_points(monkeypatch):
    """Stage 1 with the engagement's numba kernels and with their numpy twins (the code
    they replaced) gives the same points, to the byte of their pickles: a box stock (side
    cuts) and a mesh stock (a ball raster on an inclined plane), sensitivity pass on."""
    import pickle

    from errpred import _engage_kernels as EK
    from errpred import point_engagement as PE

    prog = parse_program(plane_raster(30.0, R, passes=4))
    blocks = [b for b in range(len(prog)) if 45 <= prog.line[b] <= 52]

    def points():
        out = [side_cut(mode, 2.0)[2] for mode in ("up", "slot")]
        model = GeometryModel(Tool("ball", D, flute_length_mm=15), plane_stock(30.0, 0.2),
                              cutter_locations(prog), Resolution(pixel_mm=D / 64))
        out += [g for b in blocks for g in model.geometry(b)]
        return [pickle.dumps(g, protocol=4) for g in out]

    compiled = points()
    for name in ("grid_candidates", "boundary_cells", "sub_samples", "cell_weights"):
        monkeypatch.setattr(PE, name, getattr(EK, name + "_numpy"))
    twins = points()
    assert len(compiled) == len(twins) >= 8
    assert sum(b"predicted" in p for p in compiled) >= 4  # points that cut and were predicted
    assert compiled == twins


def test_precheck_samples_are_the_inset_grid_samples_and_cached():
    """The pre-check's samples: every PRECHECK_ROTATION_STRIDE-th rotation step of the
    micro edges asked for, moved in radially and up by the inset; a repeated request
    gets the same array, a different edge set or inset its own."""
    from errpred import constants as K

    tool, model, g = side_cut("slot", 0.0)
    eng = model.engager
    grid = eng.grid(1)
    n, m = grid.shape
    ok = model.edges.z <= 1.0
    assert 0 < ok.sum() < m
    for inset in (K.PRECHECK_INSET_MM, K.RAPID_TOUCH_MM):
        got = eng.precheck_samples(ok, inset)
        src = grid.samples.reshape(n, m, 3)[::K.PRECHECK_ROTATION_STRIDE][:, ok].reshape(-1, 3)
        assert got.shape == src.shape
        rho0, rho = np.hypot(src[:, 0], src[:, 1]), np.hypot(got[:, 0], got[:, 1])
        assert np.allclose(rho, np.maximum(rho0 - inset, 0.0), atol=1e-12)
        assert np.allclose(got[:, 2], src[:, 2] + inset, atol=1e-12)
        assert eng.precheck_samples(ok.copy(), inset) is got
    rows = len(range(0, n, K.PRECHECK_ROTATION_STRIDE))
    assert eng.precheck_samples(~ok, K.PRECHECK_INSET_MM).shape == (rows * (~ok).sum(), 3)


def test_sweep_kernels_are_given_read_only_sweeps(monkeypatch):
    """Every call of the clustered sweep kernels gets T1 and T2 (or a subset of them)
    read-only: numba compiles a kernel once per argument type, and a writeable subset
    compiled a second copy of the largest kernel (14 s on a fresh cache). Covers a
    3-axis raster (its height map's remaining sweeps), a tilted ball and a flat end
    mill's side view (the nearest sweeps of T2 asked first)."""
    import inspect

    from errpred import bottomview, engagement, geometry, surface, t1memo

    seen: list[tuple[str, int, tuple[bool, ...]]] = []

    def recorder(name, real):
        def call(*args):
            caller = inspect.stack()[1]
            seen.append((caller.filename.rsplit("/", 1)[-1], caller.lineno,
                         tuple(a.flags.writeable for a in args[2:7])))
            return real(*args)
        return call

    for mod in (bottomview, engagement, geometry, surface, t1memo):
        for name in ("inside_any_sweep_clustered", "sweep_margin_clustered"):
            if hasattr(mod, name):
                monkeypatch.setattr(mod, name, recorder(name, getattr(mod, name)))
    prog = parse_program(plane_raster(30.0, R, passes=4))
    pred = Predictor(Tool("ball", D, flute_length_mm=15), plane_stock(30.0, 0.2), prog,
                     STEEL, stiff_tool())
    pred.model.use_sweep_map = True
    pred.run([b for b in range(len(prog)) if 45 <= prog.line[b] <= 52])
    u = np.array([math.sin(math.radians(45.0)), 0.0, math.cos(math.radians(45.0))])
    prog = parse_program(plane_raster(20.0, R, passes=4, axis=u))
    Predictor(Tool("ball", D, flute_length_mm=15), plane_stock(20.0, 0.2), prog, STEEL,
              stiff_tool()).run([b for b in range(len(prog)) if 45 <= prog.line[b] <= 52])
    # a wall with the path ahead in short moves: T2 has more sweeps than are asked first
    tool = Tool("flat", D, flutes=3, helix_deg=0.0, flute_length_mm=6.0)
    ahead = "".join(f"G1 X{x}\n" for x in range(3, 31, 3))
    prog = parse_program(f"G21 G90 G94\nS6000 M3\nG0 X-30 Y0 Z0\nG1 X-2 F600\nG1 X2\n"
                         f"{ahead}M30\n")
    model = GeometryModel(tool, Stock.from_box([-20.0, R - 1.0, 0.001], [20.0, 30.0, 2.0]),
                          cutter_locations(prog), Resolution(pixel_mm=D / 64))
    (g,) = model.geometry(2)
    assert g.view == "side"
    sites = {(f, line) for f, line, _ in seen}
    assert {f for f, _ in sites} >= {"t1memo.py", "bottomview.py", "surface.py"}, sites
    # the memo's three calls: without the map, with it, and the sweeps it lacks
    assert len({line for f, line in sites if f == "t1memo.py"}) == 3, sites
    writeable = {(f, line) for f, line, flags in seen if any(flags)}
    assert not writeable, writeable
