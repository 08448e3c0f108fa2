"""The pages of ``errpred predict`` and ``errpred compensate`` (self-contained HTML).

Each page says what a person needs to judge the run without the JSON:

* the error on the part: a wall (the generation points' normals near horizontal,
  :data:`errpred.constants.PAGE_WALL_NORMAL_Z`) unrolled, arc length along the contour
  of each waterline level x Z; a free-form surface from above, X x Y;
* the smallest and largest error per waterline level (wall) or per pass (runs
  between rapid moves, free-form), as a plot and a table;
* force and deflection over the revolution of one point (the largest |E|, or the
  line asked for);
* the tool-change finding (:func:`errpred.report.tool_change`).

``compensate``'s page shows the error before and after correction as verified: the
dense re-prediction of the original and of the accepted candidate against the
original's surface (:class:`errpred.verified.VerifiedCorrection`), not the points
the correction was fitted to.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from nc.atomic import atomic_write
from nc.program import RAPID

from .constants import PAGE_LEVEL_GAP_MM, PAGE_TABLE_ROWS, PAGE_WALL_NORMAL_Z
from .page import Figure, Section, render_page
from .page_plots import error_on_part_png, levels_png
from .plots import revolution_png, revolution_series
from .predict import Prediction
from .report import tool_change
from .verification import ErrorField

if TYPE_CHECKING:
    from nc.program import Program

    from .correct import Compensation
    from .scenario import Scenario

__all__ = ["ErrorSet", "compensate_page", "from_field", "from_prediction", "is_wall",
           "predict_page", "write_compensate_page", "write_page_text", "write_predict_page"]


@dataclass(frozen=True, eq=False)
class ErrorSet:
    """Predicted errors at points of one program, in program order.

    Attributes
    ----------
    point_mm, tip_mm, normal : ndarray, shape (n, 3)
        Generation point [mm], tool tip [mm] and surface normal there.
    E_um : ndarray, shape (n,) [um]
    line : ndarray, shape (n,), int
        Source line of the point's block.
    pass_id : ndarray, shape (n,), int
        Pass of the point: rapid moves before its block.
    """

    point_mm: np.ndarray
    tip_mm: np.ndarray
    normal: np.ndarray
    E_um: np.ndarray
    line: np.ndarray
    pass_id: np.ndarray


def from_prediction(prediction: Prediction, program: Program) -> ErrorSet:
    """The predicted points of ``prediction`` of ``program`` (:class:`nc.program.Program`)."""
    pts = prediction.predicted()
    n = len(pts)
    passes = np.cumsum(np.asarray(program.motion) == RAPID)
    block = np.array([p.block for p in pts], np.int64)
    return ErrorSet(
        point_mm=np.array([p.geometry.gen.point_world for p in pts], float).reshape(n, 3),
        tip_mm=np.array([p.geometry.tip for p in pts], float).reshape(n, 3),
        normal=np.array([p.geometry.gen.normal_world for p in pts], float).reshape(n, 3),
        E_um=np.array([p.result.E_um for p in pts], float),
        line=np.array([p.line for p in pts], np.int64),
        pass_id=passes[block] if n else np.zeros(0, np.int64))


def from_field(field: ErrorField) -> ErrorSet:
    """A verified dense field (errors against the original's surface; passes and lines of
    the original)."""
    return ErrorSet(point_mm=field.point_mm, tip_mm=field.tip_mm, normal=field.normal,
                    E_um=field.E_um, line=field.ref_line, pass_id=field.chain)


def is_wall(es: ErrorSet) -> bool:
    """Whether the points lie on a wall: the median |n_z| below ``PAGE_WALL_NORMAL_Z``."""
    return bool(len(es.E_um)) and float(np.median(np.abs(es.normal[:, 2]))) < PAGE_WALL_NORMAL_Z


def _level_centres(z: np.ndarray) -> np.ndarray:
    """Waterline levels: tip Z values in clusters split by gaps over PAGE_LEVEL_GAP_MM,
    their means, descending (a waterline program goes down)."""
    if not z.size:
        return np.zeros(0)
    s = np.sort(z)
    cut = np.flatnonzero(np.diff(s) > PAGE_LEVEL_GAP_MM) + 1
    return np.array([g.mean() for g in np.split(s, cut)])[::-1]


def _groups(es: ErrorSet, wall: bool, keys: np.ndarray) -> np.ndarray:
    """Index into ``keys`` of each point: the nearest level Z (wall) or its pass."""
    if wall:
        return np.argmin(np.abs(es.tip_mm[:, 2, None] - keys[None, :]), axis=1) \
            if len(es.E_um) else np.zeros(0, np.int64)
    return np.searchsorted(keys, es.pass_id)


def _unrolled(es: ErrorSet, ids: np.ndarray) -> np.ndarray:
    """Arc length along the contour of each level [mm]: from the level's first point, in
    program order."""
    s = np.zeros(len(es.E_um))
    for g in np.unique(ids):
        k = np.flatnonzero(ids == g)
        p = es.point_mm[k]
        s[k] = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    return s


def _sentence(text: str) -> str:
    return text[:1].upper() + text[1:] + ("" if text.endswith(".") else ".")


def _fmt(v: float, sign: bool = True) -> str:
    return "-" if v is None or not math.isfinite(v) else (f"{v:+.2f}" if sign else f"{v:.2f}")


@dataclass(frozen=True, eq=False)
class _Layout:
    wall: bool
    keys: np.ndarray


def _layout(sets: list[ErrorSet]) -> _Layout:
    """Wall or free-form from the first set; levels from its tips, passes from all sets."""
    wall = is_wall(sets[0])
    if wall:
        keys = _level_centres(sets[0].tip_mm[:, 2])
    else:
        keys = np.unique(np.concatenate([s.pass_id for s in sets]))
    return _Layout(wall, keys)


def _part_section(sets: list[tuple[str, ErrorSet]], lay: _Layout, caption: str) -> Section:
    panels = []
    for title, es in sets:
        if lay.wall:
            s = _unrolled(es, _groups(es, True, lay.keys))
            panels.append((title, s, es.point_mm[:, 2], es.E_um))
        else:
            panels.append((title, es.point_mm[:, 0], es.point_mm[:, 1], es.E_um))
    view = ("Unrolled wall: arc length along the contour of each waterline level (from the "
            "level's first predicted point, in program order) against Z of the generation "
            "point." if lay.wall else
            "Seen from above: X and Y of the generation points (a free-form surface).")
    return Section("Error on the part", paragraphs=(view,), figures=(Figure(
        error_on_part_png(panels, lay.wall), caption),))


def _stats(es: ErrorSet, ids: np.ndarray, g: int) -> dict[str, Any] | None:
    k = np.flatnonzero(ids == g)
    if not k.size:
        return None
    e = es.E_um[k]
    return {"points": int(k.size), "min": float(e.min()), "max": float(e.max()),
            "rms": math.sqrt(float(np.mean(e ** 2))), "largest": float(np.max(np.abs(e))),
            "lines": (int(es.line[k].min()), int(es.line[k].max()))}


def _levels_section(sets: list[tuple[str, ErrorSet]], lay: _Layout) -> Section:
    """Smallest and largest error per level (pass) of each set: a plot and a table of the
    worst ``PAGE_TABLE_ROWS`` (largest |E| in any set), in program order."""
    per = []
    for _, es in sets:
        ids = _groups(es, lay.wall, lay.keys)
        per.append([_stats(es, ids, g) for g in range(len(lay.keys))])
    where = lay.keys if lay.wall else np.arange(1, len(lay.keys) + 1)
    series = []
    for (label, _), st in zip(sets, per, strict=True):
        ok = np.array([s is not None for s in st], bool)
        series.append((label, where[ok], np.array([s["min"] for s in st if s]),
                       np.array([s["max"] for s in st if s])))
    what = "level" if lay.wall else "pass"
    head = ("level: tool tip Z [mm]" if lay.wall else "pass", "lines")
    for label, _ in sets:
        pre = f"{label}: " if len(sets) > 1 else ""
        head += (f"{pre}points", f"{pre}smallest .. largest E [um]", f"{pre}RMS [um]")
    worst = [max((s["largest"] for s in col if s), default=0.0)
             for col in zip(*per, strict=True)]
    keep = sorted(np.argsort(worst)[::-1][:PAGE_TABLE_ROWS]) if len(worst) > PAGE_TABLE_ROWS \
        else range(len(worst))
    rows = [head]
    for g in keep:
        ss = [st[g] for st in per]
        lines = [s["lines"] for s in ss if s]
        lo, hi = min(a for a, _ in lines), max(b for _, b in lines)
        row = (f"{lay.keys[g]:.3f}" if lay.wall else str(g + 1),
               f"{lo}-{hi}" if lo != hi else str(lo))
        for s in ss:
            row += (("0", "-", "-") if s is None else
                    (str(s["points"]), f"{_fmt(s['min'])} .. {_fmt(s['max'])}",
                     _fmt(s["rms"], False)))
        rows.append(row)
    plural = {"level": "levels", "pass": "passes"}[what]
    note = (f"{len(lay.keys)} {plural}; the table lists the {len(keep)} with the largest |E|, "
            f"in program order." if len(keep) < len(lay.keys) else
            f"{len(lay.keys)} {plural if len(lay.keys) != 1 else what}.")
    heading = "Error per waterline level" if lay.wall else "Error per pass"
    return Section(heading, paragraphs=(note,), tables=(tuple(rows),), figures=(Figure(
        levels_png(series, lay.wall),
        f"Smallest and largest predicted error of each {what}."),))


def _revolution_section(prediction: Prediction, which: str) -> Section:
    rev = revolution_series(prediction)
    if rev is None:
        return Section("Force and deflection over one revolution",
                       paragraphs=("No point was predicted: no revolution to show.",))
    line, theta, force, defl, tm = rev
    return Section("Force and deflection over one revolution", figures=(Figure(
        revolution_png(theta, force, defl, tm, f"line {line}"),
        f"Force on the tool and its deflection over one revolution at line {line} ({which}); "
        "dashed: the rotation at which the surface is generated."),))


def _tool_change_section(tc: dict | None) -> Section:
    if tc is None:
        return Section("Tool change", paragraphs=(
            "The scenario sets no [tool_change] tolerance_um: no tool-change finding.",))
    rows = (("finding", "value"),
            ("tolerance on the wear part of the error [um]", f"{tc['tolerance_um']:g}"),
            ("first line over the tolerance", str(tc["line"]) if tc["line"] else "none"),
            ("largest wear part of the error [um]", _fmt(tc["max_wear_error_um"])),
            ("largest wear part with the tool as it is now [um]",
             _fmt(tc["max_wear_error_now_um"])),
            ("cutting distance left [m]",
             _fmt(tc["remaining_cutting_distance_mm"] / 1e3, False)
             if tc["remaining_cutting_distance_mm"] is not None else "-"),
            ("runs of this program left", _fmt(tc["remaining_program_runs"], False)
             if tc["remaining_program_runs"] is not None else "-"))
    return Section("Tool change", paragraphs=(_sentence(tc["advice"]),
                                              "Criterion: " + tc["criterion"] + "."),
                   tables=(rows,))


def predict_page(scenario: Scenario, prediction: Prediction, rep: dict[str, Any],
                 program: Program) -> str:
    """The page of ``errpred predict``.

    Parameters
    ----------
    scenario : Scenario
    prediction : Prediction
        Errors [um] at the prediction points.
    rep : dict
        Its report (:func:`errpred.pipeline.scenario_report`; errors in um).
    program : Program
        The program predicted (its rapid moves separate the passes).
    """
    from .findings import findings_line

    s = rep["summary"]
    es = from_prediction(prediction, program)
    errors = s.get("errors") or []
    if errors:
        verdict, good = findings_line(errors, str(scenario.program_path)) + ".", False
    elif "max_abs_error_um" in s:
        at = s["max_error_at"]
        verdict = (f"Largest predicted |error| {s['max_abs_error_um']:.2f} um at line "
                   f"{at['line']}; range {s['error_range_um'][0]:+.2f} .. "
                   f"{s['error_range_um'][1]:+.2f} um (+ material left).")
        if "walls" in s:
            w = s["walls"]
            verdict += (f" The walls the flank finishes beside the floors: largest |error| "
                        f"{w['max_abs_error_um']:.2f} um at line {w['line']} ({w['points']} "
                        "points; predicted, not corrected).")
        good = True
    else:
        verdict, good = "No point was predicted (nothing of the program cuts).", True
    scope = (f"lines {scenario.lines[0]}-{scenario.lines[1]}" if scenario.lines
             else "the whole program")
    rows = [("quantity", "value"),
            ("points by status", ", ".join(f"{k} {v}" for k, v in
                                           sorted(s["status_counts"].items())))]
    if "max_abs_error_um" in s:
        rows += [("mean error [um]", _fmt(s["mean_error_um"])),
                 ("mean |error| [um]", _fmt(s["mean_abs_error_um"], False))]
    if "against_design" in s:
        rows.append(("largest |deviation| from the design surface [um]",
                     _fmt(s["against_design"]["max_abs_um"], False)))
    rows.append(("actual cutting distance, most-worn micro edge [m]",
                 _fmt(s["wear"]["max_cutting_distance_mm"] / 1e3, False)))
    sections = [Section("Result", paragraphs=(
        f"Scenario {scenario.name} ({scenario.path}), program {scenario.program_path}, "
        f"{scope}: {s['points']} prediction points on {s['blocks']} blocks. Errors along the "
        "surface normal, positive where material is left.",), tables=(tuple(rows),))]
    if len(es.E_um):
        lay = _layout([es])
        sections += [
            _part_section([("predicted", es)], lay,
                          "Predicted error at each generation point (red: material left, "
                          "blue: overcut)."),
            _levels_section([("predicted", es)], lay)]
    sections += [_revolution_section(prediction, "the point with the largest |E|"
                                     if not any(k != -1 for k in prediction.series)
                                     else "the line asked for"),
                 _tool_change_section(s.get("tool_change"))]
    return render_page(f"errpred predict: {scenario.name}", verdict, sections, good=good)


def write_predict_page(path: str | os.PathLike, scenario: Scenario, prediction: Prediction,
                       rep: dict[str, Any], program: Program) -> None:
    """:func:`predict_page` written atomically to ``path``."""
    write_page_text(path, predict_page(scenario, prediction, rep, program))


def compensate_page(scenario: Scenario, comp: Compensation) -> str:
    """The page of ``errpred compensate``.

    Parameters
    ----------
    scenario : Scenario
    comp : Compensation
        Its result: the verified dense fields before and after [um], every pass.
    """
    v = comp.verified
    b, a = v.before_stats, v.after_stats
    good = comp.corrected or not v.passes
    verdict = (("Corrected, verified: " if comp.corrected else
                "Nothing written: " if v.passes else "") + comp.reason() + ".")
    stat_rows = (("program", "points", "largest |E| [um]", "most negative E [um]",
                  "largest E [um]", "RMS [um]"),) + tuple(
        (name, str(st.points), _fmt(st.max_abs_um, False), _fmt(st.min_um), _fmt(st.max_um),
         _fmt(st.rms_um, False))
        for name, st in (("original", b), ("corrected" if comp.corrected else
                                           "best candidate (not accepted)", a)))
    pass_rows = (("pass", "attempt", "relaxation", "largest move [um]", "RMS after [um]",
                  "largest |E| after [um]", "nowhere worse", "accepted"),) + tuple(
        (str(p.index), str(p.attempt), f"{p.relaxation:.2f}",
         f"{p.largest_move_mm * 1e3:.2f}", _fmt(p.comparison.after.rms_um, False),
         _fmt(p.comparison.after.max_abs_um, False), "yes" if p.comparison.ok else "NO",
         "yes" if p.accepted else "no")
        for p in v.passes)
    scope = (f"lines {scenario.lines[0]}-{scenario.lines[1]}" if scenario.lines
             else "the whole program")
    sections = [Section("Result", paragraphs=(
        f"Scenario {scenario.name} ({scenario.path}), program {scenario.program_path}, "
        f"{scope}. Every candidate and the original were predicted densely (points at most "
        f"{scenario.resolution.dense().point_spacing_mm:g} mm apart, block ends included) "
        "and compared point by point against the original's surface; the figures below are "
        "that verification, not the points the correction was fitted to.",),
        tables=(stat_rows, pass_rows) if v.passes else (stat_rows,))]
    before = from_field(v.before)
    sets = [("before correction", before)]
    if v.passes:
        sets.append(("after correction" if comp.corrected else "best candidate",
                     from_field(v.best_field)))
    if len(before.E_um):
        lay = _layout([s for _, s in sets])
        sections += [
            _part_section(sets, lay, "Verified error at the dense points before and after "
                                     "correction, one colour scale (red: material left, "
                                     "blue: overcut)."),
            _levels_section(sets, lay)]
    sections.append(_revolution_section(v.predictions[0], "the original program's point "
                                                          "with the largest |E|"))
    cut = v.predictions[v.best_pass + 1] if v.predictions else None
    tc = tool_change(cut, scenario.tool_change_tolerance_um) if cut is not None else None
    sections.append(_tool_change_section(tc))
    return render_page(f"errpred compensate: {scenario.name}", verdict, sections, good=good)


def write_compensate_page(path: str | os.PathLike, scenario: Scenario,
                          comp: Compensation) -> None:
    """:func:`compensate_page` written atomically to ``path``."""
    write_page_text(path, compensate_page(scenario, comp))


def write_page_text(path: str | os.PathLike, text: str) -> None:
    """A rendered page written atomically."""
    with atomic_write(path) as fh:
        fh.write(text)

