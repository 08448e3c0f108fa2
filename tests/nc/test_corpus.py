"""Real NC programs: LinuxCNC's sample programs and other public programs.

``linuxcnc_corpus.txt`` lists every program file that Debian's linuxcnc-uspace
installs (read in place, as ``test_linuxcnc_samples.py`` does; CI installs
the package); ``external_corpus.txt`` lists further public programs (CAM
outputs, LinuxCNC's own interpreter tests) with their provenance, read when
their files are put in ``$NC_CORPUS_DIR`` or ``../shared/nc-corpus/``.

Programs the reader reads are compared with LinuxCNC's rs274 move by move
(unless rs274 refuses the file itself). Programs it still refuses are strict
xfails with the reason: when support arrives they pass, the xfail fails
loudly, and the list is updated.
"""

from __future__ import annotations

import os

import pytest

from nc import NCParseError, read_program
from nc.linuxcnc import compare_with_rs274, rs274_path

HERE = os.path.dirname(__file__)
PREFIXES = {"NC/": "/usr/share/linuxcnc/ncfiles/",
            "EX/": "/usr/share/doc/linuxcnc/examples/sample-configs/sim/"}
EXTERNAL_DIR = os.environ.get("NC_CORPUS_DIR") or os.path.join(
    HERE, "..", "..", "..", "shared", "nc-corpus")

#: status -> (what the reader's message says, what the reader needs to read it)
REASONS = {
    "oword": ("O-word control flow:", "O-word syntax rs274 refuses too (o<name> callsub)"),
    "param": ("parameters and expressions", "'#' parameters and expressions"),
    "polar": ("unexpected character '^'", "LinuxCNC polar coordinates (^ @)"),
    "comp": ("(cutter compensation", "cutter radius compensation"),
    "cycle": ("(a canned cycle", "canned cycles"),
    "probe": ("(a probing move", "probing moves"),
    "kins": ("unsupported code M42", "kinematics switching (LinuxCNC user M428/M429)"),
    "userm": ("unsupported code M190", "LinuxCNC user M-codes (M100-M199)"),
    "m70": ("unsupported code M7", "modal state save and restore (M70-M73)"),
    "lathe": ("unsupported code G7", "LinuxCNC lathe cycles G70-G72 (G71.1, G72)"),
    "g43.1": ("code G43.1", "dynamic tool length offset G43.1"),
    "osubfile": ("sub in this file", "O-word subroutines from other files (SUBROUTINE_PATH)"),
    "w": ("unknown word W", "axes U V W"),
    "polar@": ("unexpected character '@'", "LinuxCNC polar coordinates (^ @)"),
    "g33": ("code G33", "spindle-synchronized motion G33"),
    "uvw": ("unknown word U", "axes U V W"),
    "rotation": ("rotation of a work offset (G10 R)", "work offsets with rotation (G10 L2 R)"),
    "nurbs": ("G5.2 (a spline", "NURBS G5.2/G5.3"),
    "tilt": ("Q word with G68.x", "LinuxCNC's G68.2 Q orientation forms and G53.3"),
    "arcradius": ("differ by", "arc radii beyond LinuxCNC's tolerance (rs274 refuses too)"),
    "g71": ("unsupported code G71", "G70/G71 units (Siemens/Heidenhain style)"),
    "ijk-g0": ("I word in a straight move", "I J words in a G0 block"),
    "plotter": ("unsupported code G78", "a plotter dialect (G78, G22, G4 H)"),
    "m98": ("M98 (a subroutine call", "M98/M99 subprograms"),
    "m111": ("unsupported code M111", "LinuxCNC user M-codes (M100-M199)"),
    "spline": ("(a spline", "splines G5/G5.1"),
    "sysvar": ("system variable", "the control's system variables (Mach's probe result #5063)"),
}
#: read-runs-on: read to the end of the main program's text, which runs into a
#: subprogram without M30/M02 (recorded, Program.main_open_end_line); rs274 runs
#: on into the subprogram's blocks, so the move lists differ by design
READ = ("read", "read-only", "read-runs-on", "empty")


def _manifest(name: str) -> list[tuple[str, str]]:
    """(status, path) per program of a manifest file."""
    out = []
    with open(os.path.join(HERE, name), encoding="utf-8") as fh:
        for line in fh:
            if line.strip() and not line.startswith("#"):
                status, where = line.split()[:2]
                assert status in READ or status in REASONS, line
                for short, long in PREFIXES.items():
                    if where.startswith(short):
                        where = long + where[len(short):]
                if name.startswith("external"):
                    where = os.path.join(EXTERNAL_DIR, where)
                out.append((status, where))
    return out


CORPUS = _manifest("linuxcnc_corpus.txt") + _manifest("external_corpus.txt")


def _id(path: str) -> str:
    return path.replace("/usr/share/", "").replace(EXTERNAL_DIR + os.sep, "external/")


def test_manifests_are_complete():
    assert len(CORPUS) == len({p for _, p in CORPUS})
    package = [p for _, p in CORPUS if p.startswith("/usr/share/")]
    assert len(package) == 137
    with open(os.path.join(HERE, "external_corpus.txt"), encoding="utf-8") as fh:
        for line in fh:
            if line.strip() and not line.startswith("#"):
                cells = line.split()
                assert len(cells) == 6 and len(cells[4]) == 40, line  # commit, licence


def _existing(path: str) -> str:
    if not os.path.exists(path):
        pytest.skip(f"{path} is not on this machine")
    return path


@pytest.mark.parametrize("status,path", [c for c in CORPUS if c[0] in READ],
                         ids=[_id(p) for s, p in CORPUS if s in READ])
def test_corpus_program_is_read(status, path):
    prog = read_program(_existing(path))
    if status == "empty":
        assert len(prog) == 0
        return
    assert len(prog) > 0 and prog.known.all()
    assert bool(prog.main_open_end_line) == (status == "read-runs-on")
    if status == "read" and rs274_path() is not None:
        result = compare_with_rs274(path, prog, tool_lengths_mm={t: 0.0 for t in range(100)})
        assert result.ok and result.moves == len(prog), result.message


@pytest.mark.parametrize("status,path", [
    pytest.param(s, p, marks=pytest.mark.xfail(raises=NCParseError, strict=True,
                                               reason=f"needs {REASONS[s][1]}"), id=_id(p))
    for s, p in CORPUS if s not in READ])
def test_corpus_program_refused_for_now(status, path):
    try:
        read_program(_existing(path))
    except NCParseError as exc:
        assert REASONS[status][0] in str(exc), str(exc)  # any other refusal: a failure
        raise
