"""The whole prediction: convergence, compensation, wear, tool change, report."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from nc import parse_program
from nc.path import cutter_locations
from errpred.coefficients import CuttingCoefficients
from errpred.correct import compensate
from errpred.verification import error_field
from errpred.geometry import Resolution
from errpred.pipeline import load, predict
from errpred.physics import ShapeErrorModel
from errpred.plots import _lag_deg
from errpred.predict import Predictor
from errpred.raster.meshes import Stock
from errpred.report import summary, tool_change
from errpred.scenario import bundled_scenario
from errpred.tool import Tool

from .cases import STEEL, plane_raster, plane_stock, stiff_tool

#: Representative slices of the bundled scenarios (see their descriptions).
SLICES = [("mold-ball", 19118, 19140), ("mold-ball", 6165, 6185), ("wall-radius", 38, 53)]


@pytest.mark.parametrize("name,lo,hi", SLICES, ids=[f"{n}-{a}" for n, a, _ in SLICES])
def test_default_resolution_converges(name, lo, hi):
    """method.md section 9: the default is within 0.5 um of a 4x finer setting."""
    s = dataclasses.replace(load(bundled_scenario(name)), lines=(lo, hi))
    base = s.resolution
    stock = s.stock.load()
    a = {p.line: p for p in predict(s, stock=stock).points}
    b = {p.line: p for p in predict(s, resolution=base.finer(4), stock=stock).points}
    both = [ln for ln, p in a.items() if p.status == "predicted" and b[ln].status == "predicted"]
    assert len(both) >= 10
    diff = max(abs(a[ln].result.E_um - b[ln].result.E_um) for ln in both)
    assert diff <= 0.5, diff


def _plane_case():
    slope = 25.0
    prog = parse_program(plane_raster(slope, 5.0, passes=6, length=12.0))
    tool = Tool("ball", 10.0, flute_length_mm=15)
    stock = plane_stock(slope, 0.2)
    soft = stiff_tool(k_N_m=1.2e6)  # errors of ~10 um, as an overhung tool leaves
    res = Resolution.default(tool).dense()

    def run(p, origin=None):
        return Predictor(tool, stock, p, STEEL, soft, resolution=res).run()

    return prog, run


def _away_from_pass_ends(fld, end_mm: float = 1.0) -> np.ndarray:
    """The points of a dense error field more than ``end_mm`` along the path from either
    end of their pass. At a raster pass's ends the error steps (16 -> 2 um within
    0.6 mm where the tool leaves the stock); a vertex move cannot follow the step, and
    the verification's 2 um overcut limit keeps the correction there partial."""
    away = np.zeros(len(fld), bool)
    for c in np.unique(fld.chain):
        m = fld.chain == c
        s = fld.s_mm[m]
        away[m] = np.minimum(s - s.min(), s.max() - s) > end_mm
    return away


def test_compensation_one_pass_and_iterated():
    """Verified on the dense prediction (every block end) of the corrected program."""
    prog, run = _plane_case()
    one = compensate(prog, run, iterate=False)
    assert one.corrected and one.verified.comparison.ok
    assert one.max_error_um[0] > 8.0  # a case with something to correct
    b, a = one.verified.before_stats, one.verified.after_stats
    assert one.verified.comparison.unmatched <= 0.05 * a.points
    away = _away_from_pass_ends(one.verified.best_field)
    assert np.abs(one.verified.best_field.E_um[away]).max() <= 0.15 * b.max_abs_um
    assert a.rms_um <= 0.25 * b.rms_um, one.rms_error_um
    assert a.min_um >= -2.0 - 1e-9  # the overcut limit
    it = compensate(prog, run, iterate=True, tolerance_mm=5e-5, max_iterations=3)
    fit = it.verified.best_field
    assert np.abs(fit.E_um[_away_from_pass_ends(fit)]).max() <= 0.05 * b.max_abs_um
    assert it.verified.after_stats.max_abs_um <= 0.15 * b.max_abs_um, it.max_error_um
    assert it.verified.after_stats.rms_um < a.rms_um
    # the corrected program is the original with numbers changed, line for line
    strip = str.maketrans("", "", "0123456789.-+ ")
    old, new = "\n".join(prog.lines).splitlines(), it.text.splitlines()
    assert len(old) == len(new)
    assert all(a.translate(strip) == b.translate(strip) or len(b) > len(a)
               for a, b in zip(old, new, strict=True))


def test_corrected_program_moves_points_against_the_error():
    prog, run = _plane_case()
    field = error_field(run(prog), cutter_locations(prog), prog.line, moved=False)
    res = compensate(prog, run, iterate=False)
    new = parse_program(res.text)
    checked = 0
    for b in np.unique(field.block):
        sel = field.block == b
        if field.E_um[sel].min() > 1.0 and b + 1 in field.block:
            move = new.end[b, :3] - prog.end[b, :3]
            n = field.normal[sel].mean(axis=0)
            assert float(move @ n) < 0  # material left: the tool goes deeper
            checked += 1
    assert checked > 20


def test_edge_forces_grow_linearly_with_cutting_distance():
    """Wear: a slot cut again and again; the revolution-mean force rises in a line."""
    tool = Tool("flat", 10.0, flutes=2, helix_deg=0.0, flute_length_mm=6.0)
    stock = Stock.from_box([-400.0, -30.0, 0.001], [400.0, 30.0, 2.0])
    coeffs = dataclasses.replace(STEEL, Kte1_N_mm2=2e-3, Kre1_N_mm2=3e-3, Kae1_N_mm2=1e-3)
    lines = ["G21 G90 G94", "S6000 M3", "G0 X-300 Y0 Z0", "G1 X-299 F600"]
    lines += [f"G1 X{-299 + 20 * k}" for k in range(1, 13)] + ["M30"]
    prog = parse_program("\n".join(lines) + "\n")
    res = Resolution(pixel_mm=10 / 64, angle_step_rad=math.radians(2.0))
    out = Predictor(tool, stock, prog, coeffs, stiff_tool(), resolution=res).run()
    pts = [p for p in out.points if p.result is not None and p.line >= 6]
    cl = np.array([p.result.cl_max_mm for p in pts])
    fx = np.array([p.result.mean_force_N[1] for p in pts])  # feed-normal component
    assert np.all(np.diff(cl) > 0)
    slope, icpt = np.polyfit(cl, fx, 1)
    assert abs(slope) > 0
    assert np.abs(fx - (slope * cl + icpt)).max() <= 1e-6 * np.abs(fx).max()
    # without wear growth the same cut gives the same force every block
    flat = Predictor(tool, stock, prog, STEEL, stiff_tool(), resolution=res).run()
    f0 = np.array([p.result.mean_force_N[1] for p in flat.points
                   if p.result is not None and p.line >= 6])
    assert np.ptp(f0) <= 1e-9 * np.abs(f0).max()


def test_tool_change_suggestion_is_the_first_block_whose_wear_part_is_over_tolerance():
    """A ball end mill, worn 40 m before, with edge-force growth and radius loss: the
    finding is the first point whose wear part (not its error) exceeds the tolerance."""
    prog = parse_program(plane_raster(25.0, 5.0, passes=3, length=12.0))
    coeffs = dataclasses.replace(STEEL, Kte1_N_mm2=2e-4, Kre1_N_mm2=2.5e-4, Kae1_N_mm2=5e-5)
    pred = Predictor(Tool("ball", 10.0, flute_length_mm=15), plane_stock(25.0, 0.2), prog,
                     coeffs, stiff_tool(k_N_m=1.2e6),
                     shape_error=ShapeErrorModel(wear_rate=2e-7), initial_wear_mm=40e3).run()
    pts = pred.predicted()
    W = np.array([p.result.E_wear_um for p in pts])
    E = np.array([p.result.E_um for p in pts])
    assert W.max() - W[0] > 0.01 and np.all(W > 0)
    tol = 0.5 * (W[0] + W.max())
    assert np.abs(E).min() > tol          # the error is over it everywhere, the wear part not
    tc = tool_change(pred, tol)
    first = next(p for p in pts if abs(p.result.E_wear_um) > tol)
    assert first is not pts[0]
    assert tc["line"] == first.line
    assert tc["wear_error_um"] == pytest.approx(first.result.E_wear_um, abs=1e-3)
    assert tc["E_um"] == pytest.approx(first.result.E_um, abs=1e-3)
    assert tc["remaining_cutting_distance_mm"] == 0.0
    no = tool_change(pred, 1e6)
    assert no["line"] is None and no["remaining_cutting_distance_mm"] > 0
    s = summary(pred, tol)
    assert s["max_abs_error_um"] == pytest.approx(np.abs(E).max(), abs=1e-3)
    # material is left everywhere (E > 0): no overcut, and the range stays signed
    assert E.min() > 0
    assert s["max_overcut_um"] == 0.0
    assert s["max_undercut_um"] == pytest.approx(E.max(), abs=1e-3)
    assert s["error_range_um"] == pytest.approx([E.min(), E.max()], abs=1e-3)
    assert s["tool_change"]["max_wear_error_um"] == pytest.approx(W.max(), abs=1e-3)
    assert s["wear"]["start_max_cutting_distance_mm"] == 40e3


def test_long_blocks_get_several_points_and_are_corrected_along_their_length():
    """A 20 mm pass in one block (21.3 mm along the slope): points every 5 mm or less."""
    slope = 20.0
    prog = parse_program(plane_raster(slope, 5.0, passes=3, length=20.0, step=20.0))
    tool = Tool("ball", 10.0, flute_length_mm=15)
    stock = plane_stock(slope, 0.2)

    res = dataclasses.replace(Resolution.default(tool), point_spacing_mm=5.0)

    def run(p, origin=None, resolution=res):
        return Predictor(tool, stock, p, STEEL, stiff_tool(k_N_m=1.2e6),
                         resolution=resolution).run()

    pred = run(prog)
    long_block = [b for b in range(len(prog)) if prog.line[b] == 9][0]  # pass 2, one G1
    pts = [p for p in pred.points if p.block == long_block]
    length = 20.0 / math.cos(math.radians(slope))
    assert len(pts) == math.ceil(length / 5.0) and all(p.status == "predicted" for p in pts)
    fr = [(p.geometry.path_mm - pts[0].geometry.path_mm) for p in pts]
    np.testing.assert_allclose(np.diff(fr), length / len(pts), rtol=1e-6)  # 5-decimal words
    # densely (2 mm, ends included) the corrected long blocks are verified along them
    dense = res.dense()
    out = compensate(prog, lambda p, o=None: run(p, resolution=dense), iterate=False)
    assert out.corrected
    fld, before = out.verified.best_field, out.verified.before_stats
    assert np.abs(fld.E_um[_away_from_pass_ends(fld)]).max() <= 0.2 * before.max_abs_um
    assert out.verified.after_stats.rms_um <= 0.4 * before.rms_um


def test_lag_of_a_delayed_response():
    n = 360
    th = np.arange(n) * 2 * math.pi / n
    force = np.stack([np.exp(-((th - 1.0) / 0.1) ** 2), np.zeros(n), np.zeros(n)], axis=1)
    defl = np.roll(force, 25, axis=0) * 1e-3
    assert _lag_deg(force, defl) == pytest.approx(25.0)


def test_unknown_coefficients_fail_before_anything_runs():
    with pytest.raises(ValueError, match="Ktc_N_mm2"):
        CuttingCoefficients(Ktc_N_mm2=float("nan"), Krc_N_mm2=1, Kac_N_mm2=1, Kte0_N_mm=1,
                            Kre0_N_mm=1, Kae0_N_mm=1)


def test_dense_points_keep_their_count_when_a_block_grows_by_micrometres():
    """A block the dense spacing's length (2 mm) and the same block a correction made
    1 um longer get one point each (the corner before them is the move before's), as the
    spacing's slack (``POINT_SPACING_SLACK``, 1 %) says; a block 1.5 % longer than the
    spacing is split in two, and no two points of a block lie farther apart than the
    spacing and its slack. At a slack of 1e-9 the 1 um longer block got two points."""
    from errpred import constants as K

    prog = parse_program("\n".join([
        "G21 G90 G17 G94", "S8000 M3", "G0 X0 Y2 Z5", "G1 Z0 F1600",
        "G1 X2", "G1 X4.001", "G1 X6.031", "G1 X8.031", "M5"]))
    tool = Tool("ball", 10.0, flute_length_mm=15)
    dense = Resolution.default(tool).dense(2.0)
    model = Predictor(tool, plane_stock(0.0, 0.2), prog, STEEL, stiff_tool(k_N_m=1.2e6),
                      resolution=dense).model
    moves = {round(float(prog.end[b, 0]), 3): b for b in range(len(prog))
             if 5 <= prog.line[b] <= 8}
    counts = {x: len(model.geometry(b)) for x, b in moves.items()}
    assert counts == {2.0: 2, 4.001: 1, 6.031: 2, 8.031: 1}, counts
    for b in moves.values():
        s = np.array([g.path_mm for g in model.geometry(b)])
        assert np.all(np.diff(s) <= 2.0 * (1 + K.POINT_SPACING_SLACK) + 1e-9)
