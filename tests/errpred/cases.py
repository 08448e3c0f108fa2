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
