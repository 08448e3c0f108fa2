"""Throughput of the process gain for planning (orient.gain.process_gain_batch).

A 15 x 15 lead/tilt grid (-30..30 deg) at each of many cutter locations with
their own surface normal, feed direction and local cut (ball end mill D10, 2
flutes, 30 deg helix; finishing: depth 0.05-0.5 mm, pick 0.1-1 mm, previous
pass on either side or none, flat, convex or concave surfaces). Prints:

* postures per second and microseconds per posture on one core (serial
  kernel; wall clock and CPU time of this process) and on all cores
  (numba's threads);
* the time of one ``process_gain`` call (one posture, Python overhead and
  ``H`` over the tooth period included);
* the same split by kind of cut (single groove, previous pass, curved).

Usage: python benchmarks/bench_gain.py [--points N] [--threads T]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from errpred.coefficients import CuttingCoefficients
from errpred.tool import Tool
from orient.engagement import LocalCut
from orient.gain import process_gain, process_gain_batch
from orient.geometry import posture_axis

COEF = CuttingCoefficients(Ktc_N_mm2=2000.0, Krc_N_mm2=700.0, Kac_N_mm2=300.0,
                           Kte0_N_mm=20.0, Kre0_N_mm=25.0, Kae0_N_mm=5.0)
TOOL = Tool("ball", 10.0, flutes=2, helix_deg=30.0, flute_length_mm=20.0)


def locations(n: int, seed: int = 0, kind: str = "mixed"):
    rng = np.random.default_rng(seed)
    normal = rng.normal(size=(n, 3)) * [0.5, 0.5, 1.0]
    normal[:, 2] = np.abs(normal[:, 2]) + 0.3
    feed = rng.normal(size=(n, 3))
    cuts = []
    for _ in range(n):
        side = {"groove": 0, "previous": int(rng.choice([-1, 1]))}.get(
            kind, int(rng.integers(-1, 2)))
        curved = kind == "curved" or (kind == "mixed" and rng.random() < 0.3)
        kf, kb = (rng.uniform(-0.04, 0.04, 2) if curved else (0.0, 0.0))
        cuts.append(LocalCut(rng.uniform(0.05, 0.5), rng.uniform(0.1, 1.0),
                             1 if kind == "curved" else side, rng.uniform(0.03, 0.15),
                             float(kf), float(kb)))
    return normal, feed, cuts


def grid_axes(normal, feed, k: int = 15):
    lead, tilt = np.meshgrid(np.radians(np.linspace(-30, 30, k)),
                             np.radians(np.linspace(-30, 30, k)), indexing="ij")
    return posture_axis(normal[:, None, :], feed[:, None, :], lead.ravel(), tilt.ravel())


def run(points: int, parallel: bool, kind: str = "mixed", threads: int | None = None):
    normal, feed, cuts = locations(points, 1, kind)
    axes = grid_axes(normal, feed)
    cut_arr = np.empty((points, 1), dtype=object)
    for i, c in enumerate(cuts):
        cut_arr[i, 0] = c
    args = (TOOL, COEF, axes, normal[:, None, :], feed[:, None, :], cut_arr)
    process_gain_batch(*(a[:2] if isinstance(a, np.ndarray) else a for a in args),
                       parallel=parallel)                     # compile / load the cache
    t0, c0 = time.perf_counter(), time.process_time()
    out = process_gain_batch(*args, parallel=parallel, threads=threads)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    n = axes.shape[0] * axes.shape[1]
    return n, wall, cpu, out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=200, help="cutter locations (x 225 postures)")
    ap.add_argument("--threads", type=int, default=None, help="chunks for the parallel run")
    args = ap.parse_args(argv)
    print(f"ball end mill D{TOOL.diameter_mm:g}, {TOOL.flutes} flutes; 15 x 15 lead/tilt grid "
          f"at {args.points} cutter locations; {os.cpu_count()} CPUs")
    n, wall, cpu, out = run(args.points, parallel=False)
    print(f"one core : {n} postures in {wall:.2f} s wall ({cpu:.2f} s CPU): "
          f"{n / wall:,.0f} postures/s, {1e6 * wall / n:.1f} us/posture "
          f"({1e6 * cpu / n:.1f} us CPU)")
    engaged = float(np.mean(out.engaged_fraction > 0))
    print(f"           {100 * engaged:.0f} % of the postures cut")
    n, wall, cpu, _ = run(args.points, parallel=True, threads=args.threads)
    print(f"all cores: {n} postures in {wall:.2f} s wall: {n / wall:,.0f} postures/s, "
          f"{1e6 * wall / n:.1f} us/posture; 2 million postures in "
          f"{2e6 * wall / n:.0f} s")
    for kind in ("groove", "previous", "curved"):
        n, wall, cpu, _ = run(max(args.points // 4, 10), parallel=False, kind=kind)
        print(f"  {kind:9s}: {1e6 * wall / n:.1f} us/posture ({1e6 * cpu / n:.1f} us CPU)")
    u = posture_axis([0, 0, 1.0], [1.0, 0, 0], math.radians(10), math.radians(-5))
    cut = LocalCut(0.3, 0.6, 1, 0.08)
    process_gain(TOOL, COEF, u, [0, 0, 1.0], [1.0, 0, 0], cut)
    reps = 200
    t0 = time.perf_counter()
    for _ in range(reps):
        process_gain(TOOL, COEF, u, [0, 0, 1.0], [1.0, 0, 0], cut, spindle_rpm=8000.0)
    print(f"one process_gain call (H at 90 steps per tooth): "
          f"{1e6 * (time.perf_counter() - t0) / reps:.0f} us")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
