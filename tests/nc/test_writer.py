"""The 5-axis writer: read back by this package and by LinuxCNC's rs274."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from nc import read_program
from nc.errors import KinematicsError
from nc.kinematics import MACHINES, get_machine
from nc.linuxcnc import compare_with_rs274
from nc.path import CutterLocations, cutter_locations, read_cl_csv
from nc.writer import DIALECTS, PostOptions, post, write_program

BLADE = os.path.join(os.path.dirname(__file__), "..", "..", "nc", "data", "blade_cl.csv")

#: Machines with pivots away from the origin, so the kinematics matter.
GEOMETRY = {
    "xyzac-trt": dict(tilt_pivot_mm=(0.0, 20.0, -35.0), rotary_pivot_mm=(5.0, -3.0, 0.0)),
    "xyzbc-trt": dict(tilt_pivot_mm=(-15.0, 0.0, -40.0), rotary_pivot_mm=(2.0, 4.0, 0.0)),
    "xyzbc-head-table": dict(tool_length_mm=80.0, tilt_pivot_mm=(0.0, 0.0, 150.0),
                             rotary_pivot_mm=(10.0, -5.0, 0.0)),
    "xyzbc-head-head": dict(tool_length_mm=80.0, tilt_pivot_mm=(0.0, 0.0, 120.0),
                            rotary_pivot_mm=(3.0, 0.0, 200.0)),
}


def machine(name):
    return get_machine(name, **GEOMETRY[name])


@pytest.fixture(scope="module")
def blade():
    cl = read_cl_csv(BLADE)
    return cl.take(slice(0, 300))  # four passes: reversals, tilt and twist changes


def _cutting_points(prog, m):
    """Tip and axis of every feed move after the approach, read back."""
    cl = cutter_locations(prog, m)
    cut = np.flatnonzero(~cl.rapid)
    return cl.tip[cut], cl.axis[cut]


@pytest.mark.parametrize("dialect", DIALECTS)
@pytest.mark.parametrize("name", list(MACHINES))
def test_round_trip_through_reader(name, dialect, blade, tmp_path, lcnc_agrees):
    m = machine(name)
    out = tmp_path / "p.nc"
    res = write_program(out, blade, m, PostOptions(dialect=dialect))
    prog = read_program(out)
    if dialect == "linuxcnc":
        lcnc_agrees(out)
    tip, axis = _cutting_points(prog, m)
    # the first feed move descends from the approach point to the first point
    assert len(tip) == len(res.tip)
    # 4 decimals of mm and degrees; lever arms up to ~250 mm -> 4e-4 mm
    np.testing.assert_allclose(tip, res.tip, atol=5e-4)
    ang = np.arccos(np.clip(np.sum(axis * res.axis, axis=1), -1, 1))
    assert ang.max() < (3e-6 if dialect != "fanuc-g43.5" else 2e-6)
    # every input point is among the written ones, in order
    src = res.source
    assert np.all(np.diff(src) > 0)
    assert set(np.arange(len(blade))) <= set(np.round(src[np.isclose(src, np.round(src))]).astype(int))


@pytest.mark.parametrize("name", list(MACHINES))
def test_linuxcnc_programs_pass_rs274(name, blade, tmp_path, rs274):
    m = machine(name)
    out = tmp_path / "p.ngc"
    res = write_program(out, blade, m, PostOptions(dialect="linuxcnc", line_numbers=True))
    prog = read_program(out)
    result = compare_with_rs274(out, prog)
    assert result.ok, result.message
    assert result.moves == len(res.tip) + 2  # + approach and retract


def test_inverse_time_on_rotary_moves_only(blade, tmp_path):
    m = machine("xyzac-trt")
    # a straight 3-axis pass first (no rotary motion), then the blade
    flat = CutterLocations.from_arrays(
        np.column_stack([np.linspace(-40, -30, 5), np.full(5, -20.0), np.full(5, 5.0)]),
        blade.axis[0], 1200.0, 12000.0)
    res = post(flat, m)
    lines = [ln for ln in res.text.splitlines() if ln.startswith(("G1", "G93", "G94"))]
    assert not any("G93" in ln for ln in lines)
    res = post(blade, m)
    prog_lines = res.text.splitlines()
    g1 = [ln for ln in prog_lines if " G1 " in f" {ln} " or ln.startswith("G93 G1")]
    inv = [ln for ln in g1 if "F" in ln]
    assert res.inverse_time_moves > 0
    # in G93 every feed move carries its F (rs274 refuses it otherwise)
    prog = read_program_text(res.text)
    fm = prog.modal_column("feed_mode")
    assert np.all(~np.isnan(prog.feed[fm == 93]))
    # inverse-time F = tip feed / tip distance: the tip moves at the programmed feed
    cl = cutter_locations(prog, m)
    cut = np.flatnonzero(~cl.rapid)[1:]
    np.testing.assert_allclose(cl.feed_mm_min[cut], 1500.0, rtol=2e-3)
    assert len(inv) == len(g1)


def read_program_text(text):
    from nc import parse_program

    return parse_program(text)


def test_linearization_keeps_the_tip_on_the_line(blade):
    m = machine("xyzac-trt")
    tol = 0.002
    res = post(blade, m, PostOptions(linearize_tol_mm=tol))
    prog = read_program_text(res.text)
    j = np.column_stack([prog.end[:, :3], prog.end[:, [3, 5]]])[1:-1]  # cutting points
    tip, _ = m.forward(j)
    worst = 0.0
    for f in np.linspace(0.05, 0.95, 19):
        mid = j[:-1] + f * (j[1:] - j[:-1])  # what the control interpolates
        p, _ = m.forward(mid)
        a, b = tip[:-1], tip[1:]
        d = b - a
        t = np.clip(np.sum((p - a) * d, 1) / np.maximum(np.sum(d * d, 1), 1e-30), 0, 1)
        worst = max(worst, np.linalg.norm(p - (a + t[:, None] * d), axis=1).max())
    assert worst <= tol + 2e-4  # + rounding of the written digits
    # without linearization the same path leaves the line by more than tol
    raw = np.column_stack([blade.tip, np.zeros((len(blade), 2))])
    from nc.kinematics import solve_path

    sol = solve_path(m, blade.tip, blade.axis)
    jj = sol.joints
    mid = 0.5 * (jj[:-1] + jj[1:])
    p, _ = m.forward(mid)
    chord_mid = 0.5 * (blade.tip[:-1] + blade.tip[1:])
    assert np.linalg.norm(p - chord_mid, axis=1).max() > tol
    assert raw.shape[0] == len(blade)


def test_c_axis_unwraps_past_360(tmp_path, rs274):
    m = machine("xyzac-trt")
    t = np.linspace(0, 4 * math.pi, 241)  # the tool axis circles twice around Z
    tilt = math.radians(30)
    axis = np.column_stack([np.sin(tilt) * np.cos(t), np.sin(tilt) * np.sin(t),
                            np.full_like(t, math.cos(tilt))])
    tip = np.column_stack([20 * np.cos(t), 20 * np.sin(t), np.full_like(t, -5.0)])
    cl = CutterLocations.from_arrays(tip, axis, 800.0, 10000.0)
    out = tmp_path / "spiral.ngc"
    write_program(out, cl, m)
    prog = read_program(out)
    c = np.degrees(prog.end[1:-1, 5])
    assert np.ptp(c) > 700  # two turns, not wrapped back into +-180
    assert np.abs(np.diff(c)).max() < 5
    result = compare_with_rs274(out, prog)
    assert result.ok, result.message


def test_options_shape_the_text(blade):
    m = machine("xyzbc-head-table")
    res = post(blade.take(slice(0, 5)), m, PostOptions(
        dialect="fanuc-g43.4", line_numbers=True, line_number_start=100, line_number_step=5,
        linear_decimals=3, angle_decimals=2, end_code="M2", program_number=42, tool=7))
    lines = res.text.splitlines()
    assert lines[0] == "%" and lines[1] == "O0042" and lines[-1] == "%"
    numbered = [ln for ln in lines if ln.startswith("N")]
    numbers = [int(ln.split()[0][1:]) for ln in numbered]
    assert numbers == list(range(100, 100 + 5 * len(numbers), 5))
    assert any("G43.4 H7" in ln for ln in lines) and any("T7 M6" in ln for ln in lines)
    assert numbered[-1].endswith("M2")
    for ln in lines:
        for w in ln.split():
            if w[0] in "XYZ" and w[1:2] in "-0123456789":
                assert len(w.split(".")[1]) == 3
            if w[0] in "BC" and w[1:2] in "-0123456789":
                assert len(w.split(".")[1]) == 2
    res = post(blade.take(slice(0, 5)), m, PostOptions(dialect="fanuc-g43.5", header=False,
                                                       end_code=None))
    assert "(" not in res.text and "M30" not in res.text and "G43.5" in res.text
    assert not any(w[0] in "ABC" for ln in res.text.splitlines() for w in ln.split()
                   if w[:1] in "ABC" and w[1:2] in "-0123456789")


def test_unreachable_posture_writes_nothing(blade, tmp_path):
    m = get_machine("xyzac-trt", tilt_limits_rad=(math.radians(-30), math.radians(30)))
    out = tmp_path / "p.ngc"
    out.write_text("previous program\n")
    with pytest.raises(KinematicsError) as info:
        write_program(out, blade, m)
    assert info.value.index is not None
    assert out.read_text() == "previous program\n"
    assert sorted(os.listdir(tmp_path)) == ["p.ngc"]  # no temporary file left behind


def test_options_are_checked():
    with pytest.raises(ValueError, match="dialect"):
        PostOptions(dialect="heidenhain")
    with pytest.raises(ValueError, match="linear_decimals"):
        PostOptions(linear_decimals=12)
    with pytest.raises(ValueError, match="clearance_mm"):
        PostOptions(clearance_mm=float("nan"))


def test_noisy_axis_near_singularity_is_refused_not_written(tmp_path):
    rng = np.random.default_rng(5)
    n = 200
    m = machine("xyzac-trt")
    tip = np.column_stack([np.linspace(-30, 30, n), np.zeros(n), np.full(n, -2.0)])
    axis = np.column_stack([rng.normal(0, 2e-3, n), rng.normal(0, 2e-3, n), np.ones(n)])
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    cl = CutterLocations.from_arrays(tip, axis, 1000.0, 8000.0)
    out = tmp_path / "noisy.ngc"
    with pytest.raises(KinematicsError, match="singular_cone_rad"):
        write_program(out, cl, m)
    assert not out.exists()
    res = write_program(out, cl, m, PostOptions(singular_cone_rad=0.01))
    assert res.singular_points == n
    prog = read_program(out)
    c = np.degrees(prog.end[1:-1, 5])
    assert np.ptp(c) == 0.0  # C held, never spun


@pytest.mark.parametrize("dialect", DIALECTS)
def test_source_name_cannot_break_the_header_comment(dialect, tmp_path):
    cl = CutterLocations.from_arrays([[0.0, 0.0, 5.0], [10.0, 0.0, 5.0]], [0.0, 0.0, 1.0],
                                     600.0, 1000.0)
    path = tmp_path / "p.nc"
    write_program(path, cl, get_machine("xyzac-trt"),
                  PostOptions(dialect=dialect, source="wall (lead 15 deg); pass 1"))
    header = next(line for line in path.read_text().splitlines()
                  if line.startswith("(PROGRAM:"))
    assert header.count("(") == 1 and header.count(")") == 1 and ";" not in header
    assert "[lead 15 deg], pass 1" in header
    assert len(read_program(path)) > 0     # the reader takes the whole program


def test_round_trip_skips_the_rapid_points_before_the_first_cut():
    """A CAM path that starts with several rapid moves (a retract, a move over the start,
    a descent): the writer replaces them by its approach, and the round trip compares
    what was written (it had compared shifted points: 75 mm on the mold core)."""
    from nc.gcode import parse_program
    from nc.writer import PostOptions, post, round_trip_error

    m = get_machine("xyzbc-head-table", tool_length_mm=40.0)
    x = np.linspace(0.0, 20.0, 41)
    tip = np.r_[[[0.0, 0.0, 25.0], [-5.0, 20.0, 25.0], [-5.0, 20.0, 1.0]],
                np.c_[x, np.full(41, 20.0), 0.1 * x]]
    ax = np.tile([np.sin(0.3), 0.0, np.cos(0.3)], (len(tip), 1))
    rapid = np.r_[[True, True, True], np.zeros(41, bool)]
    cl = CutterLocations.from_arrays(tip, ax, np.where(rapid, np.nan, 1600.0), 10000.0,
                                     rapid=rapid)
    res = post(cl, m, PostOptions(dialect="linuxcnc"))
    assert res.first_written == 3
    back = cutter_locations(parse_program(res.text, file="<round trip>"), m)
    e_tip, e_axis = round_trip_error(res, back)
    assert e_tip < 1e-3 and e_axis < 1e-6


def test_a_rapid_turning_past_the_pole_is_written_on_the_line():
    """A link's turn at the clearance height from one flank's tilt to the other's (B 45 to
    -40 deg on a head-table machine) whose axis passes 0.3 deg from the C axis: by slerp
    no bisection depth keeps the tip on the line (C swings through 180 deg in a sliver);
    the writer turns a rapid by the machine's own interpolation of the angles, and the
    program read back keeps the tip within the tolerance of the line everywhere."""
    from nc.kinematics import linearize, solve_path

    m = get_machine("xyzbc-head-table")
    tol = 0.002

    def ax(b, c):
        b, c = math.radians(b), math.radians(c)
        return [math.sin(b) * math.cos(c), math.sin(b) * math.sin(c), math.cos(b)]

    tips = np.array([[60.0, 25.0, 0.0], [60.0, 25.0, 25.0], [-5.0, 25.5, 25.0],
                     [-5.0, 25.5, 0.0]])
    axes = np.array([ax(45.0, 0.3), ax(45.0, 0.3), ax(-40.0, -0.3), ax(-40.0, -0.3)])
    rapid = np.array([False, True, True, True])
    cl = CutterLocations.from_arrays(tips, axes, np.where(rapid, np.nan, 1000.0), 8000.0,
                                     rapid=rapid)
    sol = solve_path(m, tips, axes)
    assert linearize(m, tips, axes, sol.joints).max_deviation_mm > 10.0     # slerp: no
    res = post(cl, m, PostOptions(linearize_tol_mm=tol))
    prog = read_program_text(res.text)
    j = np.column_stack([prog.end[:, :3], prog.end[:, [4, 5]]])[1:-1]
    tip, _ = m.forward(j)
    at = (np.abs(tip[:, 2] - 25.0) < 1e-3)                    # the move at the top
    k = np.flatnonzero(at[:-1] & at[1:])
    assert len(k) >= 2                                         # points were inserted
    for f in np.linspace(0.05, 0.95, 19):
        p, _ = m.forward(j[k] + f * (j[k + 1] - j[k]))
        a, b = tip[k], tip[k + 1]
        d = b - a
        t = np.clip(np.sum((p - a) * d, 1) / np.maximum(np.sum(d * d, 1), 1e-30), 0, 1)
        assert np.linalg.norm(p - (a + t[:, None] * d), axis=1).max() <= tol + 2e-4
