"""Prediction throughput and memory on the bundled mold-ball scenario.

Prints, for a run of consecutive blocks of the 24,351-block finishing
program at the default resolution:

* blocks per second on one core (this process) and on both cores (a pool of
  two worker processes for the geometry stage), and their ratio;
* the time split between the geometry stage and the physics stage;
* memory: the program and the sweep index (fixed per program), and the peak
  Python allocation while predicting N and 4N blocks (tracemalloc): it must
  not grow with the number of blocks beyond the report's own records.

Usage: python benchmarks/bench_errpred.py [--first LINE] [--blocks N]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
import tracemalloc

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from errpred.pipeline import blocks_in_scope, build_predictor, load  # noqa: E402
from errpred.physics import WearState, evaluate  # noqa: E402
from errpred.scenario import bundled_scenario  # noqa: E402


def stage_seconds(pred, blocks) -> tuple[float, float, int]:
    """Stage 1 (geometry) and stage 2 (physics) of ``blocks`` in this process, one after
    the other: seconds of each and the number of prediction points."""
    t0 = time.perf_counter()
    geoms = [g for gl in pred.geometries(blocks) for g in gl]
    t_geo = time.perf_counter() - t0
    wear = WearState.new(pred.edges)
    t0 = time.perf_counter()
    for g in geoms:
        evaluate(pred.tool, pred.edges, pred.coefficients, pred.compliance, pred.shape,
                 pred.theta, g, wear)
    return t_geo, time.perf_counter() - t0, len(geoms)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--first", type=int, default=19103, help="first program line")
    ap.add_argument("--blocks", type=int, default=1500)
    args = ap.parse_args(argv)
    s = load(bundled_scenario("mold-ball"))
    s = dataclasses.replace(s, lines=(args.first, 10**9))
    t0 = time.perf_counter()
    pred = build_predictor(s)
    setup = time.perf_counter() - t0
    blocks = blocks_in_scope(s, pred.program)[: args.blocks]
    print(f"mold-ball: {len(pred.program):,} blocks in the program, {len(pred.cl):,} path "
          f"points, {len(pred.model.sweeps):,} sweeps; setup {setup:.2f} s")
    print(f"fixed memory: sweep index {pred.model.sweeps.nbytes / 1e6:.1f} MB, program "
          f"arrays {sum(a.nbytes for a in (pred.program.end, pred.program.line)) / 1e6:.1f} MB")
    pred.run(blocks[:30])  # numba compiled and cached
    t_geo, t_phys, _ = stage_seconds(pred, blocks)
    one = len(blocks) / (t_geo + t_phys)
    print(f"1 core : {one:8.1f} blocks/s  (geometry {t_geo / len(blocks) * 1e3:.2f} ms/block, "
          f"physics {t_phys / len(blocks) * 1e3:.2f} ms/block)")
    t0 = time.perf_counter()
    pred.run(blocks, workers=2)
    two = len(blocks) / (time.perf_counter() - t0)
    print(f"2 cores: {two:8.1f} blocks/s  (x{two / one:.2f}; geometry in 2 worker processes, "
          "physics in order in this one)")
    for n in (len(blocks) // 4, len(blocks)):
        tracemalloc.start()
        out = pred.run(blocks[:n])
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        print(f"peak allocation predicting {n:5d} blocks: {peak / 1e6:6.1f} MB "
              f"({len(out.points):,} points kept in the result)")
    print("target: >= 1,000 blocks/s per core (not reached; see the closing note)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
