"""Sweep membership kernels and the sweep index, against brute force."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nc.path import CutterLocations
from errpred._cluster_kernels import inside_any_sweep_clustered, sweep_margin_clustered
from errpred._kernels import (inside_any_sweep, sweep_distance, sweep_lower_bound, sweep_within,
                              sweeps_within)
from errpred.sweeps import build_sweeps
from errpred.tool import Tool, core_distance

finite = dict(allow_nan=False, allow_infinity=False)
coord = st.floats(-6, 6, **finite)


def brute(q, p0, d, w, c, r, top):
    """Distance to the swept core by dense sampling along the move."""
    s = np.linspace(0.0, 1.0, 4001)[:, None]
    v = q[None, :] - (p0[None, :] + s * d[None, :])
    h = v @ w
    rho = np.linalg.norm(v - h[:, None] * w[None, :], axis=1)
    dr = np.maximum(rho - c, 0.0)
    dz = np.maximum(np.maximum(r - h, h - top), 0.0)
    return float(np.hypot(dr, dz).min())


@settings(max_examples=300)
@given(q=st.tuples(coord, coord, coord), d=st.tuples(coord, coord, st.floats(-2, 2, **finite)),
       tilt=st.floats(0, 1.2, **finite), az=st.floats(0, 6.3, **finite),
       kind=st.sampled_from([(0.0, 5.0), (4.0, 1.0), (5.0, 0.0), (2.5, 2.5)]))
def test_sweep_distance_matches_brute_force(q, d, tilt, az, kind):
    c, r = kind
    top = 12.0
    q, d = np.array(q), np.array(d)
    w = np.array([math.sin(tilt) * math.cos(az), math.sin(tilt) * math.sin(az), math.cos(tilt)])
    p0 = np.zeros(3)
    got = sweep_distance(q[0], q[1], q[2], p0, d, w, c, r, top)
    ref = brute(q, p0, d, w, c, r, top)
    # the brute force samples s on a grid: its minimum is above the true one by at
    # most the grid's half step times |d| (the distance is 1-Lipschitz in s |d|)
    assert ref - 0.5 * np.linalg.norm(d) / 4000 - 1e-9 <= got <= ref + 1e-7


def test_single_tool_position_is_the_tool_solid():
    """A zero-length sweep is the tool itself: inside iff core distance <= r."""
    rng = np.random.default_rng(4)
    for tool in (Tool("ball", 10), Tool("radius", 10, 1.5), Tool("flat", 10)):
        pts = rng.uniform([-6, -6, -1], [6, 6, 8], (4000, 3))
        w = np.array([0.0, 0.0, 1.0])
        inside = np.array([sweep_distance(*p, np.zeros(3), np.zeros(3), w, tool.core_radius_mm,
                                          tool.corner_radius_mm, tool.flute_length_mm)
                           <= tool.corner_radius_mm + 1e-9 for p in pts])
        rho = np.hypot(pts[:, 0], pts[:, 1])
        below_top = pts[:, 2] <= tool.flute_length_mm
        env = tool.envelope_z(rho)
        expected = (rho <= tool.radius_mm) & (pts[:, 2] >= env) & below_top
        ok = np.abs(core_distance(rho, pts[:, 2], tool.core_radius_mm, tool.corner_radius_mm)
                    - tool.corner_radius_mm) > 1e-6  # away from the boundary
        assert np.array_equal(inside[ok], expected[ok])


def test_clustered_kernels_equal_the_plain_ones():
    rng = np.random.default_rng(9)
    n = 300
    p0 = np.column_stack([rng.uniform(-10, 10, n), rng.uniform(-10, 10, n), rng.uniform(-1, 1, n)])
    d = np.column_stack([rng.uniform(-2, 2, n), rng.uniform(-2, 2, n), rng.uniform(-.2, .2, n)])
    w = np.tile([0.0, 0.0, 1.0], (n, 1))
    lo = np.minimum(p0, p0 + d) - 6
    hi = np.maximum(p0, p0 + d) + 6
    hi[:, 2] += 12
    pts = rng.uniform([-4, -4, -1.5], [4, 4, 1], (3000, 3))
    cand = rng.uniform(size=3000) < 0.8
    for c, r in ((0.0, 5.0), (4.0, 1.0), (5.0, 0.0)):
        a = inside_any_sweep(pts, cand, p0, d, w, lo, hi, c, r, 12.0, 1e-6)
        b = inside_any_sweep_clustered(pts, cand, p0, d, w, lo, hi, c, r, 12.0, 1e-6, 0.5)
        assert np.array_equal(a, b) and not a[~cand].any()
        floor = -0.2
        m = sweep_margin_clustered(pts, cand, p0, d, w, lo, hi, c, r, 12.0, floor, 0.5)
        sel = np.flatnonzero(cand)[:200]
        for i in sel:
            dmin = min(sweep_distance(*pts[i], p0[j], d[j], w[j], c, r, 12.0) - r
                       for j in range(n))
            assert m[i] == pytest.approx(min(max(dmin, floor), -floor), abs=1e-9)
        # the margin's sign is the membership
        assert np.array_equal(m[cand] <= 1e-6, a[cand])


@pytest.mark.parametrize("tool", [Tool("ball", 10.0, flute_length_mm=20.0),
                                  Tool("radius", 10.0, 1.0, flute_length_mm=20.0)])
def test_membership_against_a_few_sweeps_is_each_point_against_each(tool):
    """Up to ``FEW_SWEEPS`` sweeps (the move the tool is on, past the height map) are
    tested point by point without binning; with one more they are binned. Either way
    a point is inside where some sweep holds it within the tolerance, on the sweeps'
    tight bounds too (points just below a tip, within the tolerance, count)."""
    from errpred.constants import FEW_SWEEPS

    rng = np.random.default_rng(5)
    tips = np.cumsum(np.vstack([[0.0, 0.0, 0.0], rng.normal(0, 0.4, (FEW_SWEEPS + 1, 3))]),
                     axis=0)
    axis = np.tile([0.0, 0.0, 1.0], (tips.shape[0], 1))
    sw = build_sweeps(CutterLocations.from_arrays(tips, axis, 1000.0, 8000.0), tool)
    c, r, top, eps = tool.core_radius_mm, tool.corner_radius_mm, tool.flute_length_mm, 1e-3
    # points around the tools' surfaces, and a few just below the tips
    pts = np.concatenate([
        tips[rng.integers(0, tips.shape[0], 3000)]
        + rng.normal(0, 1, (3000, 3)) * [tool.radius_mm, tool.radius_mm, 2.0],
        tips + [0.0, 0.0, -0.5 * eps]])
    cand = rng.uniform(size=pts.shape[0]) < 0.9
    cand[-tips.shape[0]:] = True
    for n in range(1, len(sw) + 1):
        assert (n <= FEW_SWEEPS) == (n < len(sw))   # both paths, the last binned
        p0, d, w, lo, hi = (a[:n] for a in (sw.p0, sw.d, sw.w, sw.lo, sw.hi))
        got = inside_any_sweep_clustered(pts, cand, p0, d, w, lo, hi, c, r, top, eps, 0.2)
        want = np.array([bool(cand[i]) and any(
            sweep_within(*pts[i], p0[j], d[j], w[j], c, r, top, r + eps) for j in range(n))
            for i in range(pts.shape[0])])
        assert np.array_equal(got, want)
        assert 0.1 < want[cand].mean() < 0.9 and want[-tips.shape[0]:][:n].all()


def test_index_query_is_a_superset_and_local():
    rng = np.random.default_rng(2)
    pts = np.cumsum(rng.normal(0, 0.6, (5000, 3)), axis=0)
    axis = np.tile([0.0, 0.0, 1.0], (5000, 1))
    cl = CutterLocations.from_arrays(pts, axis, 1000.0, 8000.0)
    sw = build_sweeps(cl, Tool("ball", 6))
    for _ in range(20):
        c = pts[rng.integers(len(pts))]
        lo, hi = c - 2.0, c + 2.0
        got = set(sw.query(lo, hi).tolist())
        brute_ids = set(np.flatnonzero(np.all((sw.lo <= hi) & (sw.hi >= lo), axis=1)).tolist())
        assert got == brute_ids
        assert len(got) < 0.2 * len(sw)
        # the same test on given ids, without the grid: the ids among them, in their order
        some = rng.permutation(len(sw))[:2000]
        assert sw.overlapping(some, lo, hi).tolist() == [j for j in some if j in brute_ids]


def test_clipping_to_path_intervals():
    tip = np.array([[0.0, 0, 0], [10.0, 0, 0], [10.0, 10.0, 0]])
    cl = CutterLocations.from_arrays(tip, [0.0, 0.0, 1.0], 1000.0, 8000.0)
    sw = build_sweeps(cl, Tool("ball", 6))
    ids = np.arange(len(sw))
    p0, d, *_ = sw.clipped(ids, 4.0, 15.0)
    np.testing.assert_allclose(p0, [[4.0, 0, 0], [10.0, 0, 0]])
    np.testing.assert_allclose(d, [[6.0, 0, 0], [0.0, 5.0, 0]])
    p0, d, *_ = sw.clipped(ids, -math.inf, 4.0)
    np.testing.assert_allclose(d, [[4.0, 0, 0]])


def _reference_near(sw, lo, hi, centre, reach, order_from, t1_end, t2_start):
    """Sweeps.near composed from its parts in numpy (query, prune unless the reach is
    infinite, order, clip)."""
    ids = sw.query(lo, hi)
    if math.isfinite(reach):
        keep = np.array([_may_reach_brute(sw, j, centre, reach) for j in ids], dtype=bool)
        ids = ids[keep] if ids.size else ids
    mid = sw.p0[ids] + 0.5 * sw.d[ids]
    ids = ids[np.argsort(np.sum((mid - order_from) ** 2, axis=1), kind="stable")]
    return sw.clipped(ids, -math.inf, t1_end), sw.clipped(ids, t2_start, math.inf)


def _may_reach_brute(sw, j, centre, reach):
    return bool(sweeps_within(np.array([j]), *centre, reach, sw.p0, sw.d, sw.w, sw.lo, sw.hi,
                              sw.core_radius_mm, sw.corner_radius_mm, sw.top_mm)[0])


def test_near_is_query_prune_order_and_clip():
    rng = np.random.default_rng(12)
    pts = np.cumsum(rng.normal(0, 0.6, (3000, 3)), axis=0)
    axis = np.tile([0.0, 0.0, 1.0], (3000, 1))
    cl = CutterLocations.from_arrays(pts, axis, 1000.0, 8000.0)
    for tool in (Tool("ball", 6), Tool("radius", 8, 1.0)):
        sw = build_sweeps(cl, tool)
        for _ in range(10):
            k = int(rng.integers(len(pts)))
            c = pts[k]
            lo, hi = c - 3.0, c + 3.0
            L = float(sw.path_end[min(k, len(sw) - 1)])
            *got, ids = sw.near(lo, hi, c + [0, 0, 1.0], 4.0, c, L - 0.05, L + 0.05)
            ref = _reference_near(sw, lo, hi, c + [0, 0, 1.0], 4.0, c, L - 0.05, L + 0.05)
            for g, r in zip(got, ref, strict=True):
                for a, b in zip(g, r, strict=True):
                    assert a.shape == b.shape and np.array_equal(a, b)


def test_near_orders_equal_distances_by_id():
    """A path back and forth over the same few segments: many sweeps share a middle, so
    their distances are equal; :meth:`Sweeps.near` (numpy's sort, not a stable one)
    gives them in the order of their ids, as the stable sort of the sorted ids does,
    with and without the reach test and from a shared look-up."""
    rng = np.random.default_rng(8)
    corners = np.array([[0.0, 0, 0], [2.0, 0, 0], [2.0, 1.5, 0], [0.0, 1.5, 0.5]])
    pts = corners[rng.integers(0, 4, 400)]
    pts = pts[np.r_[True, np.any(pts[1:] != pts[:-1], axis=1)]]   # no zero-length moves
    cl = CutterLocations.from_arrays(pts, [0.0, 0.0, 1.0], 1000.0, 8000.0)
    sw = build_sweeps(cl, Tool("ball", 6))
    mid = sw.p0 + 0.5 * sw.d
    assert np.unique(mid, axis=0).shape[0] < len(sw) // 10   # ties everywhere
    c = np.array([1.0, 0.7, 0.2])
    L = float(sw.path_end[len(sw) // 2])
    for reach in (math.inf, 6.0):
        args = (c - 2.0, c + 2.0, c, reach, c + [0.3, 0.1, 0.0], L - 0.1, L + 0.1)
        ref = _reference_near(sw, *args)
        got = sw.near(*args)
        shared = sw.near(*args, within=sw.query(c - 3.0, c + 3.0))
        ids = sw.query(c - 2.0, c + 2.0)
        ids = ids[np.argsort(np.sum((mid[ids] - args[4]) ** 2, axis=1), kind="stable")]
        if math.isfinite(reach):
            ids = ids[[_may_reach_brute(sw, j, c, reach) for j in ids]]
        ids1 = ids[sw.path_start[ids] < L - 0.1]     # the sweeps T1 keeps a part of
        for g in (got, shared):
            for x, y in zip((*g[0], *g[1]), (*ref[0], *ref[1]), strict=True):
                assert np.array_equal(x, y)
            assert np.array_equal(g[2], ids1)


def test_sweeps_left_out_reach_no_point_of_the_ball():
    """sweeps_within is a safe pruning: a sweep it drops has no point of the ball within
    reach - radius (checked by the exact distance at random points in the ball)."""
    rng = np.random.default_rng(3)
    n = 400
    p0 = rng.uniform(-15, 15, (n, 3))
    d = rng.uniform(-3, 3, (n, 3))
    w = rng.normal(size=(n, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    for c, r in ((0.0, 3.0), (2.0, 1.0), (3.0, 0.0)):
        top = 10.0
        lo = np.minimum(p0, p0 + d) - (c + r) - top
        hi = np.maximum(p0, p0 + d) + (c + r) + top
        centre, ball, margin = np.zeros(3), 4.0, 0.3
        keep = sweeps_within(np.arange(n), *centre, ball + margin, p0, d, w, lo, hi, c, r, top)
        assert 0 < keep.sum() < n
        q = rng.normal(size=(3000, 3))
        q *= (ball * rng.uniform(size=3000) ** (1 / 3) / np.linalg.norm(q, axis=1))[:, None]
        for j in np.flatnonzero(~keep):
            dist = min(sweep_distance(*x, p0[j], d[j], w[j], c, r, top) for x in q[:300])
            assert dist - r > margin - 1e-9


@settings(max_examples=300)
@given(q=st.tuples(coord, coord, coord), d=st.tuples(coord, coord, st.floats(-2, 2, **finite)),
       tilt=st.floats(0, 1.2, **finite), az=st.floats(0, 6.3, **finite),
       kind=st.sampled_from([(0.0, 5.0), (4.0, 1.0), (5.0, 0.0), (2.5, 2.5)]),
       slack=st.floats(-0.5, 0.5, **finite))
def test_sweep_within_answers_as_the_distance(q, d, tilt, az, kind, slack):
    """The early-answer membership test agrees with the distance it shortcuts, and the
    closed-form lower bound is one."""
    c, r = kind
    top = 12.0
    q, d = np.array(q), np.array(d)
    w = np.array([math.sin(tilt) * math.cos(az), math.sin(tilt) * math.sin(az), math.cos(tilt)])
    p0 = np.array([0.3, -0.2, 0.1])
    dist = sweep_distance(q[0], q[1], q[2], p0, d, w, c, r, top)
    assert sweep_lower_bound(q[0], q[1], q[2], p0, d, w, c, r, top) <= dist + 1e-12
    for lim in (r + 1e-6, dist + slack, dist - 1e-9, dist + 1e-9):
        # (at exactly the distance, rounding of the lower bound may answer either way)
        assert sweep_within(q[0], q[1], q[2], p0, d, w, c, r, top, lim) == (dist <= lim)


def test_clustered_kernels_equal_the_plain_ones_on_a_finishing_raster():
    """Points around a ball end mill inside a dense raster of earlier passes (the move
    just behind the tool holds most of them): the clustered kernels, with their first
    pass against one likely sweep, answer as the plain test and the brute-force margin."""
    tool = Tool("ball", 6)
    xs = np.arange(0.0, 20.0, 0.5)
    rows = []
    for k, y in enumerate(np.arange(-3.0, 3.01, 0.35)):
        line = xs if k % 2 == 0 else xs[::-1]
        rows.append(np.column_stack([line, np.full(line.size, y), 0.01 * line]))
    tip = np.vstack(rows)
    cl = CutterLocations.from_arrays(tip, [0.0, 0.0, 1.0], 1000.0, 8000.0)
    sw = build_sweeps(cl, tool)
    centre = tip[-5]
    L = float(sw.path_end[-5])
    t1, _, _ = sw.near(centre - 4, centre + 4, centre + [0, 0, 3], 8.0, centre + [0, 0, 3],
                       L - 0.05, L + 0.05)
    rng = np.random.default_rng(21)
    pts = centre + rng.uniform([-3, -3, -0.2], [3, 3, 3], (4000, 3))
    cand = rng.uniform(size=4000) < 0.9
    c, r, top = tool.core_radius_mm, tool.corner_radius_mm, tool.flute_length_mm
    a = inside_any_sweep(pts, cand, *t1, c, r, top, 1e-6)
    b = inside_any_sweep_clustered(pts, cand, *t1, c, r, top, 1e-6, 0.2)
    assert np.array_equal(a, b) and 0.2 < a[cand].mean() < 0.98
    floor = -0.05
    m = sweep_margin_clustered(pts, cand, *t1, c, r, top, floor, 0.2)
    for i in np.flatnonzero(cand)[:300]:
        dmin = min(sweep_distance(*pts[i], t1[0][j], t1[1][j], t1[2][j], c, r, top) - r
                   for j in range(t1[0].shape[0]))
        assert m[i] == pytest.approx(min(max(dmin, floor), -floor), abs=1e-12)
    assert np.all(m[~cand] == floor)


def _split_bound_twin(q, p0, d, w, c, r, top):
    """numpy twin of ``errpred._kernels._split_bound`` (points q: (k, 3))."""
    v = q - p0
    h0 = v @ w
    dw = d[0] * w[0] + d[1] * w[1] + d[2] * w[2]
    e = v - h0[:, None] * w
    dp = d - dw * w
    qq = float(dp @ dp)
    t = np.clip((e @ dp) / qq, 0.0, 1.0) if qq > 0 else np.zeros(len(q))
    a = np.maximum(np.linalg.norm(e - t[:, None] * dp, axis=1) - c, 0.0)
    hlo, hhi = np.minimum(h0, h0 - dw), np.maximum(h0, h0 - dw)
    b = np.where(hhi < r, r - hhi, np.where(hlo > top, hlo - top, 0.0))
    return np.hypot(a, b), dw == 0.0


def test_split_bound_equals_its_twin_bounds_the_distance_and_is_it_square_to_the_axis():
    """The radial/axial lower bound of the swept core's distance (tools with c > 0): the
    kernel equals its numpy twin, never exceeds the distance, is the distance for a move
    square to the axis (then sweep_within answers without the search), and is often far
    tighter than the axis-strip bound there."""
    from errpred._kernels import _split_bound
    rng = np.random.default_rng(8)
    top = 10.0
    tighter = 0
    for c, r in ((9.0, 1.0), (4.0, 1.0), (5.0, 0.0), (2.5, 2.5)):
        for square in (True, False):
            for _ in range(40):
                a, b, g = rng.uniform(-4, 4, 3)
                if square:
                    # square to the axis exactly (the products cancel in floating point)
                    w, d = [(np.array([0.0, 0.0, 1.0]), np.array([a, b, 0.0])),
                            (np.array([0.0, 0.6, 0.8]), np.array([a, 0.8, -0.6])),
                            (np.array([1.0, 0.0, 0.0]), np.array([0.0, a, b]))][_ % 3]
                else:
                    w = rng.normal(size=3)
                    w /= np.linalg.norm(w)
                    d = np.array([a, b, g])
                p0 = rng.uniform(-1, 1, 3)
                q = rng.uniform(-15, 15, (25, 3))
                twin, exact_twin = _split_bound_twin(q, p0, d, w, c, r, top)
                for k in range(q.shape[0]):
                    got, exact = _split_bound(*q[k], *p0, *d, *w, c, r, top)
                    assert got == pytest.approx(twin[k], rel=1e-12, abs=1e-12)
                    assert exact == exact_twin == square
                    dist = sweep_distance(*q[k], p0, d, w, c, r, top)
                    assert got <= dist + 1e-9
                    lb = sweep_lower_bound(*q[k], p0, d, w, c, r, top)
                    assert got <= lb + 1e-12 and lb <= dist + 1e-9
                    if exact:
                        assert got == pytest.approx(dist, abs=1e-7)
                        for lim in (dist - 1e-6, dist + 1e-6, r + 1e-6):
                            assert sweep_within(*q[k], p0, d, w, c, r, top, lim) == (dist <= lim)
                        strip = _dist_strip_bound(q[k], p0, d, w, c, r, top)
                        tighter += got > strip + 1e-6
    assert tighter > 100


def _dist_strip_bound(q, p0, d, w, c, r, top):
    """The axis-strip bound alone (the swept axis's distance minus c)."""
    from errpred._kernels import _dist_half_strip
    a = q - (p0 + r * w)
    return _dist_half_strip(*a, *d, *w, top - r) - c


def test_shortlists_are_each_bin_tested_alone():
    """The per-bin short lists (with the Lipschitz shortcuts between the levels: all
    points, super cube, coarse cube, bin) are, in order, the sweeps that pass the
    reach test against the bin's own sphere."""
    from errpred._cluster_kernels import _bins, _shortlists
    from errpred._kernels import _may_reach, _sphere
    rng = np.random.default_rng(12)
    n = 300
    p0 = rng.uniform(-6, 6, (n, 3))
    d = rng.uniform(-2, 2, (n, 3))
    w = rng.normal(size=(n, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    w[::3] = [0.0, 0.0, 1.0]
    d[::3, 2] = 0.0  # square to the axis: the radial/axial bound is exact there
    pts = rng.uniform(-3, 3, (1500, 3))
    for c, r in ((0.0, 3.0), (4.0, 1.0), (2.0, 2.0)):
        top = 8.0
        lo = np.minimum(p0, p0 + d) - (c + r) - top
        hi = np.maximum(p0, p0 + d) + (c + r) + top
        # 0.4 mm bins: one super cube; 0.1 mm: several, and several coarse cubes in each
        for reach, cell in ((1e-6, 0.4), (0.3, 0.4), (1e-6, 0.1)):
            idx, order, keys, m = _bins(pts, np.ones(len(pts), dtype=np.bool_), cell)
            starts, offsets, lists, nb = _shortlists(pts, idx, order, keys, m, p0, d, w, lo,
                                                     hi, c, r, top, reach,
                                                     np.zeros(0, dtype=np.bool_),
                                                     np.zeros(0))
            sizes = []
            for b in range(nb):
                cx, cy, cz, rad = _sphere(pts, idx, order, starts[b], starts[b + 1])
                ref = [j for j in range(n)
                       if _may_reach(j, cx, cy, cz, reach + rad, p0, d, w, lo, hi, c, r, top)]
                assert lists[offsets[b]:offsets[b + 1]].tolist() == ref
                sizes.append(len(ref))
            assert 0 < np.mean(sizes) < n


@pytest.mark.parametrize("tilted", [False, True])
def test_clustered_membership_over_many_cubes_equals_the_full_list(tilted):
    """Points spread over many super and coarse cubes (bins of 0.1 mm), most of them
    inside earlier passes: each bin's points go first against the sweeps that held
    the bins' before, the rest against their short list; the answers are those of
    every point tested against every sweep (:func:`inside_any_sweep`)."""
    rng = np.random.default_rng(31)
    # a raster of passes 0.8 mm apart at slowly falling depths, in pieces
    rows = []
    for k in range(25):
        y = -10 + 0.8 * k
        xs = np.linspace(-10, 10, 9)
        for a, b in zip(xs[:-1], xs[1:]):
            rows.append(([a, y, -0.05 * k], [b - a, 0.0, rng.uniform(-0.05, 0.05)]))
    p0 = np.array([r[0] for r in rows])
    d = np.array([r[1] for r in rows])
    n = p0.shape[0]
    w = np.tile([0.0, 0.0, 1.0], (n, 1))
    if tilted:
        w = w + rng.normal(0, 0.15, (n, 3))
        w /= np.linalg.norm(w, axis=1, keepdims=True)
    pts = rng.uniform([-9, -14, -1.5], [9, 14, 2.0], (6000, 3))  # some beyond the passes
    cand = rng.uniform(size=pts.shape[0]) < 0.9
    for c, r in ((0.0, 3.0), (2.0, 1.0), (3.0, 0.0)):
        top = 10.0
        lo = np.minimum(p0, p0 + d) - (c + r) - top
        hi = np.maximum(p0, p0 + d) + (c + r) + top
        full = inside_any_sweep(pts, cand, p0, d, w, lo, hi, c, r, top, 1e-6)
        assert 0.2 < full[cand].mean() < 0.95  # both answers, many of each
        for cell in (0.1, 0.2, 0.5):
            got = inside_any_sweep_clustered(pts, cand, p0, d, w, lo, hi, c, r, top, 1e-6, cell)
            assert np.array_equal(got, full)


@pytest.mark.parametrize("tilting", [False, True])
def test_block_lookup_gives_near_the_same_sweeps(tilting):
    """Positions along a run of cutter locations: :meth:`Sweeps.near` from the block's
    shared look-up (:class:`BlockLookup`) returns the same arrays as with its own grid
    look-up; with a constant axis every position is inside the shared box, a position
    outside it (the axis turning a lot) gets None (its own look-up). A look-up grown
    for the blocks after it gives the positions of a later block it holds the same
    arrays too."""
    from errpred.sweeps import BlockLookup
    rng = np.random.default_rng(5)
    n = 2500
    pts = np.cumsum(rng.normal(0, 0.5, (n, 3)), axis=0)
    pts[:, 2] *= 0.2
    axis = np.tile([0.0, 0.0, 1.0], (n, 1))
    if tilting:
        axis = axis + rng.normal(0, 0.2, (n, 3))
        axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    cl = CutterLocations.from_arrays(pts, axis, 1000.0, 8000.0)
    tool = Tool("radius", 6, 1.0)
    sw = build_sweeps(cl, tool)
    R, height, margin = tool.radius_mm, tool.flute_length_mm + tool.corner_radius_mm, 0.1
    path = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))]
    used = inside = held = 0
    for k in rng.integers(200, n - 10, 30):
        i0, i1 = int(k), int(k) + 3
        shared = BlockLookup(sw, pts[i0 - 1:i1 + 1], axis[i0 - 1:i1 + 1], R, height, margin,
                             1e9)
        if k % 2:   # a look-up grown for the blocks after it, used by the next block
            grown = BlockLookup(sw, pts[i0 - 4:i0], axis[i0 - 4:i0], R, height, margin, 1e9,
                                grow=2.0)
            inside_box = bool(np.all(shared.own_lo >= grown.own_lo - 2.0)
                              and np.all(shared.own_hi <= grown.own_hi + 2.0))
            assert grown.holds(grown) and grown.holds(shared) == inside_box
            if not inside_box:
                continue
            shared = grown
            held += 1
        for s in range(i0, i1 + 1):
            for t in (0.0, 0.3, 0.5, 1.0):
                tip = pts[s - 1] + t * (pts[s] - pts[s - 1])
                u = (1 - t) * axis[s - 1] + t * axis[s]
                u /= np.linalg.norm(u)
                h = rng.uniform(0.3, 1.0) * height
                top = tip + h * u
                ext = R * np.sqrt(np.clip(1 - u * u, 0, None)) + margin
                lo, hi = np.minimum(tip, top) - ext, np.maximum(tip, top) + ext
                ids = shared.ids_for(lo, hi)
                used += 1
                if ids is None:
                    continue
                inside += 1
                L = path[s - 1] + t * (path[s] - path[s - 1])
                args = (lo, hi, tip + 0.5 * h * u, R + 1.0, tip + R * u, L - 0.01, L + 0.01)
                a, b = sw.near(*args), sw.near(*args, within=ids)
                for x, y in zip((*a[0], *a[1], a[2]), (*b[0], *b[1], b[2])):
                    assert np.array_equal(x, y)
    assert inside == used if not tilting else 0 < inside <= used
    assert held >= 3
    # an axis turning by 74 deg between two cutter locations: the tool's top halfway
    # (the axis vertical there) rises above the box of both ends: its own look-up
    a2 = np.array([[0.6, 0.0, 0.8], [-0.6, 0.0, 0.8]])
    t2 = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    turn = BlockLookup(sw, t2, a2, R, height, margin, 1e9)
    tip, top = np.array([0.5, 0.0, 0.0]), np.array([0.5, 0.0, height])
    inner = (t2[0] - 0.01, t2[0] + 0.01)
    assert turn.ids_for(*inner) is not None
    assert turn.ids_for(np.minimum(tip, top) - R - margin, np.maximum(tip, top) + margin) is None
    # a block spanning more than the limit has no shared look-up
    far = BlockLookup(sw, pts[100:400], axis[100:400], R, height, margin, 1.0)
    assert far.ids_for(pts[200] - 1, pts[200] + 1) is None


def test_the_hot_sweep_holds_the_most_of_the_candidates_sampled():
    """The clustered test's first pass picks, of the first sweeps, the one that holds
    the most of the candidates it samples (spread over them): not the first to hold
    one; among the candidates left after it, the next; -1 where none holds any."""
    from errpred._cluster_kernels import _hot_sweep

    # three parked ball end mills (no displacement) of radius 1 along x: sweep 0 holds
    # the points around x = 0 (a tenth), sweep 1 around x = 5 (six tenths), sweep 2
    # around x = 10 (three tenths)
    p0 = np.array([[0.0, 0, 0], [5.0, 0, 0], [10.0, 0, 0]])
    d = np.zeros((3, 3))
    w = np.tile([0.0, 0.0, 1.0], (3, 1))
    rng = np.random.default_rng(4)
    centres = np.repeat([0.0, 5.0, 10.0], [100, 600, 300])
    pts = np.column_stack([centres, np.zeros(1000), np.ones(1000)])
    pts += rng.uniform(-0.3, 0.3, pts.shape)
    order = rng.permutation(1000)
    pts = np.ascontiguousarray(pts[order])
    owner = (centres[order] / 5.0).astype(int)
    c, r, top, lim = 0.0, 1.0, 10.0, 1.0 + 1e-6
    every = np.ones(1000, dtype=np.bool_)
    assert _hot_sweep(pts, every, p0, d, w, c, r, top, lim, 16, 48, 0) == 1
    # sparse candidates: sampled among the candidates, not among all points
    rest = np.ascontiguousarray(owner != 1)
    assert _hot_sweep(pts, rest, p0, d, w, c, r, top, lim, 16, 48, 0) == 2
    assert _hot_sweep(pts, np.ascontiguousarray(owner == 0), p0, d, w, c, r, top, lim,
                      16, 48, 0) == 0
    # only the first n_sweeps sweeps are looked at
    assert _hot_sweep(pts, rest, p0, d, w, c, r, top, lim, 1, 48, 0) == 0
    far = np.ascontiguousarray(pts + [0.0, 50.0, 0.0])
    assert _hot_sweep(far, every, p0, d, w, c, r, top, lim, 16, 48, 0) == -1
    # enough = 1 (the margins' pass): the first sweep to hold a sampled point, the first
    # point first
    assert _hot_sweep(pts, every, p0, d, w, c, r, top, lim, 16, 4, 1) == owner[0]


@pytest.mark.parametrize("kernel", ["distance", "membership"])
def test_a_radius_tools_search_compiles_once_for_read_only_and_writable_sweeps(kernel):
    """``_search_distance`` and ``_search_within`` take the sweep as scalars: a read-only
    sweep (errpred's) and a writable one (orient's, built inside its kernels) reach one
    compiled version, with the same answer; no version takes an array (a row given to a
    kernel that is not inlined is made a view: its reference count cost more than the
    membership test itself)."""
    from numba import njit, types

    from errpred import _kernels

    if kernel == "distance":
        search, n_args = _kernels._search_distance, 15

        @njit
        def ask(p0, d, w):
            return sweep_distance(0.3, -0.2, 2.0, p0[0], d[0], w[0], 2.0, 1.0, 12.0)
    else:
        search, n_args = _kernels._search_within, 16

        @njit
        def ask(p0, d, w):
            return sweep_within(0.3, -0.2, 2.0, p0[0], d[0], w[0], 2.0, 1.0, 12.0, 1.0)

    # a move with an axial part (the point lies in the tool at the move's start)
    arrays = [np.array([[0.0, 0.0, 0.0]]), np.array([[1.5, 0.5, 0.4]]),
              np.array([[0.0, 0.0, 1.0]])]
    frozen = [a.copy() for a in arrays]
    for a in frozen:
        a.flags.writeable = False
    # other tests in this process may have compiled other versions (other callers' types)
    before = set(search.signatures)
    assert ask(*arrays) == ask(*frozen)
    assert len(ask.signatures) == 2          # the caller: one version for each
    sigs = search.signatures
    assert (types.float64,) * n_args in sigs
    assert len(set(sigs) - before) <= 1
    assert not any(isinstance(t, types.Array) for sig in sigs for t in sig)


def test_the_sweep_tests_scalar_helpers_are_inlined_by_llvm_not_by_numba():
    """The scalar helpers of the sweep tests are inlined where they are called, by LLVM
    (``forceinline``), not by numba (``inline="always"``): numba's inlining copies a
    callee's IR into every call site and runs its passes again there, which took 33 s
    of the prediction's 82 s of compiling on an empty cache; LLVM's gives the same
    answers (``benchmarks/check_geometry_same.py``: the same bytes). Fails where a helper
    is inlined by numba again, or where a caller keeps a call to it (the call would cost
    more than a ball end mill's closed form)."""
    from numba import njit

    from errpred import _kernels

    helpers = ("_core_dist", "_dist_half_strip", "_golden", "_strip_bound", "_split_bound")
    for helper in helpers:
        disp = getattr(_kernels, helper)
        assert disp.targetoptions.get("inline", "never") == "never", helper
        assert disp.targetoptions.get("forceinline") is True, helper

    @njit(cache=False)
    def ask(p0, d, w, x):
        # the sweep tests as the clustered kernels call them: a ball, a radius end mill
        return (sweep_distance(x, -0.2, 2.0, p0[0], d[0], w[0], 0.0, 3.0, 12.0)
                + sweep_distance(x, -0.2, 2.0, p0[0], d[0], w[0], 2.0, 1.0, 12.0)
                + sweep_lower_bound(x, -0.2, 2.0, p0[0], d[0], w[0], 2.0, 1.0, 12.0)
                + sweep_within(x, -0.2, 2.0, p0[0], d[0], w[0], 2.0, 1.0, 12.0, 1.0))

    p0, d, w = (np.array([[0.0, 0.0, 0.0]]), np.array([[1.5, 0.5, 0.4]]),
                np.array([[0.0, 0.0, 1.0]]))
    assert math.isfinite(ask(p0, d, w, 0.3))
    # the caller and its linked callees (_search_distance, _search_within): no call to
    # a helper is left in any of them (numba's mangled names hold a name's length first)
    llvm = [ln for ln in "\n".join(ask.inspect_llvm().values()).splitlines() if " call " in ln]
    for helper in helpers:
        calls = [ln for ln in llvm if f"{len(helper)}{helper}" in ln]
        assert not calls, (helper, calls[:2])
