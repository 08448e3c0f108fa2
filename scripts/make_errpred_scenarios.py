"""Make the bundled errpred scenarios ``errpred/scenarios/<name>/``.

Run from anywhere: ``python scripts/make_errpred_scenarios.py`` rewrites every
file of both scenarios (deterministic: same bytes on every run);
``--check`` regenerates into a temporary folder and fails if the committed
files differ.

mold-ball: a D10 ball end mill finishing a free-form core in P20-class steel.
The design (:func:`design_z`, analytic) is an elliptic core 16 mm high on a
60 x 40 mm plate, flanks up to 60 deg, a saddle on top; smallest concave
radius 5.9 mm > the ball radius, so the ball touches it at one point. The
stock is the design offset by 0.15 mm. Tips come from an exact drop-cutter
(:func:`drop_ball`, height error < 1e-6 mm), checked by a different method
(:func:`check_no_gouge`, 3-D distance from the ball centre). Contours (climb)
Z 14.5..2.0 every 0.25 mm, then raster along +X (pick 0.35 mm) where the
slope is under 40 deg; chord tolerance 4 um, blocks up to 0.6 mm.

wall-radius: JP5804367's example (para. 0097-0104), radius end mill D20 r1,
helix 0, 2700 min^-1, 1300 mm/min, Z pitch 0.5, radial allowance 0.2, down
cut, dry, S55C, around a 3-deg drafted rounded-rectangle boss; lines and G2.
"""

from __future__ import annotations

import filecmp
import math
import os
import sys
import tempfile

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
OUT = os.path.join(ROOT, "errpred", "scenarios")

# ----------------------------------------------------------------- mold-ball design surface
CX, CY, AY = 30.0, 20.0, 0.7            # core centre; y squeeze of the ellipse
R0, R1, W, H = 10.0, 22.0, 4.5, 16.0    # plateau / foot radii, fillet width, height
S, SA, SB = 2.0, 10.0, 7.0              # saddle amplitude and its x / y scales
PLATE = ((0.0, 60.0), (0.0, 40.0))      # design / stock footprint [mm]
BOTTOM_Z = -10.0                        # bottom face of the design and stock solids
R_BALL, ALLOWANCE, GRID_MM = 5.0, 0.15, 0.3
SPINDLE, FEED, PLUNGE = 10000, 1600.0, 400.0       # fz = 1600 / (2 * 10000) = 0.08 mm
SAFE_Z, CHORD_TOL, MAX_STEP = 25.0, 0.004, 0.6
Z_HI, Z_LO, DZ = 14.5, 2.0, 0.25
PICK, Y_FIRST, X_START, X_END, STEEP_DEG = 0.35, 0.2, -5.5, 65.5, 40.0


def _lc(t):
    """``W log cosh(t / W)`` without overflow."""
    a = np.abs(t) / W
    return W * (a + np.log1p(np.exp(-2.0 * a)) - math.log(2.0))


def design_z(x, y):
    """Height of the mold-ball design surface at (x, y) [mm] (analytic, C-infinity)."""
    dx, dy = np.asarray(x) - CX, np.asarray(y) - CY
    r = np.sqrt(dx * dx + (dy / AY) ** 2)
    t = -(_lc(r - R0) - _lc(r - R1) + _lc(r + R0) - _lc(r + R1)) / (2.0 * (R1 - R0))
    saddle = S * ((dx / SA) ** 2 - (dy / SB) ** 2)
    base = np.cos(np.pi * dx / 45.0) * np.cos(np.pi * dy / 50.0) + 0.04 * dx
    return (H + saddle) * t + base


def slope_deg(u, v, h=1e-5):
    """Slope of the design surface at (u, v) [deg]."""
    fx = (design_z(u + h, v) - design_z(u - h, v)) / (2 * h)
    fy = (design_z(u, v + h) - design_z(u, v - h)) / (2 * h)
    return np.degrees(np.arctan(np.hypot(fx, fy)))


def _zoom(obj, bu, bv, step, levels):
    """Refine maximisers (bu, bv) of ``obj(U, V)`` by 9 x 9 searches, 4 times finer each."""
    k = np.arange(-4, 5)
    ku, kv = (a.ravel() for a in np.meshgrid(k, k))
    rows = np.arange(bu.size)
    for _ in range(levels):
        step /= 4.0
        U, V = bu[:, None] + ku * step, bv[:, None] + kv * step
        G = obj(U, V)
        j = np.argmax(G, axis=1)
        bu, bv, best = U[rows, j], V[rows, j], G[rows, j]
    return bu, bv, best


def drop_ball(x, y, R, samples=20, levels=4, chunk=2000):
    """Drop a ball of radius R onto the design: tip z and contact (u, v).

    The ball centre height is ``max over |(u,v)-(x,y)| <= R of f(u,v) +
    sqrt(R^2 - d^2)``: first over a grid of ``2 samples + 1`` squared points in
    the disc, then four 9 x 9 searches, each 4 times finer, around the best.
    """
    x, y = np.asarray(x, float).ravel(), np.asarray(y, float).ravel()
    g = np.linspace(-R, R, 2 * samples + 1)
    du, dv = (a.ravel() for a in np.meshgrid(g, g))
    keep = du * du + dv * dv <= R * R
    du, dv = du[keep], dv[keep]
    cap = np.sqrt(R * R - du * du - dv * dv)
    tip, cu, cv = np.empty(x.size), np.empty(x.size), np.empty(x.size)
    for s in range(0, x.size, chunk):
        X, Y = x[s:s + chunk, None], y[s:s + chunk, None]

        def height(U, V):
            d2 = U * U + V * V
            G = design_z(X + U, Y + V) + np.sqrt(np.maximum(R * R - d2, 0.0))
            return np.where(d2 <= R * R, G, -np.inf)

        j = np.argmax(design_z(X + du, Y + dv) + cap, axis=1)
        bu, bv, best = _zoom(height, du[j], dv[j], g[1] - g[0], levels)
        tip[s:s + chunk] = best - R
        cu[s:s + chunk], cv[s:s + chunk] = x[s:s + chunk] + bu, y[s:s + chunk] + bv
    return tip, cu, cv


def check_no_gouge(tips, R):
    """Distance from ball centres ``tip + R z`` to the design surface [mm].

    Independent of :func:`drop_ball`'s objective: minimises the 3-D distance
    over surface points (a 0.1 mm grid over the disc, then zoomed searches).
    """
    c = np.asarray(tips, float) + [0.0, 0.0, R]
    g = np.arange(-R, R + 1e-9, 0.1)
    du, dv = (a.ravel() for a in np.meshgrid(g, g))
    out = np.empty(len(c))
    for s in range(0, len(c), 500):
        X, Y, Z = (c[s:s + 500, i, None] for i in range(3))

        def closeness(U, V):
            return -(U ** 2 + V ** 2 + (design_z(X + U, Y + V) - Z) ** 2)

        j = np.argmax(closeness(du, dv), axis=1)
        out[s:s + 500] = np.sqrt(-_zoom(closeness, du[j], dv[j], 0.1, 6)[2])
    return out


# ----------------------------------------------------------------- meshes and files
def write_stl(path, tris, title):
    """Binary STL of triangles (n, 3, 3) [mm], float32, fixed header."""
    tris = np.asarray(tris, dtype=np.float64)
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    rec = np.zeros(len(tris), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["n"], rec["v"] = n, tris
    with open(path, "wb") as fh:
        fh.write(title.encode("ascii")[:80].ljust(80, b" "))
        fh.write(np.uint32(len(tris)).tobytes())
        fh.write(rec.tobytes())


def heightfield_solid(xs, ys, Z, Zc, z_bottom):
    """Closed solid: a grid heightfield top, vertical sides, flat bottom.

    ``Zc`` (cell centre heights) picks, per cell, the diagonal whose midpoint
    is nearer the true surface. Returns triangles (n, 3, 3), outward normals.
    """
    X, Y = np.meshgrid(xs, ys)
    P = np.stack([X, Y, Z], axis=-1)
    a, b, c, d = P[:-1, :-1], P[:-1, 1:], P[1:, 1:], P[1:, :-1]     # ccw from above
    diag_ac = np.abs((Z[:-1, :-1] + Z[1:, 1:]) / 2 - Zc) <= np.abs((Z[:-1, 1:] + Z[1:, :-1]) / 2 - Zc)
    m = diag_ac[..., None]
    t1 = np.stack([a, b, np.where(m, c, d)], axis=-2).reshape(-1, 3, 3)
    t2 = np.stack([np.where(m, a, b), c, d], axis=-2).reshape(-1, 3, 3)
    ring = np.concatenate([P[0, :-1], P[:-1, -1], P[-1, :0:-1], P[:0:-1, 0]])   # ccw
    low = ring.copy()
    low[:, 2] = z_bottom
    nxt = np.roll(np.arange(len(ring)), -1)
    sides = np.concatenate([np.stack([ring, low, low[nxt]], 1), np.stack([ring, low[nxt], ring[nxt]], 1)])
    centre = np.array([xs.mean(), ys.mean(), z_bottom])
    bottom = np.stack([np.broadcast_to(centre, low.shape), low[nxt], low], 1)
    return np.concatenate([t1, t2, sides, bottom])


class GCode:
    """Modal G-code writer: words that did not change are left out."""

    def __init__(self, header):
        self.lines, self.state = list(header), {}

    def move(self, g, feed=None, **axes):
        words = [] if self.state.get("G") == g else [g]
        self.state["G"] = g
        for k in "XYZIJ":
            if k in axes:
                v = f"{axes[k]:.4f}".rstrip("0").rstrip(".")
                v = "0" if v in ("-0", "") else v
                if k in "IJ" or self.state.get(k) != v:
                    words.append(k + v)
                if k in "XYZ":
                    self.state[k] = v
        if g != "G0" and feed is not None and self.state.get("F") != feed:
            words.append(f"F{feed:g}")
            self.state["F"] = feed
        if len(words) > (g in words):
            self.lines.append(" ".join(words))

    def text(self, footer):
        return "\n".join(self.lines + list(footer)) + "\n"


# ----------------------------------------------------------------- mold-ball tool path
def raster_passes():
    """Lock-step marching along every pass: points (x, z, slope) per pass."""
    ys = Y_FIRST + PICK * np.arange(int((PLATE[1][1] - 2 * Y_FIRST) / PICK) + 1)
    z0, u, v = drop_ball(np.full(ys.size, X_START), ys, R_BALL)
    pts = [[(X_START, z0[i], float(slope_deg(u[i], v[i])))] for i in range(ys.size)]
    cur, zc = np.full(ys.size, X_START), z0
    while True:
        act = np.flatnonzero(cur < X_END - 1e-9)
        if act.size == 0:
            return ys, pts
        step = np.full(act.size, MAX_STEP)
        for it in range(12):
            x1 = np.minimum(cur[act] + step, X_END)
            z1, u1, v1 = drop_ball(x1, ys[act], R_BALL)
            zm, _, _ = drop_ball((cur[act] + x1) / 2, ys[act], R_BALL)
            err = np.abs(zm - (zc[act] + z1) / 2)
            length = np.hypot(x1 - cur[act], z1 - zc[act])
            bad = (err > CHORD_TOL) | (length > MAX_STEP + 1e-9)
            if not bad.any() or it == 11:
                break
            shrink = np.minimum(np.where(length > MAX_STEP, 0.999 * MAX_STEP / length, 1.0),
                                np.where(err > CHORD_TOL, 0.9 * np.sqrt(CHORD_TOL / err), 1.0))
            step = np.where(bad, step * shrink, step)
        sl = slope_deg(u1, v1)
        for n, i in enumerate(act):
            pts[i].append((x1[n], z1[n], sl[n]))
        cur[act], zc[act] = x1, z1


def contour_loops():
    """Waterline loops, each (n, 2) clockwise, exact tip height Z, per level."""
    import contourpy
    from scipy.interpolate import RegularGridInterpolator

    xs, ys = np.arange(-2.0, 62.0001, 0.25), np.arange(-2.0, 42.0001, 0.25)
    X, Y = np.meshgrid(xs, ys)
    CL = drop_ball(X, Y, R_BALL)[0].reshape(X.shape)
    gy, gx = np.gradient(CL, ys, xs)
    grad = [RegularGridInterpolator((ys, xs), g) for g in (gx, gy)]
    gen = contourpy.contour_generator(xs, ys, CL)
    levels = []
    for Z in np.arange(Z_HI, Z_LO - 1e-9, -DZ):
        lines = [ln for ln in gen.lines(Z) if len(ln) > 20]
        assert len(lines) == 1 and np.allclose(lines[0][0], lines[0][-1]), Z
        ln = lines[0]
        s = np.concatenate([[0], np.cumsum(np.hypot(*np.diff(ln, axis=0).T))])
        n = int(np.ceil(s[-1] / 0.4))
        t = np.linspace(0, s[-1], n, endpoint=False)
        p = np.stack([np.interp(t, s, ln[:, 0]), np.interp(t, s, ln[:, 1])], axis=1)
        p = _to_level(p, Z, grad)
        for _ in range(6):                  # chord check, insert midpoints where needed
            q = np.roll(p, -1, axis=0)
            mid = (p + q) / 2
            bad = np.abs(drop_ball(mid[:, 0], mid[:, 1], R_BALL)[0] - Z) > CHORD_TOL
            if not bad.any():
                break
            new = _to_level(mid[bad], Z, grad)
            idx = np.flatnonzero(bad) + 1
            p = np.insert(p, idx, new, axis=0)
        area = np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])
        if area > 0:
            p = p[::-1]                     # clockwise from above: climb around a boss
        start = np.argmin(np.hypot(p[:, 0] - CX, p[:, 1] - 0.0))
        levels.append((Z, np.roll(p, -start, axis=0)))
    return levels, grad


def _to_level(p, Z, grad):
    """Newton along the gradient of the CL surface until the tip is exactly at Z."""
    p = p.copy()
    for _ in range(12):
        z = drop_ball(p[:, 0], p[:, 1], R_BALL)[0]
        if np.all(np.abs(z - Z) < 1e-7):
            return p
        g = np.stack([f(p[:, ::-1]) for f in grad], axis=1)
        p -= ((z - Z) / np.sum(g * g, axis=1))[:, None] * g
    raise RuntimeError("waterline point did not converge")


def mold_program():
    """The mold-ball G-code text, and facts for the description."""
    levels, grad = contour_loops()
    ys, passes = raster_passes()
    g = GCode(["%", "O1001 (MOLD-BALL FINISH)",
               "(GENERATED BY SCRIPTS/MAKE_ERRPRED_SCENARIOS.PY - DO NOT EDIT)",
               "(T1 BALL END MILL D10 2 FLUTES HELIX 30 CARBIDE OVERHANG 40)",
               "(STOCK DESIGN + 0.15 MM, P20 PREHARDENED MOLD STEEL)",
               f"(OP1 CONTOUR Z{Z_HI:g} TO Z{Z_LO:g} STEP {DZ:g}, CLIMB)",
               f"(OP2 RASTER +X, PICK {PICK:g}, SLOPE < {STEEP_DEG:g} DEG)",
               "G21 G90 G17 G94 G40 G49 G80", "T1 M6", "G54", f"S{SPINDLE} M3", "M8", "G43 H1"])
    tips, marks = [], {}

    def lead(p, Z):
        gr = np.array([f(p[None, ::-1])[0] for f in grad])
        q = p - 1.5 * gr / np.linalg.norm(gr)
        assert drop_ball(q[:1], q[1:], R_BALL)[0][0] < Z - 0.2
        return q

    for k, (Z, p) in enumerate(levels):
        q = lead(p[0], Z)
        if k == 0:
            g.move("G0", X=q[0], Y=q[1])
            g.move("G0", Z=SAFE_Z)
            g.move("G0", Z=Z + 1.0)
            g.move("G1", PLUNGE, Z=Z)
        else:
            g.move("G1", FEED, X=q[0], Y=q[1], Z=Z)
        marks.setdefault(round(Z, 2), len(g.lines) + 1)
        for x, y in np.vstack([p, p[:1]]):
            g.move("G1", FEED, X=x, Y=y, Z=Z)
            tips.append((x, y, Z))
        g.move("G1", FEED, X=q[0], Y=q[1])
    g.move("G0", Z=SAFE_Z)
    raster_start = len(g.lines) + 1
    for y, pts in zip(ys, passes):
        a = np.array(pts)
        ok = (a[:, 2] < STEEP_DEG) | (a[:, 1] > Z_HI + 0.05) | (a[:, 1] < Z_LO - 0.05)
        runs = []                                   # shallow runs, gaps < 1 mm bridged
        for i in np.flatnonzero(ok):
            if runs and a[i, 0] - a[runs[-1][1], 0] < 1.0:
                runs[-1][1] = i
            else:
                runs.append([i, i])
        marks.setdefault(round(y, 3), len(g.lines) + 1)
        for i, j in runs:
            if a[j, 0] - a[i, 0] < 1.0:
                continue
            g.move("G0", X=a[i, 0], Y=y)
            g.move("G0", Z=a[i, 1] + 1.0)
            g.move("G1", PLUNGE, Z=a[i, 1])
            for x, z, _ in a[i + 1:j + 1]:
                g.move("G1", FEED, X=x, Z=z)
            g.move("G0", Z=SAFE_Z)
            tips += [(x, y, z) for x, z, _ in a[i:j + 1]]
    text = g.text(["M9", "M5", "G0 Z50", "M30", "%"])
    return text, np.array(tips), marks, raster_start, ys


# ----------------------------------------------------------------- wall-radius
WC, WA, WB, WRHO = (50.0, 40.0), 30.0, 20.0, 8.0     # boss centre, half sizes, corner at z=0
DRAFT, BOSS_H, SLAB_Z, FOOT = math.radians(3.0), 40.0, -60.0, (100.0, 80.0)
W_D, W_R, W_ALLOW, W_PITCH, W_TOP, W_LOW = 20.0, 1.0, 0.2, 0.5, 38.5, 0.5
W_RPM, W_FEED = 2700, 1300.0


def section(z, extra):
    """Half sizes and corner radius of the boss section at height z, offset by extra."""
    d = extra - z * math.tan(DRAFT)
    return WA + d, WB + d, WRHO + d


def ring(z, extra, n=48):
    """Section outline (m, 3), counter-clockwise from the middle of the +X side."""
    A, B, rc = section(z, extra)
    pts = [(A, 0.0)]
    for sx, sy, a0 in ((1, 1, 0), (-1, 1, 90), (-1, -1, 180), (1, -1, 270)):
        t = np.radians(np.linspace(a0, a0 + 90, n + 1))
        pts += list(zip(sx * (A - rc) + rc * np.cos(t), sy * (B - rc) + rc * np.sin(t)))
    p = np.array(pts) + WC
    return np.column_stack([p, np.full(len(p), z)])


def boss_solid(extra):
    """Slab 100 x 80 x 60 with the drafted boss on it (walls offset by extra)."""
    lo, up = ring(0.0, extra), ring(BOSS_H, extra)
    nx = np.roll(np.arange(len(lo)), -1)
    walls = np.concatenate([np.stack([lo, lo[nx], up[nx]], 1), np.stack([lo, up[nx], up], 1)])
    top = np.stack([np.broadcast_to([*WC, BOSS_H], up.shape), up, up[nx]], 1)
    rel = lo[:, :2] - WC
    hx, hy = FOOT[0] / 2, FOOT[1] / 2
    scale = np.minimum(hx / np.maximum(np.abs(rel[:, 0]), 1e-12), hy / np.maximum(np.abs(rel[:, 1]), 1e-12))
    outer = np.vstack([rel * scale[:, None], [[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]]])
    ang = lambda p: np.mod(np.arctan2(p[:, 1], p[:, 0]), 2 * np.pi)
    outer = outer[np.argsort(ang(outer), kind="stable")]
    outer = np.column_stack([np.round(outer + WC, 9), np.zeros(len(outer))])
    ai, ao = np.append(ang(rel), 2 * np.pi), np.append(ang(outer[:, :2] - WC), 2 * np.pi)
    ni, no = len(lo), len(outer)
    ann, i, j = [], 0, 0
    while i < ni or j < no:
        if j == no or (i < ni and ai[i + 1] <= ao[j + 1]):
            ann.append([lo[i], outer[j % no], lo[(i + 1) % ni]])
            i += 1
        else:
            ann.append([lo[i % ni], outer[j], outer[(j + 1) % no]])
            j += 1
    low = outer.copy()
    low[:, 2] = SLAB_Z
    on = np.roll(np.arange(no), -1)
    sides = np.concatenate([np.stack([outer, low, low[on]], 1), np.stack([outer, low[on], outer[on]], 1)])
    bottom = np.stack([np.broadcast_to([*WC, SLAB_Z], low.shape), low[on], low], 1)
    return np.concatenate([walls, top, np.array(ann), sides, bottom])


def levels_z(k):
    """Tip height of wall-radius level k [mm]."""
    return W_TOP - W_PITCH * k


def wall_program():
    """The wall-radius G-code: waterline climb around the boss, lines and G2 arcs."""
    g = GCode(["%", "O2001 (WALL-RADIUS FINISH, JP5804367 EXAMPLE CONDITIONS)",
               "(GENERATED BY SCRIPTS/MAKE_ERRPRED_SCENARIOS.PY - DO NOT EDIT)",
               "(T1 RADIUS END MILL D20 R1 2 INSERTS HELIX 0)",
               "(STOCK S55C, BOSS WALL ALLOWANCE 0.2 MM, DRAFT 3 DEG)",
               f"(WATERLINE Z{W_TOP:g} TO Z{W_LOW:g} PITCH {W_PITCH:g}, DOWN CUT, DRY)",
               "G21 G90 G17 G94 G40 G49 G80", "T1 M6", "G54", f"S{W_RPM} M3", "G43 H1"])
    off = (W_D / 2 - W_R) + W_R * math.cos(DRAFT)
    cx, cy = WC
    levels = np.arange(W_TOP, W_LOW - 1e-9, -W_PITCH)
    ends, starts = [], []
    for k, Z in enumerate(levels):
        A, B, rc = section(Z + W_R * (1 - math.sin(DRAFT)), off)
        lead = (cx, cy - B - 3.0)
        if k == 0:
            g.move("G0", X=lead[0], Y=lead[1])
            g.move("G0", Z=Z + 2.0)
        starts.append(len(g.lines) + 1)
        g.move("G1", W_FEED, X=lead[0], Y=lead[1], Z=Z)
        g.move("G1", W_FEED, X=cx, Y=cy - B)
        for px, py, qx, qy, ix, iy in (
                (-(A - rc), -B, -A, -(B - rc), 0, rc), (-A, B - rc, -(A - rc), B, rc, 0),
                (A - rc, B, A, B - rc, 0, -rc), (A, -(B - rc), A - rc, -B, -rc, 0)):
            g.move("G1", W_FEED, X=cx + px, Y=cy + py)
            g.move("G2", W_FEED, X=cx + qx, Y=cy + qy, I=ix, J=iy)
            ends.append((cx + px, cy + py, Z))
        g.move("G1", W_FEED, X=cx, Y=cy - B)
        g.move("G1", W_FEED, X=lead[0], Y=lead[1])
    g.move("G0", Z=50.0)
    return g.text(["M5", "M30", "%"]), np.array(ends), starts


def wall_gouge_margin(tips, extra=0.0):
    """Smallest distance from the tool's corner core circle to the boss, minus r [mm].

    Signed distance to the drafted boss: the horizontal rounded-rectangle
    distance at the point's height times cos(draft) (exact on the planar and
    conical faces). 0 means touching, negative a gouge.
    """
    t = np.radians(np.arange(0, 360, 0.5))
    core = (W_D / 2 - W_R)
    worst = np.inf
    for x, y, z in tips:
        px, py, pz = x + core * np.cos(t), y + core * np.sin(t), z + W_R
        A, B, rc = section(pz, extra)
        qx = np.abs(px - WC[0]) - (A - rc)
        qy = np.abs(py - WC[1]) - (B - rc)
        sd = np.hypot(np.maximum(qx, 0), np.maximum(qy, 0)) + np.minimum(np.maximum(qx, qy), 0) - rc
        worst = min(worst, float(np.min(sd * math.cos(DRAFT))) - W_R)
    return worst


# ----------------------------------------------------------------- scenario files
KIENZLE_SRC = ("kc1.1 = 2200 N/mm^2, mc = 0.24 for low-alloy steel (rake 6 deg as tabulated; "
               "Tabellenbuch Zerspantechnik, 5th ed. 2022, ISBN 978-3-7585-1315-2, p. 215, as "
               "transcribed in FreeCAD's material card src/Mod/Material/Resources/Materials/"
               "Machining/LowAlloySteel.FCMat, commit ad4ad3d0e658)")


def kienzle_fit(kc11, mc, h_lo, h_hi):
    """Least-squares line ``Kte + Ktc h`` through ``kc1.1 h^(1-mc)`` on [h_lo, h_hi]."""
    h = np.linspace(h_lo, h_hi, 400)
    (kte, ktc), *_ = np.linalg.lstsq(np.column_stack([np.ones_like(h), h]), kc11 * h ** (1 - mc),
                                     rcond=None)
    return round(float(ktc), -1), round(float(kte), 1)


def cutting_toml(h_lo, h_hi, axial, why):
    ktc, kte = kienzle_fit(2200.0, 0.24, h_lo, h_hi)
    krc, kre = round(0.4 * ktc, -1), round(1.2 * kte, 1)
    kac, kae = (round(0.15 * ktc, -1), round(0.3 * kte, 1)) if axial else (0.0, 0.0)
    src = (f"Ktc and Kte0: least-squares line through the Kienzle law Ft/b = kc1.1 h^(1-mc) over "
           f"h = {h_lo:g}..{h_hi:g} mm (the chip thicknesses of this cut), {KIENZLE_SRC}. "
           f"Krc = 0.4 Ktc, Kre0 = 1.2 Kte0{', Kac = 0.15 Ktc, Kae0 = 0.3 Kte0' if axial else ''}"
           f" and the wear growth Kxe1 (edge force doubling after 100 m of actual cutting "
           f"distance) are representative values, not from a measurement. {why}")
    return "\n".join([
        "[cutting]", f"Ktc_N_mm2 = {ktc:.1f}", f"Krc_N_mm2 = {krc:.1f}", f"Kac_N_mm2 = {kac:.1f}",
        f"Kte0_N_mm = {kte:.1f}", f"Kre0_N_mm = {kre:.1f}", f"Kae0_N_mm = {kae:.1f}",
        f"Kte1_N_mm2 = {kte / 1e5:.3e}", f"Kre1_N_mm2 = {kre / 1e5:.3e}",
        f"Kae1_N_mm2 = {kae / 1e5:.3e}", f'source = "{src}"', ""])


def modes_toml(table, src):
    out = ["[dynamics]", 'model = "dynamic"', f'source = "{src}"', ""]
    for d, f, z, k in table:
        out += ["[[dynamics.modes]]", f'direction = "{d}"', f"frequency_hz = {f:.1f}",
                f"damping_ratio = {z}", f"stiffness_N_m = {k:.3e}", ""]
    return "\n".join(out)


def cantilever(E, rho, d, L):
    """Stiffness [N/m] and first frequency [Hz] of a clamped round bar (diameter d, length L)."""
    I, A = math.pi * d ** 4 / 64, math.pi * d ** 2 / 4
    return 3 * E * I / L ** 3, 1.875 ** 2 / (2 * math.pi) * math.sqrt(E * I / (rho * A * L ** 4))


def mold_toml(marks, raster_start, ys, n_blocks, chord_err, sizes):
    zc = marks[8.0]
    iy = int(np.argmin(np.abs(ys - 20.0)))
    ry = marks[round(float(ys[iy]), 3)]
    k, f = cantilever(600e9, 14.5e3, 0.010, 0.040)
    desc = (f"Finishing a free-form core (60 x 40 mm, 16 mm high, flanks up to 60 deg, saddle on top) "
            f"in P20-class prehardened mold steel with a D10 two-flute ball end mill, "
            f"{SPINDLE} min^-1, {FEED:g} mm/min (fz 0.08 mm), allowance {ALLOWANCE:g} mm, dry "
            f"air blast (M8). {n_blocks} motion blocks: contour (waterline, climb) Z {Z_HI:g} "
            f"to {Z_LO:g} in {DZ:g} mm steps from line {marks[Z_HI]}, then raster along +X "
            f"(pick {PICK:g} mm, slopes under {STEEP_DEG:g} deg) from line {raster_start}. "
            f"Representative slices for [program] lines: contour [{zc}, {zc + 299}] "
            f"(Z 8.0 and below, flank 52-60 deg); raster [{ry}, {ry + 299}] (passes from "
            f"Y {ys[iy]:.2f} over the saddle top and the base). Tool tips by exact drop-cutter "
            f"(no gouge, within 1 um); chord tolerance {CHORD_TOL * 1e3:g} um. STLs: binary, "
            f"{GRID_MM:g} mm grid, largest deviation from the analytic surface "
            f"{chord_err[0] * 1e3:.1f} um (design) and {chord_err[1] * 1e3:.1f} um (stock); "
            f"{sizes[0] / 1e6:.1f} MB and {sizes[1] / 1e6:.1f} MB.")
    dyn_src = ("Representative values, not from a measurement (no published tool-tip FRF for "
               "this tool was found). Plausibility: a clamped carbide bar D10 x 40 mm "
               f"(E 600 GPa) alone has k = {k:.2e} N/m and f1 = {f:.0f} Hz; holder and spindle "
               "in series lower both, to the 2-2.3 kHz, 6-7e6 N/m chosen here.")
    shape_src = ("Representative values, not from a measurement; a few um as in seed 003 "
                 "(Hiroshima Pref. Tech. Res. Inst., Development of compensation system for "
                 "machining error of die and mold, 2nd report: static runout 2 um of a D20 "
                 "ball end mill, form measured on the spinning tool at 0.5 mm axial pitch). "
                 "Wear rate representative.")
    return "\n".join([
        'name = "mold-ball"', f'description = "{desc}"', "",
        "[stock]", 'stl = "stock.stl"', 'design_stl = "design.stl"', "",
        "[tool]", 'type = "ball"', "diameter_mm = 10.0", "flutes = 2", "helix_deg = 30.0",
        "flute_length_mm = 20.0", "overhang_mm = 40.0", 'rotation = "cw"',
        "shank_diameter_mm = 10.0", "", "[tool.holder]", "diameter_mm = 24.0",
        "length_mm = 80.0", "", "[program]", 'gcode = "finish.nc"', 'allow = ["M8", "M9"]', "",
        cutting_toml(0.005, 0.08, True, "P20 (1.2311, 40CrMnMo7) is a low-alloy steel."),
        modes_toml([("x", 2150.0, 0.03, 6.0e6), ("x", 3900.0, 0.04, 2.2e7),
                    ("y", 2240.0, 0.028, 6.5e6), ("y", 4050.0, 0.04, 2.5e7)], dyn_src),
        "[shape_error]", "kappa_deg = [0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0]",
        "radius_deviation_um = [-2.0, -1.2, -0.5, 0.3, 1.0, 1.5, 2.0]",
        "wear_rate_um_per_m = 0.05", f'source = "{shape_src}"', ""])


def wall_toml(n_blocks, sizes, starts):
    k, f = cantilever(210e9, 7.85e3, 0.020, 0.100)
    desc = (f"The worked example of JP5804367 (para. 0097-0104) on a drafted boss: radius end "
            f"mill D20 corner R1, 2 inserts (helix 0), S55C, {W_RPM} min^-1, {W_FEED:g} mm/min, "
            f"radial allowance {W_ALLOW:g} mm, Z pitch {W_PITCH:g} mm, waterline down cut, dry. "
            f"Boss 60 x 40 mm at the floor, corner radius 8 mm, walls drafted 3 deg, 40 mm high, "
            f"on a 100 x 80 x 60 mm slab; {n_blocks} motion blocks (G1 and G2), levels Z "
            f"{W_TOP:g} to {W_LOW:g}. The corner radius touches the wall at kappa = 87 deg. "
            f"Each level takes {starts[1] - starts[0]} lines (level k starts at line "
            f"{starts[0]} + {starts[1] - starts[0]} k); representative slice [{starts[30]}, "
            f"{starts[40] - 1}] (Z {levels_z(30):g} to {levels_z(39):g}). STLs: "
            f"binary, {sizes[0] / 1e3:.0f} kB and {sizes[1] / 1e3:.0f} kB.")
    dyn_src = ("Representative values, not from a measurement. Plausibility: a clamped steel bar "
               f"D20 x 100 mm (E 210 GPa) alone has k = {k:.2e} N/m and f1 = {f:.0f} Hz; the "
               "holder and spindle in series lower both.")
    shape_src = ("Representative values, not from a measurement (the patent measures the "
                 "spinning tool's diameter at several sections before and after cutting and "
                 "takes wear proportional to the actual cutting distance, para. 0102, but lists "
                 "no values).")
    return "\n".join([
        'name = "wall-radius"', f'description = "{desc}"', "",
        "[stock]", 'stl = "stock.stl"', 'design_stl = "design.stl"', "",
        "[tool]", 'type = "radius"', "diameter_mm = 20.0", "corner_radius_mm = 1.0",
        "flutes = 2", "helix_deg = 0.0", "flute_length_mm = 10.0", "overhang_mm = 100.0",
        'rotation = "cw"', "shank_diameter_mm = 20.0", "", "[tool.holder]",
        "diameter_mm = 40.0", "length_mm = 60.0", "", "[program]", 'gcode = "finish.nc"', "",
        cutting_toml(0.005, 0.05, False,
                     "S55C (about C55) is not in the table: the low-alloy row is used as the "
                     "nearest class. Axial coefficients 0 as in JP5804367 para. 0101 (helix 0: "
                     "Fa negligible)."),
        modes_toml([("x", 1150.0, 0.03, 4.0e6), ("x", 2600.0, 0.045, 1.8e7),
                    ("y", 1210.0, 0.032, 4.4e6), ("y", 2750.0, 0.045, 2.0e7)], dyn_src),
        "[shape_error]", "kappa_deg = [0.0, 30.0, 60.0, 75.0, 87.0, 90.0]",
        "radius_deviation_um = [1.0, 0.5, -0.5, -1.5, -2.5, -3.0]",
        "wear_rate_um_per_m = 0.2", f'source = "{shape_src}"', "",
        "[tool_change]", "tolerance_um = 30.0", ""])


# ----------------------------------------------------------------- main
def build(out):
    """Write both scenarios under ``out``; return a summary dict."""
    import trimesh

    from nc import read_program

    summary = {}
    d = os.path.join(out, "mold-ball")
    os.makedirs(d, exist_ok=True)
    nx, ny = (int(math.ceil((b - a) / GRID_MM)) for a, b in PLATE)
    xs, ys = np.linspace(*PLATE[0], nx + 1), np.linspace(*PLATE[1], ny + 1)
    X, Y = np.meshgrid(xs, ys)
    XC, YC = np.meshgrid((xs[1:] + xs[:-1]) / 2, (ys[1:] + ys[:-1]) / 2)

    def offset(x, y):
        return drop_ball(x, y, ALLOWANCE, samples=3)[0].reshape(np.shape(x)) + ALLOWANCE

    errs, sizes = [], []
    for name, fz in (("design.stl", design_z), ("stock.stl", offset)):
        Z, Zc = fz(X, Y), fz(XC, YC)
        tris = heightfield_solid(xs, ys, Z, Zc, BOTTOM_Z)
        mids = [((Z[:, 1:] + Z[:, :-1]) / 2, (X[:, 1:] + X[:, :-1]) / 2, Y[:, 1:]),
                ((Z[1:] + Z[:-1]) / 2, X[1:], (Y[1:] + Y[:-1]) / 2)]
        e = max(float(np.max(np.abs(m - fz(mx, my)))) for m, mx, my in mids)
        diag = np.minimum(np.abs((Z[:-1, :-1] + Z[1:, 1:]) / 2 - Zc),
                          np.abs((Z[:-1, 1:] + Z[1:, :-1]) / 2 - Zc))
        errs.append(max(e, float(diag.max())))
        path = os.path.join(d, name)
        write_stl(path, tris, f"errpred scenario mold-ball {name}")
        sizes.append(os.path.getsize(path))
        m = trimesh.load(path, force="mesh")
        assert m.is_watertight and m.is_winding_consistent and m.volume > 0, name
    text, tips, marks, raster_start, pass_y = mold_program()
    with open(os.path.join(d, "finish.nc"), "w", newline="\n") as fh:
        fh.write(text)
    prog = read_program(os.path.join(d, "finish.nc"), allow=["M8", "M9"])
    dist = check_no_gouge(tips[::20], R_BALL)
    assert np.all(np.abs(dist - R_BALL) < 1e-3), float(np.abs(dist - R_BALL).max())
    with open(os.path.join(d, "scenario.toml"), "w", newline="\n") as fh:
        fh.write(mold_toml(marks, raster_start, pass_y, len(prog), errs, sizes))
    summary["mold-ball"] = dict(blocks=len(prog), lines=len(prog.lines), stl_bytes=sizes,
                                chord_um=[e * 1e3 for e in errs],
                                tip_err_um=float(np.abs(dist - R_BALL).max() * 1e3))

    d = os.path.join(out, "wall-radius")
    os.makedirs(d, exist_ok=True)
    sizes = []
    for name, extra in (("design.stl", 0.0), ("stock.stl", W_ALLOW)):
        path = os.path.join(d, name)
        write_stl(path, boss_solid(extra), f"errpred scenario wall-radius {name}")
        sizes.append(os.path.getsize(path))
        m = trimesh.load(path, force="mesh")
        assert m.is_watertight and m.is_winding_consistent and m.volume > 0, name
    text, ends, starts = wall_program()
    with open(os.path.join(d, "finish.nc"), "w", newline="\n") as fh:
        fh.write(text)
    prog = read_program(os.path.join(d, "finish.nc"))
    margin = wall_gouge_margin(ends)
    assert abs(margin) < 1e-3, margin
    with open(os.path.join(d, "scenario.toml"), "w", newline="\n") as fh:
        fh.write(wall_toml(len(prog), sizes, starts))
    summary["wall-radius"] = dict(blocks=len(prog), stl_bytes=sizes, margin_um=margin * 1e3)
    return summary


def check_built(build_fn, out_root: str) -> int:
    """Rebuild into a temporary folder and compare with ``out_root``; print, return 0/1.

    Shared by the scenario scripts (``make_orient_scenarios.py`` imports it).
    """
    with tempfile.TemporaryDirectory() as tmp:
        build_fn(tmp)
        bad = [os.path.join(n, f) for n in sorted(os.listdir(tmp))
               for f in sorted(os.listdir(os.path.join(tmp, n)))
               if not filecmp.cmp(os.path.join(tmp, n, f), os.path.join(out_root, n, f),
                                  shallow=False)]
    print("differ: " + ", ".join(bad) if bad else "bundled scenarios are up to date")
    return 1 if bad else 0


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if argv == ["--check"]:
        return check_built(build, OUT)
    if argv:
        print(__doc__.split("\n\n")[1])
        return 2
    for name, facts in build(OUT).items():
        print(name, facts)
    return 0


if __name__ == "__main__":
    sys.path.insert(0, ROOT)
    sys.exit(main())
