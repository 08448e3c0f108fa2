"""Make the bundled orient scenarios ``orient/scenarios/thin-wall/`` and the program of
``orient/scenarios/mold-core/``.

Run from anywhere: ``python scripts/make_orient_scenarios.py`` rewrites every
file (deterministic: same bytes on every run); ``--check`` regenerates into a
temporary folder and fails if the committed files differ.

thin-wall: a steel rib, 60 mm long (X), 30 mm high, 3.5 mm thick when finished,
standing on a 60 x 40 x 10 mm plate, finished on its +Y face with a D10 ball
end mill on a table-tilting A/C machine. The CAM default orientation is the
one a 5-axis CAM system proposes for a wall: the tool axis in the plane
normal to the feed, inclined 30 deg from the wall normal toward +Z (away from
the plate). One-way passes along +X, 0.5 mm apart in Z, from the top down
(each pass has the finished surface of the previous one above it); radial
allowance 0.2 mm. The wall is the flexible side (its first bending mode,
clamped at the plate, is a few kHz with little damping); the tool is a stiff
short carbide ball end mill.

mold-core: errpred's bundled mold-ball core (its design and stock STLs are referenced,
not copied) finished on a 5-axis head-table machine; its CAM program ``raster.nc`` is
the raster operation of errpred's ``finish.nc`` (lines MOLD_RASTER_FIRST to the end:
every raster pass, along +X, pick 0.35 mm, where the surface is shallower than 40 deg)
after the program's own header, lifted first to the safe height. Only the program is
written here; ``scenario.toml`` is committed by hand (it holds the sources).

Other ribs: :class:`Rib` holds the geometry and the program's layout (its
defaults are the bundled thin wall) and :func:`write_rib` writes a rib's files,
e.g. the tests' flexible wall (``tests/sim/flexible_wall.py``).
"""

from __future__ import annotations

import math
import os
import struct
import sys
from dataclasses import dataclass

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
OUT = os.path.join(ROOT, "orient", "scenarios")


@dataclass(frozen=True)
class Rib:
    """A rib standing on a plate and the CAM program that finishes its +Y face.

    The defaults are the bundled thin wall; other ribs (tests, benchmarks) are
    the same geometry and program with other values.

    Attributes
    ----------
    length, plate_w, plate_t : float [mm]
        Plate X 0..length, Y 0..plate_w, Z -plate_t..0 (the rib is as long).
    wall_y0, wall_t, wall_h : float [mm]
        Finished wall Y wall_y0..wall_y0 + wall_t, Z 0..wall_h.
    allowance : float [mm]
        Stock left on the +Y face.
    r_ball : float [mm]
        Ball radius of the tool.
    inclination_deg : float [deg]
        CAM default posture: tool axis in the plane normal to the feed, inclined
        this much from the wall normal toward +Z (away from the plate).
    pick, z_top, z_low : float [mm]
        Contact heights of the one-way passes: z_top down to z_low, pick apart.
    x_start, x_end, step : float [mm]
        Contact x along a pass (the ball clear of the rib at both ends).
    spindle_rpm, feed_mm_min : float [rev/min], [mm/min]
    clear_y : float [mm]
        Approach and retract distance along the tool axis.
    machine : str
        Named machine the program is written for (``nc.kinematics.MACHINES``).
    tool_length_mm : float [mm]
        The machine's tool length: the tool's overhang (``[tool] overhang_mm``), as the
        scenario's readers resolve the machine (it places the tip from a head's pivots;
        a table-table machine's program does not depend on it).
    """

    length: float = 60.0
    plate_w: float = 40.0
    plate_t: float = 10.0
    wall_y0: float = 18.5
    wall_t: float = 3.5
    wall_h: float = 30.0
    allowance: float = 0.2
    r_ball: float = 5.0
    inclination_deg: float = 30.0
    pick: float = 0.5
    z_top: float = 29.5
    z_low: float = 6.0
    x_start: float = -6.0
    x_end: float = 66.0
    step: float = 2.0
    spindle_rpm: float = 9000.0          # fz = 0.1 mm with 1800 mm/min and two flutes
    feed_mm_min: float = 1800.0
    clear_y: float = 12.0
    machine: str = "xyzac-trt"
    tool_length_mm: float = 35.0

    def pass_heights(self) -> np.ndarray:
        """Contact Z of the passes, top down [mm]."""
        return np.arange(self.z_top, self.z_low - 1e-9, -self.pick)


#: The bundled thin wall: a steel rib 60 mm long, 30 mm high, 3.5 mm thick.
THIN_WALL = Rib()


def t_profile(thickness: float, rib: Rib = THIN_WALL) -> np.ndarray:
    """The rib's cross-section (Y, Z), counter-clockwise, shape (8, 2) [mm]."""
    y0, h, pw, pt = rib.wall_y0, rib.wall_h, rib.plate_w, rib.plate_t
    y1 = y0 + thickness
    return np.array([(0.0, -pt), (pw, -pt), (pw, 0.0), (y1, 0.0),
                     (y1, h), (y0, h), (y0, 0.0), (0.0, 0.0)])


#: Triangles of the T profile (indices into :func:`t_profile`), counter-clockwise.
T_CAPS = ((0, 1, 2), (0, 2, 3), (0, 3, 6), (0, 6, 7), (6, 3, 4), (6, 4, 5))


def extrude(profile: np.ndarray, length: float) -> np.ndarray:
    """Closed triangle soup of the profile extruded along +X, shape (t, 3, 3) [mm]."""
    n = len(profile)
    a = np.column_stack([np.zeros(n), profile])
    b = np.column_stack([np.full(n, length), profile])
    tris = []
    for i, j, k in T_CAPS:
        tris.append((b[i], b[j], b[k]))          # +X cap: counter-clockwise seen from +X
        tris.append((a[i], a[k], a[j]))          # -X cap: reversed
    for i in range(n):
        j = (i + 1) % n
        tris.append((a[i], a[j], b[j]))
        tris.append((a[i], b[j], b[i]))
    return np.array(tris)


def write_stl(path: str, tris: np.ndarray, title: str) -> None:
    """Binary STL with facet normals from the vertex order."""
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    with open(path, "wb") as fh:
        fh.write(title.encode("ascii")[:80].ljust(80, b" "))
        fh.write(struct.pack("<I", len(tris)))
        fh.writelines(struct.pack("<12fH", *nn, *t.ravel(), 0) for nn, t in zip(n, tris))


def cam_cutter_locations(rib: Rib = THIN_WALL):
    """The CAM default path: contacts on the finished +Y face, ball centres, tips, axes.

    Returns
    -------
    tip : ndarray, shape (n, 3) [mm]
    axis : ndarray, shape (n, 3)
    rapid : ndarray of bool, shape (n,)
    """
    incl = math.radians(rib.inclination_deg)
    u = np.array([0.0, math.cos(incl), math.sin(incl)])
    y_face = rib.wall_y0 + rib.wall_t
    xs = np.arange(rib.x_start, rib.x_end + 1e-9, rib.step)
    tips, rapid = [], []
    for z in rib.pass_heights():
        centres = np.column_stack([xs, np.full_like(xs, y_face + rib.r_ball),
                                   np.full_like(xs, z)])
        t = centres - rib.r_ball * u
        approach = t[0] + rib.clear_y * u
        retract = t[-1] + rib.clear_y * u
        tips += [approach, *t, retract]
        rapid += [True, *([False] * len(t)), False]
    tips = np.array(tips)
    return tips, np.tile(u, (len(tips), 1)), np.array(rapid)


def write_rib(out: str, rib: Rib, *, design_title: str, stock_title: str, source: str) -> dict:
    """Write a rib's ``design.stl``, ``stock.stl`` and ``cam.nc`` into the folder ``out``
    (created); the scenario file is not written. Returns a few facts of the program."""
    sys.path.insert(0, ROOT)
    from nc.kinematics import get_machine
    from nc.path import CutterLocations
    from nc.writer import PostOptions, write_program

    os.makedirs(out, exist_ok=True)
    write_stl(os.path.join(out, "design.stl"), extrude(t_profile(rib.wall_t, rib), rib.length),
              design_title)
    write_stl(os.path.join(out, "stock.stl"),
              extrude(t_profile(rib.wall_t + rib.allowance, rib), rib.length), stock_title)
    tip, axis, rapid = cam_cutter_locations(rib)
    feed = np.where(rapid, np.nan, rib.feed_mm_min)
    cl = CutterLocations.from_arrays(tip, axis, feed, rib.spindle_rpm, rapid=rapid)
    machine = get_machine(rib.machine, tool_length_mm=rib.tool_length_mm)
    res = write_program(os.path.join(out, "cam.nc"), cl, machine,
                        PostOptions(dialect="linuxcnc", source=source))
    return {"points": len(tip), "passes": int(np.sum(rapid)), "program_lines":
            res.text.count("\n")}


#: errpred's mold-ball program and the first line of its raster operation (the line
#: after the contour's last retract ``G0 Z25``; the scenario's description says so too).
MOLD_PROGRAM = os.path.join(ROOT, "errpred", "scenarios", "mold-ball", "finish.nc")
MOLD_RASTER_FIRST = 13836
#: the header lines of finish.nc kept (``%`` to ``G43 H1``) and the safe height [mm]
MOLD_HEADER_LAST = 13
MOLD_SAFE_Z = 25.0


def write_mold_core(out: str) -> dict:
    """Write ``raster.nc`` (the raster operation of errpred's mold-ball program) into the
    folder ``out`` (created). Returns a few facts of the program."""
    with open(MOLD_PROGRAM, encoding="ascii") as fh:
        lines = fh.read().splitlines()
    head, body = lines[:MOLD_HEADER_LAST], lines[MOLD_RASTER_FIRST - 1:]
    assert head[-1] == "G43 H1" and lines[MOLD_RASTER_FIRST - 2] == f"G0 Z{MOLD_SAFE_Z:g}", (
        "errpred's finish.nc changed: update MOLD_HEADER_LAST / MOLD_RASTER_FIRST")
    head = head[:2] + [f"(RASTER OPERATION OF ERRPRED MOLD-BALL FINISH.NC, ITS LINES "
                       f"{MOLD_RASTER_FIRST}-{len(lines)}, AFTER ITS HEADER)"] + head[2:]
    text = "\n".join(head + [f"G0 Z{MOLD_SAFE_Z:g}"] + body) + "\n"
    os.makedirs(out, exist_ok=True)
    with open(os.path.join(out, "raster.nc"), "w", encoding="ascii", newline="\n") as fh:
        fh.write(text)
    return {"program_lines": text.count("\n"),
            "offset_to_finish_nc_lines": MOLD_RASTER_FIRST - (len(head) + 2)}


def build(out_root: str) -> dict:
    write_mold_core(os.path.join(out_root, "mold-core"))
    return write_rib(os.path.join(out_root, "thin-wall"), THIN_WALL,
                     design_title="thin-wall design: rib 60 x 30 x 3 mm on a plate",
                     stock_title="thin-wall stock: rib with 0.2 mm on the +Y face",
                     source="thin-wall CAM default (inclination 30 deg toward +Z)")


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if argv == ["--check"]:
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        from make_errpred_scenarios import check_built

        return check_built(build, OUT)
    if argv:
        print(__doc__.split("\n\n")[1])
        return 2
    print(build(OUT))
    return 0


if __name__ == "__main__":
    sys.exit(main())
