"""The steps of the command line, as a Python API: scenario in, results out.

>>> from errpred.pipeline import load, predict, write_outputs
>>> s = load("errpred/scenarios/mold-ball/scenario.toml")     # doctest: +SKIP
>>> pred = predict(s, workers=2)                                # doctest: +SKIP
>>> rep = write_outputs(s, pred, "report.json", "plots/")       # doctest: +SKIP
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

import numpy as np

from nc.program import Program

from . import constants as K
from .correct import Compensation, compensate
from .geometry import Resolution
from .physics import ShapeErrorModel
from .predict import Prediction, Predictor
from .repredict import Repredictor
from .report import report, write_report
from .scenario import Scenario, load_scenario
from .tool_state import write_tool_state

__all__ = ["load", "build_predictor", "blocks_in_scope", "predict", "scenario_report",
           "write_outputs", "compensate_scenario", "design_deviation_um", "write_end_state"]


def load(path: str | os.PathLike) -> Scenario:
    """Read and check a scenario file (:func:`errpred.scenario.load_scenario`)."""
    return load_scenario(path)


def build_predictor(scenario: Scenario, program: Program | None = None,
                    resolution: Resolution | None = None, stock=None,
                    workpiece=None, machine=None, sensitivity: bool = True) -> Predictor:
    """A :class:`Predictor` for the scenario (or another program, e.g. corrected).

    ``workpiece``: the workpiece's modes at a cutting point (see :class:`Predictor`);
    ``machine``: the machine the program is written for (default: the scenario's, with
    the tool's overhang as its tool length); ``sensitivity``: also the error's
    sensitivity to a correction (corrections need it, predictions alone do not). The
    wear starts from the scenario's tool state (:attr:`Scenario.initial_wear_mm`).
    """
    prog = program if program is not None else scenario.read_program()
    res = resolution or scenario.resolution
    se = scenario.shape_error
    shape = ShapeErrorModel(deviation=se.radius_deviation_mm, wear_rate=se.wear_rate_mm_per_mm)
    return Predictor(scenario.tool, stock if stock is not None else scenario.stock.load(), prog,
                     scenario.coefficients, scenario.compliance, shape_error=shape,
                     resolution=res,
                     machine=machine if machine is not None
                     else scenario.resolve_machine(),
                     workpiece=workpiece,
                     initial_wear_mm=scenario.initial_wear_mm, sensitivity=sensitivity)


def blocks_in_scope(scenario: Scenario, program: Program) -> list[int]:
    """Block indices to predict: all, or those on the scenario's line range."""
    if scenario.lines is None:
        return list(range(len(program)))
    lo, hi = scenario.lines
    return [int(b) for b in np.flatnonzero((program.line >= lo) & (program.line <= hi))]


def predict(scenario: Scenario, *, program: Program | None = None, workers: int = 1,
            progress: Callable[[int], None] | None = None, resolution: Resolution | None = None,
            series_lines=(), stock=None, workpiece=None, client=None) -> Prediction:
    """Predict the error along the scenario's program (or ``program``).

    ``workpiece``: the workpiece's modes at a cutting point (see :class:`Predictor`);
    ``client``: a Dask client for the geometry stage (``workers`` is then unused).
    """
    pred = build_predictor(scenario, program, resolution, stock, workpiece, sensitivity=False)
    blocks = blocks_in_scope(scenario, pred.program)
    return pred.run(blocks, workers=workers, progress=progress, series_lines=series_lines,
                    client=client)


def design_deviation_um(scenario: Scenario, prediction: Prediction) -> dict[int, float]:
    """Predicted surface against the design: point index -> deviation [um].

    The machined surface at a generation point lies ``E`` outward of the
    program's nominal surface; against the design it is that plus the
    nominal surface's own distance outward of the design mesh (positive:
    material left). Empty when the scenario has no design surface.
    """
    if scenario.stock.design_path is None:
        return {}
    mesh = scenario.stock.load_design()
    idx = [i for i, p in enumerate(prediction.points)
           if p.result is not None and p.status == "predicted"]
    if not idx:
        return {}
    import trimesh

    pts = np.array([prediction.points[i].geometry.gen.point_world for i in idx])
    inside = trimesh.proximity.ProximityQuery(mesh).signed_distance(pts)  # + inside
    return {i: float((-sd * 1e3) + prediction.points[i].result.E_um)
            for i, sd in zip(idx, inside, strict=True)}


def scenario_report(scenario: Scenario, prediction: Prediction,
                    design: dict[int, float] | None = None) -> dict[str, Any]:
    """The JSON report of a prediction, with the scenario's metadata."""
    t = scenario.tool
    meta = {
        "scenario": scenario.name,
        "scenario_file": str(scenario.path),
        "program": str(scenario.program_path),
        "tool": {"type": t.kind, "diameter_mm": t.diameter_mm,
                 "corner_radius_mm": t.corner_radius_mm, "flutes": t.flutes,
                 "helix_deg": t.helix_deg, "rotation": t.rotation},
        "resolution": {"pixel_mm": scenario.resolution.pixel_mm,
                       "micro_edges": scenario.resolution.micro_edges,
                       "angle_step_deg": float(np.degrees(scenario.resolution.angle_step_rad)),
                       "chord_tol_mm": scenario.resolution.chord_tol_mm},
        "sign": "E > 0: material left (undercut); E < 0: overcut",
        "sources": scenario.sources,
        "tool_start": scenario.tool_start,
    }
    rep = report(prediction, meta, scenario.tool_change_tolerance_um)
    from .findings import error_findings

    rep["summary"]["errors"] = error_findings(prediction)
    if design:
        for i, v in design.items():
            rep["points"][i]["E_design_um"] = round(v, 4)
        vals = np.array(list(design.values()))
        rep["summary"]["against_design"] = {
            "max_abs_um": round(float(np.abs(vals).max()), 4),
            "mean_um": round(float(vals.mean()), 4)}
    return rep


def write_end_state(scenario: Scenario, prediction: Prediction, path: str | os.PathLike,
                    command: str = "predict") -> None:
    """Write the tool's wear at the end of ``prediction`` as a tool-state file.

    The next scenario starts from it with ``[tool] state = "FILE"``
    (:mod:`errpred.tool_state`). ``command`` is recorded as provenance.
    """
    write_tool_state(path, scenario.tool, prediction.edges_kappa_rad, prediction.edges_z_mm,
                     prediction.wear_mm,
                     written_by={"command": command, "scenario": str(scenario.path),
                                 "program": str(scenario.program_path),
                                 "lines": list(scenario.lines) if scenario.lines else None,
                                 "tool_start": scenario.tool_start})


def write_outputs(scenario: Scenario, prediction: Prediction, report_path=None,
                  plots_dir=None, design: dict[int, float] | None = None,
                  tool_state_path=None) -> dict[str, Any]:
    """Write the report (JSON), the plots (PNG) and the tool's end state; returns the report.

    ``tool_state_path``: where to write the wear at the end (:func:`write_end_state`).
    """
    rep = scenario_report(scenario, prediction, design)
    if report_path is not None:
        write_report(report_path, rep)
    if tool_state_path is not None:
        write_end_state(scenario, prediction, tool_state_path, "predict")
    if plots_dir is not None:
        from .plots import revolution_series, write_all

        rep["plots"] = write_all(prediction, plots_dir, revolution=revolution_series(prediction),
                                 name=scenario.name)
    return rep


def compensate_scenario(scenario: Scenario, *, iterate: bool | None = None, workers: int = 1,
                        progress: Callable[[str], None] | None = None,
                        block_progress: Callable[[int, int], None] | None = None,
                        client=None, tool_state_out: str | os.PathLike | None = None
                        ) -> Compensation:
    """Correct the scenario's program (one pass, or iterated per the scenario), verified.

    Every candidate and the original are predicted densely
    (:meth:`errpred.geometry.Resolution.dense`) over the scenario's line range (the
    same original lines in a corrected program whose blocks were split).
    ``tool_state_out``: write the tool's wear at the end of the program that will be
    written (the corrected one; the original when there was nothing to correct) there
    (:func:`write_end_state`), from its own dense prediction; nothing when no
    correction was verified (nothing will be cut).

    Raises
    ------
    nc.command.Refused
        The original program has an error-level finding (a rapid move into material, a
        cut deeper than the flutes: :mod:`errpred.findings`).
    nc.rewrite.RewriteError
        The program cannot be rewritten (``#`` parameters, O-words, canned cycles...:
        :func:`nc.rewrite.check_rewritable`), before anything is predicted.
    """
    from nc.command import Refused
    from nc.path import cutter_locations
    from nc.rewrite import check_rewritable

    from .findings import error_findings, findings_line

    program = scenario.read_program()
    check_rewritable(program)       # before any prediction, not after the first one
    stock = scenario.stock.load()
    opts = scenario.correction
    it = opts.iterate if iterate is None else iterate
    res = scenario.resolution.dense()
    machine = scenario.resolve_machine()

    # each candidate takes stage 1 from the one before where it cannot have changed
    # (a fallback differs only near the worse points)
    repro = Repredictor()

    def run(prog: Program, origin: np.ndarray) -> Prediction:
        pred = build_predictor(scenario, prog, res, stock)
        if scenario.lines is None:
            blocks = list(range(len(prog)))
        else:
            lo, hi = scenario.lines
            orig = origin[prog.line - 1]
            blocks = [int(b) for b in np.flatnonzero((orig >= lo) & (orig <= hi))]
        cb = None if block_progress is None else (lambda d: block_progress(d, len(blocks)))
        out = repro.run(pred, blocks, workers=workers, progress=cb, client=client)
        if prog is program:
            found = error_findings(out)
            if found:
                raise Refused(findings_line(found, str(scenario.program_path)))
        return out

    def path(prog: Program):
        return cutter_locations(prog, machine, chord_tol_mm=res.chord_tol_mm)

    try:
        comp = compensate(program, run, path=path, iterate=it,
                          tolerance_mm=opts.tolerance_um * 1e-3,
                          max_iterations=opts.max_iterations,
                          relaxation=opts.relaxation,
                          tolerance_um=opts.verify_tolerance_um,
                          reach_mm=K.FALLBACK_REACH_RADII * scenario.tool.radius_mm,
                          verify_walls=opts.verify_walls, progress=progress)
    finally:
        repro.close()
    if tool_state_out is not None and (comp.corrected or not comp.verified.passes):
        cut = comp.predictions[comp.verified.best_pass + 1]
        write_end_state(scenario, cut, tool_state_out, "compensate")
    return comp
