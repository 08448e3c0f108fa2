"""Real public NC programs (tests/data/nc-corpus, provenance in SOURCES.md).

Every file is read. Those in LinuxCNC's dialect are compared with LinuxCNC's
rs274 move by move. Files the reader still refuses are strict xfails with the
exact reason: when support for them arrives, they pass and the xfail fails
loudly, so that they move to the list of files read.
"""

from __future__ import annotations

import os

import pytest

from nc import NCParseError, read_program
from nc.linuxcnc import compare_with_rs274

CORPUS = os.path.join(os.path.dirname(__file__), "..", "data", "nc-corpus")

#: file -> compared with rs274 (False: rs274 refuses the file, reason given)
READ = {
    "lcnc-3dtest.ngc": True, "lcnc-arcspiral.ngc": True, "lcnc-b-index.ngc": True,
    "lcnc-boat-xyzbc.ngc": True, "lcnc-cds.ngc": True, "lcnc-lathe_pawn.ngc": True,
    "lcnc-plasmatest.ngc": True, "lcnc-skeleton.ngc": True, "lcnc-tort.ngc": True,
    "lcnc-vector_test.ngc": True,
    # LinuxCNC's own tests: G10 L2 (R0), G10 L2 P1 in inch with rotary axes, G92 A, G53
    "lcnc-test-arc-feed_basic_xy.ngc": True, "lcnc-test-unit-conversion.ngc": True,
    "lcnc-test-machinekit_412.ngc": True, "lcnc-test-tkalcevic_realtime_error.ngc": True,
    "lcnc-test-z_jump_tangent_improvement.ngc": True,
    "pygcode-Alien.tap": True, "pygcode-Clamp.nc": True, "pygcode-Cross2.tap": True,
    "pygcode-Disc3.tap": True, "pygcode-Scorpion.tap": True, "pygcode-plug6a.tap": True,
    "camotics-buildbotics.gcode": True, "camotics-cds.gcode": True,
    "camotics-scorpion.nc": True, "camotics-wave.gcode": True,
    "camotics-slant_test.nc": False,  # rs274: "File ended with no percent sign or program end"
    "camotics-text.ngc": False,       # rs274: "Bad character '%' used" (a '%' line mid-file)
    "pcb2gcode-front.ngc": True, "pcb2gcode-outline.ngc": True,
    "pcb2gcode-custom_tiled-outline.ngc": True,
    "gcodes-simple_mill.gcode": False,  # rs274: "Bad character" (a UTF-8 byte-order mark)
}

#: file -> (what the reader says, why: the part of the work that will read it)
REFUSED = {
    "lcnc-cone.ngc": ("O-word subroutines and control flow", "O-word control flow"),
    "lcnc-daisy.ngc": ("O-word subroutines and control flow", "O-word control flow"),
    "camotics-genes-encoder.ngc": ("O-word subroutines and control flow",
                                   "O-word control flow"),
    "pcb2gcode-linuxcnc_tiled-front.ngc": ("O-word subroutines and control flow",
                                           "O-word control flow"),
    "pcb2gcode-mach3_tiled-outline.ngc": ("M98 (a subroutine call",
                                          "M98/M99 subprograms"),
    "pcb2gcode-mach4-back.ngc": ("parameters and expressions", "'#' parameters (macro B)"),
    "pcb2gcode-D1MiniGSR-drill.ngc": ("G81 (a canned cycle", "canned cycles"),
    "lcnc-offsets.ngc": ("parameters and expressions", "'#' parameters (macro B)"),
    "camotics-cutout.ngc": ("parameters and expressions", "'#' parameters (macro B)"),
    "lcnc-hole-circle.ngc": ("unexpected character '^'",
                             "LinuxCNC polar coordinates '^' and canned cycle G81"),
    "lcnc-polar.ngc": ("G81 (a canned cycle", "canned cycles"),
    "lcnc-comp.ngc": ("G42 (cutter compensation", "cutter radius compensation"),
    "pygcode-DB25.tap": ("G41 (cutter compensation", "cutter radius compensation"),
    "lcnc-butterfly-xy.ngc": ("G5.2 (a spline", "NURBS G5.2/G5.3"),
    "lcnc-simple_example.ngc": ("G68.2 (a tilted working plane", "tilted working plane"),
    "lcnc-test-arc-feed_full_xy.ngc": ("rotation of a work offset (G10 R)",
                                       "work offsets with rotation (G10 L2 R)"),
    "lcnc-test-g10-l1-l10.ngc": ("rotation of a work offset (G10 R)",
                                 "work offsets with rotation (G10 L2 R)"),
    "pygcode-unsupported-Horse2.tap": ("unknown or unsupported code G71",
                                       "G70/G71 units (Siemens/Heidenhain style)"),
    "pygcode-Colt.tap": ("differ by 0.0057 mm",
                         "arc radii differ beyond LinuxCNC's tolerance (rs274 refuses it too)"),
    "gcodes-circle.gcode": ("I word in a straight move", "I J words in a G0 block"),
    "gcodes-371373P.gcode": ("unknown or unsupported code G78",
                             "a plotter/cutter dialect (G78, G22, G4 H)"),
}


def test_every_corpus_file_is_listed_with_its_provenance():
    files = {f for f in os.listdir(CORPUS) if f != "SOURCES.md"}
    assert files == set(READ) | set(REFUSED)
    assert not set(READ) & set(REFUSED)
    sources = open(os.path.join(CORPUS, "SOURCES.md"), encoding="utf-8").read()
    for f in files:
        row = next((ln for ln in sources.splitlines() if ln.startswith(f"| {f} |")), None)
        assert row is not None, f
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert len(cells) == 5 and len(cells[3]) == 40 and cells[4], row  # commit, licence
        assert os.path.getsize(os.path.join(CORPUS, f)) < 200_000


@pytest.mark.parametrize("name", sorted(READ))
def test_corpus_file_is_read(name, rs274_available):
    path = os.path.join(CORPUS, name)
    prog = read_program(path)
    assert len(prog) > 0 and prog.known.all()
    if READ[name] and rs274_available:
        result = compare_with_rs274(path, prog, tool_lengths_mm={t: 0.0 for t in range(100)})
        assert result.ok and result.moves == len(prog), result.message


@pytest.mark.parametrize("name", [
    pytest.param(n, marks=pytest.mark.xfail(raises=NCParseError, strict=True,
                                            reason=f"needs {why}"))
    for n, (_, why) in sorted(REFUSED.items())])
def test_corpus_file_refused_for_now(name):
    try:
        read_program(os.path.join(CORPUS, name))
    except NCParseError as exc:
        assert REFUSED[name][0] in str(exc), str(exc)  # any other refusal: a real failure
        raise


@pytest.fixture(scope="session")
def rs274_available():
    from nc.linuxcnc import rs274_path

    return rs274_path() is not None
