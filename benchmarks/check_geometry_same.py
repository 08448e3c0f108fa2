"""Do code changes keep errpred's stage-1 answers? Digests of every PointGeometry.

Predicts the geometry stage (with the correction's sensitivity pass, as the
main job's dense predictions do) on the bench slices of
``benchmarks/bench_errpred.py`` (``--blocks`` consecutive blocks each), and
with ``--dense`` also at the dense verification's spacing, and writes one
SHA-256 digest per point of its pickle (the packed per-revolution arrays,
dtypes included), in order, to a JSON file (``--save``); ``--compare`` reads
such a file made by the code before a change and says which points differ
(exit 1 if any, or if the point counts differ).

Usage: python benchmarks/check_geometry_same.py (--save F | --compare F)
[--blocks N] [--slices NAMES] [--dense]
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import os
import pickle
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from errpred.pipeline import blocks_in_scope, build_predictor, load  # noqa: E402
from errpred.scenario import bundled_scenario  # noqa: E402

SLICES = {
    "contour": ("mold-ball", 6131),
    "raster": ("mold-ball", 19103),
    "wall-radius": ("wall-radius", 374),
}


def digests(name: str, n_blocks: int, dense: bool, zmap: bool | None) -> list[str]:
    scenario, first = SLICES[name]
    s = load(bundled_scenario(scenario))
    s = dataclasses.replace(s, lines=(first, 10**9))
    res = s.resolution.dense() if dense else None
    pred = build_predictor(s, resolution=res, sensitivity=True)
    pred.model.use_sweep_map = zmap
    blocks = blocks_in_scope(s, pred.program)[:n_blocks]
    return [hashlib.sha256(pickle.dumps(g, protocol=4)).hexdigest()
            for gl in pred.geometries(blocks) for g in gl]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    io = ap.add_mutually_exclusive_group(required=True)
    io.add_argument("--save", help="write the digests to this JSON file")
    io.add_argument("--compare", help="compare with the digests in this JSON file")
    ap.add_argument("--blocks", type=int, default=40)
    ap.add_argument("--slices", default=",".join(SLICES))
    ap.add_argument("--dense", action="store_true",
                    help="also at the dense verification's spacing (Resolution.dense)")
    args = ap.parse_args(argv)
    runs = {}
    for name in args.slices.split(","):
        if name not in SLICES:
            ap.error(f"--slices: unknown slice {name!r}; expected one of {', '.join(SLICES)}")
        # with and without the sweeps' height map: both ways of answering T1
        for zmap in (None, False):
            runs[f"{name} zmap={zmap}"] = digests(name, args.blocks, False, zmap)
        if args.dense:
            runs[f"{name} dense"] = digests(name, args.blocks, True, False)
    if args.save:
        with open(args.save, "w") as fh:
            json.dump(runs, fh, indent=0)
        print(f"{sum(map(len, runs.values()))} points in {args.save}")
        return 0
    with open(args.compare) as fh:
        ref = json.load(fh)
    bad = 0
    for key, got in runs.items():
        want = ref.get(key)
        if want is None:
            print(f"{key}: not in {args.compare}")
            bad += 1
            continue
        diff = [i for i, (a, b) in enumerate(zip(got, want)) if a != b]
        same = len(got) == len(want) and not diff
        print(f"{key}: {len(got)} points, {'same bytes' if same else f'{len(diff)} differ'}"
              + ("" if len(got) == len(want) else f" (reference {len(want)} points)"))
        bad += not same
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
