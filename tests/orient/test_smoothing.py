"""The smooth posture sequence: exact against brute force, limits respected."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from orient.smoothing import best_smooth_path


def _axes(angles_rad):
    a = np.asarray(angles_rad)
    return np.stack([np.sin(a), np.zeros_like(a), np.cos(a)], axis=-1)


def _brute(score, axes, step, rate, breaks):
    n, s = score.shape
    best, arg = -np.inf, None
    for seq in itertools.product(range(s), repeat=n):
        tot = 0.0
        for i, j in enumerate(seq):
            tot += score[i, j]
            if i and not breaks[i]:
                ang = np.arccos(np.clip(axes[i - 1, seq[i - 1]] @ axes[i, j], -1, 1))
                if ang > rate * step[i] + 1e-6:
                    tot = -np.inf
        if tot > best:
            best, arg = tot, seq
    return best, arg


@pytest.mark.parametrize("seed", range(6))
def test_matches_brute_force(seed):
    rng = np.random.default_rng(seed)
    n, s = 5, 4
    ang = np.sort(rng.uniform(-0.5, 0.5, (n, s)), axis=1)
    ang[:, 0] = 0.0                       # a common candidate keeps every sequence feasible
    score = rng.uniform(0, 2, (n, s))
    score[rng.uniform(size=(n, s)) < 0.15] = -np.inf
    score[:, 0] = np.maximum(score[:, 0], 0.0)
    step = rng.uniform(0.5, 2.0, n)
    breaks = np.zeros(n, bool)
    breaks[3] = seed % 2 == 0
    rate = 0.2
    got = best_smooth_path(score, _axes(ang), step, rate, breaks)
    want, _ = _brute(score, _axes(ang), step, rate, breaks)
    assert np.isclose(score[np.arange(n), got].sum(), want)


def test_rate_limit_holds_and_breaks_lift_it():
    n = 6
    ang = np.tile([0.0, 0.6], (n, 1))
    score = np.tile([0.0, 1.0], (n, 1))
    score[:3, 1] = -np.inf                  # the better posture is only allowed from point 3
    step = np.full(n, 1.0)
    got = best_smooth_path(score, _axes(ang), step, max_rate_rad_per_mm=0.1)
    assert list(got) == [0] * n              # 0.6 rad in one 1 mm step is too fast
    brk = np.zeros(n, bool)
    brk[3] = True
    got = best_smooth_path(score, _axes(ang), step, 0.1, brk)
    assert list(got) == [0, 0, 0, 1, 1, 1]


def test_normal_turning_faster_than_the_limit_still_has_a_path():
    ang = np.array([[0.0], [0.5], [1.0]])
    got = best_smooth_path(np.zeros((3, 1)), _axes(ang), np.ones(3), 0.01)
    assert list(got) == [0, 0, 0]


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="no feasible"):
        best_smooth_path(np.array([[-np.inf]]), _axes([[0.0]]), np.ones(1), 0.1)
    with pytest.raises(ValueError, match="NaN"):
        best_smooth_path(np.array([[np.nan]]), _axes([[0.0]]), np.ones(1), 0.1)
    with pytest.raises(ValueError, match="axes"):
        best_smooth_path(np.zeros((2, 2)), np.zeros((2, 3, 3)), np.ones(2), 0.1)
