"""Small synthetic machining cases shared by the errpred tests.

Every case is built from geometry whose answer is known by hand: a plane
(possibly inclined) finished by a ball end mill in raster passes, a wall
side-milled by a flat end mill, a slot.
"""

from __future__ import annotations

import math

import numpy as np
import trimesh

from errpred.coefficients import CuttingCoefficients
from errpred.dynamics import Compliance, Mode
from errpred.raster.meshes import Stock

#: Representative steel finishing coefficients for the synthetic cases
#: (N/mm^2 and N/mm); the tests compare the model with itself or with
#: closed forms, so any realistic values do.
STEEL = CuttingCoefficients(Ktc_N_mm2=2000.0, Krc_N_mm2=800.0, Kac_N_mm2=300.0,
                            Kte0_N_mm=20.0, Kre0_N_mm=25.0, Kae0_N_mm=5.0)


def stiff_tool(f_hz: float = 2500.0, k_N_m: float = 5e6, zeta: float = 0.03) -> Compliance:
    return Compliance.from_modes({"x": [Mode.from_frequency(f_hz, zeta, k_N_m)],
                                  "y": [Mode.from_frequency(1.04 * f_hz, zeta, k_N_m)]})


def heightfield_stock(fn, x_range, y_range, step: float, bottom: float) -> Stock:
    """A closed solid under z = fn(x, y) over a rectangle, down to ``bottom``."""
    xs = np.arange(x_range[0], x_range[1] + 1e-9, step)
    ys = np.arange(y_range[0], y_range[1] + 1e-9, step)
    X, Y = np.meshgrid(xs, ys)
    Z = fn(X, Y)
    ny, nx = X.shape
    top = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
    bot = top.copy()
    bot[:, 2] = bottom
    nv = top.shape[0]
    idx = np.arange(nv).reshape(ny, nx)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    faces = [np.column_stack([a, b, c]), np.column_stack([a, c, d]),
             np.column_stack([a, c, b]) + nv, np.column_stack([a, d, c]) + nv]
    ring = np.concatenate([idx[0, :], idx[1:, -1], idx[-1, -2::-1], idx[-2:0:-1, 0]])
    p, q = ring, np.roll(ring, -1)
    faces += [np.column_stack([p, q + nv, q]), np.column_stack([p, p + nv, q + nv])]
    mesh = trimesh.Trimesh(np.vstack([top, bot]), np.vstack(faces), process=True)
    trimesh.repair.fix_normals(mesh)
    assert mesh.is_watertight
    return Stock.from_mesh(mesh)


def plane_raster(slope_deg: float, R: float, *, passes: int = 8, pick: float = 0.4,
                 length: float = 16.0, step: float = 0.5, axis=None, feed=1600.0,
                 spindle=8000.0) -> str:
    """G-code: raster passes along X on the plane z = -tan(slope) x.

    The ball (radius R) touches the plane; ``axis`` (unit, optional) tilts
    the tool (a G43.5 tool-vector program); the tip is then centre - R axis.
    """
    t = math.tan(math.radians(slope_deg))
    n = np.array([t, 0.0, 1.0]) / math.hypot(t, 1.0)
    u = np.array([0.0, 0.0, 1.0]) if axis is None else np.asarray(axis, float)
    five = axis is not None
    lines = ["G21 G90 G17 G94", f"S{spindle:g} M3"]
    if five:
        lines.append("G43.5 H1")
    for k in range(passes):
        y = k * pick
        xs = np.arange(0.0, length + 1e-9, step)
        if k % 2:
            xs = xs[::-1]
        for i, x in enumerate(xs):
            contact = np.array([x, y, -t * x])
            tip = contact + R * n - R * u
            vec = f" I{u[0]:.6f} J{u[1]:.6f} K{u[2]:.6f}" if five else ""
            if i == 0:
                lines.append(f"G0 X{tip[0]:.5f} Y{tip[1]:.5f} Z{tip[2] + 5:.5f}{vec}")
                lines.append(f"G1 Z{tip[2]:.5f} F{feed:g}")
            else:
                lines.append(f"G1 X{tip[0]:.5f} Y{tip[1]:.5f} Z{tip[2]:.5f}{vec}")
        lines.append(f"G0 Z{tip[2] + 5:.5f}")
    lines.append("M30")
    return "\n".join(lines) + "\n"


def plane_stock(slope_deg: float, allowance: float) -> Stock:
    t = math.tan(math.radians(slope_deg))
    lift = allowance / math.cos(math.radians(slope_deg))
    return heightfield_stock(lambda X, Y: -t * X + lift, (-8, 26), (-8, 12), 1.0, -30.0)


# --- a wall side-milled by a straight-flute flat end mill (tool wear tests) ---------------
#: The wall: a box whose bottom and top (z 2 and 8 mm above the tip) fall on micro-edge
#: boundaries of the D10 flat end mill (flank micro edges 0.0625 mm long from z = 0), so
#: every flank micro edge between them cuts the whole of its length: all the edges that
#: shape the wall have the same actual cutting distance.
WALL_BOX_MM = ((0.0, -60.0, 2.0), (20.0, 60.0, 8.0))
#: Radial depth of cut into the wall's x = 0 face [mm].
WALL_AE_MM = 0.3


def wall_tool():
    from errpred.tool import Tool

    return Tool("flat", 10.0, flutes=2, helix_deg=0.0, flute_length_mm=12.0)


def wall_passes(y_from: float, y_to: float, step: float = 10.0, *, header: bool = True,
                end: bool = True, feed: float = 600.0, spindle: float = 6000.0) -> list[str]:
    """G-code lines: one pass along Y at depth WALL_AE_MM, entering from outside the wall.

    The tool comes down outside the stock (beyond its Y end), cuts from ``y_from`` to
    ``y_to`` in blocks of ``step`` mm and goes up again (within its own slot: no cut).
    """
    x = -5.0 + WALL_AE_MM
    out = ["G21 G90 G94", f"S{spindle:g} M3"] if header else []
    out += [f"G0 X{x:g} Y{y_from:g} Z20", "G0 Z0"]
    n = int(round(abs(y_to - y_from) / step))
    sign = 1.0 if y_to > y_from else -1.0
    out += [f"G1 Y{y_from + sign * step * k:g} F{feed:g}" for k in range(1, n + 1)]
    out.append("G0 Z20")
    if end:
        out.append("M30")
    return out


def write_wall_scenario(folder, name: str, program_lines: list[str], *, wear_rate_um_per_m=0.2,
                        edge_wear: bool = True, tool_extra: str = "",
                        tolerance_um: float | None = 30.0) -> str:
    """A scenario file (and its program) for the wall case in ``folder``; returns its path.

    Cutting coefficients :data:`STEEL`, with the wall-radius scenario's wear growth
    (edge force doubling after 100 m) when ``edge_wear``; the tool's dynamics those of
    :func:`stiff_tool`. ``tool_extra``: more lines in ``[tool]`` (a start state).
    """
    import os

    (folder / f"{name}.nc").write_text("\n".join(program_lines) + "\n")
    lo, hi = WALL_BOX_MM
    wear = ("Kte1_N_mm2 = 2.0e-4\nKre1_N_mm2 = 2.5e-4\nKae1_N_mm2 = 5.0e-5\n"
            if edge_wear else "")
    tc = f"[tool_change]\ntolerance_um = {tolerance_um!r}\n" if tolerance_um else ""
    text = f"""name = "{name}"

[stock]
box_min_mm = {list(lo)}
box_max_mm = {list(hi)}

[tool]
type = "flat"
diameter_mm = 10.0
flutes = 2
helix_deg = 0.0
flute_length_mm = 12.0
{tool_extra}

[program]
gcode = "{name}.nc"

[cutting]
Ktc_N_mm2 = {STEEL.Ktc_N_mm2!r}
Krc_N_mm2 = {STEEL.Krc_N_mm2!r}
Kac_N_mm2 = {STEEL.Kac_N_mm2!r}
Kte0_N_mm = {STEEL.Kte0_N_mm!r}
Kre0_N_mm = {STEEL.Kre0_N_mm!r}
Kae0_N_mm = {STEEL.Kae0_N_mm!r}
{wear}
[[dynamics.modes]]
direction = "x"
frequency_hz = 2500.0
damping_ratio = 0.03
stiffness_N_m = 5.0e6

[[dynamics.modes]]
direction = "y"
frequency_hz = 2600.0
damping_ratio = 0.03
stiffness_N_m = 5.0e6

[shape_error]
wear_rate_um_per_m = {wear_rate_um_per_m!r}

{tc}"""
    path = folder / f"{name}.toml"
    path.write_text(text)
    return os.fspath(path)
