"""Real NC programs that Debian packages install (``external_packages.txt``), read
where the package puts them: nothing third-party is committed here.

Each row says what the reader must do: read the program (and agree with LinuxCNC's
``rs274`` move by move, for a LinuxCNC program) or refuse it at a given line with a
given reason. A refusal here is the right answer for that program (a post's output
with no feed rate, a main program that ends in M99), not a gap; ``rs274`` is asked too
where the program is LinuxCNC's. Absent packages are skipped with the command that
installs them (CI's ``.ci/run`` does).
"""

from __future__ import annotations

import os

import pytest

from nc import NCParseError, read_any
from nc.linuxcnc import Rs274Error, compare_with_rs274, rs274_path, run_rs274

HERE = os.path.dirname(__file__)

#: tag -> fragment of the reader's one-line message
REASONS = {
    "nofeed": "cutting move with no feed",
    "m99main": "M99 in the main program",
}
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
