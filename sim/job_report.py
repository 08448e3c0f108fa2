"""The main job's report: the JSON behind it and the self-contained HTML page (no physics)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from errpred.constants import PAGE_WALL_NORMAL_Z
from errpred.correct_path import error_points
from errpred.findings import findings_line
from errpred.page import Figure, Section, render_page
from nc.atomic import atomic_write
from nc.errors import KinematicsError
from nc.kinematics import solve_path

from .constants import JOB_SURFACE_RATIO, SPECTRUM_MAX_HZ
from .job import JobResult
from .job_plots import error_map_png, lobes_png, margin_png, posture_png, spectra_png

__all__ = ["job_page", "job_report", "write_job_report"]

_CHECK_TEXT = {
    "margin_above_1_where_cutting": "stability margin above 1 at every cutting point (plan)",
    "no_collisions": "no collision or gouge of the final program (FCL), and a feasible "
                     "posture at every point of the plan",
    "no_program_errors": ("no rapid move (G0) into material and no cut deeper than the "
                          "flutes in the planned program"),
    "correction_verified_nowhere_worse": "the corrected program, re-predicted at points "
                                         "2 mm apart (block ends included), is nowhere "
                                         "worse than the planned one",
    "round_trip_within_1um": "final program read back within 1 um of the corrected path",
    "simulation_covered_the_program": "the simulated machine cut every cutter location in "
                                      "the material of the three runs (planned, corrected, "
                                      "the CAM program's worst pass)",
    "no_chatter_in_simulation": "no sustained chatter (a detector call outliving its "
                                "window) in the simulated run of the final program",
    "surface_error_reduced_to_25pct": f"simulated surface error (RMS) after correction at most "
                                      f"{JOB_SURFACE_RATIO:.0%} of before",
}


def _why_not(res: JobResult, rep: dict[str, Any]) -> dict[str, str]:
    """One line per failed check: what was found instead (``report.json``'s ``checks_why``
    and the page's check table)."""
    checks, s, sim = rep["checks"], rep["plan"], rep["simulation"]
    opt = res.scenario.options
    p = res.plan
    lo = [math.degrees(x) for x in (*opt.lead_range_rad, *opt.tilt_range_rad)]
    sp = opt.spindle
    speeds = (f" and speeds {sp.range_rpm[0]:.0f}-{sp.range_rpm[1]:.0f} min^-1" if sp is not None
              else "")
    why = {
        "margin_above_1_where_cutting": (
            f"lowest margin {s['margin_min']} at {p.spindle_rpm:.0f} min^-1 ({s['points_below_1']}"
            f" of {s['cutting_points']} cutting points below 1; CAM posture "
            f"{s['cam_margin_min']}): no posture within lead {lo[0]:g}..{lo[1]:g} deg, tilt "
            f"{lo[2]:g}..{lo[3]:g} deg{speeds} reaches 1 there"),
        "no_collisions": (f"{res.collisions} colliding cutter location(s) on the final path, "
                          f"{p.infeasible.size} point(s) without a feasible posture (the CAM "
                          f"posture kept there)"),
        "no_program_errors": findings_line(res.findings),
        "correction_verified_nowhere_worse": rep["correction"]["reason"],
        "round_trip_within_1um": (f"read back {rep['program']['round_trip_tip_mm']} mm from the "
                                  f"corrected path"),
        "simulation_covered_the_program": "; ".join(
            f"{name}: {v['coverage']}" for name, v in (("planned", sim["planned"]),
                                                       ("corrected", sim["corrected"]),
                                                       ("CAM worst pass", sim["cam_worst_pass"]))
            if not v["complete"]),
        "no_chatter_in_simulation": (
            f"{sim['corrected']['sustained_chatter_episodes']} sustained chatter episode(s) in "
            f"the corrected program's run ({sim['corrected']['chatter_windows']} of "
            f"{sim['corrected']['detector_windows']} windows), as the lowest planned margin "
            f"{s['margin_min']} predicts" if (s["margin_min"] or 0) < 1 else
            f"{sim['corrected']['sustained_chatter_episodes']} sustained chatter episode(s) in "
            f"the corrected program's run although every planned margin is above 1"),
        "surface_error_reduced_to_25pct": (
            f"simulated RMS {sim['planned']['surface_rms_um']} -> "
            f"{sim['corrected']['surface_rms_um']} um (ratio {sim['surface_rms_ratio']})"
            + (": the chatter marks, which the correction does not remove, dominate"
               if sim["corrected"]["sustained_chatter_episodes"] else "")),
    }
    return {k: why[k] for k, v in checks.items() if not v}


def _r(x: float, nd: int = 3) -> float | None:
    return None if x is None or not math.isfinite(float(x)) else round(float(x), nd)


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x)))) if np.size(x) else math.nan


def _verification(v) -> dict[str, Any]:
    return {"cutter_locations": int(v.points.size),
            "coverage": v.coverage, "complete": v.complete,
            "machining_s": _r(v.machining_s, 2),
            "spindle_rpm": _r(v.spindle_rpm, 1),
            "surface_rms_um": _r(_rms(v.surface_um)),
            "surface_max_abs_um": _r(float(np.max(np.abs(v.surface_um))) if v.points.size
                                     else math.nan),
            "chatter_marks_max_um": _r(float(np.max(v.marks_um)) if v.points.size
                                       else math.nan),
            "detector_windows": int(v.summary["windows"]),
            "chatter_windows": int(v.summary["chatter_windows"]),
            "sustained_chatter_episodes": int(v.summary["sustained_episodes"]),
            "transient_chatter_episodes": [
                {"first_s": _r(e["first_s"]), "last_s": _r(e["last_s"]), "windows": e["windows"]}
                for e in v.summary["episodes"] if not e["sustained"]],
            "first_chatter_s": v.summary.get("first_detection_s"),
            "chatter_share_after_first": _r(v.summary.get("chatter_share_after_detection", 0.0))}


def _errors(res: JobResult) -> tuple[tuple, tuple]:
    comp = res.compensation
    ref = comp.paths[0]
    before = error_points(ref, comp.predictions[0])
    after = error_points(comp.paths[comp.best], comp.predictions[comp.best], reference=ref)
    return before, after


def job_report(res: JobResult, errors: tuple | None = None) -> dict[str, Any]:
    """The JSON report of a job (summary, checks, per-point arrays); ``errors``: the
    predicted error points before and after correction, if already computed."""
    p = res.plan
    idx = p.touching_index
    comp = res.compensation
    (pb, eb), (pa, ea) = errors if errors is not None else _errors(res)
    scn = res.scenario
    rep = {
        "scenario": scn.name,
        "scenario_file": str(scn.path),
        "programs": {"final": res.final_path.name, "planned": res.planned_path.name},
        "checks": res.checks,
        "plan": {
            "spindle_rpm": p.spindle_rpm,
            "cam_spindle_rpm": _cam_rpm(p),
            "cutting_points": int(idx.size),
            "points": len(p.cl),
            "cam_margin_min": _r(float(p.cam_margin[idx].min())),
            "margin_min": _r(float(p.margin[idx].min())),
            "cam_points_below_1": int(np.count_nonzero(p.cam_margin[idx] < 1)),
            "points_below_1": int(np.count_nonzero(p.margin[idx] < 1)),
            "time_periodic_checks": [{k: (_r(v) if isinstance(v, float) else v)
                                      for k, v in c.items()} for c in p.sdm_checks],
        },
        "correction": {
            "passes": comp.iterations,
            "best_pass": comp.best,
            "largest_change_um": [_r(x * 1e3) for x in comp.largest_change_mm],
            "predicted_max_abs_um": [_r(x) for x in comp.max_error_um],
            "predicted_rms_um": [_r(x) for x in comp.rms_error_um],
            "stage1_blocks_computed": list(res.stage1_computed),
            "verified": comp.corrected,
            "verification": (comp.verified.comparison.as_dict()
                             if comp.verified.comparison is not None else None),
            "reason": comp.reason(),
        },
        "program": {
            "dialect": scn.options.dialect,
            "machine": res.plan.machine.name,
            "lines": len(res.final.text.splitlines()),
            "round_trip_tip_mm": _r(res.round_trip[0], 6),
            "round_trip_axis_deg": _r(math.degrees(res.round_trip[1]), 6),
            "collisions": res.collisions,
        },
        "simulation": {
            "planned": _verification(res.verify_planned),
            "corrected": _verification(res.verify_final),
            "cam_worst_pass": {**_verification(res.verify_cam),
                               "cutter_locations_run": list(res.cam_points)},
            "surface_rms_ratio": _r(res.surface_ratio, 4),
        },
        "seconds": res.seconds,
        "points": {
            "margin_cam": [_r(x) for x in p.cam_margin[idx]],
            "margin_planned": [_r(x) for x in p.margin[idx]],
            "cutter_location": idx.tolist(),
            "lead_deg": [_r(math.degrees(x), 2) for x in p.lead_rad[idx]],
            "tilt_deg": [_r(math.degrees(x), 2) for x in p.tilt_rad[idx]],
            "predicted_before": {"xyz_mm": np.round(pb, 4).tolist(),
                                 "E_um": [_r(x) for x in eb]},
            "predicted_after": {"xyz_mm": np.round(pa, 4).tolist(),
                                "E_um": [_r(x) for x in ea]},
            "simulated_before": {"xyz_mm": np.round(res.verify_planned.contact_mm, 4).tolist(),
                                 "E_um": [_r(x) for x in res.verify_planned.surface_um]},
            "simulated_after": {"xyz_mm": np.round(res.verify_final.contact_mm, 4).tolist(),
                                "E_um": [_r(x) for x in res.verify_final.surface_um]},
        },
    }
    rep["checks_why"] = _why_not(res, rep)
    return rep


def _cam_rpm(plan) -> float:
    """The CAM program's spindle speed [min^-1]: its posture's margins are at this speed."""
    return float(plan.stats.get("program_spindle_rpm", plan.spindle_rpm))


def _rotary(res: JobResult, d: np.ndarray) -> tuple[dict, str]:
    """The rotary axes along the path: the planned program as written (its joints at their
    tip travel), the CAM posture solved on the same machine from the planned program's first
    joints; and a note when the CAM posture has no continuous solution in the limits."""
    p = res.plan
    n = len(p.cl)
    out = {}
    note = ""
    try:
        cam = solve_path(p.machine, p.cam.tip, p.cam.axis, allow_jumps=True,
                         start=res.planned.joints[0] if len(res.planned.joints) else None)
        out["CAM"] = (d, cam.joints[:, 3:])
    except KinematicsError as exc:
        note = f" The CAM posture has no solution within the machine's limits: {exc}."
    out["planned"] = (np.interp(res.planned.source, np.arange(n), d),
                      res.planned.joints[:, 3:])
    return out, note


def _map_view(normal: np.ndarray, point: np.ndarray) -> tuple[tuple[int, int], str]:
    """The error map's axes (along, up) and their caption: a wall (median |n_z| below
    ``errpred.constants.PAGE_WALL_NORMAL_Z``, as errpred's pages decide) from the side, its
    longer horizontal extent along; a free-form part from above (X, Y)."""
    if len(normal) and float(np.median(np.abs(normal[:, 2]))) < PAGE_WALL_NORMAL_Z:
        span = np.ptp(point[:, :2], axis=0)
        along = int(np.argmax(span))
        return (along, 2), f"seen from the side: {'XY'[along]} along the wall, Z up"
    return (0, 1), "seen from above: X and Y"


def job_page(res: JobResult, rep: dict[str, Any], errors: tuple | None = None) -> str:
    """The self-contained HTML page of a job (``errors`` as in :func:`job_report`)."""
    p = res.plan
    s = rep["plan"]
    sim = rep["simulation"]
    checks = rep["checks"]
    good = all(checks.values())
    why = rep["checks_why"]
    failed = [_CHECK_TEXT[k] for k, v in checks.items() if not v]
    verdict = ("All checks hold: the program is ready to cut." if good else
               "Not every check holds: " + "; ".join(failed) + ".")
    (pb, eb), (pa, ea) = errors if errors is not None else _errors(res)
    d = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p.cl.tip, axis=0), axis=1))])
    cutting = np.zeros(len(p.cl), bool)
    cutting[p.touching_index] = True
    rotary, rotary_note = _rotary(res, d)
    view, view_text = _map_view(p.contacts.normal[p.touching_index],
                                p.contacts.point[p.touching_index])
    wp_text = {"rigid": "", "modes": " and the workpiece's modes",
               "thin_wall": " and the wall's"}.get(res.scenario.workpiece.kind, "")
    vp, vf, vc = res.verify_planned, res.verify_final, res.verify_cam
    max_hz = min(SPECTRUM_MAX_HZ,
                 float(vp.spectrum_hz[-1]) if vp.spectrum_hz.size else SPECTRUM_MAX_HZ)
    teeth = res.scenario.base.tool.flutes
    check_rows = (("check", "holds", "why not"),) + tuple(
        (_CHECK_TEXT[k], "yes" if v else "NO", "" if v else why.get(k, ""))
        for k, v in checks.items())
    sim_rows = (("simulated run", "cutter locations", "surface RMS [um]", "largest |E| [um]",
                 "chatter marks max [um]", "chatter windows",
                 "chatter episodes: sustained, transient"),) + tuple(
        (name, str(v["coverage"]), str(v["surface_rms_um"]),
         str(v["surface_max_abs_um"]), str(v["chatter_marks_max_um"]),
         f"{v['chatter_windows']} of {v['detector_windows']}",
         f"{v['sustained_chatter_episodes']}, {len(v['transient_chatter_episodes'])}")
        for name, v in (("CAM program, worst pass", sim["cam_worst_pass"]),
                        ("planned, uncorrected", sim["planned"]),
                        ("planned and corrected (final)", sim["corrected"])))
    corr = rep["correction"]
    sections = [
        Section("Result", paragraphs=(
            (f"Scenario {rep['scenario']} ({rep['scenario_file']}). The final program "
            f"{rep['programs']['final']} ({rep['program']['lines']} lines, "
            f"{rep['program']['dialect']} for {rep['program']['machine']}) runs at "
            f"{p.spindle_rpm:.0f} min^-1."),
            (f"Planning raised the lowest stability margin from {s['cam_margin_min']} (CAM "
            f"posture at the CAM program's {s['cam_spindle_rpm']:.0f} min^-1, "
            f"{s['cam_points_below_1']} of {s['cutting_points']} cutting points below 1) to "
            f"{s['margin_min']} (planned posture at {p.spindle_rpm:.0f} min^-1, "
            f"{s['points_below_1']} below 1)."),
            (f"The predicted error (RMS over the generation points) went from "
            f"{corr['predicted_rms_um'][0]} um to {corr['predicted_rms_um'][corr['best_pass']]}"
            f" um in {corr['passes']} correction passes; in the simulated machine from "
            f"{sim['planned']['surface_rms_um']} um to {sim['corrected']['surface_rms_um']} um "
            f"(ratio {sim['surface_rms_ratio']})."),
            (f"Verification of the correction, re-predicted at both ends of every block and "
             f"at most 2 mm apart, against the planned program: {corr['reason']}."),
            f"Run time: {rep['seconds']['total']:.0f} s."),
            tables=(check_rows,)),
        Section("Stability margin along the path", figures=(Figure(
            margin_png(d, p.cam_margin, p.margin, cutting, res.scenario.options.margin_target,
                       s["cam_spindle_rpm"], p.spindle_rpm),
            f"Zero-order stability margin at each cutting point: the CAM posture (red) at the "
            f"CAM program's spindle speed, {s['cam_spindle_rpm']:.0f} min^-1, and the planned "
            f"lead/tilt (blue) at the planned speed, {p.spindle_rpm:.0f} min^-1. Below 1 the "
            f"cut chatters."),)),
        Section("Posture along the path", paragraphs=(
            f"Lead and tilt of the tool against the surface where it cuts, and the machine's "
            f"rotary axes {' and '.join(p.machine.rotary_names)} ({p.machine.name}) over the "
            f"whole path: the planned program as written (its joints), the CAM posture solved "
            f"on the same machine.{rotary_note}",), figures=(Figure(
            posture_png(d, cutting, {"CAM": (p.cam_lead_rad, p.cam_tilt_rad),
                                     "planned": (p.lead_rad, p.tilt_rad)},
                        rotary, p.machine.rotary_names),
            "Lead, tilt and the two rotary axes along the path: CAM posture (red), planned "
            "(blue)."),)),
        Section("Error map before and after correction", figures=(Figure(
            error_map_png([("predicted, planned path", pb, eb),
                           ("predicted, corrected path", pa, ea),
                           ("simulated machine, planned program", vp.contact_mm, vp.surface_um),
                           ("simulated machine, corrected program", vf.contact_mm,
                            vf.surface_um)], *view),
            f"Surface error against the design along its normal over the finished face "
            f"({view_text}). Top: the error prediction (rasterized engagement, micro-edge "
            f"forces, the tool's compliance{wp_text}); bottom: the time-domain simulation "
            f"of the written programs."),)),
        Section("Stability lobes at representative points", figures=(Figure(
            lobes_png(res.lobes, s["cam_spindle_rpm"]),
            "Limiting depth of cut over spindle speed (zero-order method) for the CAM posture "
            "and the planned one; the star is the operating point (depth of the finishing "
            f"cut, planned speed {p.spindle_rpm:.0f} min^-1)"
            + (f"; the red cross the CAM program's speed, {s['cam_spindle_rpm']:.0f} min^-1"
               if abs(s["cam_spindle_rpm"] - p.spindle_rpm) > 0.5 else "") + "."),)),
        Section("Simulated acceleration spectrum", paragraphs=(_episodes_text(sim["corrected"]),),
                tables=(sim_rows,), figures=(Figure(
            spectra_png([((f"CAM program, worst pass (cutter locations {res.cam_points[0]}-"
                          f"{res.cam_points[1]}, {vc.spindle_rpm:.0f} rev/min)"),
                          vc.spectrum_hz, vc.spectrum_m_s2, vc.spindle_rpm),
                         ("planned and corrected program, whole run", vf.spectrum_hz,
                          vf.spectrum_m_s2, vf.spindle_rpm)], teeth, max_hz),
            "Spindle accelerometers while cutting (averaged spectrum). Chatter shows as peaks "
            "between the tooth-passing harmonics."),)),
    ]
    return render_page(f"firstcut job: {rep['scenario']}", verdict, sections, good=good)


def _episodes_text(v: dict[str, Any]) -> str:
    """What the detector's calls on the final program were (``sim.report`` module notes)."""
    head = ("The controller's chatter detector judges the accelerometers window by window. "
            "Chatter is self-excited and goes on once set off: an episode of calls that "
            "outlives its window is sustained chatter. A step of the cut (entering or "
            "leaving the material, a change of posture) rings the structure at its natural "
            "frequency for a moment; calls that die within their window are transients.")
    eps = v["transient_chatter_episodes"]
    if not eps and not v["sustained_chatter_episodes"]:
        return head + " On the final program the detector called no chatter."
    times = ", ".join(f"{e['first_s']:.2f} s" for e in eps[:12]) + (" ..." if len(eps) > 12
                                                                      else "")
    return (head + f" On the final program: {v['sustained_chatter_episodes']} sustained "
            f"episode(s), {len(eps)} transient(s)" + (f" (at {times})." if eps else "."))


def _json_default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serializable: {type(o).__name__}")


def write_job_report(res: JobResult, folder: str | Path) -> dict[str, Any]:
    """Write ``report.json`` and ``report.html`` into ``folder`` (atomically); returns the
    report."""
    folder = Path(folder)
    errors = _errors(res)
    rep = job_report(res, errors)
    with atomic_write(folder / "report.json") as fh:
        json.dump(rep, fh, indent=1, default=_json_default)
    page = job_page(res, rep, errors)
    with atomic_write(folder / "report.html") as fh:
        fh.write(page)
    return rep
