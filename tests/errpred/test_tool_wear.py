"""Tool wear across runs: the wear part of the error, the tool-change finding, tool states.

The case (``cases.write_wall_scenario``): a wall side-milled by a straight-flute D10
flat end mill at 0.3 mm radial depth, every shaping micro edge cutting its whole length,
so all of them have the same actual cutting distance and closed forms hold.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from errpred.cli import main
from errpred.pipeline import load, predict
from errpred.report import summary, tool_change
from errpred.scenario import ScenarioError, load_scenario
from errpred.tool_state import FORMAT, read_tool_state

from .cases import WALL_AE_MM, wall_passes, write_wall_scenario

RATE_UM_PER_M = 0.2


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("wall")


#: Program A of the round trip; its end state is the start of the state-file tests.
PROG_A = wall_passes(-66.0, -36.0, end=False)


@pytest.fixture(scope="module")
def state_a(folder):
    """Program A predicted by the command line, its end state written: the file's path."""
    sa = write_wall_scenario(folder, "progA", PROG_A + ["M30"])
    state = folder / "after-A.json"
    assert main(["predict", sa, "--tool-state-out", str(state), "-q",
                 "-o", str(folder / "progA-report.json")]) == 0
    return state


def _scenario(folder, name, lines, **kw):
    return load(write_wall_scenario(folder, name, lines, **kw))


def _pred(scn):
    return [p for p in predict(scn).predicted()]


# --------------------------------------------------------------------------- the wear part
def test_wear_part_is_the_error_minus_that_of_a_fresh_tool(folder):
    """W = E(worn) - E(fresh tool, same point), checked against a second prediction
    with the wear models switched off (edge-force growth and radius loss both on)."""
    lines = wall_passes(-66.0, -26.0)
    used = "used_cutting_distance_m = 60.0"
    worn = load(write_wall_scenario(folder, "worn", lines, tool_extra=used))
    pw = _pred(worn)
    fresh = dataclasses.replace(
        worn, coefficients=worn.coefficients.replace(Kte1_N_mm2=0.0, Kre1_N_mm2=0.0,
                                                     Kae1_N_mm2=0.0),
        shape_error=dataclasses.replace(worn.shape_error, wear_rate_mm_per_mm=0.0))
    pf = _pred(fresh)
    assert len(pw) == len(pf) >= 3
    for a, b in zip(pw, pf, strict=True):
        ra, rb = a.result, b.result
        assert ra.E_wear_um == pytest.approx(ra.E_um - rb.E_um, abs=1e-9)
        assert rb.E_wear_um == 0.0
        # both parts are there: 60 m of radius loss at 0.2 um/m is 12 um, and the edge
        # forces, 1.6 times their new-tool value (Kre1 60e3 mm = 15 N/mm on 25 N/mm),
        # push the tool off the wall (material left)
        assert ra.E_wear_p_um == pytest.approx(RATE_UM_PER_M * ra.cl_wear_mm * 1e-3, rel=1e-12)
        assert ra.E_wear_p_um > 12.0 and ra.E_wear_d_um > 0.5
    assert all(abs(p.result.E_um) > 30.0 for p in pf)  # a large deflection error


# --------------------------------------------------------------------------- tool change
def test_tool_change_ignores_the_deflection_and_fires_on_wear(folder):
    lines = wall_passes(-66.0, -26.0)
    new = _scenario(folder, "new", lines)
    pred = predict(new)
    E = np.array([p.result.E_um for p in pred.predicted()])
    W = np.array([p.result.E_wear_um for p in pred.predicted()])
    tol = 30.0
    assert np.abs(E).min() > 2 * tol          # the old finding fired at the first point
    assert np.abs(W).max() < 0.05 * tol       # but a new tool has hardly worn
    tc = tool_change(pred, tol)
    # edge-force growth and radius loss: sooner than by the radius loss alone (150 m)
    assert tc["line"] is None and 1e4 < tc["remaining_cutting_distance_mm"] < 150e3
    assert tc["advice"].startswith("no tool change needed")
    # the same cut with a tool that has cut 160 m already: wear alone is over 30 um
    worn = _scenario(folder, "worn160", lines, tool_extra="used_cutting_distance_m = 160.0")
    pw = predict(worn)
    first = pw.predicted()[0]
    tc = tool_change(pw, tol)
    assert first.result.E_wear_um > tol
    assert tc["line"] == first.line and tc["block"] == first.block
    assert tc["wear_error_um"] == pytest.approx(first.result.E_wear_um, abs=1e-3)
    assert tc["remaining_cutting_distance_mm"] == 0.0
    assert tc["advice"].startswith(f"change the tool before line {first.line}")
    assert summary(pw, tol)["tool_change"] == tc


def test_without_wear_models_the_finding_says_so(folder):
    scn = _scenario(folder, "nowear", wall_passes(-66.0, -46.0), edge_wear=False,
                    wear_rate_um_per_m=0.0, tool_extra="used_cutting_distance_m = 80.0")
    pred = predict(scn)
    assert all(p.result.E_wear_um == 0.0 for p in pred.predicted())
    tc = tool_change(pred, 30.0)
    assert tc["line"] is None and tc["remaining_cutting_distance_mm"] is None
    assert tc["advice"].startswith("no wear in the scenario's models")


def test_tool_change_line_is_the_first_point_whose_wear_part_crosses(folder):
    """A start state that puts the crossing in the middle of the pass (radius loss only)."""
    lines = wall_passes(-66.0, 54.0)
    probe = _scenario(folder, "probe", lines, edge_wear=False)
    pp = predict(probe)
    c_run = float(pp.wear_mm.max())
    tol = 30.0
    u_mm = tol / (RATE_UM_PER_M * 1e-3) - 0.5 * c_run        # crossing half-way
    scn = _scenario(folder, "mid", lines, edge_wear=False,
                    tool_extra=f"used_cutting_distance_m = {u_mm / 1e3!r}")
    pred = predict(scn)
    pts = pred.predicted()
    W = np.array([p.result.E_wear_um for p in pts])
    k = int(np.argmax(W > tol))
    assert 2 <= k <= len(pts) - 3 and np.all(W[:k] <= tol)
    tc = tool_change(pred, tol)
    assert (tc["line"], tc["block"]) == (pts[k].line, pts[k].block)


def test_remaining_distance_is_the_closed_form_of_a_linear_wear_rate(folder):
    """Edge-force growth off: W = rate * cl on every shaping edge, so the tool can cut
    (tol - rate * cl_end) / rate more, cl_end its edges' distance at the end."""
    lines = wall_passes(-66.0, 54.0)
    tol = 30.0
    for used_m in (0.0, 37.5):
        scn = _scenario(folder, f"rate{used_m:g}", lines, edge_wear=False,
                        tool_extra=f"used_cutting_distance_m = {used_m!r}")
        pred = predict(scn)
        cut = pred.wear_mm > used_m * 1e3
        cl_end = pred.wear_mm[cut]
        assert np.ptp(cl_end) <= 1e-9 * cl_end.max()   # the case: every edge cuts alike
        c_end = float(cl_end[0])
        rate = RATE_UM_PER_M * 1e-3                      # um per mm
        want = (tol - rate * c_end) / rate
        tc = tool_change(pred, tol)
        assert tc["remaining_cutting_distance_mm"] == pytest.approx(want, abs=2e-3)
        assert tc["wear_growth_um_per_m"] == pytest.approx(RATE_UM_PER_M, rel=1e-9)
        assert tc["cutting_distance_at_tolerance_mm"] == pytest.approx(tol / rate, abs=2e-3)
        run = c_end - used_m * 1e3
        assert tc["remaining_program_runs"] == pytest.approx(want / run, rel=1e-4)
        assert tc["remaining_at"]["cutting_distance_mm"] == pytest.approx(c_end, abs=1e-3)
        # the distance itself, by hand: between two points in the full cut the edges
        # cut one 10 mm block, 100 revolutions through the engagement arc
        # R acos(1 - ae/R) each (the feed's share of the arc, 0.05 mm per tooth, adds
        # about 1 %)
        arc = 5.0 * math.acos(1 - WALL_AE_MM / 5.0)
        cl = np.array([p.result.cl_wear_mm for p in pred.predicted()])
        assert np.diff(cl)[2:] == pytest.approx(100 * arc, rel=0.02)


# --------------------------------------------------------------------------- tool states
def test_state_carried_from_program_a_to_b_equals_a_and_b_concatenated(folder, state_a):
    """Predict A writing its end state; B from that state; A+B in one program."""
    a, b, state = PROG_A, wall_passes(66.0, 36.0), state_a
    doc = json.loads(state.read_text())
    assert doc["format"] == FORMAT and doc["micro_edges"]["count"] == len(
        doc["cutting_distance_mm"])
    sb = load(write_wall_scenario(folder, "progB", b, tool_extra='state = "after-A.json"'))
    sab = load(write_wall_scenario(folder, "progAB", a + b[2:]))
    pa = predict(load(folder / "progA.toml"))
    assert np.array_equal(read_tool_state(state).cl_mm, pa.wear_mm)  # every digit
    pb, pab = predict(sb), predict(sab)
    assert pa.wear_mm.max() > 100.0 and pb.wear_mm.max() > pa.wear_mm.max()
    np.testing.assert_allclose(pb.wear_mm, pab.wear_mm, rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(pb.initial_wear_mm, pa.wear_mm)
    tail = pab.predicted()[-len(pb.predicted()):]
    for x, y in zip(pb.predicted(), tail, strict=True):
        assert x.result.cl_wear_mm == pytest.approx(y.result.cl_wear_mm, rel=1e-12)
        assert x.result.E_wear_um == pytest.approx(y.result.E_wear_um, abs=1e-9)
        assert x.result.E_um == pytest.approx(y.result.E_um, abs=1e-9)


def test_report_carries_the_finding_with_units(folder, state_a):
    rep = json.loads((folder / "progA-report.json").read_text())
    tc = rep["summary"]["tool_change"]
    for key in ("tolerance_um", "line", "block", "wear_error_um", "max_wear_error_um",
                "remaining_cutting_distance_mm", "cutting_distance_at_tolerance_mm",
                "wear_growth_um_per_m", "remaining_program_runs", "advice"):
        assert key in tc, key
    assert tc["line"] is None and tc["remaining_cutting_distance_mm"] > 0
    at = tc["remaining_at"]
    assert at["cutting_distance_mm"] == pytest.approx(max(json.loads(
        state_a.read_text())["cutting_distance_mm"]), abs=1e-3)
    pts = [p for p in rep["points"] if p["status"] == "predicted"]
    assert all(0 < p["E_wear_um"] < 1.0 for p in pts)
    assert rep["tool_start"] == "new tool"


def test_wear_part_for_another_state_of_the_tool_is_exact(folder, state_a):
    """W is linear in the edges' cutting distances: program A cut again from its own end
    state has, at every point, the wear part run 1's weights give for the end state plus
    run 1's own; and the projected runs left follow from those two numbers."""
    p1 = predict(load(folder / "progA.toml"))
    again = write_wall_scenario(folder, "progA2", PROG_A + ["M30"],
                                tool_extra='state = "after-A.json"')
    p2 = predict(load(again))
    pts1, pts2 = p1.predicted(), p2.predicted()
    assert len(pts1) == len(pts2) >= 2
    now = np.array([p.result.wear_part_um(p1.wear_mm) for p in pts1])
    W1 = np.array([p.result.E_wear_um for p in pts1])
    W2 = np.array([p.result.E_wear_um for p in pts2])
    np.testing.assert_allclose(W2, now + W1, rtol=1e-10, atol=1e-9)
    assert np.all(W2 > 1.5 * W1)
    # a fresh tool: the end state is this run's cut, so per run the wear part grows by
    # `now`, and x runs more take it to now (1 + x)
    tol = 5.0
    tc = tool_change(p1, tol)
    i = int(np.argmax(now))
    assert tc["remaining_program_runs"] == pytest.approx(tol / now[i] - 1.0, abs=1e-4)  # 4 decimals
    assert tc["remaining_at"]["wear_error_now_um"] == pytest.approx(now[i], abs=1e-4)


def _write_state(folder, name, edit):
    src = json.loads((folder / "after-A.json").read_text())
    edit(src)
    (folder / name).write_text(json.dumps(src))


BAD_STATES = [
    ("missing.json", None, "file not found"),
    ("notjson.json", "text", "not valid JSON"),
    ("format.json", lambda d: d.update(format="something-else"), "format: expected"),
    ("short.json", lambda d: d["cutting_distance_mm"].pop(), "cutting_distance_mm: expected"),
    ("nan.json", lambda d: d["cutting_distance_mm"].__setitem__(3, math.nan),
     "cutting_distance_mm[3]: expected a finite number"),
    ("negative.json", lambda d: d["cutting_distance_mm"].__setitem__(5, -1.0),
     "cutting_distance_mm[5]: expected a value >= 0"),
    ("strings.json", lambda d: d.update(cutting_distance_mm="12.5"),
     "expected an array of"),
    ("ball.json", lambda d: d["tool"].update(type="ball", corner_radius_mm=5.0),
     "tool.type: made for a ball end mill D10"),
    ("d12.json", lambda d: d["tool"].update(diameter_mm=12.0), "tool.diameter_mm: made for"),
    ("edges.json", lambda d: [d["micro_edges"].update(count=d["micro_edges"]["count"] - 1),
                              d["micro_edges"]["kappa_deg"].pop(),
                              d["micro_edges"]["z_mm"].pop(),
                              d["cutting_distance_mm"].pop()],
     "micro_edges.count: "),
]


@pytest.mark.parametrize("name,edit,expect", BAD_STATES, ids=[b[0] for b in BAD_STATES])
def test_bad_state_files_are_refused_in_one_line(folder, state_a, name, edit, expect):
    if edit == "text":
        (folder / name).write_text("{not json")
    elif edit is not None:
        _write_state(folder, name, edit)
    path = write_wall_scenario(folder, f"bad-{name[:-5]}", wall_passes(-66.0, -56.0),
                               tool_extra=f'state = "{name}"')
    with pytest.raises(ScenarioError) as exc:
        load_scenario(path)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(path) and "tool.state" in msg, msg
    assert name in msg and expect in msg, msg


def test_state_for_another_resolution_and_bad_uniform_keys(folder, state_a):
    lines = wall_passes(-66.0, -56.0)
    path = write_wall_scenario(folder, "res", lines, tool_extra='state = "after-A.json"')
    (folder / "res.toml").write_text((folder / "res.toml").read_text()
                                     + "\n[resolution]\nmicro_edges = 60\n")
    with pytest.raises(ScenarioError, match=r"tool\.state: .*micro_edges"):
        load_scenario(path)
    for extra, expect in (("used_cutting_distance_m = -1.0", "expected a value >= 0"),
                          ("used_cutting_distance_m = nan", "expected a finite number"),
                          ('used_cutting_distance_m = "12"', "expected a number"),
                          ('state = "after-A.json"\nused_cutting_distance_m = 1.0',
                           "not both")):
        p = write_wall_scenario(folder, "uni", lines, tool_extra=extra)
        with pytest.raises(ScenarioError, match="tool.used_cutting_distance_m") as exc:
            load_scenario(p)
        assert expect in str(exc.value)


def test_cli_bad_state_exits_2_and_compensate_writes_the_corrected_programs_state(
        folder, state_a, capsys):
    lines = wall_passes(-66.0, -46.0)
    _write_state(folder, "neg.json", lambda d: d["cutting_distance_mm"].__setitem__(0, -2.0))
    bad = write_wall_scenario(folder, "clibad", lines, tool_extra='state = "neg.json"')
    out = folder / "never.json"
    assert main(["predict", bad, "--tool-state-out", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and "neg.json" in err and err.count("\n") == 1
    assert not out.exists()
    # compensate: the state is that of the corrected program (the one written)
    good = write_wall_scenario(folder, "comp", lines, tool_extra='state = "after-A.json"')
    prog, st = folder / "comp-corrected.nc", folder / "comp-state.json"
    assert main(["compensate", good, "-o", str(prog), "--tool-state-out", str(st), "-q"]) == 0
    scn = load(good)
    from nc import read_program

    # the corrected program's own dense prediction (the one its verification made)
    again = predict(scn, program=read_program(prog), resolution=scn.resolution.dense())
    state = read_tool_state(st)
    np.testing.assert_allclose(state.cl_mm, again.wear_mm, rtol=1e-12)
    # ... not that of the program as given: the corrected one cuts 0.06 mm deeper
    before = predict(scn).wear_mm
    assert np.abs(state.cl_mm - before).max() > 1e-3 * before.max()
    assert json.loads(st.read_text())["written_by"]["command"] == "compensate"
