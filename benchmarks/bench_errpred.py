"""Prediction throughput, its breakdown and memory on the bundled programs.

For each slice (mold-ball contour lines 6131-, mold-ball raster 19103-,
wall-radius 374-; ``--blocks`` consecutive blocks each) at the default
resolution it prints:

* blocks per second on one core (this process: stage 1 geometry and stage 2
  physics, as ``errpred predict`` runs them, or with ``--sensitivity`` as a
  correction does; marginal cost: the kernels are compiled and the predictor built
  before the clock starts), min and median of ``--repeat`` runs;
* on 3-axis ball end milling, the same without the sweeps' height map
  (``errpred.zmap``: every T1 test exact), the ratio, and the share of the
  tests the map answered;
* the same per CPU-second of this process, and the CPU/wall ratio (the share
  of a core the run got: on a shared machine the wall rate follows the load);
* blocks per second with two worker processes for stage 1 (physics in order
  in this process) and the ratio to one core; blocks per CPU-second of this
  process and its workers, and their CPU/wall (how many cores they got);
* where a block's time goes (inclusive, so nested stages overlap): the
  pre-check, the stock's bottom view, the sweep lookup, the engagement (with
  its step weights and sensitivity pass), the finished surface, the side
  view, the physics;
* sweeps per prediction point: considered (T1 and T2 after the lookup), those
  that contain any engagement sample, and those that are the first to contain
  one in the order tested (they decide);
* memory: the sweep index, and the peak Python allocation predicting N and 4N
  blocks (tracemalloc; flat in program length but for the results kept) and
  this process's peak resident size.

The machine is shared: figures are min and median of repeats, and the ratio
to one core is taken in the same run, its runs in turn repeat by repeat (one core,
one core without the map, the workers): best against best, and the median of each
repeat's ratio.

Usage: python benchmarks/bench_errpred.py [--blocks N] [--repeat K] [--slices NAMES]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import resource
import statistics
import sys
import time
import tracemalloc
from collections import defaultdict

import numpy as np
from numba import njit

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from errpred import bottomview, geometry, point_engagement, t1memo  # noqa: E402
from errpred import constants as K  # noqa: E402
from errpred._kernels import sweep_within  # noqa: E402
from errpred.physics import WearState, evaluate  # noqa: E402
from errpred.pipeline import blocks_in_scope, build_predictor, load  # noqa: E402
from errpred.scenario import bundled_scenario  # noqa: E402
from errpred.zmap import sweep_map  # noqa: E402

SLICES = {
    "contour": ("mold-ball", 6131),
    "raster": ("mold-ball", 19103),
    "wall-radius": ("wall-radius", 374),
}


@njit(cache=True)
def _first_container(points, p0, d, w, c, r, top, lim):
    """For each point: the first sweep (in the order given) that contains it, or -1."""
    out = np.full(points.shape[0], -1, dtype=np.int64)
    for i in range(points.shape[0]):
        for j in range(p0.shape[0]):
            if sweep_within(points[i, 0], points[i, 1], points[i, 2], p0[j], d[j], w[j], c, r,
                            top, lim):
                out[i] = j
                break
    return out


@njit(cache=True)
def _any_container(points, p0, d, w, c, r, top, lim):
    """For each sweep: does it contain any of the points?"""
    out = np.zeros(p0.shape[0], dtype=np.bool_)
    for j in range(p0.shape[0]):
        for i in range(points.shape[0]):
            if sweep_within(points[i, 0], points[i, 1], points[i, 2], p0[j], d[j], w[j], c, r,
                            top, lim):
                out[j] = True
                break
    return out


class _Probe:
    """Inclusive seconds of the geometry stage's steps, and the sweeps per point."""

    STEPS = {
        "pre-check": (geometry.GeometryModel, "_material_at"),
        "sweep lookup": (geometry.GeometryModel, "_near_sweeps"),
        "engagement": (point_engagement.PointEngagement, "engagement"),
        "step weights": (point_engagement.PointEngagement, "step_weights"),
        "finished surface": (bottomview.BottomTemplate, "finished_surface"),
        "side view": (geometry.GeometryModel, "_side_view"),
    }

    def __init__(self, sweep_stats: bool) -> None:
        self.seconds: dict[str, float] = defaultdict(float)
        self.considered: list[int] = []
        self.containing: list[int] = []
        self.deciding: list[int] = []
        self._saved = []
        self._sweep_stats = sweep_stats

    def __enter__(self):
        for label, (owner, name) in self.STEPS.items():
            self._wrap(owner, name, label)
        self._wrap(geometry, "stock_view", "stock bottom view")
        return self

    def __exit__(self, *exc):
        for owner, name, f in reversed(self._saved):
            setattr(owner, name, f)

    def _wrap(self, owner, name, label):
        f = getattr(owner, name)
        self._saved.append((owner, name, f))
        seconds = self.seconds
        probe = self

        def timed(*a, **kw):
            t0 = time.perf_counter()
            try:
                out = f(*a, **kw)
            finally:
                seconds[label] += time.perf_counter() - t0
            if name == "engagement" and probe._sweep_stats and "stock_shift" not in kw:
                probe._count(a[0], a[4])
            return out

        setattr(owner, name, timed)

    def _count(self, model, memo):
        """Sweeps per point over the samples the engagement tested against T1."""
        tested = [w for tag, w in memo.tested if tag[0] == "grid"]
        if not tested:
            return
        world = np.concatenate(tested)
        t1 = memo.args_t1
        tool = model.tool
        args = (*t1[:3], tool.core_radius_mm, tool.corner_radius_mm, tool.flute_length_mm,
                tool.corner_radius_mm + K.MEMBERSHIP_EPS_MM)
        first = _first_container(world, *args)
        self.considered.append(t1[0].shape[0])
        self.containing.append(int(_any_container(world, *args).sum()))
        self.deciding.append(int(np.unique(first[first >= 0]).size))


def stage_seconds(pred, blocks) -> tuple[float, float, int]:
    """Stage 1 (geometry) and stage 2 (physics) of ``blocks`` in this process, one after
    the other: seconds of each and the number of prediction points (also bench_dask's)."""
    t0 = time.perf_counter()
    geoms = [g for gl in pred.geometries(blocks) for g in gl]
    t_geo = time.perf_counter() - t0
    wear = WearState.new(pred.edges)
    t0 = time.perf_counter()
    for g in geoms:
        evaluate(pred.tool, pred.edges, pred.coefficients, pred.compliance, pred.shape,
                 pred.theta, g, wear)
    return t_geo, time.perf_counter() - t0, len(geoms)


def _one_core(pred, blocks, cpu=None):
    """Stage 1 then stage 2 of ``blocks`` in this process: (seconds, geometry seconds);
    this process's CPU seconds appended to ``cpu`` where given."""
    c0 = time.process_time()
    t_geo, t_phys, _ = stage_seconds(pred, blocks)
    if cpu is not None:
        cpu.append(time.process_time() - c0)
    return t_geo + t_phys, t_geo


def _cpu_seconds() -> float:
    """CPU seconds of this process and its ended children (user + system)."""
    a, b = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return a.ru_utime + a.ru_stime + b.ru_utime + b.ru_stime


def _fmt(rates):
    return f"min {min(rates):7.1f}  median {statistics.median(rates):7.1f}"


def fill_map_along(model, blocks):
    """Fill the sweeps' height map of ``model`` (a :class:`errpred.geometry.GeometryModel`
    whose map is on) at the start of ``blocks``: every tile within a tool radius (and a
    tile) of their path, with every sweep before them that reaches it (the path every
    half tile, offsets half a tile apart; a coarser ring, a radius to each side, left
    tiles between its points to be filled from scratch inside the timed runs). Returns
    the map."""
    zmap = model._sweep_map()
    i0 = model.block_points(blocks[0])[0]
    i1 = model.block_points(blocks[-1])[1]
    start = float(model.path[i0])
    r = model.tool.radius_mm
    half = 0.5 * zmap.cell * zmap.size
    tips = model.cl.tip[i0:i1 + 1]
    steps = np.maximum(np.ceil(np.linalg.norm(np.diff(tips, axis=0), axis=1) / half), 1)
    path = np.concatenate([tips[:1]] + [a + (b - a) * (np.arange(1, k + 1) / k)[:, None]
                                        for a, b, k in zip(tips[:-1], tips[1:],
                                                           steps.astype(int))])
    reach = np.arange(-r - 2 * half, r + 2 * half + 1e-9, half)
    ring = np.array([(a, b, 0.0) for a in reach for b in reach
                     if np.hypot(a, b) <= r + 2 * half])
    if zmap.frame is not None:          # the map's grid lies across its axis
        ring = ring @ zmap.frame
    around = (path[:, None, :] + ring).reshape(-1, 3)
    zmap.classify(np.ascontiguousarray(around), start)
    return zmap


def bench_slice(label, scenario, first, n_blocks, repeat, workers, sensitivity):
    s = load(bundled_scenario(scenario))
    s = dataclasses.replace(s, lines=(first, 10**9))
    t0 = time.perf_counter()
    pred = build_predictor(s, sensitivity=sensitivity)
    setup = time.perf_counter() - t0
    blocks = blocks_in_scope(s, pred.program)[:n_blocks]
    print(f"\n== {label}: {scenario} lines {first}-{int(pred.program.line[blocks[-1]])} "
          f"({len(blocks)} blocks of {len(pred.program):,}; {len(pred.model.sweeps):,} sweeps; "
          f"setup {setup:.2f} s; "
          f"{'with' if sensitivity else 'without'} the correction's sensitivity pass)")
    if pred.model.sweeps is not None and sweep_map(pred.model.sweeps, pred.tool) is not None:
        # the slices start far into their programs: the height map's tiles along the
        # slice, filled with every sweep before it that reaches them, are start-up here
        # (marginal cost per block), so force the map and fill them first
        pred.model.use_sweep_map = True
        t0 = time.perf_counter()
        zmap = fill_map_along(pred.model, blocks)
        held = int((zmap.tile_index >= 0).sum())
        print(f"  sweeps' height map: {held} tiles along the slice filled with the "
              f"{zmap.time:,} sweeps before it: {time.perf_counter() - t0:.1f} s")
    pred.run(blocks[:10])  # kernels compiled or loaded from the cache
    one, geo_share, cpu = [], [], []
    zmap = pred.model._sweep_map()
    base, base_cpu, two, two_cpu = [], [], [], []
    # in turn, repeat by repeat: one core, one core without the height map, the workers
    # (on a shared machine the load drifts; a ratio of runs next to each other holds)
    for _ in range(repeat):
        total, t_geo = _one_core(pred, blocks, cpu)
        one.append(len(blocks) / total)
        geo_share.append(t_geo / total)
        if zmap is not None:
            # the same blocks without the sweeps' height map (every T1 test exact)
            pred.model.use_sweep_map = False
            base.append(len(blocks) / _one_core(pred, blocks, base_cpu)[0])
            pred.model.use_sweep_map = True  # forced, as above
        c0 = _cpu_seconds()
        t0 = time.perf_counter()
        pred.run(blocks, workers=workers)
        two.append(len(blocks) / (time.perf_counter() - t0))
        two_cpu.append(_cpu_seconds() - c0)
    print(f"1 core     blocks/s: {_fmt(one)}   (geometry {100 * statistics.median(geo_share):.0f} %"
          " of it)")
    # on a shared machine the wall rate is the share of a core this process got
    print(f"  per CPU-second: {_fmt([len(blocks) / c for c in cpu])}   (CPU/wall "
          f"{statistics.median([c * r / len(blocks) for c, r in zip(cpu, one)]):.2f})")
    if zmap is not None:
        counts = np.zeros(3)
        classify = type(zmap).classify

        def counted(self, points, t1_end):
            state = classify(self, points, t1_end)
            counts[:] += [(state == v).sum() for v in (-1, 0, 1)]
            return state

        type(zmap).classify = counted
        try:
            _one_core(pred, blocks)
        finally:
            type(zmap).classify = classify
        share = counts / max(counts.sum(), 1)
        print(f"  without the sweeps' height map: {_fmt(base)}   (map x{max(one) / max(base):.2f},"
              f" best against best; map answered {100 * (share[0] + share[2]):.1f} % of the T1 "
              f"tests: {100 * share[0]:.1f} % outside, {100 * share[2]:.1f} % inside; "
              f"{zmap.nbytes / 1e6:.0f} MB, {int((zmap.tile_index >= 0).sum())} tiles)")
        print(f"    per CPU-second: {_fmt([len(blocks) / c for c in base_cpu])}   (map "
              f"x{min(base_cpu) / min(cpu):.2f} in CPU, best against best)")
    paired = statistics.median(b / a for a, b in zip(one, two))
    print(f"{workers} workers  blocks/s: {_fmt(two)}   (x{max(two) / max(one):.2f} of one core, "
          f"best against best; x{paired:.2f}, the median of each repeat's runs in turn)")
    # CPU this process and the workers used (a pool is started and ended per run): the
    # CPU a block costs there, and how many cores the run got (CPU/wall; 2 workers can
    # only beat one process when the machine has a second core free)
    print(f"  per CPU-second (this process + workers): "
          f"{_fmt([len(blocks) / c for c in two_cpu])}   (CPU/wall "
          f"{statistics.median([c * r / len(blocks) for c, r in zip(two_cpu, two)]):.2f})")
    # breakdown and sweeps, one more single-core run with the probes in
    memo_init, memo_call = t1memo.RemovedMemo.__init__, t1memo.RemovedMemo.__call__

    def init(self, tool, t1, *rest):
        memo_init(self, tool, t1, *rest)
        self.args_t1, self.tested = t1, []

    def call(self, tag, keys, world):
        self.tested.append((tag, np.asarray(world)))
        return memo_call(self, tag, keys, world)

    t1memo.RemovedMemo.__init__, t1memo.RemovedMemo.__call__ = init, call
    try:
        with _Probe(sweep_stats=True) as probe:
            t0 = time.perf_counter()
            geoms = [g for gl in pred.geometries(blocks) for g in gl]
            t_geo = time.perf_counter() - t0
    finally:
        t1memo.RemovedMemo.__init__, t1memo.RemovedMemo.__call__ = memo_init, memo_call
    wear = WearState.new(pred.edges)
    t0 = time.perf_counter()
    for g in geoms:
        evaluate(pred.tool, pred.edges, pred.coefficients, pred.compliance, pred.shape,
                 pred.theta, g, wear)
    t_phys = time.perf_counter() - t0
    nb = len(blocks)
    print(f"per block [ms] (inclusive; this run with probes and sweep counts: geometry "
          f"{t_geo / nb * 1e3:.2f}, "
          f"physics {t_phys / nb * 1e3:.2f})")
    for k in ("pre-check", "stock bottom view", "sweep lookup", "engagement", "step weights",
              "finished surface", "side view"):
        print(f"  {k:18s} {probe.seconds.get(k, 0.0) / nb * 1e3:7.2f}")
    if probe.considered:
        print(f"sweeps per point (T1, engagement samples in stock): considered {np.mean(probe.considered):7.1f}, "
              f"containing a sample {np.mean(probe.containing):6.1f}, "
              f"deciding {np.mean(probe.deciding):5.1f}")
    # memory
    print(f"sweep index {pred.model.sweeps.nbytes / 1e6:.1f} MB")
    for n in (max(1, len(blocks) // 4), len(blocks)):
        tracemalloc.start()
        out = pred.run(blocks[:n])
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        print(f"peak allocation predicting {n:5d} blocks: {peak / 1e6:6.1f} MB "
              f"({len(out.points):,} points kept in the result)")
    return one, two


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=300, help="blocks per slice")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--sensitivity", action="store_true",
                    help="also the error's sensitivity, as a correction predicts (default: as "
                         "errpred predict, without)")
    ap.add_argument("--slices", default=",".join(SLICES),
                    help=f"comma-separated, of {', '.join(SLICES)}")
    args = ap.parse_args(argv)
    for name in args.slices.split(","):
        if name not in SLICES:
            ap.error(f"--slices: unknown slice {name!r}; expected one of {', '.join(SLICES)}")
        bench_slice(name, *SLICES[name], args.blocks, args.repeat, args.workers,
                    args.sensitivity)
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"\npeak resident size of this process: {rss:.0f} MB")
    print("targets (issue 17): >= 1,000 blocks/s on one core on both mold-ball slices, "
          ">= 200 on wall-radius, 2 workers >= 1.8x one")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
