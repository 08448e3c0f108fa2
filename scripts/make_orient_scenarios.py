"""Make the bundled orient scenario ``orient/scenarios/thin-wall/``.

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
"""

from __future__ import annotations

import math
import os
import struct
import sys

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
OUT = os.path.join(ROOT, "orient", "scenarios")

# ----------------------------------------------------------------- thin-wall geometry [mm]
LENGTH, PLATE_W, PLATE_T = 60.0, 40.0, 10.0     # plate: X 0..60, Y 0..40, Z -10..0
WALL_Y0, WALL_T, WALL_H = 18.5, 3.5, 30.0      # finished wall: Y 18.5..22, Z 0..30
ALLOWANCE = 0.2                                  # stock on the +Y face
R_BALL = 5.0
INCLINATION_DEG = 30.0                           # CAM default: from the normal toward +Z
PICK, Z_TOP, Z_LOW = 0.5, 29.5, 6.0              # contact heights of the passes
X_START, X_END, STEP = -6.0, 66.0, 2.0           # contact x of a pass (ball clear at both ends)
SPINDLE, FEED = 9000.0, 1800.0                   # fz = 0.1 mm
CLEAR_Y = 12.0                                   # retract along +Y between passes


def t_profile(thickness: float) -> np.ndarray:
    """The rib's cross-section (Y, Z), counter-clockwise, shape (8, 2) [mm]."""
    y1 = WALL_Y0 + thickness
    return np.array([(0.0, -PLATE_T), (PLATE_W, -PLATE_T), (PLATE_W, 0.0), (y1, 0.0),
                     (y1, WALL_H), (WALL_Y0, WALL_H), (WALL_Y0, 0.0), (0.0, 0.0)])


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


def cam_cutter_locations():
    """The CAM default path: contacts on the finished +Y face, ball centres, tips, axes.

    Returns
    -------
    tip : ndarray, shape (n, 3) [mm]
    axis : ndarray, shape (n, 3)
    rapid : ndarray of bool, shape (n,)
    """
    incl = math.radians(INCLINATION_DEG)
    u = np.array([0.0, math.cos(incl), math.sin(incl)])
    y_face = WALL_Y0 + WALL_T
    xs = np.arange(X_START, X_END + 1e-9, STEP)
    zs = np.arange(Z_TOP, Z_LOW - 1e-9, -PICK)
    tips, rapid = [], []
    for z in zs:
        centres = np.column_stack([xs, np.full_like(xs, y_face + R_BALL), np.full_like(xs, z)])
        t = centres - R_BALL * u
        approach = t[0] + CLEAR_Y * u
        retract = t[-1] + CLEAR_Y * u
        tips += [approach, *t, retract]
        rapid += [True, *([False] * len(t)), False]
    tips = np.array(tips)
    return tips, np.tile(u, (len(tips), 1)), np.array(rapid)


def build(out_root: str) -> dict:
    sys.path.insert(0, ROOT)
    from nc.kinematics import get_machine
    from nc.path import CutterLocations
    from nc.writer import PostOptions, write_program

    out = os.path.join(out_root, "thin-wall")
    os.makedirs(out, exist_ok=True)
    write_stl(os.path.join(out, "design.stl"), extrude(t_profile(WALL_T), LENGTH),
              "thin-wall design: rib 60 x 30 x 3 mm on a plate")
    write_stl(os.path.join(out, "stock.stl"), extrude(t_profile(WALL_T + ALLOWANCE), LENGTH),
              "thin-wall stock: rib with 0.2 mm on the +Y face")
    tip, axis, rapid = cam_cutter_locations()
    feed = np.where(rapid, np.nan, FEED)
    cl = CutterLocations.from_arrays(tip, axis, feed, SPINDLE, rapid=rapid)
    machine = get_machine("xyzac-trt")
    res = write_program(os.path.join(out, "cam.nc"), cl, machine,
                        PostOptions(dialect="linuxcnc", source="thin-wall CAM default "
                                    "(inclination 30 deg toward +Z)"))
    return {"points": len(tip), "passes": int(np.sum(rapid)), "program_lines":
            res.text.count("\n")}


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
