"""``python -m nc``: called with argument lists, as a user would type them."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from nc import read_program
from nc.cli import main

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")
BLADE = os.path.join(ROOT, "nc", "data", "blade_cl.csv")


def test_parse_summary(tmp_path, capsys):
    path = tmp_path / "p.nc"
    path.write_text("G21 G90\nG0 X0 Y0 Z5\nG1 Z0 F100\nG1 X30 Y40\nM30\n")
    assert main(["parse", str(path)]) == 0
    out = capsys.readouterr().out
    assert "3 (2 rapid" not in out
    assert "3 (1 rapid, 2 linear, 0 arc)" in out
    assert "55.000 mm" in out  # 5 + 50
    assert "0.55 min" in out


def test_parse_json_has_every_block_in_mm_and_degrees(tmp_path, capsys):
    path = tmp_path / "p.nc"
    path.write_text("G20 G90 G93\nG1 X1 A90 F2\nG94 G0 Y2\nM30\n")
    assert main(["parse", str(path), "--json"]) == 0
    blocks = json.loads(capsys.readouterr().out)
    assert blocks == [
        {"line": 2, "motion": "G1", "xyz_mm": [25.4, 0.0, 0.0], "abc_deg": [90.0, 0.0, 0.0],
         "feed": 2.0, "feed_mode": "G93"},
        {"line": 3, "motion": "G0", "xyz_mm": [25.4, 50.8, 0.0], "abc_deg": [90.0, 0.0, 0.0],
         "feed": None, "feed_mode": "G94"},
    ]


def test_parse_error_is_one_clear_line(tmp_path, capsys):
    path = tmp_path / "bad.nc"
    path.write_text("G21\nG1 X1 Y2 Y3 F10\n")
    assert main(["parse", str(path)]) == 2
    err = capsys.readouterr().err
    assert err == (f"error: {path}:2:10: word Y appears twice in one block; expected each "
                   "word at most once\n")
    assert main(["parse", str(tmp_path / "missing.nc")]) == 2
    assert "No such file" in capsys.readouterr().err


#: Bad programs for ``parse`` and ``check``: (text, line, column, message part).
BAD_PROGRAMS = [
    ("G21\nG1 X1 Y2 Y3 F10\n", 2, 10, "appears twice"),
    ("G21 G0 X1 M" + "9" * 400 + "\n", 1, 11, "unknown or unsupported code M99999999..."),
    ("G21 G0 X1\nG2 X1 Y0 I-1 P10000000 F100\n", 2, 14, "MAX_ARC_TURNS"),
    ("G20 G0 X10000000\nG2 I-10000000 F1\n", 2, 4, "MAX_ARC_CHORDS"),
    ("G21\nG1 X1 F0.0000001\n", 2, 7, "expected F0 or F >="),
    ("G21\nG1 X1 (open\n", 2, 7, "comment not closed"),
]


@pytest.mark.parametrize("argv,src,line,col,part", [
    (argv, *case) for argv in (["parse"], ["parse", "--json"], ["check"]) for case in BAD_PROGRAMS
    # only the summary expands arcs into chords
    if case[3] != "MAX_ARC_CHORDS" or argv == ["parse"]])
def test_bad_programs_end_in_one_line_and_exit_2(tmp_path, capsys, argv, src, line, col,
                                                 part):
    path = tmp_path / "bad.nc"
    path.write_text(src)
    assert main([*argv, str(path)]) == 2
    captured = capsys.readouterr()
    assert captured.err.startswith(f"error: {path}:{line}:{col}: ")
    assert part in captured.err
    assert captured.err.count("\n") == 1 and captured.err.endswith("\n")
    assert captured.out == ""


def test_bad_program_one_line_from_the_shell(tmp_path):
    """``python -m nc parse`` as a process: stderr is the one line, exit status 2."""
    path = tmp_path / "bad.nc"
    path.write_text("G21 G0 X1\nG2 X1 Y0 I-1 P10000000 F100\n")
    for cmd in ("parse", "check"):
        proc = subprocess.run([sys.executable, "-m", "nc", cmd, str(path)],
                              capture_output=True, text=True, cwd=ROOT)
        assert proc.returncode == 2
        assert proc.stderr.count("\n") == 1 and proc.stdout == ""
        assert proc.stderr.startswith(f"error: {path}:2:14: expected P (arc turns)")


def test_allow_option(tmp_path, capsys):
    path = tmp_path / "p.nc"
    path.write_text("G21 G64 P0.01\nM8\nG0 X1\nM8\nM30\n")
    assert main(["parse", str(path), "--strict"]) == 2
    assert "--allow G64" in capsys.readouterr().err
    assert main(["parse", str(path), "--strict", "--allow", "G64,M8"]) == 0
    capsys.readouterr()
    # without --strict they are passed over, and the summary says which
    assert main(["parse", str(path)]) == 0
    out = capsys.readouterr().out
    assert "passed over" in out and "G64 x1 (line 1)" in out and "M8 x2 (line 2)" in out


def test_main_program_m99_is_shown_as_its_end(tmp_path, capsys):
    path = tmp_path / "p.nc"
    path.write_text("G21 G90\nG0 X1\nG1 X3 F100\nM99\n")
    assert main(["parse", str(path), "--json"]) == 0
    assert [b["line"] for b in json.loads(capsys.readouterr().out)] == [2, 3]
    assert main(["parse", str(path)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "program end" in out and "M99 in the main program at line 4" in out
    assert main(["parse", str(path), "--strict"]) == 2
    err = capsys.readouterr().err
    assert f"{path}:4:1:" in err and "M99 in the main program" in err


def test_offsets_file(tmp_path, capsys):
    path = tmp_path / "p.nc"
    path.write_text("G21 G55\nG0 X1\nM30\n")
    offsets = tmp_path / "offsets.toml"
    offsets.write_text("[G55]\nxyz_mm = [100.0, 0.0, -50.0]\n")
    assert main(["parse", str(path), "--offsets", str(offsets)]) == 0
    bad = tmp_path / "bad.toml"
    bad.write_text("[G55]\nxyz = [1, 2, 3]\n")
    assert main(["parse", str(path), "--offsets", str(bad)]) == 2
    assert "xyz_mm" in capsys.readouterr().err


@pytest.mark.parametrize("dialect", ["linuxcnc", "fanuc-g43.4", "fanuc-g43.5"])
def test_post_bundled_blade(tmp_path, capsys, dialect, lcnc_agrees):
    out = tmp_path / "blade.nc"
    assert main(["post", BLADE, "--machine", "xyzac-trt", "--dialect", dialect,
                 "-o", str(out), "--summary"]) == 0
    text = capsys.readouterr().out
    assert f"wrote {out}: 1458 cutter locations" in text
    assert "motion blocks" in text
    prog = read_program(out)
    assert len(prog) >= 1458
    if dialect == "linuxcnc":
        lcnc_agrees(out)


def test_post_errors_leave_no_file(tmp_path, capsys):
    out = tmp_path / "blade.ngc"
    assert main(["post", BLADE, "--machine", "no-such-machine", "-o", str(out)]) == 2
    assert "unknown machine" in capsys.readouterr().err
    machine = tmp_path / "narrow.toml"
    machine.write_text('kind = "xyzac-trt"\n[tilt]\nmin_deg = -20.0\nmax_deg = 20.0\n')
    assert main(["post", BLADE, "--machine", str(machine), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "error: point" in err and "limit" in err
    assert not out.exists() and os.listdir(tmp_path) == ["narrow.toml"]


def test_check_against_rs274(tmp_path, capsys, rs274):
    out = tmp_path / "blade.ngc"
    assert main(["post", BLADE, "--machine", "xyzbc-trt", "-o", str(out)]) == 0
    capsys.readouterr()
    assert main(["check", str(out)]) == 0
    assert "rs274 agrees" in capsys.readouterr().out


def test_module_runs_as_a_program(tmp_path, lcnc_agrees):
    out = tmp_path / "b.ngc"
    proc = subprocess.run([sys.executable, "-m", "nc", "post", BLADE, "--machine",
                           "xyzbc-head-table", "--tool-length", "90", "-o", str(out)],
                          capture_output=True, text=True, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    prog = read_program(out)
    assert np.isfinite(prog.end).all()
    lcnc_agrees(out)


def test_check_takes_relative_paths_and_reports_refusals(tmp_path, capsys, rs274,
                                                         monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["post", BLADE, "--machine", "xyzbc-trt", "-o", "blade.ngc"]) == 0
    capsys.readouterr()
    assert main(["check", "blade.ngc"]) == 0
    assert "rs274 agrees" in capsys.readouterr().out
    (tmp_path / "bad.ngc").write_text("G1 X1 F100\nG2 X2 Y0\nM2\n")
    assert main(["check", "bad.ngc"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: bad.ngc:2:") and err.count("\n") == 1


@pytest.mark.parametrize("toml,part", [
    ("[G55]\nxyz_mm = 5\n", "G55.xyz_mm: expected a non-empty array of numbers, got an integer"),
    ("[G55]\nxyz_mm = [1, 2]\n", "G55.xyz_mm: expected 3 numbers, got 2"),
    ('[G55]\nxyz_mm = [1, "a", 3]\n', "G55.xyz_mm[1]: expected a number"),
    ("[G55]\nxyz_mm = [1, nan, 3]\n", "G55.xyz_mm[1]: expected a finite number"),
    ("[G55]\nxyz_mm = [1, 2, 3]\nabc_deg = true\n", "G55.abc_deg: expected a non-empty array"),
    ("[G55]\nabc_deg = [1, 2, 3]\n", "G55.xyz_mm: missing"),
    ("[G55]\nxyz_mm = [1, 2, 3]\nabc = [1, 2, 3]\n", "G55.abc: unknown key"),
    ("[G60]\nxyz_mm = [1, 2, 3]\n", "G60: expected tables [G54] ... [G59], [G28], [G30]"),
    ("[G55\n", "not valid TOML"),
])
def test_bad_offsets_file_ends_in_one_line(tmp_path, capsys, toml, part):
    path = tmp_path / "p.nc"
    path.write_text("G21 G55\nG0 X1\nM30\n")
    offsets = tmp_path / "offsets.toml"
    offsets.write_text(toml)
    assert main(["parse", str(path), "--offsets", str(offsets)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {offsets}: ") and part in err and err.count("\n") == 1


def test_check_rs274_refusal_is_one_line(tmp_path, capsys, rs274):
    """A program this reader takes and rs274 refuses (G43.4): rs274's message and block
    on one line, exit 2; rs274 that does not finish in time is an Rs274Error too."""
    from nc.linuxcnc import Rs274Error, run_rs274

    path = tmp_path / "tcp.ngc"
    path.write_text("G21 G43.4 H1\nG1 X1 A10 F100\nM2\n")
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: rs274 refused {path}: ") and "G43.4" in err
    assert err.count("\n") == 1
    with pytest.raises(Rs274Error, match="did not finish"):
        run_rs274(path, timeout_s=1e-6)


@pytest.mark.parametrize("ending, said", [("exit 3", "exit status 3, no message"),
                                           ("kill -SEGV $$", "killed by SIGSEGV, no message")])
def test_rs274_that_ends_without_a_message_is_named_by_how_it_ended(tmp_path, monkeypatch,
                                                                     ending, said):
    """An rs274 that fails and prints nothing (a crash): the error says how it ended."""
    import nc.linuxcnc as L

    fake = tmp_path / "rs274"
    fake.write_text(f"#!/bin/sh\n{ending}\n")
    fake.chmod(0o755)
    monkeypatch.setattr(L, "rs274_path", lambda: str(fake))
    path = tmp_path / "p.ngc"
    path.write_text("G21 G1 X1 F100\nM2\n")
    with pytest.raises(L.Rs274Error) as caught:
        L.run_rs274(path)
    assert str(caught.value) == f"rs274 refused {path}: {said}"


def test_parse_reports_unknown_position_and_reference_points(tmp_path, capsys):
    path = tmp_path / "p.nc"
    path.write_text("G21 G90\nG0 X1 Y1 Z5\nG91 G28 Z0\nG90 G0 X2 Y2\nG0 Z5\nG1 Z0 F100\nM30\n")
    assert main(["parse", str(path)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    # G28's second row, the G0 X Y from there, the G0 Z from the unknown Z
    assert "position not known" in out and "3 blocks from line 3" in out
    setup = tmp_path / "setup.toml"
    setup.write_text("[G54]\nxyz_mm = [0.0, 0.0, -100.0]\n[G28]\nxyz_mm = [0.0, 0.0, 0.0]\n")
    assert main(["parse", str(path), "--offsets", str(setup), "--json"]) == 0
    blocks = json.loads(capsys.readouterr().out)
    assert [b["xyz_mm"][2] for b in blocks] == [5.0, 5.0, 100.0, 100.0, 5.0, 0.0]
