"""Posting throughput: path solving, linearization and program text.

Takes the bundled blade cutter locations, repeated to about 100,000 points
(passes shifted upward so the path stays continuous in posture), and times
on the xyzac-trt machine with pivots away from the origin:

* ``solve_path`` (branch choice, unwrapping, singular cone),
* ``linearize`` (points inserted for the 2 um tip tolerance),
* ``post`` for each dialect (all of the above plus the text),
* reading the LinuxCNC program back with ``read_program``.

Baseline in the same process: formatting the same number of ``G1 X Y Z A C
F`` lines with plain f-strings, the floor for any Python writer.

Usage: python benchmarks/bench_post.py [--points N]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import tracemalloc

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from nc import parse_program  # noqa: E402
from nc.kinematics import get_machine, linearize, solve_path  # noqa: E402
from nc.path import CutterLocations, read_cl_csv  # noqa: E402
from nc.writer import DIALECTS, PostOptions, post  # noqa: E402

BLADE = os.path.join(os.path.dirname(__file__), "..", "nc", "data", "blade_cl.csv")


def _timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=100_000)
    args = ap.parse_args(argv)
    blade = read_cl_csv(BLADE)
    reps = -(-args.points // len(blade))
    tip = np.vstack([blade.tip + [0, 0, 0.01 * k] for k in range(reps)])[: args.points]
    axis = np.vstack([blade.axis] * reps)[: args.points]
    cl = CutterLocations.from_arrays(tip, axis, 1500.0, 12000.0)
    m = get_machine("xyzac-trt", tilt_pivot_mm=(0, 20, -35), rotary_pivot_mm=(5, -3, 0))
    n = len(cl)
    print(f"{n:,} cutter locations (bundled blade x {reps}), machine xyzac-trt")
    sol, t_solve = _timed(lambda: solve_path(m, cl.tip, cl.axis))
    print(f"solve_path : {t_solve * 1e3:7.0f} ms  {n / t_solve:12,.0f} points/s")
    lin, t_lin = _timed(lambda: linearize(m, cl.tip, cl.axis, sol.joints))
    print(f"linearize  : {t_lin * 1e3:7.0f} ms  {n / t_lin:12,.0f} points/s  "
          f"({len(lin.tip) - n:,} inserted, max deviation {lin.max_deviation_mm * 1e3:.2f} um)")
    texts = {}
    for d in DIALECTS:
        res, t = _timed(lambda: post(cl, m, PostOptions(dialect=d)))
        tracemalloc.start()
        post(cl, m, PostOptions(dialect=d))
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        texts[d] = res.text
        print(f"post {d:12s}: {t * 1e3:6.0f} ms  {n / t:10,.0f} points/s  "
              f"{len(res.tip):,} blocks, peak {peak / 1e6:.0f} MB")
    prog, t_read = _timed(lambda: parse_program(texts["linuxcnc"]))
    print(f"read back  : {t_read * 1e3:7.0f} ms  {len(prog) / t_read:12,.0f} blocks/s")
    j = lin.joints

    def baseline():
        return "\n".join(f"G1 X{a:.4f} Y{b:.4f} Z{c:.4f} A{np.degrees(d):.4f} "
                         f"C{np.degrees(e):.4f} F1500." for a, b, c, d, e in j.tolist())

    _, t_base = _timed(baseline)
    _, t_lcnc = _timed(lambda: post(cl, m, PostOptions(dialect="linuxcnc")))
    print(f"baseline f-string formatting of {len(j):,} lines: {t_base * 1e3:.0f} ms; "
          f"post(linuxcnc)/baseline = {t_lcnc / t_base:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
