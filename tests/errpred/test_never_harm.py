"""The output never harms (issue 16), on parts unlike the bundled ones
(tests/errpred/adversarial.py): what ``errpred compensate`` writes is re-predicted densely
here, from the written file, independently of the loop that made it; a program the
verification refuses is not written and the command ends with exit status 1; a block that
cuts only between its quarter points is cut, with its wear; a rapid move into material is
an error."""

from __future__ import annotations

import html
import json
import math

import numpy as np
import pytest

from errpred.cli import main as errpred_main
from errpred.pipeline import build_predictor, load
from errpred.verification import compare, error_field
from nc import parse_program
from nc.path import cutter_locations

from . import adversarial as adv


def _dense_fields(scenario_path, corrected_path):
    """The original's and the written program's dense errors against the original."""
    s = load(scenario_path)
    orig = s.read_program()
    res = s.resolution.dense()
    stock = s.stock.load()
    ref = cutter_locations(orig, s.resolve_machine(), chord_tol_mm=res.chord_tol_mm)
    before = error_field(build_predictor(s, orig, res, stock).run(), ref, orig.line,
                         moved=False)
    prog = parse_program(corrected_path.read_text(), file=str(corrected_path))
    after = error_field(build_predictor(s, prog, res, stock).run(), ref, orig.line)
    return orig, prog, before, after


def test_a_steep_wall_is_corrected_to_3um_everywhere_ends_included(tmp_path, capsys):
    """A wall inclined 89.5 deg, three waterline levels in 10 mm blocks whose ends lie in
    air: the written program, re-predicted every 2 mm (block ends included), is within
    +-3 um everywhere and nowhere worse than the original."""
    scn = adv.steep_wall(tmp_path / "wall", levels=3, length=30.0, stiffness_scale=0.3,
                         extra="\n[correction]\nmax_iterations = 4\n")
    out = tmp_path / "corrected.nc"
    assert errpred_main(["compensate", str(scn), "--iterate", "-q", "-o", str(out),
                         "--report", str(tmp_path / "v.json")]) == 0
    orig, prog, before, after = _dense_fields(scn, out)
    assert before.E_um.max() > 8.0                       # a case with something to correct
    assert len(after) >= 0.9 * len(before)
    assert np.all(np.abs(after.E_um) <= 3.0), after.E_um
    assert after.E_um.min() >= -3.0
    assert compare(before, after).ok
    rep = json.loads((tmp_path / "v.json").read_text())
    assert rep["corrected"] and rep["verification"]["ok"]
    assert rep["verification"]["after"]["max_abs_um"] <= 3.0
    # each block's end is a vertex moved once: the lines of the original are all there
    # (words and comments kept), split blocks add G1 lines after their own
    assert len(prog) >= len(orig)


def test_a_full_circle_stays_a_full_circle(tmp_path):
    """A Fanuc-style full circle (G2 with equal start and end) corrected: still a full
    circle, the path length within 0.1 mm of the original's, nowhere worse densely."""
    scn = adv.full_circle(tmp_path / "boss", radius=15.0, levels=1, stiffness_scale=0.3,
                          extra="\n[correction]\nmax_iterations = 2\n")
    out = tmp_path / "corrected.nc"
    assert errpred_main(["compensate", str(scn), "--iterate", "-q", "-o", str(out)]) == 0
    orig, prog, before, after = _dense_fields(scn, out)
    circles = [b for b in range(len(prog)) if prog.arc_index[b] >= 0]
    assert len(circles) == 1
    b = circles[0]
    k = int(prog.arc_index[b])
    assert abs(abs(prog.arc_sweep[k]) - 2 * math.pi) < 1e-9
    np.testing.assert_allclose(prog.start[b, :3], prog.end[b, :3], atol=1e-3)
    length = [float(np.sum(np.linalg.norm(np.diff(cutter_locations(p).tip, axis=0),
                                          axis=1))) for p in (orig, prog)]
    assert abs(length[1] - length[0]) < 0.1
    assert compare(before, after).ok
    assert np.abs(after.E_um).max() < np.abs(before.E_um).max()


def test_a_line_across_two_islands_cuts_both_and_wears_the_tool(tmp_path):
    """One G1 from X10 to X90 beside two islands that only its middle stretches reach
    (its quarter points cut nothing): two stretches are found, and the wear they add is
    within 15 % of the same cut programmed as 0.5 mm blocks (each block its own point)."""
    scn = adv.two_islands(tmp_path / "islands")
    s = load(scn)
    pred = build_predictor(s).run()
    line = [p for p in pred.points if p.line == 8]
    assert len(line) == 2 and all(p.geometry.cuts for p in line)
    x = sorted(float(p.geometry.tip[0]) for p in line)
    assert 30.0 < x[0] < 48.0 and 50.0 < x[1] < 68.0
    text = (tmp_path / "islands" / "program.nc").read_text().splitlines()
    i = text.index("G1 X90")
    fine = text[:i] + [f"G1 X{v:.2f}" for v in np.arange(10.5, 90.01, 0.5)] + text[i + 1:]
    ref = build_predictor(s, parse_program("\n".join(fine) + "\n")).run()
    assert pred.wear_mm.sum() == pytest.approx(ref.wear_mm.sum(), rel=0.15)
    assert pred.wear_mm.max() == pytest.approx(ref.wear_mm.max(), rel=0.2)


def test_a_rapid_into_material_is_an_error_in_predict_and_compensate(tmp_path, capsys):
    scn = adv.rapid_into_stock(tmp_path / "rapid")
    rep = tmp_path / "report.json"
    assert errpred_main(["predict", str(scn), "-q", "-o", str(rep)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "rapid move (G0) into material at line 6" in err[0], err
    data = json.loads(rep.read_text())            # the report is written: it says where
    assert [f["line"] for f in data["summary"]["errors"]] == [6]
    assert data["points"][1]["status"] == "rapid-into-material"
    out = tmp_path / "corrected.nc"
    assert errpred_main(["compensate", str(scn), "-q", "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "line 6" in err[0], err
    assert not out.exists()


def test_a_cut_deeper_than_the_flutes_is_an_error_and_levels_within_them_are_not(tmp_path,
                                                                                  capsys):
    """One pass with its tip 25 mm under the block's top, the flutes 10 mm long: the shank
    meets the material over the whole pass (the block reaches 30 mm under the tip, so
    the tool's bottom view is inside the material over all its depth: it cuts). The same
    depth in five levels 5 mm apart (each level's shank runs in what the levels above
    cut): no finding."""
    deep = adv.deep_side_cut(tmp_path / "deep", (5.0,), base_z=-25.0)
    rep = tmp_path / "deep.json"
    assert errpred_main(["predict", str(deep), "-q", "-o", str(rep)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "1 cut deeper than the flutes (10 mm" in err[0], err
    assert "at line 7:" in err[0] and "must not be run" in err[0]
    found = json.loads(rep.read_text())["summary"]["errors"]
    assert found and {f["status"] for f in found} == {"above-flutes"}
    assert {f["line"] for f in found} == {7} and found[0]["flute_length_mm"] == 10.0
    out = tmp_path / "corrected.nc"
    assert errpred_main(["compensate", str(deep), "-q", "-o", str(out)]) == 1
    assert "deeper than the flutes" in capsys.readouterr().err and not out.exists()

    levels = adv.deep_side_cut(tmp_path / "levels", (25.0, 20.0, 15.0, 10.0, 5.0))
    s = load(levels)
    pred = build_predictor(s, s.read_program()).run()
    cutting = [p for p in pred.points if p.geometry.cuts]
    assert {p.line for p in cutting} == {7 + 4 * k for k in range(5)}   # every level cuts
    assert not any(p.geometry.above_flutes for p in pred.points)
    # the same last level without the four above it: its shank is in the material
    alone = adv.deep_side_cut(tmp_path / "alone", (25.0, 5.0))
    s = load(alone)
    pts = build_predictor(s, s.read_program()).run().points
    assert [p.line for p in pts if p.geometry.above_flutes] == [11]
    # one block ramping from 2 to 16 mm deep: its point, in the middle of what it cuts
    # (9 mm deep), has its shank clear; the pre-check's stations toward its end do not
    ramp = adv.deep_side_cut(tmp_path / "ramp", (28.0,), ramp_to=14.0)
    s = load(ramp)
    pts = build_predictor(s, s.read_program()).run().points
    (mid,) = [p for p in pts if p.line == 7]
    assert mid.status == "predicted" and 8.0 < 30.0 - mid.geometry.tip[2] < 10.0
    assert mid.geometry.above_flutes
    assert errpred_main(["predict", str(ramp), "-q", "-o", str(tmp_path / "r.json")]) == 1
    assert "deeper than the flutes" in capsys.readouterr().err


def test_compensate_writes_nothing_when_no_correction_is_verified(tmp_path, capsys,
                                                                  monkeypatch):
    """The command's end of the contract: a correction the loop could not verify is not
    written, one line says why, exit status 1 (the loop itself: test_correct_path)."""
    import errpred.pipeline as pipeline
    from errpred.correct import compensate

    scn = adv.steep_wall(tmp_path / "wall", levels=2, length=20.0)

    def refused(scenario, **kwargs):
        prog = scenario.read_program()
        ref = cutter_locations(prog)

        def predict(p, origin):            # a plant whose error grows with any move
            pred = build_predictor(scenario, prog).run()
            moved = float(np.abs(p.end[:, :3] - prog.end[:, :3]).max()) * 1e3 \
                if len(p) == len(prog) else 50.0
            for q in pred.predicted():
                object.__setattr__(q.result, "E_um", q.result.E_um + 5.0 * moved)
            return pred

        return compensate(prog, predict, path=lambda p: ref, iterate=False)

    monkeypatch.setattr(pipeline, "compensate_scenario", refused)
    out = tmp_path / "corrected.nc"
    rep = tmp_path / "verification.json"
    assert errpred_main(["compensate", str(scn), "-q", "-o", str(out),
                         "--report", str(rep)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nothing written" in err[0] and "worse" in err[0], err
    assert not out.exists()
    # the page says why, in red, as the one line does
    page = html.unescape((tmp_path / "corrected.html").read_text())
    why = err[0].split("nothing written to ")[1].split(": ", 1)[1]
    assert f'<p class="verdict bad">Nothing written: {why}' in page
    # the report holds the data behind the refusal: the last candidate (the one the
    # reason names), per block, and each pass's worse points and lines
    data = json.loads(rep.read_text())
    assert not data["corrected"] and data["verification_of"].startswith("the last candidate")
    ver, passes = data["verification"], data["passes"]
    assert ver["reason"] in why and ver["after"] == passes[-1]["after"]
    lines = {b["line"] for b in ver["per_block"]}
    assert len(lines) >= 3 and ver["after"]["points"] == sum(
        b["after"]["points"] for b in ver["per_block"])
    first = passes[0]
    assert not first["ok"] and first["worse_points"] > 0
    assert first["worse_lines"] and set(first["worse_lines"]) <= lines


def test_compensate_refuses_a_program_it_cannot_rewrite_before_predicting(tmp_path):
    """A program with '#' parameters reads and predicts, but its words cannot be
    rewritten: compensate says so before the first dense prediction. It used to
    predict the whole original first and refuse at the first rewrite (31 s on a
    68-block public program), or write this one unchanged (nothing to correct)."""
    from errpred.pipeline import compensate_scenario
    from errpred.scenario import load_scenario
    from nc.rewrite import RewriteError
    from tests.errpred.test_scenario import VALID, _write

    path = _write(tmp_path, VALID)
    (tmp_path / "p.nc").write_text("G21 G90 G17 (finish [ball])\nG0 X5 Y5 Z25\n"
                                   "G1 Z19.5 F500\n#1=40\nG1 X#1 F1000\nM30\n")
    stages = []
    with pytest.raises(RewriteError, match=r"p\.nc:4: rewriting programs with '#'"):
        compensate_scenario(load_scenario(path), progress=stages.append)
    assert stages == []


def test_the_walls_beside_the_floors_are_verified_too(tmp_path, capsys):
    """A radius end mill ramping along the front face of a block, 2 mm into it: its
    bottom finishes a floor while its flank finishes the wall. The correction fits the
    floors; the walls are compared with the original's too (not corrected), said in the
    command's output and in the report, and the written program, re-predicted here, has
    every wall point matched and no worse."""
    scn = adv.deep_side_cut(tmp_path / "ramp", (25.0,), base_z=0.0, ramp_to=24.0)
    out = tmp_path / "corrected.nc"
    assert errpred_main(["compensate", str(scn), "-o", str(out),
                         "--report", str(tmp_path / "v.json")]) == 0
    said = capsys.readouterr().out
    assert "the walls beside the floors (not corrected), at " in said
    walls = json.loads((tmp_path / "v.json").read_text())["verification"]["walls"]
    assert walls["ok"] and walls["worse_points"] == 0 and walls["after"]["points"] >= 10
    assert walls["before"]["max_abs_um"] > 5.0       # walls with an error worth seeing
    orig, prog, before, after = _dense_fields(scn, out)
    assert len(after.walls) == walls["after"]["points"]
    c = compare(before, after)
    assert c.ok and c.walls is not None and c.walls.unmatched == 0
    # [correction] verify_walls = false: not compared, not said
    off = adv.deep_side_cut(tmp_path / "off", (25.0,), base_z=0.0, ramp_to=24.0)
    off.write_text(off.read_text() + "\n[correction]\nverify_walls = false\n")
    assert errpred_main(["compensate", str(off), "-o", str(tmp_path / "off.nc"),
                         "--report", str(tmp_path / "off.json")]) == 0
    said = capsys.readouterr().out
    assert "walls beside the floors not compared ([correction] verify_walls = false)" in said
    assert json.loads((tmp_path / "off.json").read_text())["verification"]["walls"] is None
