"""Regenerate the converged time-periodic limits of the 1-DOF milling benchmark.

Writes ``tests/orient/data/sdm_1dof_converged.csv``: the stability limit
(axial depth [mm]) of Insperger & Stepan's 1-DOF milling model (m = 0.03993
kg, 922 Hz, zeta = 0.011, Kt = 6e8 N/m^2, Kn = 2e8 N/m^2, 2 teeth; the
constants of ``tests/orient/test_stability.py``) on the grid spindle 5,000 to
25,000 rev/min every 500, radial immersion a/D = 0.05, 0.1, 0.5, 1, up and
down milling, converged by refinement:

* :func:`orient.stability.sdm_margin` at ``k = L, 2L, 4L`` steps per tooth
  period, ``L = max(32, ceil(16 tau f_n))`` (16, 32, 64 steps per period of
  the mode at least), with the directional matrix as exact step averages on
  ``16 k`` intervals (16 exact sub-steps per step), margin tolerance 1e-9;
* the method converges as ``dt^2`` once the coefficient is integrated
  exactly, so the limit is Richardson's ``R = s_4L + (s_4L - s_2L) / 3``;
  ``R' = s_2L + (s_2L - s_L) / 3`` gives the error estimate ``|R - R'|``
  (written as ``uncertainty``) and the observed order
  ``log2((s_L - s_2L) / (s_2L - s_4L))``. Where ``R`` and ``R'`` differ by
  more than 0.02 %, the refinement goes on (8L, then 16L) and the last three
  levels are used;
* the margin is the smallest ``s`` with spectral radius 1: the first
  level scans upward from the default start (a quarter of the ZOA critical
  margin) by factors of 1.02 (not the default 1.3, which can step over a
  narrow unstable window), the finer ones from 0.9 times the coarser
  level's margin.

Also written, for information: the zero-order (ZOA) limit of the same
point (:func:`orient.stability.zoa_margin` of the exact mean directional
matrix). Run (about 10 minutes on one core):

    PYTHONPATH=$PWD python scripts/sdm_benchmark_table.py [--out PATH] [--speed-step RPM]
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from pathlib import Path

import numpy as np

from errpred.dynamics import Mode
from orient.dynamics import ModalSystem
from orient.stability import StraightEndMill2D, sdm_margin, zoa_margin
from orient.stability import sdm as _sdm

M_KG, FN_HZ, ZETA = 0.03993, 922.0, 0.011
K_N_M = 1340049.648                 # = M_KG (2 pi FN_HZ)^2
KT, KN, TEETH = 6e8, 2e8, 2
IMMERSIONS = (0.05, 0.1, 0.5, 1.0)
MILLING = ("up", "down")
SUBSTEPS = 16
RTOL = 1e-9
#: Refine while two successive Richardson values differ by more than this [-] ...
AGREE = 2e-4
#: ... up to this many levels (16 L steps) [-].
MAX_LEVELS = 5
#: The scan in ``s`` multiplies by this per step (instead of ``SDM_SCAN_FACTOR``): fine
#: enough not to step over a narrow unstable window below the boundary [-].
SCAN_FACTOR = 1.02
OUT = Path(__file__).resolve().parents[1] / "tests" / "orient" / "data" / "sdm_1dof_converged.csv"


def system() -> ModalSystem:
    wn = 2 * math.pi * FN_HZ
    m = K_N_M / wn ** 2
    return ModalSystem.from_modes([(Mode(K_N_M, m, 2 * ZETA * math.sqrt(K_N_M * m)),
                                    (1.0, 0.0, 0.0))])


def _level(tool: StraightEndMill2D, sys_: ModalSystem, rpm: float, k: int,
           near: float | None) -> tuple[float, str]:
    """Margin at ``k`` steps: the fine scan from the default start, or from just
    below the coarser level's margin ``near`` (the margins converge from above)."""
    h = tool.directional_samples(k * SUBSTEPS)
    start = None if near is None else 0.9 * near
    res = sdm_margin(h, sys_, rpm, TEETH, steps=k, s_start=start, rtol=RTOL)
    if start is not None and res.margin <= start:          # unstable at the start: redo
        res = sdm_margin(h, sys_, rpm, TEETH, steps=k, rtol=RTOL)
    return res.margin, res.kind


def converged(tool: StraightEndMill2D, sys_: ModalSystem, rpm: float) -> dict:
    """Levels ``L, 2L, 4L`` (and on, to ``MAX_LEVELS``, while two successive Richardson
    values differ by more than ``AGREE`` relative); the last Richardson value."""
    tau = 60.0 / (rpm * TEETH)
    base = max(32, math.ceil(16 * tau * FN_HZ))
    s = [_level(tool, sys_, rpm, base, None)[0]]
    s.append(_level(tool, sys_, rpm, 2 * base, s[-1])[0])
    r_prev = math.nan
    while True:
        m, kind = _level(tool, sys_, rpm, base * 2 ** len(s), s[-1])
        s.append(m)
        r = s[-1] + (s[-1] - s[-2]) / 3
        r_prev = s[-2] + (s[-2] - s[-3]) / 3
        if abs(r - r_prev) <= AGREE * r or len(s) >= MAX_LEVELS:
            break
    a, b = s[-3] - s[-2], s[-2] - s[-1]
    order = math.log2(a / b) if a * b > 0 else math.nan
    return {"limit_mm": r, "uncertainty_mm": abs(r - r_prev), "order": order, "kind": kind,
            "base_steps": base, "levels": len(s), "finest_steps": base * 2 ** (len(s) - 1),
            "s_finest": s[-1]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--speed-step", type=float, default=500.0, help="rev/min")
    args = ap.parse_args(argv)
    _sdm.SDM_SCAN_FACTOR = SCAN_FACTOR        # this script's process only
    sys_ = system()
    speeds = np.arange(5000.0, 25000.0 + 1e-9, args.speed_step)
    rows = []
    t0 = time.perf_counter()
    for milling in MILLING:
        for ad in IMMERSIONS:
            tool = StraightEndMill2D(KT, KN, TEETH, ad, milling, depth_mm=1.0)
            p = tool.mean_directional_matrix()
            for rpm in speeds:
                c = converged(tool, sys_, float(rpm))
                c.update(milling=milling, radial_immersion=ad, rpm=float(rpm),
                         zoa_mm=zoa_margin(p, sys_, float(rpm), TEETH))
                rows.append(c)
                print(f"{milling:4s} {ad:4.2f} {rpm:7.0f}  {c['limit_mm']:.6f} mm "
                      f"+- {c['uncertainty_mm']:.1e}  order {c['order']:.2f}  {c['kind']:4s}"
                      f"  ({time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    cols = ["milling", "radial_immersion", "rpm", "limit_mm", "uncertainty_mm", "kind", "order",
            "base_steps", "levels", "finest_steps", "s_finest", "zoa_mm"]
    with open(args.out, "w", newline="") as f:
        f.write("# Converged time-periodic stability limits [mm] of the 1-DOF milling benchmark\n"
                "# (Insperger & Stepan; tests/orient/test_stability.py), Richardson-extrapolated\n"
                "# from L, 2L, 4L steps per tooth period; regenerate with\n"
                "# scripts/sdm_benchmark_table.py (its docstring says how).\n")
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({c: (f"{r[c]:.9g}" if isinstance(r[c], float) else r[c]) for c in cols})
    print(f"wrote {args.out} ({len(rows)} rows, {time.perf_counter() - t0:.0f} s)",
          file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
