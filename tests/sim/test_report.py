"""Figures of a simulated run: chatter episodes, sustained against transient (sim.report)."""

from __future__ import annotations

import numpy as np
import pytest

from orient.detect import ChatterDetector, DetectorSettings
from sim.report import chatter_episodes, chatter_timeline, summarize_run

FS_HZ = 25600.0
RPM = 11400.0
TEETH = 2
F_RING_HZ = 3650.0          # between the tooth harmonics 3420 and 3800 Hz
WINDOW = 2048


def _detector() -> ChatterDetector:
    return ChatterDetector(DetectorSettings(FS_HZ, threshold=5.0, window_samples=WINDOW,
                                            hop_samples=256, harmonic_base="tooth",
                                            relative_threshold=0.05))


def _cut(seconds: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A steady cut: tooth harmonics of 100 m/s^2 on X and Y plus sensor noise."""
    t = np.arange(int(seconds * FS_HZ)) / FS_HZ
    f_tooth = RPM / 60.0 * TEETH
    x = sum(100.0 / m * np.cos(2 * np.pi * m * f_tooth * t + m) for m in range(1, 11))
    y = sum(100.0 / m * np.sin(2 * np.pi * m * f_tooth * t + 2 * m) for m in range(1, 11))
    acc = np.stack([x, y], axis=1) + 0.5 * rng.standard_normal((t.size, 2))
    return t, acc


def _ring(t: np.ndarray, start_s: float, amp: float, decay_s: float) -> np.ndarray:
    """A vibration at F_RING_HZ from ``start_s``: exp(-(t - start) / decay_s); decay_s
    = inf holds it (a self-excited vibration at its limit cycle)."""
    tau = np.clip(t - start_s, 0.0, None)
    env = np.where(t >= start_s, amp * np.exp(-tau / decay_s), 0.0)
    return np.stack([env * np.cos(2 * np.pi * F_RING_HZ * tau),
                     0.2 * env * np.sin(2 * np.pi * F_RING_HZ * tau)], axis=1)


# (end times of the calls, window [s], expected episodes (first, last, calls, sustained))
EPISODES = [
    ([], 0.08, []),
    ([1.00], 0.08, [(1.00, 1.00, 1, False)]),
    ([1.00, 1.01, 1.02], 0.08, [(1.00, 1.02, 3, False)]),
    ([1.00, 1.04, 1.08, 1.12], 0.08, [(1.00, 1.12, 4, True)]),
    ([1.00, 1.01, 2.00, 2.05, 2.10], 0.08, [(1.00, 1.01, 2, False), (2.00, 2.10, 3, True)]),
    ([1.00, 1.08], 0.08, [(1.00, 1.00, 1, False), (1.08, 1.08, 1, False)]),
]


@pytest.mark.parametrize(("calls", "window_s", "expected"), EPISODES)
def test_chatter_episodes_from_a_table(calls, window_s, expected):
    end = np.round(np.arange(0.5, 2.5, 0.01), 6)
    chatter = np.isin(end, np.round(calls, 6))
    got = chatter_episodes(end, chatter, window_s)
    assert [(pytest.approx(a), pytest.approx(b), n, s) for a, b, n, s in got] == expected


def test_a_ringing_that_dies_within_its_window_is_a_transient_and_chatter_is_sustained():
    rng = np.random.default_rng(11)
    t, acc = _cut(1.5, rng)
    window_s = WINDOW / FS_HZ
    # a step of the cut at 0.5 s: the structure rings 200 m/s^2, decaying in 5 ms
    ringing = acc + _ring(t, 0.5, 200.0, 0.005)
    ring = summarize_run(t, ringing, {}, _detector(), RPM, TEETH)
    assert ring["chatter_windows"] >= 1                      # the detector does call it
    assert ring["sustained_episodes"] == 0
    assert all(e["last_s"] - e["first_s"] < window_s for e in ring["episodes"])
    # the same vibration held from 0.5 s on (self-excited): one sustained episode
    held = summarize_run(t, acc + _ring(t, 0.5, 40.0, np.inf), {}, _detector(), RPM, TEETH)
    assert held["sustained_episodes"] == 1
    assert held["episodes"][0]["first_s"] < 0.5 + window_s
    assert held["episodes"][0]["last_s"] == pytest.approx(t[-1], abs=0.011)
    # nothing added: no call at all
    quiet = summarize_run(t, acc, {}, _detector(), RPM, TEETH)
    assert quiet["chatter_windows"] == 0 and quiet["episodes"] == []


@pytest.mark.parametrize("chunk_windows", [2, 3, 37, 56, 10_000])
def test_a_run_judged_in_chunks_gets_the_verdicts_of_the_whole_run_fed_at_once(chunk_windows):
    rng = np.random.default_rng(5)
    t, acc = _cut(1.2, rng)                      # 113 windows: 2 and 56 leave one at the end
    t = t + 3.0                                  # a stream that does not start at 0 s
    acc = acc + _ring(t, 3.55, 40.0, np.inf)     # quiet, then chatter to the end
    det = _detector()
    det.reset()
    whole = det.feed(acc[:, 0], acc[:, 1], RPM, TEETH)
    fs = det.settings.sample_rate_hz
    tl = chatter_timeline(t, acc, det, RPM, TEETH, chunk_windows=chunk_windows)
    chatter = np.array([d.chatter for d in whole])
    assert chatter.any() and not chatter.all()   # the signal holds both verdicts
    assert np.array_equal(tl["chatter"], chatter)
    assert np.array_equal(tl["amplitude"], [d.amplitude for d in whole], equal_nan=True)
    assert np.array_equal(tl["frequency_hz"], [d.frequency_hz for d in whole], equal_nan=True)
    assert np.array_equal(tl["end_s"], t[0] + np.array([d.sample_index for d in whole]) / fs)
    assert list(tl["cause"]) == [d.cause or "" for d in whole]


def test_chatter_timeline_refuses_a_chunk_of_one_window():
    t, acc = _cut(0.1, np.random.default_rng(0))
    with pytest.raises(ValueError, match="chunk_windows"):
        chatter_timeline(t, acc, _detector(), RPM, TEETH, chunk_windows=1)
