"""Chatter detector on labelled simulated runs (issue 5: sensors and detection).

Targets: detection >= 95 %, false alarms <= 2 %, detection within 20 spindle
revolutions of the onset. The runs (:mod:`sim.labelled`): stable, tool-side
and workpiece-side chatter, at several spindle speeds and sensor noise levels
(labels from orient's analysis, not from the detector); the detector is
orient's (:mod:`orient.detect`) with the simulated machine's settings
(:func:`sim.sensors.detector_settings`). Prints the confusion matrix (label
x verdict), the detection rate, the false-alarm rate over the windows before
the onset (and all windows of stable runs), the latency, and the detector's
time per window.

Usage: python benchmarks/bench_detector.py [--speeds N] [--seeds N]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.abspath(os.path.join(os.path.dirname(__file__), "..")))

from orient.detect import ChatterDetector
from sim.labelled import KINDS, LabelledCase, labelled_run, score_detector
from sim.sensors import Accelerometers, detector_settings

NOISE_M_S2 = (0.3, 1.0, 3.0)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", type=int, default=9, help="spindle speeds from 5000 to 13000")
    ap.add_argument("--seeds", type=int, default=2, help="noise seeds per case")
    args = ap.parse_args(argv)
    detector = ChatterDetector(detector_settings(Accelerometers()))
    scores, t_sim = [], 0.0
    for kind in KINDS:
        for rpm in np.linspace(5000.0, 13000.0, args.speeds):
            for noise in NOISE_M_S2:
                for seed in range(args.seeds):
                    t0 = time.perf_counter()
                    run = labelled_run(LabelledCase(kind, float(rpm), noise, seed=seed))
                    t_sim += time.perf_counter() - t0
                    scores.append(score_detector(run, detector))
    labels, verdicts = ("stable", "tool", "workpiece"), (None, "tool", "workpiece")
    print(f"{len(scores)} labelled runs ({args.speeds} speeds 5000-13000 rev/min x noise "
          f"{NOISE_M_S2} m/s^2 x {args.seeds} seeds x 3 kinds); simulation {t_sim:.1f} s")
    print("\nconfusion (rows: label, columns: first verdict after the onset)")
    print(f"{'':>10} " + " ".join(f"{v or 'none'!s:>10}" for v in verdicts))
    for lab in labels:
        row = [sum(1 for s in scores if s.label == lab and s.detected == v) for v in verdicts]
        print(f"{lab:>10} " + " ".join(f"{c:>10d}" for c in row))
    chat = [s for s in scores if s.label != "stable"]
    within = [s for s in chat if s.detected is not None and s.latency_rev <= 20.0]
    right = [s for s in within if s.detected == s.label]
    fa = sum(s.false_alarms for s in scores) / max(1, sum(s.quiet_windows for s in scores))
    lat = np.array([s.latency_rev for s in chat if math.isfinite(s.latency_rev)])
    print(f"\ndetection within 20 rev: {len(within)}/{len(chat)} = {len(within) / len(chat):.1%} "
          f"(target >= 95 %); right cause {len(right)}/{len(chat)} = {len(right) / len(chat):.1%}")
    print(f"false alarms: {sum(s.false_alarms for s in scores)} of "
          f"{sum(s.quiet_windows for s in scores)} quiet windows = {fa:.2%} (target <= 2 %)")
    if lat.size:
        print(f"latency [rev]: median {np.median(lat):.1f}, p95 {np.percentile(lat, 95):.1f}, "
              f"max {lat.max():.1f} (target <= 20)")
    # time per window
    run = labelled_run(LabelledCase("tool", 9000.0, 1.0, seed=0, revolutions=200))
    a = run.signals.acceleration_m_s2
    detector.reset()
    t0 = time.perf_counter()
    n = len(detector.feed(a[:, 0], a[:, 1], 9000.0, 2))
    dt = time.perf_counter() - t0
    st = detector.settings
    print(f"\ndetector: {n} windows of {st.window_samples} samples (hop {st.hop_samples}) in "
          f"{dt * 1e3:.1f} ms = {dt / n * 1e6:.0f} us per window; the stream's real time per "
          f"hop is {st.hop_samples / st.sample_rate_hz * 1e3:.1f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
