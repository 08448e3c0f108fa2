"""The sweeps' height map: its bounds hold, its answers are the exact test's, and a
prediction with it is the prediction without it, bit for bit."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from nc import parse_program
from nc.path import CutterLocations
from errpred import constants as K
from errpred._kernels import inside_any_sweep
from errpred._zmap_kernels import FIELDS, PLANES, capsule_low
from errpred.predict import Predictor
from errpred.sweeps import build_sweeps
from errpred.tool import Tool
from errpred.zmap import SweepMap, sweep_map

from .cases import STEEL, plane_raster, plane_stock, stiff_tool


def _true_low(x, y, c0, d, rho, n=20001):
    """Lowest z within ``rho`` of the segment on the line through (x, y): dense in s,
    then a golden-section polish (the function is convex in s)."""
    s = np.linspace(0.0, 1.0, n)
    c = c0[None, :] + s[:, None] * d[None, :]
    h2 = rho * rho - (x - c[:, 0]) ** 2 - (y - c[:, 1]) ** 2
    if not (h2 >= 0).any():
        return math.inf

    def f(t):
        cc = c0 + t * d
        v = rho * rho - (x - cc[0]) ** 2 - (y - cc[1]) ** 2
        return cc[2] - math.sqrt(v) if v >= 0 else math.inf

    z = np.where(h2 >= 0, c[:, 2] - np.sqrt(np.clip(h2, 0, None)), np.inf)
    k = int(np.argmin(z))
    lo, hi = s[max(k - 1, 0)], s[min(k + 1, n - 1)]
    for _ in range(80):
        m1, m2 = lo + (hi - lo) * 0.382, lo + (hi - lo) * 0.618
        if f(m1) <= f(m2):
            hi = m2
        else:
            lo = m1
    return min(float(z[k]), f(0.5 * (lo + hi)))


def test_capsule_low_bounds_the_true_boundary_and_its_slopes():
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(300):
        c0 = rng.uniform(-2, 2, 3)
        d = rng.normal(size=3) * rng.choice([0.01, 0.5, 3.0])
        rho = rng.uniform(0.5, 5.0)
        x, y = c0[:2] + d[:2] * rng.uniform(-0.3, 1.3) + rng.uniform(-rho, rho, 2)
        true = _true_low(x, y, c0, d, rho)
        lo, gx, gy = capsule_low(x, y, *c0, *d, rho, -1)
        up = capsule_low(x, y, *c0, *d, rho, 1)[0]
        if math.isinf(true):
            assert math.isinf(up)
            continue
        assert lo <= true + 1e-12 and up >= true - 1e-12
        if math.isfinite(up):
            assert up - lo < 1e-4
            checked += 1
        if math.isfinite(gx):
            # the slopes are the tangent plane's: finite differences of the true boundary
            e = 1e-5
            fx = (_true_low(x + e, y, c0, d, rho) - _true_low(x - e, y, c0, d, rho)) / (2 * e)
            fy = (_true_low(x, y + e, c0, d, rho) - _true_low(x, y - e, c0, d, rho)) / (2 * e)
            assert gx == pytest.approx(fx, abs=2e-3 * (1 + abs(fx)))
            assert gy == pytest.approx(fy, abs=2e-3 * (1 + abs(fy)))
    assert checked > 150


def _wavy_raster(step=0.4, passes=25, length=12.0, seg=0.5):
    """Ball tips over a wavy surface: raster passes along x, stepping over in y."""
    pts = []
    for k in range(passes):
        y = -0.5 * passes * step + k * step
        xs = np.arange(0.0, length + 1e-9, seg)
        if k % 2:
            xs = xs[::-1]
        for x in xs:
            pts.append([x, y, 0.6 * math.sin(0.5 * x) + 0.3 * math.cos(0.7 * y)])
    pts = np.array(pts)
    return CutterLocations.from_arrays(pts, [0.0, 0.0, 1.0], 1000.0, 8000.0)


def _wavy(xy):
    """The wavy surface of :func:`_wavy_raster` at points ``xy`` (k, 2)."""
    return 0.6 * np.sin(0.5 * xy[:, 0]) + 0.3 * np.cos(0.7 * xy[:, 1])


def _exact_of(sw, tool, pts, ids):
    """The exact test of ``pts`` against sweeps ``ids``."""
    return inside_any_sweep(pts, np.ones(len(pts), dtype=np.bool_), sw.p0[ids], sw.d[ids],
                            sw.w[ids], sw.lo[ids] - 1.0, sw.hi[ids] + 1.0, 0.0,
                            tool.corner_radius_mm, tool.flute_length_mm, K.MEMBERSHIP_EPS_MM)


def _exact(sw, tool, pts, time):
    """The exact T1 test of ``pts`` against sweeps ``0 .. time - 1``."""
    return _exact_of(sw, tool, pts, np.arange(time))


def _near_wavy(rng, n):
    """``n`` points around the wavy surface (within 1e-4 to 1 mm of it, either side,
    and jittered by up to 0.05 mm), (n, 3)."""
    xy = rng.uniform([0.0, -5.0], [12.0, 5.0], (n, 2))
    dz = rng.choice([1e-4, 1e-3, 1e-2, 0.1, 1.0], n) * rng.choice([-1, 1], n)
    return np.column_stack([xy, _wavy(xy) + dz + rng.uniform(-0.05, 0.05, n)])


def _classify_twin(points, vals, tile_index, origin, cell, size, guard):
    """numpy twin of :func:`errpred._zmap_kernels.classify`."""
    out = np.zeros(points.shape[0], dtype=np.int8)
    fx = (points[:, 0] - origin[0]) / cell
    fy = (points[:, 1] - origin[1]) / cell
    tx, ty = tile_index.shape
    ok = (fx >= 0) & (fx < tx * size) & (fy >= 0) & (fy < ty * size)
    ix = np.where(ok, fx, 0).astype(np.int64)
    iy = np.where(ok, fy, 0).astype(np.int64)
    s = np.where(ok, tile_index[ix // size, iy // size], -1)
    ok &= s >= 0
    v = vals[np.where(ok, s, 0), ix % size, iy % size]
    u, w = fx - ix, fy - iy
    z = points[:, 2]
    up = ((1 - u) * (1 - w) * v[:, 0] + u * (1 - w) * v[:, 1] + (1 - u) * w * v[:, 2]
          + u * w * v[:, 3])
    with np.errstate(invalid="ignore"):
        inside = (up + guard <= z) & (z <= v[:, 4] - guard)
        below = z < v[:, 5] - guard
        for f in range(6, 9 + 3 * PLANES, 3):
            lo = v[:, f] + v[:, f + 1] * (u - 0.5) * cell + v[:, f + 2] * (w - 0.5) * cell
            below &= ~(lo <= z + guard)
    out[ok & inside] = 1
    out[ok & ~inside & below] = -1
    return out


@pytest.mark.parametrize("cell", [0.1, 0.25])
def test_map_answers_are_the_exact_tests_and_most_are_answered(cell):
    tool = Tool("ball", 6.0, flute_length_mm=12.0)
    cl = _wavy_raster()
    sw = build_sweeps(cl, tool)
    zmap = SweepMap(sw, tool, cell_mm=cell)
    rng = np.random.default_rng(5)
    decided = total = 0
    for frac in (0.3, 0.6, 0.95):
        time = int(frac * len(sw))
        t1_end = float(sw.path_end[time - 1])
        # points around the envelope of what is cut so far, some far off it
        pts = _near_wavy(rng, 6000)
        state = zmap.classify(pts, t1_end)
        assert zmap.time == time
        exact = _exact(sw, tool, pts, time)
        assert not (state[exact] == -1).any()
        assert not (state[~exact] == 1).any()
        twin = _classify_twin(pts, zmap._vals, zmap.tile_index, zmap.origin, zmap.cell,
                              zmap.size, K.ZMAP_GUARD_MM)
        assert np.array_equal(twin, state)
        decided += int((state != 0).sum())
        total += len(pts)
    assert decided > 0.6 * total
    assert zmap._vals.shape[-1] == FIELDS


def test_map_going_back_restores_its_first_state():
    tool = Tool("ball", 6.0, flute_length_mm=12.0)
    sw = build_sweeps(_wavy_raster(), tool)
    zmap = SweepMap(sw, tool)
    pts = np.array([[6.0, 0.0, 0.0], [3.0, 1.0, 0.5]])
    first = zmap.classify(pts, float(sw.path_end[200]))
    kept = {key: zmap._vals[slot].copy() for key, slot in enumerate(zmap.tile_index.ravel())
            if slot >= 0}
    zmap.classify(pts, float(sw.path_end[400]))
    again = zmap.classify(pts, float(sw.path_end[200]))   # back: the kept state
    assert zmap.time == 201 and np.array_equal(first, again)
    now = {key: zmap._vals[slot] for key, slot in enumerate(zmap.tile_index.ravel())
           if slot >= 0}
    assert now.keys() == kept.keys()
    assert all(np.array_equal(now[k], kept[k]) for k in kept)
    zmap.classify(pts, float(sw.path_end[50]))            # before it: started again
    assert zmap.time == 51


def test_map_applies_to_ball_end_milling_along_an_axis_most_sweeps_have():
    cl = _wavy_raster(passes=3)
    ball = Tool("ball", 6.0)
    vertical = sweep_map(build_sweeps(cl, ball), ball)
    assert vertical is not None and vertical.frame is None and vertical.all_held
    bull = Tool("radius", 6.0, 1.0)
    assert sweep_map(build_sweeps(cl, bull), bull) is None
    # a 3+2 program: one tilted axis throughout, held in a frame whose z is that axis
    axis = np.array([0.0, math.sin(0.1), math.cos(0.1)])
    tilted = CutterLocations.from_arrays(cl.tip, axis, 1000.0, 8000.0)
    zmap = sweep_map(build_sweeps(tilted, ball), ball)
    assert zmap is not None and zmap.all_held
    np.testing.assert_allclose(zmap.frame[2], axis, atol=1e-15)
    np.testing.assert_allclose(zmap.frame @ zmap.frame.T, np.eye(3), atol=1e-15)
    # an axis that turns along the passes: no axis held by most sweeps, no map
    turning = np.column_stack([np.zeros(len(cl)), np.sin(np.linspace(0, 0.3, len(cl))),
                               np.cos(np.linspace(0, 0.3, len(cl)))])
    five = CutterLocations.from_arrays(cl.tip, turning, 1000.0, 8000.0)
    assert sweep_map(build_sweeps(five, ball), ball) is None


def _rotation(a: float, b: float) -> np.ndarray:
    """A rotation about x by ``a`` then about y by ``b`` [rad]."""
    ca, sa, cb, sb = math.cos(a), math.sin(a), math.cos(b), math.sin(b)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, ca, -sa], [0.0, sa, ca]])
    ry = np.array([[cb, 0.0, sb], [0.0, 1.0, 0.0], [-sb, 0.0, cb]])
    return ry @ rx


@pytest.mark.parametrize("mixed", [False, True], ids=["3+2", "mostly-3+2"])
def test_a_tilted_map_answers_as_the_exact_test_of_t1(mixed):
    """The wavy raster turned as a whole (a 3+2 program: the tool tilted by 30 and 20
    deg): the map, in the frame of the tilted axis, gives the exact test's answers, and
    most of them. With some sweeps of another axis among them (every 25th cutter
    location's tool turned by a further 2 deg: 83 % of the sweeps keep the tilted
    axis), those are not in the map: the point's T1 test
    (:class:`errpred.t1memo.RemovedMemo`) tests them exactly, and still answers as the
    exact test of every sweep."""
    from errpred._cluster_kernels import read_only
    from errpred.t1memo import RemovedMemo

    tool = Tool("ball", 6.0, flute_length_mm=12.0)
    cl = _wavy_raster()
    rot = _rotation(math.radians(30.0), math.radians(20.0))
    axis = np.tile(rot @ np.array([0.0, 0.0, 1.0]), (len(cl), 1))
    if mixed:
        axis[::25] = rot @ np.array([0.0, math.sin(math.radians(2.0)),
                                     math.cos(math.radians(2.0))])
    turned = CutterLocations.from_arrays(cl.tip @ rot.T, axis, 1000.0, 8000.0)
    sw = build_sweeps(turned, tool)
    zmap = sweep_map(sw, tool)
    assert zmap is not None and zmap.frame is not None and zmap.all_held == (not mixed)
    rng = np.random.default_rng(11)
    decided = total = 0
    for frac in (0.3, 0.6, 0.95):
        time = int(frac * len(sw))
        t1_end = float(sw.path_end[time - 1])
        pts = np.ascontiguousarray(_near_wavy(rng, 4000) @ rot.T)
        exact = _exact(sw, tool, pts, time)
        state = zmap.classify(pts, t1_end)
        held = zmap.holds(np.arange(len(sw)))
        assert held.sum() == (sw.w[:time] == axis[-1]).all(axis=1).sum()
        # the map's answers: inside a held sweep, or below every held one
        in_held = _exact_of(sw, tool, pts, np.flatnonzero(held))
        assert not (state[in_held] == -1).any()
        assert not (state[~in_held] == 1).any()
        ids = np.arange(time)
        t1 = read_only(*(np.ascontiguousarray(a[ids]) for a in (sw.p0, sw.d, sw.w, sw.lo,
                                                                   sw.hi)))
        memo = RemovedMemo(tool, t1, zmap, t1_end, ids)
        assert np.array_equal(memo.test(pts), exact)
        decided += int((state != 0).sum())
        total += len(pts)
    assert decided > 0.6 * total


@pytest.mark.parametrize("slope", [20.0, 35.0])
def test_prediction_with_the_map_is_the_prediction_without(slope):
    """Per point, the engagement, its step weights, the generation point and the
    sensitivity pass are identical with the height map and without it, also when the
    same blocks are predicted again (the map goes back to its kept state)."""
    prog = parse_program(plane_raster(slope, 5.0, passes=4))
    blocks = [b for b in range(len(prog)) if 40 <= prog.line[b] <= 62]
    runs = {}
    for use in (False, True):
        pred = Predictor(Tool("ball", 10.0, flute_length_mm=15), plane_stock(slope, 0.2), prog,
                         STEEL, stiff_tool())
        pred.model.use_sweep_map = use  # forced either way
        runs[use] = [g for _ in range(2) for gl in pred.geometries(blocks) for g in gl]
        if use:
            assert pred.model._zmap is not None and pred.model._zmap.time > 0
    plain, mapped = runs[False], runs[True]
    assert len(plain) == len(mapped) and sum(g.status == "predicted" for g in plain) >= 10
    for a, b in zip(plain, mapped, strict=True):
        assert a.status == b.status
        for name in ("cutting0", "weight0", "shift0", "cl_per_rev"):
            x, y = getattr(a, name), getattr(b, name)
            assert (x is None and y is None) or np.array_equal(x, y)
        if a.gen is not None:
            assert a.gen.theta_rad == b.gen.theta_rad and a.gen.kappa_rad == b.gen.kappa_rad
        if a.sensitivity is not None:
            for x, y in zip(a.sensitivity[1:], b.sensitivity[1:], strict=True):
                assert np.array_equal(x, y)


def test_a_run_far_into_the_program_leaves_the_map_out_unless_asked():
    """The map is filled in program order: a short run far into a program would first
    insert every sweep before it, so it runs without the map (same answers) unless
    the map is asked for; a run from the start uses it."""
    prog = parse_program(plane_raster(30.0, 5.0, passes=4))
    late = [b for b in range(len(prog)) if 60 <= prog.line[b] <= 61]
    early = [b for b in range(len(prog)) if 0 < prog.line[b] <= 62]
    pred = Predictor(Tool("ball", 10.0, flute_length_mm=15), plane_stock(30.0, 0.2), prog,
                     STEEL, stiff_tool())
    list(pred.geometries(late))
    assert pred.model._zmap is None
    list(pred.geometries(early))
    assert pred.model._zmap.time > 0
    pred.model.use_sweep_map = True
    fresh = Predictor(Tool("ball", 10.0, flute_length_mm=15), plane_stock(30.0, 0.2), prog,
                      STEEL, stiff_tool())
    fresh.model.use_sweep_map = True
    list(fresh.geometries(late))
    assert fresh.model._zmap.time > 0


def test_forked_workers_take_the_parents_kept_map_and_answer_the_same():
    """Predicted again in two forked workers, whose map (the parent's, past these
    blocks) goes back to its kept state by taking the kept arrays, not a copy
    (``SweepMap.hand_over_kept``): the same points as without the map; the parent's
    map keeps its state."""
    prog = parse_program(plane_raster(30.0, 5.0, passes=4))
    blocks = [b for b in range(len(prog)) if 40 <= prog.line[b] <= 62]
    runs = {}
    for use in (False, True):
        pred = Predictor(Tool("ball", 10.0, flute_length_mm=15), plane_stock(30.0, 0.2), prog,
                         STEEL, stiff_tool())
        pred.model.use_sweep_map = use
        list(pred.geometries(blocks))                      # the parent's map past the blocks
        runs[use] = [g for gl in pred.geometries(blocks, workers=2) for g in gl]
        if use:
            z = pred.model._zmap
            assert not z._hand_over and "_vals" in z._snapshot     # the parent's: as it was
    assert len(runs[False]) == len(runs[True]) >= 10
    for a, b in zip(runs[False], runs[True], strict=True):
        assert a.status == b.status
        for name in ("cutting0", "weight0", "shift0", "cl_per_rev"):
            x, y = getattr(a, name), getattr(b, name)
            assert (x is None and y is None) or np.array_equal(x, y)


def test_handed_over_kept_state_is_taken_once():
    """``hand_over_kept``: going back takes the kept arrays themselves (answers as a
    copy gives), leaves no kept arrays behind, and a second going back starts again."""
    prog = parse_program(plane_raster(30.0, 5.0, passes=4))
    pred = Predictor(Tool("ball", 10.0, flute_length_mm=15), plane_stock(30.0, 0.2), prog,
                     STEEL, stiff_tool())
    z = pred.model._sweep_map()
    L = pred.model.path
    pts = np.column_stack([np.linspace(-20, 20, 400), np.zeros(400), np.linspace(-2, 2, 400)])
    z.classify(pts, float(L[len(L) // 3]))
    z.classify(pts, float(L[-1]))
    want = copy.deepcopy(z)
    z.hand_over_kept()
    got = z.classify(pts, float(L[len(L) // 2]))
    assert np.array_equal(got, want.classify(pts, float(L[len(L) // 2])))
    assert "_vals" not in z._snapshot and z.nbytes == z._vals.nbytes + z.tile_index.nbytes
    assert np.array_equal(z.classify(pts, float(L[len(L) // 3])),
                          want.classify(pts, float(L[len(L) // 3])))


def test_by_default_a_sweep_goes_only_into_the_tiles_queries_touch(monkeypatch):
    """Query by query along the program, one sweep at a time, on one side of the
    passes: the default map puts each new sweep only into the tiles a query touches
    (the tiles the sweeps reach on the other side stay behind, and none is filled
    with a sweep more than once), and answers as the eager map (every sweep into every
    tile it reaches) does, bit for bit in every tile it holds current."""
    tool = Tool("ball", 6.0, flute_length_mm=12.0)
    sw = build_sweeps(_wavy_raster(), tool)
    rng = np.random.default_rng(4)
    queries = []
    for t in range(40, 120):
        # points around the tip of sweep t, on the -y side only
        tip = sw.p0[t] + sw.d[t]
        xy = tip[:2] + rng.uniform([-1.5, -3.0], [1.5, 0.0], (300, 2))
        queries.append((t, np.column_stack([xy, _wavy(xy) + rng.uniform(-0.2, 0.2, 300)])))
    maps = {}
    for lazy in (True, False):
        if not lazy:
            monkeypatch.setattr(K, "ZMAP_JUMP_SWEEPS", 10**9)
        z = SweepMap(sw, tool)
        out, behind = [], 0
        for t, pts in queries:
            out.append(z.classify(pts, float(sw.path_end[t])))
            slots = z.tile_index.ravel()[z.tile_index.ravel() >= 0]
            behind = max(behind, int((z._filled[slots] < z.time).sum()))
        maps[lazy] = (z, out, behind)
    (lz, lazy_out, lazy_behind), (ez, eager_out, eager_behind) = maps[True], maps[False]
    assert lazy_behind > 0 and eager_behind == 0
    for a, b in zip(lazy_out, eager_out, strict=True):
        assert np.array_equal(a, b)
    assert any((a != 0).sum() > 100 for a in lazy_out)
    for key, slot in enumerate(lz.tile_index.ravel()):
        if slot >= 0 and lz._filled[slot] == lz.time:
            assert np.array_equal(lz._vals[slot], ez._vals[ez.tile_index.ravel()[key]],
                                  equal_nan=True)


def test_a_jump_leaves_tiles_behind_and_each_is_caught_up_as_eager_insertion_fills_it(
        monkeypatch):
    """Queries that jump (``ZMAP_JUMP_SWEEPS`` or more sweeps after the map's time) leave
    the tiles where they are and catch each one up when a later query touches it: the
    answers are the eager map's (every skipped sweep into every tile it reaches), every
    tile a query touched holds what the eager map's holds, bit for bit (the same sweeps
    in the same order), and the tiles no query touched since stay behind."""
    tool = Tool("ball", 6.0, flute_length_mm=12.0)
    sw = build_sweeps(_wavy_raster(), tool)
    n = len(sw)
    rng = np.random.default_rng(11)

    def near(x0, x1):
        xy = rng.uniform([x0, -5.0], [x1, 5.0], (1500, 2))
        return np.column_stack([xy, _wavy(xy) + rng.uniform(-0.3, 0.3, len(xy))])

    # (sweeps inserted, points): small steps and jumps, over different parts of the part
    steps = [(n // 10, near(0, 12)), (n // 10 + 2, near(0, 4)), (n // 2, near(0, 4)),
             (n // 2 + 1, near(0, 4)), (n // 2 + 3, near(8, 12)), (9 * n // 10, near(0, 12))]
    maps = {}
    for lazy in (True, False):
        if not lazy:
            monkeypatch.setattr(K, "ZMAP_JUMP_SWEEPS", 10**9)
        z = SweepMap(sw, tool)
        out = []
        for k, (time, pts) in enumerate(steps):
            out.append(z.classify(pts, float(sw.path_end[time - 1])))
            assert z.time == time
            if lazy and k == 3:     # after a jump, the tiles of x > 4 were not touched
                slots = z.tile_index.ravel()[z.tile_index.ravel() >= 0]
                assert (z._filled[slots] < z.time).any()
        maps[lazy] = (z, out)
    (lz, lazy_out), (ez, eager_out) = maps[True], maps[False]
    for a, b in zip(lazy_out, eager_out):
        assert np.array_equal(a, b)
    current = 0
    for key, slot in enumerate(lz.tile_index.ravel()):
        if slot >= 0 and lz._filled[slot] == lz.time:
            current += 1
            assert np.array_equal(lz._vals[slot], ez._vals[ez.tile_index.ravel()[key]],
                                  equal_nan=True)
    assert current > 0
    exact = _exact(sw, tool, steps[-1][1], steps[-1][0])
    assert not (lazy_out[-1][exact] == -1).any() and not (lazy_out[-1][~exact] == 1).any()


def test_a_tile_left_behind_is_caught_up_even_when_a_query_drops_one_of_its_own():
    """A jump's query whose new tile takes the slot of one of its own tiles (the least
    recently used of a small budget) leaves no other tile marked caught up: the tile
    left behind at the jump still answers as the exact test."""
    tool = Tool("ball", 6.0, flute_length_mm=12.0)
    sw = build_sweeps(_wavy_raster(), tool)
    z = SweepMap(sw, tool, max_tiles=12)
    span, ty = z.cell * z.size, int(z.shape[1])

    def centre(key):
        a, b = divmod(key, ty)
        xy = np.array([[z.origin[0] + (a + 0.5) * span, z.origin[1] + (b + 0.5) * span]])
        return np.column_stack([xy, _wavy(xy)])

    x = int((6.0 - z.origin[0]) / span) * ty + int((-2.6 - z.origin[1]) / span)
    others = [k for k in range(z.tile_index.size) if k != x][:11]
    new = next(k for k in range(z.tile_index.size) if k not in others and k != x)
    at = [float(sw.path_end[t - 1]) for t in (50, 150)]
    z.classify(np.vstack([centre(k) for k in others]), at[0])      # 11 slots
    z.classify(centre(x), at[0])                                    # the 12th: x
    z.classify(np.vstack([centre(others[0]), centre(new)]), at[1])  # a jump; x left behind
    a, b = divmod(x, ty)
    rng = np.random.default_rng(0)
    xy = rng.uniform([z.origin[0] + a * span, z.origin[1] + b * span],
                     [z.origin[0] + (a + 1) * span, z.origin[1] + (b + 1) * span], (500, 2))
    pts = np.column_stack([xy, _wavy(xy) + rng.uniform(-0.3, 0.3, len(xy))])
    got = z.classify(pts, at[1])
    exact = _exact(sw, tool, pts, 150)
    assert exact.sum() > 100 and (got != 0).sum() > 100
    assert not (got[exact] == -1).any() and not (got[~exact] == 1).any()


def test_tiles_of_and_the_classify_kernel_agree_on_a_tile_edge():
    """With a tile side that is no power of two, a point at a tile's edge is put in the
    same tile by both (else the kernel could read a tile the query did not catch up)."""
    from errpred._zmap_kernels import tiles_of

    tool = Tool("ball", 6.0, flute_length_mm=12.0)
    z = SweepMap(build_sweeps(_wavy_raster(), tool), tool, tile=24)
    span = z.cell * z.size
    checked = 0
    for a in range(1, int(z.shape[0])):
        for x in z.origin[0] + a * span + np.arange(-6, 7) * 1e-15:
            key = tiles_of(np.array([[x, z.origin[1] + 0.5 * span, 0.0]]), z.origin, z.cell,
                           z.size, z.shape)
            assert key.size == 1
            assert key[0] // z.shape[1] == int((x - z.origin[0]) / z.cell) // z.size
            checked += 1
    assert checked > 20


@pytest.mark.parametrize("seed", range(12))
def test_the_map_with_jumps_and_a_small_budget_answers_as_the_eager_map_and_exactly(
        seed, monkeypatch):
    """Random query sequences (small steps, jumps, 31-33 sweeps, going back), over random
    parts of the part, on a lazy map with a small tile budget (tiles dropped and filled
    again) against an eager map with room for all: the same answers where the lazy map
    still holds the point's tile (0 elsewhere), every decided answer the exact test's,
    and every caught-up tile bit for bit the eager one's."""
    rng = np.random.default_rng(seed)
    tool = Tool("ball", 6.0, flute_length_mm=12.0)
    sw = build_sweeps(_wavy_raster(), tool)
    # budgets above the tiles a step of a few sweeps reaches, below those of the part
    cell, tile, budget = [(0.1, 32, 24), (0.25, 16, 20), (0.2, 16, 24)][seed % 3]
    monkeypatch.setattr(K, "ZMAP_SCAN_SWEEPS", int(rng.choice([0, 16, 4096])))
    lazy = SweepMap(sw, tool, cell_mm=cell, tile=tile, max_tiles=budget)
    eager = SweepMap(sw, tool, cell_mm=cell, tile=tile, max_tiles=10**5)
    n, span, t = len(sw), cell * tile, int(rng.integers(40, len(sw) // 3))
    dropped, take = [0], lazy._slot

    def slot():
        dropped[0] += not lazy._free and lazy._vals.shape[0] >= lazy.max_tiles
        return take()

    lazy._slot = slot
    decided = 0
    for q in range(20):
        step = rng.choice(["small", "jump", "edge", "back"], p=[0.4, 0.3, 0.15, 0.15])
        if q:
            t = {"small": min(n, t + int(rng.integers(1, 4))),
                 "jump": min(n, t + int(rng.integers(32, 250))),
                 "edge": min(n, t + int(rng.choice([31, 32, 33]))),
                 "back": int(rng.integers(32, t + 1))}[step]   # (from 0: a jump)
        xy = rng.uniform([-1.0, -6.0], [13.0, 6.0]) + rng.uniform(-1.0 * span, 1.0 * span,
                                                                  (200, 2))
        pts = np.column_stack([xy, _wavy(xy) + rng.choice([1e-3, 1e-2, 0.1, 1.0], 200)
                               * rng.choice([-1, 1], 200)])
        got = lazy.classify(pts, float(sw.path_end[t - 1]))
        with monkeypatch.context() as m:
            m.setattr(K, "ZMAP_JUMP_SWEEPS", 10**9)
            want = eager.classify(pts, float(sw.path_end[t - 1]))
        exact = _exact(sw, tool, pts, t)
        assert not (got[exact] == -1).any() and not (got[~exact] == 1).any()
        fx = ((pts[:, 0] - lazy.origin[0]) / cell).astype(int) // tile
        fy = ((pts[:, 1] - lazy.origin[1]) / cell).astype(int) // tile
        inside = (fx >= 0) & (fx < lazy.shape[0]) & (fy >= 0) & (fy < lazy.shape[1])
        held = np.zeros(len(pts), dtype=bool)
        held[inside] = lazy.tile_index[fx[inside], fy[inside]] >= 0
        assert np.array_equal(got[held], want[held]) and not got[~held].any()
        flat = lazy.tile_index.ravel()
        for key in np.flatnonzero(flat >= 0).tolist():
            if lazy._filled[flat[key]] == lazy.time:
                e = eager.tile_index.ravel()[key]
                assert e >= 0 and np.array_equal(lazy._vals[flat[key]], eager._vals[e],
                                                 equal_nan=True)
        decided += int((got != 0).sum())
    assert decided > 0
    assert dropped[0] > 0           # tiles were dropped for others (and some filled again)
