"""Cutter locations, arc expansion and the CL file format."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nc import parse_program
from nc.errors import CLFileError
from nc.path import (CutterLocations, block_lengths, cutter_locations, expand_arcs,
                     read_cl_csv, write_cl_csv)
from nc.summary import summarize


@pytest.mark.parametrize("tol", [1e-1, 1e-2, 1e-3, 1e-4])
def test_arc_chords_stay_within_tolerance(tol):
    prog = parse_program("G21 G90 G17\nG0 X10 Y0\nG3 X-10 Y0 Z-3 I-10 J0 F100\n")
    pts, block = expand_arcs(prog, tol)
    arc = pts[block == 1]
    chain = np.vstack([[10, 0, 0], arc[:, :3]])
    mids = 0.5 * (chain[1:] + chain[:-1])
    # sagitta: distance of the chord midpoints inside the circle
    sag = 10 - np.hypot(mids[:, 0], mids[:, 1])
    assert sag.max() <= tol * (1 + 1e-9)
    assert sag.max() > tol / 4  # not absurdly fine either
    np.testing.assert_allclose(np.hypot(arc[:, 0], arc[:, 1]), 10, atol=1e-12)
    # helix: z linear in the angle
    ang = np.unwrap(np.arctan2(chain[:, 1], chain[:, 0]))
    np.testing.assert_allclose(chain[:, 2], -3 * ang / math.pi, atol=1e-12)
    np.testing.assert_array_equal(arc[-1], prog.end[1])


def test_expanded_length_converges_to_helix_length():
    prog = parse_program("G21 G90 G17\nG0 X10 Y0\nG3 X10 Y0 Z-6 I-10 J0 P2 F100\n")
    exact = math.hypot(2 * 2 * math.pi * 10, 6)
    assert block_lengths(prog)[1] == pytest.approx(exact, rel=1e-12)
    errs = []
    for tol in (1e-1, 1e-2, 1e-3):
        pts, block = expand_arcs(prog, tol)
        chain = np.vstack([prog.end[0, :3], pts[block == 1, :3]])
        errs.append(exact - np.linalg.norm(np.diff(chain, axis=0), axis=1).sum())
    assert errs[0] > errs[1] > errs[2] > 0
    assert errs[2] / exact < 1e-4


def test_spiral_arc_blends_radius():
    # start radius 10, end radius 10.004 (within LinuxCNC's tolerance)
    prog = parse_program("G21 G90 G17\nG0 X10 Y0\nG3 X0 Y10.004 I-10 J0 F100\n")
    pts, block = expand_arcs(prog, 1e-3)
    r = np.hypot(pts[block == 1, 0], pts[block == 1, 1])
    assert np.all(np.diff(r) > 0) and r[-1] == pytest.approx(10.004)


def test_summary_figures_by_hand():
    src = ("G21 G90 G17 G94\nG0 X0 Y0 Z5\nG1 Z0 F100\nG1 X30 F300\n"
           "G2 X30 Y-20 I0 J-10\nG93 G1 X0 F2\nG94 G0 Z5\nM30\n")
    s = summarize(parse_program(src))
    assert s.motion_blocks == 6 and s.rapid_blocks == 2 and s.arc_blocks == 1
    cutting = 5 + 30 + math.pi * 10 + 30
    assert s.cutting_length_mm == pytest.approx(cutting)
    assert s.rapid_length_mm == pytest.approx(5 + 5)
    assert s.cutting_time_min == pytest.approx(5 / 100 + (30 + math.pi * 10) / 300 + 0.5)
    # the arc bulges to X40 between its ends
    np.testing.assert_allclose(s.bbox_max_mm, (40, 0, 5), atol=1e-3)
    np.testing.assert_allclose(s.bbox_min_mm, (0, -20, 0), atol=1e-9)


def test_cutter_locations_three_axis_and_vector():
    prog = parse_program("G21 G90\nG0 X0 Y0 Z5\nG1 Z0 F200\nG1 X10\n")
    cl = cutter_locations(prog)
    assert cl.rapid.tolist() == [True, False, False]
    np.testing.assert_allclose(cl.axis, [[0, 0, 1]] * 3)
    np.testing.assert_allclose(cl.feed_mm_min[1:], 200)
    prog = parse_program("G21 G90\nG43.5 H1\nG1 X1 I0 J1 K1 F100\nG1 X2 I0 J0 K1\n")
    cl = cutter_locations(prog)
    np.testing.assert_allclose(cl.axis, [[0, math.sqrt(0.5), math.sqrt(0.5)], [0, 0, 1]])
    with pytest.raises(ValueError, match="machine is needed"):
        cutter_locations(parse_program("G21 G1 X1 A10 F100\n"))


def test_cutter_locations_validation():
    tip = np.zeros((2, 3))
    with pytest.raises(ValueError, match="unit vector"):
        CutterLocations.from_arrays(tip, [0, 0, 2], 100.0)
    with pytest.raises(ValueError, match="not finite"):
        CutterLocations.from_arrays(np.array([[0, 0, np.nan], [0, 0, 0]]), [0, 0, 1], 100.0)
    with pytest.raises(ValueError, match="feed"):
        CutterLocations.from_arrays(tip, [0, 0, 1], 0.0)
    with pytest.raises(ValueError, match="shape"):
        CutterLocations.from_arrays(np.zeros((2, 2)), [0, 0, 1], 100.0)


def test_cl_csv_round_trip(tmp_path):
    rng = np.random.default_rng(3)
    axis = rng.normal(size=(20, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    cl = CutterLocations.from_arrays(rng.uniform(-50, 50, (20, 3)), axis,
                                     rng.uniform(100, 3000, 20), 9000.0)
    path = tmp_path / "cl.csv"
    write_cl_csv(path, cl, decimals=9)
    back = read_cl_csv(path)
    np.testing.assert_allclose(back.tip, cl.tip, atol=1e-9)
    np.testing.assert_allclose(back.axis, cl.axis, atol=2e-9)
    np.testing.assert_allclose(back.feed_mm_min, cl.feed_mm_min, atol=1e-9)
    np.testing.assert_allclose(back.spindle_rpm, 9000.0)


@pytest.mark.parametrize("body,line,column,fragment", [
    ("x,y,z,i,j,k\n0,0,0,0,0,1\n", 1, None, "lacks column(s) feed"),
    ("x,y,z,i,j,k,feed,colour\n", 1, None, "unknown column(s) colour"),
    ("x,y,z,i,j,k,feed\n0,0,0,0,0,1,100\n0,0,zero,0,0,1,100\n", 3, "z", "not a number"),
    ("x,y,z,i,j,k,feed\n0,0,nan,0,0,1,100\n", 2, "z", "not a finite"),
    ("x,y,z,i,j,k,feed\n0,0,0,0,0,0.9,100\n", 2, "i", "unit vector"),
    ("x,y,z,i,j,k,feed\n0,0,0,0,0,1,-5\n", 2, "feed", "feed > 0"),
    ("x,y,z,i,j,k,feed\n0,0,0,0,0,1\n", 2, None, "6 fields; expected 7"),
    ("# only a comment\n", None, None, "empty file"),
])
def test_cl_csv_errors_name_line_and_column(tmp_path, body, line, column, fragment):
    path = tmp_path / "bad.csv"
    path.write_text(body)
    with pytest.raises(CLFileError) as info:
        read_cl_csv(path)
    err = info.value
    assert err.file == str(path) and err.line == line and err.column == column
    assert fragment in str(err) and str(err).startswith(str(path))
