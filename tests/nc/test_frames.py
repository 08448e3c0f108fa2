"""Frame and reference codes (G10 L2/L20, G28/G30, G52, G53, G92...) against rs274.

Each program is read here and by LinuxCNC's rs274; every move's end must
agree within rs274's printed resolution. rs274's G28/G30 points are its
parameters 5161... and 5181..., zero when no variable file sets them, so the
reader is told the same points.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from nc import NCParseError, parse_program, read_program
from nc.linuxcnc import compare_with_rs274
from nc.path import cutter_locations
from nc.rewrite import RewriteError, rewrite_coordinates
from nc.summary import blocks_as_json, summarize

HOME = {"G28": (0, 0, 0), "G30": (0, 0, 0)}

PROGRAMS = {
    "safety-line-and-g28": "G00 G17 G40 G49 G80 G90\nG21\nG91 G28 Z0\nG90 G54 G0 X10 Y5\n"
                           "G0 Z20\nG1 Z-1 F200\nG91 G28 X0 Y0 Z0\nG90\nM30\n",
    "g92-family": "G21 G0 X1 Y2 Z3\nG92 X0 Y0\nG1 X1 F100\nG92.2\nG1 X1\nG92.3\nG1 X2\n"
                  "G92.1\nG1 X3\nM2\n",
    "g52-local-offset": "G21 G0 X1 Y2 Z3\nG52 X10\nG52 Y5\nG1 X0 F100\nG92 X0\nG1 X1\n"
                        "G52 Z1\nG1 X1\nG91 G28 X1 Z0\nG90 G52 X0 Y0 Z0\nG0 X1 Y1 Z1\nM2\n",
    "g28-g30-intermediate": "G21 G0 X5 Y5 Z5\nG28 X1\nG0 X2 Y3 Z4\nG30 Z0\nG28\n"
                            "G0 X1 Y1 Z1\nG53 G0 Z0\nG53 G1 X7 F100\nM2\n",
    "g10-work-offsets": "G21 G0 X1\nG10 L2 P1 X100\nG1 X0 F10\nG10 L20 P0 X5\nG1 X5\n"
                        "G10 L2 P2 X-20 Z10\nG55 G0 X0\nG1 Y3\nG91 G10 L20 P2 Y1\nG90 G1 Y2\n"
                        "G54 G0 X0 Y0\nG53 G0 X0\nG10 L1 P1 Z0.1\nM2\n",
    "g92-inch-rotary": "G20 G0 X1 A10\nG92 X0 A0\nG1 X1 A5 F10\nG92.1\nG1 X2\nM2\n",
    "g28.1-stores-the-point": "G21 G0 X5 Y6 Z7\nG28.1\nG0 X0 Y0 Z0\nG91 G28 Z1\nG90 G30.1\n"
                              "G0 X1 Y1 Z1\nG30\nM2\n",
    "g92-at-end-of-4-axis-job": "G21 G0 X0 A0\nG1 A360 F1000\nG1 A720\nG92 A0\nG1 A90 X1\n"
                                "M30\n",
}


@pytest.mark.parametrize("name", list(PROGRAMS))
def test_frames_agree_with_rs274(name, rs274, tmp_path):
    path = tmp_path / f"{name}.ngc"
    path.write_text(PROGRAMS[name])
    prog = read_program(path, reference_points=HOME)
    assert prog.known.all()
    result = compare_with_rs274(path, prog)
    assert result.ok and result.moves == len(prog), result.message


def test_g92_offsets_by_hand():
    prog = parse_program(PROGRAMS["g92-family"])
    # G92 X0 Y0 at (1, 2, 3): the next blocks read in a frame shifted by (1, 2)
    np.testing.assert_allclose(prog.end[:, :3], [[1, 2, 3], [1, 0, 3], [1, 2, 3],
                                                 [2, 0, 3], [3, 2, 3]])
    np.testing.assert_allclose(prog.end_machine[:, :3], [[1, 2, 3], [2, 2, 3], [1, 2, 3],
                                                         [3, 2, 3], [3, 2, 3]])
    # where the frame changed, the block starts where the tool is, in the new frame
    np.testing.assert_allclose(prog.start[1, :3], [0, 0, 3])
    np.testing.assert_allclose(prog.start[2, :3], [2, 2, 3])  # G92.2: machine frame
    assert list(prog.reframed) == [1, 2, 3, 4]
    from nc.path import block_lengths
    np.testing.assert_allclose(block_lengths(prog)[1:], [1, 1, 2, 0])


def test_four_axis_job_runs_past_g92_a0():
    prog = parse_program(PROGRAMS["g92-at-end-of-4-axis-job"])
    assert len(prog) == 4
    np.testing.assert_allclose(np.degrees(prog.end[:, 3]), [0, 360, 720, 90])
    np.testing.assert_allclose(np.degrees(prog.start[3, 3]), 0)  # A read 0 after G92
    np.testing.assert_allclose(np.degrees(prog.end_machine[3, 3]), 810)


def test_g28_without_reference_point_makes_position_unknown():
    prog = parse_program(PROGRAMS["safety-line-and-g28"])
    # rows: safety line, G28 (intermediate, reference), G0 X Y, G0 Z, G1 Z, G28 (2 rows)
    assert list(prog.line) == [1, 3, 3, 4, 5, 6, 7, 7]
    assert list(prog.machine_moves) == [2, 7]
    assert prog.known.tolist() == [True, True, False, False, False, True, True, False]
    assert math.isnan(prog.end[2, 2]) and prog.end[2, 0] == 0
    # known again: Z given absolutely at line 5 (X Y at line 4)
    np.testing.assert_allclose(prog.end[4, :3], [10, 5, 20])
    s = summarize(prog)
    assert s.unknown_blocks == 4 and s.unknown_first_line == 3
    assert s.cutting_length_mm == pytest.approx(21.0)
    np.testing.assert_allclose(s.bbox_max_mm, [10, 5, 20])  # the start of the G1 Z-1
    js = blocks_as_json(prog)
    assert js[2]["xyz_mm"][2] is None
    with pytest.raises(ValueError, match=r":3:\d+: position not known"):
        cutter_locations(prog)
    # the machine's point given: everything known; the G28 Z ends at machine Z0
    known = parse_program(PROGRAMS["safety-line-and-g28"],
                          reference_points={"G28": (0, 0, 50)},
                          work_offsets={"G54": (0, 0, 10)})
    assert known.known.all()
    np.testing.assert_allclose(known.end[2, :3], [0, 0, 40])
    cutter_locations(known)


def test_arc_at_unknown_position_is_refused():
    with pytest.raises(NCParseError, match="G28/G30 at line 2"):
        parse_program("G21 G0 X1\nG91 G28 Z0\nG90 G2 X0 Y1 I-1 F100\n")
    # after an absolute move in X Y Z the arc is fine
    prog = parse_program("G21 G0 X1\nG91 G28 Z0\nG90 G0 X1 Y0 Z1\nG2 X0 Y1 I-1 F100\n")
    # the move from the unknown Z is itself not known; the arc after it is
    assert prog.known.tolist() == [True, True, False, False, True]


def test_strict_refuses_frame_codes():
    for src in ("G21\nG92 X0\n", "G21\nG91 G28 Z0\n", "G21\nG53 G0 Z0\n",
                "G21\nG10 L2 P1 X0\n", "G21 S100 M3\nG95 G1 X1 F0.1\n"):
        with pytest.raises(NCParseError, match="without strict"):
            parse_program(src, strict=True)


@pytest.mark.parametrize("src,fragment", [
    ("G21\nG92\n", "expected axis words"),
    ("G21\nG92.1 X0\n", "expected none"),
    ("G21\nG10 L2 P7 X0\n", "G59.1"),
    ("G21\nG10 L2 P1 R45 X0\n", "rotation"),
    ("G21\nG10 L3 P1 X0\n", "L2 or L20"),
    ("G21\nG10 L2 P1\n", "axis words \\(or R0\\)"),
    ("G21\nG91 G53 G0 X0\n", "G53 needs"),
    ("G21\nG53 G2 X0 I1\n", "G53 needs"),
    ("G21\nG43.4 H1\nG28 Z0\n", "tool centre point"),
    ("G21\nG28 Z0 G92 X0\n", "two codes of the frame group"),
])
def test_frame_errors(src, fragment):
    with pytest.raises(NCParseError, match=fragment):
        parse_program(src)


def test_rewrite_refuses_programs_that_change_frame():
    prog = parse_program(PROGRAMS["g92-family"])
    with pytest.raises(RewriteError, match="G92"):
        rewrite_coordinates(prog, {0: prog.end[0]})


def test_g28_1_makes_the_point_known():
    prog = parse_program(PROGRAMS["g28.1-stores-the-point"])
    assert prog.known.all()
    np.testing.assert_allclose(prog.end[2:4, :3], [[0, 0, 1], [0, 0, 7]])  # G91 G28 Z1: via Z1
    np.testing.assert_allclose(prog.end[-1, :3], [0, 0, 7])  # G30: the point of G30.1


def test_check_command_uses_rs274s_reference_points(rs274, tmp_path, capsys):
    from nc.cli import main

    path = tmp_path / "g28.ngc"
    path.write_text(PROGRAMS["safety-line-and-g28"])
    assert main(["check", str(path)]) == 0
    assert "agrees" in capsys.readouterr().out


def _random_frame_program(rng: np.random.Generator) -> str:
    """Moves mixed with every frame code the reader models, in random order."""
    def xyz(k=3):
        axes = rng.choice(list("XYZ"), size=rng.integers(1, k + 1), replace=False)
        return " ".join(f"{a}{rng.uniform(-50, 50):.3f}" for a in sorted(axes))

    lines = ["G21 G90 G17 G94", "G0 X1 Y2 Z3 A0"]
    for _ in range(40):
        kind = rng.integers(0, 12)
        if kind <= 3:
            lines.append(f"G1 {xyz()} F500")
        elif kind == 4:
            lines.append(f"G0 {xyz()} A{rng.uniform(-90, 90):.3f}")
        elif kind == 5:
            lines.append(f"G92 {xyz(2)}" if rng.random() < 0.7 else
                         rng.choice(["G92.1", "G92.2", "G92.3"]))
        elif kind == 6:
            lines.append(f"G52 {xyz(2)}")
        elif kind == 7:
            lines.append(f"G10 L{rng.choice([2, 20])} P{rng.integers(0, 4)} {xyz(2)}")
        elif kind == 8:
            lines.append(f"G{rng.integers(54, 57)}")
        elif kind == 9:
            lines.append(f"G53 G0 {xyz(2)}")
        elif kind == 10:
            inc = rng.random() < 0.5
            lines.append(("G91 " if inc else "") + f"G{rng.choice([28, 30])} "
                         + (xyz(2) if rng.random() < 0.8 else "") + ("\nG90" if inc else ""))
        else:
            lines.append(f"G91 G1 {xyz()} F300\nG90")
    return "\n".join(lines) + "\nM2\n"


def test_random_frame_programs_agree_with_rs274(rs274, tmp_path):
    """40 random mixes of moves and frame codes, each read here and by rs274."""
    rng = np.random.default_rng(20261126)
    for k in range(40):
        path = tmp_path / f"random-{k}.ngc"
        path.write_text(_random_frame_program(rng))
        prog = read_program(path, reference_points=HOME)
        assert prog.known.all()
        result = compare_with_rs274(path, prog)
        assert result.ok and result.moves == len(prog), (result.message, path.read_text())
