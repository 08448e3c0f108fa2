"""Chatter detector on synthetic two-channel signals (orient/detect.py).

Every signal is built here from closed-form sinusoids and seeded noise, so the
true frequency, amplitude and X/Y phase are known exactly.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from orient.detect import ChatterDetector, Detection, DetectorSettings

FS = 10_000.0            # sample rate [Hz]
N = 1024                 # window [samples]
HOP = 256                # hop [samples]
THRESHOLD = 1.0          # [m/s^2]


def _settings(**kw) -> DetectorSettings:
    return DetectorSettings(FS, THRESHOLD, window_samples=N, hop_samples=HOP, **kw)


def _time(n: int, start: int = 0) -> np.ndarray:
    return (start + np.arange(n)) / FS


def _harmonics(rng, t, rpm, teeth, peak):
    """X, Y: random spindle harmonics (tooth-passing strongest), random phases."""
    f_sp = rpm / 60.0
    x = np.zeros_like(t)
    y = np.zeros_like(t)
    for m in range(1, int(0.45 * FS / f_sp)):
        a = peak * (1.0 if m % teeth == 0 else 0.2) * rng.uniform(0.2, 1.0) / (1 + 0.1 * m)
        x += a * np.cos(2 * np.pi * m * f_sp * t + rng.uniform(0, 2 * np.pi))
        y += a * rng.uniform(0.3, 1.0) * np.cos(2 * np.pi * m * f_sp * t
                                                 + rng.uniform(0, 2 * np.pi))
    return x, y


def _free_frequency(rng, rpm, margin_hz):
    """A frequency at least ``margin_hz`` from every spindle harmonic, in (200, 4000) Hz."""
    f_sp = rpm / 60.0
    assert f_sp / 2 > margin_hz + 1.0, "no room between the harmonics"
    while True:
        f = rng.uniform(200.0, 4000.0)
        if abs(f - round(f / f_sp) * f_sp) >= margin_hz:
            return f


def _noise_sigma(rng, settings):
    """Noise std for a per-bin noise amplitude rms in [0, threshold/4] (Hann: 2 s sqrt(1.5/N))."""
    rms_amp = rng.uniform(0.0, 0.25) * settings.threshold
    return rms_amp / (2.0 * math.sqrt(1.5 / settings.window_samples))


def test_sinusoid_frequency_within_a_fraction_of_a_bin_and_amplitude_within_2_percent():
    rng = np.random.default_rng(1)
    det = ChatterDetector(_settings())
    t = _time(N)
    df = FS / N
    ferr, aerr = [], []
    for _ in range(200):
        rpm = rng.uniform(8000, 20000)
        f = _free_frequency(rng, rpm, 3 * df + 2 * df)
        a = rng.uniform(2.0, 10.0)
        ph = rng.uniform(0, 2 * np.pi)
        ax = a * np.cos(2 * np.pi * f * t + ph) + rng.normal(0, 0.01, N)
        ay = 0.5 * a * np.cos(2 * np.pi * f * t + ph + 0.3) + rng.normal(0, 0.01, N)
        d = det.analyze(ax, ay, rpm, 2)
        assert d.chatter
        ferr.append(abs(d.frequency_hz - f) / df)
        aerr.append(max(abs(d.amplitude_x / a - 1), abs(d.amplitude_y / (0.5 * a) - 1),
                        abs(d.amplitude / (a * math.hypot(1, 0.5)) - 1)))
    # measured: frequency error <= 0.02 bin, amplitude error <= 0.8 %
    assert max(ferr) < 0.1
    assert max(aerr) < 0.02


def test_harmonics_plus_noise_give_few_false_alarms_and_chatter_is_found():
    """500 random windows: speeds, teeth, harmonic content up to 20x threshold, noise."""
    rng = np.random.default_rng(2)
    s = _settings()
    det = ChatterDetector(s)
    t = _time(N)
    false_alarms = detected = injected = strong_harmonics = 0
    trials = 500
    for _ in range(trials):
        rpm = rng.uniform(3000, 24000)
        teeth = int(rng.integers(1, 5))
        x, y = _harmonics(rng, t, rpm, teeth, peak=rng.uniform(1.0, 20.0))
        sigma = _noise_sigma(rng, s)
        x = x + rng.normal(0, sigma, N)
        y = y + rng.normal(0, sigma, N)
        d = det.analyze(x, y, rpm, teeth)
        false_alarms += d.chatter
        strong_harmonics += d.harmonic_amplitude > 5 * THRESHOLD
        # the same window with a chatter component at 2x threshold, where there is room
        margin = s.band_hz + 3 * s.bin_hz
        if rpm / 60.0 / 2 <= margin + 1.0:
            continue
        injected += 1
        f = _free_frequency(rng, rpm, margin)
        ph = rng.uniform(0, 2 * np.pi)
        xc = x + 2.0 * np.cos(2 * np.pi * f * t + ph)
        yc = y + 2.0 * np.sin(2 * np.pi * f * t + ph)
        dc = det.analyze(xc, yc, rpm, teeth)
        if dc.chatter and abs(dc.frequency_hz - f) <= s.bin_hz:
            detected += 1
    assert strong_harmonics > trials // 2          # the check is not vacuous
    assert false_alarms <= 0.02 * trials           # measured: 0
    assert injected > 0.8 * trials
    assert detected >= 0.98 * injected             # measured: all


def test_circular_whirl_is_tool_side_and_one_directional_is_workpiece_side():
    det = ChatterDetector(_settings())
    t = _time(N)
    rpm, f = 12000.0, 1234.5
    w = 2 * np.pi * f * t
    cases = {
        "circular": (3 * np.cos(w), 3 * np.sin(w), "tool"),
        "circular, reverse": (3 * np.cos(w), -3 * np.sin(w), "tool"),
        "elliptic 60 deg": (3 * np.cos(w), 2.5 * np.cos(w - np.radians(60)), "tool"),
        "in phase": (3 * np.cos(w), 2 * np.cos(w), "workpiece"),
        "anti-phase": (3 * np.cos(w), -2 * np.cos(w), "workpiece"),
        "nearly in phase (20 deg)": (3 * np.cos(w), 3 * np.cos(w - np.radians(20)), "workpiece"),
        "along X only": (3 * np.cos(w), 0 * w, "workpiece"),
        "90 deg but 10:1": (3 * np.cos(w), 0.3 * np.sin(w), "workpiece"),
    }
    for name, (ax, ay, cause) in cases.items():
        d = det.analyze(ax, ay, rpm, 2)
        assert d.chatter, name
        assert d.cause == cause, (name, d.whirl, d.phase_rad)
    d = det.analyze(3 * np.cos(w), 3 * np.sin(w), rpm, 2)
    # X = cos(w t), Y = sin(w t) = cos(w t - pi/2): X leads Y by +90 deg
    assert d.phase_rad == pytest.approx(np.pi / 2, abs=1e-6)
    assert d.whirl == pytest.approx(1.0, abs=1e-6)
    d = det.analyze(3 * np.cos(w), -2 * np.cos(w), rpm, 2)
    assert abs(abs(d.phase_rad) - np.pi) < 1e-6 and d.whirl < 1e-6


def test_phase_threshold_separates_at_the_stated_angle():
    t = _time(N)
    w = 2 * np.pi * 1575.3 * t      # midway between harmonics of 150 Hz
    for thr_deg in (30.0, 45.0, 60.0):
        det = ChatterDetector(_settings(phase_threshold_rad=math.radians(thr_deg)))
        below = det.analyze(np.cos(w) * 3, 3 * np.cos(w - math.radians(thr_deg - 3)), 9000, 2)
        above = det.analyze(np.cos(w) * 3, 3 * np.cos(w - math.radians(thr_deg + 3)), 9000, 2)
        assert (below.cause, above.cause) == ("workpiece", "tool")


def test_onset_in_a_stream_is_detected_within_half_a_window_plus_a_hop():
    """Chatter (3x threshold) starts at a known sample; chunks of random sizes.

    Stated latency: at most N/2 + hop samples after the onset (0.0768 s, i.e.
    15.4 revolutions at 12000 rev/min with N = 1024, hop = 256, 10 kHz).
    """
    rng = np.random.default_rng(3)
    rpm, teeth = 12000.0, 2
    total, onset = 30_000, 12_345
    t = _time(total)
    x, y = _harmonics(rng, t, rpm, teeth, peak=10.0)
    x += rng.normal(0, 0.02, total)
    y += rng.normal(0, 0.02, total)
    f = 1111.0
    on = np.arange(total) >= onset
    x = x + on * 3.0 * np.cos(2 * np.pi * f * t)
    y = y + on * 3.0 * np.cos(2 * np.pi * f * t + 0.2)

    det = ChatterDetector(_settings())
    dets: list[Detection] = []
    i = 0
    while i < total:
        k = int(rng.integers(1, 700))
        dets += det.feed(x[i:i + k], y[i:i + k], rpm, teeth)
        i += k
    ends = np.array([d.sample_index for d in dets])
    np.testing.assert_array_equal(ends, np.arange(N, total + 1, HOP))
    flags = np.array([d.chatter for d in dets])
    assert not np.any(flags[ends <= onset])                      # no alarm before
    first = ends[np.argmax(flags)]
    latency = first - onset
    assert 0 < latency <= N // 2 + HOP
    revs = latency / FS * rpm / 60.0
    assert revs <= (N / 2 + HOP) / FS * rpm / 60.0
    assert np.all(flags[ends >= onset + N])                      # and it stays
    assert all(d.cause == "workpiece" for d in dets if d.chatter)

    # the same signal fed in one piece gives the same detections
    one = ChatterDetector(_settings()).feed(x, y, rpm, teeth)
    assert [(d.sample_index, d.chatter, d.frequency_hz) for d in one] == \
        [(d.sample_index, d.chatter, d.frequency_hz) for d in dets]
    assert det.samples_seen == total


def test_flip_chatter_at_half_tooth_passing_needs_tooth_base():
    """Two teeth: flip chatter at ft/2 = spindle frequency x odd integers."""
    t = _time(N)
    rpm, teeth = 9000.0, 2
    f_sp = rpm / 60.0
    f_flip = 3 * f_sp                # = 1.5 ft: a spindle harmonic, not a tooth harmonic
    x = 5 * np.cos(2 * np.pi * 2 * f_sp * t) + 3 * np.cos(2 * np.pi * f_flip * t)
    y = 5 * np.sin(2 * np.pi * 2 * f_sp * t) + 3 * np.cos(2 * np.pi * f_flip * t + 0.1)
    assert not ChatterDetector(_settings()).analyze(x, y, rpm, teeth).chatter
    d = ChatterDetector(_settings(harmonic_base="tooth")).analyze(x, y, rpm, teeth)
    assert d.chatter and abs(d.frequency_hz - f_flip) < FS / N


def test_relative_threshold_compares_with_the_harmonic_content():
    t = _time(N)
    rpm = 6000.0
    x = 100 * np.cos(2 * np.pi * 200 * t) + 2 * np.cos(2 * np.pi * 750 * t)
    y = 100 * np.sin(2 * np.pi * 200 * t)
    d = ChatterDetector(_settings()).analyze(x, y, rpm, 2)
    assert d.chatter
    assert d.harmonic_amplitude == pytest.approx(100 * math.sqrt(2), rel=0.02)
    assert d.harmonic_ratio == pytest.approx(2 / (100 * math.sqrt(2)), rel=0.03)
    d = ChatterDetector(_settings(relative_threshold=0.05)).analyze(x, y, rpm, 2)
    assert not d.chatter and d.cause is None


def test_speed_tolerance_widens_high_harmonic_bands():
    t = _time(N)
    rpm_true, rpm_read = 12000.0, 12000.0 * 1.01      # speed read 1 % high
    f = 15 * rpm_true / 60.0                           # 15th harmonic: 3000 Hz, 30 Hz off
    x = 5 * np.cos(2 * np.pi * f * t)
    y = 5 * np.sin(2 * np.pi * f * t)
    assert ChatterDetector(_settings()).analyze(x, y, rpm_read, 2).chatter
    assert not ChatterDetector(_settings(speed_tolerance=0.015)).analyze(x, y, rpm_read,
                                                                          2).chatter


def test_silence_and_dense_harmonics():
    det = ChatterDetector(_settings())
    d = det.analyze(np.zeros(N), np.zeros(N), 6000, 2)
    assert not d.chatter and d.cause is None
    # harmonics closer than two bands: no candidate bin at all
    d = ChatterDetector(_settings(harmonic_band_hz=60.0)).analyze(
        np.random.default_rng(4).normal(size=N), np.zeros(N), 6000, 2)
    assert not d.chatter and math.isnan(d.frequency_hz)


def test_time_per_window_is_reported():
    det = ChatterDetector(_settings())
    rng = np.random.default_rng(5)
    d = det.analyze(rng.normal(size=N), rng.normal(size=N), 10000, 2)
    many = det.feed(rng.normal(size=100 * HOP + N), rng.normal(size=100 * HOP + N), 10000, 2)
    assert d.elapsed_s > 0 and len(many) == 101
    # generous bound (measured ~0.1 ms per window batched, ~0.3 ms alone)
    assert max(x.elapsed_s for x in many) < 0.01


@pytest.mark.parametrize("kw, match", [
    ({"sample_rate_hz": 0.0}, "sample_rate_hz"),
    ({"sample_rate_hz": math.nan}, "sample_rate_hz"),
    ({"threshold": -1.0}, "threshold"),
    ({"window_samples": 8}, "window_samples"),
    ({"hop_samples": 2000}, "hop_samples"),
    ({"window": "kaiser"}, "window"),
    ({"harmonic_band_hz": 5.0}, "main-lobe"),
    ({"phase_threshold_rad": 2.0}, "phase_threshold_rad"),
    ({"harmonic_base": "flute"}, "harmonic_base"),
    ({"speed_tolerance": 0.7}, "speed_tolerance"),
    ({"max_frequency_hz": 6000.0}, "max_frequency_hz"),
])
def test_invalid_settings_are_refused(kw, match):
    args = {"sample_rate_hz": FS, "threshold": THRESHOLD, "window_samples": N,
            "hop_samples": HOP}
    args.update(kw)
    with pytest.raises(ValueError, match=match):
        DetectorSettings(**args)


def test_invalid_samples_and_speeds_are_refused():
    det = ChatterDetector(_settings())
    good = np.zeros(N)
    bad = good.copy()
    bad[17] = np.nan
    with pytest.raises(ValueError, match="ax.*index 17"):
        det.analyze(bad, good, 6000, 2)
    with pytest.raises(ValueError, match="ay"):
        det.analyze(good, np.where(good == 0, np.inf, 0), 6000, 2)
    with pytest.raises(ValueError, match="window_samples"):
        det.analyze(good[:-1], good[:-1], 6000, 2)
    with pytest.raises(ValueError, match="spindle_rpm"):
        det.analyze(good, good, 0.0, 2)
    with pytest.raises(ValueError, match="teeth"):
        det.analyze(good, good, 6000, 0)
    det.feed(np.ones(100), np.ones(100), 6000, 2)
    with pytest.raises(ValueError, match="ay"):
        det.feed(np.ones(10), bad[:10] * 0 + np.nan, 6000, 2)
    with pytest.raises(ValueError, match="equal lengths"):
        det.feed(np.ones(10), np.ones(11), 6000, 2)
    assert det.samples_seen == 100            # refused chunks are not buffered


def test_from_durations():
    s = DetectorSettings.from_durations(FS, 2.0, window_s=0.1024, hop_s=0.0256)
    assert (s.window_samples, s.hop_samples) == (1024, 256)
    assert s.window_s == pytest.approx(0.1024) and s.bin_hz == pytest.approx(FS / 1024)


@pytest.mark.parametrize("n", [16, 17, 1024, 2049])
@pytest.mark.parametrize("window", ["hann", "hamming", "blackman", "blackmanharris",
                                    "boxcar", "random"])
def test_window_response_from_its_lines_equals_the_direct_sum(window, n):
    """The window's response at fractional bins, from its DFT lines (Dirichlet kernels),
    against the sum over its N samples; a window that is no cosine sum (random: all its
    lines kept) as well."""
    from scipy.signal import get_window

    from orient.detect import window_lines, window_response

    rng = np.random.default_rng(n)
    w = rng.uniform(0.1, 1.0, n) if window == "random" else get_window(window, n,
                                                                        fftbins=True)
    d = np.concatenate([rng.uniform(-0.5, 0.5, 100), [0.0, 0.5, -0.5, 1e-12, -1e-9]])
    direct = np.abs(np.exp(-2j * np.pi * np.outer(d, np.arange(n)) / n) @ w)
    lines = window_lines(w)
    got = window_response(lines, n, d)
    assert got.shape == d.shape
    np.testing.assert_allclose(got, direct, rtol=1e-13)
    if window != "random":       # a cosine sum of K terms has 2K - 1 lines
        assert lines[0].size <= 7
    # at a line's own bin the Dirichlet kernel is N: the response is |sum(w)|
    assert window_response(lines, n, np.zeros(1))[0] == pytest.approx(abs(w.sum()), rel=1e-14)
