"""The step weights' kernels against their numpy twins, on seeded cases, bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from errpred._engage_kernels import (
    boundary_cells,
    boundary_cells_numpy,
    cell_weights,
    cell_weights_numpy,
    grid_candidates,
    grid_candidates_numpy,
    sub_samples,
    sub_samples_numpy,
)


def _engagement_mask(rng, n, m):
    """A blob of cutting cells (a window of rotation steps, a band of edges) with holes."""
    c0 = np.zeros((n, m), dtype=bool)
    a = int(rng.integers(0, n))
    span = int(rng.integers(1, n // 2))
    rows = (a + np.arange(span)) % n  # wraps around the revolution sometimes
    j0, j1 = sorted(rng.integers(0, m, 2))
    c0[np.ix_(rows, np.arange(j0, j1 + 1))] = True
    c0 &= rng.random((n, m)) > 0.1
    return c0


@pytest.mark.parametrize("seed", range(6))
def test_boundary_cells_as_numpy(seed):
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(8, 200)), int(rng.integers(1, 60))
    c0 = _engagement_mask(rng, n, m)
    engaged = c0.any(axis=1)
    for rows in (np.flatnonzero(engaged | np.roll(engaged, 1) | np.roll(engaged, -1)),
                 np.arange(n), np.sort(rng.choice(n, n // 3, replace=False))):
        rows = rows.astype(np.int64)
        got, want = boundary_cells(c0, rows), boundary_cells_numpy(c0, rows)
        assert all(np.array_equal(g, w) for g, w in zip(got, want, strict=True))
        if c0[rows].any() and not c0[rows].all():
            assert got[0].size > 0  # a mixed mask has a boundary: the test can fail


def test_boundary_cells_of_a_uniform_mask_are_none():
    for v in (False, True):
        i, j = boundary_cells(np.full((12, 5), v), np.arange(12))
        assert i.size == 0 and j.size == 0


@pytest.mark.parametrize("seed", range(4))
def test_sub_samples_as_numpy(seed):
    rng = np.random.default_rng(100 + seed)
    m, se, st, cells = 40, 4, 8, int(rng.integers(0, 300))
    n = 180
    theta = np.arange(n) * (2 * math.pi / n)
    i = rng.integers(0, n, cells)
    j = rng.integers(0, m, cells)
    du_step = ((np.arange(st) + 0.5) / st - 0.5) * (2 * math.pi / n)
    sub_rho = rng.uniform(0.0, 5.0, (m, se))
    sub_z = rng.uniform(0.0, 15.0, (m, se))
    sub_lag = rng.uniform(-1.0, 1.0, (m, se))
    for shift in (np.zeros(3), rng.normal(0, 0.01, 3)):
        got = sub_samples(theta[i], j, du_step, sub_rho, sub_z, sub_lag, shift)
        want = sub_samples_numpy(theta[i], j, du_step, sub_rho, sub_z, sub_lag, shift)
        for g, w in zip(got, want, strict=True):
            assert g.shape == w.shape == (cells * st * se, 3)
            assert np.array_equal(g, w)


@pytest.mark.parametrize("seed", range(4))
def test_cell_weights_as_numpy(seed):
    rng = np.random.default_rng(200 + seed)
    n, m, st, se = 90, 30, 8, 4
    cells = int(rng.integers(0, 120))
    flat = rng.choice(n * m, cells, replace=False)
    i, j = flat // m, flat % m
    cut = rng.random(cells * st * se) < rng.random()
    du = (np.arange(st) + 0.5) / st - 0.5
    step = 2 * math.pi / n
    base = (rng.random((n, m)) < 0.4).astype(np.float32)
    out = []
    for f in (cell_weights, cell_weights_numpy):
        w, s = base.copy(), np.zeros((n, m), dtype=np.float32)
        f(cut, i, j, du, step, w, s)
        out.append((w, s))
    (wk, sk), (wn, sn) = out
    assert np.array_equal(wk, wn) and np.array_equal(sk, sn)
    if cells:
        # shares are multiples of 1/32 and the centroid lies inside the step
        assert np.all(wk[i, j] * (st * se) == np.round(wk[i, j] * (st * se)))
        assert np.all(np.abs(sk) <= 0.5 * step)


@pytest.mark.parametrize("seed", range(4))
def test_grid_candidates_as_numpy(seed):
    """The fused gather, shift and interval test against the steps it replaced (the
    interval test is errpred._interval_kernels.interval_membership), on a seeded wavy stock."""
    from errpred._interval_kernels import cells_smooth

    rng = np.random.default_rng(300 + seed)
    n_px, pixel, depth_offset = 40, 0.25, 5.0
    c = (np.arange(n_px) + 0.5) * pixel - 0.5 * n_px * pixel
    X, Y = np.meshgrid(c, c)
    bottom = 4.0 + 0.8 * np.sin(X * rng.uniform(0.5, 3)) * np.cos(Y) + rng.normal(0, 0.02, X.shape)
    top = bottom + rng.uniform(0.5, 3.0)
    bottom[rng.random(X.shape) < 0.05] = np.inf  # holes: no material there
    top[~np.isfinite(bottom)] = np.inf
    sm_t, sm_b = cells_smooth(top, 0.1), cells_smooth(bottom, 0.1)
    n, m = 90, 50
    samples = np.column_stack([rng.uniform(-4.9, 4.9, n * m), rng.uniform(-4.9, 4.9, n * m),
                               rng.uniform(-2.0, 3.0, n * m)])
    rows = np.sort(rng.choice(n, int(rng.integers(1, n)), replace=False)).astype(np.int64)
    cols = np.flatnonzero(rng.random(m) < 0.8).astype(np.int64)
    for shift in (np.zeros(3), rng.normal(0, 0.05, 3)):
        args = (samples, rows, cols, m, shift, top, bottom, sm_t, sm_b, pixel, depth_offset,
                1e-6)
        got, want = grid_candidates(*args), grid_candidates_numpy(*args)
        for g, w in zip(got, want, strict=True):
            assert g.dtype == w.dtype and np.array_equal(g, w)
        idx, _, _, unsure = got
        assert 0 < idx.size < rows.size * cols.size and unsure.any() and not unsure.all()


@pytest.mark.parametrize("n", [0, 1, 2, 3, 7, 180])
def test_engaged_steps_with_their_neighbours_as_numpy_roll(n):
    """The engagement's window (each engaged rotation step and one either side, around
    the revolution) as ``mask | np.roll(mask, 1) | np.roll(mask, -1)``, both ends wrapping."""
    from errpred.point_engagement import _with_neighbours

    rng = np.random.default_rng(n)
    for _ in range(50):
        m = rng.random(n) < rng.random()
        assert np.array_equal(_with_neighbours(m), m | np.roll(m, 1) | np.roll(m, -1))
    if n >= 3:
        one = np.zeros(n, dtype=bool)
        one[0] = True                               # wraps to the last step
        assert np.flatnonzero(_with_neighbours(one)).tolist() == [0, 1, n - 1]
