"""Heidenhain Klartext: reader, writer, round trips, real programs, bad input.

The table KNOWN holds hand-checked pairs (blocks -> moves): each expected
value is worked out in the comment beside it from the TNC 640 manual's rules,
not from running the reader.
"""

from __future__ import annotations

import math
import os
import random
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nc import constants as K
from nc.dialects import detect_dialect, read_any
from nc.errors import InputError, NCParseError
from nc.heidenhain import parse_heidenhain, read_heidenhain
from nc.heidenhain_writer import (TNC_FORMS, TNCPostOptions, heidenhain_round_trip,
                                  post_heidenhain, write_heidenhain)
from nc.kinematics import MACHINES, get_machine
from nc.path import CutterLocations, cutter_locations
from nc.program import TCP_ANGLES, TCP_OFF, TCP_VECTOR

#: Public TNC programs are not copied into the repository: their sources are listed
#: in tests/nc/external_heidenhain.txt; put the files in $NC_CORPUS_DIR/heidenhain or
#: ../shared/nc-corpus/heidenhain to run the tests that read them.
DATA = os.path.join(os.environ.get("NC_CORPUS_DIR") or os.path.join(
    os.path.dirname(__file__), "..", "..", "..", "shared", "nc-corpus"), "heidenhain")


def _external(fname: str) -> str:
    path = os.path.join(DATA, fname)
    if not os.path.exists(path):
        pytest.skip(f"{fname} not present in {DATA} (see tests/nc/external_heidenhain.txt)")
    return path
S2 = math.sqrt(2.0)
NAN = math.nan


def tnc(*blocks: str, unit: str = "MM") -> str:
    lines = [f"BEGIN PGM T {unit}", *blocks, f"END PGM T {unit}"]
    return "\n".join(f"{i} {b}" for i, b in enumerate(lines)) + "\n"


# (id, blocks, expected rows); a row: dict with motion m, end xyz, feed f, and
# optionally arc (centre xyz, sweep deg, plane), tcp, tv (tool vector), rot (A B C deg)
KNOWN = [
    ("line", ["L X+10 Y+20 Z+5 R0 F500"],
     [dict(m=1, xyz=(10, 20, 5), f=500)]),
    ("incremental", ["L X+10 Y+10 Z+0 R0 FMAX", "L IX+5 IY-2 F200"],
     [dict(m=0, xyz=(10, 10, 0), f=NAN), dict(m=1, xyz=(15, 8, 0), f=200)]),
    # FMAX is rapid for its own block only: the third block cuts at F300 again
    ("fmax-not-modal", ["L X+1 R0 F300", "L X+2 FMAX", "L X+3"],
     [dict(m=1, xyz=(1, 0, 0), f=300), dict(m=0, xyz=(2, 0, 0), f=300),
      dict(m=1, xyz=(3, 0, 0), f=300)]),
    # quarter circle counter-clockwise about the origin: +90 deg, G3
    ("c-ccw", ["L X+10 Y+0 R0 F100", "CC X+0 Y+0", "C X+0 Y+10 DR+"],
     [dict(m=1, xyz=(10, 0, 0), f=100),
      dict(m=3, xyz=(0, 10, 0), f=100, arc=((0, 0, 0), 90, 17))]),
    # same end clockwise: the long way, -270 deg, G2
    ("c-cw", ["L X+10 Y+0 R0 F100", "CC X+0 Y+0", "C X+0 Y+10 DR-"],
     [dict(m=1, xyz=(10, 0, 0), f=100),
      dict(m=2, xyz=(0, 10, 0), f=100, arc=((0, 0, 0), -270, 17))]),
    # end = start: a full circle
    ("c-full", ["L X+10 Y+0 R0 F100", "CC X+0 Y+0", "C X+10 Y+0 DR-"],
     [dict(m=1, xyz=(10, 0, 0), f=100),
      dict(m=2, xyz=(10, 0, 0), f=100, arc=((0, 0, 0), -360, 17))]),
    # chord 10 = 2R: half circle about (5, 0), counter-clockwise from 180 to 360 deg
    ("cr-half", ["L X+0 Y+0 R0 F100", "CR X+10 Y+0 R+5 DR+"],
     [dict(m=1, xyz=(0, 0, 0), f=100),
      dict(m=3, xyz=(10, 0, 0), f=100, arc=((5, 0, 0), 180, 17))]),
    # R<0: the arc longer than 180 deg. Centre (0, 10): start at -90 deg, end at 0 deg,
    # clockwise -> -270 deg
    ("cr-long", ["L X+0 Y+0 R0 F100", "CR X+10 Y+10 R-10 DR-"],
     [dict(m=1, xyz=(0, 0, 0), f=100),
      dict(m=2, xyz=(10, 10, 0), f=100, arc=((0, 10, 0), -270, 17))]),
    # tangent +X at (10, 0), through (20, 10): centre (10, 10), +90 deg
    ("ct", ["L X+0 Y+0 R0 F100", "L X+10", "CT X+20 Y+10"],
     [dict(m=1, xyz=(0, 0, 0), f=100), dict(m=1, xyz=(10, 0, 0), f=100),
      dict(m=3, xyz=(20, 10, 0), f=100, arc=((10, 10, 0), 90, 17))]),
    # polar: radius 10 at 30 deg, then +60 deg more: (0, 10)
    ("lp", ["CC X+0 Y+0", "LP PR+10 PA+30 R0 F100", "LP IPA+60"],
     [dict(m=1, xyz=(10 * math.cos(math.pi / 6), 5, 0), f=100),
      dict(m=1, xyz=(0, 10, 0), f=100)]),
    # helix: two turns counter-clockwise rising 2 mm, back over the start
    ("cp-helix", ["L X+10 Y+0 Z+0 R0 F100", "CC X+0 Y+0", "CP IPA+720 IZ+2 DR+"],
     [dict(m=1, xyz=(10, 0, 0), f=100),
      dict(m=3, xyz=(10, 0, 2), f=100, arc=((0, 0, 0), 720, 17))]),
    # CC in Y Z (as CAM writes for lead-ins): the arc is in the YZ plane (G19);
    # start 5.165 below the centre in Y (angle 180 deg), 90 deg clockwise -> angle 90 deg
    ("cp-yz", ["L X+5 Y-20 Z+2.5 R0 F100", "CC Y-14.835 Z+2.5", "CP IPA-90 DR- F555"],
     [dict(m=1, xyz=(5, -20, 2.5), f=100),
      dict(m=2, xyz=(5, -14.835, 7.665), f=555, arc=((5, -14.835, 2.5), -90, 19))]),
    ("tool-call", ["TOOL CALL 5 Z S4000", "M3", "L X+1 R0 F100"],
     [dict(m=1, xyz=(1, 0, 0), f=100, tool=5, rpm=4000, sp=1)]),
    # M5 acts at the end of its block: that block still runs with the spindle on
    ("m5-at-end", ["TOOL CALL 5 Z S4000", "L X+1 R0 F100 M3", "L X+2 M5", "L X+3"],
     [dict(m=1, xyz=(1, 0, 0), f=100, sp=1), dict(m=1, xyz=(2, 0, 0), f=100, sp=1),
      dict(m=1, xyz=(3, 0, 0), f=100, sp=0)]),
    ("tcpm-angles", ["FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS",
                     "L X+10 Y+20 Z+5 B+30 C+45 R0 F1000"],
     [dict(m=1, xyz=(10, 20, 5), f=1000, tcp=TCP_ANGLES, rot=(0, 30, 45))]),
    ("m128-ln", ["M128", "LN X+1 Y+2 Z+3 NX+0 NY+0 NZ+1 TX+0 TY+0.6 TZ+0.8 F500", "L X+2",
                 "M129", "L X+3"],
     [dict(m=1, xyz=(1, 2, 3), f=500, tcp=TCP_VECTOR, tv=(0, 0.6, 0.8)),
      dict(m=1, xyz=(2, 2, 3), f=500, tcp=TCP_VECTOR, tv=(0, 0.6, 0.8)),
      dict(m=1, xyz=(3, 2, 3), f=500, tcp=TCP_OFF)]),
    # datum shift X+100 Y+50: program (1, 2, 3) is workpiece (101, 52, 3)
    ("datum-shift", ["CYCL DEF 7.0 DATUM SHIFT", "CYCL DEF 7.1 X+100", "CYCL DEF 7.2 Y+50",
                     "L X+1 Y+2 Z+3 R0 F100"],
     [dict(m=1, xyz=(101, 52, 3), f=100)]),
    # SPB+90 turns Z toward X: tilted X (1,0,0) -> (0,0,-1), tool axis -> (1,0,0)
    ("plane-spatial", ["PLANE SPATIAL SPA+0 SPB+90 SPC+0 STAY", "L X+10 Y+0 Z+0 R0 F100",
                       "PLANE RESET STAY", "L X+1 Y+0 Z+0"],
     [dict(m=1, xyz=(0, 0, -10), f=100, tcp=TCP_VECTOR, tv=(1, 0, 0)),
      dict(m=1, xyz=(1, 0, 0), f=100, tcp=TCP_OFF)]),
    # cycle 19 A+90: tilted Y -> (0,0,1), tool axis Z -> (0,-1,0)
    ("cycle-19", ["CYCL DEF 19.0 WORKING PLANE", "CYCL DEF 19.1 A+90",
                  "L X+0 Y+10 Z+0 R0 F100"],
     [dict(m=1, xyz=(0, 0, 10), f=100, tcp=TCP_VECTOR, tv=(0, -1, 0))]),
    # a section repeat runs once and then REP more times
    ("lbl-rep", ["L X+0 Y+0 Z+0 R0 F100", "LBL 1", "L IX+1", "CALL LBL 1 REP 2"],
     [dict(m=1, xyz=(0, 0, 0), f=100), dict(m=1, xyz=(1, 0, 0), f=100),
      dict(m=1, xyz=(2, 0, 0), f=100), dict(m=1, xyz=(3, 0, 0), f=100)]),
    ("subprogram", ["L X+1 R0 F100", "CALL LBL 5", "L X+3", "M30", "LBL 5", "L Y+2", "LBL 0"],
     [dict(m=1, xyz=(1, 0, 0), f=100), dict(m=1, xyz=(1, 2, 0), f=100),
      dict(m=1, xyz=(3, 2, 0), f=100)]),
    # Q1 = 5, Q2 = 11, Q3 = -4 -> X 5, Y 11, Z -(-4) = 4, feed Q2 = 11
    ("q-params", ["Q1 = 5", "Q2 = Q1 * 2 + 1", "FN 0: Q3 = -4", "L X+Q1 Y+Q2 Z-Q3 R0 FQ2"],
     [dict(m=1, xyz=(5, 11, 4), f=11)]),
    ("fauto", ["TOOL CALL 1 Z S1000 F800", "L X+5 R0 F200", "L X+6 FAUTO"],
     [dict(m=1, xyz=(5, 0, 0), f=200), dict(m=1, xyz=(6, 0, 0), f=800)]),
    ("comma-decimal", ["L X+1,5 Y-0,25 R0 F100"],
     [dict(m=1, xyz=(1.5, -0.25, 0), f=100)]),
    # M126 (after C reached 350): shortest way from 350 deg to 10 deg is +20 -> 370 deg
    ("m126", ["L C+350 R0 F100", "M126", "L C+10"],
     [dict(m=1, xyz=(0, 0, 0), f=100, rot=(0, 0, 350)),
      dict(m=1, xyz=(0, 0, 0), f=100, rot=(0, 0, 370))]),
    # M140 MB 50: 50 mm up the tool axis, rapid
    ("m140-mb", ["L X+1 Y+1 Z+2 R0 F100", "L M140 MB+50"],
     [dict(m=1, xyz=(1, 1, 2), f=100), dict(m=0, xyz=(1, 1, 52), f=100)]),
    # CT after an arc: the arc ends at (10, 10) going +Y; the tangential arc to
    # (0, 20) continues the same circle about (0, 10): another +90 deg
    ("ct-after-arc", ["L X+0 Y+0 R0 F100", "CC X+0 Y+10", "C X+10 Y+10 DR+", "CT X+0 Y+20"],
     [dict(m=1, xyz=(0, 0, 0), f=100),
      dict(m=3, xyz=(10, 10, 0), f=100, arc=((0, 10, 0), 90, 17)),
      dict(m=3, xyz=(0, 20, 0), f=100, arc=((0, 10, 0), 90, 17))]),
    # 7.1 IX+5 adds to the active shift (100): program X1 -> 106
    ("datum-incremental", ["CYCL DEF 7.0 DATUM SHIFT", "CYCL DEF 7.1 X+100",
                           "CYCL DEF 7.0 DATUM SHIFT", "CYCL DEF 7.1 IX+5",
                           "L X+1 Y+0 Z+0 R0 F100"],
     [dict(m=1, xyz=(106, 0, 0), f=100)]),
    # shift, then tilt about the shifted datum: SPC+90 turns (10, 0, 0) to (0, 10, 0)
    ("plane-after-shift", ["CYCL DEF 7.0 DATUM SHIFT", "CYCL DEF 7.1 X+100",
                           "PLANE SPATIAL SPA+0 SPB+0 SPC+90 TURN MB MAX FMAX SEQ- TABLE ROT",
                           "L X+10 Y+0 Z+0 R0 F100"],
     [dict(m=1, xyz=(100, 10, 0), f=100, tcp=TCP_VECTOR, tv=(0, 0, 1))]),
    # PLANE RESET TURN puts the rotary axes back to zero: an untilted 3-axis move
    ("plane-turn-reset", ["PLANE SPATIAL SPA+0 SPB+30 SPC+0 TURN FMAX", "L X+1 R0 F100",
                          "PLANE RESET TURN FMAX", "L X+2"],
     [dict(m=1, xyz=(math.cos(math.pi / 6), 0, -0.5), f=100, tcp=TCP_VECTOR,
           tv=(0.5, 0, math.cos(math.pi / 6))),
      dict(m=1, xyz=(2, 0, -0.5), f=100, tcp=TCP_OFF, rot=(0, 0, 0))]),
    ("lbl-name-rep-slash", ["L X+0 R0 F100", 'LBL "EDGE"', "L IX+2", 'CALL LBL "EDGE" REP 1/1'],
     [dict(m=1, xyz=(0, 0, 0), f=100), dict(m=1, xyz=(2, 0, 0), f=100),
      dict(m=1, xyz=(4, 0, 0), f=100)]),
    # tool axis Y: working plane ZX (G18), tool vector +Y
    ("tool-axis-y", ["TOOL CALL 1 Y S1000", "L X+1 R0 F100"],
     [dict(m=1, xyz=(1, 0, 0), f=100, tcp=TCP_VECTOR, tv=(0, 1, 0))]),
]


BY_NAME = {k[0]: k for k in KNOWN}


def _check_rows(prog, rows):
    assert len(prog) == len(rows)
    for b, r in zip(prog, rows):
        assert b.motion == r["m"]
        np.testing.assert_allclose(b.end[:3], r["xyz"], atol=1e-9)
        if math.isnan(r["f"]):
            assert math.isnan(b.feed)
        else:
            assert b.feed == pytest.approx(r["f"])
        if "arc" in r:
            centre, sweep, plane = r["arc"]
            np.testing.assert_allclose(b.arc.centre, centre, atol=1e-9)
            assert math.degrees(b.arc.sweep_rad) == pytest.approx(sweep)
            assert b.arc.plane == plane
        else:
            assert b.arc is None
        if "tcp" in r:
            assert b.modal.tcp == r["tcp"]
        if "tv" in r:
            np.testing.assert_allclose(b.tool_vector, r["tv"], atol=1e-12)
        if "rot" in r:
            np.testing.assert_allclose(np.degrees(b.end[3:]), r["rot"], atol=1e-9)
        if "tool" in r:
            assert b.modal.tool == r["tool"]
        if "rpm" in r:
            assert b.modal.spindle_rpm == r["rpm"]
        if "sp" in r:
            assert b.modal.spindle_dir == r["sp"]


@pytest.mark.parametrize("name,blocks,rows", KNOWN, ids=[k[0] for k in KNOWN])
def test_known_pairs_read(name, blocks, rows):
    _check_rows(parse_heidenhain(tnc(*blocks)), rows)


def test_inch_program_scales_coordinates_and_tenth_inch_feed():
    prog = parse_heidenhain(tnc("L X+1 Y+2 R0 F100", unit="INCH"))
    np.testing.assert_allclose(prog.end[0, :3], (25.4, 50.8, 0))
    assert prog.feed[0] == pytest.approx(254.0)  # F in 1/10 inch/min
    assert prog.modals[0].units == 20


def test_metadata_and_name():
    prog = parse_heidenhain("0 BEGIN PGM side-slots MM\n1 BLK FORM 0.1 Z X+0 Y-40 Z-100\n"
                            "2 BLK FORM 0.2 X+80 Y+0 Z+0\n3 * - a section\n"
                            "4 L X+1 R0 F10 ; comment\n5 END PGM side-slots MM\n")
    assert prog.number == "side-slots"
    assert prog.metadata["blk_form"] == ["BLK FORM 0.1 Z X+0 Y-40 Z-100",
                                         "BLK FORM 0.2 X+80 Y+0 Z+0"]
    assert prog.line.tolist() == [5]


def test_tilted_arc_is_chords_on_the_tilted_circle():
    prog = parse_heidenhain(tnc("PLANE SPATIAL SPA+0 SPB+90 SPC+0 STAY",
                                "L X+10 Y+0 Z+0 R0 F100", "CC X+0 Y+0", "C X+0 Y+10 DR+"))
    arc_rows = prog.end[1:, :3]
    assert len(arc_rows) > 10 and np.all(prog.arc_index == -1)
    # tilted XY plane is the workpiece's Y(-Z) plane: every chord end 10 from the origin
    np.testing.assert_allclose(np.linalg.norm(arc_rows, axis=1), 10, atol=1e-9)
    np.testing.assert_allclose(arc_rows[:, 0], 0, atol=1e-9)
    np.testing.assert_allclose(arc_rows[-1], (0, 10, 0), atol=1e-9)


def test_program_goes_to_cutter_locations():
    prog = parse_heidenhain(tnc(*BY_NAME["c-ccw"][1]))
    cl = cutter_locations(prog)
    assert np.allclose(np.linalg.norm(cl.tip[1:, :2], axis=1), 10)


# --------------------------------------------------------------------------- writer
GEOMETRY = {
    "xyzac-trt": dict(tilt_pivot_mm=(0.0, 20.0, -35.0), rotary_pivot_mm=(5.0, -3.0, 0.0)),
    "xyzbc-trt": dict(tilt_pivot_mm=(-15.0, 0.0, -40.0), rotary_pivot_mm=(2.0, 4.0, 0.0)),
    "xyzbc-head-table": dict(tool_length_mm=80.0, tilt_pivot_mm=(0.0, 0.0, 150.0),
                             rotary_pivot_mm=(10.0, -5.0, 0.0)),
    "xyzbc-head-head": dict(tool_length_mm=80.0, tilt_pivot_mm=(0.0, 0.0, 120.0),
                            rotary_pivot_mm=(3.0, 0.0, 200.0)),
}


def test_known_pairs_write_ln():
    # the m128-ln pair written back: the same LN words, read back to the same row
    cl = CutterLocations.from_arrays([[1.0, 2.0, 3.0]], [[0.0, 0.6, 0.8]], 500.0, 1000.0)
    res = post_heidenhain(cl, get_machine("xyzbc-trt"), TNCPostOptions(form="ln-vector"))
    assert ("LN X+1.0000 Y+2.0000 Z+3.0000 NX+0.0000000 NY+0.6000000 NZ+0.8000000 "
            "TX+0.0000000 TY+0.6000000 TZ+0.8000000 F500") in res.text
    prog = parse_heidenhain(res.text)
    _check_rows(_Rows(prog, 1, 2), BY_NAME["m128-ln"][2][:1])


def test_known_pairs_write_angles():
    # the tcpm-angles pair: tip and the axis of B30 C45 on a machine; written and read
    m = get_machine("xyzbc-trt")
    _, axis = m.forward(np.array([[10.0, 20.0, 5.0, math.radians(30), math.radians(45)]]))
    cl = CutterLocations.from_arrays([[10.0, 20.0, 5.0]], axis, 1000.0, 1000.0)
    res = post_heidenhain(cl, m, TNCPostOptions(form="tcpm-angles"))
    line = [ln for ln in res.text.splitlines() if "F1000" in ln][0]
    b, c = (float(v) for v in re.findall(r"[BC]([+-][\d.]+)", line))
    # B30 C45 or the other solution B-30 C225: both give the pair's tool axis
    assert (b, c) in ((30.0, 45.0), (-30.0, 225.0), (-30.0, -135.0))
    prog = parse_heidenhain(res.text)
    row = prog[1]
    np.testing.assert_allclose(row.end[:3], (10, 20, 5))
    assert row.modal.tcp == TCP_ANGLES


class _Rows:
    """Rows lo..hi of a program, as a sequence of blocks (for _check_rows)."""

    def __init__(self, prog, lo, hi):
        self.p, self.lo, self.hi = prog, lo, hi

    def __len__(self):
        return self.hi - self.lo

    def __iter__(self):
        return (self.p[i] for i in range(self.lo, self.hi))


@pytest.mark.parametrize("form", TNC_FORMS)
@pytest.mark.parametrize("name", list(MACHINES))
def test_writer_round_trip_blade(name, form, tmp_path):
    from nc.path import read_cl_csv

    blade = read_cl_csv(os.path.join(os.path.dirname(__file__), "..", "..", "nc", "data",
                                     "blade_cl.csv")).take(slice(0, 200))
    m = get_machine(name, **GEOMETRY[name])
    out = tmp_path / "p.h"
    res = write_heidenhain(out, blade, m, TNCPostOptions(form=form, program_name="BLADE"))
    assert out.read_text() == res.text
    e_tip, e_ang = heidenhain_round_trip(res, m, form)
    assert e_tip <= 1e-3 and e_ang <= 1e-4
    prog = read_any(out)  # detected as Heidenhain
    cl = cutter_locations(prog, m)
    cut = np.flatnonzero(~cl.rapid)  # approach and retract are FMAX
    assert len(cut) == len(blade)
    np.testing.assert_allclose(cl.tip[cut], blade.tip, atol=1e-3)
    ang = np.degrees(np.arccos(np.clip(np.sum(cl.axis[cut] * blade.axis, 1), -1, 1)))
    assert ang.max() < 1e-3  # tool axis through the machine's forward kinematics


@settings(max_examples=25)
@given(data=st.data())
def test_writer_round_trip_random_paths(data):
    name = data.draw(st.sampled_from(sorted(MACHINES)))
    form = data.draw(st.sampled_from(TNC_FORMS))
    m = get_machine(name, **GEOMETRY[name])
    n = data.draw(st.integers(2, 25))
    seed = data.draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    lo, hi = m.axes[0].min_rad, m.axes[0].max_rad
    tilt = rng.uniform(math.radians(2), min(hi, math.radians(85)), n)
    tilt *= rng.choice([-1.0, 1.0], n) if lo < 0 else 1.0
    joints = np.column_stack([rng.uniform(-100, 100, (n, 3)), tilt,
                              rng.uniform(-math.pi, math.pi, n)])
    _, axis = m.forward(joints)
    tip = rng.uniform(-100, 100, (n, 3))
    cl = CutterLocations.from_arrays(tip, axis, rng.uniform(10, 5000, n), 8000.0)
    res = post_heidenhain(cl, m, TNCPostOptions(form=form))
    e_tip, e_ang = heidenhain_round_trip(res, m, form)
    assert e_tip <= 1e-3 and e_ang <= 1e-4


def test_write_refuses_values_a_tnc_cannot_take():
    cl = CutterLocations.from_arrays([[1e5, 0, 0], [2, 0, 0]], [0, 0, 1], 100.0)
    with pytest.raises(InputError, match="beyond what a TNC accepts"):
        post_heidenhain(cl, get_machine("xyzbc-trt"))


def test_write_refuses_when_read_back_differs(tmp_path):
    cl = CutterLocations.from_arrays([[1.23456, 0, 0], [2, 0, 0]], [0, 0, 1], 100.0)
    with pytest.raises(InputError, match="not written"):
        write_heidenhain(tmp_path / "p.h", cl, get_machine("xyzbc-trt"),
                         TNCPostOptions(linear_decimals=2))
    assert not (tmp_path / "p.h").exists()


# --------------------------------------------------------------------------- real programs
@pytest.mark.parametrize("fname,line,what", [
    ("CIRSTUD.h", 6, "unsupported M91"),
    ("CUT.h", 52, "END PGM RECTIFI MM does not match BEGIN PGM CUT MM"),
    ("0D.h", 11, "END PGM 0 MM does not match BEGIN PGM 0D MM"),
])
def test_real_programs_refused_in_one_line(fname, line, what):
    path = _external(fname)
    assert detect_dialect(open(path, encoding="latin-1").read()) == "heidenhain"
    with pytest.raises(NCParseError) as exc:
        read_any(path)
    first = str(exc.value).splitlines()[0]
    assert first.startswith(f"{path}:{line}:") and what in first


def test_real_program_body_reads_once_the_machine_reads_are_gone(tmp_path):
    # CIRSTUD.h without its SYSREAD/M91 lines and the jumps that use them, and with
    # the start the operator jogs to by hand programmed: the stud circle
    # itself (CC, C DR+ full circles, LBL repeat) is read
    src = open(_external("CIRSTUD.h")).read().splitlines()
    keep = [ln.replace(" M91", "") for ln in src
            if not ln.startswith(("FN18", "FN12", "Q4 =", "Q5 =", "Q3 =", "Q6 ="))
            and "Q2" not in ln]
    keep.insert(keep.index("STOP") + 1, "L X-20 Y-10 R0 FMAX")
    prog = parse_heidenhain("\n".join(keep) + "\n", file="cirstud")
    arcs = prog.arc_index >= 0
    assert arcs.sum() == 26  # LBL 1 once + REP 25
    np.testing.assert_allclose(np.degrees(prog.arc_sweep), 360.0)
    np.testing.assert_allclose(prog.arc_radius, 20.0)  # about CC X+0 Y+0 from X-20 Y+0
    z = prog.end[arcs, 2]
    np.testing.assert_allclose(np.diff(z), -2.5)  # L IZ-2.5 each pass


# --------------------------------------------------------------------------- bad input
BAD = [
    (["L X+1 RL F100"], "radius compensation RL"),
    (["FN 18: SYSREAD Q1 = ID270 NR1"], "FN 18 is not supported"),
    (["L X+Q7 F100"], "Q7 is used before it is set"),
    (["CALL LBL 9"], "no LBL 9"),
    (["L X+1"], "cutting move with no feed"),
    (["C X+1 Y+0 DR+ F100"], "no circle centre"),
    (["CC X+0 Y+0", "L X+5 R0 F10", "C X+0 Y+6 DR+"], "radius"),
    (["CT X+1 Y+1 F100"], "CT needs a contour element"),
    (["CC X+0 Y+0", "L X+5 R0 F10", "CP IPA-90 DR+"], "IPA and DR disagree"),
    (["L M140 MB MAX"], "retract_limit_mm"),
    (["PLANE SPATIAL SPA+0 SPB+10 SPC+0 STAY", "M128"], "tilted plane"),
    (["APPR LT X+1 Y+1 LEN10 RR F300"], "APPR"),
    (["CYCL DEF 200 DRILLING"], "cycle 200 is not read"),
    (["TOOL CALL 1 Z S1000 DL+0.1"], "delta length"),
    (["L X+1 F100 M91"], "unsupported M91"),
    (["PLANE VECTOR BX+1 BY+0 BZ+0 NX+0 NY+0 NZ+1 STAY"], "PLANE VECTOR is not supported"),
    (["L X+1 Y+2 X+3 F100"], "appears twice"),
    (["PLANE SPATIAL SPA+0 SPB+30 SPC+0 TURN MB MAX FMAX", "PLANE RESET STAY",
      "L X+1 R0 F100"], "PLANE ... TURN|MOVE put them"),
    (["L X+1 F100 FU"], "FU"),
    (["Q1 = 2 $ 3"], "formula"),
    (["LBL 1", "L IX+1 F10", "CALL LBL 1"], "nested deeper"),
]


@pytest.mark.parametrize("blocks,what", BAD, ids=[b[1] for b in BAD])
def test_bad_input_one_error(blocks, what):
    with pytest.raises(NCParseError) as exc:
        parse_heidenhain(tnc(*blocks), file="p.h")
    first = str(exc.value).splitlines()[0]
    assert re.match(r"p\.h:\d+(:\d+)?: ", first), first
    assert what in first


def test_allow_list():
    prog = parse_heidenhain(tnc("L X+1 R0 F100 M110"), allow=["M110"])
    assert len(prog) == 1
    with pytest.raises(NCParseError, match="unsupported M110"):
        parse_heidenhain(tnc("L X+1 R0 F100 M110"))
    with pytest.raises(ValueError, match="M91 is a move in machine coordinates"):
        parse_heidenhain(tnc("L X+1 R0 F100"), allow=["M91"])


def test_missing_end_and_begin():
    with pytest.raises(NCParseError, match="expected 'END PGM T MM'"):
        parse_heidenhain("0 BEGIN PGM T MM\n1 L X+1 R0 F10\n")
    with pytest.raises(NCParseError, match="BEGIN PGM"):
        parse_heidenhain("G1 X1 F10\n")


def test_endless_repeat_hits_the_limit(monkeypatch):
    monkeypatch.setattr(K, "TNC_MAX_EXECUTED_BLOCKS", 1000)
    with pytest.raises(NCParseError, match="TNC_MAX_EXECUTED_BLOCKS"):
        parse_heidenhain(tnc("LBL 1", "LBL 2", "L IX+1 R0 F10", "CALL LBL 2 REP 99",
                             "CALL LBL 1 REP 99"))


def test_fuzz_never_crashes():
    rng = random.Random(1234)
    base = tnc(*BY_NAME["c-ccw"][1], *BY_NAME["lbl-rep"][1], "Q1 = 3", "L X+Q1 FMAX",
               "FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS", "L X+1 B+10 C+5 F10",
               "FUNCTION RESET TCPM", "PLANE SPATIAL SPA+0 SPB+30 SPC+0 STAY",
               "CC X+1 Y+1", "CP IPA+30 DR+", "PLANE RESET STAY", "M30")
    alphabet = "LCRTPXYZABIFMNQ+-.,0123456789 =*/()~;\"'\n"
    ok = bad = 0
    for _ in range(1500):
        s = list(base)
        for _ in range(rng.randint(1, 4)):
            k = rng.randrange(len(s))
            op = rng.random()
            if op < 0.4:
                del s[k]
            elif op < 0.8:
                s.insert(k, rng.choice(alphabet))
            else:
                s[k] = rng.choice(alphabet)
        try:
            parse_heidenhain("".join(s), file="f.h")
            ok += 1
        except NCParseError as exc:
            assert re.match(r"f\.h(:\d+(:\d+)?)?: \S", str(exc)), str(exc)
            bad += 1
    assert ok > 50 and bad > 50


def test_detect_and_dispatch(tmp_path):
    h = tmp_path / "a.h"
    h.write_text(tnc("L X+1 R0 F10"))
    g = tmp_path / "a.ngc"
    g.write_text("G1 X1 F10\nM2\n")
    assert detect_dialect(h.read_text()) == "heidenhain"
    assert detect_dialect(g.read_text()) == "gcode"
    assert read_any(h).metadata["dialect"] == "heidenhain"
    assert read_any(g).end[0, 0] == 1.0
    with pytest.raises(NCParseError):
        read_any(h, dialect="gcode")  # forced: the G-code reader refuses it
    assert read_heidenhain(h).number == "T"


def test_cli_parse_dialect(tmp_path, capsys):
    from nc.cli import main

    h = tmp_path / "a.h"
    h.write_text(tnc("L M140 MB MAX", "L X+1 R0 F10"))
    assert main(["parse", str(h), "--json"]) == 2
    assert "retract-limit" in capsys.readouterr().err
    assert main(["parse", str(h), "--json", "--retract-limit", "50"]) == 0
    assert '"line":' in capsys.readouterr().out


def test_cli_post_heidenhain(tmp_path, capsys):
    from nc.cli import main

    blade = os.path.join(os.path.dirname(__file__), "..", "..", "nc", "data", "blade_cl.csv")
    for dialect, verb in (("heidenhain-tcpm", "L "), ("heidenhain-ln", "LN ")):
        out = tmp_path / f"p-{dialect}.h"
        assert main(["post", blade, "--machine", "xyzbc-trt", "--dialect", dialect,
                     "-o", str(out)]) == 0
        text = out.read_text()
        assert text.startswith(f"0 BEGIN PGM p-{dialect} MM") and f" {verb}X" in text
        assert len(read_any(out)) > 100


def test_rewrite_refuses_klartext():
    from nc.rewrite import RewriteError, rewrite_coordinates

    prog = parse_heidenhain(tnc("L X+1 R0 F100"), file="p.h")
    with pytest.raises(RewriteError, match="Heidenhain"):
        rewrite_coordinates(prog, {0: np.array([2.0, 0.0, 0.0])})


def test_cam_style_program():
    # the shape CAM posts write for a TNC 640 (written here, not copied): tool axis
    # first, retract, structure lines, feeds in Q parameters, a lead-in arc in the
    # YZ plane, cycle 32, retract at the end
    text = """0  BEGIN PGM slot MM
1  BLK FORM 0.1 Z  X+0  Y-25  Z-35
2  BLK FORM 0.2  X+220  Y+0  Z+0
3  ;-------------------------------------
4  ;  #3 D=10 - flat end mill
5  * - Slot1 (3)
6  TOOL CALL 3 Z S4043
7  L M140 MB MAX
8  M3
9  L  X+10  Y-12.5 R0 FMAX
10 L  Z+85 R0 FMAX
11 M8
12 CYCL DEF 32.0 TOLERANCE
13 CYCL DEF 32.1
14 FN 0: Q50 =+550 ; Cutting
15 FN 0: Q53 =+300 ; Entry
16 L  Z+5 FMAX
17 L  Z+1 FQ53
18 CC  Y-11.5  Z+1
19 CP IPA+90 DR+ FQ50
20 L  X+40
21 L  Z+85 FMAX
22 M9
23 M5
24 L M140 MB MAX
25 M30
26 END PGM slot MM
"""
    prog = parse_heidenhain(text, file="slot.h", retract_limit_mm=200.0)
    z = prog.end[:, 2]
    assert prog.number == "slot" and len(prog) == 9
    np.testing.assert_allclose(z[[0, 2, 3, 4]], [200, 85, 5, 1])
    # CP: from Y-12.5 (angle 180 deg about Y-11.5 Z+1 in Y-Z) +90 deg -> Y-11.5 Z+0
    np.testing.assert_allclose(prog.end[5, :3], (10, -11.5, 0), atol=1e-12)
    assert prog.arc_plane.tolist() == [19] and prog.feed[5] == 550 and prog.feed[4] == 300
    np.testing.assert_allclose(prog.end[-1, :3], (40, -11.5, 200))
    assert prog.modal_column("spindle_dir").tolist() == [0, 1, 1, 1, 1, 1, 1, 1, 0]
    cl = cutter_locations(prog)
    assert np.all(cl.feed_mm_min[~cl.rapid] > 0)
