"""Make the bundled 5-axis cutter-location file ``nc/data/blade_cl.csv``.

The shape: the pressure side of a twisted blade, a ruled surface between a
hub section (z = 0) and a tip section (z = 40 mm), 60 mm long, cambered by
8 mm and twisted by 12 deg over its height. A ball end mill of radius 3 mm
finishes it in zig-zag passes along the blade from 4 mm to 38 mm above the
hub, stepping up 2 mm per pass;
the tool axis is inclined 40 deg from the surface normal toward +Z (the
tool comes from above, as it must on a wall) with a 10 deg lead along the
feed. Tip = contact point + R n - R u (ball centre R off the surface).

Run from the repository root: ``python scripts/make_blade_cl.py``. The
output is deterministic.
"""

from __future__ import annotations

import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from nc.path import CutterLocations, write_cl_csv  # noqa: E402

R_BALL_MM = 3.0
LENGTH_MM, HEIGHT_MM, CAMBER_MM = 60.0, 40.0, 8.0
TWIST_RAD = math.radians(12.0)
INCLINATION_RAD = math.radians(40.0)
LEAD_RAD = math.radians(10.0)
FIRST_PASS_MM, LAST_PASS_MM, STEP_UP_MM, POINTS_PER_PASS = 4.0, 38.0, 2.0, 81
FEED_MM_MIN, SPINDLE_RPM = 1500.0, 12000.0


def surface(t: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Blade surface point at length fraction t in [0, 1], height fraction s."""
    x = LENGTH_MM * (t - 0.5)
    y = CAMBER_MM * np.sin(np.pi * t)
    # twist about the vertical line through the blade's middle, growing with height
    ang = TWIST_RAD * s
    xr = x * np.cos(ang) - (y - CAMBER_MM / 2) * np.sin(ang)
    yr = x * np.sin(ang) + (y - CAMBER_MM / 2) * np.cos(ang) + CAMBER_MM / 2
    return np.stack([xr, yr - 2.0 * s, HEIGHT_MM * s], axis=-1)


def frame(t: np.ndarray, s: np.ndarray, h: float = 1e-6):
    """Contact point, outward normal, feed direction (along +t) and up tangent."""
    p = surface(t, s)
    dt = (surface(t + h, s) - surface(t - h, s)) / (2 * h)
    ds = (surface(t, s + h) - surface(t, s - h)) / (2 * h)
    n = np.cross(ds, dt)  # outward: the concave (pressure) side faces -y
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    n[n[:, 1] > 0] *= -1
    f = dt / np.linalg.norm(dt, axis=-1, keepdims=True)
    up = ds - (ds * n).sum(-1, keepdims=True) * n
    up /= np.linalg.norm(up, axis=-1, keepdims=True)
    return p, n, f, up


def cutter_locations() -> CutterLocations:
    tips, axes = [], []
    n_pass = int(round((LAST_PASS_MM - FIRST_PASS_MM) / STEP_UP_MM)) + 1
    for k in range(n_pass):
        s = np.full(POINTS_PER_PASS, (FIRST_PASS_MM + k * STEP_UP_MM) / HEIGHT_MM)
        t = np.linspace(0.05, 0.95, POINTS_PER_PASS)
        if k % 2:
            t = t[::-1]
        p, n, f, up = frame(t, s)
        if k % 2:
            f = -f
        u = np.cos(INCLINATION_RAD) * n + np.sin(INCLINATION_RAD) * up
        u = np.cos(LEAD_RAD) * u + np.sin(LEAD_RAD) * f
        u /= np.linalg.norm(u, axis=-1, keepdims=True)
        tips.append(p + R_BALL_MM * n - R_BALL_MM * u)
        axes.append(u)
    tip, axis = np.vstack(tips), np.vstack(axes)
    return CutterLocations.from_arrays(tip, axis, FEED_MM_MIN, SPINDLE_RPM)


def main() -> None:
    out = os.path.join(os.path.dirname(__file__), "..", "nc", "data", "blade_cl.csv")
    cl = cutter_locations()
    write_cl_csv(out, cl)
    print(f"wrote {os.path.normpath(out)}: {len(cl)} cutter locations")


if __name__ == "__main__":
    main()
