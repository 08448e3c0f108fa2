"""The planner on the bundled thin-wall scenario: stable where the CAM chatters, no
collisions, axis limits, smooth, written and read back, accepted by LinuxCNC's rs274."""

from __future__ import annotations

import numpy as np

from nc import read_program
from nc.kinematics import solve_path
from nc.linuxcnc import compare_with_rs274
from nc.path import CutterLocations, cutter_locations
from nc.writer import PostOptions, write_program
from orient.interference import InterferenceChecker, ToolAssembly
from orient.scenario import bundled_scenario, load_plan_scenario


def test_cam_posture_chatters_and_planned_posture_does_not(planned):
    _, res = planned
    idx = res.touching_index
    assert len(idx) > 1000
    assert res.cam_margin[idx].min() < 1.0          # the CAM default chatters somewhere
    assert res.margin[idx].min() > 1.0              # the plan is stable at every cutting point
    # never worse than the CAM posture where that was feasible
    ok = res.cam_feasible[idx]
    assert np.all(res.margin[idx][ok] >= np.minimum(res.cam_margin[idx][ok],
                                                    res.margin[idx][ok]) - 1e-9)


def test_time_periodic_method_confirms_the_lowest_points(planned):
    _, res = planned
    assert len(res.sdm_checks) >= 3
    for c in res.sdm_checks:
        assert c["sdm_margin"] > 1.0, c


def test_no_collision_no_gouge_and_within_axis_limits(planned):
    scn, res = planned
    feed = ~res.cl.rapid
    import trimesh

    stock = trimesh.load(str(scn.base.stock.path), force="mesh")
    design = scn.base.stock.load_design()
    chk = InterferenceChecker(stock, ToolAssembly.from_tool(
        scn.base.tool, clearance_mm=scn.options.clearance_mm), design_mesh=design,
        gouge_tol_mm=scn.options.gouge_tol_mm)
    r = chk.check(res.cl.tip[feed], res.cl.axis[feed])
    assert not r.collides.any() and not r.gouges.any()
    sol = solve_path(res.machine, res.cl.tip, res.cl.axis)      # raises outside the limits
    assert res.machine.within_limits(sol.joints).all()


def test_ball_centre_and_contact_are_kept(planned):
    scn, res = planned
    idx = res.touching_index
    R = scn.base.tool.radius_mm
    np.testing.assert_allclose(res.cl.tip[idx] + R * res.cl.axis[idx],
                               res.contacts.centre[idx], atol=1e-9)
    incl = np.degrees(np.arccos(np.sum(res.cl.axis[idx] * res.contacts.normal[idx], axis=1)))
    assert incl.min() >= np.degrees(scn.options.min_inclination_rad) - 1e-6
    assert incl.max() <= np.degrees(scn.options.max_inclination_rad) + 1e-6


def test_axis_turns_no_faster_than_the_limit_within_a_pass(planned):
    scn, res = planned
    idx = res.touching_index
    run = np.cumsum(res.cam.rapid)[idx]
    same = run[1:] == run[:-1]
    turn = np.arccos(np.clip(np.sum(res.cl.axis[idx][1:] * res.cl.axis[idx][:-1], axis=1),
                             -1, 1))
    step = np.linalg.norm(np.diff(res.cam.tip[idx], axis=0), axis=1)
    assert np.all(turn[same] <= scn.options.max_rate_rad_per_mm * step[same] + 1e-6)


def test_program_round_trips_and_rs274_accepts_it(planned, tmp_path, rs274):
    _, res = planned
    out = tmp_path / "planned.ngc"
    post = write_program(out, res.cl, res.machine, PostOptions(dialect="linuxcnc",
                                                               source="test"))
    prog = read_program(out)
    back = cutter_locations(prog, res.machine)
    # every written point is read back at the same tip, with the same axis
    d = np.linalg.norm(back.tip[:, None, :] - post.tip[None, ::7, :], axis=2)
    j = d.argmin(axis=0)
    assert d.min(axis=0).max() < 2e-4
    cos = np.sum(back.axis[j] * post.axis[::7], axis=1)
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 1e-3
    cmp = compare_with_rs274(out, prog)
    assert cmp.ok, cmp.message


def test_first_pass_of_the_face_cuts_on_both_sides():
    """Passes run from the top down with the previous pass above (machined side +Z): the
    top pass has none beside it, every later one has."""
    from nc.kinematics import get_machine
    from nc.path import cutter_locations
    from orient.contacts import ball_contacts
    from orient.cuts import local_cuts

    scn = load_plan_scenario(bundled_scenario("thin-wall"))
    cam = cutter_locations(scn.base.read_program(), get_machine(scn.base.machine))
    con = ball_contacts(cam, scn.base.tool.radius_mm, scn.base.stock.load_design())
    idx = np.flatnonzero(con.touching)
    side = np.array([c.previous_side for c in local_cuts(scn, con, idx, cam, 9000.0)])
    top = con.point[idx, 2] > con.point[idx, 2].max() - 1e-6
    assert top.sum() > 20
    assert np.all(side[top] == 0) and np.all(side[~top] != 0)


def test_the_feed_is_the_ball_centre_motion_where_the_posture_turns():
    """A ball whose centre runs along +X while its axis swings in the Y-Z plane: the tip
    moves in Y and Z as well, but the contact -- and the feed of the cut -- runs along
    +X."""
    import trimesh

    from orient.contacts import ball_contacts

    n = 9
    x = np.linspace(0.0, 8.0, n)
    ang = np.radians(np.linspace(0.0, 40.0, n))
    axis = np.c_[np.zeros(n), np.sin(ang), np.cos(ang)]
    centre = np.c_[x, np.zeros(n), np.full(n, 5.0)]
    cl = CutterLocations.from_arrays(centre - 5.0 * axis, axis, 1000.0, 9000.0)
    plate = trimesh.creation.box(extents=(40.0, 40.0, 2.0))
    plate.apply_translation((0.0, 0.0, -1.0))
    con = ball_contacts(cl, 5.0, plate)
    assert con.touching.all()
    np.testing.assert_allclose(con.feed, np.tile([1.0, 0.0, 0.0], (n, 1)), atol=1e-12)
