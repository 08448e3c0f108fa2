"""Canned drilling cycles (nc.cycles): hand-checked moves, rs274 on random programs,
refusals, the summary and errpred's refusal."""

from __future__ import annotations

import random

import numpy as np
import pytest

from nc import NCParseError, parse_program
from nc.cycles import refuse_drilling
from nc.linuxcnc import compare_with_rs274, rs274_path
from nc.summary import blocks_as_json, summarize

HEAD = "G21 G17 G90 G94\nT1 M6\nS1000 M3\nF100\nG0 X0 Y0 Z10\n"
NO_RS274 = "LinuxCNC's rs274 is not installed (Debian package linuxcnc-uspace)"

#: source (after HEAD) -> the cycle's moves (motion, x, y, z), worked out by hand
#: from LinuxCNC's documented cycle (initial level Z10 from HEAD)
KNOWN = [
    # G98: rapid to X Y at the current Z, down to R, feed to Z, rapid to the initial level
    ("G98 G81 X10 Y5 Z-5 R2", [(0, 10, 5, 10), (0, 10, 5, 2), (1, 10, 5, -5), (0, 10, 5, 10)]),
    # G99: back to R; the modal repeat starts at R (a zero-length rapid, as LinuxCNC)
    ("G99 G81 X10 Y5 Z-5 R2\nX20",
     [(0, 10, 5, 10), (0, 10, 5, 2), (1, 10, 5, -5), (0, 10, 5, 2),
      (0, 20, 5, 2), (1, 20, 5, -5), (0, 20, 5, 2)]),
    # G83 Q2 from R1 to Z-4: pecks to -1, -3, rapid out to R, back to 0.254 above
    ("G99 G83 X0 Y0 Z-4 R1 Q2",
     [(0, 0, 0, 10), (0, 0, 0, 1), (1, 0, 0, -1), (0, 0, 0, 1), (0, 0, 0, -0.746),
      (1, 0, 0, -3), (0, 0, 0, 1), (0, 0, 0, -2.746), (1, 0, 0, -4), (0, 0, 0, 1)]),
    # G73: back off 0.254 after each peck, out to the initial level at the end
    ("G98 G73 X0 Y0 Z-3 R1 Q2",
     [(0, 0, 0, 10), (0, 0, 0, 1), (1, 0, 0, -1), (0, 0, 0, -0.746), (1, 0, 0, -3),
      (0, 0, 0, 10)]),
    # G85: feed in, feed out to R, rapid to the clearance level
    ("G98 G85 X1 Y1 Z-2 R1", [(0, 1, 1, 10), (0, 1, 1, 1), (1, 1, 1, -2), (1, 1, 1, 1),
                               (0, 1, 1, 10)]),
    # G89: feed in, dwell, feed out to the clearance level
    ("G99 G89 X1 Y1 Z-2 R1 P0.5", [(0, 1, 1, 10), (0, 1, 1, 1), (1, 1, 1, -2),
                                    (1, 1, 1, 1)]),
    # G91 with L3: X steps of 5 from X0; R from the initial level (10-8=2), Z from R
    ("G91 G98 G81 X5 Y0 Z-4 R-8 L3",
     [(0, 5, 0, 10), (0, 5, 0, 2), (1, 5, 0, -2), (0, 5, 0, 10),
      (0, 10, 0, 10), (0, 10, 0, 2), (1, 10, 0, -2), (0, 10, 0, 10),
      (0, 15, 0, 10), (0, 15, 0, 2), (1, 15, 0, -2), (0, 15, 0, 10)]),
    # Fanuc's K repeats as L
    ("G90 G99 G81 X3 Y0 Z-1 R1 K2",
     [(0, 3, 0, 10), (0, 3, 0, 1), (1, 3, 0, -1), (0, 3, 0, 1),
      (0, 3, 0, 1), (1, 3, 0, -1), (0, 3, 0, 1)]),
    # G87 back boring: off the axis by I J, down at rapid, feed up to K and back
    ("G98 G87 X4 Y0 Z-6 R1 I1 J0 K-3",
     [(0, 4, 0, 10), (0, 4, 0, 1), (0, 5, 0, 1), (0, 5, 0, -6), (0, 4, 0, -6),
      (1, 4, 0, -3), (1, 4, 0, -6), (0, 5, 0, -6), (0, 5, 0, 10), (0, 4, 0, 10)]),
    # G18: the normal is Y. Y0 is below R1: first a rapid up Y to 1 (which is now
    # the initial level); then to Z2 X3 at Y1, feed to Y-4, back to Y1
    ("G18 G98 G81 Z2 X3 Y-4 R1",
     [(0, 0, 1, 10), (0, 3, 1, 2), (1, 3, -4, 2), (0, 3, 1, 2)]),
    # any other motion code ends the cycle: the G0 is a plain rapid
    ("G98 G81 X1 Y0 Z-1 R1\nG0 X9", [(0, 1, 0, 10), (0, 1, 0, 1), (1, 1, 0, -1),
                                      (0, 1, 0, 10), (0, 9, 0, 10)]),
]

def _moves(text: str):
    prog = parse_program(HEAD + text + "\nG80\nM2\n")
    return prog, [(int(m), *np.round(e[:3], 9)) for m, e in zip(prog.motion[1:], prog.end[1:])]


@pytest.mark.parametrize("source,expected", KNOWN, ids=[k[0].split("\n")[0] for k in KNOWN])
def test_known_cycle_moves(source, expected):
    prog, got = _moves(source)
    assert got == [tuple(float(v) for v in e) for e in expected]
    cycle_rows = [i - 1 for i in prog.drilling]
    assert cycle_rows == list(range(len(cycle_rows)))
    # feeds at the programmed F, rapids flagged
    assert np.all(prog.feed[1:] == 100.0)


@pytest.mark.skipif(rs274_path() is None, reason=NO_RS274)
@pytest.mark.parametrize("source,expected", KNOWN, ids=[k[0].split("\n")[0] for k in KNOWN])
def test_known_cycle_moves_agree_with_rs274(source, expected, tmp_path):
    path = tmp_path / "c.ngc"
    # LinuxCNC repeats with L only (Fanuc's K is read as L here)
    path.write_text(HEAD + source.replace(" K2", " L2") + "\nG80\nM2\n")
    cmp = compare_with_rs274(path, parse_program(path.read_text(), file=str(path)))
    assert cmp.ok, cmp.message


def _random_program(seed: int) -> str:
    """Cycles in every plane, unit, distance mode and return level, with repeats."""
    rng = random.Random(seed)
    units = rng.choice([20, 21])
    s = 1.0 if units == 21 else 1 / 25.4
    plane = rng.choice([17, 17, 18, 19])
    a, b, c = {17: "XYZ", 18: "ZXY", 19: "YZX"}[plane]
    out = [f"G{units} G{plane} G90 G94", "T1 M6", "S1000 M3", f"F{rng.uniform(50, 500):.1f}",
           f"G0 X{rng.uniform(-5, 5) * s:.4f} Y{rng.uniform(-5, 5) * s:.4f} "
           f"Z{rng.uniform(-5, 15) * s:.4f}"]
    # rs274 moves G74/G84 along permuted axes in G18/G19 (its tapping
    # cycle's own bug): tapping is compared in G17 only
    codes = [73, 81, 82, 83, 85, 86, 89] + ([87, 84] if plane == 17 else [])
    for _ in range(rng.randint(1, 6)):
        code = rng.choice(codes)
        inc = rng.random() < 0.3
        words = [f"G{rng.choice([98, 99])}", "G91" if inc else "G90", f"G{code}",
                 f"{a}{rng.uniform(-10, 10) * s:.4f}", f"{b}{rng.uniform(-10, 10) * s:.4f}"]
        r = rng.uniform(-3, 3) * s if inc else rng.uniform(0, 4) * s
        z = -rng.uniform(0.5, 8) * s if inc else r - rng.uniform(0.5, 8) * s
        words += [f"R{r:.4f}", f"{c}{z:.4f}"]
        if code in (73, 83):
            words.append(f"Q{rng.uniform(0.3, 3) * s:.4f}")
        if code in (82, 86, 89):
            words.append(f"P{rng.uniform(0, 1):.2f}")
        if code == 87:
            top = rng.uniform(0.1, 2) * s + (0 if inc else z)
            words += [f"I{rng.uniform(-2, 2) * s:.4f}", f"J{rng.uniform(-2, 2) * s:.4f}",
                      f"K{top:.4f}"]
        if rng.random() < 0.4:
            words.append(f"L{rng.randint(1, 3)}")
        out.append(" ".join(words))
        for _ in range(rng.randint(0, 2)):  # modal repeats
            out.append(f"{a}{rng.uniform(-10, 10) * s:.4f}")
        if rng.random() < 0.3:
            out.append(rng.choice(["G80", f"G0 {c}{rng.uniform(0, 10) * s:.4f}",
                                   f"G1 {a}{rng.uniform(-5, 5) * s:.4f}"]))
    return "\n".join(out + ["G80", "M2"]) + "\n"


@pytest.mark.skipif(rs274_path() is None, reason=NO_RS274)
@pytest.mark.parametrize("seed", range(40))
def test_random_cycles_agree_with_rs274(seed, tmp_path):
    path = tmp_path / f"r{seed}.ngc"
    path.write_text(_random_program(seed))
    prog = parse_program(path.read_text(), file=str(path))
    cmp = compare_with_rs274(path, prog)
    assert cmp.ok, cmp.message
    assert len(prog.drilling) > 0


@pytest.mark.parametrize("source,where,words", [
    ("G81 X1 Y1 R1", "6:1", "Z missing"),
    ("G81 X1 Y1 Z-1", "6:1", "R missing"),
    ("G83 X1 Z-3 R1", "6:1", "Q missing"),
    ("G83 X1 Z-3 R1 Q0", "6:15", "peck depth Q > 0"),
    ("G82 X1 Z-3 R1", "6:1", "P missing"),
    ("G81 X1 Z3 R1", "6:11", "below the bottom"),
    ("G81 X1 A5 Z-1 R1", "6:8", "rotary axes"),
    ("G81 X1 Z-1 R1 L0", "6:15", "whole number >= 1"),
    ("G81 X1 Z-1 R1 L2.5", "6:15", "whole number >= 1"),
    ("G81 X1 Z-1 R1 Q1", "6:15", "Q only in G73 and G83"),
    ("G80 G81 X1 Z-1 R1", "6:1", "G80 with a canned cycle"),
    ("G87 X1 Z-3 R1 I1 J0", "6:1", "K missing"),
    ("G83 X1 Z-1000 R1 Q0.001", "6:18", "at most 100000"),
    ("G88 X1 Z-1 R1 P1", "6:1", "retracted by hand"),
    ("G76 X1 Z-1 R1", "6:1", "fine-boring or threading"),
    ("M5\nG84 X1 Z-1 R1", "7:1", "spindle turning clockwise"),
    ("G93 G81 X1 Z-1 R1 F10", "6:1", "inverse-time"),
])
def test_bad_cycles_one_line_with_place(source, where, words):
    with pytest.raises(NCParseError) as exc:
        parse_program(HEAD + source + "\n", file="p.nc")
    msg = str(exc.value)
    assert msg.startswith(f"p.nc:{where}: "), msg
    assert words in msg and "\n" not in msg


def test_cycle_moves_of_a_program_are_bounded(monkeypatch):
    import nc.constants as K

    # checked before a block expands, against a bound of its moves (here 9; it makes 4)
    monkeypatch.setattr(K, "MAX_CYCLE_MOVES_PROGRAM", 12)
    assert len(parse_program(HEAD + "G98 G81 X1 Z-1 R1\nG80\n").drilling) == 4
    with pytest.raises(NCParseError, match=r"^b\.nc:7:1: canned cycles would make more "
                       "than 12"):
        parse_program(HEAD + "G98 G81 X1 Z-1 R1\nX2\nG80\n", file="b.nc")


def test_strict_refuses_cycles_and_allow_cannot_pass_them():
    with pytest.raises(NCParseError, match="canned cycle; read without strict"):
        parse_program(HEAD + "G81 X1 Z-1 R1\n", strict=True)
    with pytest.raises(ValueError, match="canned cycle"):
        parse_program(HEAD, allow=["G81"])


def test_summary_counts_drilling_apart_from_milling():
    prog = parse_program(HEAD + "G1 X10 F100\nG98 G81 X20 Y0 Z-5 R2 F50\nG80\nG0 Z20\nM2\n")
    s = summarize(prog)
    assert s.drilling_blocks == 4
    assert s.rapid_blocks == 2 and s.linear_blocks == 1
    assert s.motion_blocks == s.rapid_blocks + s.linear_blocks + s.arc_blocks + 4
    assert s.cutting_length_mm == pytest.approx(10.0)
    assert s.drilling_length_mm == pytest.approx(7.0)  # R2 to Z-5 at feed
    assert s.drilling_time_min == pytest.approx(7.0 / 50)
    assert s.cutting_time_min == pytest.approx(10.0 / 100)
    # rapids: Z10 of HEAD, X10->X20 at Z10, down to R2, from Z-5 up to 10, G0 Z20
    assert s.rapid_length_mm == pytest.approx(10 + 10 + 8 + 15 + 10)
    rows = blocks_as_json(prog)
    assert [r.get("drilling", False) for r in rows] == [False, False] + [True] * 4 + [False]


def test_prediction_refuses_drilling_programs():
    prog = parse_program(HEAD + "G98 G81 X20 Y0 Z-5 R2\nG80\nM2\n", file="d.nc")
    with pytest.raises(NCParseError, match=r"^d\.nc:6:1: canned drilling cycle .* models "
                       "milling only"):
        refuse_drilling(prog, "the error prediction")
    refuse_drilling(parse_program(HEAD + "G1 X1\nM2\n"), "the error prediction")  # milling: ok

