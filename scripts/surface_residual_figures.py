"""Where the main job's simulated surface error lives, pass by pass, against errpred's
prediction: from a job's ``report.json`` (``python -m sim job``), its ``points``
section (predicted and simulated error before and after the correction, with their
contact points).

Prints the RMS of the simulated and the predicted error before and after correction, and
per waterline level (Z, one pass each on the bundled thin wall): both RMS and the mean of
simulated minus predicted (the prediction interpolated along X at the simulated points,
within the level); then the share of the corrected run's squared error on the top pass
and at the passes' ends. A difference that stays after the correction is what the
correction cannot remove: a difference between the two models.

Usage: python scripts/surface_residual_figures.py REPORT.json [--ends-mm 2]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

#: Two points are on the same waterline level (and at a pass end) within this [mm].
LEVEL_TOL_MM = 0.05


def _rms(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else float("nan")


def _along_levels(p: np.ndarray, e: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``e`` at ``p`` interpolated along X to ``q`` on the same Z level (NaN outside)."""
    out = np.full(len(q), np.nan)
    for z in np.unique(np.round(q[:, 2], 2)):
        m = np.abs(q[:, 2] - z) < LEVEL_TOL_MM
        mp = np.abs(p[:, 2] - z) < LEVEL_TOL_MM
        if mp.sum() < 2:
            continue
        o = np.argsort(p[mp, 0])
        out[m] = np.interp(q[m, 0], p[mp, 0][o], e[mp][o], left=np.nan, right=np.nan)
    return out


def main(argv: list[str] | None = None) -> int:
    a = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    a.add_argument("report", type=Path)
    a.add_argument("--ends-mm", type=float, default=2.0,
                   help="points within this of the run's X extent count as pass ends [mm]")
    args = a.parse_args(argv)
    pts = json.loads(args.report.read_text())["points"]

    def get(key: str) -> tuple[np.ndarray, np.ndarray]:
        return np.asarray(pts[key]["xyz_mm"], float), np.asarray(pts[key]["E_um"], float)

    pb, eb = get("predicted_before")
    pa, ea = get("predicted_after")
    sb, esb = get("simulated_before")
    sa, esa = get("simulated_after")
    qb, qa = _along_levels(pb, eb, sb), _along_levels(pa, ea, sa)
    print(f"simulated RMS {_rms(esb):.3f} -> {_rms(esa):.3f} um (ratio "
          f"{_rms(esa) / _rms(esb):.4f}); predicted {_rms(eb):.3f} -> {_rms(ea):.3f} um")
    print(f"simulated minus predicted at the simulated points, RMS: before "
          f"{_rms(esb - qb):.2f}, after {_rms(esa - qa):.2f} um")
    print(f"{'Z mm':>6} {'n':>4} | {'sim B':>6} {'pred B':>6} {'d B':>6} | "
          f"{'sim A':>6} {'pred A':>6} {'d A':>6}")
    for z in np.unique(np.round(sb[:, 2], 1))[::-1]:
        m = np.abs(sb[:, 2] - z) < LEVEL_TOL_MM
        ma = np.abs(sa[:, 2] - z) < LEVEL_TOL_MM
        db, da = esb[m] - qb[m], esa[ma] - qa[ma]
        print(f"{z:6.2f} {int(m.sum()):4d} | {_rms(esb[m]):6.2f} {_rms(qb[m]):6.2f} "
              f"{np.nanmean(db) if np.isfinite(db).any() else np.nan:6.2f} | "
              f"{_rms(esa[ma]):6.2f} {_rms(qa[ma]):6.2f} "
              f"{np.nanmean(da) if np.isfinite(da).any() else np.nan:6.2f}")
    total = float(np.sum(esa ** 2))
    top = np.abs(sa[:, 2] - sa[:, 2].max()) < LEVEL_TOL_MM
    x0, x1 = sa[:, 0].min(), sa[:, 0].max()
    reach = args.ends_mm + LEVEL_TOL_MM
    ends = (sa[:, 0] <= x0 + reach) | (sa[:, 0] >= x1 - reach)
    print(f"corrected run: top pass {int(top.sum())} points, "
          f"{100 * np.sum(esa[top] ** 2) / total:.1f} % of the squared error; pass ends "
          f"(within {args.ends_mm:g} mm) {int(ends.sum())} points, "
          f"{100 * np.sum(esa[ends] ** 2) / total:.1f} %, RMS {_rms(esa[ends]):.2f} um "
          f"against {_rms(esa[~ends]):.2f} um in between")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
