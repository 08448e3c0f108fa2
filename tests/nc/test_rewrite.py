"""Rewriting coordinates keeps the program as it was written."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nc import parse_program
from nc.rewrite import RewriteError, rewrite_coordinates, write_rewritten

SRC = """%
O2001 (FINISH)
N10 G21 G90 G17 (mm)
N20 G0 X0. Y0. Z5.
N30 G1 Z-1. F200 ; plunge
N40 X10.5
N50 Y5.
N60 G3 X5.5 Y10. I-5. J0.
N70 G91 G1 X-1. Y-.5
N80 G90 X0 Y0
N90 M30
%
"""


def test_only_the_numbers_of_changed_words_change():
    prog = parse_program(SRC)
    out = rewrite_coordinates(prog, {2: [10.512, 0.0, -1.0]})
    old, new = SRC.splitlines(), out.splitlines()
    changed = [i for i, (a, b) in enumerate(zip(old, new)) if a != b]
    # N40 gets the new X; N50 keeps its X by gaining the word it used to inherit
    assert changed == [5, 6]
    assert new[5] == "N40 X10.512"
    assert new[6] == "N50 X10.500 Y5."
    back = parse_program(out)
    np.testing.assert_allclose(back.end[2:, :3], prog.end[2:, :3] + np.array(
        [[0.012, 0, 0]] + [[0, 0, 0]] * (len(prog) - 3)), atol=1e-9)


def test_words_added_to_a_lower_case_line_are_lower_case():
    """LinuxCNC's arcspiral.ngc is written in lower case: a word the rewrite adds takes
    the line's case (a mixed line is left upper case)."""
    src = SRC.replace("N50 Y5.", "n50 y5.").replace("N40 X10.5", "n40 x10.5")
    prog = parse_program(src)
    new = rewrite_coordinates(prog, {2: [10.512, 0.0, -1.0]}).splitlines()
    assert new[5] == "n40 x10.512" and new[6] == "n50 x10.500 y5."
    mixed = rewrite_coordinates(parse_program(src.replace("n50 y5.", "n50 Y5.")),
                                {2: [10.512, 0.0, -1.0]}).splitlines()
    assert mixed[6] == "n50 X10.500 Y5."


def test_incremental_successor_compensates():
    prog = parse_program(SRC)
    e = prog.end[4].copy()  # the arc end, before the G91 block
    e[:3] += (0.004, -0.003, 0.002)
    out = rewrite_coordinates(prog, {4: e}, centres={4: prog.arc_centre[0]})
    back = parse_program(out)
    np.testing.assert_allclose(back.end[4, :3], e[:3], atol=1e-9)
    np.testing.assert_allclose(back.end[5:, :3], prog.end[5:, :3], atol=1e-9)
    assert "N70 G91 G1 X-1.004 Y-.497 Z-0.002" in out


def test_moved_arc_start_keeps_centre_and_new_centre_is_written():
    src = "G21 G90 G17\nG0 X10 Y0\nG3 X0 Y10 I-10 J0 F100\nG2 X10 Y0 R10\nM2\n"
    prog = parse_program(src)
    out = rewrite_coordinates(prog, {0: [10.01, 0, 0]})
    back = parse_program(out)
    np.testing.assert_allclose(back.arc_centre[0], prog.arc_centre[0], atol=1e-9)
    assert "I-10.010" in out
    # a new centre for the R arc changes R
    c = np.array([0.002, 0.001, 0.0])
    with pytest.raises(RewriteError):
        # moving the centre while the ends stay breaks the equal-radius rule
        # only beyond tolerance; 2 mm does
        rewrite_coordinates(prog, {}, centres={1: [2.0, 0.0, 0.0]})
    out = rewrite_coordinates(prog, {}, centres={2: c})
    assert "G2 X10 Y0 R9.999" in out  # |start - new centre| = 9.9990002
    back = parse_program(out)
    np.testing.assert_allclose(back.end, prog.end, atol=1e-9)


def test_inch_program_rewritten_in_inch():
    src = "G20 G90\nG0 X1. Y1.\nG1 X2.5 F20.\nM2\n"
    prog = parse_program(src)
    e = prog.end[1].copy()
    e[0] += 0.0254  # one thousandth of an inch
    out = rewrite_coordinates(prog, {1: e})
    assert "X2.5010" in out
    np.testing.assert_allclose(parse_program(out).end[1, 0], 2.501 * 25.4, atol=1e-9)


def test_crlf_and_rotary_words():
    src = "G21 G90\r\nG1 X1 A10.5 F100\r\nG1 X2\r\nM2\r\n"
    prog = parse_program(src)
    e = prog.end[0].copy()
    e[3] = math.radians(10.25)
    out = rewrite_coordinates(prog, {0: e})
    # the next block inherited A10.5; it now says so
    assert out == "G21 G90\r\nG1 X1 A10.2500 F100\r\nG1 X2 A10.5000\r\nM2\r\n"


def test_bad_requests_are_refused():
    prog = parse_program(SRC)
    with pytest.raises(RewriteError, match="out of range"):
        rewrite_coordinates(prog, {99: [0, 0, 0]})
    with pytest.raises(RewriteError, match="finite"):
        rewrite_coordinates(prog, {1: [0, math.nan, 0]})
    with pytest.raises(RewriteError, match="not an arc"):
        rewrite_coordinates(prog, {}, centres={1: [0, 0, 0]})
    vec = parse_program("G21 G43.5 H1\nG1 X1 I0 J0 K1 F10\nM2\n")
    with pytest.raises(RewriteError, match="G43.5"):
        rewrite_coordinates(vec, {0: [1, 0, 0, 0.1, 0, 0]})


def test_write_is_atomic(tmp_path):
    prog = parse_program(SRC)
    out = tmp_path / "corrected.nc"
    out.write_text("old\n")
    with pytest.raises(RewriteError):
        write_rewritten(out, prog, {99: [0, 0, 0]})
    assert out.read_text() == "old\n"
    write_rewritten(out, prog, {2: [10.51, 0, -1]})
    assert "N40 X10.510" in out.read_text()
    assert [p.name for p in tmp_path.iterdir()] == ["corrected.nc"]


#: Splits of a straight block: (program, block, points, the block's lines written, the
#: pieces' ends read back). Absolute, incremental (the pieces written incrementally too),
#: inch (words in inch).
SPLITS = [
    ("G21 G90\nG0 X0 Y0 Z0\nG1 X10 F100\nX20\nM2\n", 1, [[2.5, 0, 0], [5.0, 0.001, 0]],
     ["G1 X2.500 F100", "G1 X5.000 Y0.001 Z0.000", "G1 X10.000 Y0.000 Z0.000", "X20"],
     [[2.5, 0, 0], [5.0, 0.001, 0], [10, 0, 0], [20, 0, 0]]),
    ("G21 G91\nG1 X10 F100\nX10\nM2\n", 0, [[4.0, 0, 0]],
     ["G1 X4.000 F100", "G1 X6.000 Y0.000 Z0.000", "X10"],
     [[4, 0, 0], [10, 0, 0], [20, 0, 0]]),
    ("G20 G90\nG1 X1. F10\nM2\n", 0, [[12.7, 0, 0]],
     ["G1 X0.5000 F10", "G1 X1.0000 Y0.0000 Z0.0000"],
     [[12.7, 0, 0], [25.4, 0, 0]]),
    ("g21 g90\ng0 x0 y0 z0\ng1 x10 f100\nm2\n", 1, [[2.5, 0, 0]],
     ["g1 x2.500 f100", "g1 x10.000 y0.000 z0.000", "m2"],
     [[2.5, 0, 0], [10, 0, 0]]),
]


@pytest.mark.parametrize("src,block,points,written,ends", SPLITS,
                         ids=["absolute", "incremental", "inch", "lower-case"])
def test_a_straight_block_is_split_into_g1_pieces(src, block, points, written, ends):
    prog = parse_program(src)
    out = rewrite_coordinates(prog, {}, splits={block: np.array(points, float)})
    lines = out.splitlines()
    first = int(prog.line[block]) - 1
    assert lines[first:first + len(written)] == written
    back = parse_program(out)
    assert len(back) == len(prog) + len(points)
    np.testing.assert_allclose(back.end[block:block + len(ends), :3], ends, atol=1e-6)


def test_only_straight_feed_blocks_split():
    prog = parse_program(SRC)
    with pytest.raises(RewriteError, match="not a straight feed"):
        rewrite_coordinates(prog, {}, splits={4: [[8.0, 8.0, -1.0]]})      # the G3
    with pytest.raises(RewriteError, match="not a straight feed"):
        rewrite_coordinates(prog, {}, splits={0: [[0.0, 0.0, 1.0]]})       # the G0


# A post's header comments may hold '#' and '[ ]' ("(Set units to inches [G21 for
# mm])", "(TOOL #3)"): the words are plain numbers and the program is rewritten.
COMMENTED = """(T1 D=6 CR=3 - ball end mill #1)
G21 G90 G17 (Set units to millimetres [G20 for inches])
G0 X0 Y0 Z5
G1 Z-0.5 F300 ; pass #1 [finish]
G1 X20 F1000
M30
"""


def test_hash_and_brackets_in_comments_do_not_stop_a_rewrite():
    prog = parse_program(COMMENTED)
    out = rewrite_coordinates(prog, {2: [20.0, 0.0, -0.502]})
    old, new = COMMENTED.splitlines(), out.splitlines()
    assert [i for i, (a, b) in enumerate(zip(old, new)) if a != b] == [4]
    assert new[4] == "G1 X20 Z-0.502 F1000"
    np.testing.assert_allclose(parse_program(out).end[2, :3], [20.0, 0.0, -0.502])


def test_a_parameter_outside_comments_is_refused_naming_its_line():
    from nc.rewrite import check_rewritable

    prog = parse_program(COMMENTED.replace("G1 X20 F1000", "#1=20\nG1 X#1 F1000"),
                         file="p.nc")
    with pytest.raises(RewriteError, match=r"^p\.nc:5: rewriting programs with '#'"):
        check_rewritable(prog)
    with pytest.raises(RewriteError, match="'#' parameters"):
        rewrite_coordinates(prog, {2: [20.0, 0.0, -0.502]})
