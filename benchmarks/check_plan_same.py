"""Compare two plans of one scenario (issue 20: the planner made faster must plan the
same): the chosen posture per cutter location, the speed, the margins, the cut senses,
the reasons, the infeasible points and the grid's margins and feasibility.

Saves a plan's arrays with ``--save FILE.npz`` (run on the code before a change), then
compares a later run's against it with ``--against FILE.npz``; prints the largest
differences and exits 1 where the chosen postures, the speed, the reasons or the
infeasible points differ or a margin differs by more than ``--rtol``.

Usage: python benchmarks/check_plan_same.py SCENARIO [--save F.npz] [--against F.npz]
       [--rtol 1e-6]

Differences are relative to the value, or absolute for values below 1 in size (cut
senses near 0, angles in radians).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, ROOT)

from orient.plan import plan  # noqa: E402
from orient.scenario import load_plan_scenario  # noqa: E402

#: arrays compared exactly (the choice) and within the margin tolerance
EXACT = ("tip", "axis", "feed", "infeasible", "grid_feasible", "rpm")
CLOSE = ("margin", "cam_margin", "sense", "cam_sense", "lead", "tilt", "grid_margin")


def arrays(res) -> dict:
    """The plan's arrays compared (numpy, saveable)."""
    return {"tip": res.cl.tip, "axis": res.cl.axis, "feed": res.cl.feed_mm_min,
            "infeasible": res.infeasible, "grid_feasible": res.grid_feasible,
            "rpm": np.array([res.spindle_rpm]), "margin": res.margin,
            "cam_margin": res.cam_margin, "sense": res.cut_sense,
            "cam_sense": res.cam_cut_sense, "lead": res.lead_rad, "tilt": res.tilt_rad,
            "grid_margin": res.grid_margin, "reason": np.array(res.reason),
            "sdm": np.array([[c["point"], c["zoa_margin"], c["sdm_margin"]]
                             for c in res.sdm_checks]).reshape(-1, 3)}


def compare(a: dict, b: dict, rtol: float) -> list[str]:
    """Lines describing each difference beyond the tolerances (empty: the same plan)."""
    bad = []
    for k in EXACT:
        if not np.array_equal(a[k], b[k], equal_nan=True):
            bad.append(f"{k}: differs")
    if not np.array_equal(a["reason"], b["reason"]):
        d = np.flatnonzero(a["reason"] != b["reason"])
        for i in d[:3]:
            print(f"  reason {i}: {a['reason'][i]!r}\n    was {b['reason'][i]!r}")
        bad.append(f"reason: {len(d)} differ")
    for k in CLOSE + ("sdm",):
        x, y = np.asarray(a[k], float), np.asarray(b[k], float)
        if x.shape != y.shape:
            bad.append(f"{k}: shapes {x.shape} and {y.shape}")
            continue
        same_inf = np.array_equal(~np.isfinite(x), ~np.isfinite(y)) and \
            np.array_equal(x[~np.isfinite(x)], y[~np.isfinite(y)], equal_nan=True)
        f = np.isfinite(x) & np.isfinite(y)
        # relative to the value, or to 1 for values below 1 (a cut sense near 0, angles)
        rel = np.abs(x[f] - y[f]) / np.maximum(np.abs(y[f]), 1.0) if f.any() else [0.0]
        worst = float(np.max(rel, initial=0.0))
        print(f"  {k}: largest relative difference {worst:.3g}"
              f"{'' if same_inf else ' (non-finite entries differ)'}")
        if worst > rtol or not same_inf:
            bad.append(f"{k}: relative difference {worst:.3g} > {rtol:g}")
    return bad


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario")
    ap.add_argument("--save", help="write this plan's arrays here (.npz)")
    ap.add_argument("--against", help="compare with the arrays saved here (.npz)")
    ap.add_argument("--rtol", type=float, default=1e-6)
    args = ap.parse_args(argv)
    scn = load_plan_scenario(args.scenario)
    t0, c0 = time.perf_counter(), time.process_time()
    res = plan(scn)
    print(f"plan: {time.perf_counter() - t0:.1f} s wall, {time.process_time() - c0:.1f} s CPU, "
          f"load {os.getloadavg()[0]:.1f}; stages {res.stats['seconds']}")
    mine = arrays(res)
    if args.save:
        np.savez(args.save, **mine)
    if not args.against:
        return 0
    ref = dict(np.load(args.against))
    bad = compare(mine, ref, args.rtol)
    for line in bad:
        print(f"DIFFERS {line}")
    print("same plan" if not bad else f"{len(bad)} differences")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
