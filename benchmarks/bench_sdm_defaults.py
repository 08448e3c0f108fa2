"""Accuracy and cost of the time-periodic defaults on the 1-DOF milling benchmark.

Reads the converged limits of ``tests/orient/data/sdm_1dof_converged.csv``
(``scripts/sdm_benchmark_table.py``) and, at every point of its grid, runs
:func:`orient.stability.sdm_margin` the way a caller does by default:
``StraightEndMill2D.directional_samples(tool.recommended_samples())`` and
no ``steps``. Prints the signed relative error (default / converged - 1)
per immersion and milling sense, the worst over the grid, the time per
margin evaluation, and the zero-order (ZOA) error on the same grid for
information.

Usage: PYTHONPATH=$PWD python benchmarks/bench_sdm_defaults.py [--table PATH] [--every N] [--plain]
"""

from __future__ import annotations

import argparse
import csv
import math
import time
from pathlib import Path

import numpy as np

from errpred.dynamics import Mode
from orient.dynamics import ModalSystem
from orient.stability import StraightEndMill2D, sdm_margin

TABLE = Path(__file__).resolve().parents[1] / "tests" / "orient" / "data" / "sdm_1dof_converged.csv"


def _system() -> ModalSystem:
    k, fn, zeta = 1340049.648, 922.0, 0.011
    wn = 2 * math.pi * fn
    m = k / wn ** 2
    return ModalSystem.from_modes([(Mode(k, m, 2 * zeta * math.sqrt(k * m)), (1.0, 0.0, 0.0))])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--table", type=Path, default=TABLE)
    ap.add_argument("--every", type=int, default=1, help="use every N-th row")
    ap.add_argument("--plain", action="store_true",
                    help="pass steps=default_steps explicitly: the margin at the default "
                         "steps without the error control")
    args = ap.parse_args(argv)
    with open(args.table) as f:
        rows = list(csv.DictReader(line for line in f if not line.startswith("#")))[::args.every]
    sys_ = _system()
    sdm_margin(StraightEndMill2D(6e8, 2e8, 2, 1.0, "down").directional_samples(40), sys_,
               15000.0, 2)                                    # compile the kernel first
    err, zerr, t_total = [], [], 0.0
    groups: dict[tuple[str, float], list[float]] = {}
    for r in rows:
        tool = StraightEndMill2D(6e8, 2e8, 2, float(r["radial_immersion"]), r["milling"])
        t0 = time.perf_counter()
        h = tool.directional_samples(tool.recommended_samples())
        steps = None
        if args.plain:
            from orient.stability import default_steps

            steps = default_steps(sys_, float(r["rpm"]), 2)
        s = sdm_margin(h, sys_, float(r["rpm"]), 2, steps=steps).margin
        t_total += time.perf_counter() - t0
        ref = float(r["limit_mm"])
        e = s / ref - 1.0
        err.append(e)
        zerr.append(float(r["zoa_mm"]) / ref - 1.0)
        groups.setdefault((r["milling"], float(r["radial_immersion"])), []).append(e)
    err_a, zerr_a = np.array(err), np.array(zerr)
    for (mill, ad), es in groups.items():
        es = np.array(es)
        print(f"{mill:4s} a/D {ad:4.2f}: error {es.min() * 100:+6.2f} .. {es.max() * 100:+6.2f} %")
    i = int(np.argmax(np.abs(err_a)))
    j = int(np.argmax(err_a))
    print(f"worst |error| {err_a[i] * 100:+.2f} % ({rows[i]['milling']} a/D "
          f"{rows[i]['radial_immersion']} {float(rows[i]['rpm']):.0f} rev/min); "
          f"most unsafe {err_a[j] * 100:+.2f} % ({rows[j]['milling']} a/D "
          f"{rows[j]['radial_immersion']} {float(rows[j]['rpm']):.0f} rev/min); "
          f"{np.sum(err_a > 0.005)} of {len(rows)} points above +0.5 %, "
          f"{np.sum(np.abs(err_a) > 0.01)} beyond 1 %")
    print(f"time per margin evaluation: {t_total / len(rows) * 1e3:.1f} ms "
          f"({len(rows)} points, {t_total:.1f} s)")
    print(f"ZOA on the same grid: {zerr_a.min() * 100:+.1f} .. {zerr_a.max() * 100:+.1f} % "
          f"({np.sum(zerr_a > 0.005)} of {len(rows)} points above +0.5 %)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
