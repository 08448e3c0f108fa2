"""The plan as JSON: per cutter location and a summary (degrees and µm only here); and the
one-line summary of the points without a feasible posture (the planner's and the job's refusal)."""

from __future__ import annotations

import json
import math
import os

import numpy as np

from nc.atomic import atomic_write

from .constants import INFEASIBLE_LISTED
from .plan import PlanResult

__all__ = ["infeasible_summary", "plan_report", "summary", "write_plan_report"]


def _f(x: float, nd: int = 4):
    """JSON-friendly float: None for inf/NaN."""
    x = float(x)
    return round(x, nd) if math.isfinite(x) else None


def summary(res: PlanResult) -> dict:
    """Smallest and median margins before and after, postures, checks, and the points
    without a feasible posture (``infeasible``: indices; their CAM posture was kept)."""
    idx = res.touching_index
    m, mc = res.margin[idx], res.cam_margin[idx]
    worst = int(idx[np.argmin(m)])
    worst_cam = int(idx[np.argmin(mc)])
    return {
        "points": len(res.cl), "cutting_points": len(idx),
        "spindle_rpm": res.spindle_rpm,
        "machine": getattr(res.machine, "name", str(res.machine)),
        "margin_min": _f(m.min()), "margin_median": _f(np.median(m)),
        "margin_min_at": {"point": worst, "block": int(res.cl.block[worst])},
        "cam_margin_min": _f(mc.min()), "cam_margin_median": _f(np.median(mc)),
        "cam_margin_min_at": {"point": worst_cam, "block": int(res.cl.block[worst_cam])},
        "points_below_1_before": int(np.sum(mc < 1.0)),
        "points_below_1_after": int(np.sum(m < 1.0)),
        "cam_infeasible_points": int(np.sum(~res.cam_feasible[idx])),
        "planned_collisions": res.stats.get("planned_collisions"),
        "infeasible_points": int(len(res.infeasible)),
        "infeasible": [int(i) for i in res.infeasible],
        "infeasible_lines": res.stats.get("infeasible_lines", []),
        "interference_dropped": res.stats.get("interference_dropped"),
        "inclination_deg_range": [_f(np.degrees(np.nanmin(_incl(res)))),
                                  _f(np.degrees(np.nanmax(_incl(res))))],
        "time_periodic_checks": res.sdm_checks,
        "wall_first_frequencies_hz": res.stats.get("wall_first_frequencies_hz", []),
        "seconds": {k: round(v, 3) for k, v in res.stats.get("seconds", {}).items()},
    }


def _incl(res: PlanResult) -> np.ndarray:
    idx = res.touching_index
    c = np.sum(res.cl.axis[idx] * res.contacts.normal[idx], axis=1)
    return np.arccos(np.clip(c, -1.0, 1.0))


def plan_report(res: PlanResult, *, scenario: str = "", program: str = "") -> dict:
    """The whole report as a JSON-ready dict."""
    pts = []
    touching = np.zeros(len(res.cl), bool)
    touching[res.touching_index] = True
    infeasible = np.zeros(len(res.cl), bool)
    infeasible[res.infeasible] = True
    for i in range(len(res.cl)):
        rec = {"point": i, "block": int(res.cl.block[i]), "cutting": bool(touching[i]),
               "infeasible": bool(infeasible[i]),
               "tip_mm": [round(float(v), 5) for v in res.cl.tip[i]],
               "axis": [round(float(v), 7) for v in res.cl.axis[i]],
               "reason": res.reason[i]}
        if touching[i]:
            rec.update({
                "normal": [round(float(v), 6) for v in res.contacts.normal[i]],
                "lead_deg": _f(math.degrees(res.lead_rad[i]), 3),
                "tilt_deg": _f(math.degrees(res.tilt_rad[i]), 3),
                "margin": _f(res.margin[i]), "cut_sense": _f(res.cut_sense[i], 3),
                "cam_lead_deg": _f(math.degrees(res.cam_lead_rad[i]), 3),
                "cam_tilt_deg": _f(math.degrees(res.cam_tilt_rad[i]), 3),
                "cam_margin": _f(res.cam_margin[i]),
                "cam_cut_sense": _f(res.cam_cut_sense[i], 3),
                "cam_feasible": bool(res.cam_feasible[i])})
        pts.append(rec)
    return {"scenario": scenario, "program": program,
            "method": "zero-order margin at the spindle speed (time-periodic checks at the "
                      "lowest points); margin > 1 stable",
            "summary": summary(res), "points": pts}


def write_plan_report(path: str | os.PathLike, res: PlanResult, **kw) -> dict:
    """Write :func:`plan_report` atomically; returns it."""
    rep = plan_report(res, **kw)
    with atomic_write(path) as fh:
        json.dump(rep, fh, indent=1)
        fh.write("\n")
    return rep


def infeasible_summary(res: PlanResult, listed: int = INFEASIBLE_LISTED) -> str:
    """One line: how many points of a plan have no feasible posture, the first
    ``listed`` of them (CAM program lines and point indices) and the reason of the
    first cutting point among them (of the first point if none cuts).

    Parameters
    ----------
    res : orient.plan.PlanResult
        A plan with at least one point in ``res.infeasible``.
    listed : int
        Points named.

    Returns
    -------
    str
        Without a line break.
    """
    inf = res.infeasible
    lines = res.stats.get("infeasible_lines", [])
    more = ", ..." if len(inf) > listed else ""
    cutting = inf[np.isin(inf, res.touching_index)]
    first = int(cutting[0]) if len(cutting) else int(inf[0])
    return (f"{len(inf)} of {len(res.cl)} points have no feasible posture, at CAM program "
            f"lines {', '.join(map(str, lines[:listed]))}{', ...' if len(lines) > listed else ''}"
            f" (points {', '.join(map(str, inf[:listed].tolist()))}{more}); point "
            f"{first}: {res.reason[first].removeprefix('infeasible: ')}")
