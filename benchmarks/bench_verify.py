"""Timings of the main job's simulated verification runs (issue 17).

The job (``python -m sim job``, ``sim/job.py`` step 5) runs three simulated runs
(:func:`sim.verify.verify_program`): the planned program, the corrected one, and
the CAM program's worst pass. This runs the same three, one after the other in
this process on one core, from a job's output folder (``--job DIR``: its
``report.json`` and the two programs it wrote, ``NAME-planned.nc`` and
``NAME.nc``, or their ``.NOT-FOR-CUTTING.nc`` names), and prints per run the wall
time (min and median over ``--repeats``), the simulated time and the run's
figures, and the process's CPU time (less sensitive to other processes on a
loaded machine than the wall time). The kernels are compiled (or loaded from
numba's cache) by a short run first, outside the timing; the workpiece model of
each program is built once, outside the timing too (the job hands the planner's
to the runs).

``--save FILE.npz`` keeps each run's answers (surface error and chatter marks per
cutter location, the averaged spectrum, the detector's figures) to compare two
versions of the code (``--compare FILE.npz``: the largest differences).

Usage: python benchmarks/bench_verify.py --job DIR [--scenario S] [--repeats N]
[--runs planned,corrected,cam] [--stretch FIRST,LAST] [--save F.npz] [--compare F.npz]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")                  # one core
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")               # BLAS too

import numpy as np

sys.path.insert(0, os.path.abspath(os.path.join(os.path.dirname(__file__), "..")))

from orient.scenario import load_plan_scenario
from sim.cli import BUNDLED
from sim.machine import SimulatedNC
from sim.verify import scenario_with_program, verify_program


def _program(job: Path, name: str) -> Path:
    for p in (job / f"{name}.nc", job / f"{name}.NOT-FOR-CUTTING.nc"):
        if p.exists():
            return p
    raise SystemExit(f"{job}: no {name}.nc (nor {name}.NOT-FOR-CUTTING.nc)")


def _answers(v) -> dict[str, np.ndarray]:
    s = v.summary
    return {"points": v.points, "surface_um": v.surface_um, "marks_um": v.marks_um,
            "spectrum": v.spectrum_m_s2,
            "figures": np.array([v.machining_s, s["chatter_windows"], s["sustained_episodes"],
                                 v.covered.size], dtype=float)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--job", required=True, type=Path, help="a job's output folder")
    ap.add_argument("--scenario", default=str(BUNDLED))
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--runs", default="planned,corrected,cam")
    ap.add_argument("--stretch", help="FIRST,LAST: run only these cutter locations of the "
                    "planned and corrected programs (a shorter measurement)")
    ap.add_argument("--save", type=Path)
    ap.add_argument("--compare", type=Path)
    args = ap.parse_args(argv)
    scn = load_plan_scenario(args.scenario)
    report = json.loads((args.job / "report.json").read_text())
    name = report["scenario"] if isinstance(report.get("scenario"), str) else scn.name
    cam = tuple(report["simulation"]["cam_worst_pass"]["cutter_locations_run"])
    part = tuple(int(x) for x in args.stretch.split(",")) if args.stretch else None
    runs = {"planned": (scenario_with_program(scn, _program(args.job, f"{name}-planned")), part),
            "corrected": (scenario_with_program(scn, _program(args.job, name)), part),
            "cam": (scn, cam)}
    picked = [r.strip() for r in args.runs.split(",") if r.strip()]
    print(f"load average at start {', '.join(f'{x:.2f}' for x in os.getloadavg())}; "
          f"NUMBA_NUM_THREADS={os.environ['NUMBA_NUM_THREADS']}, "
          f"OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']}")
    t = time.perf_counter()
    s0, _ = runs["cam"]
    verify_program(s0, points=(cam[0], cam[0] + 3))
    print(f"warm-up (kernels compiled or loaded): {time.perf_counter() - t:.1f} s")
    saved = {}
    total = np.zeros(args.repeats)
    cpu_total = np.zeros(args.repeats)
    for key in picked:
        s, pts = runs[key]
        wp = SimulatedNC(s, points=pts).workpiece
        walls, cpus = [], []
        for r in range(args.repeats):
            t, c = time.perf_counter(), time.process_time()
            v = verify_program(s, points=pts, workpiece=wp)
            walls.append(time.perf_counter() - t)
            cpus.append(time.process_time() - c)
            total[r] += walls[-1]
            cpu_total[r] += cpus[-1]
        w, c = np.array(walls), np.array(cpus)
        print(f"{key:9s} {v.machining_s:7.2f} s simulated: wall min {w.min():6.1f} s, median "
              f"{np.median(w):6.1f} s, CPU min {c.min():6.1f} s, median {np.median(c):6.1f} s "
              f"({args.repeats} runs); surface RMS "
              f"{np.sqrt(np.mean(v.surface_um ** 2)):.3f} um, chatter windows "
              f"{v.chatter_windows}, covered {v.covered.size}/{v.asked.size}", flush=True)
        for k, a in _answers(v).items():
            saved[f"{key}.{k}"] = a
    print(f"all      wall min {total.min():6.1f} s, median {np.median(total):6.1f} s, CPU min "
          f"{cpu_total.min():6.1f} s, median {np.median(cpu_total):6.1f} s; load "
          f"average at end {', '.join(f'{x:.2f}' for x in os.getloadavg())}")
    if args.save:
        np.savez(args.save, **saved)
    if args.compare:
        ref = np.load(args.compare)
        for k, a in saved.items():
            if k not in ref:
                continue
            b = ref[k]
            if a.shape != b.shape:
                print(f"compare {k}: shapes {a.shape} and {b.shape}")
                continue
            d = float(np.max(np.abs(a - b))) if a.size else 0.0
            print(f"compare {k}: {'identical' if np.array_equal(a, b) else f'max |diff| {d:.3g}'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
