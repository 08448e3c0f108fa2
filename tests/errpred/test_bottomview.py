"""The bottom view's kernels (stock membership, smooth cells) against their numpy twins."""

from __future__ import annotations

import math

import numpy as np

from errpred._interval_kernels import box_membership, interval_membership
from errpred.frames import tool_frame


def _numpy_twin(xyz, top, bottom, smooth_top, smooth_bottom, p, depth_offset, e):
    """The interpolation as numpy array code (what the kernel replaced)."""
    n = top.shape[0]
    fx = (xyz[:, 0] + 0.5 * n * p) / p - 0.5
    fy = (xyz[:, 1] + 0.5 * n * p) / p - 0.5
    j0 = np.clip(np.floor(fx).astype(np.int64), 0, n - 2)
    i0 = np.clip(np.floor(fy).astype(np.int64), 0, n - 2)
    tx = np.clip(fx - j0, 0.0, 1.0)
    ty = np.clip(fy - i0, 0.0, 1.0)
    depth = xyz[:, 2] + depth_offset

    def interp(a):
        v00, v01 = a[i0, j0], a[i0, j0 + 1]
        v10, v11 = a[i0 + 1, j0], a[i0 + 1, j0 + 1]
        with np.errstate(invalid="ignore"):
            out = (1 - ty) * ((1 - tx) * v00 + tx * v01) + ty * ((1 - tx) * v10 + tx * v11)
        return np.where(np.isnan(out), v00, out)

    inside = (interp(bottom) - e <= depth) & (depth <= interp(top) + e)
    unsure = ~(smooth_top[i0, j0] & smooth_bottom[i0, j0])
    return inside, unsure


def test_interval_membership_equals_its_numpy_twin():
    rng = np.random.default_rng(5)
    n, p = 34, 0.3
    for trial in range(5):
        bottom = rng.uniform(-1.0, 2.0, (n, n))
        top = bottom + rng.uniform(0.0, 3.0, (n, n))
        # no material (both +inf), material without a bottom or a top in view
        bottom[rng.random((n, n)) < 0.1] = math.inf
        top[np.isposinf(bottom)] = math.inf
        bottom[rng.random((n, n)) < 0.05] = -math.inf
        top[rng.random((n, n)) < 0.05] = math.inf
        smooth_top = rng.random((n - 1, n - 1)) < 0.8
        smooth_bottom = rng.random((n - 1, n - 1)) < 0.8
        xyz = np.column_stack([rng.uniform(-0.6 * n * p, 0.6 * n * p, 20000),
                               rng.uniform(-0.6 * n * p, 0.6 * n * p, 20000),
                               rng.uniform(-3.0, 5.0, 20000)])
        args = (xyz, top, bottom, smooth_top, smooth_bottom, p, 1.5, 1e-6)
        got = interval_membership(*args)
        ref = _numpy_twin(*args)
        assert np.array_equal(got[0], ref[0]) and np.array_equal(got[1], ref[1])
        assert 0 < got[0].sum() < xyz.shape[0] and got[1].any()


def _cells_smooth_twin(a, limit):
    c = np.stack([a[:-1, :-1], a[1:, :-1], a[:-1, 1:], a[1:, 1:]])
    fin = np.isfinite(c)
    big = np.where(fin, c, -np.inf).max(axis=0)
    small = np.where(fin, c, np.inf).min(axis=0)
    with np.errstate(invalid="ignore"):
        span = big - small
    same_inf = (~fin).all(axis=0) & (c == c[0]).all(axis=0)
    return (fin.all(axis=0) & (span <= limit)) | same_inf


def test_cells_smooth_equals_its_numpy_twin():
    from errpred._interval_kernels import cells_smooth

    rng = np.random.default_rng(6)
    for _ in range(5):
        a = rng.normal(0.0, 0.3, (30, 30))
        a[rng.random((30, 30)) < 0.15] = math.inf
        a[rng.random((30, 30)) < 0.05] = -math.inf
        a[:8, :8] = math.inf
        got, ref = cells_smooth(a, 0.25), _cells_smooth_twin(a, 0.25)
        assert np.array_equal(got, ref) and got.any() and not got.all()


def test_box_membership_equals_its_numpy_twin():
    """The box stock's test (``BottomTemplate.in_stock_local``): the kernel answers as the
    numpy expression it replaced (world points by a matrix product, then the grown box),
    on tilted frames, with points spread around every face and half the growth either
    side of the grown faces."""
    rng = np.random.default_rng(11)
    lo, hi, e = np.array([-3.9, -3.9, -9.95]), np.array([61.1, 61.05, 0.0]), 1e-6
    for trial in range(6):
        axis = rng.normal(size=3) * [0.3, 0.3, 1.0]
        axis /= np.linalg.norm(axis)
        frame = tool_frame(axis, rng.normal(size=3), 1)
        tip = rng.uniform(lo, hi)
        xyz = rng.uniform(-40.0, 40.0, (20000, 3))
        world = tip + xyz @ frame
        # a quarter moved onto a grown face, half its growth in or out along its normal
        # (a kernel that left the growth out, or grew the box twice, answers otherwise)
        k = 5000
        face = rng.integers(0, 3, k)
        side = rng.integers(0, 2, k)
        off = rng.choice([-0.5 * e, 0.5 * e], k)
        target = np.where(side == 1, hi[face] + e, lo[face] - e) + off * np.where(side, 1, -1)
        world[np.arange(k), face] = target
        xyz[:k] = (world[:k] - tip) @ frame.T
        twin = np.all(((tip + xyz @ frame) >= lo - e) & ((tip + xyz @ frame) <= hi + e), axis=1)
        got = box_membership(xyz, tip, frame, lo, hi, e)
        assert np.array_equal(got, twin)
        assert 0 < got.sum() < xyz.shape[0]
