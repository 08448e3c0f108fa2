"""Stage 1 of a 3+2 program: a mold-ball slice turned as a whole (issue 17).

The bundled mold-ball scenario's stock mesh and cutter locations are turned by a
rotation about x then y (``--tilt A B``, degrees), so the tool stands tilted along
the whole program, as in 3+2 machining; the physics is the same, only the frame
is not. For ``--blocks`` blocks of a slice (contour from line 6131, raster from
19103) it prints stage 1's blocks per second on one core with the sweeps' height
map (held in the frame of the tilted axis) and without it, runs in turn repeat by
repeat (min and median), and whether every point's stage-1 result is the same
both ways (it must be: the map's answers are the exact test's). ``--tilt 0 0``
is the slice as bundled (the map in the world frame).

As in ``bench_errpred.py``, the map's tiles along the slice are filled with every
sweep before it first (start-up, printed), so the rates are the marginal cost
per block.

Usage: python benchmarks/bench_tilted.py [--slice contour|raster] [--blocks N]
[--repeat K] [--tilt A B]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import pickle
import statistics
import sys
import time

import numpy as np
import trimesh

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.dirname(__file__))

from bench_errpred import SLICES, fill_map_along  # noqa: E402
from errpred.geometry import GeometryModel  # noqa: E402
from errpred.pipeline import blocks_in_scope, build_predictor, load  # noqa: E402
from errpred.raster.meshes import Stock  # noqa: E402
from errpred.scenario import bundled_scenario  # noqa: E402


def rotation(a_deg: float, b_deg: float) -> np.ndarray:
    """About x by ``a_deg``, then about y by ``b_deg`` [deg]: (3, 3)."""
    a, b = math.radians(a_deg), math.radians(b_deg)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, math.cos(a), -math.sin(a)],
                   [0.0, math.sin(a), math.cos(a)]])
    ry = np.array([[math.cos(b), 0.0, math.sin(b)], [0.0, 1.0, 0.0],
                   [-math.sin(b), 0.0, math.cos(b)]])
    return ry @ rx


def turned_model(model: GeometryModel, rot: np.ndarray) -> GeometryModel:
    """``model``'s stock mesh and cutter locations turned by ``rot``."""
    cl = dataclasses.replace(model.cl, tip=model.cl.tip @ rot.T, axis=model.cl.axis @ rot.T)
    st = model.stock
    stock = Stock.from_mesh(trimesh.Trimesh(st.vertices @ rot.T, st.faces, process=False))
    return GeometryModel(model.tool, stock, cl, model.res, sensitivity=False)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slice", default="contour", choices=("contour", "raster"))
    ap.add_argument("--blocks", type=int, default=150)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--tilt", type=float, nargs=2, default=(25.0, 15.0), metavar=("A", "B"))
    args = ap.parse_args(argv)
    scenario, first = SLICES[args.slice]
    s = dataclasses.replace(load(bundled_scenario(scenario)), lines=(first, 10**9))
    pred = build_predictor(s, sensitivity=False)
    blocks = blocks_in_scope(s, pred.program)[:args.blocks]
    model = turned_model(pred.model, rotation(*args.tilt))
    model.use_sweep_map = True
    zmap = model._sweep_map()
    if zmap is None:
        sys.exit("no height map applies to this program")
    print(f"{args.slice} slice, {len(blocks)} blocks, turned by {args.tilt[0]:g} deg about x "
          f"and {args.tilt[1]:g} deg about y: tool axis {np.round(model.cl.axis[0], 4)}, "
          f"map {'in the world frame' if zmap.frame is None else 'across the tilted axis'}")
    t0 = time.perf_counter()
    fill_map_along(model, blocks)
    print(f"  the map's tiles along the slice filled: {time.perf_counter() - t0:.1f} s")

    def run(use: bool) -> list:
        model.use_sweep_map = use
        return [g for b in blocks for g in model.geometry(b)]

    run(True)           # kernels compiled or loaded, the tiles the ring left out
    run(False)
    rates: dict = {True: [], False: []}
    results: dict = {}
    for _ in range(args.repeat):
        for use in (True, False):
            t0 = time.perf_counter()
            results[use] = run(use)
            rates[use].append(len(blocks) / (time.perf_counter() - t0))
    for use in (True, False):
        r = rates[use]
        print(f"  1 core {'with' if use else 'without'} the map: min {min(r):6.1f}  "
              f"median {statistics.median(r):6.1f} blocks/s")
    same = [pickle.dumps(dataclasses.replace(a, lookup_box=None))
            == pickle.dumps(dataclasses.replace(b, lookup_box=None))
            for a, b in zip(results[True], results[False], strict=True)]
    print(f"  the same stage-1 results with and without the map: {sum(same)} of {len(same)} "
          f"points ({sum(g.status == 'predicted' for g in results[True])} predicted)")


if __name__ == "__main__":
    main()
