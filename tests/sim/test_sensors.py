"""Accelerometer chain (sim.sensors): gains, ADC scaling, noise, frame."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from sim.sensors import Accelerometers, sample_accelerometers


def _sine(f_hz, amp, fs_sim=200_000.0, dur=0.2, axis=0):
    t = np.arange(int(dur * fs_sim)) / fs_sim
    a = np.zeros((t.size, 3))
    a[:, axis] = amp * np.sin(2 * math.pi * f_hz * t)
    return t, a


def _amplitude(x, fs, f):
    n = x.size
    t = np.arange(n) / fs
    return 2 * abs(np.sum(x * np.exp(-2j * math.pi * f * t))) / n


def test_in_band_gain_is_the_location_factor_and_counts_scale_back():
    s = Accelerometers(noise_rms_m_s2=0.0)
    t, a = _sine(1000.0, 100.0)
    out = sample_accelerometers(t, a, s)
    x = out.acceleration_m_s2[out.time_s > 0.05, 0]
    amp = _amplitude(x - x.mean(), s.sample_rate_hz, 1000.0)
    # Butterworth at 10.24 kHz and a 28 kHz resonance: flat within 0.5 % at 1 kHz
    assert amp == pytest.approx(s.location_factor * 100.0, rel=0.005)
    np.testing.assert_array_equal(out.acceleration_m_s2, out.counts * s.lsb_m_s2)
    assert s.lsb_m_s2 == pytest.approx(1000.0 / 65536)
    assert np.all(np.abs(out.acceleration_m_s2[:, 1]) == 0)


def test_antialias_filter_attenuates_above_nyquist():
    """A 20 kHz vibration (above the 12.8 kHz Nyquist) aliases to 5.6 kHz attenuated by
    the analog chain's gain there: Butterworth order n at fc, |H| = (1 + (f/fc)^2n)^-1/2,
    times the mounted resonance 1 / |1 - (f/fr)^2 + 2 i zeta f/fr|."""
    s = Accelerometers(noise_rms_m_s2=0.0)
    t, a = _sine(20_000.0, 100.0, fs_sim=2e6, dur=0.1)   # input resolved: the chain alone
    out = sample_accelerometers(t, a, s)
    x = out.acceleration_m_s2[out.time_s > 0.05, 0]
    alias = s.sample_rate_hz - 20_000.0
    fc = s.antialias_fraction * s.sample_rate_hz
    r = 20_000.0 / s.resonance_hz
    gain = (1 + (20_000.0 / fc) ** (2 * s.antialias_order)) ** -0.5 \
        / abs(1 - r * r + 2j * s.resonance_damping * r)
    assert gain < 0.01
    assert _amplitude(x, s.sample_rate_hz, alias) == pytest.approx(
        s.location_factor * 100.0 * gain, rel=0.1)


def test_noise_level_and_seed():
    s = Accelerometers(noise_rms_m_s2=2.0)
    t = np.arange(20_000) / 100_000.0
    a = np.zeros((t.size, 3))
    one = sample_accelerometers(t, a, s, seed=3)
    two = sample_accelerometers(t, a, s, seed=3)
    np.testing.assert_array_equal(one.counts, two.counts)
    assert np.std(one.acceleration_m_s2, axis=0) == pytest.approx([2.0, 2.0], rel=0.05)


def test_rotation_to_machine_frame_and_clipping():
    s = Accelerometers(noise_rms_m_s2=0.0, range_m_s2=10.0)
    t, a = _sine(500.0, 100.0, axis=0)
    c, si = math.cos(0.3), math.sin(0.3)
    R = np.array([[c, si, 0], [-si, c, 0], [0, 0, 1.0]])
    out = sample_accelerometers(t, a, Accelerometers(noise_rms_m_s2=0.0), rotation=R)
    x = out.acceleration_m_s2[out.time_s > 0.05]
    ax = _amplitude(x[:, 0], s.sample_rate_hz, 500.0)
    ay = _amplitude(x[:, 1], s.sample_rate_hz, 500.0)
    assert ay / ax == pytest.approx(math.tan(0.3), rel=0.01)
    clipped = sample_accelerometers(t, a, s)
    assert clipped.clipped > 0
    assert clipped.counts.max() == 2 ** 15 - 1


def test_bad_input():
    with pytest.raises(ValueError, match="antialias_fraction"):
        Accelerometers(antialias_fraction=0.6)
    with pytest.raises(ValueError, match="noise_rms_m_s2"):
        Accelerometers(noise_rms_m_s2=float("nan"))
    t = np.arange(10) / 1e4
    with pytest.raises(ValueError, match="tool_acceleration_m_s2"):
        sample_accelerometers(t, np.zeros((9, 3)), Accelerometers())
    with pytest.raises(ValueError, match="rotation"):
        sample_accelerometers(t, np.zeros((10, 3)), Accelerometers(), rotation=np.ones((3, 3)))


def test_stream_in_chunks_equals_one_call():
    from sim.sensors import AccelerometerStream

    rng = np.random.default_rng(5)
    t = np.arange(30_000) / 120_000.0
    a = rng.normal(0, 50, size=(t.size, 3))
    s = Accelerometers(noise_rms_m_s2=0.0)
    one = sample_accelerometers(t, a, s)
    st = AccelerometerStream(s, 1 / 120_000.0)
    cuts = (0, 77, 1000, 5000, 17_333, t.size)
    parts = [st.push(t[i:j], a[i:j]) for i, j in itertools.pairwise(cuts)]
    counts = np.concatenate([p.counts for p in parts])
    n = one.counts.shape[0]
    np.testing.assert_array_equal(counts[:n], one.counts)
    np.testing.assert_allclose(np.concatenate([p.time_s for p in parts])[:n], one.time_s,
                               atol=1e-12)


def test_stream_push_many_equals_push_chunk_by_chunk():
    """Several ticks at once give the samples of pushing them one by one, bit for bit
    (noise included), and say how many came from each tick."""
    from sim.sensors import AccelerometerStream

    rng = np.random.default_rng(7)
    dt = 1 / 120_000.0
    t = np.arange(20_000) * dt
    a = rng.normal(0, 50, size=(t.size, 3))
    cuts = (0, 3, 77, 600, 601, 601, 5000, 12_345, t.size)
    s = Accelerometers(noise_rms_m_s2=0.5)
    one = AccelerometerStream(s, dt, seed=3)
    each = [one.push(t[i:j], a[i:j]) for i, j in itertools.pairwise(cuts)]
    many = AccelerometerStream(s, dt, seed=3)
    pairs = list(itertools.pairwise(cuts))
    first, n1 = many.push_many([t[i:j] for i, j in pairs[:4]], [a[i:j] for i, j in pairs[:4]])
    rest, n2 = many.push_many([t[i:j] for i, j in pairs[4:]], [a[i:j] for i, j in pairs[4:]])
    np.testing.assert_array_equal(np.r_[n1, n2], [p.time_s.size for p in each])
    assert sum(p.time_s.size for p in each) > 2000
    for key in ("time_s", "counts", "acceleration_m_s2"):
        np.testing.assert_array_equal(
            np.concatenate([getattr(first, key), getattr(rest, key)]),
            np.concatenate([getattr(p, key) for p in each]))
    assert many.samples == one.samples
