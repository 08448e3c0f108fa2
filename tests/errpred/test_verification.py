"""The verification's comparison (errpred.verification.compare) from a table of cases: each
point of a corrected program against the original's error at the same place on the path."""

from __future__ import annotations

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
