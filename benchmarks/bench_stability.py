"""Timings of orient's stability analysis on a 2-DOF (and a 3-mode) case.

Prints:

* the time of one ZOA margin (single call, median of repeats);
* the batch throughput of ``zoa_margin_batch`` in postures per second (numba,
  parallel over ``NUMBA_NUM_THREADS`` threads; set it to 1 for one core),
  for a tool with 2 bending modes and for tool + 1 workpiece mode, with the
  tool modes carried to each posture's tool axis;
* the time for lobes over 200 spindle speeds by the time-periodic method
  (full discretization) and by the ZOA.

Case: Altintas & Budak's cutting data (Kt = 796 N/mm^2, Kr = 0.212, four
flutes, half-immersion up-milling) on the symmetric 2-DOF tool of Ding et
al. 2010 (922 Hz, zeta 0.011, k = 1.34e6 N/m), as in the tests.

Usage: python benchmarks/bench_stability.py [--postures N] [--speeds N]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from errpred.dynamics import Compliance, Mode
from orient.dynamics import ModalSystem, minimal_rotation
from orient.stability import (
    StraightEndMill2D,
    stability_lobes,
    zoa_frequency_grid,
    zoa_margin,
    zoa_margin_batch,
)


def _mode() -> Mode:
    k = 1340049.648
    wn = 2 * math.pi * 922.0
    m = k / wn**2
    return Mode(k, m, 2 * 0.011 * math.sqrt(k * m))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--postures", type=int, default=100_000)
    ap.add_argument("--speeds", type=int, default=200)
    args = ap.parse_args(argv)
    import numba

    print(f"numba threads: {numba.get_num_threads()}")
    tool = StraightEndMill2D(796e6, 0.212 * 796e6, 4, 0.5, "up", depth_mm=1.0)
    p0 = tool.mean_directional_matrix()
    comp = Compliance.from_modes({"x": _mode(), "y": _mode()})
    sys2 = ModalSystem.tool(comp)
    wp = ModalSystem.from_modes([(Mode.from_frequency(1400.0, 0.02, 4e6), (0.0, 0.6, 0.8))])
    sys3 = ModalSystem.combine(sys2, wp)

    # --- one margin
    zoa_margin(p0, sys2, 9000.0, 4)
    zoa_margin(p0, sys3, 9000.0, 4)
    for name, s in (("2 modes", sys2), ("3 modes", sys3)):
        ts = []
        for rpm in np.linspace(5000.0, 20000.0, 200):
            t = time.perf_counter()
            zoa_margin(p0, s, float(rpm), 4)
            ts.append(time.perf_counter() - t)
        print(f"one ZOA margin ({name}, {zoa_frequency_grid(s).size} frequencies): "
              f"median {1e3 * np.median(ts):.3f} ms, max {1e3 * max(ts):.3f} ms")

    # --- batch: postures = tool axes around the vertical, P rotated with them
    rng = np.random.default_rng(0)
    n = args.postures
    axes = rng.normal([0.0, 0.0, 1.0], 0.35, size=(n, 3))
    axes[:, 2] = np.abs(axes[:, 2]) + 0.2
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    rot = minimal_rotation(axes)
    p = rot @ p0 @ np.swapaxes(rot, 1, 2)
    for name, s in (("2 modes", sys2), ("3 modes", sys3)):
        md = s.directions_for_axes(axes)
        zoa_margin_batch(p[:8], s, 12000.0, 4, mode_directions=md[:8])
        t = time.perf_counter()
        out = zoa_margin_batch(p, s, 12000.0, 4, mode_directions=md)
        dt = time.perf_counter() - t
        print(f"zoa_margin_batch ({name}): {n / dt:,.0f} postures/s "
              f"({1e6 * dt / n:.1f} us/posture), finite margins {np.isfinite(out).mean():.0%}")

    # --- lobes over speeds
    rpm = np.linspace(5000.0, 30000.0, args.speeds)
    h = tool.directional_samples(tool.recommended_samples())
    t = time.perf_counter()
    z = stability_lobes(h, sys2, 4, rpm, method="zoa", depth_mm=1.0)
    tz = time.perf_counter() - t
    t = time.perf_counter()
    s = stability_lobes(h, sys2, 4, rpm, method="sdm", depth_mm=1.0)
    ts_ = time.perf_counter() - t
    print(f"lobes over {rpm.size} speeds ({rpm[0]:.0f}-{rpm[-1]:.0f} rev/min), 2 modes: "
          f"ZOA {tz:.3f} s, time-periodic {ts_:.1f} s")
    print(f"  lowest limit: ZOA {z.depth_limit_mm.min():.4f} mm, "
          f"time-periodic {s.depth_limit_mm.min():.4f} mm")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
