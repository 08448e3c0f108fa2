"""nc.macro_b: Fanuc macro B and subprograms of one file, read into moves.

The table's moves were worked out by hand from Fanuc's Custom Macro B rules
(vacant variables, argument specification I, DO/END, M98 P/L, M99 P); the
arithmetic is checked against Python's with hypothesis; bad input ends in one
NCParseError line naming file:line:col; a seeded fuzz finds no crash.
"""

from __future__ import annotations

import math
import os
import random

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from nc import constants as K
from nc.errors import NCParseError
from nc.gcode import parse_program, read_program
from nc.macro_b import expand_macro_b, needs_macro_b
from nc.summary import summarize
from nc.rewrite import RewriteError, rewrite_coordinates


def _moves(src: str) -> tuple[list[tuple[float, float, float]], list[int]]:
    prog = parse_program(src, file="m.nc")
    return [tuple(round(float(v), 9) for v in row[:3]) for row in prog.end], list(prog.line)


# (what, source, end points (x, y, z) [mm], source line of each move); hand-checked
KNOWN = [
    ("assignment and arithmetic",
     "O1\n#1=2\n#2=#1*3+1\nG1 X#2 F100\nM30\n", [(7, 0, 0)], [4]),
    ("vacant variable leaves its address out",
     "O1\nG0 X1 Y2\nG0 X#1 Y5\nM30\n", [(1, 2, 0), (1, 5, 0)], [2, 3]),
    ("vacant is 0 in a sum, EQ tells vacant from 0",
     "O1\n#2=#1+3\nIF [#1 EQ 0] THEN #2=9\nIF [#1 EQ #0] THEN #3=4\nG0 X#2 Y#3\nM30\n",
     [(3, 4, 0)], [5]),
    ("IF GOTO skips forward",
     "O1\n#1=1\nIF [#1 EQ 1] GOTO 20\nG0 X9\nN20 G0 X2\nM30\n", [(2, 0, 0)], [5]),
    ("GOTO backward as a counted loop",
     "O1\n#1=0\nN5 #1=#1+1\nG0 X#1\nIF [#1 LT 3] GOTO 5\nM30\n",
     [(1, 0, 0), (2, 0, 0), (3, 0, 0)], [4, 4, 4]),
    ("WHILE DO1 END1",
     "%\nO1\n#1=1\nWHILE [#1 LE 3] DO1\nG1 X[#1*2] F50\n#1=#1+1\nEND1\nG0 Z5\nM30\n%\n",
     [(2, 0, 0), (4, 0, 0), (6, 0, 0), (6, 0, 5)], [5, 5, 5, 8]),
    ("nested DO1 / DO2",
     "O1\n#1=0\nWHILE [#1 LT 2] DO1\n#2=0\nWHILE [#2 LT 2] DO2\nG0 X#1 Y#2\n#2=#2+1\n"
     "END2\n#1=#1+1\nEND1\nM30\n",
     [(0, 0, 0), (0, 1, 0), (1, 0, 0), (1, 1, 0)], [6, 6, 6, 6]),
    ("M98 P L: a subprogram three times",
     "O1\nG0 X0\nM98 P2 L3\nG90 G0 Z1\nM30\nO2\nG91 G1 X1 F10\nM99\n",
     [(0, 0, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0), (3, 0, 1)], [2, 7, 7, 7, 4]),
    ("M98 Pxxxxnnnn: count 2, program 7",
     "O1\nM98 P20007\nM30\nO7\nG91 G0 Y2\nM99\n", [(0, 2, 0), (0, 4, 0)], [5, 5]),
    ("G65 arguments and locals per level",
     "O1\n#1=5\nG65 P9 X3 Y4 R1\nG0 Z#1\nM30\nO9\n#1=#24+#25\nG0 X#24 Y#25 Z-#18\n"
     "G0 X#1\nM99\n",
     [(3, 4, -1), (7, 4, -1), (7, 4, 5)], [8, 9, 4]),
    ("subprograms share the caller's locals, common variables are global",
     "O1\n#1=2\n#100=3\nM98 P5\nG0 X#1 Y#100\nM30\nO5\n#1=#1*10\n#100=#100+1\nM99\n",
     [(20, 4, 0)], [5]),
    ("M99 Pn returns to block Nn of the caller",
     "O1\nM98 P3\nG0 X9\nN50 G0 X1\nM30\nO3\nG0 Y1\nM99 P50\n",
     [(0, 1, 0), (1, 1, 0)], [7, 4]),
    ("Haas M97: an N number of the same program as a subprogram",
     "O1\nM97 P100 L2\nG90 G0 Z3\nM30\nN100 G91 G0 X5\nM99\n",
     [(5, 0, 0), (10, 0, 0), (10, 0, 3)], [5, 5, 3]),
    ("bolt circle of 4 holes, COS and SIN in degrees",
     "O1\n#1=0\nWHILE [#1 LT 4] DO1\n#2=#1*90\nG0 X[10*COS[#2]] Y[10*SIN[#2]]\n#1=#1+1\n"
     "END1\nM30\n",
     [(10, 0, 0), (0, 10, 0), (-10, 0, 0), (0, -10, 0)], [5, 5, 5, 5]),
    ("ATAN[a]/[b] 0...360, FIX toward 0, FUP away from 0, ROUND",
     "O1\nG0 X[ATAN[-1]/[-1]] Y[FIX[-1.7]+FUP[-1.2]] Z[ROUND[2.5]]\nM30\n",
     [(225, -3, 3)], [2]),
    ("AND OR XOR bitwise, EQ exact",
     "O1\n#1=[5 AND 3]+[4 OR 1]*10\nIF [1 EQ 1.00001] THEN #1=0\nG0 X#1\nM30\n",
     [(51, 0, 0)], [4]),
    ("text before the first O is the main program; #3006 stop passes",
     "%\nG0 X1\n#3006=1 (CHECK)\nM98 P100\nM30\nO100\nG0 Y2\nM99\n%\n",
     [(1, 0, 0), (1, 2, 0)], [2, 7]),
    ("indirect variables #[..] and a G65 with L repeats",
     "O1\n#5=7\n#6=#[#5-2]\nG65 P2 L2 A#6\nM30\nO2\n#100=#100+#1\nG0 X#100\nM99\n",
     [(7, 0, 0), (14, 0, 0)], [8, 8]),
    ("assignments before '%' run, then the first O program",
     "#1=2\n%\nO1001 (PART)\nG0 X[1+#1]\nM30\n%\n", [(3, 0, 0)], [4]),
    ("blocks, then '%': the tape ends there, as the reader reads it",
     "G0 X1\n%\nO1\nG0 X[2]\nM98 P1\n", [(1, 0, 0)], [1]),
    ("a G65 argument given a vacant variable stays vacant",
     "O1\nG65 P2 A#9 B1\nM30\nO2\nIF [#1 EQ #0] THEN #1=7\nG0 X#1 Y#2\nM99\n",
     [(7, 1, 0)], [6]),
    ("external output (POPEN, DPRNT, PCLOS) moves nothing",
     "O1\n#100=2\nPOPEN\nDPRNT[X#100[53]]\nPCLOS\nG0 X#100\nM30\n", [(2, 0, 0)], [6]),
    ("programs each between '%' lines: the main ends at its '%', the others are called",
     "%\nO1\nM98 P2\nG0 Y1\nM30\n%\n%\nO2\nG0 X1\nM99\n%\n",
     [(1, 0, 0), (1, 1, 0)], [9, 4]),
    ("M30 in a subprogram ends the run",
     "O1\nM98 P2\nG0 X9\nO2\nG0 X1\nM30\n", [(1, 0, 0)], [5]),
]


@pytest.mark.parametrize("what,src,ends,lines", KNOWN, ids=[k[0] for k in KNOWN])
def test_known_programs(what, src, ends, lines):
    got, got_lines = _moves(src)
    assert got == [tuple(float(v) for v in e) for e in ends]
    assert got_lines == lines


def test_block_delete_skips_macro_statements():
    src = "O1\n#1=1\n/#1=2\nG0 X#1\nM30\n"
    assert _moves(src)[0] == [(2, 0, 0)]
    assert parse_program(src, block_delete=True).end[0, 0] == 1


def test_detection_leaves_plain_and_linuxcnc_programs_alone():
    assert not needs_macro_b("G0 X1\nG1 Y2 F100\nM30\n")
    assert not needs_macro_b("#1=2\nG0 X#1\n")  # LinuxCNC parameters (nc.macro)
    assert not needs_macro_b("o100 while [#1 LT 3]\no100 endwhile\n")
    assert needs_macro_b("O1\n#1=2\nG0 X#1\n")  # an O program number: Fanuc
    assert needs_macro_b("G0 X1\nM98 P2\n") and needs_macro_b("N5 WHILE [1 EQ 1] DO1\n")
    assert needs_macro_b("O1\nN5 G0 X1\nGOTO 5\n") and needs_macro_b("g0 x1\nm99\n")
    # LinuxCNC's M65/M66 (digital outputs, wait), O-words and #<name>: not Fanuc
    assert not needs_macro_b("M66 P0 L3 Q5\nM65 P1\nG0 X1\n")
    assert not needs_macro_b("#<a>=1\nG0 X#<a>\nM99\n")
    assert not needs_macro_b("o100 sub\nG0 X[1]\no100 endsub\nM98 P100\n")
    assert not needs_macro_b("G0 X1\nG1 X2 F100 (END OF PASS)\nM9\nM30\n")


def test_error_columns_point_into_expanded_and_plain_lines():
    # a reader error on a line the expansion kept as is: the word's own column
    with pytest.raises(NCParseError) as info:
        parse_program("O1\n#1=1\nG0 X#1\nG0 X1 X2\nM30\n", file="m.nc")
    assert str(info.value).startswith("m.nc:4:") and info.value.column == 7


def test_rewriting_a_macro_program_is_refused():
    # one source line makes three moves: a corrected coordinate has no one place to go
    prog = parse_program("O1\nM98 P2 L3\nM30\nO2\nG91 G1 X1 F10\nM99\n", file="m.nc")
    with pytest.raises(RewriteError, match="Fanuc macro B programs and subprograms"):
        rewrite_coordinates(prog, ends={0: prog.end[0] + 0.001})


# -- arithmetic against Python ------------------------------------------------
_LEAF = st.integers(-50, 50).map(float) | st.sampled_from([0.5, 1.25, -2.75, 3.0])


def _tree(children):
    return st.tuples(st.sampled_from("+-*/"), children, children)


_EXPR = st.recursive(_LEAF, _tree, max_leaves=8)


def _render(t) -> tuple[str, float]:
    if isinstance(t, float):
        return repr(t), t
    op, a, b = t
    (sa, va), (sb, vb) = _render(a), _render(b)
    if op == "/" and vb == 0:
        op = "+"
    value = {"+": va + vb, "-": va - vb, "*": va * vb, "/": va / vb if vb else 0.0}[op]
    return f"[{sa} {op} {sb}]", value


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_EXPR)
def test_arithmetic_matches_python(tree):
    text, value = _render(tree)
    if abs(value) >= 1e6:
        return
    prog = parse_program(f"O1\n#1={text}\nG0 X#1\nM30\n")
    assert prog.end[0, 0] == pytest.approx(value, rel=1e-12, abs=1e-12)


_CMP = {"EQ": lambda a, b: a == b, "NE": lambda a, b: a != b, "GT": lambda a, b: a > b,
        "GE": lambda a, b: a >= b, "LT": lambda a, b: a < b, "LE": lambda a, b: a <= b}


@settings(max_examples=100, deadline=None)
@given(st.sampled_from(sorted(_CMP)), st.integers(-3, 3), st.integers(-3, 3),
       st.integers(0, 15), st.integers(0, 15))
def test_comparisons_and_bitwise_logic_match_python(op, a, b, m, n):
    # IF [a op b] THEN, and AND / OR / XOR of whole numbers bit by bit, as Fanuc
    src = (f"O1\n#1=0\nIF [{a} {op} {b}] THEN #1=1\n"
           f"G0 X#1 Y[{m} AND {n}] Z[[{m} OR {n}] + [{m} XOR {n}] * 100]\nM30\n")
    end = parse_program(src).end[0]
    assert end[0] == float(_CMP[op](a, b))
    assert (end[1], end[2]) == (m & n, (m | n) + (m ^ n) * 100)


@settings(max_examples=100, deadline=None)
@given(st.floats(-720, 720, allow_nan=False), st.floats(0.001, 1000), st.floats(-1000, 1000))
def test_functions_match_python(angle, positive, x):
    # Fanuc numbers have no exponent: written with 12 decimals, read back as such
    angle, positive, x = (float(f"{v:.12f}") for v in (angle, positive, x))
    if positive == 0:
        return
    src = (f"O1\n#1={angle:.12f}\n#2={positive:.12f}\n#3={x:.12f}\n"
           "G0 X[SIN[#1]] Y[COS[#1]] Z[SQRT[#2]]\n"
           "G0 X[ABS[#3]] Y[FIX[#3]] Z[FUP[#3]]\n"
           "G0 X[#3 / #2] Y[LN[#2]] Z[ATAN[#3]/[#2]]\nM30\n")
    end = parse_program(src).end
    trunc = math.trunc(x)
    fup = trunc + (x > trunc) - (x < trunc)
    want = [(math.sin(math.radians(angle)), math.cos(math.radians(angle)), math.sqrt(positive)),
            (abs(x), trunc, fup),
            (x / positive, math.log(positive),
             math.degrees(math.atan2(x, positive)) % 360.0)]
    for row, w in zip(end, want):
        assert list(row[:3]) == pytest.approx(list(w), rel=1e-12, abs=1e-9)


@settings(max_examples=100, deadline=None)
@given(st.floats(-1000, 1000), st.floats(-1000, 1000), st.floats(0.01, 10),
       st.floats(-4, 4), st.integers(0, 99_999))  # results within the reader's 1e7 coordinates
def test_30i_functions_match_python(a, b, base, power, whole):
    """ATAN[a,b], ATAN[x], POW[a,b], BCD/BIN against Python (NAT=0: 0...360 deg)."""
    a, b, base, power = (float(f"{v:.12f}") for v in (a, b, base, power))
    if a == 0 and b == 0:
        return
    src = (f"O1\n#1={a:.12f}\n#2={b:.12f}\n#3={base:.12f}\n#4={power:.12f}\n#5={whole}\n"
           "G0 X[ATAN[#1,#2]] Y[ATAN[#1]] Z[POW[#3,#4]]\n"
           "G0 X[BCD[#5]] Y[BIN[BCD[#5]]] Z[ATAN[#1]/[#2] - ATAN[#1,#2]]\nM30\n")
    end = parse_program(src).end
    want = [(math.degrees(math.atan2(a, b)) % 360.0, math.degrees(math.atan(a)) % 360.0,
             base ** power),
            (float(int(str(whole), 16)), float(whole), 0.0)]
    for row, w in zip(end, want):
        assert list(row[:3]) == pytest.approx(list(w), rel=1e-12, abs=1e-9)


# -- bad input: one line each ---------------------------------------------------
BAD = [
    ("GOTO to a missing N", "O1\nGOTO 99\nM30\n", 2, "no block N99 in program O1"),
    ("unclosed WHILE", "O1\nWHILE [1 EQ 1] DO1\nG0 X1\nM30\n", 2, "DO1 has no END1"),
    ("END without DO", "O1\nG0 X1\nEND2\nM30\n", 3, "END2 without its DO2"),
    ("crossed ranges", "O1\nWHILE [1 EQ 1] DO1\nWHILE [1 EQ 1] DO2\nEND1\nEND2\nM30\n", 4,
     "END1 without its DO1 (DO2 is open)"),
    ("loop number", "O1\nWHILE [1 EQ 1] DO4\nM30\n", 2, "loop number 1, 2 or 3"),
    ("M99 P in the main program", "O1\nN5 G0 X1\nM99 P5\n", 3, "M99 P in the main program"),
    ("call to another file", "O1\nM98 P4321\nM30\n", 2, "no program O4321 in this file"),
    ("G65 to another file", "O1\nG65 P9010 A1\nM30\n", 2, "no program O9010 in this file"),
    ("G66 modal macro", "O1\nG66 P9 A1\nM30\n", 2, "G66: modal macro calls"),
    ("system variable read", "O1\nG0 X#5021\nM30\n", 2, "system variable #5021"),
    ("system variable set", "O1\n#4001=1\nM30\n", 2, "system variable #4001"),
    ("vacant GOTO", "O1\nGOTO #1\nM30\n", 2, "GOTO's N number is vacant"),
    ("vacant condition", "O1\nIF [#1] GOTO 5\nN5 M30\n", 2, "IF condition is vacant"),
    ("vacant M98 P", "O1\nM98 P#7\nM30\n", 2, "M98's P is vacant"),
    ("#0 set", "O1\n#0=1\nM30\n", 2, "#0 is always vacant"),
    ("#500 before set", "O1\nG0 X#500\nM30\n", 2, "#500 is read before the program sets"),
    ("#40 does not exist", "O1\n#40=1\nM30\n", 2, "#40 does not exist"),
    ("alarm", "O1\n#3000=12 (PART MISSING)\nM30\n", 2, "alarm 12 (#3000): PART MISSING"),
    ("division by zero", "O1\n#1=1/#2\nM30\n", 2, "division by zero"),
    ("recursion", "O1\nM98 P2\nM30\nO2\nM98 P2\nM99\n", 5, "calls nested more than"),
    ("subprogram without M99", "O1\nM98 P2\nM30\nO2\nG0 X1\n", 4, "ends at line 5 without M99"),
    ("two statements", "O1\n#1=1 G0 X1\nM30\n", 2, "one macro statement per block"),
    ("G65 argument letter", "O1\nG65 P2 G1\nM30\nO2\nM99\n", 2, "G is not a G65 argument"),
    ("duplicate program", "O1\nM30\nO2\nM99\nO2\nM99\n", 5, "O2 appears twice"),
    ("bad expression", "O1\n#1=[1+\nM30\n", 2, "expression"),
    ("ADP", "O1\n#1=1.\nG0 X[ADP[#1]]\nM30\n", 3, "ADP (add a decimal point"),
    ("POW of a negative base", "O1\n#1=POW[-2,0.5]\nM30\n", 2, "POW of -2, 0.5"),
    ("BIN of a non-BCD value", "O1\n#1=BIN[26]\nM30\n", 2, "BIN of 26"),
]


@pytest.mark.parametrize("what,src,line,fragment", BAD, ids=[b[0] for b in BAD])
def test_bad_input_is_one_line(what, src, line, fragment):
    with pytest.raises(NCParseError) as info:
        parse_program(src, file="bad.nc")
    err = info.value
    assert fragment in str(err)
    assert str(err).startswith(f"bad.nc:{line}:") and "\n" not in str(err)
    assert err.line == line and err.column is not None and err.column >= 1


# M99 in the main program (no call active) ends it (nc.macro_b's docstring: Centroid
# reads it as the end of the job; a Fanuc control would start again: one pass is read)
M99_MAIN = [
    ("plain M99 ends the main program", "O1\nG0 X1\nM99\n", [(1, 0, 0)], [2], 3),
    ("blocks after it are not run", "O1\nG0 X1\nM99\nG0 X5\nM30\n", [(1, 0, 0)], [2], 3),
    ("its block's move runs first (Centroid's 'G1 X3 M99')",
     "G0 X1\nG1 X3 F100 M99\nG0 X9\n", [(1, 0, 0), (3, 0, 0)], [1, 2], 2),
    ("M99 in a subprogram still returns; the main program's M99 ends",
     "O1\nM98 P2 L2\nG0 Z4\nM99\nO2\nG91 G0 X1\nG90\nM99\n",
     [(1, 0, 0), (2, 0, 0), (2, 0, 4)], [6, 6, 3], 4),
    ("after the assignments before the first O", "#1=2\nO1\nG0 X#1\nM99\n",
     [(2, 0, 0)], [3], 4),
]


@pytest.mark.parametrize("what,src,moves,lines,m99", M99_MAIN, ids=[m[0] for m in M99_MAIN])
def test_m99_in_the_main_program_ends_it(what, src, moves, lines, m99):
    prog = parse_program(src, file="m.nc")
    assert _moves(src) == (moves, lines)
    assert prog.main_m99_line == m99


def test_m99_main_is_refused_when_strict_and_recorded_otherwise():
    src = "O1\nG0 X1\nM99\n"
    with pytest.raises(NCParseError) as info:
        parse_program(src, file="bad.nc", strict=True)
    assert str(info.value).startswith("bad.nc:3:1: ") and "\n" not in str(info.value)
    assert "M99 in the main program" in str(info.value) and "expected M30 or M02" in str(
        info.value)
    assert parse_program("O1\nG0 X1\nM30\n").main_m99_line == 0
    assert parse_program("G0 X1\n").main_m99_line == 0


OPEN_END = [
    # (what, source, line of the O program the main program runs into, or 0)
    ("runs into the subprogram", "G0 X1\nM98 P2\nG0 Z5\nO2\nG1 X2 F100\nM99\n", 4),
    ("M30 before it", "G0 X1\nM98 P2\nM30\nO2\nG1 X2 F100\nM99\n", 0),
    ("M02 before it", "G0 X1\nM98 P2\nM02\nO2\nG1 X2 F100\nM99\n", 0),
    ("% before it", "%\nG0 X1\nM98 P2\n%\nO2\nG1 X2 F100\nM99\n", 0),
    ("main program numbered, subprogram after M30", "O1\nM98 P2\nM30\nO2\nG1 X2 F100\nM99\n",
     0),
]


@pytest.mark.parametrize("what,src,line", OPEN_END, ids=[m[0] for m in OPEN_END])
def test_main_program_running_into_a_subprogram_is_recorded(what, src, line):
    prog = parse_program(src, file="m.nc")
    assert prog.main_open_end_line == line
    assert summarize(prog).main_open_end_line == (line or None)
    # the subprogram's blocks come once, from the call: the text after the main
    # program's end is not run on into
    sub_line = src.split("\n").index("G1 X2 F100") + 1
    assert sum(1 for v in prog.line if v == sub_line) == 1


def test_main_program_running_into_a_subprogram_is_refused_when_strict():
    src = "G0 X1\nM98 P2\nG0 Z5\nO2\nG1 X2 F100\nM99\n"
    with pytest.raises(NCParseError) as info:
        parse_program(src, file="open.nc", strict=True)
    msg = str(info.value)
    assert msg.startswith("open.nc:4:") and "\n" not in msg
    assert "begins, without M30 or M02" in msg and "expected M30 or M02 before it" in msg


def test_runtime_errors_point_at_the_statement():
    with pytest.raises(NCParseError) as info:
        parse_program("O1\n#1=1\nIF [#1 EQ 1] GOTO 77\nM30\n", file="m.nc")
    assert info.value.column == info.value.text.index("GOTO") + 1
    with pytest.raises(NCParseError) as info:
        parse_program("O1\nG0 X[2 / [#5 - #5]]\nM30\n", file="m.nc")
    assert info.value.column == info.value.text.index("/") + 1


def test_runaway_loop_ends_in_one_line(monkeypatch):
    monkeypatch.setattr(K, "MACRO_B_MAX_EXECUTED_BLOCKS", 10_000)
    with pytest.raises(NCParseError, match=r"m\.nc:3:1: .*more than 10,000 blocks executed"):
        parse_program("O1\n#1=0\nWHILE [#1 GE 0] DO1\n#1=#1+1\nEND1\nM30\n", file="m.nc")
    with pytest.raises(NCParseError, match="more than 500 blocks"):
        expand_macro_b(["O1", "N1 G0 X1", "GOTO 1"], "m.nc", max_blocks=500)


# -- seeded fuzz -----------------------------------------------------------------
_SEED_PROGRAM = ("%\nO1 (MAIN)\n#1=0\n#2=3\nWHILE [#1 LT #2] DO1\nG65 P9 X[#1*10] Y5. R2.\n"
                 "IF [#1 EQ 1] THEN #3=ATAN[1]/[2]\n#1=#1+1\nEND1\nM98 P2 L2\n"
                 "IF [#3 NE #0] GOTO 40\nG0 X-1\nN40 G0 Z50\nM30\nO2\nG91 G1 X1 F100\n"
                 "G90\nM99\nO9\nG0 X#24 Y#25\nG1 Z-#18 F50\nG0 Z[SQRT[4]+#18]\nM99\n%\n")
_ALPHABET = "#[]=+-*/.0123456789 XYZGMPLONIFWHDEQTA()\n"
_TOKENS = ["#", "[", "]", "=", "GOTO", "WHILE", "DO1", "END1", "IF", "THEN", "M99", "M98",
           "G65", "EQ", "#0", "#1", "P2", "L0", "N40", "\n"]


def test_seeded_fuzz_never_crashes(monkeypatch):
    monkeypatch.setattr(K, "MACRO_B_MAX_EXECUTED_BLOCKS", 5_000)
    rng = random.Random(18)
    read = refused = 0
    for _ in range(400):
        chars = list(_SEED_PROGRAM)
        for _ in range(rng.randint(1, 4)):
            k = rng.randrange(len(chars))
            op = rng.random()
            if op < 0.3:
                del chars[k]
            elif op < 0.6:
                chars.insert(k, rng.choice(_ALPHABET))
            else:
                chars.insert(k, rng.choice(_TOKENS))
        try:
            parse_program("".join(chars), file="f.nc")
            read += 1
        except NCParseError as exc:
            assert "\n" not in str(exc)
            refused += 1
    assert read + refused == 400 and read > 0 and refused > 0


# -- public programs (not committed; see external_fanuc_macro.txt) ---------------
_HERE = os.path.dirname(__file__)
_CORPUS_DIR = os.path.join(os.environ.get("NC_CORPUS_DIR") or os.path.join(
    _HERE, "..", "..", "..", "shared", "nc-corpus"), "fanuc")

#: status -> what the one-line message of the refusal says
CORPUS_REASONS = {
    "rplane": "R plane 0.1 below the bottom Z0.5",
    "otherfile": "calls to other files are not supported",
    "typo": "expected one macro statement per block",
    "divzero": "division by zero",
    "vacantgoto": "GOTO's N number is vacant",
    "zeroarc": "arc of zero radius",
    "system": "system variable #5405",
}


def _corpus() -> list[tuple[str, int, str]]:
    out = []
    with open(os.path.join(_HERE, "external_fanuc_macro.txt"), encoding="utf-8") as fh:
        for line in fh:
            if line.strip() and not line.startswith("#"):
                cells = line.split()
                assert len(cells) == 6 and len(cells[4]) == 40, line
                status, _, at = cells[0].partition("@")
                assert status == "read" or status in CORPUS_REASONS, line
                out.append((status, int(at or 0), cells[1]))
    return out


@pytest.mark.parametrize("status,line,name", _corpus(), ids=[c[2] for c in _corpus()])
def test_public_macro_programs(status, line, name):
    path = os.path.join(_CORPUS_DIR, name)
    if not os.path.exists(path):
        pytest.skip(f"{path} is not on this machine")
    if status == "read":
        assert len(read_program(path)) > 0
        return
    with pytest.raises(NCParseError) as info:
        read_program(path)
    assert info.value.line == line and CORPUS_REASONS[status] in str(info.value)
    assert "\n" not in str(info.value)
