"""The prediction report: one JSON record per prediction point and a summary.

Units in key names (``_um``, ``_mm``, ``_N``, ``_deg``). Errors are positive
where material is left (undercut). The report is written atomically.
"""

from __future__ import annotations

import json
import math
import os
from typing import Any

import numpy as np

from nc.atomic import atomic_write

from .geometry import STATUS
from .predict import Prediction

__all__ = ["point_record", "summary", "report", "write_report", "tool_change"]


def _r(v: float, nd: int = 4) -> float | None:
    return None if v is None or not math.isfinite(v) else round(float(v), nd)


def _vec(v, nd: int = 6) -> list[float | None]:
    return [round(float(x), nd) if math.isfinite(float(x)) else None for x in v]


def point_record(p) -> dict[str, Any]:
    """One prediction point as a plain dict."""
    g = p.geometry
    rec: dict[str, Any] = {
        "line": p.line,
        "block": g.block,
        "status": g.status,
        "cuts": g.cuts,
        "reason": STATUS.get(g.status, g.status),
        "point_mm": _vec(g.tip, 5),
        "axis": _vec(g.axis),
    }
    if g.gen is not None:
        rec.update({
            "view": g.view,
            "theta_m_deg": _r(math.degrees(g.gen.theta_rad), 3),
            "kappa_m_deg": _r(math.degrees(g.gen.kappa_rad), 3),
            "normal": _vec(g.gen.normal_world),
            "generation_point_mm": _vec(g.gen.point_world, 5),
            "finished_pixels": g.finished_pixels,
        })
    if p.result is not None and not math.isfinite(p.result.E_um):
        r = p.result
        rec.update({"peak_force_N": _r(r.peak_force_N, 3), "mean_force_N": _vec(r.mean_force_N, 3),
                    "cutting_distance_mm": {"max_edge": _r(r.cl_max_mm, 3)}})
    elif p.result is not None:
        r = p.result
        rec.update({
            "peak_force_N": _r(r.peak_force_N, 3),
            "mean_force_N": _vec(r.mean_force_N, 3),
            "deflection_um": _vec(r.deflection_um, 4),
            "E_d_um": _r(r.E_d_um),
            "E_p_um": _r(r.E_p_um),
            "E_um": _r(r.E_um),
            "cutting_distance_mm": {"max_edge": _r(r.cl_max_mm, 3),
                                    "generating_edge": _r(r.cl_gen_mm, 3)},
        })
    if g.notes:
        rec["notes"] = list(g.notes)
    return rec


def _numbered(records: list[dict]) -> list[dict]:
    """Number the points of blocks that have several (long blocks)."""
    count: dict[int, int] = {}
    for r in records:
        count[r["block"]] = count.get(r["block"], 0) + 1
    seen: dict[int, int] = {}
    for r in records:
        if count[r["block"]] > 1:
            r["point"] = seen.get(r["block"], 0)
            seen[r["block"]] = r["point"] + 1
    return records


def tool_change(prediction: Prediction, tolerance_um: float | None) -> dict | None:
    """The first predicted point whose |E| (with wear) exceeds the tolerance."""
    if tolerance_um is None:
        return None
    for p in prediction.predicted():
        if abs(p.result.E_um) > tolerance_um:
            return {"tolerance_um": tolerance_um, "line": p.line, "block": p.block,
                    "E_um": _r(p.result.E_um),
                    "cutting_distance_mm": _r(p.result.cl_max_mm, 3),
                    "advice": f"change the tool before line {p.line}: the predicted error "
                              f"with wear exceeds {tolerance_um:g} um there"}
    return {"tolerance_um": tolerance_um, "line": None,
            "advice": f"the predicted error stays within {tolerance_um:g} um: no tool change"}


def summary(prediction: Prediction, tool_change_um: float | None = None) -> dict[str, Any]:
    """Largest and mean error and where, counts per status, wear at the end."""
    pts = prediction.points
    counts: dict[str, int] = {}
    for p in pts:
        counts[p.status] = counts.get(p.status, 0) + 1
    pred = prediction.predicted()
    out: dict[str, Any] = {"points": len(pts), "blocks": len({p.block for p in pts}),
                           "status_counts": counts}
    if pred:
        E = np.array([p.result.E_um for p in pred])
        k = int(np.argmax(np.abs(E)))
        worst = pred[k]
        out.update({
            "max_abs_error_um": _r(abs(E[k])),
            "max_error_um": _r(E[k]),
            "max_error_at": {"line": worst.line, "block": worst.block,
                             "point_mm": _vec(worst.geometry.tip, 4)},
            "mean_error_um": _r(float(E.mean())),
            "mean_abs_error_um": _r(float(np.abs(E).mean())),
            "max_undercut_um": _r(float(E.max())),
            "max_overcut_um": _r(float(E.min())),
        })
    out["wear"] = {"max_cutting_distance_mm": _r(float(prediction.wear_mm.max(initial=0.0)), 3),
                   "mean_cutting_distance_mm": _r(float(prediction.wear_mm.mean()), 3)
                   if prediction.wear_mm.size else 0.0}
    tc = tool_change(prediction, tool_change_um)
    if tc is not None:
        out["tool_change"] = tc
    return out


def report(prediction: Prediction, meta: dict[str, Any] | None = None,
           tool_change_um: float | None = None) -> dict[str, Any]:
    """The whole report: metadata, summary, per-point records, wear per edge."""
    return {
        **(meta or {}),
        "summary": summary(prediction, tool_change_um),
        "points": _numbered([point_record(p) for p in prediction.points]),
        "wear_per_micro_edge": {
            "kappa_deg": _vec(np.degrees(prediction.edges_kappa_rad), 3),
            "z_mm": _vec(prediction.edges_z_mm, 4),
            "cutting_distance_mm": _vec(prediction.wear_mm, 3),
        },
    }


def write_report(path: str | os.PathLike, rep: dict[str, Any]) -> None:
    """Write the report as JSON, atomically."""
    with atomic_write(path) as fh:
        json.dump(rep, fh, indent=1, allow_nan=False)
        fh.write("\n")
