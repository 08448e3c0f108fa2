"""G68/G69 rotation, G68.2/G53.1 tilted planes (nc.rotation): hand-checked pairs, the
tilted path through the machine's kinematics and the Fanuc writer, refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nc import NCParseError, parse_program
from nc.kinematics import get_machine, solve_path
from nc.path import cutter_locations
from nc.program import TCP_OFF, TCP_VECTOR
from nc.rotation import euler_zxz, plane_from_points, plane_from_vectors
from nc.writer import PostOptions, post

HEAD = "G21 G17 G90 G94\nT1 M6\nS1000 M3\nF100\nG0 X0 Y0 Z5\n"
S = math.sqrt(0.5)

#: source (after HEAD) -> ends of its moves (x, y, z) in the program frame, by hand
KNOWN = [
    # G68 about (10, 0) by 90 deg: (20, 0) -> (10, 10); G91 Y5 along the rotated Y (-X)
    ("G68 X10 Y0 R90\nG1 X20 Y0\nG91 Y5", [(10, 10, 5), (5, 10, 5)]),
    # centre omitted: the current position (0, 0)
    ("G68 R90\nG1 X10 Y0", [(0, 10, 5)]),
    # G18: the plane Z-X, rotation about +Y from Z toward X; centre Z0 X0
    ("G18\nG68 X0 Z0 R90\nG1 X0 Z10", [(10, 0, 0)]),
    # 3-D conversion: about +X by 90 through the origin: (0, 10, 0) -> (0, 0, 10)
    ("G68 X0 Y0 Z0 I1 J0 K0 R90\nG1 X0 Y10 Z0", [(0, 0, 10)]),
    # G69 ends it: the next coordinates are the program frame's again
    ("G68 X0 Y0 R45\nG1 X10 Y0\nG69\nG1 X10 Y0",
     [(10 * S, 10 * S, 5), (10, 0, 5)]),
    # G68.2 I0 J90 K0: the front face, plane X = X, plane Y = +Z, plane Z = -Y
    ("G68.2 X100 Y0 Z0 I0 J90 K0\nG53.1\nG0 X0 Y0 Z10\nG1 Z0\nX5 Y3",
     [(100, -10, 0), (100, 0, 0), (105, 0, 3)]),
    # I90 J45: Z turned 90 about Z, then 45 about the new X (world Y): axis (s, 0, s)
    ("G68.2 X0 Y0 Z0 I90 J45 K0\nG53.1\nG1 X0 Y0 Z10", [(10 * S, 0, 10 * S)]),
    # G68.2 P2: a plane tilted 30 deg about X through (10, 20, 5): x = +X, the third
    # point 10 along (0, cos 30, sin 30); (1, 2, 3) -> (11, 20 + 2c - 3s, 5 + 2s + 3c)
    ("G68.2 P2 Q1 X10 Y20 Z5\nG68.2 P2 Q2 X20 Y20 Z5\n"
     "G68.2 P2 Q3 X10 Y28.660254037844386 Z10\nG53.1\nG1 X1 Y2 Z3",
     [(11, 20 + 2 * 0.8660254037844386 - 1.5, 5 + 1 + 3 * 0.8660254037844386)]),
    # P2 with Q0's shift X5 in the plane's axes; x = +Y, third point at -X: z = +Z, y = -X
    ("G68.2 P2 Q0 X5 Y0 Z0 R0\nG68.2 P2 Q1 X0 Y0 Z0\nG68.2 P2 Q2 X0 Y10 Z0\n"
     "G68.2 P2 Q3 X-10 Y0 Z0\nG1 X1 Y0 Z0\nY1", [(0, 6, 0), (-1, 6, 0)]),
    # P2 with Q0 R90: the points give the work frame, then a turn of 90 about its Z
    ("G68.2 P2 Q0 R90\nG68.2 P2 Q1 X0 Y0 Z0\nG68.2 P2 Q2 X1 Y0 Z0\n"
     "G68.2 P2 Q3 X0 Y1 Z0\nG1 X1 Y0 Z0", [(0, 1, 0)]),
    # G68.2 P3: x = +X, z = -Y: the front face as P0's I0 J90 K0 above (y = z x x = +Z)
    ("G68.2 P3 Q1 X100 Y0 Z0 I1 J0 K0\nG68.2 P3 Q2 I0 J-1 K0\nG53.1\nG0 X0 Y0 Z10\n"
     "G1 Z0\nX5 Y3", [(100, -10, 0), (100, 0, 0), (105, 0, 3)]),
    # canned cycle under G68: the hole at (10, 0) rotated 90 about the origin -> (0, 10)
    ("G68 X0 Y0 R90\nG98 G81 X10 Y0 Z-1 R1\nG80",
     [(0, 10, 5), (0, 10, 1), (0, 10, -1), (0, 10, 5)]),
]


@pytest.mark.parametrize("source,ends", KNOWN, ids=[k[0].split("\n")[0] for k in KNOWN])
def test_known_rotated_moves(source, ends):
    prog = parse_program(HEAD + source + "\nM30\n")
    np.testing.assert_allclose(prog.end[1:, :3], np.array(ends, dtype=float), atol=1e-9)


def test_g68_arc_stays_an_arc_with_its_centre_rotated():
    prog = parse_program(HEAD + "G68 X10 Y0 R90\nG1 X20 Y5\nG3 X10 Y15 I-10 J0\nM30\n")
    b = prog[-1]
    # program frame: start (20,5), centre (10,5), end (10,15); rotated about (10,0) by 90
    np.testing.assert_allclose(b.start[:3], [5, 10, 5], atol=1e-9)
    np.testing.assert_allclose(b.end[:3], [-5, 0, 5], atol=1e-9)
    np.testing.assert_allclose(b.arc.centre, [5, 0, 5], atol=1e-9)
    assert b.arc.sweep_rad == pytest.approx(math.pi / 2)  # still G3, a quarter


EULER = [(0, 30, 0), (30, 40, -20), (-75, 120, 10), (200, 15, 95)]


@pytest.mark.parametrize("angles", EULER)
def test_three_points_and_two_vectors_give_p0s_plane(angles):
    """P2 through the P0 plane's origin, origin + x and origin + y + x, and P3 with its
    x and z columns: the same moves and tool vectors after G53.1 as P0."""
    M = euler_zxz(*angles)
    o = np.array([12.0, -7.0, 3.0])
    fmt = " ".join
    p1, p2, p3 = o, o + 25 * M[:, 0], o + 10 * M[:, 0] + 40 * M[:, 1]
    xyz = [fmt(f"{c}{v:.15f}" for c, v in zip("XYZ", p)) for p in (p1, p2, p3)]
    ijk = [fmt(f"{c}{v:.15f}" for c, v in zip("IJK", M[:, k])) for k in (0, 2)]
    tail = "G53.1\nG0 X0 Y0 Z20\nG1 Z0 F300\nX10 Y4\nG2 X20 Y4 I5 J0\nG0 Z20\nG69\nM30\n"
    p0 = parse_program(HEAD + "G68.2 X12 Y-7 Z3 I{} J{} K{}\n".format(*angles) + tail)
    forms = [HEAD + "".join(f"G68.2 P2 Q{k + 1} {xyz[k]}\n" for k in range(3)) + tail,
             HEAD + f"G68.2 P3 Q1 {xyz[0]} {ijk[0]}\nG68.2 P3 Q2 {ijk[1]}\n" + tail]
    for src in forms:
        prog = parse_program(src)
        assert len(prog) == len(p0)
        np.testing.assert_allclose(prog.end, p0.end, atol=1e-9)
        np.testing.assert_allclose(prog.tool_vector, p0.tool_vector, atol=1e-12)
        np.testing.assert_array_equal(prog.modal_column("tcp"), p0.modal_column("tcp"))
    np.testing.assert_allclose(plane_from_points(p1, p2, p3), M, atol=1e-12)
    np.testing.assert_allclose(plane_from_vectors(M[:, 0], M[:, 2]), M, atol=1e-12)


def test_two_vectors_a_hair_from_perpendicular_keep_z():
    """A post's rounded unit vectors (0.05 deg off): z exact, x made perpendicular."""
    a = math.radians(0.05)
    M = plane_from_vectors([math.cos(a), 0, math.sin(a)], [0, 0, 2])
    np.testing.assert_allclose(M, np.eye(3), atol=1e-15)


def test_euler_zxz_columns_are_the_plane_axes():
    M = euler_zxz(0, 90, 0)
    np.testing.assert_allclose(M, [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-12)
    M = euler_zxz(30, 40, 50)
    np.testing.assert_allclose(M.T @ M, np.eye(3), atol=1e-12)
    assert np.linalg.det(M) == pytest.approx(1.0)


def _tilted_program():
    return parse_program(HEAD + "G68.2 X20 Y10 Z0 I30 J40 K-20\nG53.1\nG0 X0 Y0 Z20\n"
                         "G1 Z0 F300\nX10\nG2 X20 Y0 I5\nG1 Y8\nG0 Z20\nG69\nG0 Z100\nM30\n")


def test_tilted_arc_as_chords_on_the_circle_with_the_tool_along_the_plane_z():
    prog = _tilted_program()
    M = euler_zxz(30, 40, -20)
    o = np.array([20.0, 10, 0])
    line = 11  # the G2
    rows = np.flatnonzero(prog.line == line)
    assert len(rows) > 10 and np.all(prog.motion[rows] == 1)
    centre = o + M @ [15, 0, 0]
    np.testing.assert_allclose(np.linalg.norm(prog.end[rows, :3] - centre, axis=1), 5, atol=1e-9)
    np.testing.assert_allclose(prog.end[rows[-1], :3], o + M @ [20, 0, 0], atol=1e-9)
    # every chord point in the plane (z' = 0)
    np.testing.assert_allclose((prog.end[rows, :3] - o) @ M[:, 2], 0, atol=1e-9)
    tcp = prog.modal_column("tcp")
    assert np.all(tcp[1:] == TCP_VECTOR)  # from G53.1 on, and after G69 (tool still turned)
    np.testing.assert_allclose(prog.tool_vector[1:], np.tile(M[:, 2], (len(prog) - 1, 1)),
                               atol=1e-12)
    cl = cutter_locations(prog)
    np.testing.assert_allclose(cl.axis[-1], M[:, 2], atol=1e-12)


def test_a_new_rotation_keeps_the_tool_where_g53_1_turned_it():
    prog = parse_program(HEAD + "G68.2 X0 Y0 Z0 I0 J30 K0\nG53.1\nG1 X1\nG69\n"
                         "G68 X0 Y0 R90\nG1 X2 Y0\nM30\n")
    assert prog.modal_column("tcp")[-1] == TCP_VECTOR
    np.testing.assert_allclose(prog.tool_vector[-1], euler_zxz(0, 30, 0)[:, 2], atol=1e-12)
    np.testing.assert_allclose(prog.end[-1, :3], [0, 2, 5], atol=1e-9)  # Z5 kept throughout


def test_rotary_words_after_g69_end_the_held_tool_axis():
    prog = parse_program(HEAD + "G68.2 X0 Y0 Z0 I0 J30 K0\nG53.1\nG1 X1\nG69\nG0 A0 C0\n"
                         "G1 X2\nM30\n")
    tcp = prog.modal_column("tcp")
    assert list(tcp) == [TCP_OFF, TCP_VECTOR, TCP_OFF, TCP_OFF]


@pytest.mark.parametrize("name", ["xyzbc-head-table", "xyzac-trt"])
def test_tilted_program_through_kinematics_and_the_fanuc_writer(name):
    """The tilted path as machine joints (nc.kinematics) and as a G43.4 program read back."""
    prog = _tilted_program()
    machine = get_machine(name)
    cl = cutter_locations(prog)
    sol = solve_path(machine, cl.tip, cl.axis)
    tip, axis = machine.forward(sol.joints)
    np.testing.assert_allclose(tip, cl.tip, atol=1e-6)
    np.testing.assert_allclose(axis, cl.axis, atol=1e-9)
    # the same path posted with Fanuc TCP (G43.4) and read back: within 1 um, 1e-4 deg
    cut = cl.take(np.flatnonzero(~cl.rapid))
    res = post(cut, machine, PostOptions(dialect="fanuc-g43.4"))
    back = cutter_locations(parse_program(res.text), machine)
    feed = np.flatnonzero(~back.rapid)
    assert np.linalg.norm(back.tip[feed] - res.tip, axis=1).max() <= 1e-3
    cos = np.clip(np.sum(back.axis[feed] * res.axis, axis=1), -1, 1)
    assert np.degrees(np.arccos(cos)).max() <= 1e-4


@pytest.mark.parametrize("source,where,words", [
    ("G68 X0 Y0", "6:1", "without R"),
    ("G68 X0 Y0 R10\nG68 X0 Y0 R20", "7:1", "expected G69 first"),
    ("G68 X0 Y0 R10\nG18", "7:1", "change of plane under G68"),
    ("G68 X0 Y0 R10\nG55", "7:1", "change of frame"),
    ("G68 X0 Y0 R10\nG92 X0", "7:1", "change of frame"),
    ("G68 X0 Y0 R10 G1", "6:1", "without motion"),
    ("G68 X0 Y0 Z3 R10", "6:11", "in the plane's two axes"),
    ("G68.2 X0 Y0 Z0 I0 J30 K0 P1", "6:26", "G68.2 P1 (roll-pitch-yaw) is not supported"),
    ("G68.2 X0 Y0 Z0 I0 J30 K0 P4", "6:26", "expected P0"),
    ("G68.2 P2 Q1 X0 Y0 Z0\nG1 X1", "7:1", "G68.2 P2 definition not complete"),
    ("G68.2 P2 Q1 X0 Y0 Z0\nG69", "7:1", "G68.2 P2 definition not complete"),
    ("G68.2 P2 Q1 X0 Y0 Z0\nG68.2 P2 Q3 X0 Y1 Z0", "7:10", "Q3 here; expected Q2 next"),
    ("G68.2 P2 Q1 X0 Y0 Z0\nG68.2 P2 Q0 X1", "7:10", "Q0 here; expected Q2 next"),
    ("G68.2 P2 Q1 X0 Y0 Z0\nG68.2 P3 Q1 X0 Y0 Z0 I1 J0 K0", "7:1", "P2 definition not"),
    ("G68.2 P2 Q1 X0 Y0 Z0 I1", "6:22", "I word with G68.2 P2 Q1"),
    ("G68.2 P2 Q1 X0 Y0", "6:10", "Q1 without Z"),
    ("G68.2 P2 X0 Y0 Z0", "6:7", "P2 without Q"),
    ("G68.2 P2 Q1 X0 Y0 Z0\nG68.2 P2 Q2 X1 Y0 Z0\nG68.2 P2 Q3 X2 Y0 Z0", "8:10",
     "three points on one line"),
    ("G68.2 P2 Q1 X0 Y0 Z0\nG68.2 P2 Q2 X0 Y0 Z0\nG68.2 P2 Q3 X2 Y0 Z0", "8:10",
     "two points at one place"),
    ("G68.2 P2 Q0 X1 R10\nG68.2 P2 Q1 X0 Y0 Z0\nG68.2 P2 Q2 X1 Y0 Z0\n"
     "G68.2 P2 Q3 X0 Y1 Z0", "9:1", "both a shift X Y Z and a turn R"),
    ("G68.2 P3 Q1 X0 Y0 Z0 I1 J0 K0\nG68.2 P3 Q2 I0.0035 J0 K1", "7:10",
     "perpendicular within 0.1 deg"),
    ("G68.2 P3 Q1 X0 Y0 Z0 I0 J0 K0\nG68.2 P3 Q2 I0 J0 K1", "7:10", "zero vector"),
    ("G68.2 P3 Q1 X0 Y0 Z0 I1 J0 K0\nG68.2 P3 Q2 X1 I0 J0 K1", "7:13", "X word with G68.2 P3"),
    ("G68.2 P3 Q1 X0 Y0 Z0 I1 J0 K0 R5", "6:31", "R word with G68.2 P3 Q1"),
    ("G68.2 P3 Q1 X0 Y0 Z0 I1 J0 K0\nG53.1", "7:1", "P3 definition not complete"),
    ("G68.2 X0 Y0 Z0 Q123 I0 J30", "6:16", "Q word with G68.x"),
    ("G53.1", "6:1", "without a tilted working plane"),
    ("G68.2 X0 Y0 Z0 I0 J30 K0\nG53.1\nG1 B10", "8:4", "rotary word B under G68.2"),
    ("G43.4 H1\nG68 X0 Y0 R10", "7:1", "tool centre point"),
    ("G69 X1", "6:5", "G69 alone"),
    ("G68.2 X0 Y0 Z0 I0 J30 K0\nG53.1\nG43.4 H1", "8:1", "tool centre point control"),
])
def test_bad_rotation_one_line_with_place(source, where, words):
    with pytest.raises(NCParseError) as exc:
        parse_program(HEAD + source + "\n", file="r.nc")
    msg = str(exc.value)
    assert msg.startswith(f"r.nc:{where}: "), msg
    assert words in msg and "\n" not in msg


def test_strict_refuses_rotation():
    with pytest.raises(NCParseError, match="a coordinate rotation; read without strict"):
        parse_program(HEAD + "G68 X0 Y0 R10\n", strict=True)


@pytest.mark.parametrize("source,line,what", [
    ("G68 X0 Y0 R10\nG1 X1\nG69\nG1 X2", 7, "rotated frame"),
    ("G98 G81 X1 Z-1 R1\nG80\nG1 X2", 6, "canned drilling cycles"),
])
def test_rewrite_refuses_rotated_and_drilling_programs(source, line, what):
    from nc.rewrite import RewriteError, rewrite_coordinates

    prog = parse_program(HEAD + source + "\nM30\n")
    assert len(prog.rotated) + len(prog.drilling) > 0
    with pytest.raises(RewriteError, match=f"^<string>:{line}: the program has .*{what}"):
        rewrite_coordinates(prog, ends={len(prog) - 1: (3.0, 0.0, 5.0)})


def test_chords_of_tilted_arcs_are_bounded(monkeypatch):
    import nc.constants as K

    monkeypatch.setattr(K, "MAX_TILTED_ARC_CHORDS", 100)
    src = HEAD + "G68.2 X0 Y0 Z0 I0 J30 K0\nG53.1\nG1 X0 Y0 Z0\nG2 X0 Y0 I50 P20\n"
    with pytest.raises(NCParseError, match=r"^t\.nc:9:1: arc in the tilted plane would make "
                       "more than 100 chords"):
        parse_program(src, file="t.nc")
