"""The G-code reader, from one table of programs with hand-computed results.

Each case is used three ways: parsed and compared with the expected blocks;
rewritten unchanged and with moved points and read back (round trip); and,
where the program is in LinuxCNC's dialect, interpreted by LinuxCNC's rs274
as an independent reference.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from nc import NCParseError, parse_program, read_program
from nc.linuxcnc import run_rs274
from nc.rewrite import rewrite_coordinates

S2 = math.sqrt(0.5)

# name, source, options, expected [(line, motion, xyz_mm, abc_deg, feed)], linuxcnc?
CASES = [
    ("absolute-mm", "G21 G90 G94\nG0 X1 Y2 Z3\nG1 X4 F100\nY-5.5 Z.25\n", {},
     [(2, 0, (1, 2, 3), (0, 0, 0), math.nan), (3, 1, (4, 2, 3), (0, 0, 0), 100.0),
      (4, 1, (4, -5.5, 0.25), (0, 0, 0), 100.0)], True),
    ("incremental-inch", "G20 G91\nG0 X1 Y1\nG1 X.5 Z-.1 F10\n", {},
     [(2, 0, (25.4, 25.4, 0), (0, 0, 0), math.nan),
      (3, 1, (38.1, 25.4, -2.54), (0, 0, 0), 254.0)], True),
    ("units-switch-in-block", "G21 G90\nG0 X1\nG20 G1 X1 F1\n", {},
     [(2, 0, (1, 0, 0), (0, 0, 0), math.nan), (3, 1, (25.4, 0, 0), (0, 0, 0), 25.4)], True),
    ("arc-ijk-quarter", "G21 G90 G17\nG0 X10 Y0\nG3 X0 Y10 I-10 J0 F500\n", {},
     [(2, 0, (10, 0, 0), (0, 0, 0), math.nan), (3, 3, (0, 10, 0), (0, 0, 0), 500.0)], True),
    ("arc-r-short-and-long", "G21 G90 G17\nG0 X0 Y0\nG2 X10 Y10 R10 F300\nG2 X0 Y0 R-10\n",
     {}, [(2, 0, (0, 0, 0), (0, 0, 0), math.nan), (3, 2, (10, 10, 0), (0, 0, 0), 300.0),
          (4, 2, (0, 0, 0), (0, 0, 0), 300.0)], True),
    ("full-circle-and-helix-turns",
     "G21 G90 G17\nG0 X5 Y0 Z0\nG2 I-5 J0 F100\nG3 X5 Y0 Z-2 I-5 P2\n", {},
     [(2, 0, (5, 0, 0), (0, 0, 0), math.nan), (3, 2, (5, 0, 0), (0, 0, 0), 100.0),
      (4, 3, (5, 0, -2), (0, 0, 0), 100.0)], True),
    ("planes-zx-yz-helical",
     "G21 G90\nG0 X0 Y0 Z0\nG18 G2 X10 Z0 Y5 I5 K0 F100\nG19 G3 Y15 Z0 J5 K0\n", {},
     [(2, 0, (0, 0, 0), (0, 0, 0), math.nan), (3, 2, (10, 5, 0), (0, 0, 0), 100.0),
      (4, 3, (10, 15, 0), (0, 0, 0), 100.0)], True),
    ("rotary-inverse-time",
     "G21 G90 G93\nG1 X10 A90 F2\nG1 X20 C-45 F4\nG94 G1 X30 F100\n", {},
     [(2, 1, (10, 0, 0), (90, 0, 0), 2.0), (3, 1, (20, 0, 0), (90, 0, -45), 4.0),
      (4, 1, (30, 0, 0), (90, 0, -45), 100.0)], True),
    ("comments-numbers-tape",
     "%\nO0012 (part)\nn10 g21 g90 (mode; semicolon inside)\n/N20 G0 X5 ; end comment\n"
     "N30 g1x1y2z3f50\n%\nX99 (after the tape end: never read)\n", {},
     [(4, 0, (5, 0, 0), (0, 0, 0), math.nan), (5, 1, (1, 2, 3), (0, 0, 0), 50.0)], True),
    ("block-delete-on",
     "G21 G90\n/G0 X5\nG1 X1 F50\n", {"block_delete": True},
     [(3, 1, (1, 0, 0), (0, 0, 0), 50.0)], False),
    ("tcp-vector",
     "G21 G90 G94\nG43.5 H2\nG1 X1 Y0 Z0 I0 J0 K1 F100\nG1 X2 I1 J0 K1\nG49\n", {},
     [(3, 1, (1, 0, 0), (0, 0, 0), 100.0), (4, 1, (2, 0, 0), (0, 0, 0), 100.0)], False),
    ("tcp-angles",
     "G21 G90 G94\nG43.4 H1\nG1 X1 Y2 Z3 A10 C20 F100\nG49\n", {},
     [(3, 1, (1, 2, 3), (10, 0, 20), 100.0)], False),
    ("arc-centre-absolute",
     "G21 G90 G90.1 G17\nG0 X10 Y0\nG3 X0 Y10 I0 J0 F500\n", {},
     [(2, 0, (10, 0, 0), (0, 0, 0), math.nan), (3, 3, (0, 10, 0), (0, 0, 0), 500.0)], True),
    ("zero-length-feed", "G21 G90\nG0 X1\nG1 F100\n", {},
     [(2, 0, (1, 0, 0), (0, 0, 0), math.nan), (3, 1, (1, 0, 0), (0, 0, 0), 100.0)], True),
    ("allowed-codes", "G21 G90 G64 P0.01\nM8\nG0 X1\nG4 P0.5\nM9\nM2\n",
     {"allow": ["G64", "M8", "M9", "G4"]},
     [(3, 0, (1, 0, 0), (0, 0, 0), math.nan)], True),
    ("passive-codes", "G0 G17 G40 G49 G80 G90\nG21 G94 G61\nM7\nM8\nG64 P0.01 Q0.001\n"
     "G1 X1 F100\nM1\nG4 P0.1\nM9\nG61.1\nM48\nG0 G80 X2\nM5 M9\n", {},
     [(1, 0, (0, 0, 0), (0, 0, 0), math.nan), (6, 1, (1, 0, 0), (0, 0, 0), 100.0),
      (12, 0, (2, 0, 0), (0, 0, 0), 100.0)], True),
    ("feed-per-revolution", "G21 S1000 M3\nG95 G1 X10 F0.1\nG94 G1 X0 F50\n", {},
     [(2, 1, (10, 0, 0), (0, 0, 0), 0.1), (3, 1, (0, 0, 0), (0, 0, 0), 50.0)], True),
    ("crlf-lines", "G21 G90\r\nG0 X1\r\nG1 Y2 F10\r\n", {},
     [(2, 0, (1, 0, 0), (0, 0, 0), math.nan), (3, 1, (1, 2, 0), (0, 0, 0), 10.0)], True),
]


def _check(prog, expected):
    assert len(prog) == len(expected)
    for blk, (line, motion, xyz, abc, feed) in zip(prog, expected):
        assert blk.line == line
        assert blk.motion == motion
        np.testing.assert_allclose(blk.end[:3], xyz, atol=1e-12)
        np.testing.assert_allclose(np.degrees(blk.end[3:]), abc, atol=1e-12)
        if math.isnan(feed):
            assert math.isnan(blk.feed)
        else:
            assert blk.feed == pytest.approx(feed, rel=1e-12)


@pytest.mark.parametrize("name,src,opts,expected,lcnc", CASES, ids=[c[0] for c in CASES])
def test_parse_table(name, src, opts, expected, lcnc):
    _check(parse_program(src, **opts), expected)


@pytest.mark.parametrize("name,src,opts,expected,lcnc", CASES, ids=[c[0] for c in CASES])
def test_rewrite_unchanged_is_identity(name, src, opts, expected, lcnc):
    prog = parse_program(src, **opts)
    out = rewrite_coordinates(prog, {})
    assert out == src if src.endswith(prog.newline) else src + prog.newline


@pytest.mark.parametrize("name,src,opts,expected,lcnc", CASES, ids=[c[0] for c in CASES])
def test_rewrite_round_trip(name, src, opts, expected, lcnc):
    """Move every block end by a few micrometres; reading back gives exactly those."""
    prog = parse_program(src, **opts)
    rng = np.random.default_rng(7)
    ends = {}
    for i in range(len(prog)):
        if prog.arc_index[i] >= 0 and "R" in prog[i].text.upper():
            continue  # an R arc keeps its radius; its ends stay (tested below)
        e = prog.end[i].copy()
        e[:3] += rng.uniform(-0.01, 0.01, 3)
        if prog.modals[prog.modal_index[i]].tcp == 2:
            e[3:] = prog.end[i, 3:]
        ends[i] = e
    centres = {i: prog.arc_centre[prog.arc_index[i]] for i in ends if prog.arc_index[i] >= 0}
    # arcs keep their centre; their radius changes by the moved ends, so move
    # their start and end the same way around it: only z is moved for arcs
    for i in centres:
        ends[i][:2] = prog.end[i, :2]
        ends[i][[0, 1, 2]] = prog.end[i, :3] + np.array([0, 0, 0.004])
        if i > 0:
            ends[i - 1] = ends.get(i - 1, prog.end[i - 1]).copy()
            ends[i - 1][:2] = prog.end[i - 1, :2]
    out = rewrite_coordinates(prog, ends, centres=centres)
    back = parse_program(out, **opts)
    target = prog.end.copy()
    for i, e in ends.items():
        target[i] = e
    units = back.modal_column("units")
    res = np.where(units == 20, 0.5e-4 * 25.4, 0.5e-3)
    assert np.all(np.abs(back.end[:, :3] - target[:, :3]) <= res[:, None] * 3 + 1e-9)
    # only coordinate words changed: the non-numeric skeleton of each line stays
    strip = str.maketrans("", "", "0123456789.-+ ")
    for a, b in zip(src.splitlines(), out.splitlines()):
        letters_a = "".join(ch for ch in a.translate(strip))
        letters_b = "".join(ch for ch in b.translate(strip))
        assert set(letters_b) >= set(letters_a)


@pytest.mark.parametrize("name,src,opts,expected,lcnc",
                         [c for c in CASES if c[4]], ids=[c[0] for c in CASES if c[4]])
def test_rs274_agrees(name, src, opts, expected, lcnc, rs274, tmp_path):
    path = tmp_path / f"{name}.ngc"
    if not any(end in src.upper() for end in ("M2", "M30", "%")):
        src += "M2\n"  # rs274 wants a program end; it adds no move
    path.write_text(src)
    prog = read_program(path, **opts)
    canon = run_rs274(path, block_delete=opts.get("block_delete", False))
    assert len(canon.kind) == len(prog)
    kinds = {0: "TRAVERSE", 1: "FEED", 2: "ARC", 3: "ARC"}
    assert [kinds[int(m)] for m in prog.motion] == list(canon.kind)
    assert np.all(np.abs(prog.end[:, :3] - canon.end[:, :3])
                  <= canon.resolution[:, None] + 1e-9)
    assert np.all(np.abs(np.degrees(prog.end[:, 3:]) - canon.end[:, 3:]) <= 0.5e-4 + 1e-9)
    arcs = np.flatnonzero(prog.arc_index >= 0)
    for i in arcs:
        k = prog.arc_index[i]
        c = canon.centre[i]
        sel = ~np.isnan(c)
        assert np.all(np.abs(prog.arc_centre[k][sel] - c[sel]) <= canon.resolution[i] + 1e-9)
        turns = math.ceil(abs(prog.arc_sweep[k]) / (2 * math.pi) - 1e-9)
        assert abs(canon.turns[i]) == turns


def test_arc_geometry():
    prog = parse_program(CASES[4][1])  # R arcs
    short, long_ = prog[1].arc, prog[2].arc
    np.testing.assert_allclose(short.centre[:2], (10, 0), atol=1e-12)
    assert short.sweep_rad == pytest.approx(-math.pi / 2)
    np.testing.assert_allclose(long_.centre[:2], (10, 0), atol=1e-12)
    assert long_.sweep_rad == pytest.approx(-1.5 * math.pi)
    prog = parse_program(CASES[5][1])  # full circle, helix with P2
    assert prog[1].arc.sweep_rad == pytest.approx(-2 * math.pi)
    assert prog[2].arc.sweep_rad == pytest.approx(4 * math.pi)
    assert prog[2].arc.turns == 2
    prog = parse_program(CASES[6][1])  # G18, G19
    assert prog[1].arc.plane == 18 and prog[1].arc.sweep_rad == pytest.approx(-math.pi)
    np.testing.assert_allclose(prog[1].arc.normal, (0, 1, 0))
    np.testing.assert_allclose(prog[1].arc.centre[[0, 2]], (5, 0), atol=1e-12)
    assert prog[2].arc.plane == 19 and prog[2].arc.sweep_rad == pytest.approx(math.pi)


def test_modal_state_carried():
    src = ("G21 G90 G17\nT3 M6\nS8000 M4\nG43 H3\nG55\nG0 X1\nG18 G91 G93 G1 X1 F2\n"
           "G49 G94 G90 G1 X0 F10\nM5\nG1 X5\nM30\n")
    prog = parse_program(src, work_offsets={"G55": (100, 0, -50, 0, 0, 90)})
    m0, m1, m2, m3 = (b.modal for b in prog)
    assert (m0.tool, m0.spindle_rpm, m0.spindle_dir, m0.length_offset, m0.wcs) == (
        3, 8000, -1, 3, 2)
    assert (m1.plane, m1.distance, m1.feed_mode) == (18, 91, 93)
    assert (m2.length_offset, m2.feed_mode, m2.distance) == (0, 94, 90)
    assert m3.spindle_dir == 0
    assert m0.wcs_code == "G55"
    # the switch to G55 does not move the tool: Z and C, not programmed, stay
    # where they were on the machine (LinuxCNC's rs274 prints 1, 0, 50, C-90)
    np.testing.assert_allclose(prog.end[0], [1, 0, 50, 0, 0, -math.pi / 2])
    np.testing.assert_allclose(prog.end_machine[0], [101, 0, 0, 0, 0, 0], atol=1e-12)


def test_tool_vector_normalized_and_modal():
    prog = parse_program(CASES[10][1])
    np.testing.assert_allclose(prog[0].tool_vector, (0, 0, 1))
    np.testing.assert_allclose(prog[1].tool_vector, (S2, 0, S2))
    assert prog[0].modal.tcp == 2 and prog[0].modal.length_offset == 2


def test_block_delete_off_runs_the_line():
    prog = parse_program(CASES[9][1])
    assert [b.line for b in prog] == [2, 3]
    assert parse_program(CASES[8][1]).number == "0012"


# --- bad input: (source, options, line, offending text or None, message part) ---
ERRORS = [
    ("G21\nG1 X1 F100\nG1 X2 X3\n", {}, 3, "X3", "appears twice"),
    ("G21\nG17 G1 X1 F100 Q5\n", {}, 2, "Q5", "unknown word Q"),
    ("G21\nG1 X1\n", {}, 2, None, "no feed"),
    ("G21 G1 X1 F100\nG2 X3.5 Y0 I1 J0\n", {}, 2, None, "differ"),
    ("G21 G0 X0 Y0\nG2 X10 Y0 R4 F100\n", {}, 2, "R4", "impossible arc"),
    ("G21\nG1 X1.2.3 F10\n", {}, 2, ".3", "unexpected character"),
    ("G21\nG1 XNAN F10\n", {}, 2, "XNAN", "expected a number after X"),
    ("G21\nG1 X123456789012 F10\n", {}, 2, "X123456789012", "out of range"),
    ("G21\nG12 X1\n", {}, 2, "G12", "unknown or unsupported code G12"),
    ("G21\nM8\n", {"strict": True}, 2, "M8", "allow"),
    ("G21\nG64 P0.01\n", {"strict": True}, 2, "G64", "without strict"),
    ("G21\nM13\n", {}, 2, "M13", "allow"),
    ("G21\nG5 X1 Y1 I1 J1 P1 Q1\n", {}, 2, "G5", "spline"),
    ("G21\nG5.1 X1 I1 J1\n", {}, 2, "G5.1", "spline"),
    ("G21 G95 G1 X1 F0.1\n", {}, 1, None, "no spindle speed"),
    ("G21\nG1 G0 X1 F1\n", {}, 2, "G0", "motion group"),
    ("G21\nG1 X#1 F10\n", {}, 2, "#", "parameters and expressions"),
    ("G21\nG1 X1 F100 (unclosed\n", {}, 2, "(", "not closed"),
    ("X1\n", {}, 1, "X1", "without a motion mode"),
    ("G93 G1 X1 F1\nG1 X2\n", {}, 2, None, "inverse-time"),
    ("G21\nG28 X0\n", {"strict": True}, 2, "G28", "return to home"),
    ("G21\nO100 SUB\n", {}, 2, None, None),
    ("G21 G1 X1 Y1 F100\nG2 X1 Y1 R1\n", {}, 2, "R1", "end point is its start"),
    ("G21 G17 G1 X1 F100\nG2 X3 I1 K1\n", {}, 2, "K1", "K word in a G17 arc"),
    ("G21 G1 X1 F100\nG1 X2 R3\n", {}, 2, "R3", "straight move"),
    ("G21 G43.5 H1\nG1 X1 A10 F100\n", {}, 2, "A10", "under G43.5"),
    ("G21\nG1 X1 F-5\n", {}, 2, "F-5", "negative feed"),
    ("G21\nG1 X1 F100 %\n", {}, 2, "%", "alone on its line"),
]


@pytest.mark.parametrize("src,opts,line,bad,fragment", ERRORS)
def test_errors_name_line_and_column(src, opts, line, bad, fragment):
    with pytest.raises(NCParseError) as info:
        parse_program(src, file="part.nc", **opts)
    err = info.value
    assert isinstance(err, ValueError)
    assert err.file == "part.nc" and err.line == line
    text = src.split("\n")[line - 1]
    assert err.text == text
    if bad is not None:
        assert err.column == text.index(bad) + 1, str(err)
    if fragment is not None:
        assert fragment in str(err)
    assert str(err).startswith(f"part.nc:{line}")
    assert "\n" not in str(err)  # one line; the source line and caret: err.excerpt()


def test_allow_list_is_explicit_and_refuses_motion_codes():
    src = "G21\nM8\nG0 X1\n"
    assert len(parse_program(src, allow=["M8"])) == 1
    with pytest.raises(ValueError, match="return to home"):
        parse_program(src, allow=["G28"])
    for code in ("G54.1", "G59.1", "G44", "G12", "G71", "G68.2", "M98"):
        with pytest.raises(ValueError, match="would misplace the tool"):
            parse_program(src, allow=[code])
    with pytest.raises(ValueError, match="not a G or M code"):
        parse_program(src, allow=["coolant"])
    # an allowed code's own words belong to it; elsewhere they are refused
    assert len(parse_program("G21 G64 P0.01\nG0 X1\n", allow=["G64"])) == 1
    with pytest.raises(NCParseError, match="P word"):
        parse_program("G21 P0.01\nG0 X1\n", allow=["G64"])


def test_read_program_names_the_file(tmp_path):
    path = tmp_path / "bad.nc"
    path.write_text("G21\nG1 X1 F10\nG1 Y2 Y3\n")
    with pytest.raises(NCParseError) as info:
        read_program(path)
    assert str(info.value).startswith(f"{path}:3:7:")
    bom = tmp_path / "bom.nc"
    bom.write_bytes(b"\xef\xbb\xbfG21 G0 X1\nG1 Y2 F10\n")  # a byte-order mark: not code
    assert read_program(bom).end[1, 1] == 2
    binary = tmp_path / "binary.nc"
    binary.write_bytes(b"G21\nG0 X1\nG1 \xff\n")
    with pytest.raises(NCParseError, match="non-text byte") as info:
        read_program(binary)
    assert info.value.line == 3 and info.value.column == 4


def test_after_program_end_nothing_is_read():
    prog = parse_program("G21 G0 X1\nM30\nthis is not read\n")
    assert len(prog) == 1


def test_work_offset_table_is_checked():
    with pytest.raises(ValueError, match="G54...G59"):
        parse_program("G0 X1\n", work_offsets={"G60": (0, 0, 0)})
    with pytest.raises(ValueError, match="finite"):
        parse_program("G0 X1\n", work_offsets={"G54": (0, math.nan, 0)})


# --- codes that do not move the tool: read without flags, counted -----------
POST_HEADER = """%
O1001 (HEADER OF A FANUC-STYLE POST)
G00 G17 G40 G49 G80 G90
G21 G94 G61
G05.1 Q1
G05 P10000
G08 P1
T5 M06
S12000 M03
M08
G04 X1.5
G04 P500
G00 G54 X10. Y5.
G43 H5 Z25. M08
G01 Z-1. F500.
M09
M01
G05.1 Q0
G64
M05
M30
%
"""


def test_post_header_codes_are_read_and_counted():
    prog = parse_program(POST_HEADER)
    # the safety line is a (zero-length) rapid, as LinuxCNC makes it; the
    # dwell's X (Fanuc: seconds) is not an axis word
    assert [b.line for b in prog] == [3, 13, 14, 15]
    np.testing.assert_allclose(prog.end[:, :3], [[0, 0, 0], [10, 5, 0], [10, 5, 25],
                                                 [10, 5, -1]])
    assert prog[1].modal.tool == 5 and prog[1].modal.spindle_rpm == 12000
    ignored = {code: (count, first) for code, count, first in prog.ignored}
    assert ignored == {"G61": (1, 4), "G5.1": (2, 5), "G5": (1, 6), "G8": (1, 7),
                       "M8": (2, 10), "G4": (2, 11), "M9": (1, 16), "G64": (1, 19)}
    assert [c for c, _, _ in prog.ignored] == ["G61", "G5.1", "G5", "G8", "M8", "G4",
                                                 "M9", "G64"]
    with pytest.raises(NCParseError, match="G61"):
        parse_program(POST_HEADER, strict=True)
    allow = ["G61", "G8", "M8", "G4", "M9", "G64"]
    with pytest.raises(NCParseError, match="read without strict to pass it over\\)"):
        parse_program(POST_HEADER, strict=True, allow=allow)
    no_fanuc = "\n".join(ln for ln in POST_HEADER.split("\n") if not ln.startswith("G05"))
    allowed = parse_program(no_fanuc, strict=True, allow=allow)
    np.testing.assert_array_equal(allowed.end, prog.end)


def test_g80_with_motion_code_in_one_block():
    prog = parse_program("G21\nG1 X1 F100\nG0 G80 X2\nG80 G1 X3\n")
    assert list(prog.motion) == [1, 0, 1]
    with pytest.raises(NCParseError, match="motion group"):
        parse_program("G21\nG0 G1 X1 F10\n")


def test_passed_over_codes_own_their_words():
    # G64 P Q, M66 P E L Q, M19 R: none is read as an arc or axis word
    prog = parse_program("G21 G0 X1\nG64 P0.01 Q0.005\nM66 P0 L0 Q1 E0\nM19 R90\n"
                         "G2 X3 I1 F100\n")
    assert prog[1].arc.turns == 1 and prog.end[1, 0] == 3
    # G4 in a motion block owns P only
    prog = parse_program("G21 G0 X1\nG4 P0.5 G1 X2 F10\n")
    assert prog.end[1, 0] == 2


def test_feed_per_revolution():
    prog = parse_program("G21 S1000 M3\nG95 G1 X10 F0.1\nG20 G1 X1 F0.01\n")
    assert prog[0].modal.feed_mode == 95 and prog.feed[0] == pytest.approx(0.1)
    assert prog.feed[1] == pytest.approx(0.254)
    from nc.path import block_minutes
    # 10 mm at 0.1 mm/rev and 1000 rev/min: 0.1 min
    assert block_minutes(prog)[0] == pytest.approx(0.1)


# --- program headers and numbers ---------------------------------------------
@pytest.mark.parametrize("header,number", [
    ("%_N_PART1_MPF\n;$PATH=/_N_MPF_DIR\n", None),
    ("%PM\n", None),
    ("%\nO1234 (PART NAME)\n", "1234"),
    ("%\n:1234\n", "1234"),
    (":0042 (FANUC ISO NUMBER)\n", "0042"),
    ("$PART1.MIN%\n", None),
])
def test_program_headers(header, number):
    prog = parse_program(header + "G21 G90\nG0 X1\nG1 Y2 F100\nM30\n%\n")
    assert prog.number == number
    assert len(prog) == 2 and prog.end[1, 1] == 2
    assert prog.line[0] == header.count("\n") + 2


@pytest.mark.parametrize("src,bad,fragment", [
    ("%_N_PART_MPF\nDEF REAL DEPTH=5\nG0 X1\n", "DEF", "Siemens Sinumerik syntax (DEF)"),
    ("G21\nR1=5\n", "R1", "Siemens Sinumerik assignments"),
    ("G21\nN10 CYCLE800(1,\"TC1\",0)\n", "N10", "Siemens Sinumerik syntax (CYCLE800)"),
    ("G21\nX=R1 Y=2\n", "X", "Siemens Sinumerik assignments"),
    ("0 BEGIN PGM PART MM\n", "0", "Heidenhain conversational"),
    ("%PART G71 *\nN10 G00 X+0 *\n", "%", "Heidenhain ISO"),
    ("G21\nG66 P9000 A1\n", "G66", "modal macro calls (G66/G66.1)"),
    ("G21\nG0 X#5420\n", "#", "parameters and expressions: system parameter #5420"),
])
def test_foreign_dialects_are_named(src, bad, fragment):
    with pytest.raises(NCParseError) as info:
        parse_program(src, file="p.nc")
    err = info.value
    assert fragment in err.message and "not supported" in err.message
    assert err.column == err.text.index(bad) + 1


@pytest.mark.parametrize("before, kind", [("G0", 0), ("G1", 1)])
def test_g80_alone_leaves_the_motion_mode_before_the_cycle(before, kind):
    """Fanuc's group 09: G80 cancels the cycle, the G0/G1 mode before it moves again
    (a public bolt-circle program moves right after G80 without a motion code)."""
    prog = parse_program(f"G21 G17 G90 G94\nS1000 M3\n{before} X0 Y0 Z5 F100\n"
                         "G98 G81 X10 Y0 Z-1 R1 F50\nG80\nX20 Y5\nM2\n")
    assert prog.motion[-1] == kind
    np.testing.assert_allclose(prog.end[-1][:3], [20.0, 5.0, 5.0])
    prog = parse_program(f"G21\n{before} G80 X1 F100\nG80\nX2\n")
    assert prog.motion[-1] == kind and prog.end[-1][0] == 2.0
