"""Error prediction on Dask (issue 6: scale beyond one machine).

Prints blocks/s of the mold-ball prediction on a slice of its program: one
process, and a local Dask cluster (loopback) of 1 and 2 worker processes; the
split between stage 1 (geometry: rasterizer and sweeps, per block, distributed)
and stage 2 (force with wear, deflection: sequential in the client, because
wear grows along the program); and a projection, with its assumptions, for a
10^6-block program on a cluster.

Usage: python benchmarks/bench_dask.py [--lines FIRST LAST]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time

sys.path.insert(0, os.path.abspath(os.path.join(os.path.dirname(__file__), "..")))

from bench_errpred import stage_seconds  # noqa: E402  (same folder)
from errpred.cluster import dask_client
from errpred.pipeline import blocks_in_scope, build_predictor, load

SCENARIO = "errpred/scenarios/mold-ball/scenario.toml"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lines", type=int, nargs=2, default=(19103, 19402))
    args = ap.parse_args(argv)
    scn = dataclasses.replace(load(os.path.join(os.path.dirname(__file__), "..", SCENARIO)),
                              lines=tuple(args.lines))
    pred = build_predictor(scn)
    blocks = blocks_in_scope(scn, pred.program)
    pred.run(blocks[:20])                                   # compile, warm caches
    t_geo, t_phys, points = stage_seconds(pred, blocks)
    t0 = time.perf_counter()
    build_predictor(scn).run(blocks)
    t_one = time.perf_counter() - t0
    n = len(blocks)
    print(f"{n} blocks (lines {args.lines[0]}..{args.lines[1]}), {points} points; "
          f"{os.cpu_count()} CPUs")
    print(f"one process: {n / t_one:.1f} blocks/s (stage 1 {1e3 * t_geo / n:.1f} ms/block, "
          f"stage 2 {1e3 * t_phys / n:.2f} ms/block)")
    rates = {}
    for workers in (1, 2):
        with dask_client(workers=workers) as client:       # the command lines' cluster
            build_predictor(scn).run(blocks[:20], client=client)        # warm the workers
            p = build_predictor(scn)
            t0 = time.perf_counter()
            p.run(blocks, client=client)
            dt = time.perf_counter() - t0
        rates[workers] = n / dt
        print(f"Dask LocalCluster, {workers} worker(s): {n / dt:.1f} blocks/s "
              f"(x{t_one / dt:.2f} of one process)")
    geo_ms = 1e3 * t_geo / n
    phys_ms = 1e3 * t_phys / n
    for cores in (64, 256):
        t1 = 1e6 * geo_ms / 1e3 / cores
        t2 = 1e6 * phys_ms / 1e3
        print(f"projection, 10^6 blocks on {cores} worker cores: stage 1 {t1 / 60:.1f} min "
              f"(at {geo_ms:.1f} ms/block/core, perfect scaling, the model scattered once), "
              f"stage 2 in the client {t2 / 60:.1f} min (sequential: wear carries along the "
              f"program), overlapped -> about {max(t1, t2) / 60:.0f} min")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
