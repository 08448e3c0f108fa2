"""The simulated NC: feed override, orientation commands checked against axis limits
and interference, cutting only where the ball touches."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from nc.kinematics import get_machine
from orient.interference import InterferenceChecker, ToolAssembly
from orient.scenario import load_plan_scenario
from sim.cli import BUNDLED
from sim.machine import SimulatedNC
from sim.registers import ACK


@pytest.fixture(scope="module")
def built():
    scn = load_plan_scenario(BUNDLED)
    nc = SimulatedNC(scn, points=(2, 36))
    return scn, nc.workpiece


def _nc(built) -> SimulatedNC:
    scn, wp = built
    nc = SimulatedNC(scn, points=(2, 36), workpiece=wp)
    for _ in range(60):                              # into the cut
        nc.tick()
    return nc


def test_feed_override_scales_the_path_speed(built):
    a, b = _nc(built), _nc(built)
    b.set_feed_override(50.0)
    s0a, s0b = a.s, b.s
    for _ in range(40):
        a.tick()
        b.tick()
    assert (b.s - s0b) == pytest.approx(0.5 * (a.s - s0a), rel=1e-9)
    assert a.state.cutting == 1
    with pytest.raises(ValueError, match="override"):
        a.set_feed_override(151.0)


def test_orientation_beyond_the_axis_limits_is_refused(built):
    """The CAM posture (30 deg from the wall normal toward +Z) needs A = 60 deg; tilting
    10 deg back toward the normal needs A = 70 deg: with A limited to +-68.75 deg it is
    refused and the offset in effect stays; 10 deg the other way (A = 50) is taken."""
    nc = _nc(built)
    nc.machine = get_machine("xyzac-trt", tilt_limits_rad=(-1.2, 1.2))
    assert nc.command_orientation(0.0, -10.0, 1) == ACK["refused_axis_limit"]
    assert (nc.state.lead_offset_deg, nc.state.tilt_offset_deg) == (0.0, 0.0)
    assert nc.command_orientation(0.0, 10.0, 2) == ACK["applied"]
    assert nc.state.tilt_offset_deg == 10.0 and nc.state.ack_seq == 2


def test_orientation_into_a_collision_is_refused(built):
    """With a short overhang and an 80 mm holder, turning the axis onto the wall normal
    brings the holder into the base plate: refused; the check agrees with FCL."""
    scn, _ = built
    nc = _nc(built)
    tool = nc.tool
    big = dataclasses.replace(tool, overhang_mm=16.0,
                              holder=type(tool.holder)(diameter_mm=80.0, length_mm=50.0))
    design = scn.base.stock.load_design()
    nc.checker = InterferenceChecker(scn.stock_mesh(),
                                     ToolAssembly.from_tool(big, clearance_mm=1.0),
                                     design_mesh=design)
    i = nc.point_index()
    tips, axes = nc._posture(np.array([i]), 0.0, np.radians(-30.0))
    assert nc.checker.check(tips, axes).collides[0]
    assert nc.command_orientation(0.0, -30.0, 5) == ACK["refused_interference"]
    assert nc.state.tilt_offset_deg == 0.0
    tips, axes = nc._posture(np.array([i]), 0.0, np.radians(10.0))
    assert not nc.checker.check(tips, axes).collides[0]


def test_the_ball_centre_is_kept_and_cutting_stops_off_the_part(built):
    nc = _nc(built)
    i = nc.point_index()
    tips, axes = nc._posture(np.array([i]), np.radians(-20.0), np.radians(15.0))
    centre = tips[0] + nc.tool.radius_mm * axes[0]
    np.testing.assert_allclose(centre, nc.contacts.centre[i], atol=1e-9)
    while not nc.done:
        nc.tick()
    assert nc.state.cutting == 0                     # the pass ends in the air
    assert len(nc.surface.offset_mm) > 0
    pts = np.unique(nc.surface.point)
    assert np.all(nc.contacts.touching[pts])


def test_the_wall_vibration_is_carried_in_modal_coordinates():
    """Moving the cut from one point of the wall to another keeps each wall mode's
    modal coordinate: its displacement at the point scales by a_new / a_old (a node
    between them flips the sign); the tool modes are untouched; a mode new to the set,
    or another level of the wall, starts at rest."""
    from sim.machine import NO_WALL, carry_wall_state

    state = np.array([[1.0, 10.0], [2.0, 20.0], [3.0, 30.0], [4.0, 40.0]])   # 2 tool + 2 wall
    old = (1, np.array([0, 2]), np.array([2.0, 0.5]))
    new = (1, np.array([0, 1, 2]), np.array([-1.0, 3.0, 1.5]))
    out = carry_wall_state(state, 2, old, new)
    np.testing.assert_array_equal(out[:2], state[:2])
    np.testing.assert_allclose(out[2], state[2] * (-1.0 / 2.0))
    np.testing.assert_array_equal(out[3], [0.0, 0.0])
    np.testing.assert_allclose(out[4], state[3] * (1.5 / 0.5))
    assert not carry_wall_state(state, 2, old, (2, new[1], new[2]))[2:].any()
    np.testing.assert_array_equal(carry_wall_state(state, 2, old, NO_WALL), state[:2])


def test_ticks_run_at_once_are_the_ticks_one_by_one(built):
    """SimulatedNC.run_ticks (a stretch of servo ticks, one kernel call per stretch whose
    cut does not change) gives what tick_motion gives tick by tick, bit for bit: the
    instants and accelerations, the cutting flag per tick, the generated surface, the
    coverage and the cutter's state; a feed override taken between calls holds for
    both; it stops at the program's end and at a clock time as asked."""
    scn, wp = built
    one = SimulatedNC(scn, points=(2, 36), workpiece=wp)
    many = SimulatedNC(scn, points=(2, 36), workpiece=wp)
    t1, a1, c1, n1, clk = [], [], [], [], []
    while not one.done:
        if len(c1) == 150:
            one.set_feed_override(70.0)
        t, a = one.tick_motion()
        t1.append(t)
        a1.append(a)
        c1.append(one.state.cutting)
        n1.append(t.size)
        clk.append(one.state.time_s)
    runs, sizes = [], iter([1, 7, 142, 1, 3, 500])
    while not many.done:
        if sum(r.steps.size for r in runs) == 150:
            many.set_feed_override(70.0)
        runs.append(many.run_ticks(next(sizes), to_end=True))
    assert sum(c1) > 100 and len(c1) - sum(c1) > 10          # cutting and in the air
    np.testing.assert_array_equal(np.concatenate([r.time_s for r in runs]), np.concatenate(t1))
    np.testing.assert_array_equal(np.concatenate([r.tool_acceleration_m_s2 for r in runs]),
                                  np.concatenate(a1))
    np.testing.assert_array_equal(np.concatenate([r.cutting for r in runs]), np.array(c1, bool))
    np.testing.assert_array_equal(np.concatenate([r.steps for r in runs]), n1)
    for key, x in one.surface.arrays().items():
        np.testing.assert_array_equal(many.surface.arrays()[key], x)
    np.testing.assert_array_equal(many.cut_at, one.cut_at)
    np.testing.assert_array_equal(many.cutter.state, one.cutter.state)
    np.testing.assert_array_equal(many.cutter.surface, one.cutter.surface)
    assert (many.state.time_s, many.s, many.state.cutting) == \
        (one.state.time_s, one.s, one.state.cutting)
    assert many.run_ticks(5, to_end=True).steps.size == 0
    clock = SimulatedNC(scn, points=(2, 36), workpiece=wp)
    run = clock.run_ticks(10_000, until_s=0.1)
    k = int(np.argmax(np.array(clk) >= 0.1)) + 1          # the ticks that reach 0.1 s
    assert run.steps.size == k and clock.state.time_s == clk[k - 1]
