"""The planner never writes a colliding posture (issue 16).

A pocket 20 mm wide and a D10 ball end mill in a D40 holder (``tests/orient/pocket.py``):
the CAM posture collides at most points. Where collision-free postures exist the plan
uses them and an independent FCL check of every feed point of the planned (and the
written, read back) path finds no collision; where none exist ``python -m orient
plan -o`` refuses (status 1, one line, nothing written) unless a fallback is allowed.
The choice loop itself is checked on synthetic candidates against the optimum over the
candidates known to be free.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
import trimesh

from nc import read_program
from nc.path import cutter_locations
from orient.cli import main
from orient.geometry import posture_axis
from orient.interference import InterferenceChecker, ToolAssembly
from orient.choice import FALLBACK_SCORE, _choose_collision_free, _Inherited
from orient.plan import candidate_grid, plan
from orient.scenario import ScenarioError, load_plan_scenario
from orient.smoothing import best_smooth_path
from tests.orient.pocket import pocket_scenario

#: Contact heights of the passes [mm]; with a 30 mm opposite wall a few steep postures
#: clear it at each of them, with a 42 mm one only at the top pass.
PASSES = (29.0, 25.0, 21.0)


def _checker(scn) -> InterferenceChecker:
    """An FCL checker built here from the scenario's files (not the planner's)."""
    stock = trimesh.load(str(scn.base.stock.path), force="mesh")
    return InterferenceChecker(stock, ToolAssembly.from_tool(
        scn.base.tool, clearance_mm=scn.options.clearance_mm),
        design_mesh=scn.base.stock.load_design(), gouge_tol_mm=scn.options.gouge_tol_mm)


def _free_candidates(scn, res, chk) -> np.ndarray:
    """Per touching point: how many grid postures and the CAM's are feasible (within the
    inclination range and the axis limits, no collision, no gouge), by brute force."""
    idx = res.touching_index
    opt = scn.options
    lead, tilt = candidate_grid(opt)
    L, T = np.meshgrid(lead, tilt, indexing="ij")
    n, f = res.contacts.normal[idx], res.contacts.feed[idx]
    axes = posture_axis(n[:, None], f[:, None], L.ravel()[None], T.ravel()[None])
    axes = np.concatenate([axes, res.cam.axis[idx][:, None]], axis=1)
    tips = res.contacts.centre[idx][:, None] - scn.base.tool.radius_mm * axes
    incl = np.arccos(np.clip(np.sum(axes * n[:, None], axis=-1), -1, 1))
    ok = (incl >= opt.min_inclination_rad - 1e-9) & (incl <= opt.max_inclination_rad + 1e-9)
    s0, s1 = res.machine.inverse(tips.reshape(-1, 3), axes.reshape(-1, 3))
    ok &= (res.machine.within_limits(s0) | res.machine.within_limits(s1)).reshape(ok.shape)
    ok &= chk.check(tips.reshape(-1, 3), axes.reshape(-1, 3)).feasible.reshape(ok.shape)
    return ok.sum(axis=1)


def test_pocket_plan_is_collision_free_and_its_reasons_are_true(tmp_path, capsys):
    # an 11 x 11 grid: more colliding postures rank above the free ones than a loop
    # dropping one choice per round in 12 rounds got through (it left 7 colliding)
    scn_path = pocket_scenario(tmp_path / "scn", opposite_height_mm=30.0, pass_z=PASSES,
                               grid=11)
    scn = load_plan_scenario(scn_path)
    res = plan(scn)
    chk = _checker(scn)
    idx = res.touching_index
    # the scenario bites: the CAM posture collides at most cutting points, yet every
    # one of them has a feasible posture
    cam = chk.check(res.cam.tip[idx], res.cam.axis[idx])
    assert np.mean(~cam.feasible) > 0.5
    assert _free_candidates(scn, res, chk).min() >= 1
    # no point refused, and no collision anywhere on the planned path
    assert len(res.infeasible) == 0 and res.stats["infeasible_points"] == 0
    feed = ~res.cl.rapid
    planned = chk.check(res.cl.tip[feed], res.cl.axis[feed])
    assert planned.feasible.all(), np.flatnonzero(~planned.feasible)
    assert res.stats["planned_collisions"] == 0
    # the reasons say what the checks find
    at = chk.check(res.cl.tip[idx], res.cl.axis[idx])
    assert at.feasible.all()
    target = scn.options.margin_target
    for k, i in enumerate(idx):
        why = res.reason[i]
        assert not why.startswith("infeasible")
        if why.startswith("CAM posture kept"):
            np.testing.assert_allclose(res.cl.axis[i], res.cam.axis[i], atol=1e-12)
            assert cam.feasible[k]
        m = re.match(r"margin (\S+) >= target", why)
        if m:
            assert float(m.group(1)) >= target and res.margin[i] >= target
        m = re.search(r"CAM posture \(.*\) margin \S+, infeasible: (\w+) against the stock", why)
        if m:
            assert cam.collides[k] and cam.part_label[k] == m.group(1), (why, cam.part_label[k])
        elif "CAM posture (" in why:
            assert cam.feasible[k], why
    assert any(">= target" in res.reason[i] for i in idx)
    # the written program, read back: every feed point clear as well
    out = tmp_path / "planned.ngc"
    assert main(["plan", str(scn_path), "-o", str(out)]) == 0
    text = capsys.readouterr()
    assert "collisions of the planned postures: 0" in text.out and not text.err
    back = cutter_locations(read_program(out), res.machine)
    fb = ~back.rapid
    assert chk.check(back.tip[fb], back.axis[fb]).feasible.all()


def test_pocket_without_feasible_postures_is_refused_unless_fallback_allowed(tmp_path,
                                                                             capsys):
    scn_path = pocket_scenario(tmp_path / "scn", opposite_height_mm=42.0, pass_z=PASSES)
    scn = load_plan_scenario(scn_path)
    res = plan(scn)
    chk = _checker(scn)
    idx = res.touching_index
    free = _free_candidates(scn, res, chk)
    assert (free == 0).any() and (free > 0).any()        # some points have none, some do
    # exactly the cutting points without a feasible candidate are refused, with a true
    # reason; every other point of the path is clear
    flagged = np.isin(idx, res.infeasible)
    np.testing.assert_array_equal(flagged, free == 0)
    assert res.stats["infeasible_points"] == len(res.infeasible)
    for i in idx[flagged]:
        why = res.reason[i]
        assert why.startswith("infeasible: no feasible posture: all "), why
        n = sum(int(c) for c in re.findall(r"(\d+) [a-z]", why.split("rejected (")[1]))
        assert n == len(res.grid_lead_rad) * len(res.grid_tilt_rad) + 1, why
        np.testing.assert_allclose(res.cl.axis[i], res.cam.axis[i], atol=1e-12)
    ok_pts = np.setdiff1d(np.flatnonzero(~res.cl.rapid), res.infeasible)
    assert chk.check(res.cl.tip[ok_pts], res.cl.axis[ok_pts]).feasible.all()
    bad = chk.check(res.cl.tip[res.infeasible], res.cl.axis[res.infeasible])
    for i, f in zip(res.infeasible, bad.feasible):
        # a refused point whose kept CAM posture is clear is a cutting point without one
        assert not f or i in idx, (i, res.reason[i])
    # refused: status 1, one line naming how many and where, nothing written
    out = tmp_path / "out" / "planned.ngc"
    out.parent.mkdir()
    assert main(["plan", str(scn_path), "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    lines = res.stats["infeasible_lines"]
    assert err[0].startswith(f"error: {len(res.infeasible)} of {len(res.cl)} points have no "
                             f"feasible posture, at CAM program lines {lines[0]}, ")
    first = int(idx[flagged][0])
    assert f"point {first}: no feasible posture: all " in err[0]
    assert list(out.parent.iterdir()) == []
    # allowed: the CAM posture kept there, one warning line, status 0, flagged in the report
    assert main(["plan", str(scn_path), "-o", str(out), "--allow-fallback"]) == 0
    text = capsys.readouterr()
    assert len(text.err.strip().splitlines()) == 1 and text.err.startswith("warning: ")
    rep = json.loads((tmp_path / "out" / "planned-plan.json").read_text())
    assert rep["summary"]["infeasible"] == res.infeasible.tolist()
    assert [p["point"] for p in rep["points"] if p["infeasible"]] == res.infeasible.tolist()
    assert all(p["reason"].startswith("infeasible: ") == p["infeasible"] for p in rep["points"])
    # the same through the scenario
    allowed = pocket_scenario(tmp_path / "scn2", opposite_height_mm=42.0, pass_z=PASSES,
                              orient_extra="allow_fallback = true\n")
    out2 = tmp_path / "out2.ngc"
    assert main(["plan", str(allowed), "-o", str(out2)]) == 0 and out2.exists()
    assert capsys.readouterr().err.startswith("warning: ")


def test_allow_fallback_must_be_true_or_false(tmp_path, capsys):
    scn_path = pocket_scenario(tmp_path / "scn", orient_extra='allow_fallback = "yes"\n')
    with pytest.raises(ScenarioError) as err:
        load_plan_scenario(scn_path)
    assert str(scn_path) in str(err.value) and "orient.allow_fallback" in str(err.value)
    out = tmp_path / "o.ngc"
    assert main(["plan", str(scn_path), "-o", str(out)]) == 2
    msg = capsys.readouterr().err
    assert len(msg.strip().splitlines()) == 1 and "orient.allow_fallback" in msg
    assert not out.exists()


class _RuleChecker:
    """Stands in for FCL: a posture collides where its axis leans toward a direction
    that turns with the ball centre (``tip + R axis``) -- the free set changes from
    point to point, and whole points are blocked where ``blocked`` says so."""

    part_names = ("shank", "holder")

    def __init__(self, R: float, blocked):
        self.R, self.blocked, self.calls = R, blocked, 0

    def collides(self, tips, axes):
        c = tips + self.R * axes
        w = np.stack([np.cos(0.7 * c[:, 0]), np.sin(0.7 * c[:, 0]), np.zeros(len(c))], 1)
        return (np.sum(axes * w, axis=1) > -0.1) | self.blocked(c)

    def check(self, tips, axes):
        self.calls += len(tips)
        hit = self.collides(tips, axes)

        class _R:
            part = np.where(hit, 1, -1)
        return _R()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_choice_loop_ends_at_the_optimum_over_the_free_candidates(seed):
    """The loop checks lazily; its result must still be the best smooth path over the
    candidates that are actually free (the brute force: every candidate checked), with
    the same points left without one, and it ends within its bound."""
    rng = np.random.default_rng(seed)
    t, s, R = 60, 40, 5.0
    v = rng.normal(size=(t, s, 3))
    v[..., 2] = np.abs(v[..., 2]) + 0.5
    axes = v / np.linalg.norm(v, axis=-1, keepdims=True)
    x = np.repeat(np.arange(3), t // 3) * 100.0 + np.tile(np.arange(t // 3), 3) * 0.5
    centres = np.stack([x, np.zeros(t), np.zeros(t)], 1)
    tips = centres[:, None, :] - R * axes
    breaks = np.zeros(t, bool)
    breaks[[t // 3, 2 * t // 3]] = True                 # three passes
    step = np.full(t, 0.5)
    score = rng.uniform(0, 2, size=(t, s))
    ok = rng.uniform(size=(t, s)) > 0.2
    ok[:, -1] = True
    blocked_x = x[[7, 8, 45]]                          # no free candidate at these points

    def blocked(c):
        return np.isin(np.round(c[:, 0], 6), np.round(blocked_x, 6))

    chk = _RuleChecker(R, blocked)
    no_inh = _Inherited(*(np.zeros(0, int),) * 2, np.zeros((0, 3)), np.zeros(0),
                        np.zeros(0, int), np.zeros(t + 1, int))
    ok_lazy, cause = ok.copy(), np.zeros((t, s), np.int16)
    choice, st = _choose_collision_free(chk, tips, axes, no_inh, ok_lazy, cause, score, step,
                                        np.radians(40.0), breaks, 2)
    # brute force
    free = ok & ~chk.collides(tips.reshape(-1, 3), axes.reshape(-1, 3)).reshape(t, s)
    none = ~free.any(axis=1)
    np.testing.assert_array_equal(none, ~ok_lazy.any(axis=1))
    np.testing.assert_array_equal(np.flatnonzero(none), [7, 8, 45])
    full = np.where(free, score, -np.inf)
    full[none, -1] = FALLBACK_SCORE
    brk = breaks | none
    brk[1:] |= none[:-1]
    best = best_smooth_path(full, axes, step, np.radians(40.0), brk)
    rows = np.arange(t)
    assert free[rows[~none], choice[~none]].all()
    np.testing.assert_allclose(full[rows, choice].sum(), full[rows, best].sum(), rtol=1e-12)
    assert st["checks"] < t * s                        # lazier than the brute force
    assert 2 <= st["rounds"] <= 1 + 3 * (2 + 5)
    assert (cause[~ok_lazy & ok] != 0).all()           # every dropped candidate has a cause
