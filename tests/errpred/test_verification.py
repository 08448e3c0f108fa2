"""The verification's comparison (errpred.verification.compare) from a table of cases: each
point of a corrected program against the original's error at the same place on the path;
the walls beside the floors by the same table."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from errpred.verification import ErrorField, compare, error_stats


def _field(s_mm, E_um, chain=0) -> ErrorField:
    s = np.asarray(s_mm, float)
    n = s.size
    pts = np.c_[s, np.zeros(n), np.zeros(n)]
    z = np.zeros(n)
    return ErrorField(point_mm=pts, tip_mm=pts, axis=np.tile([0.0, 0.0, 1.0], (n, 1)),
                      normal=np.tile([0.0, 1.0, 0.0], (n, 1)), E_um=np.asarray(E_um, float),
                      gain=z, block=np.arange(n), ref_segment=np.arange(n) + 1,
                      ref_block=np.arange(n), ref_line=np.arange(n) + 10,
                      chain=np.full(n, chain), s_mm=s, shift_um=z)


BEFORE = _field([0, 2, 4, 6, 8], [10.0, 10.0, 21.0, -1.0, 4.0])

#: (after's s, after's E, worse?) with the original above, 1 um tolerance, 2 um overcut
CASES = [
    (2.0, 10.9, False),          # at an original point: within 1 um of it
    (2.0, 11.1, True),           # 1.1 um more
    (2.0, -10.9, True),          # |E| no larger, but an overcut deeper than 2 um ...
    (2.0, -2.1, True),           # ... where the original left material
    (2.0, -1.9, False),          # a 1.9 um overcut there is allowed
    (6.0, -1.9, False),          # where the original cut 1 um too deep: |E| within 1 um of it
    (6.0, -2.1, True),
    (5.0, 21.5, False),          # between 21 and -1 (a step): within the envelope
    (5.0, 22.1, True),
    (5.0, -3.1, True),           # below min(-1, 0) - 2
    (1.0, 10.5, False),          # between 10 and 10
    (12.0, 50.0, True),          # beyond the original's points by more than a spacing:
    (12.0, 0.9, False),          # it cuts where the original did not: held to the
    (12.0, -2.1, True),          # nominal surface (counted as unmatched)
]


@pytest.mark.parametrize("s,E,worse", CASES)
def test_a_point_is_worse_only_beyond_the_tolerance(s, E, worse):
    c = compare(BEFORE, _field([s], [E]))
    assert bool(c.worse[0]) is worse
    assert c.ok is not worse


def test_the_comparison_reports_before_after_and_per_block():
    after = _field([0, 2, 4, 6, 8, 12], [1.0, -0.5, 3.0, -1.5, 0.2, 0.5])
    c = compare(BEFORE, after, lines={0: 10, 4: 14})
    assert c.ok and c.unmatched == 1
    assert c.before == error_stats(BEFORE.E_um)
    assert c.after.max_abs_um == pytest.approx(3.0) and c.after.min_um == pytest.approx(-1.5)
    d = c.as_dict()
    assert d["ok"] and d["per_block"][0]["line"] == 10
    assert d["per_block"][0]["before"]["max_abs_um"] == pytest.approx(10.0)
    assert d["per_block"][0]["after"]["max_abs_um"] == pytest.approx(1.0)
    assert "verified on 6 points" in c.reason()


def test_passes_are_compared_with_their_own_pass():
    """A point of another pass (a rapid apart) at the same path length is not compared
    with this pass's original points."""
    c = compare(BEFORE, _field([2.0], [0.5], chain=1))
    assert c.ok and c.unmatched == 1
    c = compare(BEFORE, _field([2.0], [30.0], chain=1))
    assert not c.ok and "the original does not cut" in c.reason()
    with pytest.raises(ValueError, match="tolerance_um"):
        compare(BEFORE, BEFORE, tolerance_um=float("nan"))


# --- walls beside the floors (ErrorField.walls, Comparison.walls) ------------------------

def _with_walls(floor: ErrorField, walls: ErrorField | None) -> ErrorField:
    return dataclasses.replace(floor, walls=walls)


#: The walls follow the floors' table, but for a wall with no original wall near it:
#: only an overcut beyond the limit is worse there (material left is not known worse).
WALL_CASES = [(s, E, worse if not (s == 12.0 and E > 0) else False) for s, E, worse in CASES]


@pytest.mark.parametrize("s,E,worse", WALL_CASES)
def test_a_wall_point_is_worse_by_the_same_rules(s, E, worse):
    # the floors the same before and after: only the wall decides
    floor = _field([2.0], [10.0])
    c = compare(_with_walls(floor, BEFORE), _with_walls(floor, _field([s], [E])))
    assert not c.worse.any()
    assert c.walls is not None and c.walls.kind == "wall"
    assert bool(c.walls.worse[0]) is worse
    assert c.ok is not worse


def test_a_worse_wall_refuses_and_says_so():
    floor = _field([0, 2], [10.0, 10.0])
    after = _with_walls(_field([0, 2], [0.2, 0.1]), _field([2.0], [14.0]))
    c = compare(_with_walls(floor, BEFORE), after, lines={1: 11})
    assert not c.ok and not c.worse.any()
    text = c.reason()
    assert text.startswith("the walls beside the floors: worse than the original at 1 of 1")
    assert "E +14.00 um where the original has +10.00 um" in text
    assert text.endswith("(where those walls are not the part's surfaces: [correction] "
                         "verify_walls = false)")
    # not compared where the scenario says they are not the part's surfaces
    off = compare(_with_walls(floor, BEFORE), after, walls=False)
    assert off.ok and off.walls is None
    d = c.as_dict()
    assert d["ok"] is False and d["worse_points"] == 0
    assert d["walls"]["worse_points"] == 1 and "per_block" not in d["walls"]
    # a wall of the candidate where the original has none predicted: an overcut is worse
    c = compare(floor, _with_walls(floor, _field([2.0], [-5.0])))
    assert not c.ok and "no wall of the original is predicted" in c.reason()
    # floors worse too: the floor's reason, the walls named at its end
    c = compare(_with_walls(floor, BEFORE), _with_walls(_field([0, 2], [30.0, 0.0]),
                                                         _field([2.0], [14.0])))
    assert not c.ok and c.reason().endswith("walls worse at 1 points too")
    # walls no worse: said in the verified line
    c = compare(_with_walls(floor, BEFORE), _with_walls(floor, _field([2.0], [10.5])))
    assert c.ok and "walls at 1 points no worse either; 2 of the original's 5 wall points" in c.reason()
    assert c.as_dict()["walls"]["ok"] is True


def test_the_loop_refuses_a_candidate_worse_on_a_wall_and_falls_back_near_it():
    """A toy path of five points 2 mm apart: moving a point's floor by d [mm] takes
    1000 d um off its floor error and half of that off the wall beside it (a sloped
    floor: the move has a part along the wall's normal). The whole fit corrects the
    floors and overcuts the wall by 5 um; the loop refuses it, scales the moves back
    near that wall, and accepts a correction whose wall stays within the overcut
    limit."""
    from types import SimpleNamespace

    from errpred.verified import correct_verified

    s = [0.0, 2.0, 4.0, 6.0, 8.0]
    E0 = np.array([10.0, 10.0, 10.0, 10.0, 10.0])
    wall_at = 4                      # the last point finishes a wall too, 0 um before

    def predict(d):
        floor = _field(s, E0 - 1000.0 * d)
        wall = _field([s[wall_at]], [-500.0 * d[wall_at]])
        return _with_walls(floor, wall), None

    def fit(cand, field, slope, weight, hold=None, free=None):
        moves = weight * field.E_um / 1000.0
        if hold is not None:
            moves = np.where(free, moves, hold.moves)
        return SimpleNamespace(moves=moves, largest_mm=float(np.abs(moves).max()))

    def apply(cand, edit, factor):
        return cand + factor * edit.moves

    out = correct_verified(np.zeros(5), predict, fit, apply, iterate=False,
                           spacing_mm=2.0, reach_mm=0.0)
    first = out.passes[0].comparison
    assert not first.worse.any() and not first.walls.ok       # the walls refused it
    assert out.best_pass >= 1                                  # a fallback was accepted
    best = out.comparison
    assert best.ok and best.walls.ok
    wall_E = float(best.walls.after_field.E_um[0])
    assert -3.0 <= wall_E < 0.0                    # within the 2 um overcut limit (+ 1)
    # the floors far from the wall are corrected whole, the one beside it partly
    assert np.allclose(best.after_field.E_um[:3], 0.0)
    assert 0.0 < best.after_field.E_um[wall_at] < 10.0


def test_iterating_stops_once_the_rms_is_small_enough():
    """The toy path without walls, iterated: the first pass (under-relaxed, 0.7) leaves
    3 um everywhere; with ``enough_rms_um`` 5 the loop stops there, without it a second
    pass follows; a bad value is refused."""
    from types import SimpleNamespace

    from errpred.verified import correct_verified

    s = [0.0, 2.0, 4.0, 6.0, 8.0]

    def predict(d):
        return _field(s, 10.0 - 1000.0 * d), None

    def fit(cand, field, slope, weight, hold=None, free=None):
        moves = weight * field.E_um / 1000.0
        return SimpleNamespace(moves=moves, largest_mm=float(np.abs(moves).max()))

    def apply(cand, edit, factor):
        return cand + factor * edit.moves

    def run(**kw):
        return correct_verified(np.zeros(5), predict, fit, apply, iterate=True,
                                max_iterations=5, spacing_mm=2.0, **kw)

    enough = run(enough_rms_um=5.0)
    assert len(enough.passes) == 1 and enough.best_pass == 0
    assert enough.comparison.after.rms_um == pytest.approx(3.0)
    full = run()
    assert len(full.passes) >= 2 and full.comparison.after.rms_um < 1e-6
    with pytest.raises(ValueError, match="enough_rms_um"):
        run(enough_rms_um=float("nan"))


def test_where_the_original_has_two_walls_at_one_place_either_is_the_reference():
    """A block's end and the next block's start are the same place; where the original's
    wall error jumps there (-52 and -77 um: a step), a wall point of the corrected
    program at that place is compared with the range of both, not with the nearer one
    alone. The floors keep the nearer one (a joint would loosen their check)."""
    floor = _field([2.0], [1.0])
    joint = _field([0.0, 2.0, 2.0, 4.0], [-50.0, -52.0, -77.0, -75.0])
    for s_after in (2.0, 2.0 + 1e-9, 2.0 - 1e-9):
        c = compare(_with_walls(floor, joint), _with_walls(floor, _field([s_after], [-72.0])))
        assert c.ok, (s_after, c.reason())
        assert c.walls.allowed_um[0, 1] == pytest.approx(78.0)
    # beyond both values it is still worse, and a single value stays a single value
    assert not compare(_with_walls(floor, joint), _with_walls(floor, _field([2.0], [-80.0]))).ok
    assert not compare(_with_walls(floor, joint), _with_walls(floor, _field([0.0], [-55.0]))).ok
    # floors: the same joint, and a point at it is held to the nearer value alone
    assert not compare(joint, _field([2.0], [-72.0])).ok


def test_walls_the_corrected_program_no_longer_has_are_counted_and_said():
    """An original wall point with no wall of the corrected program near it is not
    compared; it is counted (``lost``) and said in the reason and the report (points
    4 mm apart at a 1 mm dense spacing: the candidate's one wall is near one of three)."""
    floor = _field([0.0, 4.0, 8.0], [1.0, 1.0, 1.0])
    walls = _field([0.0, 4.0, 8.0], [10.0, 10.0, 10.0])
    c = compare(_with_walls(floor, walls), _with_walls(floor, _field([4.0], [10.2])),
                spacing_mm=1.0)
    assert c.ok and c.walls.lost == 2
    assert "2 of the original's 3 wall points have no wall of the corrected" in c.reason()
    assert c.as_dict()["walls"]["lost_points"] == 2
    # none left at all: still compared (0 points), the three counted
    c = compare(_with_walls(floor, walls), floor, spacing_mm=1.0)
    assert c.ok and c.walls is not None and c.walls.lost == 3 and c.walls.after.points == 0