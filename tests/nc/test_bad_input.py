"""No crash on any input: the fuzzer, the limits on what expands, one-line errors.

Every bad program ends in an :class:`nc.errors.InputError` (the reader's
``NCParseError``) whose message is one line ``FILE:LINE:COLUMN: ...``; any
other exception is a bug. ``benchmarks/fuzz_gcode.py`` runs 10^5 mutated
programs; a short seeded run of it is a test here.
"""

from __future__ import annotations

import importlib.util
import math
import os
import sys
import tracemalloc

import numpy as np
import pytest

import nc.constants as K
from nc import NCParseError, parse_program, read_program
from nc.errors import InputError
from nc.path import cutter_locations, expand_arcs
from nc.summary import summarize

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")


def _fuzzer():
    """``benchmarks/fuzz_gcode.py`` as a module (the benchmarks are not a package)."""
    if "fuzz_gcode" not in sys.modules:
        spec = importlib.util.spec_from_file_location(
            "fuzz_gcode", os.path.join(ROOT, "benchmarks", "fuzz_gcode.py"))
        mod = importlib.util.module_from_spec(spec)
        sys.modules["fuzz_gcode"] = mod  # its dataclass looks itself up there
        spec.loader.exec_module(mod)
    return sys.modules["fuzz_gcode"]


def test_seeded_fuzz_run_has_no_crash(tmp_path):
    fuzz = _fuzzer()
    tally = fuzz.fuzz(2000, seed=19, workdir=str(tmp_path))
    assert tally.programs == 2000
    assert tally.crashed == 0, fuzz.report(tally, 0.0)
    assert tally.unclear == 0, fuzz.report(tally, 0.0)
    # the run reaches both ends: programs refused and programs read to the summary
    assert tally.refused > 200 and tally.read > 50, fuzz.report(tally, 0.0)
    assert tally.refused + tally.read == 2000


def test_fuzzer_counts_a_crash_as_a_crash(tmp_path, monkeypatch):
    """The tally is not vacuous: an exception that is not an InputError is a crash."""
    fuzz = _fuzzer()

    def broken(*args, **kwargs):
        raise ZeroDivisionError("planted")

    monkeypatch.setattr("nc.summary.block_lengths", broken)
    tally = fuzz.fuzz(300, seed=3, workdir=str(tmp_path))
    assert tally.crashed == tally.programs - tally.refused > 0
    assert any("ZeroDivisionError" in s and "planted" in s for s in tally.signatures)


# --- G and M codes of any length ------------------------------------------------

@pytest.mark.parametrize("word", ["M" + "9" * 400, "G" + "9" * 308, "G-" + "9" * 320,
                                  "G1" + "0" * 7, "M" + "9" * 30 + ".5"])
def test_huge_code_numbers_are_unknown_codes(word):
    src = f"G21\nG0 X1 {word} Y2\n"
    with pytest.raises(NCParseError, match="unknown or unsupported code") as info:
        parse_program(src, file="p.nc")
    err = info.value
    assert (err.line, err.column) == (2, src.split("\n")[1].index(word) + 1)
    assert "\n" not in str(err) and len(str(err)) < 200


def test_allow_refuses_a_huge_code_as_input():
    with pytest.raises(InputError, match="not a G or M code"):
        parse_program("G0 X1\n", allow=["G" + "9" * 400])


def test_digits_of_other_scripts_are_not_numbers():
    for src, col in (("G21 G1 X\u0663 F10\n", 8), ("G21 G1 X\uff11 F10\n", 8),
                     ("G21 G1\u00a0X1 F10\n", 7)):
        with pytest.raises(NCParseError) as info:
            parse_program(src)
        assert info.value.column == col


# --- limits on what expands -------------------------------------------------------

def test_arc_turns_limit():
    ok = parse_program(f"G21 G0 X5\nG2 I-5 P{K.MAX_ARC_TURNS} F100\n")
    assert ok.arc_sweep[0] == pytest.approx(-2 * math.pi * K.MAX_ARC_TURNS)
    for p in (K.MAX_ARC_TURNS + 1, 10_000_000, 0, 1.5):
        src = f"G21 G0 X5\nG2 I-5 P{p} F100\n"
        with pytest.raises(NCParseError, match="MAX_ARC_TURNS") as info:
            parse_program(src, file="p.nc")
        assert str(info.value).startswith(f"p.nc:2:{src.split(chr(10))[1].index('P') + 1}: ")


def test_the_reported_ten_million_turns_end_in_one_line_quickly():
    tracemalloc.start()
    try:
        with pytest.raises(NCParseError, match="whole number from 1 to"):
            summarize(parse_program("G2 X0 Y0 I1 P10000000 F1\n"))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1e6  # bytes: refused before anything is expanded


def test_arc_chords_limit_per_arc():
    # inch: a full circle of radius 10^7 in = 254 km needs ~1.1 million chords at 1 um
    prog = parse_program("G20 G0 X10000000\nG1 Y0 F1\nG2 I-10000000\n", file="big.nc")
    for expand in (summarize, expand_arcs, cutter_locations):
        tracemalloc.start()
        try:
            with pytest.raises(NCParseError, match="MAX_ARC_CHORDS") as info:
                expand(prog)
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        assert str(info.value).startswith("big.nc:3:4: arc of radius 2.54e+08 mm")
        assert peak < 1e6
    # a coarser tolerance makes the same arc acceptable
    pts, _ = expand_arcs(prog, chord_tol_mm=1.0)
    assert 10_000 < len(pts) < K.MAX_ARC_CHORDS


def test_arc_chords_limit_is_the_boundary(monkeypatch):
    prog = parse_program("G21 G0 X5\nG2 I-5 P10 F100\n")
    pts, _ = expand_arcs(prog)
    chords = len(pts) - 1  # one point for the rapid
    monkeypatch.setattr(K, "MAX_ARC_CHORDS", chords)
    assert len(expand_arcs(prog)[0]) == chords + 1
    monkeypatch.setattr(K, "MAX_ARC_CHORDS", chords - 1)
    with pytest.raises(NCParseError, match=f"needs {chords:,} chords"):
        expand_arcs(prog)


def test_path_points_limit(monkeypatch):
    src = "G21 G0 X5\n" + "G2 I-5 F100\n" * 10
    prog = parse_program(src, file="p.nc")
    per_circle = len(expand_arcs(prog)[0][1:]) // 10
    monkeypatch.setattr(K, "MAX_PATH_POINTS", 1 + 4 * per_circle)
    # the fifth circle passes the limit: its line (6) is named
    with pytest.raises(NCParseError, match="MAX_PATH_POINTS") as info:
        summarize(prog)
    assert str(info.value).startswith("p.nc:6:1: ")
    monkeypatch.setattr(K, "MAX_PATH_POINTS", 1 + 10 * per_circle)
    assert len(expand_arcs(prog)[0]) == 1 + 10 * per_circle


def test_expansion_is_unchanged_by_the_limits():
    """The in-place interpolation gives the same points as the plain formula."""
    prog = parse_program("G21 G0 X5 A10\nG3 X-5 Y0 Z-2 I-5 P3 F100\nG1 X1 Y2 Z3 A20\n")
    pts, block = expand_arcs(prog)
    t = np.concatenate([[1.0], np.arange(1, np.sum(block == 1) + 1) / np.sum(block == 1),
                        [1.0]])
    plain = prog.start[block] + t[:, None] * (prog.end[block] - prog.start[block])
    lines = block != 1
    np.testing.assert_array_equal(pts[lines], plain[lines])
    np.testing.assert_array_equal(pts[block == 1, 2], plain[block == 1, 2])


def test_tiny_feeds_are_refused():
    assert parse_program(f"G21 G1 X1 F{K.MIN_FEED:f}\n").feed[0] == K.MIN_FEED
    for f in ("0.0000001", "0." + "0" * 315 + "1"):
        for mode in ("G94", "G93"):
            src = f"G21 {mode} G1 X100 A5 F{f}\n"
            with pytest.raises(NCParseError, match="MIN_FEED|expected F0 or F >=") as info:
                parse_program(src)
            assert info.value.column == src.index("F") + 1


# --- one-line errors ----------------------------------------------------------------

def test_parse_error_is_one_line_and_excerpt_shows_the_caret(tmp_path):
    path = tmp_path / "bad.nc"
    path.write_text("G21\nG1 X1\tY2 Y3 F10\n")
    with pytest.raises(NCParseError) as info:
        read_program(path)
    err = info.value
    assert str(err) == (f"{path}:2:10: word Y appears twice in one block; "
                        "expected each word at most once")
    assert err.text == "G1 X1\tY2 Y3 F10" and err.column == 10
    lines = err.excerpt().split("\n")
    assert lines == [str(err), "    G1 X1 Y2 Y3 F10", "    " + " " * 9 + "^"]


def test_long_and_control_characters_stay_on_one_line():
    src = "G21\nG1 X1 F10 Y" + "9" * 300 + "\n"
    with pytest.raises(NCParseError) as info:
        parse_program(src, file="a\nb.nc")
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith("a\\nb.nc:2:11: Y99999999...(300 digits) is "
                                              "out of range")
    assert len(msg) <= K.ERROR_MAX_CHARS
    ex = info.value.excerpt().split("\n")
    assert len(ex) == 3 and len(ex[1]) <= 4 + K.ERROR_EXCERPT_CHARS
    # the caret is under the Y in the shown part of the line
    assert ex[1][ex[2].index("^")] == "Y"


# --- cutter locations: the program and the machine do not fit ---------------------------

@pytest.mark.parametrize("src,machine,where,part", [
    ("G21 G43.5 H1\nG0 X0\nG1 X1 F100\n", None, "p.nc:2:4: ", "before any tool vector"),
    ("G21 G0 X0\nG1 X1 F100\nG1 A10\n", None, "p.nc:3:4: ", "a machine is needed"),
    ("G21 G0 X0\nG1 X1 F100\nG1 B10\n", "xyzac-trt", "p.nc:3:4: ",
     "moves B, which machine xyzac-trt does not have"),
    ("G21 G0 X1\nG1 A10 F100\nG1 A20\n", "xyzac-trt", "p.nc:2:1: ",
     "no cutting move moves the tool tip"),
])
def test_cutter_locations_refuse_a_program_naming_its_line(src, machine, where, part):
    from nc.kinematics import get_machine

    prog = parse_program(src, file="p.nc")
    with pytest.raises(NCParseError) as info:
        cutter_locations(prog, None if machine is None else get_machine(machine))
    assert str(info.value).startswith(where) and part in str(info.value)
