"""Real NC programs that Debian packages install (``external_packages.txt``), read
where the package puts them: nothing third-party is committed here.

Each row says what the reader must do: read the program (and agree with LinuxCNC's
``rs274`` move by move, for a LinuxCNC program) or refuse it at a given line with a
given reason. A refusal here is the right answer for that program (a post's output
with no feed rate), not a gap; ``rs274`` is asked too where the program is LinuxCNC's.
A main program that ends in M99 (FreeCAD's Centroid post) is read to that M99 as its
end (:mod:`nc.macro_b`). Absent packages are skipped with the command that
installs them (CI's ``.ci/run`` does).
"""

from __future__ import annotations

import os

import pytest

from nc import NCParseError, read_any
from nc.gcode import parse_program
from nc.summary import summarize
from nc.linuxcnc import Rs274Error, compare_with_rs274, rs274_path, run_rs274

HERE = os.path.dirname(__file__)

#: tag -> fragment of the reader's one-line message
REASONS = {
    "nofeed": "cutting move with no feed",
}
CENTROID = "/usr/share/freecad/Mod/Path/PathTests/test_centroid_00.ngc"
#: tag -> fragment of rs274's message, for LinuxCNC programs
RS274_REASONS = {"nofeed": "zero feed rate"}


def _rows() -> list[tuple[str, str, str, str]]:
    """(expected, path, package, origin) per program of the manifest."""
    out = []
    with open(os.path.join(HERE, "external_packages.txt"), encoding="utf-8") as fh:
        for line in fh:
            if line.strip() and not line.startswith("#"):
                cells = line.split(None, 5)
                assert len(cells) == 6, line
                out.append((cells[0], cells[1], cells[2], cells[5].strip()))
    return out


ROWS = _rows()


def test_manifest_rows_are_well_formed():
    assert len({r[1] for r in ROWS}) == len(ROWS) >= 1
    for expected, path, package, origin in ROWS:
        assert path.startswith("/usr/share/") and package and origin
        if expected != "read":
            where, tag = expected.removeprefix("refused@").split(":")
            assert expected.startswith("refused@") and int(where) > 0 and tag in REASONS


@pytest.mark.parametrize("expected,path,package,origin", ROWS,
                         ids=[os.path.basename(r[1]) for r in ROWS])
def test_installed_program(expected, path, package, origin):
    if not os.path.exists(path):
        pytest.skip(f"{path} not installed: apt-get install --no-install-recommends "
                    f"{package} (CI's .ci/run installs it)")
    linuxcnc = "linuxcnc" in os.path.basename(path)
    if expected == "read":
        prog = read_any(path)
        assert len(prog) > 0 and prog.known.all()
        if linuxcnc and rs274_path() is not None:
            res = compare_with_rs274(path, prog, tool_lengths_mm={t: 0.0 for t in range(100)})
            assert res.ok and res.moves == len(prog), res.message
        return
    where, tag = expected.removeprefix("refused@").split(":")
    with pytest.raises(NCParseError) as exc:
        read_any(path)
    msg = str(exc.value)
    assert msg.startswith(f"{path}:{where}:") and "\n" not in msg, msg
    assert REASONS[tag] in msg, msg
    if linuxcnc and rs274_path() is not None:
        with pytest.raises(Rs274Error, match=RS274_REASONS[tag]):  # rs274 refuses it too
            run_rs274(path, tool_lengths_mm={t: 0.0 for t in range(100)})


def test_centroid_m99_ends_the_program():
    """The Centroid post's output with the feed it lacks given in its first G1 block
    (line 15, in memory): read to its closing M99 (line 69) as the end, one move per
    G0/G1 block with coordinates, none after; strict reading refuses that M99. Its M25
    (line 66: Centroid's Z retract, a move the reader does not model, refused unless
    allowed) comes after the last move, so it is allowed here; its 'G49 H0' (line 67)
    is refused as rs274 refuses it ("H word with no G43"), so H0 is left out here."""
    if not os.path.exists(CENTROID):
        pytest.skip(f"{CENTROID} not installed: apt-get install --no-install-recommends "
                    "freecad-common")
    with open(CENTROID, encoding="utf-8") as fh:
        lines = fh.read().split("\n")
    assert lines[14].startswith("G1 ") and lines[68].strip() == "M99"
    lines[14] += " F100"
    assert lines[66].strip() == "G49 H0"
    lines[66] = "G49"
    prog = parse_program("\n".join(lines), file="centroid.ngc", allow=["M25"])
    assert prog.main_m99_line == 69
    moving = [k + 1 for k, ln in enumerate(lines)
              if ln.split()[:1] in (["G0"], ["G1"]) and any(w[0] in "XYZ" for w in ln.split())]
    # (line 2, 'G53 G00 G17' without axis words, makes a machine-coordinate row in place)
    assert list(prog.line[prog.line > 2]) == moving and moving[-1] == 65
    assert prog.end[-1, 2] == pytest.approx(15.0 * 25.4)  # G20 at line 3: inches
    assert summarize(prog).main_m99_line == 69
    with pytest.raises(NCParseError, match=r"^centroid\.ngc:69:1: .*M99 in the main program"):
        parse_program("\n".join(lines), file="centroid.ngc", allow=["M25"], strict=True)
