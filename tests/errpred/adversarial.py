"""Scenarios unlike the bundled ones, where a correction or a pre-check can go wrong.

Each builder writes a complete errpred scenario (stock and design STL, program,
``scenario.toml``) into a folder and returns the scenario file. The tool, the
cutting coefficients and the dynamics are the bundled wall-radius scenario's
(JP5804367's worked example: D20 corner R1, 2 inserts, helix 0; ``stiffness_scale``
softens the tool, as a longer overhang does); the geometry is what changes:

* :func:`steep_wall`: a straight wall inclined 89.5 deg, six waterline levels
  0.5 mm apart in 10 mm G1 blocks, the tool entering and leaving the wall inside
  blocks (lead-in and lead-out in air); optionally zigzag.
* :func:`full_circle`: a round boss finished by one full circle (``G2`` with
  equal start and end) per level, Fanuc style.
* :func:`two_islands`: one G1 line from X10 to X90 across two islands of stock
  whose quarter points are all in air.
* :func:`rapid_into_stock`: a ``G0`` that plunges into the stock.
* :func:`deep_side_cut`: a side cut along a block 30 mm high, in one pass deeper
  than the flutes (10 mm) or in levels no deeper than them.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import trimesh

#: The wall-radius scenario's tool, coefficients, dynamics and shape error, verbatim.
_COMMON = """
[tool]
type = "radius"
diameter_mm = 20.0
corner_radius_mm = 1.0
flutes = 2
helix_deg = 0.0
flute_length_mm = 10.0
overhang_mm = 100.0
rotation = "cw"
shank_diameter_mm = 20.0

[cutting]
Ktc_N_mm2 = 4060.0
Krc_N_mm2 = 1620.0
Kac_N_mm2 = 0.0
Kte0_N_mm = 28.4
Kre0_N_mm = 34.1
Kae0_N_mm = 0.0
Kte1_N_mm2 = 2.840e-04
Kre1_N_mm2 = 3.410e-04
Kae1_N_mm2 = 0.0

[dynamics]
model = "dynamic"

[[dynamics.modes]]
direction = "x"
frequency_hz = 1150.0
damping_ratio = 0.03
stiffness_N_m = 4.000e+06

[[dynamics.modes]]
direction = "x"
frequency_hz = 2600.0
damping_ratio = 0.045
stiffness_N_m = 1.800e+07

[[dynamics.modes]]
direction = "y"
frequency_hz = 1210.0
damping_ratio = 0.032
stiffness_N_m = 4.400e+06

[[dynamics.modes]]
direction = "y"
frequency_hz = 2750.0
damping_ratio = 0.045
stiffness_N_m = 2.000e+07

[shape_error]
kappa_deg = [0.0, 30.0, 60.0, 75.0, 87.0, 90.0]
radius_deviation_um = [1.0, 0.5, -0.5, -1.5, -2.5, -3.0]
wear_rate_um_per_m = 0.2
"""

#: Wall inclination of :func:`steep_wall` from the horizontal [deg].
WALL_DEG = 89.5
#: Radial allowance left on the walls [mm].
ALLOWANCE_MM = 0.2


def _write(folder: Path, name: str, stock: trimesh.Trimesh, design: trimesh.Trimesh | None,
           gcode: str, extra: str = "", stiffness_scale: float = 1.0) -> Path:
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    assert stock.is_watertight, "stock must be closed"
    stock.export(folder / "stock.stl")
    design_key = ""
    if design is not None:
        design.export(folder / "design.stl")
        design_key = 'design_stl = "design.stl"\n'
    (folder / "program.nc").write_text(gcode)
    common = _COMMON
    for k in ("4.000e+06", "1.800e+07", "4.400e+06", "2.000e+07"):
        common = common.replace(f"stiffness_N_m = {k}",
                                f"stiffness_N_m = {float(k) * stiffness_scale:.4e}")
    toml = (f'name = "{name}"\n\n[stock]\nstl = "stock.stl"\n{design_key}\n'
            f'[program]\ngcode = "program.nc"\n{common}{extra}')
    path = folder / "scenario.toml"
    path.write_text(toml)
    return path


def _slab(x: tuple[float, float], y_back: float, z: tuple[float, float], face_y) -> trimesh.Trimesh:
    """Solid x0 <= x <= x1, face_y(z) <= y <= y_back, z0 <= z <= z1 (face_y linear in z)."""
    (x0, x1), (z0, z1) = x, z
    v = np.array([[x0, face_y(z0), z0], [x1, face_y(z0), z0], [x1, y_back, z0],
                  [x0, y_back, z0], [x0, face_y(z1), z1], [x1, face_y(z1), z1],
                  [x1, y_back, z1], [x0, y_back, z1]])
    hull = trimesh.convex.convex_hull(v)
    return hull


def steep_wall_tip_y(z_tip: float, height: float = 20.0, deg: float = WALL_DEG,
                     R: float = 10.0, r: float = 1.0) -> float:
    """Tip Y [mm] at which the corner torus of a vertical radius end mill (R, r) touches
    the design wall y = (z - height) tan(90 deg - deg) from the -Y side."""
    a = math.radians(90.0 - deg)
    z_c = z_tip + r - r * math.sin(a)
    return (z_c - height) * math.tan(a) - (R - r) - r * math.cos(a)


def steep_wall(folder: Path, *, levels: int = 6, pitch: float = 0.5, block: float = 10.0,
               feed: float = 1350.0, spindle: float = 2700.0, zigzag: bool = False,
               up_milling: bool = False, length: float = 60.0, stiffness_scale: float = 1.0,
               extra: str = "") -> Path:
    """A straight wall along X (0..``length`` mm) inclined ``WALL_DEG``, in waterline levels.

    Material at +Y; the design wall is y = (z - 20) tan(0.5 deg), the stock leaves
    ``ALLOWANCE_MM`` on it. Each level is one G1 line from X-15 to X``length + 15``
    in ``block`` mm blocks, so the tool enters and leaves the wall inside a block.
    Every level runs the same way (+X, down milling with the clockwise tool; -X, up
    milling, with ``up_milling``), with a retract between levels; ``zigzag``:
    alternate levels run back and the step down is a G1 in air.
    """
    a = math.radians(90.0 - WALL_DEG)
    H = 20.0
    face = lambda z: (z - H) * math.tan(a)                                  # noqa: E731
    off = ALLOWANCE_MM / math.cos(a)
    design = _slab((0.0, length), 30.0, (0.0, H), face)
    stock = _slab((0.0, length), 30.0, (0.0, H), lambda z: face(z) - off)
    xs = np.arange(-15.0, length + 15.0 + 1e-9, block)
    lines = ["%", "O1601 (STEEP WALL 89.5 DEG, WATERLINE)", "G21 G90 G17 G94 G40 G49 G80",
             f"S{spindle:g} M3"]
    for k in range(levels):
        z = H - pitch * (k + 1)
        y = steep_wall_tip_y(z, H)
        first = xs[::-1] if up_milling else xs
        path = first[::-1] if zigzag and k % 2 else first
        if k == 0 or not zigzag:
            lines += [f"G0 X{path[0]:.4f} Y{y:.4f}", f"G0 Z{z + 5:.4f}",
                      f"G1 Z{z:.4f} F{feed:g}"]
        else:
            lines.append(f"G1 Y{y:.4f} Z{z:.4f}")
        lines += [f"X{x:.4f}" for x in path[1:]]
        if not zigzag:
            lines.append(f"G0 Z{H + 5:.4f}")
    lines += ["G0 Z30", "M30", "%"]
    return _write(folder, "steep-wall", stock, design, "\n".join(lines) + "\n", extra,
                  stiffness_scale)


def full_circle(folder: Path, *, radius: float = 30.0, levels: int = 2, pitch: float = 0.5,
                feed: float = 1350.0, spindle: float = 2700.0, stiffness_scale: float = 1.0,
                extra: str = "") -> Path:
    """A round boss (radius ``radius``, vertical wall) finished by one full ``G2`` per level.

    Fanuc style: the circle starts and ends at the same point (``G2 X.. Y.. I..``),
    reached by a straight lead-in from outside.
    """
    H = 10.0
    design = trimesh.creation.cylinder(radius=radius, height=H, sections=256,
                                       transform=trimesh.transformations.translation_matrix(
                                           (0, 0, H / 2)))
    stock = trimesh.creation.cylinder(radius=radius + ALLOWANCE_MM, height=H, sections=256,
                                      transform=trimesh.transformations.translation_matrix(
                                          (0, 0, H / 2)))
    R = 10.0
    rc = radius + R                      # tool axis on a circle R outside the wall
    lines = ["%", "O1602 (FULL CIRCLE BOSS)", "G21 G90 G17 G94 G40 G49 G80", f"S{spindle:g} M3",
             f"G0 X{-rc - 15:.4f} Y0", "G0 Z15"]
    for k in range(levels):
        z = H - pitch * (k + 1)
        lines += [f"G1 Z{z:.4f} F{feed:g}", f"G1 X{-rc:.4f}",
                  f"G2 X{-rc:.4f} Y0 I{rc:.4f} J0", f"G1 X{-rc - 15:.4f}"]
    lines += ["G0 Z30", "M30", "%"]
    return _write(folder, "full-circle", stock, design, "\n".join(lines) + "\n", extra,
                  stiffness_scale)


def two_islands(folder: Path, *, feed: float = 1350.0, spindle: float = 2700.0,
                extra: str = "") -> Path:
    """One G1 line from X10 to X90 at Y0 across two islands of stock that only its
    middle stretches touch.

    The islands (X 38..42 and X 58..62, Y 6.5..12, 5 mm high) stand beside the
    line; the D20 tool, 0.3 mm below their top, reaches them while its centre is
    within 7.6 mm of X 40 or X 60. At the line's quarter points (X 30, 50, 70) it
    is 10 mm away from both and cuts nothing.
    """
    isl = [trimesh.creation.box(extents=(4.0, 5.5, 5.0),
                                transform=trimesh.transformations.translation_matrix(
                                    (cx, 9.25, 2.5)))
           for cx in (40.0, 60.0)]
    stock = trimesh.util.concatenate(isl)
    z = 5.0 - 0.3
    lines = ["%", "O1603 (TWO ISLANDS)", "G21 G90 G17 G94 G40 G49 G80", f"S{spindle:g} M3",
             "G0 X10 Y0", "G0 Z15", f"G1 Z{z:.4f} F{feed:g}", "G1 X90", "G0 Z30", "M30", "%"]
    return _write(folder, "two-islands", stock, None, "\n".join(lines) + "\n", extra)


def rapid_into_stock(folder: Path, *, feed: float = 1350.0, spindle: float = 2700.0,
                     extra: str = "") -> Path:
    """A ``G0`` that plunges 2 mm into a block of stock, then a G1 out of it."""
    stock = trimesh.creation.box(extents=(40.0, 40.0, 10.0),
                                 transform=trimesh.transformations.translation_matrix((20, 20, 5)))
    lines = ["%", "O1604 (RAPID INTO STOCK)", "G21 G90 G17 G94 G40 G49 G80", f"S{spindle:g} M3",
             "G0 X20 Y20 Z15", "G0 Z8", f"G1 X60 F{feed:g}", "G0 Z30", "M30", "%"]
    return _write(folder, "rapid-into-stock", stock, None, "\n".join(lines) + "\n", extra)


def deep_side_cut(folder: Path, levels: tuple[float, ...], *, base_z: float = 0.0,
                  ramp_to: float | None = None, feed: float = 1350.0,
                  spindle: float = 2700.0) -> Path:
    """Side cuts 2 mm wide along the front face (y = 0) of a block 40 x 40 mm from
    ``base_z`` up to z = 30, one pass along +X at each tip height of ``levels``, in that
    order; the tool's flutes are 10 mm long. Pass ``k``'s cutting move is on program line
    ``7 + 4 k``. With the block's base well under the tip, the tool's bottom view lies
    inside the material over all its depth. With ``ramp_to``, each pass ramps down to
    that tip height at its end (X55)."""
    stock = trimesh.creation.box(bounds=[[0.0, 0.0, base_z], [40.0, 40.0, 30.0]])
    lines = ["%", "O1605 (DEEP SIDE CUT)", "G21 G90 G17 G94 G40 G49 G80", f"S{spindle:g} M3"]
    y = -10.0 + 2.0        # the D20 tool's axis: 2 mm into the face
    for z in levels:
        end = "" if ramp_to is None else f" Z{ramp_to:g}"
        lines += [f"G0 X-15 Y{y:g} Z40", f"G0 Z{z:g}", f"G1 X55{end} F{feed:g}", "G0 Z40"]
    lines += ["M30", "%"]
    return _write(folder, "deep-side-cut", stock, None, "\n".join(lines) + "\n")
