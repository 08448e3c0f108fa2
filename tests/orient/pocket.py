"""A pocket for the planner's interference tests: a wall finished on its +Y face with
another wall 20 mm across the pocket, and a D10 ball end mill in a D40 holder.

The cross-section (Y, Z) is extruded along X over 100 mm: a plate (Y 0..60,
Z -10..0), the machined wall (Y 18.5..22, 30 mm high, 0.2 mm stock on its +Y
face) and the opposite wall (Y 42..46, ``opposite_height_mm`` high). The passes
run along the middle 24 mm, so leaning the tool along the feed does not take
the holder out of the pocket. The CAM posture is the
thin wall's (30 deg from the wall normal toward +Z): its holder reaches
over the opposite wall and, lower down, into it. The holder (D40, 20 mm
radius) is wider than the pocket, so it has to stay above the opposite wall:
with a 30 mm opposite wall steep postures clear it at every pass; with a
taller one no posture within the inclination limit does at the lower passes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

#: Pocket geometry [mm].
LENGTH, PLATE_W, PLATE_T = 100.0, 60.0, 10.0
WALL_Y0, WALL_T, WALL_H, ALLOWANCE = 18.5, 3.5, 30.0, 0.2
OPP_Y0, OPP_T = 42.0, 4.0                   # 20 mm across from the finished face (Y 22)
R_BALL, INCLINATION_DEG = 5.0, 30.0
X_START, X_END, X_STEP = 38.0, 62.0, 4.0    # contact x along a pass
CLEAR = 12.0                                # approach and retract along the CAM axis


def _profile(face_y: float, opposite_height_mm: float) -> np.ndarray:
    """Cross-section (Y, Z), counter-clockwise, shape (12, 2) [mm]."""
    return np.array([(0.0, -PLATE_T), (PLATE_W, -PLATE_T), (PLATE_W, 0.0),
                     (OPP_Y0 + OPP_T, 0.0), (OPP_Y0 + OPP_T, opposite_height_mm),
                     (OPP_Y0, opposite_height_mm), (OPP_Y0, 0.0), (face_y, 0.0),
                     (face_y, WALL_H), (WALL_Y0, WALL_H), (WALL_Y0, 0.0), (0.0, 0.0)])


#: Triangles of the profile's cap (indices into :func:`_profile`), counter-clockwise.
_CAP = ((0, 1, 2), (0, 2, 3), (0, 3, 6), (0, 6, 7), (0, 7, 10), (0, 10, 11),
        (6, 3, 4), (6, 4, 5), (10, 7, 8), (10, 8, 9))


def _extrude(profile: np.ndarray):
    """Closed mesh of the profile extruded along +X over ``LENGTH``."""
    import trimesh

    n = len(profile)
    a = np.column_stack([np.zeros(n), profile])
    b = np.column_stack([np.full(n, LENGTH), profile])
    faces = [(n + i, n + j, n + k) for i, j, k in _CAP] + [(i, k, j) for i, j, k in _CAP]
    for i in range(n):
        j = (i + 1) % n
        faces += [(i, j, n + j), (i, n + j, n + i)]
    mesh = trimesh.Trimesh(np.vstack([a, b]), np.array(faces), process=False)
    assert mesh.is_watertight and mesh.volume > 0
    return mesh


def _cam_path(pass_z: tuple[float, ...]):
    """Tips, axes and rapid flags of the CAM program (one-way passes along +X)."""
    incl = math.radians(INCLINATION_DEG)
    u = np.array([0.0, math.cos(incl), math.sin(incl)])
    face = WALL_Y0 + WALL_T
    xs = np.arange(X_START, X_END + 1e-9, X_STEP)
    tips, rapid = [], []
    for z in pass_z:
        centres = np.column_stack([xs, np.full_like(xs, face + R_BALL), np.full_like(xs, z)])
        t = centres - R_BALL * u
        tips += [t[0] + CLEAR * u, *t, t[-1] + CLEAR * u]
        rapid += [True, *([False] * len(t)), False]
    return np.array(tips), np.tile(u, (len(tips), 1)), np.array(rapid)


def pocket_scenario(folder: Path, opposite_height_mm: float = WALL_H,
                    pass_z: tuple[float, ...] = (29.0, 23.0, 17.0, 11.0),
                    grid: int = 7, orient_extra: str = "") -> Path:
    """Write the pocket scenario into ``folder`` (created); returns its TOML path.

    Parameters
    ----------
    folder : Path
    opposite_height_mm : float [mm]
        Height of the wall across the pocket.
    pass_z : tuple of float [mm]
        Contact heights of the passes, from the top down.
    grid : int
        Lead and tilt steps of the search grid (each over -60..60 deg).
    orient_extra : str
        Lines added to ``[orient]``.
    """
    from nc.kinematics import get_machine
    from nc.path import CutterLocations
    from nc.writer import PostOptions, write_program

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    _extrude(_profile(WALL_Y0 + WALL_T, opposite_height_mm)).export(folder / "design.stl")
    _extrude(_profile(WALL_Y0 + WALL_T + ALLOWANCE, opposite_height_mm)).export(
        folder / "stock.stl")
    tip, axis, rapid = _cam_path(pass_z)
    cl = CutterLocations.from_arrays(tip, axis, np.where(rapid, np.nan, 1800.0), 9000.0,
                                     rapid=rapid)
    write_program(folder / "cam.nc", cl, get_machine("xyzac-trt"),
                  PostOptions(dialect="linuxcnc", source="pocket CAM default"))
    (folder / "scenario.toml").write_text(f"""name = "pocket"
description = "Pocket 20 mm wide, D10 ball end mill in a D40 holder (tests)."

[stock]
stl = "stock.stl"
design_stl = "design.stl"

[tool]
type = "ball"
diameter_mm = 10.0
flutes = 2
helix_deg = 30.0
flute_length_mm = 15.0
overhang_mm = 35.0
rotation = "cw"
shank_diameter_mm = 10.0

[tool.holder]
diameter_mm = 40.0
length_mm = 50.0

[program]
gcode = "cam.nc"
machine = "xyzac-trt"

[cutting]
Ktc_N_mm2 = 3680.0
Krc_N_mm2 = 1470.0
Kac_N_mm2 = 550.0
Kte0_N_mm = 37.7
Kre0_N_mm = 45.2
Kae0_N_mm = 11.3

[dynamics]
model = "dynamic"

[[dynamics.modes]]
direction = "x"
frequency_hz = 3600.0
damping_ratio = 0.03
stiffness_N_m = 1.6e7

[[dynamics.modes]]
direction = "y"
frequency_hz = 3700.0
damping_ratio = 0.03
stiffness_N_m = 1.7e7

[orient]
lead_deg = [-60.0, 60.0]
tilt_deg = [-60.0, 60.0]
grid = [{grid}, {grid}]
max_inclination_deg = 70.0
verify_sdm = false
{orient_extra}
[orient.cut]
depth_mm = 0.2
pick_mm = 0.5
machined_side = [0.0, 0.0, 1.0]
""")
    return folder / "scenario.toml"
