"""Interference checks per second on a mold-like mesh, and the pre-filter's effect.

The workpiece is a bumpy height field with a steep-walled pocket (about 20k
triangles over 100 x 100 mm); the postures are random cutter contacts with
the tool axis up to 40 deg from the surface normal and the ball touching
the surface. The tool: ball end mill D 6, flutes 12, overhang 30, holder
D 32 x 40, clearance 0.5 mm.

Prints the build time, then for decisions only (``feasible``) and for full
results with distances (``check``) the checks per second with and without
the pre-filter, and how many FCL calls the pre-filter saved. Without the
pre-filter the distance run is timed on a subset (FCL distance queries of
far parts take milliseconds each).

Usage: python benchmarks/bench_interference.py [--postures N] [--grid N]
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
import trimesh

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from errpred.tool import Holder, Tool
from orient.interference import InterferenceChecker, ToolAssembly

R = 3.0


def height(x, y):
    bumps = 5.0 * np.sin(x / 10.0) * np.cos(y / 13.0)
    pocket = -15.0 * np.exp(-(((x - 10) ** 2 + (y + 5) ** 2) / 15.0 ** 2) ** 4)
    return bumps + pocket


def mold(n: int, size: float = 100.0) -> trimesh.Trimesh:
    x = np.linspace(-size / 2, size / 2, n + 1)
    X, Y = np.meshgrid(x, x)
    V = np.column_stack([X.ravel(), Y.ravel(), height(X, Y).ravel()])
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), \
        idx[:-1, 1:].ravel()
    F = np.vstack([np.column_stack([a, c, b]), np.column_stack([a, d, c])])
    return trimesh.Trimesh(V, F, process=False)


def postures(n: int, seed: int = 1):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-40, 40, (n, 2))
    h = 1e-4
    z = height(xy[:, 0], xy[:, 1])
    gx = (height(xy[:, 0] + h, xy[:, 1]) - height(xy[:, 0] - h, xy[:, 1])) / (2 * h)
    gy = (height(xy[:, 0], xy[:, 1] + h) - height(xy[:, 0], xy[:, 1] - h)) / (2 * h)
    nrm = np.column_stack([-gx, -gy, np.ones(n)])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    # axis: the normal rotated by up to 40 deg toward a random direction
    w = rng.normal(size=(n, 3))
    w -= np.sum(w * nrm, axis=1, keepdims=True) * nrm
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    ang = np.radians(rng.uniform(0.0, 40.0, n))
    u = np.cos(ang)[:, None] * nrm + np.sin(ang)[:, None] * w
    tips = np.column_stack([xy, z]) + R * nrm - R * u
    return tips, u


def rate(fn, n):
    t0 = time.perf_counter()
    out = fn()
    return n / (time.perf_counter() - t0), out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--postures", type=int, default=10_000)
    ap.add_argument("--grid", type=int, default=100, help="height-field cells per side")
    ap.add_argument("--subset", type=int, default=300,
                    help="postures for the distance run without pre-filter")
    args = ap.parse_args(argv)
    mesh = mold(args.grid)
    tool = Tool("ball", 2 * R, flute_length_mm=12.0, overhang_mm=30.0,
                holder=Holder(32.0, 40.0))
    asm = ToolAssembly.from_tool(tool, clearance_mm=0.5)
    tips, u = postures(args.postures)
    n = len(tips)
    t0 = time.perf_counter()
    fast = InterferenceChecker(mesh, asm)
    t_fast = time.perf_counter() - t0
    t0 = time.perf_counter()
    plain = InterferenceChecker(mesh, asm, prefilter=False)
    t_plain = time.perf_counter() - t0
    print(f"mesh: {len(mesh.faces):,} triangles; build {t_plain * 1e3:.0f} ms (BVH), "
          f"{t_fast * 1e3:.0f} ms (BVH + pre-filter grid, cell {fast._pf.cell:g} mm)")
    lb_test, lb_nom = fast._bounds(tips, u)       # what the pre-filter decides
    skip = lb_test > 0
    print(f"{n:,} postures x {len(asm.parts)} parts: pre-filter skips "
          f"{skip.mean():.0%} of the collision tests "
          f"({', '.join(f'{p.name} {s:.0%}' for p, s in zip(asm.parts, skip.mean(0)))}); "
          f"{(lb_nom > fast.distance_horizon_mm).mean():.0%} of the distances are beyond "
          f"the {fast.distance_horizon_mm:g} mm horizon")
    r_fast, f1 = rate(lambda: fast.feasible(tips, u), n)
    r_plain, f2 = rate(lambda: plain.feasible(tips, u), n)
    assert (f1 == f2).all(), "pre-filter changed a decision"
    print(f"feasible() / check(): {r_fast:8,.0f} checks/s with pre-filter, {r_plain:10,.0f} without "
          f"(x{r_fast / r_plain:.1f}); {f1.mean():.1%} feasible")
    r_full, res = rate(lambda: fast.check(tips, u, distances=True), n)
    m = min(args.subset, n)
    r_full_plain, res_p = rate(lambda: plain.check(tips[:m], u[:m], distances=True), m)
    assert (res_p.collides == res.collides[:m]).all()
    print(f"check(distances=True): {r_full:8,.0f} checks/s with pre-filter, {r_full_plain:10,.0f} "
          f"without (x{r_full / r_full_plain:.1f}, on {m} postures); exact distances "
          f"{res.exact.mean():.0%} of the entries")
    lab, cnt = np.unique(res.part_label, return_counts=True)
    print("offending part: " + ", ".join(f"{lbl or 'none'} {c / n:.1%}"
                                         for lbl, c in zip(lab, cnt)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
