"""orient's chatter detector on labelled simulated runs (sim.labelled, sim.sensors)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from orient.detect import ChatterDetector
from sim.labelled import LabelledCase, labelled_run, score_detector
from sim.sensors import Accelerometers, detector_settings


@pytest.fixture(scope="module")
def scores():
    det = ChatterDetector(detector_settings(Accelerometers()))
    out = []
    for i, rpm in enumerate((5500.0, 9000.0, 12500.0)):
        for kind in ("stable", "tool", "workpiece"):
            for noise in (0.3, 3.0):
                out.append(score_detector(labelled_run(LabelledCase(kind, rpm, noise, seed=i)),
                                          det))
    return out


def test_detection_rate_false_alarms_and_latency_meet_the_targets(scores):
    chat = [s for s in scores if s.label != "stable"]
    assert len(chat) == 12
    detected = [s for s in chat if s.detected is not None and s.latency_rev <= 20.0]
    assert len(detected) / len(chat) >= 0.95
    quiet = sum(s.quiet_windows for s in scores)
    assert quiet > 200          # enough quiet windows to measure a 2 % rate
    assert sum(s.false_alarms for s in scores) / quiet <= 0.02
    assert all(s.detected is None for s in scores if s.label == "stable")


def test_labels_come_from_the_analysis():
    """The label is the side whose modes dominate the compliance at the zero-order
    chatter frequency: near the flexible tool's 922 Hz for tool runs, near the
    wall's 1300 Hz for workpiece runs."""
    tool = labelled_run(LabelledCase("tool", 9000.0, 1.0, revolutions=30, onset_revolution=10))
    wall = labelled_run(LabelledCase("workpiece", 9000.0, 1.0, revolutions=30,
                                     onset_revolution=10))
    assert tool.label == "tool" and abs(tool.chatter_hz / 922.0 - 1) < 0.2
    assert wall.label == "workpiece" and abs(wall.chatter_hz / 1300.0 - 1) < 0.2
    stable = labelled_run(LabelledCase("stable", 9000.0, 1.0, revolutions=30))
    assert stable.label == "stable" and math.isnan(stable.onset_s)
    # before the onset the cut is stable: no clipping; chatter saturates the converter
    before = tool.signals.time_s < tool.onset_s
    full = np.abs(tool.signals.counts) >= 2 ** 15 - 1
    assert not full[before].any() and full[~before].any()


def test_bad_case():
    with pytest.raises(ValueError, match="kind"):
        LabelledCase("spindle", 9000.0, 1.0)
