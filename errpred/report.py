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
            "E_wear_um": _r(r.E_wear_um),
            "cutting_distance_mm": {"max_edge": _r(r.cl_max_mm, 3),
                                    "generating_edge": _r(r.cl_gen_mm, 3),
                                    "most_worn_shaping_edge": _r(r.cl_wear_mm, 3)},
        })
        if g.wall is not None and math.isfinite(r.E_wall_um):
            rec["wall"] = {"E_um": _r(r.E_wall_um), "normal": _vec(g.wall.normal_world),
                           "generation_point_mm": _vec(g.wall.point_world, 5),
                           "theta_m_deg": _r(math.degrees(g.wall.theta_rad), 3)}
    if g.above_flutes:
        rec["above_flutes"] = True          # an error finding (errpred.findings)
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
    """When to change the tool: decided on the wear part of the error only.

    The wear part ``W`` of a point (:mod:`errpred.physics`, module docstring)
    is its error with the tool's wear minus the error a fresh tool leaves at
    the same point: the deflection added by the edge forces' growth plus the
    radius lost. What a fresh tool leaves (its deflection, its form error) a
    new tool leaves again; the path correction takes it out, a tool change
    does not. So a 29.5 um deflection error with 2.8 um of wear is no reason
    to change the tool; 30 um of wear is.

    **Where.** The first predicted point (program order) with ``|W|`` above
    the tolerance: change the tool before its line.

    **How far the tool can still cut.** ``W`` is linear in the cutting
    distances of the micro edges that shape the point, ``W_i(cl) = w_i . cl``
    (:meth:`errpred.physics.PointResult.wear_part_um`), so it is known for
    any state of the tool, not only the one the point was cut with. The
    tool is assumed to go on wearing as in this run: after ``x`` more runs of
    the program its state is ``cl_end + x D``, ``D`` what each micro edge cut
    in this run, and point ``i`` would then have ``W_i(cl_end) + x W_i(D)``.
    It reaches the tolerance at ``x_i = (tol - |W_i(cl_end)|) / |W_i(D)|``
    (0 if already over, no limit if it does not grow); the smallest ``x_i``
    over the points is reported, as runs and as the cutting distance of the
    tool's most-worn micro edge among those the program cuts (``x D_j``),
    with the point it comes from and its wear part with the tool as it is
    now (``W_i(cl_end)``: what cutting that line again would leave). For a
    linear radius loss alone (``Kxe1 = 0``) on micro edges that all cut
    alike this is ``(tol - rate cl_end) / rate``.

    Parameters
    ----------
    prediction : Prediction
    tolerance_um : float or None [um]
        ``[tool_change] tolerance_um``; None: no finding (returns None).

    Returns
    -------
    dict or None
        Keys (units in the names; None where there is no such point):
        ``tolerance_um``, ``criterion``; ``line``, ``block``,
        ``wear_error_um``, ``E_um``, ``cutting_distance_mm`` (its most-worn
        shaping edge) of the first point over the tolerance;
        ``max_wear_error_um`` (signed, largest ``|W|``) and
        ``max_wear_error_at`` (``line``, ``block``, ``edge_force_um``,
        ``radius_loss_um``); ``max_wear_error_now_um`` (largest ``|W_i(cl_end)|``);
        ``remaining_cutting_distance_mm``, ``remaining_program_runs``,
        ``cutting_distance_at_tolerance_mm``, ``wear_growth_um_per_m`` (of the
        binding point's wear part per m the edge cuts), ``remaining_at``
        (``line``, ``block``, ``wear_error_now_um``, and the edge:
        ``micro_edge``, ``kappa_deg``, ``z_mm``, ``cutting_distance_mm`` now,
        ``this_run_mm``); ``advice``, in words.
    """
    if tolerance_um is None:
        return None
    tol = float(tolerance_um)
    pts = [p for p in prediction.predicted()
           if math.isfinite(p.result.E_wear_um) and p.result.wear_edges is not None]
    out: dict[str, Any] = {
        "tolerance_um": tol,
        "criterion": "wear part of the error: E with the tool's wear minus E of a fresh "
                     "tool at the same point (edge-force growth and radius loss)",
        "line": None, "block": None, "wear_error_um": None, "E_um": None,
        "cutting_distance_mm": None, "max_wear_error_um": None, "max_wear_error_at": None,
        "max_wear_error_now_um": None, "remaining_cutting_distance_mm": None,
        "remaining_program_runs": None, "cutting_distance_at_tolerance_mm": None,
        "wear_growth_um_per_m": None, "remaining_at": None,
    }
    if not pts:
        out["advice"] = "no predicted point: nothing to decide a tool change on"
        return out
    W = np.array([p.result.E_wear_um for p in pts])
    first = next((p for p, w in zip(pts, W, strict=True) if abs(w) > tol), None)
    if first is not None:
        r = first.result
        out.update({"line": first.line, "block": first.block,
                    "wear_error_um": _r(r.E_wear_um), "E_um": _r(r.E_um),
                    "cutting_distance_mm": _r(r.cl_wear_mm, 3)})
    k = int(np.argmax(np.abs(W)))
    worst = pts[k].result
    out["max_wear_error_um"] = _r(W[k])
    out["max_wear_error_at"] = {"line": pts[k].line, "block": pts[k].block,
                                "edge_force_um": _r(worst.E_wear_d_um),
                                "radius_loss_um": _r(worst.E_wear_p_um)}
    end = prediction.wear_mm
    start = prediction.initial_wear_mm if prediction.initial_wear_mm is not None \
        else np.zeros_like(end)
    run = end - start
    now = np.array([p.result.wear_part_um(end) for p in pts])
    per_run = np.array([p.result.wear_part_um(run) for p in pts])
    out["max_wear_error_now_um"] = _r(now[np.argmax(np.abs(now))])
    x = np.full(len(pts), math.inf)
    x[np.abs(now) >= tol] = 0.0
    grows = (np.abs(now) < tol) & (per_run != 0.0)
    x[grows] = (np.sign(per_run[grows]) * tol - now[grows]) / per_run[grows]
    cut = np.flatnonzero(run > 0)
    i = int(np.argmin(x))
    if math.isfinite(x[i]) and cut.size:
        j = int(cut[np.argmax(end[cut])])   # the most-worn micro edge this program cuts
        p = pts[i]
        out.update({
            "remaining_cutting_distance_mm": _r(x[i] * run[j], 3),
            "remaining_program_runs": _r(x[i], 4),
            "cutting_distance_at_tolerance_mm": _r(end[j] + x[i] * run[j], 3),
            "wear_growth_um_per_m": _r(abs(per_run[i]) / run[j] * 1e3, 6),
            "remaining_at": {"line": p.line, "block": p.block,
                             "wear_error_now_um": _r(now[i]), "micro_edge": j,
                             "kappa_deg": _r(math.degrees(prediction.edges_kappa_rad[j]), 3),
                             "z_mm": _r(prediction.edges_z_mm[j], 4),
                             "cutting_distance_mm": _r(float(end[j]), 3),
                             "this_run_mm": _r(float(run[j]), 3)},
        })
    if first is not None:
        r = first.result
        out["advice"] = (
            f"change the tool before line {first.line}: from there on wear alone (edge forces "
            f"{r.E_wear_d_um:+.1f} um, radius loss {r.E_wear_p_um:+.1f} um) moves the surface "
            f"by {r.E_wear_um:+.1f} um, more than the {tol:g} um tolerance; the most-worn "
            f"cutting edge there has cut {r.cl_wear_mm / 1e3:.2f} m")
    elif not np.any(W):
        out["advice"] = (f"no wear in the scenario's models (wear coefficients Kxe1 and "
                         f"wear_rate_um_per_m are 0): the wear part is 0 and the {tol:g} um "
                         "tool-change tolerance is never reached; the error that remains is "
                         "for the path correction")
    elif out["remaining_program_runs"] is None:
        out["advice"] = (f"no tool change needed in this program: wear moves the surface by at "
                         f"most {W[k]:+.1f} um (line {pts[k].line}), within the {tol:g} um "
                         "tolerance, and it does not grow further")
    else:
        j, p = out["remaining_at"]["micro_edge"], pts[i]
        out["advice"] = (
            f"no tool change needed in this program: wear moves the surface by at most "
            f"{W[k]:+.1f} um (line {pts[k].line}), within the {tol:g} um tolerance. The tool "
            f"can cut about {x[i] * run[j] / 1e3:.2f} m more (actual cutting distance of its "
            f"most-worn cutting edge, {prediction.edges_z_mm[j]:.2f} mm above the tip), about "
            f"{x[i]:.2f} more run(s) of this program, before wear alone reaches {tol:g} um "
            f"(first at line {p.line}; cut again now it would be {now[i]:+.1f} um)")
    return out


def summary(prediction: Prediction, tool_change_um: float | None = None) -> dict[str, Any]:
    """Largest and mean error and where, counts per status, wear at the start and the
    end, and the tool-change finding (:func:`tool_change`) with a tolerance."""
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
            "error_range_um": [_r(float(E.min())), _r(float(E.max()))],
            # E > 0 leaves material (undercut), E < 0 cuts into the part (overcut):
            # each the largest of its kind, 0 where there is none.
            "max_undercut_um": _r(max(float(E.max()), 0.0) + 0.0),
            "max_overcut_um": _r(max(-float(E.min()), 0.0) + 0.0),
        })
        walls = [p for p in pred if p.geometry.wall is not None
                 and math.isfinite(p.result.E_wall_um)]
        if walls:
            # the walls a flat or radius end mill's flank finishes beside the floors above
            # (PointGeometry.wall): predicted, not corrected
            Ew = np.array([p.result.E_wall_um for p in walls])
            kw = int(np.argmax(np.abs(Ew)))
            out["walls"] = {"points": len(walls), "max_abs_error_um": _r(abs(Ew[kw])),
                            "max_error_um": _r(Ew[kw]), "line": walls[kw].line,
                            "error_range_um": [_r(float(Ew.min())), _r(float(Ew.max()))]}
    start = prediction.initial_wear_mm
    out["wear"] = {"max_cutting_distance_mm": _r(float(prediction.wear_mm.max(initial=0.0)), 3),
                   "mean_cutting_distance_mm": _r(float(prediction.wear_mm.mean()), 3)
                   if prediction.wear_mm.size else 0.0,
                   "start_max_cutting_distance_mm": _r(float(start.max(initial=0.0)), 3)
                   if start is not None else 0.0}
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
