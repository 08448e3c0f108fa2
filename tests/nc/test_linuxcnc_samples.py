"""LinuxCNC's own sample programs, read here and by LinuxCNC's rs274.

The programs ship with Debian's linuxcnc-uspace; those inside this
package's dialect (plain motion, arcs in all planes, inch and mm, 5-axis
A/C words, inverse time) are read by both and compared move by move.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from nc import NCParseError, read_program
from nc.linuxcnc import compare_with_rs274, parse_canon

NCFILES = "/usr/share/linuxcnc/ncfiles"
TRT = ("/usr/share/doc/linuxcnc/examples/sample-configs/sim/gmoccapy/"
       "non_trivial_kinematics/table-rotary-tilting/examples")
SAMPLES = [
    (f"{NCFILES}/3dtest.ngc", []),             # inch, full circles in G17/G18/G19
    (f"{NCFILES}/arcspiral.ngc", []),          # 1000 R-form arcs, radius shrinking; G64
    (f"{NCFILES}/cds.ngc", []),                # G43 H, inch, R arcs; M9
    (f"{NCFILES}/tort.ngc", []),               # helical arcs in all three planes
    (f"{TRT}/impeller-7bl-xyzac.ngc", []),     # 5-axis A/C, inverse time, 4,492 moves
    (f"{TRT}/boat-xyzac.ngc", []),             # 5-axis A/C; coolant M8 M9 passed over
    (f"{TRT}/boat-xyzbc.ngc", []),             # 5-axis B/C; M8 M9, G53 G49 Z30 at the end
]


@pytest.mark.parametrize("path,allow", SAMPLES, ids=[os.path.basename(p) for p, _ in SAMPLES])
def test_sample_program_matches_rs274(path, allow, rs274):
    if not os.path.exists(path):
        pytest.skip(f"{path} not shipped with this linuxcnc-uspace")
    prog = read_program(path, allow=allow)
    result = compare_with_rs274(path, prog)
    assert result.ok and result.moves == len(prog) > 0, result.message


@pytest.mark.parametrize("path,codes", [
    (f"{NCFILES}/arcspiral.ngc", {"G64"}), (f"{NCFILES}/cds.ngc", {"M9"}),
    (f"{TRT}/boat-xyzac.ngc", {"M8", "M9"})], ids=["arcspiral", "cds", "boat-xyzac"])
def test_samples_refused_strictly_list_what_was_passed_over(path, codes):
    if not os.path.exists(path):
        pytest.skip(f"{path} not shipped with this linuxcnc-uspace")
    with pytest.raises(NCParseError, match="allow"):
        read_program(path, strict=True)
    prog = read_program(path)
    assert {code for code, _, _ in prog.ignored} == codes
    strict = read_program(path, strict=True, allow=sorted(codes))
    np.testing.assert_array_equal(strict.end, prog.end)


def test_parse_canon_units_and_planes():
    text = """    1 N..... USE_LENGTH_UNITS(CANON_UNITS_INCHES)
    2 N..... STRAIGHT_FEED(1.0000, 2.0000, 3.0000, 90.0000, 0.0000, 0.0000)
    3 N..... SELECT_PLANE(CANON_PLANE_XZ)
    4 N..... ARC_FEED(-1.0000, 30.0000, -1.0000, 25.0000, -2, 10.0000, 0.0000, 0.0000, 0.0000)
    5 N..... USE_LENGTH_UNITS(CANON_UNITS_MM)
    6 N..... STRAIGHT_TRAVERSE(5.0000, 6.0000, 7.0000, 0.0000, 0.0000, 45.0000)
"""
    c = parse_canon(text)
    assert list(c.kind) == ["FEED", "ARC", "TRAVERSE"]
    np.testing.assert_allclose(c.end[0], [25.4, 50.8, 76.2, 90, 0, 0])
    # XZ plane: first = Z, second = X, axis = Y
    np.testing.assert_allclose(c.end[1], [30 * 25.4, 10 * 25.4, -25.4, 0, 0, 0])
    np.testing.assert_allclose(c.centre[1][[0, 2]], [25 * 25.4, -25.4])
    assert c.turns[1] == -2
    np.testing.assert_allclose(c.end[2], [5, 6, 7, 0, 0, 45])
    np.testing.assert_allclose(c.resolution, [0.5e-4 * 25.4] * 2 + [0.5e-4])
