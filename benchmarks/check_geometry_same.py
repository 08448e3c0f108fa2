"""Do code changes keep errpred's stage-1 answers? Digests of every PointGeometry.

Predicts the geometry stage (with the correction's sensitivity pass, as the
main job's dense predictions do) on the bench slices of
``benchmarks/bench_errpred.py`` (``--blocks`` consecutive blocks each), and
with ``--dense`` also at the dense verification's spacing, and writes one
SHA-256 digest per point of its pickle (the packed per-revolution arrays,
dtypes included), in order, to a JSON file (``--save``); ``--compare`` reads
such a file made by the code before a change and says which points differ
(exit 1 if any, or if the point counts differ).

It also keeps each point's values (status, view, pixel counts, a digest of the
per-revolution arrays, the generation point's angles, point, normal and pixel
count, and its strip samples' count, sums, minima and maxima); with ``--tol T``
the points whose bytes differ are compared value by value instead: everything
but the floats equal, the floats within ``T`` (mm or rad; angles modulo 2 pi).
A change that is the same arithmetic in another order (a numba kernel for numpy
code) passes ``--tol`` but not the bytes.

Compare in the same state of numba's cache: the same code gives other bytes, within
1e-9 mm and rad, in a process that compiled its kernels than in one that loaded them
from the cache (measured with ``--blocks 100 --dense``: the wall-radius slice 74 of
100 points and 1,009 of its 1,069 dense points, the contour's dense points 5 of 101,
the raster none). Empty the cache (``find errpred -name
'*.nb[ic]' -delete``) before both runs, or run both with it full.

Usage: python benchmarks/check_geometry_same.py (--save F | --compare F [--tol T])
[--blocks N] [--slices NAMES] [--dense]
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import math
import os
import pickle
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from errpred.pipeline import blocks_in_scope, build_predictor, load  # noqa: E402
from errpred.scenario import bundled_scenario  # noqa: E402

SLICES = {
    "contour": ("mold-ball", 6131),
    "raster": ("mold-ball", 19103),
    "wall-radius": ("wall-radius", 374),
}


def _sha(obj) -> str:
    return hashlib.sha256(pickle.dumps(obj, protocol=4)).hexdigest()


def values(g) -> dict:
    """A point's values for the comparison within a tolerance (floats as a list)."""
    arrays = (g.cutting0, g.weight0, g.shift0, g.cl_per_rev, g.sensitivity)
    exact = [g.block, g.status, g.view, g.cutting_pixels, g.finished_pixels, list(g.notes),
             _sha(arrays)]
    floats = [g.path_mm, *map(float, g.tip), *map(float, g.axis), *map(float, g.frame.ravel())]
    angles: list[float] = []
    gen = g.gen
    if gen is not None:
        exact += [gen.pixels, 0 if gen.samples_theta is None else len(gen.samples_theta)]
        angles += [gen.theta_rad, gen.phi_rad]
        floats += [gen.kappa_rad, *map(float, gen.point_tool), *map(float, gen.point_world),
                   *map(float, gen.normal_world)]
        for a in (gen.samples_kappa, gen.samples_z, gen.samples_normal):
            if a is not None:
                floats += [float(a.sum()), float(a.min()), float(a.max())]
        if gen.samples_theta is not None:
            # rotation angles near 0 and 2 pi: their sines and cosines
            floats += [float(np.sin(gen.samples_theta).sum()),
                       float(np.cos(gen.samples_theta).sum())]
    return {"exact": exact, "floats": floats, "angles": angles}


def differs(a: dict, b: dict, tol: float) -> str | None:
    """Why two points' values differ beyond ``tol``, or None."""
    if a["exact"] != b["exact"]:
        return f"exact fields {a['exact']} vs {b['exact']}"
    for key in ("floats", "angles"):
        if len(a[key]) != len(b[key]):
            return f"{key}: {len(a[key])} vs {len(b[key])} values"
    d = max((abs(x - y) for x, y in zip(a["floats"], b["floats"])), default=0.0)
    da = max((abs(math.remainder(x - y, 2 * math.pi))
              for x, y in zip(a["angles"], b["angles"])), default=0.0)
    if not (d <= tol and da <= tol):
        return f"floats off by {d:.3g}, angles by {da:.3g}"
    return None


def digests(name: str, n_blocks: int, dense: bool, zmap: bool | None
            ) -> tuple[list[str], list[dict]]:
    scenario, first = SLICES[name]
    s = load(bundled_scenario(scenario))
    s = dataclasses.replace(s, lines=(first, 10**9))
    res = s.resolution.dense() if dense else None
    pred = build_predictor(s, resolution=res, sensitivity=True)
    pred.model.use_sweep_map = zmap
    blocks = blocks_in_scope(s, pred.program)[:n_blocks]
    points = [g for gl in pred.geometries(blocks) for g in gl]
    return [_sha(g) for g in points], [values(g) for g in points]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    io = ap.add_mutually_exclusive_group(required=True)
    io.add_argument("--save", help="write the digests to this JSON file")
    io.add_argument("--compare", help="compare with the digests in this JSON file")
    ap.add_argument("--blocks", type=int, default=40)
    ap.add_argument("--slices", default=",".join(SLICES))
    ap.add_argument("--dense", action="store_true",
                    help="also at the dense verification's spacing (Resolution.dense)")
    ap.add_argument("--tol", type=float, default=None,
                    help="with --compare: points whose bytes differ pass when their values "
                         "agree within this [mm or rad] (see the module's docstring)")
    args = ap.parse_args(argv)
    if args.tol is not None and not (args.compare and math.isfinite(args.tol)
                                     and args.tol >= 0):
        ap.error(f"--tol: expected a finite value >= 0 with --compare, got {args.tol!r}")
    runs, vals = {}, {}
    for name in args.slices.split(","):
        if name not in SLICES:
            ap.error(f"--slices: unknown slice {name!r}; expected one of {', '.join(SLICES)}")
        # with and without the sweeps' height map: both ways of answering T1
        for zmap in (None, False):
            key = f"{name} zmap={zmap}"
            runs[key], vals[key] = digests(name, args.blocks, False, zmap)
        if args.dense:
            key = f"{name} dense"
            runs[key], vals[key] = digests(name, args.blocks, True, False)
    if args.save:
        with open(args.save, "w") as fh:
            json.dump({**runs, "values": vals}, fh, indent=0)
        print(f"{sum(map(len, runs.values()))} points in {args.save}")
        return 0
    with open(args.compare) as fh:
        ref = json.load(fh)
    ref_vals = ref.pop("values", {})
    bad = 0
    for key, got in runs.items():
        want = ref.get(key)
        if want is None:
            print(f"{key}: not in {args.compare}")
            bad += 1
            continue
        diff = [i for i, (a, b) in enumerate(zip(got, want)) if a != b]
        same = len(got) == len(want) and not diff
        line = (f"{key}: {len(got)} points, {'same bytes' if same else f'{len(diff)} differ'}"
                + ("" if len(got) == len(want) else f" (reference {len(want)} points)"))
        if not same and args.tol is not None and len(got) == len(want):
            want_vals = ref_vals.get(key)
            if want_vals is None:
                line += f"; no values in {args.compare} (saved by an older version)"
            else:
                why = [(i, differs(vals[key][i], want_vals[i], args.tol)) for i in diff]
                why = [(i, w) for i, w in why if w is not None]
                line += (f"; {len(diff) - len(why)} of them within --tol {args.tol:g}"
                         + "".join(f"\n  point {i}: {w}" for i, w in why[:5]))
                same = not why
        print(line)
        bad += not same
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
