"""What the verified correction costs against a prediction alone, on the bundled scenarios.

For each slice of a bundled scenario (``program.lines``), in this process:

* ``predict``: the scenario's own prediction (one point per stretch of a block that
  cuts, the default resolution), repeated, min and median;
* ``dense``: the dense prediction the verification uses (every block end and at most
  2 mm apart), repeated, min and median, and its number of points;
* ``compensate``: the whole verified correction (``errpred compensate --iterate``: the
  original and every candidate predicted densely), once, with its number of dense
  predictions, the result (verified or not) and the largest |E| and RMS before and
  after on the dense points;
* the ratios compensate / predict and dense / predict.

The machine is shared and noisy: take the ratios, not the seconds.

Usage: python benchmarks/bench_compensate.py [--repeat N] [--slices NAME:FIRST:LAST ...]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from errpred.pipeline import compensate_scenario, load, predict  # noqa: E402
from errpred.scenario import bundled_scenario  # noqa: E402

#: Default slices: a few blocks of each bundled scenario's representative slices.
SLICES = ("wall-radius:38:43", "mold-ball:19103:19142", "mold-ball:6131:6150")


def _times(fn, repeat: int) -> tuple[float, float, object]:
    out, ts = None, []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t0)
    return min(ts), statistics.median(ts), out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--slices", nargs="+", default=list(SLICES))
    args = ap.parse_args(argv)
    print(f"{'slice':<24} {'blocks':>6} {'predict s':>16} {'dense s (points)':>22} "
          f"{'compensate s (pred.)':>22} {'x predict':>9}  result")
    for spec in args.slices:
        name, lo, hi = spec.split(":")
        s = dataclasses.replace(load(bundled_scenario(name)), lines=(int(lo), int(hi)))
        stock = s.stock.load()
        prog = s.read_program()
        blocks = int(((prog.line >= int(lo)) & (prog.line <= int(hi))).sum())
        p_min, p_med, _ = _times(lambda s=s: predict(s, stock=stock), args.repeat)
        d_min, d_med, dense = _times(
            lambda s=s: predict(s, stock=stock, resolution=s.resolution.dense()), args.repeat)
        n_dense = len(dense.predicted())
        s_it = dataclasses.replace(s, correction=dataclasses.replace(s.correction,
                                                                     iterate=True))
        t0 = time.perf_counter()
        comp = compensate_scenario(s_it)
        t_comp = time.perf_counter() - t0
        v = comp.verified
        b, a = v.before_stats, v.after_stats
        result = (f"{'verified' if comp.corrected else 'not corrected'}: max |E| "
                  f"{b.max_abs_um:.2f} -> {a.max_abs_um:.2f} um, RMS {b.rms_um:.2f} -> "
                  f"{a.rms_um:.2f} um")
        print(f"{spec:<24} {blocks:>6} {p_min:>7.2f} / {p_med:>6.2f} "
              f"{d_min:>8.2f} / {d_med:>6.2f} ({n_dense:>4}) {t_comp:>12.1f} "
              f"({len(v.predictions):>2}) {t_comp / p_min:>9.1f}  {result}")
        print(f"{'':<24} dense / predict {d_min / p_min:.2f}; per dense prediction "
              f"{t_comp / len(v.predictions):.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
