"""Siemens Sinumerik 840D: reader, writer, round trips, bad input.

The table KNOWN holds hand-checked pairs (blocks -> moves): each expected
value is worked out in the comment beside it from the 840D's rules (IJK
incremental from the start, CR sign, CYCLE800 axis order), not from running
the reader. The same pairs are written by the writer and read back.
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

from nc.dialects import detect_dialect, read_any
from nc.errors import InputError, NCParseError
from nc.kinematics import MACHINES, get_machine
from nc.path import CutterLocations, cutter_locations
from nc.program import TCP_ANGLES, TCP_OFF, TCP_VECTOR
from nc.siemens import parse_siemens, read_siemens
from nc.siemens_writer import (SIEMENS_FORMS, SiemensPostOptions, post_siemens,
                               siemens_round_trip, write_siemens)

NAN = math.nan
BLADE = os.path.join(os.path.dirname(__file__), "..", "..", "nc", "data", "blade_cl.csv")


def sin840(*blocks: str) -> str:
    lines = ["%_N_T_MPF", ";$PATH=/_N_MPF_DIR", *(f"N{10 * (i + 1)} {b}"
                                                  for i, b in enumerate(blocks)), "M30"]
    return "\n".join(lines) + "\n"


def c800(mode: int, a: float, b: float, c: float, x0=(0, 0, 0), x1=(0, 0, 0), st_=0) -> str:
    p = [1, '"TC1"', st_, mode, *x0, a, b, c, *x1, -1, 100, 1]
    return "CYCLE800(" + ",".join(str(v) for v in p) + ")"


# (id, blocks, expected rows); a row: dict with motion m, end xyz, feed f, and
# optionally arc (centre xyz, sweep deg, plane), tcp, tv (tool vector), rot (A B C deg)
KNOWN = [
    ("line", ["G1 X10 Y20 Z5 F500"], [dict(m=1, xyz=(10, 20, 5), f=500)]),
    ("incremental", ["G0 X10 Y10 Z0", "G91 G1 X5 Y-2 F200"],
     [dict(m=0, xyz=(10, 10, 0), f=NAN), dict(m=1, xyz=(15, 8, 0), f=200)]),
    # IC(5) adds to X10 under G90; AC(-2) is absolute under G91, X=1 adds
    ("ac-ic", ["G90 G1 X10 F100", "X=IC(5) Y=AC(3)", "G91 Z=AC(-2) X=1"],
     [dict(m=1, xyz=(10, 0, 0), f=100), dict(m=1, xyz=(15, 3, 0), f=100),
      dict(m=1, xyz=(16, 3, -2), f=100)]),
    # I J are from the start even under G90: centre (10-10, 0) = origin; G3 0 -> 90 deg
    ("g3-ijk", ["G1 X10 Y0 F100", "G3 X0 Y10 I-10 J0"],
     [dict(m=1, xyz=(10, 0, 0), f=100),
      dict(m=3, xyz=(0, 10, 0), f=100, arc=((0, 0, 0), 90, 17))]),
    # I=AC(0) J=AC(0): the centre is the origin; clockwise 0 -> 90 deg the long way
    ("g2-ac-centre", ["G1 X10 Y0 F100", "G2 X0 Y10 I=AC(0) J=AC(0)"],
     [dict(m=1, xyz=(10, 0, 0), f=100),
      dict(m=2, xyz=(0, 10, 0), f=100, arc=((0, 0, 0), -270, 17))]),
    # chord 10 = 2 CR: half circle about (5, 0), counter-clockwise 180 -> 360 deg
    ("cr-half", ["G1 X0 Y0 F100", "G3 X10 Y0 CR=5"],
     [dict(m=1, xyz=(0, 0, 0), f=100),
      dict(m=3, xyz=(10, 0, 0), f=100, arc=((5, 0, 0), 180, 17))]),
    # CR<0: more than 180 deg; centre (0, 10): start -90 deg, end 0 deg, clockwise -270
    ("cr-long", ["G1 X0 Y0 F100", "G2 X10 Y10 CR=-10"],
     [dict(m=1, xyz=(0, 0, 0), f=100),
      dict(m=2, xyz=(10, 10, 0), f=100, arc=((0, 10, 0), -270, 17))]),
    # end = start: a full circle, TURN=1 one more: 720 deg rising 2 mm
    ("helix-turn", ["G1 X10 Y0 Z0 F100", "G3 X10 Y0 Z2 I-10 J0 TURN=1"],
     [dict(m=1, xyz=(10, 0, 0), f=100),
      dict(m=3, xyz=(10, 0, 2), f=100, arc=((0, 0, 0), 720, 17))]),
    # G18: axes (Z, X), K I the centre from the start: (0, 0). Start X10 is at 90 deg
    # from Z in the Z-X plane, end Z10 at 0 deg; G3 (about +Y) 90 -> 360: +270 deg
    ("g18-arc", ["G18 G1 X10 Y0 Z0 F100", "G3 X0 Z10 I-10 K0"],
     [dict(m=1, xyz=(10, 0, 0), f=100),
      dict(m=3, xyz=(0, 0, 10), f=100, arc=((0, 0, 0), 270, 18))]),
    # R2 = 5 * 2 + 1 = 11; Z = -DEPTH = 4; F = R2 = 11
    ("r-params", ["DEF REAL DEPTH=-4", "R1=5 R2=R1*2+1", "G1 X=R1 Y=R2 Z=-DEPTH F=R2"],
     [dict(m=1, xyz=(5, 11, 4), f=11)]),
    # 10 cos 60 = 5; ATAN2(1,1) = 45 deg; TRUNC(-2.7) = -2, ROUND(2.5) = 3 -> Z 1
    ("functions", ["R1=ATAN2(1,1) R2=TRUNC(-2.7) R3=ROUND(2.5) R4=SQRT(POT(3)+POT(4))",
                   "G1 X=10*COS(60) Y=R1 Z=R2+R3 F=ABS(-20)*R4"],
     [dict(m=1, xyz=(5, 45, 1), f=100)]),
    # blanks inside an expression next to operators belong to it: 2*3+1, (2+1)
    ("expr-blanks", ["R1=2", "G1 X=R1 * 3 + 1 Y=(R1 + 1) F100"],
     [dict(m=1, xyz=(7, 3, 0), f=100)]),
    ("tool-spindle", ["T5", "M6", "S4000 M3", "G1 X1 F100"],
     [dict(m=1, xyz=(1, 0, 0), f=100, tool=5, rpm=4000, sp=1)]),
    # M5 acts at the end of its block: that block still runs with the spindle on
    ("m5-at-end", ["S4000 M3", "G1 X1 F100", "X2 M5", "X3"],
     [dict(m=1, xyz=(1, 0, 0), f=100, sp=1), dict(m=1, xyz=(2, 0, 0), f=100, sp=1),
      dict(m=1, xyz=(3, 0, 0), f=100, sp=0)]),
    ("traori-vector", ["TRAORI", "G1 X1 Y2 Z3 A3=0 B3=0.6 C3=0.8 F500", "X2", "TRAFOOF",
                       "X3"],
     [dict(m=1, xyz=(1, 2, 3), f=500, tcp=TCP_VECTOR, tv=(0, 0.6, 0.8)),
      dict(m=1, xyz=(2, 2, 3), f=500, tcp=TCP_VECTOR, tv=(0, 0.6, 0.8)),
      dict(m=1, xyz=(3, 2, 3), f=500, tcp=TCP_OFF)]),
    # components not programmed are 0; the vector is normalised: (0, 2, 0) -> (0, 1, 0)
    ("traori-partial-vector", ["TRAORI", "G1 X1 Y0 Z0 B3=2 F100"],
     [dict(m=1, xyz=(1, 0, 0), f=100, tcp=TCP_VECTOR, tv=(0, 1, 0))]),
    # blanks around '=' are allowed: A3 = 0 and C3 =1 are the vector's words
    ("blanks-around-equals", ["TRAORI", "G1 X0 Y0 Z0 A3 = 0 B3= 0 C3 =1 F100", "Y = 2"],
     [dict(m=1, xyz=(0, 0, 0), f=100, tcp=TCP_VECTOR, tv=(0, 0, 1)),
      dict(m=1, xyz=(0, 2, 0), f=100, tcp=TCP_VECTOR, tv=(0, 0, 1))]),
    ("traori-rotary", ["TRAORI", "G1 X10 Y20 Z5 B30 C45 F1000"],
     [dict(m=1, xyz=(10, 20, 5), f=1000, tcp=TCP_ANGLES, rot=(0, 30, 45))]),
    # DC: shortest way from 350 deg to 10 deg is +20 -> 370
    ("rotary-dc", ["G1 C350 F100", "C=DC(10)"],
     [dict(m=1, xyz=(0, 0, 0), f=100, rot=(0, 0, 350)),
      dict(m=1, xyz=(0, 0, 0), f=100, rot=(0, 0, 370))]),
    # ACN: 10 -> 20 turning negative is -350 -> -340; ACP: -340 -> 0 turning positive +340
    ("rotary-acn-acp", ["G1 C10 F100", "C=ACN(20)", "C=ACP(0)"],
     [dict(m=1, xyz=(0, 0, 0), f=100, rot=(0, 0, 10)),
      dict(m=1, xyz=(0, 0, 0), f=100, rot=(0, 0, -340)),
      dict(m=1, xyz=(0, 0, 0), f=100, rot=(0, 0, 0))]),
    # mode 57: A about X, B about Y, C about Z. B90: swivelled X (1,0,0) -> (0,0,-1),
    # tool axis Z -> (1,0,0); CYCLE800() swivels back
    ("cycle800-57", ["G1 X0 Y0 Z0 F100", c800(57, 0, 90, 0), "G1 X10 Y0 Z0", "CYCLE800()",
                     "G1 X1 Y0 Z0"],
     [dict(m=1, xyz=(0, 0, 0), f=100, tcp=TCP_OFF),
      dict(m=1, xyz=(0, 0, -10), f=100, tcp=TCP_VECTOR, tv=(1, 0, 0)),
      dict(m=1, xyz=(1, 0, 0), f=100, tcp=TCP_OFF)]),
    # mode 27 (Z Y X): A about Z first, then C about the new X: R = Rz(90) Rx(90).
    # (10,0,0) -> Rx -> (10,0,0) -> Rz -> (0,10,0); (0,10,0) -> (0,0,10) -> (0,0,10);
    # tool (0,0,1) -> (0,-1,0) -> (1,0,0)
    ("cycle800-27", [c800(27, 90, 0, 90), "G1 X10 Y0 Z0 F100", "X0 Y10"],
     [dict(m=1, xyz=(0, 10, 0), f=100, tcp=TCP_VECTOR, tv=(1, 0, 0)),
      dict(m=1, xyz=(0, 0, 10), f=100, tcp=TCP_VECTOR, tv=(1, 0, 0))]),
    # X0 (100,0,0) before the rotation, X1 (5,0,0) after: (100,0,0) + Rz90 (15,0,0);
    # a turn about Z leaves the tool along Z: a 3-axis row (no tool vector)
    ("cycle800-shifts", [c800(57, 0, 0, 90, x0=(100, 0, 0), x1=(5, 0, 0)),
                         "G1 X10 Y0 Z0 F100"],
     [dict(m=1, xyz=(100, 15, 0), f=100, tcp=TCP_OFF)]),
    # _ST = 1: additive, C90 on top of C90 = C180: (10,0,0) -> (-10,0,0)
    ("cycle800-additive", [c800(57, 0, 0, 90), c800(57, 0, 0, 90, st_=1),
                           "G1 X10 Y0 Z0 F100"],
     [dict(m=1, xyz=(-10, 0, 0), f=100, tcp=TCP_OFF)]),
    # solid angle (64): Rz(90) Ry(30). X10 -> Ry30 (8.660, 0, -5) -> Rz90 (0, 8.660, -5);
    # tool axis Z -> (sin30, 0, cos30) -> (0, 0.5, 0.866)
    ("cycle800-solid-angle", [c800(64, 90, 30, 0), "G1 X10 Y0 Z0 F100"],
     [dict(m=1, xyz=(0, 10 * math.cos(math.radians(30)), -5), f=100, tcp=TCP_VECTOR,
           tv=(0, 0.5, math.cos(math.radians(30))))]),
    # projection X Y Z (185), one angle: _A = 30 about X is Rx(30): Y10 -> (0, 8.660, 5),
    # tool axis (0, -0.5, 0.866)
    ("cycle800-projection-x", [c800(185, 30, 0, 0), "G1 X0 Y10 Z0 F100"],
     [dict(m=1, xyz=(0, 10 * math.cos(math.radians(30)), 5), f=100, tcp=TCP_VECTOR,
           tv=(0, -0.5, math.cos(math.radians(30))))]),
    # projection X Y Z, 45 deg about both: new X = Ry(45) X = (1, 0, -1)/sqrt2 (the line
    # where the plane meets the Z-X plane); the plane meets the Y-Z plane along
    # Rx(45) Y = (0, 1, 1)/sqrt2; normal = (1,0,-1) x (0,1,1) ~ (1, -1, 1)/sqrt3; new Y =
    # normal x new X = (1, 2, 1)/sqrt6. X10 Y10 -> 10 (1,0,-1)/sqrt2 + 10 (1,2,1)/sqrt6
    ("cycle800-projection-xy", [c800(185, 45, 45, 0), "G1 X10 Y0 Z0 F100", "X0 Y10"],
     [dict(m=1, xyz=(10 / math.sqrt(2), 0, -10 / math.sqrt(2)), f=100, tcp=TCP_VECTOR,
           tv=(1 / math.sqrt(3), -1 / math.sqrt(3), 1 / math.sqrt(3))),
      dict(m=1, xyz=(10 / math.sqrt(6), 20 / math.sqrt(6), 10 / math.sqrt(6)), f=100,
           tcp=TCP_VECTOR, tv=(1 / math.sqrt(3), -1 / math.sqrt(3), 1 / math.sqrt(3)))]),
    # projection Y X Z (182): _A is about Y: _A = 45 alone is Ry(45), X10 -> (7.07, 0, -7.07);
    # _C = 90 turns about the new Z: X10 -> Ry45 Rz90 (10,0,0) = Ry45 (0,10,0) = (0,10,0)
    ("cycle800-projection-yx", [c800(182, 45, 0, 0), "G1 X10 Y0 Z0 F100", c800(182, 45, 0, 90),
                                "G1 X10 Y0 Z0"],
     [dict(m=1, xyz=(10 / math.sqrt(2), 0, -10 / math.sqrt(2)), f=100),
      dict(m=1, xyz=(0, 10, 0), f=100)]),
    # projection Z X Y (128 + 3 + 1*4 + 2*16 = 167): _B = 30 about X alone: Rx(30);
    # the new Z (0, -0.5, 0.866) stays in the old Y-Z plane: Z10 -> (0, -5, 8.660)
    ("cycle800-projection-zx", [c800(167, 0, 30, 0), "G1 X0 Y0 Z10 F100"],
     [dict(m=1, xyz=(0, -5, 10 * math.cos(math.radians(30))), f=100, tcp=TCP_VECTOR,
           tv=(0, -0.5, math.cos(math.radians(30))))]),
    # ROTS X45 Y45 is the plane of cycle800-projection-xy
    ("rots-xy", ["ROTS X45 Y45", "G1 X10 Y0 Z0 F100", "ROTS", "G1 X1 Y0 Z0"],
     [dict(m=1, xyz=(10 / math.sqrt(2), 0, -10 / math.sqrt(2)), f=100, tcp=TCP_VECTOR,
           tv=(1 / math.sqrt(3), -1 / math.sqrt(3), 1 / math.sqrt(3))),
      dict(m=1, xyz=(1, 0, 0), f=100, tcp=TCP_OFF)]),
    # SUPA: Z50 in the frame below the swivel (offsets zero), X Y where they were
    ("supa", [c800(57, 0, 0, 90), "G1 X10 Y0 Z5 F100", "SUPA G0 Z50", "G1 X10 Y0 Z5"],
     [dict(m=1, xyz=(0, 10, 5), f=100), dict(m=0, xyz=(0, 10, 50), f=100),
      dict(m=1, xyz=(0, 10, 5), f=100)]),
    ("g53", ["G1 X1 Y2 Z3 F100", "G53 G0 Z100", "G1 Z3"],
     [dict(m=1, xyz=(1, 2, 3), f=100), dict(m=0, xyz=(1, 2, 100), f=100),
      dict(m=1, xyz=(1, 2, 3), f=100)]),
    # swivelled B90 and TRAORI: the vector (0,0,1) of the swivelled plane is (1,0,0)
    ("cycle800-traori", [c800(57, 0, 90, 0), "TRAORI", "G1 X10 Y0 Z0 A3=0 B3=0 C3=1 F100"],
     [dict(m=1, xyz=(0, 0, -10), f=100, tcp=TCP_VECTOR, tv=(1, 0, 0))]),
    # TRANS shifts; AROT Z90 turns inside it: (10,0,0) -> (0,10,0) + (100,50,0);
    # ROT (no axis) clears the whole programmable frame
    ("trans-arot", ["G1 X0 Y0 Z0 F100", "TRANS X100 Y50", "G1 X10 Y0", "AROT Z90",
                    "G1 X10 Y0", "ROT", "G1 X1 Y0"],
     [dict(m=1, xyz=(0, 0, 0), f=100), dict(m=1, xyz=(110, 50, 0), f=100, tcp=TCP_OFF),
      dict(m=1, xyz=(100, 60, 0), f=100, tcp=TCP_OFF), dict(m=1, xyz=(1, 0, 0), f=100)]),
    # ROT Y90 turns the tool axis: (0,0,1) -> (1,0,0); ATRANS Z5 in the turned frame
    # moves along the world's +X: (10,0,0) -> (0,0,-10) + (5,0,0)
    ("rot-y-atrans", ["ROT Y90", "ATRANS Z5", "G1 X10 Y0 Z0 F100"],
     [dict(m=1, xyz=(5, 0, -10), f=100, tcp=TCP_VECTOR, tv=(1, 0, 0))]),
    # R1 = 1, 2, 3: the loop body runs three times (Z-1, Z-2, Z-3), IF R1<3 jumps back
    # twice; GOTOF ENDE skips X99; GOTO N120 (block 12: sin840 numbers in tens) skips Y99
    ("goto-loop", ["R1=0", "G1 X0 Y0 Z0 F100", "LOOP1: R1=R1+1", "G1 Z=-R1", "X10",
                   "IF (R1<3) AND NOT (R1==5) GOTOB LOOP1", "GOTOF ENDE", "G1 X99",
                   "ENDE: G0 Z50", "GOTO N120", "G1 Y99", "G1 X1"],
     [dict(m=1, xyz=(0, 0, 0), f=100),
      dict(m=1, xyz=(0, 0, -1), f=100), dict(m=1, xyz=(10, 0, -1), f=100),
      dict(m=1, xyz=(10, 0, -2), f=100), dict(m=1, xyz=(10, 0, -2), f=100),
      dict(m=1, xyz=(10, 0, -3), f=100), dict(m=1, xyz=(10, 0, -3), f=100),
      dict(m=0, xyz=(10, 0, 50), f=100), dict(m=1, xyz=(1, 0, 50), f=100)]),
    # R1 = 2: the first IF takes its branch (X1), the second its ELSE (Y6), the third
    # has no ELSE and is true (Z1)
    ("if-else", ["R1=2", "IF R1>1", "G1 X1 F100", "ELSE", "G1 X2 F100", "ENDIF", "IF R1<1",
                 "G1 Y5", "ELSE", "G1 Y6", "ENDIF", "IF (R1==2) AND NOT (R1==3)", "G1 Z1",
                 "ENDIF"],
     [dict(m=1, xyz=(1, 0, 0), f=100), dict(m=1, xyz=(1, 6, 0), f=100),
      dict(m=1, xyz=(1, 6, 1), f=100)]),
    # R1 = 1, 2, 3 inside the loop: X10 X20 X30; R1 = 3 ends it
    ("while", ["R1=0", "G1 X0 F100", "WHILE R1<3", "R1=R1+1", "G1 X=R1*10", "ENDWHILE",
               "G1 Y1"],
     [dict(m=1, xyz=(0, 0, 0), f=100), dict(m=1, xyz=(10, 0, 0), f=100),
      dict(m=1, xyz=(20, 0, 0), f=100), dict(m=1, xyz=(30, 0, 0), f=100),
      dict(m=1, xyz=(30, 1, 0), f=100)]),
    # II = 1, 2, 3: Z-1 Z-2 Z-3; after ENDFOR II is 4 (X4); FOR R5 = 3 TO 1 runs nothing
    ("for", ["DEF INT II", "G1 X0 F100", "FOR II=1 TO 3", "G1 Z=-II", "ENDFOR", "G1 X=II",
             "FOR R5=3 TO 1", "G1 Y99", "ENDFOR", "G1 Y=R5"],
     [dict(m=1, xyz=(0, 0, 0), f=100), dict(m=1, xyz=(0, 0, -1), f=100),
      dict(m=1, xyz=(0, 0, -2), f=100), dict(m=1, xyz=(0, 0, -3), f=100),
      dict(m=1, xyz=(4, 0, -3), f=100), dict(m=1, xyz=(4, 3, -3), f=100)]),
    # LOOP left by IF ... GOTOF after X1 X2
    ("loop-goto", ["R1=0", "G1 X0 F100", "LOOP", "R1=R1+1", "G1 X=R1", "IF R1>=2 GOTOF OUT",
                   "ENDLOOP", "OUT: G1 Y1"],
     [dict(m=1, xyz=(0, 0, 0), f=100), dict(m=1, xyz=(1, 0, 0), f=100),
      dict(m=1, xyz=(2, 0, 0), f=100), dict(m=1, xyz=(2, 1, 0), f=100)]),
    # the body of REPEAT ... UNTIL runs once even though R1 > 5 after it
    ("repeat-until", ["R1=5", "G1 X0 F100", "REPEAT", "G1 X=R1", "R1=R1+1", "UNTIL R1>5",
                      "G1 Y1"],
     [dict(m=1, xyz=(0, 0, 0), f=100), dict(m=1, xyz=(5, 0, 0), f=100),
      dict(m=1, xyz=(5, 1, 0), f=100)]),
    # R1 = 1, 2; R2 = 1, 2 inside: the move only at R2 = 2: (1,2) then (2,2)
    ("nested", ["G1 X0 F100", "FOR R1=1 TO 2", "R2=0", "WHILE R2<2", "R2=R2+1", "IF R2==2",
                "G1 X=R1 Y=R2", "ENDIF", "ENDWHILE", "ENDFOR"],
     [dict(m=1, xyz=(0, 0, 0), f=100), dict(m=1, xyz=(1, 2, 0), f=100),
      dict(m=1, xyz=(2, 2, 0), f=100)]),
    # the section START..(the block before REPEAT) runs once, then twice more: X+1 Y+1 x3
    ("repeat-section", ["G1 X0 F100", "START: G91 X1", "Y1", "REPEAT START P=2", "G90 G1 Z5"],
     [dict(m=1, xyz=(0, 0, 0), f=100), dict(m=1, xyz=(1, 0, 0), f=100),
      dict(m=1, xyz=(1, 1, 0), f=100), dict(m=1, xyz=(2, 1, 0), f=100),
      dict(m=1, xyz=(2, 2, 0), f=100), dict(m=1, xyz=(3, 2, 0), f=100),
      dict(m=1, xyz=(3, 3, 0), f=100), dict(m=1, xyz=(3, 3, 5), f=100)]),
    # REPEATB: the labelled block once, then 3 times more: X2 X4 X6 X8
    ("repeatb", ["G1 X0 F100", "ST: G91 X2", "REPEATB ST P=3", "G90 Y1"],
     [dict(m=1, xyz=(0, 0, 0), f=100), dict(m=1, xyz=(2, 0, 0), f=100),
      dict(m=1, xyz=(4, 0, 0), f=100), dict(m=1, xyz=(6, 0, 0), f=100),
      dict(m=1, xyz=(8, 0, 0), f=100), dict(m=1, xyz=(8, 1, 0), f=100)]),
    # GOTOF skips A1..A2; REPEAT A1 A2 P=2 runs them twice, then the block after REPEAT
    ("repeat-two-labels", ["G1 X0 F100", "GOTOF OVER", "A1: G91 X1", "A2: Y1",
                           "OVER: REPEAT A1 A2 P=2", "G90 Z1"],
     [dict(m=1, xyz=(0, 0, 0), f=100), dict(m=1, xyz=(1, 0, 0), f=100),
      dict(m=1, xyz=(1, 1, 0), f=100), dict(m=1, xyz=(2, 1, 0), f=100),
      dict(m=1, xyz=(2, 2, 0), f=100), dict(m=1, xyz=(2, 2, 1), f=100)]),
    # ENDLABEL ends the section: X1 Y1 again, not Z1
    ("repeat-endlabel", ["G1 X0 F100", "BEG: G91 X1", "ENDLABEL: Y1", "Z1", "REPEAT BEG",
                         "G90 X0"],
     [dict(m=1, xyz=(0, 0, 0), f=100), dict(m=1, xyz=(1, 0, 0), f=100),
      dict(m=1, xyz=(1, 1, 0), f=100), dict(m=1, xyz=(1, 1, 1), f=100),
      dict(m=1, xyz=(2, 1, 1), f=100), dict(m=1, xyz=(2, 2, 1), f=100),
      dict(m=1, xyz=(0, 2, 1), f=100)]),
    # a section whose last block is ENDWHILE (the WHILE leaves it past ENDWHILE) and one
    # whose last block is an ENDIF skipped by a false IF: each still repeats once more
    ("repeat-ends-in-loop", ["G1 X0 F100", "R1=0", "S1: R2=0", "WHILE R2<2", "R2=R2+1",
                             "X=IC(1)", "ENDWHILE", "REPEAT S1 P=1", "S2: IF R1==1",
                             "G1 Y=R1", "E2: ENDIF", "REPEAT S2 E2 P=1", "G1 Z1"],
     [dict(m=1, xyz=(0, 0, 0), f=100), dict(m=1, xyz=(1, 0, 0), f=100),
      dict(m=1, xyz=(2, 0, 0), f=100), dict(m=1, xyz=(3, 0, 0), f=100),
      dict(m=1, xyz=(4, 0, 0), f=100), dict(m=1, xyz=(4, 0, 1), f=100)]),
    # GOTOC without a target goes on; GOTOC N60 skips N50 (X9)
    ("gotoc", ["G1 X0 F100", "GOTOC NOWHERE", "G1 X1", "GOTOC N60", "G1 X9", "G1 Y1"],
     [dict(m=1, xyz=(0, 0, 0), f=100), dict(m=1, xyz=(1, 0, 0), f=100),
      dict(m=1, xyz=(1, 1, 0), f=100)]),
    # a jump may leave a WHILE: X1 X2, then out at R1 = 3
    ("jump-out-of-while", ["R1=0", "G1 X0 F100", "WHILE 1", "R1=R1+1", "IF R1==3 GOTOF DONE",
                           "G1 X=R1", "ENDWHILE", "DONE: G1 Y1"],
     [dict(m=1, xyz=(0, 0, 0), f=100), dict(m=1, xyz=(1, 0, 0), f=100),
      dict(m=1, xyz=(2, 0, 0), f=100), dict(m=1, xyz=(2, 1, 0), f=100)]),
    ("g700-inch", ["G700 G1 X1 Y2 F10"], [dict(m=1, xyz=(25.4, 50.8, 0), f=254)]),
    # G4 F2 is a dwell of 2 s, not a feed
    ("g4-dwell", ["G1 X1 F100", "G4 F2", "X2"],
     [dict(m=1, xyz=(1, 0, 0), f=100), dict(m=1, xyz=(2, 0, 0), f=100)]),
    ("label-skip-nospace", ["G1X1F100", "MARK1: X2", "/ X3", "G0X4Y5"],
     [dict(m=1, xyz=(1, 0, 0), f=100), dict(m=1, xyz=(2, 0, 0), f=100),
      dict(m=1, xyz=(3, 0, 0), f=100), dict(m=0, xyz=(4, 5, 0), f=100)]),
    ("path-control-ignored", ["G642 SOFT FFWON", "CYCLE832(0.01,_ORI_FINISH,1)", "G64 G1 X1 F100",
                              "COMPCAD G601 X2"],
     [dict(m=1, xyz=(1, 0, 0), f=100), dict(m=1, xyz=(2, 0, 0), f=100)]),
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
    _check_rows(parse_siemens(sin840(*blocks)), rows)


def test_block_delete_skips_slashed_blocks():
    prog = parse_siemens(sin840(*BY_NAME["label-skip-nospace"][1]), block_delete=True)
    assert prog.end[:, 0].tolist() == [1, 2, 4]


def test_metadata_ignored_and_machine_moves():
    prog = parse_siemens(sin840('MSG("Schlichten; Kontur")', 'T="Fräser D10"', "M6",
                                *BY_NAME["supa"][1], *BY_NAME["path-control-ignored"][1]))
    assert prog.number == "T" and prog.metadata["dialect"] == "siemens"
    assert prog.metadata["messages"] == ["Schlichten; Kontur"]
    assert prog.metadata["tool_names"] == ["Fräser D10"]
    assert prog.machine_moves.tolist() == [1]
    codes = {c for c, _, _ in prog.ignored}
    assert {"G642", "CYCLE832", "SOFT", "FFWON", "G64", "COMPCAD", "G601"} <= codes


def test_swivelled_arc_is_chords_on_the_swivelled_circle():
    prog = parse_siemens(sin840(c800(57, 0, 90, 0), "G1 X10 Y0 Z0 F100", "G3 X0 Y10 I-10 J0"))
    rows = prog.end[1:, :3]
    assert len(rows) > 10 and np.all(prog.arc_index == -1)
    # the swivelled XY plane is the workpiece's Y(-Z) plane: chord ends 10 from the origin
    np.testing.assert_allclose(np.linalg.norm(rows, axis=1), 10, atol=1e-9)
    np.testing.assert_allclose(rows[:, 0], 0, atol=1e-9)
    np.testing.assert_allclose(rows[-1], (0, 10, 0), atol=1e-9)


def test_program_goes_to_cutter_locations():
    prog = parse_siemens(sin840(*BY_NAME["g3-ijk"][1]))
    cl = cutter_locations(prog)
    assert np.allclose(np.linalg.norm(cl.tip[1:, :2], axis=1), 10)


def test_cam_style_program():
    # the shape 5-axis CAM posts write for an 840D (written here, not copied): header,
    # WORKPIECE, tool by name, swivel reset, tolerance cycle, TRAORI with vectors,
    # retract with SUPA, swivel for a 3+2 pocket wall, end
    text = """%_N_BRACKET_MPF
;$PATH=/_N_MPF_DIR
;Operation : FINISH_WALL
N10 G17 G90 G71 G40 G94
N20 WORKPIECE(,"",,"BOX",112,0,-30,-80,0,0,100,60)
N30 T="BALL_D6" M6
N40 D1
N50 CYCLE800()
N60 G54
N70 S14000 M3 M8
N80 CYCLE832(0.005,_ORI_FINISH,1)
N90 TRAORI
N100 ORIWKS ORIAXES
N110 G0 X10. Y5. Z50. A3=0. B3=0. C3=1.
N120 G1 Z2. F2000.
N130 X12.5 Y5. Z0. A3=0.1736482 B3=0. C3=0.9848078 F800.
N140 G2 X17.5 Y5. I2.5 J0.
N150 G1 X20. A3=0. C3=1.
N160 G0 Z50.
N170 TRAFOOF
N180 SUPA G0 Z0 D0
N190 CYCLE800(1,"TC1",200000,57,0,0,0,0,-30,0,0,0,0,-1,100,1)
N200 G0 X0 Y0 Z20 D1
N210 G1 Z0 F500
N220 X40
N230 CYCLE800()
N240 CYCLE832()
N250 M5 M9
N260 M30
"""
    prog = parse_siemens(text, file="bracket.mpf")
    # moves: N110 N120 N130 N140 N150 N160, SUPA N180, N200 N210 N220
    assert prog.number == "BRACKET" and len(prog) == 10
    assert prog.metadata["tool_names"] == ["BALL_D6"]
    np.testing.assert_allclose(prog.end[2, :3], (12.5, 5, 0))
    np.testing.assert_allclose(prog.tool_vector[2], (0.1736482, 0, 0.9848078), atol=1e-7)
    # the arc under TRAORI keeps the last vector and is an arc about (15, 5)
    assert prog.motion[3] == 2 and prog.arc_centre[0].tolist() == [15.0, 5.0, 0.0]
    # B-30 (mode 57): swivelled (40, 0, 0) -> (40 cos30, 0, 40 sin30); tool (-sin30, 0, cos30)
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    np.testing.assert_allclose(prog.end[-1, :3], (40 * c, 0, 40 * s), atol=1e-9)
    np.testing.assert_allclose(prog.tool_vector[-1], (-s, 0, c), atol=1e-12)
    assert prog.modal_column("spindle_dir").tolist()[-1] == 1
    cl = cutter_locations(prog)
    assert np.all(cl.feed_mm_min[~cl.rapid] > 0)


# --------------------------------------------------------------------------- writer
GEOMETRY = {
    "xyzac-trt": dict(tilt_pivot_mm=(0.0, 20.0, -35.0), rotary_pivot_mm=(5.0, -3.0, 0.0)),
    "xyzbc-trt": dict(tilt_pivot_mm=(-15.0, 0.0, -40.0), rotary_pivot_mm=(2.0, 4.0, 0.0)),
    "xyzbc-head-table": dict(tool_length_mm=80.0, tilt_pivot_mm=(0.0, 0.0, 150.0),
                             rotary_pivot_mm=(10.0, -5.0, 0.0)),
    "xyzbc-head-head": dict(tool_length_mm=80.0, tilt_pivot_mm=(0.0, 0.0, 120.0),
                            rotary_pivot_mm=(3.0, 0.0, 200.0)),
}


class _Rows:
    """Rows lo..hi of a program, as a sequence of blocks (for _check_rows)."""

    def __init__(self, prog, lo, hi):
        self.p, self.lo, self.hi = prog, lo, hi

    def __len__(self):
        return self.hi - self.lo

    def __iter__(self):
        return (self.p[i] for i in range(self.lo, self.hi))


def test_known_pairs_write_vector():
    # the traori-vector pair written back: the same words, read back to the same row
    cl = CutterLocations.from_arrays([[1.0, 2.0, 3.0]], [[0.0, 0.6, 0.8]], 500.0, 1000.0)
    res = post_siemens(cl, get_machine("xyzbc-trt"), SiemensPostOptions(form="vector"))
    assert "G1 X1.0000 Y2.0000 Z3.0000 A3=0.0000000 B3=0.6000000 C3=0.8000000 F500" in res.text
    assert res.text.startswith("%_N_NCPATH_MPF\n;$PATH=/_N_MPF_DIR\n")
    _check_rows(_Rows(parse_siemens(res.text), 1, 2), BY_NAME["traori-vector"][2][:1])


def test_known_pairs_write_rotary():
    # the traori-rotary pair: tip and the axis of B30 C45 on a machine; written and read
    m = get_machine("xyzbc-trt")
    _, axis = m.forward(np.array([[10.0, 20.0, 5.0, math.radians(30), math.radians(45)]]))
    cl = CutterLocations.from_arrays([[10.0, 20.0, 5.0]], axis, 1000.0, 1000.0)
    res = post_siemens(cl, m, SiemensPostOptions(form="rotary"))
    line = [ln for ln in res.text.splitlines() if "F1000" in ln][0]
    b, c = (float(v) for v in re.findall(r" [BC](-?[\d.]+)", line))
    # B30 C45 or the other solution B-30 C225 (C-135): both give the pair's tool axis
    assert (b, c) in ((30.0, 45.0), (-30.0, 225.0), (-30.0, -135.0))
    row = parse_siemens(res.text)[1]
    np.testing.assert_allclose(row.end[:3], (10, 20, 5))
    assert row.modal.tcp == TCP_ANGLES


@pytest.mark.parametrize("form", SIEMENS_FORMS)
@pytest.mark.parametrize("name", list(MACHINES))
def test_writer_round_trip_blade(name, form, tmp_path):
    from nc.path import read_cl_csv

    blade = read_cl_csv(BLADE).take(slice(0, 200))
    m = get_machine(name, **GEOMETRY[name])
    out = tmp_path / "p.mpf"
    res = write_siemens(out, blade, m, SiemensPostOptions(form=form, program_name="BLADE"))
    assert out.read_text() == res.text
    e_tip, e_ang = siemens_round_trip(res, m, form)
    assert e_tip <= 1e-3 and e_ang <= 1e-4
    prog = read_any(out)  # detected as Siemens
    assert prog.metadata["dialect"] == "siemens" and prog.number == "BLADE"
    cl = cutter_locations(prog, m)
    cut = np.flatnonzero(~cl.rapid)  # approach and retract are G0
    assert len(cut) == len(blade)
    np.testing.assert_allclose(cl.tip[cut], blade.tip, atol=1e-3)
    ang = np.degrees(np.arccos(np.clip(np.sum(cl.axis[cut] * blade.axis, 1), -1, 1)))
    assert ang.max() < 1e-3  # tool axis through the machine's forward kinematics


@settings(max_examples=25, deadline=None)
@given(data=st.data())
def test_writer_round_trip_random_paths(data):
    name = data.draw(st.sampled_from(sorted(MACHINES)))
    form = data.draw(st.sampled_from(SIEMENS_FORMS))
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
    res = post_siemens(cl, m, SiemensPostOptions(form=form))
    e_tip, e_ang = siemens_round_trip(res, m, form)
    assert e_tip <= 1e-3 and e_ang <= 1e-4


def test_write_refuses_when_read_back_differs(tmp_path):
    cl = CutterLocations.from_arrays([[1.23456, 0, 0], [2, 0, 0]], [0, 0, 1], 100.0)
    with pytest.raises(InputError, match="not written"):
        write_siemens(tmp_path / "p.mpf", cl, get_machine("xyzbc-trt"),
                      SiemensPostOptions(linear_decimals=2))
    assert not (tmp_path / "p.mpf").exists()


def test_write_refuses_values_beyond_a_word():
    cl = CutterLocations.from_arrays([[1e8, 0, 0], [2, 0, 0]], [0, 0, 1], 100.0)
    with pytest.raises(InputError, match="beyond what the writer puts in a word"):
        post_siemens(cl, get_machine("xyzbc-trt"))


# --------------------------------------------------------------------------- bad input
BAD = [
    (["G41 G1 X1 F100"], "G41 is not read (cutter radius compensation"),
    (["G1 X1"], "cutting move with no feed"),
    (["X1"], "without a motion mode"),
    (["G1 X=R7 F100"], "R7 is used before it is set"),
    ([c800(192, 0, 30, 0)], "swivel mode 192 (direct (rotary axis positions)) needs the "
                            "machine's kinematics: give a machine file"),
    ([c800(193, 0, 30, 0)], "swivel mode 193 (direct (rotary axis positions)) is not a"),
    ([c800(64, 0, 30, 10)], "_C = 10 with solid angle (_MODE 64) is not read"),
    ([c800(121, 0, 30, 0)], "solid angle is _MODE 64"),
    ([c800(128, 0, 30, 0)], "bits 0-5 must name X, Y and Z once"),
    ([c800(185, 90, 90, 0)], "projection angles of +-90 deg about both axes"),
    (["ROTS X10 Y10 Z10"], "ROTS with three axes"),
    (["AROTS X90 Y90"], "AROTS solid angles of +-90 deg"),
    ([c800(21, 0, 30, 0)], "bits 0-5 must name X, Y and Z once"),
    (["CYCLE800(1,\"TC1\",2,57)"], "units digit must be 0"),
    (["G1 X1 A3=1 F100"], "without TRAORI"),
    (["TRAORI", "G1 X1 A3=0 B3=0 C3=1 F100", "B10"], "after an A3/B3/C3 tool vector"),
    (["TRAORI", "G1 X1 A3=0 B3=0 C3=0 F100"], "zero length"),
    (["G1 X0 Y0 F100", "G2 X10 Y0"], "arc without a centre"),
    (["G1 X0 Y0 F100", "G2 X30 Y0 CR=5"], "impossible arc"),
    (["G1 X0 Y0 F100", "G2 X10 Y0 I3"], "radius"),
    (["G1 X0 Y0 F100", "G3 X2 Y1 AR=90"], "AR= (opening angle)"),
    (["G1 X1 F100 M91"], "unsupported M91"),
    (["G1 X1 F100 H5"], "unsupported address H5"),
    (["ROT X10 Y20"], "ROT with more than one axis"),
    (["TRANS X10 G1"], "TRANS with other words in its block"),
    (["TRANS X10 F100"], "F with TRANS"),
    (["SCALE X2"], "scaling and mirroring frames"),
    (["GOTOF ENDE"], "GOTOF ENDE: no label or block number ENDE after this block"),
    (["ENDE: G1 X1 F100", "GOTOF ENDE"], "no label or block number ENDE after"),
    (["GOTOB ENDE", "ENDE: G1 X1 F100"], "no label or block number ENDE before"),
    (["A1: G1 X1 F100", "A1: X2"], "label A1 defined twice"),
    (["IF R1==1 X2"], "IF not closed; expected ENDIF"),
    (["R1=1", "IF R1=1 GOTOF E", "E: X1"], "unexpected '=1' in an expression"),
    (["WHILE R1<3"], "WHILE not closed; expected ENDWHILE"),
    (["G1 X1 F100 GOTOF E"], "a jump must be its block's only statement"),
    (["IF R1==1", "G1 X1 F100"], "IF not closed; expected ENDIF"),
    (["R1=1", "FOR R1=1 TO 3", "G1 X1 F100"], "FOR not closed; expected ENDFOR"),
    (["REPEAT", "G1 X1 F100"], "REPEAT not closed; expected UNTIL"),
    (["G1 X1 F100", "ENDFOR"], "ENDFOR without FOR"),
    (["UNTIL R1>1"], "UNTIL without REPEAT"),
    (["WHILE 1", "ENDIF"], "ENDIF closes the WHILE of line 3; expected ENDWHILE first"),
    (["ELSE"], "ELSE without IF"),
    (["IF 1", "ELSE", "ELSE", "ENDIF"], "a second ELSE"),
    (["REPEAT NOWHERE P=2"], "REPEAT NOWHERE: no label or block number NOWHERE"),
    (["REPEATB NOWHERE"], "REPEATB NOWHERE: no label or block number NOWHERE"),
    (["GOTOF IN", "IF 1", "IN: G1 X1 F100", "ENDIF"], "inside a structured block"),
    (["FOR XX=1 TO 3", "ENDFOR"], "the counter must be an R parameter or a DEF variable"),
    (["FOR R1=1 TO", "ENDFOR"], "expected FOR variable = start TO end"),
    (["CASE R1 OF 1 GOTOF A"], "CASE ... OF ... DEFAULT is not read"),
    (["LOOP X1", "ENDLOOP"], "LOOP with more in its block"),
    (["G1 X1 F100 ENDIF"], "ENDIF must begin its own block"),
    (["L1: G1 X1 F100", "REPEAT L1 P=0.5"], "expected a whole count"),
    (["R1=0", "IF R1==0", "A1: G1 X1 F100", "ENDIF", "REPEAT A1"], "cuts through the ENDIF"),
    (["G1 X0 F100", "R1=0", "A1: R1=R1+1", "IF R1==2 GOTOF OUT", "REPEAT A1 P=3", "OUT: X1"],
     "a jump out of the section"),
    (["A1: G1 X1 F100", "REPEAT A1 A9 P=2"], "no label A9 at or after A1"),
    (["WHILE R7>1", "ENDWHILE"], "WHILE: R7 is used before it is set"),
    (["GOTOF R1"], "no label or block number R1 after"),
    (["L100"], "subprogram calls"),
    (["CYCLE81(10,0,2,-5)"], "CYCLE81 is not read"),
    (["MYSUB(1,2)"], "unsupported call MYSUB"),
    (["G1 X1 Y2 X3 F100"], "appears twice"),
    (["R1=$AA_IW[X]"], "system variable $AA_IW"),
    (["G1 X=SIN(30 F100"], "expected ')'"),
    (["DEF STRING[10] TXT"], "DEF REAL and DEF INT"),
    (["DEF REAL X"], "address or function of the control"),
    (["G1 X1 F100 DEF REAL AB"], "DEF inside a block"),
    ([c800(57, 0, 30, 0), "TRAORI", "CYCLE800()"], "while TRAORI is on"),
    (["G95 G1 X1 F0.1"], "feed per revolution"),
    (["G1 X100000000 F1"], "out of range"),
    (["FOO=3"], "unknown name FOO="),
    (["G75 FP=1 Z1"], "G75 is not read (fixed point approach"),
    (["G1 X=1/0 F100"], "division by zero"),
    (["G1 X1 Y=SQRT(-1) F100"], "SQRT of -1 is not defined"),
    (['MSG("open'], "string not closed"),
    (["SUPA G2 X1 Y1 CR=1 F100"], "SUPA/G53/G153 needs G0 or G1"),
    (["G1 X1 F100", "G2 X2 Y0 I=DC(1)"], "expected a value, AC(..) or IC(..)"),
    (["G1 X=DC(5) F100"], "DC, ACP and ACN apply to rotary axes"),
    (["G4 F2 X1"], "dwell"),
    (["G1 X1 F100 I2"], "I in a G1 block"),
    (["TRAORI(2)"], "TRAORI with parameters"),
    (["G1.5 X1"], "expected a whole number"),
    (["X1 N20"], "block number N inside a block"),
    (["G1 X1 F100 ORIMKS"], "ORIMKS"),
]


@pytest.mark.parametrize("blocks,what", BAD, ids=[b[1][:30] for b in BAD])
def test_bad_input_one_error(blocks, what):
    with pytest.raises(NCParseError) as exc:
        parse_siemens(sin840(*blocks), file="p.mpf")
    first = str(exc.value).splitlines()[0]
    assert re.match(r"p\.mpf:\d+:\d+: ", first), first
    assert what in first, first


def test_error_column_points_at_the_word():
    with pytest.raises(NCParseError) as exc:
        parse_siemens("N10 G1 X1 F100\nN20 G1 Y=R9 X2\n", file="c.mpf")
    assert exc.value.line == 2 and exc.value.column == 10  # the R9 of Y=R9


def test_allow_list_and_its_refusals():
    assert len(parse_siemens(sin840("G1 X1 F100 H5 M110"), allow=["H5", "m110"])) == 1
    with pytest.raises(NCParseError, match="allow: TRANS moves the tool"):
        parse_siemens(sin840("G1 X1 F100"), allow=["TRANS"])
    with pytest.raises(NCParseError, match="is not an M, G or H code"):
        parse_siemens(sin840("G1 X1 F100"), allow=["G64.1"])


def test_header_only_once_and_empty_program():
    with pytest.raises(NCParseError, match="expected one header"):
        parse_siemens("%_N_A_MPF\nG1 X1 F10\n%_N_B_SPF\nG1 X2\n", file="h.mpf")
    with pytest.raises(NCParseError, match="empty program"):
        parse_siemens("%_N_A_MPF\n; nothing\n", file="e.mpf")


def test_endless_jump_loop_hits_the_limit(monkeypatch):
    import nc.constants as K

    monkeypatch.setattr(K, "SIEMENS_MAX_EXECUTED_BLOCKS", 1000)
    with pytest.raises(NCParseError, match="SIEMENS_MAX_EXECUTED_BLOCKS"):
        parse_siemens(sin840("G1 X0 F100", "L1: G91 X1", "GOTOB L1"))


@pytest.mark.parametrize("blocks,what", [
    (["G1 X0 F100", "LOOP", "G91 X1", "ENDLOOP"], "passes of the LOOP at line 4"),
    (["WHILE 1", "R1=1", "ENDWHILE"], "passes of the WHILE at line 3"),
    (["R1=0", "REPEAT", "R1=1", "UNTIL R1>1"], "passes of the REPEAT at line 4"),
    (["FOR R1=1 TO 5000", "R1=1", "ENDFOR"], "passes of the FOR at line 3"),
    (["L1: R1=1", "GOTOB L1"], "passes of GOTOB L1 at line 4 jumping back"),
    (["R1=0", "L1: R1=R1+1", "IF R1>0 GOTO L1"], "passes of GOTO L1 at line 5 jumping back"),
])
def test_runaway_loop_ends_in_one_line(monkeypatch, blocks, what):
    import nc.constants as K

    monkeypatch.setattr(K, "SIEMENS_MAX_LOOP_PASSES", 1000)
    with pytest.raises(NCParseError) as exc:
        parse_siemens(sin840(*blocks), file="r.mpf")
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith("r.mpf:") and what in msg, msg
    assert "SIEMENS_MAX_LOOP_PASSES" in msg


@pytest.mark.parametrize("a,b", [(1, 3), (-2, 2), (4, 4), (5, 2), (0, 0)])
def test_every_loop_form_gives_the_same_moves(a, b):
    """X = a, a+1, ..., b (none when a > b) written as FOR, WHILE, LOOP with a jump out,
    IF ... GOTOB, GOTO (found behind) and REPEAT ... UNTIL (a <= b: it runs at least
    once): the same moves, those worked out by hand."""
    forms = {
        "for": [f"FOR R1={a} TO {b}", "G1 X=R1", "ENDFOR"],
        "while": [f"R1={a}", f"WHILE R1<={b}", "G1 X=R1", "R1=R1+1", "ENDWHILE"],
        "loop": [f"R1={a}", "LOOP", f"IF R1>{b} GOTOF OUT", "G1 X=R1", "R1=R1+1", "ENDLOOP",
                 "OUT:"],
        "gotob": [f"R1={a}", f"IF R1>{b} GOTOF OUT", "BACK: G1 X=R1", "R1=R1+1",
                  f"IF R1<={b} GOTOB BACK", "OUT:"],
        "goto": [f"R1={a}", f"IF R1>{b} GOTOC OUT", "BACK: G1 X=R1", "R1=R1+1",
                 f"IF R1<={b} GOTO BACK", "OUT:"],
    }
    if a <= b:
        forms["until"] = [f"R1={a}", "REPEAT", "G1 X=R1", "R1=R1+1", f"UNTIL R1>{b}"]
    expected = [0.0] + [float(x) for x in range(a, b + 1)]
    for name, blocks in forms.items():
        prog = parse_siemens(sin840("G1 X0 Y0 Z0 F100", *blocks))
        assert [b_.end[0] for b_ in prog] == expected, name


def test_loop_passes_count_from_the_last_entry(monkeypatch):
    """An inner loop entered 30 times with 30 passes each (900 passes in all) stays under
    a bound of 50 passes: the count starts again at each entry."""
    import nc.constants as K

    monkeypatch.setattr(K, "SIEMENS_MAX_LOOP_PASSES", 50)
    prog = parse_siemens(sin840("G1 X0 F100", "FOR R1=1 TO 30", "R2=0", "WHILE R2<30",
                                "R2=R2+1", "ENDWHILE", "G1 X=R1", "ENDFOR"))
    assert len(prog) == 31 and prog[30].end[0] == 30
    # the same with the inner loop an IF ... GOTOB: not taken, it ends its loop's count
    prog = parse_siemens(sin840("G1 X0 F100", "FOR R1=1 TO 30", "R2=0", "IN: R2=R2+1",
                                "IF R2<30 GOTOB IN", "G1 X=R1", "ENDFOR"))
    assert len(prog) == 31 and prog[30].end[0] == 30


def test_nested_section_repeats_are_bounded(monkeypatch):
    import nc.constants as K

    monkeypatch.setattr(K, "SIEMENS_MAX_REPEAT_DEPTH", 3)
    # REPEAT A1 A2 repeats a section that holds REPEATB: depth 2, allowed
    prog = parse_siemens(sin840("G1 X0 F100", "GOTOF GO", "A1: G91 X1", "REPEATB A1 P=1",
                                "A2: G90", "GO: REPEAT A1 A2 P=2", "G1 Y1"))
    # X1 then X1 again (REPEATB) per pass, two passes: X4; then Y1
    assert [round(b.end[0]) for b in prog] == [0, 1, 2, 3, 4, 4]


def test_projection_frame_against_a_closed_form():
    """Projection (ROTS) angles a about X, b about Y are ROT Y b then AROT X a' with
    tan a' = tan a cos b (the plane's line in the Y-Z plane rises by tan a: its normal
    (cos a' sin b, -sin a', cos a' cos b) ~ (tan b, -tan a, 1)); the same for the
    other pairs with the axes renamed cyclically (Z X: Y -> Z, X -> X ...)."""
    from nc.siemens_frames import projection_frame, rotation

    rng = np.random.default_rng(11)
    for _ in range(50):
        a, b = rng.uniform(-80, 80, 2)
        ap = math.degrees(math.atan(math.tan(math.radians(a)) * math.cos(math.radians(b))))
        for first, second in ((0, 1), (2, 0), (1, 2)):
            expected = rotation(second, b) @ rotation(first, ap)
            np.testing.assert_allclose(projection_frame(first, second, a, b), expected,
                                       atol=1e-12)
    for a, b in rng.uniform(-180, 180, (50, 2)):  # beyond 90 deg: still a rotation
        R = projection_frame(0, 1, a, b)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)


def test_a_kept_expression_reads_the_parameters_of_each_evaluation():
    """Expressions are parsed once and kept: the same text must still give each
    evaluation's value, and its run-time errors (unset name, division by zero)."""
    from nc.siemens_expr import ExprError, condition, evaluate

    assert evaluate("R1*2+AB MOD 3", {"R1": 1.0, "AB": 5.0}) == 4.0
    assert evaluate("R1*2+AB MOD 3", {"R1": 2.5, "AB": 7.0}) == 6.0
    with pytest.raises(ExprError, match="AB in an expression"):
        evaluate("R1*2+AB MOD 3", {"R1": 1.0})
    assert condition("R1<>0 AND 1/R1>0.5", {"R1": 1.0})
    with pytest.raises(ExprError, match="division by zero"):
        condition("R1<>0 AND 1/R1>0.5", {"R1": 0.0})  # both sides run, as before


def test_program_ends_at_m30_and_tape_marks_pass():
    prog = parse_siemens("%\nG1 X1 F100\nM30\nG1 X2\n%\n")
    assert len(prog) == 1


def test_fuzz_never_crashes(monkeypatch):
    import nc.constants as K

    monkeypatch.setattr(K, "SIEMENS_MAX_LOOP_PASSES", 1000)
    monkeypatch.setattr(K, "SIEMENS_MAX_EXECUTED_BLOCKS", 100_000)
    rng = random.Random(4321)
    base = sin840(*BY_NAME["g3-ijk"][1], *BY_NAME["r-params"][1], *BY_NAME["supa"][1],
                  "TRAORI", "G1 X1 Y2 Z3 A3=0 B3=0.6 C3=0.8 F500", "TRAFOOF",
                  c800(27, 10, 0, 20), "G2 X5 Y5 CR=10", "CYCLE800()", 'MSG("x;y")',
                  "G1 C=DC(20)", "G3 X=IC(0) Y=IC(0) Z2 I-10 J0 TURN=1", "R3=0",
                  "AG: R3=R3+1 G1 X=R3", "IF R3<4 GOTOB AG", "TRANS X2", "AROT Z10", "X1",
                  "TRANS", "ROT", c800(185, 20, -15, 30), "G1 X2 Y2 Z0", c800(64, 45, 10, 0),
                  "CYCLE800()", "ROTS X10 Y20", "ROTS", *BY_NAME["if-else"][1][1:],
                  *BY_NAME["nested"][1][1:], *BY_NAME["repeat-until"][1],
                  *BY_NAME["loop-goto"][1], *BY_NAME["repeat-endlabel"][1][1:],
                  "REPEATB BEG P=1", "GOTOC NOWHERE")
    alphabet = "GXYZABCIJKRFMNTDS+-.=()\"',;:/$ 0123456789\n"
    ok = bad = 0
    for _ in range(800):
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
            parse_siemens("".join(s), file="f.mpf")
            ok += 1
        except NCParseError as exc:
            assert re.match(r"f\.mpf(:\d+(:\d+)?)?: \S", str(exc)), str(exc)
            assert "\n" not in str(exc)
            bad += 1
    assert ok > 50 and bad > 50


# --------------------------------------------------------------------------- dialects
def test_detect_and_dispatch(tmp_path):
    s = tmp_path / "a.mpf"
    s.write_text(sin840("G1 X1 F10", "CYCLE800()"))
    assert detect_dialect(s.read_text()) == "siemens"
    assert detect_dialect(";$PATH=/_N_WKS_DIR/_N_A_WPD\nG1 X1 F10\n") == "siemens"
    # no header: Sinumerik-only words in the first blocks
    assert detect_dialect("N10 G17 G90\nN20 CYCLE800()\nN30 G1 X1 F10\n") == "siemens"
    assert detect_dialect("G0 X0\nTRAORI\n") == "siemens"
    assert detect_dialect("N10 G642 G1 X1 F10\n") == "siemens"
    assert detect_dialect("N1 G1 X0 Y0 F9\nN2 G3 X2 Y2 CR=2.\n") == "siemens"
    assert detect_dialect("G1 X0 F9\nG3 X2 Y2 R2.\n") == "gcode"
    # an ISO program naming Sinumerik words in a parenthesised comment stays G-code
    assert detect_dialect("%\nO1000 (TRAORI POST, CYCLE800 OFF)\nG1 X1 F10\n%\n") == "gcode"
    assert detect_dialect("G1 X1 F10\nM2\n") == "gcode"
    assert detect_dialect("0 BEGIN PGM A MM\n1 END PGM A MM\n") == "heidenhain"
    assert read_any(s).metadata["dialect"] == "siemens"
    assert read_siemens(s).number == "T"
    g = tmp_path / "a.ngc"
    g.write_text("G1 X1 F10\nM2\n")
    assert len(read_any(g, dialect="siemens")) == 1  # forced: plain ISO lines read too
    with pytest.raises(NCParseError):
        read_any(s, dialect="gcode")  # forced: the G-code reader refuses the header


def test_cli_parse_and_post(tmp_path, capsys):
    from nc.cli import main

    s = tmp_path / "a.mpf"
    s.write_text(sin840(*BY_NAME["cycle800-57"][1]))
    assert main(["parse", str(s), "--json"]) == 0
    assert '"line":' in capsys.readouterr().out
    assert main(["parse", str(s), "--dialect", "siemens"]) == 0
    capsys.readouterr()
    bad = tmp_path / "b.mpf"
    bad.write_text(sin840("MIRROR X0"))
    assert main(["parse", str(bad)]) == 2
    assert "mirroring frames" in capsys.readouterr().err
    for dialect, word in (("siemens-traori", " A3="), ("siemens-traori-rot", " B")):
        out = tmp_path / f"p-{dialect}.mpf"
        assert main(["post", BLADE, "--machine", "xyzbc-trt", "--dialect", dialect,
                     "-o", str(out)]) == 0
        text = out.read_text()
        assert text.startswith("%_N_P_SIEMENS_TRAORI") and word in text and "TRAORI\n" in text
        assert len(read_any(out)) > 100


def test_rewrite_refuses_sinumerik():
    from nc.rewrite import RewriteError, rewrite_coordinates

    prog = parse_siemens(sin840("G1 X1 F100"), file="p.mpf")
    with pytest.raises(RewriteError, match="Siemens"):
        rewrite_coordinates(prog, {0: np.array([2.0, 0.0, 0.0])})


@pytest.mark.parametrize("form", SIEMENS_FORMS)
@pytest.mark.parametrize("name,blocks,rows", KNOWN, ids=[k[0] for k in KNOWN])
def test_known_pairs_round_trip_through_the_writer(name, blocks, rows, form):
    """Every pair's moves, as cutter locations (arcs in chords, rotary moves through
    the machine), written by both posts and read back: the same tips and tool axes."""
    m = get_machine("xyzbc-trt", **GEOMETRY["xyzbc-trt"])
    prog = parse_siemens(sin840(*blocks))
    cl = cutter_locations(prog, m)
    res = post_siemens(cl, m, SiemensPostOptions(form=form))
    e_tip, e_ang = siemens_round_trip(res, m, form)
    assert e_tip <= 1e-3 and e_ang <= 1e-4
    back = cutter_locations(parse_siemens(res.text), m)
    np.testing.assert_allclose(back.tip[1:-1], cl.tip, atol=1e-3)
    cosang = np.clip(np.sum(back.axis[1:-1] * cl.axis, axis=1), -1, 1)
    assert np.degrees(np.arccos(cosang)).max() < 1e-3
    np.testing.assert_array_equal(back.rapid[1:-1][~cl.rapid], False)


# -- CYCLE800 direct mode (192): the plane from the machine's rotary axes ---------------
DIRECT_MACHINES = ["xyzac-trt", "xyzbc-trt", "xyzbc-head-table", "xyzbc-head-head"]


@pytest.mark.parametrize("name", DIRECT_MACHINES)
@pytest.mark.parametrize("ax1,ax2", [(30.0, 50.0), (-45.0, 120.0), (0.0, -90.0)])
def test_cycle800_direct_mode_against_the_forward_transform(name, ax1, ax2):
    """_A/_B are rotary axes 1/2 (axis 2 carried by axis 1; mixed: the head's first).
    The tool vector after the swivel is the kinematics' forward tool axis at those
    joints; on table-table machines the swivelled X Y Z are the forward transform's
    tip displacements for machine X Y Z; on all, the plane is right-handed."""
    from nc.kinematics import get_machine

    m = get_machine(name)
    tilt, rot = m.axes
    first = rot if (tilt.carrier, rot.carrier) == ("head", "head") else tilt
    joints = np.zeros(5)
    joints[3 if first is tilt else 4] = math.radians(ax1)
    joints[4 if first is tilt else 3] = math.radians(ax2)
    p = np.array([10.0, 20.0, 5.0])
    prog = parse_siemens(sin840("G1 X0 Y0 Z0 F100", c800(192, ax1, ax2, 0, x0=(1, 2, 3)),
                                "G1 X10 Y20 Z5"), machine=m)
    _, axis = m.forward(joints)
    if prog.modal_column("tcp")[-1] == TCP_OFF:  # the plane keeps the tool along Z
        np.testing.assert_allclose(axis, [0, 0, 1], atol=1e-12)
    else:
        np.testing.assert_allclose(prog.tool_vector[-1], axis, atol=1e-12)
    R = m.tool_frame(joints[3], joints[4])
    np.testing.assert_allclose(prog.end[-1, :3], [1, 2, 3] + R @ p, atol=1e-9)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    if tilt.carrier == rot.carrier == "table":
        tip0, _ = m.forward(joints)
        for k in range(3):
            j = joints.copy()
            j[k] += 1.0
            np.testing.assert_allclose(m.forward(j)[0] - tip0, R[:, k], atol=1e-12)


def test_cycle800_direct_mode_head_frame_by_closed_form():
    """Head-table B/C: the spindle turned by B about Y, the table's C undone about Z."""
    from nc.kinematics import get_machine
    from nc.rotation import rotation_about

    m = get_machine("xyzbc-head-table")
    b, c = 25.0, 70.0
    tilt, rot = m.axes
    want = (rotation_about(rot.vector, -math.radians(c) * rot.direction)
            @ rotation_about(tilt.vector, math.radians(b) * tilt.direction))
    prog = parse_siemens(sin840("G1 X0 Y0 Z0 F100", c800(192, b, c, 0), "G1 X1 Y0 Z0",
                                "G1 X0 Y1 Z0"), machine=m)
    np.testing.assert_allclose(prog.end[-2, :3], want[:, 0], atol=1e-12)
    np.testing.assert_allclose(prog.end[-1, :3], want[:, 1], atol=1e-12)
    with pytest.raises(NCParseError, match="direct mode .192. with _C"):
        parse_siemens(sin840(c800(192, b, c, 5)), file="p.mpf", machine=m)
