"""Decision rules (orient/strategies.py) and the posture memory (orient/memory.py).

The rules are checked on ``StandInModel``, a *test double* of the planner's
PostureModel: the inclination is the contract's geometry (exact), the rest
are simple analytic shapes chosen so that the right decision is known in
closed form. It is not physics and nothing else should use it.
"""

from __future__ import annotations

import json
import math
import os

import numpy as np
import pytest

from orient.detect import Detection
from orient.memory import (
    CuttingConditions,
    MemoryScales,
    PostureMemory,
    PostureMemoryError,
)
from orient.strategies import (
    DetectorRule,
    EigenCriterion,
    GainMinimization,
    MemoryRule,
    OperatorInput,
    OperatorRule,
    PostureGrid,
    PostureModel,
    PostureState,
    Strategy,
    TrialRule,
)

R = math.radians
STEP = R(10.0)


class StandInModel:
    """TEST DOUBLE of PostureModel (analytic, not physics).

    Local frame f = X, b = Y, n = Z; the tool axis is the contract's
    ``u = sin(lead) f - cos(lead) sin(tilt) b + cos(lead) cos(tilt) n``.
    * cut sense: ``tanh(2 tilt) cos(lead)``: positive tilt is up-cut, and its
      degree grows with the tilt (as the patent's Fig. 5 c -> d);
    * gain along e: ``-1e7 (1 - 0.9 (u.e)^2)`` [N/m]: the force acts mostly
      perpendicular to the tool axis (small along it, as the patent's [0069]);
    * margin: a paraboloid peaked at ``peak`` with value 2;
    * feasible: inclination <= max_inclination, outside the ``forbidden``
      discs (centre lead, tilt, radius) [rad].
    """

    def __init__(self, max_inclination=None, forbidden=(), peak=None):
        self.max_inclination = R(60.0) if max_inclination is None else max_inclination
        self.forbidden = list(forbidden)
        self.peak = (R(5.0), R(-10.0)) if peak is None else peak

    @staticmethod
    def axis(lead, tilt):
        return np.array([math.sin(lead), -math.cos(lead) * math.sin(tilt),
                         math.cos(lead) * math.cos(tilt)])

    def inclination(self, lead, tilt):
        return math.acos(max(-1.0, min(1.0, self.axis(lead, tilt)[2])))

    def cut_sense(self, lead, tilt):
        return math.tanh(2.0 * tilt) * math.cos(lead)

    def gain(self, lead, tilt, direction):
        return -1e7 * (1.0 - 0.9 * float(self.axis(lead, tilt) @ direction) ** 2)

    def margin(self, lead, tilt):
        return 2.0 - ((lead - self.peak[0]) ** 2 + (tilt - self.peak[1]) ** 2) / R(10.0) ** 2

    def feasible(self, lead, tilt):
        if self.inclination(lead, tilt) > self.max_inclination + 1e-12:
            return False
        return all(math.hypot(lead - cl, tilt - ct) >= r for cl, ct, r in self.forbidden)


def _state(model, lead_deg, tilt_deg, conditions=None):
    return PostureState.from_model(model, R(lead_deg), R(tilt_deg), 10000.0, conditions)


def _det(chatter=True, cause="tool"):
    return Detection(chatter=chatter, frequency_hz=1234.0, amplitude=3.0,
                     cause=cause if chatter else None, phase_rad=1.5, harmonic_ratio=0.5,
                     amplitude_x=2.0, amplitude_y=2.0, whirl=0.9, harmonic_amplitude=6.0,
                     spindle_hz=166.7, tooth_hz=333.3, sample_index=1024, elapsed_s=1e-4)


def _apply(model, state, change):
    return PostureState.from_model(model, change.lead_rad, change.tilt_rad, state.spindle_rpm,
                                   state.conditions)


def _best_on_circle(model, lead, tilt, radius, key, n=3600):
    """Reference: brute-force extremum of ``key`` on a fine circle (independent of the rule)."""
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    pts = [(lead + radius * math.cos(x), tilt + radius * math.sin(x)) for x in a]
    pts = [p for p in pts if model.feasible(*p)]
    return min(key(*p) for p in pts)


def test_protocols_are_satisfied():
    m = StandInModel()
    assert isinstance(m, PostureModel)
    for rule in (OperatorRule(m), DetectorRule(m), TrialRule(m), EigenCriterion(m),
                 GainMinimization(m, [0, 0, 1]), MemoryRule(m, PostureMemory())):
        assert isinstance(rule, Strategy)


# --- operator / detector rules --------------------------------------------------------
def test_cause_A_decreases_inclination_by_about_a_step():
    m = StandInModel()
    rule = OperatorRule(m, STEP)
    s = _state(m, 10.0, 30.0)
    ch = rule.propose(s, OperatorInput("A"))
    assert ch is not None and m.feasible(ch.lead_rad, ch.tilt_rad)
    new = m.inclination(ch.lead_rad, ch.tilt_rad)
    ref = _best_on_circle(m, s.lead_rad, s.tilt_rad, STEP, m.inclination)
    # the ring has 10 deg directions: within step*(1 - cos 5 deg) of the best move
    assert ref <= new <= ref + STEP * (1 - math.cos(R(5.0))) + 1e-12
    assert new < s.inclination_rad - 0.9 * STEP
    assert "tool side" in ch.reason


def test_cause_A_at_the_normal_returns_none_with_a_reason():
    m = StandInModel()
    rule = OperatorRule(m, STEP)
    assert rule.propose(_state(m, 0.0, 0.0), OperatorInput("A")) is None
    assert "cannot be decreased" in rule.last_reason


def test_cause_A_blocked_full_step_takes_a_feasible_partial_step():
    # every full-step move toward the normal is blocked; partial steps are not
    m = StandInModel(forbidden=[(R(0.0), R(20.0), R(6.0))])
    rule = OperatorRule(m, STEP)
    s = _state(m, 0.0, 30.0)
    ch = rule.propose(s, OperatorInput("A"))
    assert ch is not None and m.feasible(ch.lead_rad, ch.tilt_rad)
    assert m.inclination(ch.lead_rad, ch.tilt_rad) < s.inclination_rad


def test_cause_B_from_down_cut_switches_to_up_cut_and_increases_inclination():
    m = StandInModel()
    rule = OperatorRule(m, STEP)
    s = _state(m, 0.0, -20.0)
    assert s.cut_sense < 0
    ch = rule.propose(s, OperatorInput("B"))
    new = _apply(m, s, ch)
    assert new.cut_sense > 0
    assert new.inclination_rad > s.inclination_rad + 0.9 * STEP     # mirrored and pushed out
    assert new.tilt_rad > 0 and "up-cut" in ch.reason


def test_cause_B_up_cut_increases_inclination_and_up_cut_degree():
    m = StandInModel()
    rule = OperatorRule(m, STEP)
    s = _state(m, 5.0, 20.0)
    new = _apply(m, s, rule.propose(s, OperatorInput("B")))
    assert new.inclination_rad > s.inclination_rad + 0.9 * STEP
    assert new.cut_sense > s.cut_sense


def test_cause_B_without_feasible_up_cut_falls_back_to_more_inclination():
    m = StandInModel(forbidden=[(R(0.0), R(45.0), R(44.0))])     # the whole up-cut side
    rule = OperatorRule(m, STEP)
    s = _state(m, 0.0, -20.0)
    ch = rule.propose(s, OperatorInput("B"))
    new = _apply(m, s, ch)
    assert new.cut_sense < 0 and new.inclination_rad > s.inclination_rad
    assert "no feasible up-cut" in ch.reason


def test_no_feasible_posture_returns_none_with_reason():
    m = StandInModel(max_inclination=R(30.0))
    s = _state(m, 0.0, 30.0)            # at the limit: nothing bigger is allowed
    rule = OperatorRule(m, STEP)
    assert rule.propose(s, OperatorInput("B")) is None
    assert "cannot be increased" in rule.last_reason
    blocked = StandInModel(forbidden=[(0.0, 0.0, R(100.0))])
    for r in (OperatorRule(blocked, STEP), GainMinimization(blocked, [0, 0, 1]),
              EigenCriterion(blocked)):
        assert r.propose(_state(m, 0.0, 10.0), OperatorInput("A")) is None
        assert "feasible" in r.last_reason


def test_operator_rule_ignores_detections_and_detector_rule_ignores_operator_input():
    m = StandInModel()
    s = _state(m, 0.0, 20.0)
    assert OperatorRule(m).propose(s, _det()) is None
    assert DetectorRule(m).propose(s, OperatorInput("A")) is None
    assert DetectorRule(m).propose(s, _det(chatter=False)) is None
    assert OperatorRule(m).propose(s, None) is None
    with pytest.raises(TypeError, match="event"):
        OperatorRule(m).propose(s, "chatter")


def test_detector_cause_maps_to_operator_cause():
    m = StandInModel()
    for lead, tilt in ((0.0, 20.0), (10.0, -25.0), (-5.0, 35.0)):
        s = _state(m, lead, tilt)
        for cause, letter in (("tool", "A"), ("workpiece", "B")):
            a = DetectorRule(m, STEP).propose(s, _det(cause=cause))
            b = OperatorRule(m, STEP).propose(s, OperatorInput(letter))
            assert (a.lead_rad, a.tilt_rad) == (b.lead_rad, b.tilt_rad)
    # chatter of unknown side -> trial: a pure tilt step
    s = _state(m, 0.0, 20.0)
    rule = DetectorRule(m, STEP)
    ch = rule.propose(s, _det(cause=None))
    assert ch.lead_rad == s.lead_rad and ch.tilt_rad == pytest.approx(s.tilt_rad + STEP)
    assert rule.trial.phase == "trying"
    assert rule.propose(_apply(m, s, ch), _det(chatter=False)) is None
    assert rule.trial.phase == "idle"                                   # the trial succeeded


# --- trial -------------------------------------------------------------------------------
def test_trial_tilts_one_way_then_reverses_then_gives_up():
    m = StandInModel()
    rule = OperatorRule(m, STEP)
    s0 = _state(m, 0.0, 20.0)
    c1 = rule.propose(s0, OperatorInput("C"))
    assert c1.tilt_rad == pytest.approx(s0.tilt_rad + STEP)           # more inclination first
    s1 = _apply(m, s0, c1)
    assert s1.inclination_rad > s0.inclination_rad
    c2 = rule.propose(s1, OperatorInput("C"))                           # chatter persists
    assert c2.tilt_rad == pytest.approx(s1.tilt_rad - 2 * STEP)        # two steps back
    s2 = _apply(m, s1, c2)
    assert rule.propose(s2, OperatorInput("C")) is None                 # both ways failed
    assert "both ways" in rule.last_reason


def test_trial_success_keeps_the_tried_posture():
    m = StandInModel()
    rule = TrialRule(m, STEP)
    s0 = _state(m, 0.0, -20.0)
    c1 = rule.propose(s0, _det())
    assert c1.tilt_rad == pytest.approx(s0.tilt_rad - STEP)            # inclination grows
    s1 = _apply(m, s0, c1)
    assert rule.propose(s1, None) is None and rule.phase == "trying"   # no news
    assert rule.propose(s1, _det(chatter=False)) is None
    assert rule.phase == "idle" and "succeeded" in rule.last_reason


def test_trial_first_way_infeasible_goes_the_other_way():
    m = StandInModel(max_inclination=R(25.0))
    rule = TrialRule(m, STEP)
    s0 = _state(m, 0.0, 20.0)
    c1 = rule.propose(s0, _det())
    assert c1.tilt_rad == pytest.approx(s0.tilt_rad - STEP)
    assert rule.phase == "reversed" and "infeasible" in c1.reason


def test_trial_upright_first_and_settling_and_external_moves():
    m = StandInModel()
    rule = TrialRule(m, STEP, first="upright", settle_detections=2)
    s0 = _state(m, 0.0, 20.0)
    c1 = rule.propose(s0, _det())
    assert c1.tilt_rad == pytest.approx(s0.tilt_rad - STEP)
    s1 = _apply(m, s0, c1)
    assert rule.propose(s1, _det()) is None and "settling" in rule.last_reason
    assert rule.propose(s1, _det()) is None
    c2 = rule.propose(s1, _det())                                       # now it counts
    assert c2.tilt_rad == pytest.approx(s1.tilt_rad + 2 * STEP)
    # someone else moved the tool: a new trial starts from there
    moved = _state(m, 5.0, 0.0)
    c3 = rule.propose(moved, _det())
    assert c3 is not None and abs(c3.tilt_rad - moved.tilt_rad) == pytest.approx(STEP)


# --- analytical rules --------------------------------------------------------------------
def test_gain_minimization_picks_the_feasible_grid_minimum():
    m = StandInModel()
    grid = PostureGrid(R(20.0), R(5.0))
    s = _state(m, 10.0, 30.0)
    for e in ([0, 0, 1], [0, 1, 0], [1, 0, 1]):
        e = np.asarray(e, float) / np.linalg.norm(e)
        ch = GainMinimization(m, e, grid).propose(s, _det())
        cand = [p for p in grid.around(s.lead_rad, s.tilt_rad) if m.feasible(*p)]
        # reference: the largest |u.e| on the grid (|gain| = 1e7 (1 - 0.9 (u.e)^2))
        best = max(abs(m.axis(*p) @ e) for p in cand)
        assert abs(m.axis(ch.lead_rad, ch.tilt_rad) @ e) == pytest.approx(best, abs=1e-12)
    # along the normal: the smallest inclination on the grid (10 deg lead, 10 deg tilt)
    ch = GainMinimization(m, [0, 0, 1], grid).propose(s, _det())
    assert (ch.lead_rad, ch.tilt_rad) == pytest.approx((R(0.0), R(10.0)))


def test_gain_minimization_skips_infeasible_candidates():
    grid = PostureGrid(R(20.0), R(5.0))
    m = StandInModel(forbidden=[(R(0.0), R(10.0), R(2.0))])            # the best one
    ch = GainMinimization(m, [0, 0, 1], grid).propose(_state(m, 10.0, 30.0), _det())
    assert m.feasible(ch.lead_rad, ch.tilt_rad)
    assert (ch.lead_rad, ch.tilt_rad) != pytest.approx((R(0.0), R(10.0)))


def test_eigen_criterion_goes_to_the_margin_peak_and_stays():
    m = StandInModel(peak=(R(5.0), R(-10.0)))
    rule = EigenCriterion(m, PostureGrid(R(20.0), R(5.0)))
    s = _state(m, -5.0, 5.0)
    ch = rule.propose(s, OperatorInput("C"))
    assert (ch.lead_rad, ch.tilt_rad) == pytest.approx((R(5.0), R(-10.0)))
    assert rule.propose(_apply(m, s, ch), _det()) is None
    assert "already the best" in rule.last_reason
    assert rule.propose(s, None) is None                                  # no chatter, no move
    assert EigenCriterion(m, always=True).propose(s, None) is not None   # planning mode


# --- memory rule -------------------------------------------------------------------------
def _cond(rpm=10000.0, depth=0.2, pick=0.3, normal=(0, 0, 1), feed=(1, 0, 0), tool="T1"):
    return CuttingConditions(rpm, depth, pick, normal, feed, tool)


def test_memory_rule_goes_to_the_nearest_feasible_remembered_posture():
    mem = PostureMemory()
    mem.remember(_cond(rpm=10500.0), R(5.0), R(25.0))                   # nearest
    mem.remember(_cond(rpm=11500.0), R(-5.0), R(15.0))
    mem.remember(_cond(tool="T2"), R(0.0), R(40.0))                      # other tool
    m = StandInModel()
    rule = MemoryRule(m, mem)
    s = _state(m, 0.0, 35.0, _cond())
    ch = rule.propose(s, _det())
    assert (ch.lead_rad, ch.tilt_rad) == (R(5.0), R(25.0))
    m2 = StandInModel(forbidden=[(R(5.0), R(25.0), R(1.0))])
    ch = MemoryRule(m2, mem).propose(s, _det())
    assert (ch.lead_rad, ch.tilt_rad) == (R(-5.0), R(15.0))
    assert MemoryRule(m, mem).propose(_state(m, 0.0, 35.0), _det()) is None   # no conditions
    far = _state(m, 0.0, 35.0, _cond(rpm=30000.0))
    assert MemoryRule(m, mem, max_distance=2.0).propose(far, _det()) is None


def test_memory_rule_learns_without_chatter_once():
    mem = PostureMemory()
    m = StandInModel()
    rule = MemoryRule(m, mem)
    s = _state(m, 3.0, 12.0, _cond())
    assert rule.propose(s, _det(chatter=False)) is None and len(mem) == 1
    assert rule.propose(s, _det(chatter=False)) is None and len(mem) == 1
    moved = _state(m, 0.0, 30.0, _cond(depth=0.21))
    ch = rule.propose(moved, OperatorInput("B"))
    assert (ch.lead_rad, ch.tilt_rad) == (R(3.0), R(12.0))


# --- memory ------------------------------------------------------------------------------
def test_memory_distance_follows_the_documented_scales():
    mem = PostureMemory(MemoryScales(speed_rel=0.1, depth_mm=0.1, pick_mm=0.1,
                                     angle_rad=R(10.0)))
    a = _cond()
    assert mem.distance(a, _cond(rpm=10000 * math.exp(0.1))) == pytest.approx(1.0)
    assert mem.distance(a, _cond(depth=0.5)) == pytest.approx(3.0)
    assert mem.distance(a, _cond(pick=0.2, depth=0.1)) == pytest.approx(math.sqrt(2))
    tilt = R(10.0)
    n = (0, -math.sin(tilt), math.cos(tilt))
    # the chord of 10 deg over a 10 deg scale
    assert mem.distance(a, _cond(normal=n)) == pytest.approx(2 * math.sin(tilt / 2) / tilt)
    assert mem.distance(a, _cond(tool="T9")) == math.inf
    # the feed is stored projected onto the plane normal to the surface normal
    c = _cond(feed=(1, 0, 0.5))
    assert c.feed_dir == pytest.approx((1.0, 0.0, 0.0))


def test_memory_nearest_brute_force_and_kdtree_agree():
    rng = np.random.default_rng(7)
    big, small = PostureMemory(), PostureMemory()
    conds = []
    for i in range(200):
        n = rng.normal(size=3)
        n[2] = abs(n[2]) + 1
        c = _cond(rpm=rng.uniform(5000, 20000), depth=rng.uniform(0.05, 0.5),
                  pick=rng.uniform(0.05, 0.5), normal=n, feed=rng.normal(size=3))
        conds.append(c)
        big.remember(c, 0.01 * i, -0.01 * i)
    for i in range(60):
        small.remember(conds[i], 0.01 * i, -0.01 * i)
    for _ in range(30):
        q = conds[int(rng.integers(200))]
        q = _cond(rpm=q.spindle_rpm * 1.02, depth=q.depth_mm, pick=q.pick_mm + 0.01,
                  normal=q.normal, feed=q.feed_dir)
        got = big.nearest(q, k=3)
        ref = sorted(((big.distance(q, e.conditions), j) for j, e in enumerate(big.entries)))
        assert [m.distance for m in got] == pytest.approx([d for d, _ in ref[:3]])
        assert got[0].entry is big.entries[ref[0][1]]
        got_s = small.nearest(q, k=2)
        ref_s = sorted(small.distance(q, e.conditions) for e in small.entries)[:2]
        assert [m.distance for m in got_s] == pytest.approx(ref_s)
    assert big.nearest(_cond(tool="nope")) == []
    assert len(big.nearest(conds[0], k=500)) == 200
    assert big.nearest(conds[0], max_distance=0.0)[0].distance == 0.0


def test_memory_json_round_trip(tmp_path):
    mem = PostureMemory(MemoryScales(speed_rel=0.2))
    mem.remember(_cond(), R(5.0), R(25.0), note="first")
    mem.remember(_cond(rpm=12345.678, normal=(0.1, 0.2, 0.9), feed=(0, 1, 0), tool="T2"),
                 -0.123456789, 0.5)
    path = tmp_path / "memory.json"
    mem.save(path)
    back = PostureMemory.load(path)
    assert back.entries == mem.entries and back.scales == mem.scales
    assert [p.name for p in tmp_path.iterdir()] == ["memory.json"]      # no temp file left
    with pytest.raises(FileNotFoundError):
        mem.save(tmp_path / "missing_dir" / "m.json")


@pytest.mark.parametrize("mutate, match", [
    (lambda d: "not json {", "not valid JSON"),
    (lambda d: {**d, "format": "other"}, "format"),
    (lambda d: {**d, "version": 99}, "version"),
    (lambda d: {**d, "entries": [{k: v for k, v in d["entries"][0].items()
                                  if k != "tilt_rad"}]}, r"entries\[0\]: missing key 'tilt_rad'"),
    (lambda d: {**d, "entries": [{**d["entries"][0], "spindle_rpm": -5}]},
     r"entries\[0\]: spindle_rpm"),
    (lambda d: {**d, "entries": [{**d["entries"][0], "normal": [0, 0]}]}, r"entries\[0\]: normal"),
    (lambda d: {**d, "entries": [{**d["entries"][0], "colour": 1}]}, "unknown key 'colour'"),
    (lambda d: json.dumps(d).replace("0.2,", "NaN,", 1), "not valid JSON"),
])
def test_memory_bad_files_are_refused_with_clear_errors(tmp_path, mutate, match):
    mem = PostureMemory()
    mem.remember(_cond(), R(5.0), R(25.0))
    data = mem.to_dict()
    bad = mutate(data)
    path = tmp_path / "bad.json"
    path.write_text(bad if isinstance(bad, str) else json.dumps(bad))
    with pytest.raises(PostureMemoryError, match=match) as info:
        PostureMemory.load(path)
    assert os.fspath(path) in str(info.value)


def test_invalid_inputs_are_refused():
    m = StandInModel()
    with pytest.raises(ValueError, match="cause"):
        OperatorInput("D")
    with pytest.raises(ValueError, match="cut_sense"):
        PostureState(0.0, 0.1, 0.1, 1.5, 10000.0)
    with pytest.raises(ValueError, match="lead_rad"):
        PostureState(math.nan, 0.1, 0.1, 0.5, 10000.0)
    with pytest.raises(ValueError, match="step_rad"):
        OperatorRule(m, -1.0)
    with pytest.raises(TypeError, match="model"):
        OperatorRule(object())
    with pytest.raises(ValueError, match="direction"):
        GainMinimization(m, [0, 0, 0])
    with pytest.raises(ValueError, match="first"):
        TrialRule(m, first="sideways")
    with pytest.raises(ValueError, match="feed_dir"):
        _cond(feed=(0, 0, 2))
    with pytest.raises(ValueError, match="spindle_rpm"):
        _cond(rpm=math.inf)
