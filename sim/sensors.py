"""Two accelerometers near the spindle nose (``docs/method.md`` §7-8).

The simulated tool's acceleration (its modes only: the sensors sit on the
spindle, they do not touch the workpiece) is turned into what a data
acquisition card delivers:

1. *location*: the spindle nose moves ``location_factor`` times as much as the
   tool tip in the tool's bending modes (a mode shape ratio);
2. *frame*: workpiece frame to the machine's X and Y (``rotation``);
3. *sensor and conditioning*: the accelerometer's mounted resonance (second
   order, unit gain at low frequency) and an analog anti-alias low-pass
   (Butterworth) at ``antialias_fraction`` of the sample rate, integrated
   exactly for an input linear between the simulation's steps (first-order
   hold, so no frequency warping whatever the step);
4. *noise*: white, ``noise_rms_m_s2`` per channel (seeded generator);
5. *sampling and ADC*: linear interpolation to the sample instants, then a
   ``bits``-bit converter over ``+- range_m_s2``: counts, clipped.

Units: m/s^2 in, counts and m/s^2 out, Hz, s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import signal

from nc.checks import real_number
from orient.detect import DetectorSettings

from . import _kernels as _k
from .constants import (
    DETECTOR_HARMONIC_BASE,
    DETECTOR_HOP_SAMPLES,
    DETECTOR_RELATIVE_THRESHOLD,
    DETECTOR_THRESHOLD_M_S2,
    DETECTOR_WINDOW_SAMPLES,
)

__all__ = ["AccelerometerStream", "Accelerometers", "SensorSignals", "detector_settings",
           "sample_accelerometers"]


@dataclass(frozen=True)
class Accelerometers:
    """The sensor pair and its acquisition chain.

    Parameters
    ----------
    sample_rate_hz : float [Hz]
        ADC rate.
    location_factor : float [-]
        Spindle-nose motion per tool-tip motion in the bending modes.
    resonance_hz : float [Hz]
        Mounted resonance of the accelerometers.
    resonance_damping : float [-]
        Its damping ratio.
    antialias_fraction : float [-]
        Anti-alias corner as a fraction of the sample rate (< 0.5).
    antialias_order : int
        Butterworth order.
    noise_rms_m_s2 : float [m/s^2]
        White noise per channel (sensor, cable, converter).
    range_m_s2 : float [m/s^2]
        Full scale: +- this.
    bits : int
        Converter resolution.
    """

    sample_rate_hz: float = 25_600.0
    location_factor: float = 0.3
    resonance_hz: float = 28_000.0
    resonance_damping: float = 0.05
    antialias_fraction: float = 0.4
    antialias_order: int = 8
    noise_rms_m_s2: float = 0.5
    range_m_s2: float = 500.0
    bits: int = 16

    def __post_init__(self) -> None:
        real_number("sample_rate_hz", self.sample_rate_hz, ">0")
        real_number("location_factor", self.location_factor, ">0")
        real_number("resonance_hz", self.resonance_hz, ">0")
        real_number("resonance_damping", self.resonance_damping, ">0")
        a = real_number("antialias_fraction", self.antialias_fraction, ">0")
        if a >= 0.5:
            raise ValueError(f"antialias_fraction: expected < 0.5, got {a!r}")
        if not isinstance(self.antialias_order, int) or self.antialias_order < 1:
            raise ValueError(f"antialias_order: expected an integer >= 1, got "
                             f"{self.antialias_order!r}")
        real_number("noise_rms_m_s2", self.noise_rms_m_s2, ">=0")
        real_number("range_m_s2", self.range_m_s2, ">0")
        if not isinstance(self.bits, int) or not 8 <= self.bits <= 24:
            raise ValueError(f"bits: expected an integer in 8..24, got {self.bits!r}")

    @property
    def lsb_m_s2(self) -> float:
        """One count [m/s^2]."""
        return 2.0 * self.range_m_s2 / 2 ** self.bits

    def to_m_s2(self, counts: Any) -> np.ndarray:
        """Counts back to m/s^2 (what a reader of the stream does)."""
        return np.asarray(counts, dtype=float) * self.lsb_m_s2


@dataclass(frozen=True, eq=False)
class SensorSignals:
    """Sampled accelerometer signals.

    Attributes
    ----------
    time_s : ndarray, shape (k,) [s]
    counts : ndarray of int32, shape (k, 2)
        Converter output, X and Y.
    acceleration_m_s2 : ndarray, shape (k, 2) [m/s^2]
        The same in m/s^2 (counts times one LSB).
    clipped : int
        Samples that hit the converter's range.
    """

    time_s: np.ndarray
    counts: np.ndarray
    acceleration_m_s2: np.ndarray
    clipped: int


def _sections(sensors: Accelerometers) -> list[tuple[float, float]]:
    """The analog chain as unit-gain second-order low-pass sections ``(w [rad/s], zeta)``
    (a first-order one as ``(w, inf)``): the Butterworth's pole pairs and the resonance."""
    fc = 2 * math.pi * sensors.antialias_fraction * sensors.sample_rate_hz
    _z, poles, _gain = signal.butter(sensors.antialias_order, fc, analog=True, output="zpk")
    out = [(sensors.resonance_hz * 2 * math.pi, sensors.resonance_damping)]
    for p in poles:
        if p.imag > 1e-9 * abs(p):
            out.append((abs(p), -p.real / abs(p)))
        elif abs(p.imag) <= 1e-9 * abs(p):
            out.append((abs(p), math.inf))
    return out


def _section_tf(dt: float, w: float, zeta: float) -> tuple[np.ndarray, np.ndarray]:
    """Discrete transfer function of one section, exact for a first-order-hold input."""
    if math.isinf(zeta):                       # w / (s + w)
        A, B, C, D = np.array([[-w]]), np.array([[w]]), np.array([[1.0]]), np.array([[0.0]])
    else:                                      # w^2 / (s^2 + 2 zeta w s + w^2)
        A = np.array([[0.0, 1.0], [-w * w, -2 * zeta * w]])
        B, C, D = np.array([[0.0], [w * w]]), np.array([[1.0, 0.0]]), np.array([[0.0]])
    Ad, Bd, Cd, Dd, _ = signal.cont2discrete((A, B, C, D), dt, method="foh")
    b, a = signal.ss2tf(Ad, Bd, Cd, Dd)
    return b[0], a


def _filter_exact(x: np.ndarray, dt: float, w: float, zeta: float) -> np.ndarray:
    """One section, integrated exactly for ``x`` linear between samples (first-order hold)."""
    b, a = _section_tf(dt, w, zeta)
    return signal.lfilter(b, a, x)


def _convert(sensors: Accelerometers, ts: np.ndarray, y: np.ndarray) -> SensorSignals:
    """The converter: ``y`` (k, 2) [m/s^2] at ``ts`` to clipped counts of one LSB."""
    lsb = sensors.lsb_m_s2
    lo, hi = -(2 ** (sensors.bits - 1)), 2 ** (sensors.bits - 1) - 1
    raw = np.rint(y / lsb)
    clipped = int(np.sum((raw < lo) | (raw > hi)))
    counts = np.clip(raw, lo, hi).astype(np.int32)
    return SensorSignals(time_s=ts, counts=counts, acceleration_m_s2=counts * lsb,
                         clipped=clipped)


def sample_accelerometers(time_s: Any, tool_acceleration_m_s2: Any, sensors: Accelerometers,
                          *, rotation: Any = None, rng: np.random.Generator | None = None,
                          seed: int = 0) -> SensorSignals:
    """ADC samples of the two accelerometers for a simulated tool acceleration.

    Parameters
    ----------
    time_s : array_like, shape (n,) [s]
        Equally spaced simulation instants.
    tool_acceleration_m_s2 : array_like, shape (n, 3) [m/s^2]
        Tool acceleration in the workpiece frame (:class:`sim.cutting.MillingRun`).
    sensors : Accelerometers
    rotation : array_like, shape (3, 3), optional
        Workpiece frame to machine frame (rows: machine X, Y, Z in workpiece
        coordinates); default identity.
    rng : numpy.random.Generator, optional
        Noise source; default ``numpy.random.default_rng(seed)``.
    seed : int
        Seed of the default generator.

    Returns
    -------
    SensorSignals
    """
    t = np.asarray(time_s, dtype=float).reshape(-1)
    acc = np.asarray(tool_acceleration_m_s2, dtype=float)
    if acc.shape != (t.size, 3):
        raise ValueError(f"tool_acceleration_m_s2: expected shape ({t.size}, 3), got {acc.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(acc))):
        raise ValueError("time_s, tool_acceleration_m_s2: expected finite values")
    if t.size < 2 or np.any(np.diff(t) <= 0):
        raise ValueError("time_s: expected >= 2 increasing instants")
    dt = float(t[1] - t[0])
    if not np.allclose(np.diff(t), dt, rtol=1e-6, atol=0.0):
        raise ValueError("time_s: expected equally spaced instants")
    R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
    if R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-9):
        raise ValueError("rotation: expected a (3, 3) rotation matrix")
    x = sensors.location_factor * (acc @ R.T)[:, :2]
    for w, zeta in _sections(sensors):
        x = np.stack([_filter_exact(x[:, c], dt, w, zeta) for c in range(2)], axis=1)
    fs = sensors.sample_rate_hz
    ts = np.arange(t[0], t[-1], 1.0 / fs)
    y = np.stack([np.interp(ts, t, x[:, c]) for c in range(2)], axis=1)
    gen = rng if rng is not None else np.random.default_rng(seed)
    if sensors.noise_rms_m_s2 > 0:
        y = y + gen.normal(0.0, sensors.noise_rms_m_s2, size=y.shape)
    return _convert(sensors, ts, y)


class AccelerometerStream:
    """:func:`sample_accelerometers` chunk by chunk (a running machine).

    The filters' states, the noise generator and the converter's clock carry
    over between chunks, so cutting a run into chunks gives the same samples
    as one call (up to the interpolation at chunk joints, which uses the last
    sample of the previous chunk).

    Parameters
    ----------
    sensors : Accelerometers
    dt_s : float [s]
        Simulation step of the chunks.
    rotation : array_like, shape (3, 3), optional
        Workpiece frame to machine frame.
    seed : int
        Noise seed.
    """

    def __init__(self, sensors: Accelerometers, dt_s: float, *, rotation: Any = None,
                 seed: int = 0) -> None:
        self.sensors = sensors
        self.dt_s = real_number("dt_s", dt_s, ">0")
        self.rotation = np.ascontiguousarray(np.eye(3) if rotation is None else rotation,
                                             dtype=float)
        # the sections as one second-order cascade: one filter call per chunk
        self._sos = np.array([np.r_[np.pad(b, (0, 3 - len(b))) / a[0],
                                    np.pad(a, (0, 3 - len(a))) / a[0]]
                              for b, a in (_section_tf(self.dt_s, w, z)
                                           for w, z in _sections(sensors))])
        self._zi = np.zeros((len(self._sos), 2, 2))
        self._rng = np.random.default_rng(seed)
        self._t_last: float | None = None
        self._y_last = np.zeros(2)
        self._next_sample = 0.0
        self.samples = 0

    def _filtered(self, t: np.ndarray, acc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The instants and the two filtered signals of new simulation samples ``t``
        [s], ``acc`` (k, 3) [m/s^2], the last sample of the previous call before them
        (the interpolation's left end); advances the filters' state (one kernel pass,
        :func:`sim._kernels.accel_filter`: location factor, frame and the cascade)."""
        acc = np.ascontiguousarray(acc, dtype=float)
        x = np.empty((acc.shape[0], 2))
        _k.accel_filter(acc, self.rotation, float(self.sensors.location_factor), self._sos,
                        self._zi, x)
        if self._t_last is not None:
            t = np.concatenate([[self._t_last], t])
            x = np.concatenate([self._y_last[None], x])
        return t, x

    def push(self, time_s: np.ndarray, tool_acceleration_m_s2: np.ndarray) -> SensorSignals:
        """New converter samples for a chunk of the simulation (equally spaced times).
        (The real-time server's path, one tick a call: kept lean; :meth:`push_many`
        gives the same samples for many chunks at once.)"""
        s = self.sensors
        t, x = self._filtered(np.asarray(time_s, dtype=float).reshape(-1),
                              np.asarray(tool_acceleration_m_s2, dtype=float).reshape(-1, 3))
        if t.size == 0:
            return SensorSignals(np.zeros(0), np.zeros((0, 2), np.int32), np.zeros((0, 2)), 0)
        step = 1.0 / s.sample_rate_hz
        ts = self._next_sample + step * np.arange(
            max(0, math.floor((t[-1] - self._next_sample) / step + 1e-9) + 1))
        ts = ts[ts <= t[-1]]
        y = np.stack([np.interp(ts, t, x[:, c]) for c in range(2)], axis=1)
        if s.noise_rms_m_s2 > 0:
            y = y + self._rng.normal(0.0, s.noise_rms_m_s2, size=y.shape)
        self._t_last, self._y_last = float(t[-1]), x[-1].copy()
        if ts.size:
            self._next_sample = float(ts[-1]) + step
        self.samples += ts.size
        return _convert(s, ts, y)

    def push_many(self, time_s: list[np.ndarray], tool_acceleration_m_s2: list[np.ndarray]
                  ) -> tuple[SensorSignals, np.ndarray]:
        """Several chunks in one call: the samples that :meth:`push` gives for each chunk
        in turn, bit for bit, concatenated, and how many came from each chunk.

        The filters run once over all the chunks (a recurrence: the same arithmetic
        as chunk by chunk), the sample instants are stepped chunk by chunk as
        :meth:`push` steps them, the interpolation and the noise take them all at once
        (each sample between the same two simulation instants; the noise generator's
        draws in the same order). One call for a run's 200 servo ticks instead of 200
        saves scipy's and numpy's per-call cost (the simulated verification of the main
        job pushed 28,243 ticks).

        Parameters
        ----------
        time_s : list of ndarray, each shape (k_i,) [s]
            The chunks' simulation instants (equally spaced, increasing across chunks).
        tool_acceleration_m_s2 : list of ndarray, each shape (k_i, 3) [m/s^2]

        Returns
        -------
        SensorSignals
            All the chunks' samples.
        ndarray of int, shape (len(time_s),)
            Samples per chunk.
        """
        chunks = [np.asarray(t, dtype=float).reshape(-1) for t in time_s]
        accs = [np.asarray(a, dtype=float).reshape(-1, 3) for a in tool_acceleration_m_s2]
        if len(chunks) != len(accs):
            raise ValueError(f"tool_acceleration_m_s2: expected {len(chunks)} chunks, got "
                             f"{len(accs)}")
        return self.push_chunks(np.concatenate([np.zeros(0), *chunks]),
                                np.concatenate([np.zeros((0, 3)), *accs]),
                                np.array([c.size for c in chunks], dtype=np.int64))

    def push_chunks(self, time_s: np.ndarray, tool_acceleration_m_s2: np.ndarray,
                    counts: np.ndarray) -> tuple[SensorSignals, np.ndarray]:
        """:meth:`push_many` with the chunks one after the other in two arrays: ``time_s``
        (k,) [s] and ``tool_acceleration_m_s2`` (k, 3) [m/s^2], ``counts`` (chunks,) the
        instants of each chunk (summing to k), as :meth:`sim.machine.SimulatedNC.run_ticks`
        gives them. The same samples, bit for bit, as :meth:`push` chunk by chunk."""
        counts = np.asarray(counts, dtype=np.int64).reshape(-1)
        t_all = np.asarray(time_s, dtype=float).reshape(-1)
        acc = np.asarray(tool_acceleration_m_s2, dtype=float).reshape(-1, 3)
        if acc.shape[0] != t_all.size or int(counts.sum()) != t_all.size \
                or np.any(counts < 0):
            raise ValueError(f"counts: expected chunk sizes >= 0 summing to the {t_all.size} "
                             f"instants (and as many accelerations), got {int(counts.sum())} "
                             f"and {acc.shape[0]}")
        s = self.sensors
        t, x = self._filtered(t_all, acc)
        per_chunk = np.zeros(counts.size, dtype=np.int64)
        if t.size == 0:
            return (SensorSignals(np.zeros(0), np.zeros((0, 2), np.int32), np.zeros((0, 2)), 0),
                    per_chunk)
        step = 1.0 / s.sample_rate_hz
        nxt = self._next_sample
        first = np.zeros(counts.size)
        t_end = self._t_last
        ends = t_all[np.maximum(np.cumsum(counts) - 1, 0)].tolist() if t_all.size \
            else [0.0] * counts.size
        for c, (k, te) in enumerate(zip(counts.tolist(), ends)):   # as push steps them
            if k:
                t_end = te
            if t_end is None:
                continue
            # the instants nxt + step * j, j = 0 .. m - 1, that are <= t_end (the
            # same float operations as numpy's nxt + step * arange(m))
            m = max(0, math.floor((t_end - nxt) / step + 1e-9) + 1)
            while m > 0 and nxt + step * float(m - 1) > t_end:
                m -= 1
            if m:
                first[c] = nxt
                per_chunk[c] = m
                nxt = (nxt + step * float(m - 1)) + step
        j = np.arange(int(per_chunk.sum())) - np.repeat(np.cumsum(per_chunk) - per_chunk,
                                                         per_chunk)
        ts = np.repeat(first, per_chunk) + step * j
        y = np.stack([np.interp(ts, t, x[:, c]) for c in range(2)], axis=1)
        if s.noise_rms_m_s2 > 0:
            y = y + self._rng.normal(0.0, s.noise_rms_m_s2, size=y.shape)
        self._t_last, self._y_last = float(t[-1]), x[-1].copy()
        self._next_sample = nxt
        self.samples += ts.size
        return _convert(s, ts, y), per_chunk


def detector_settings(sensors: Accelerometers, **overrides: Any) -> DetectorSettings:
    """orient's chatter-detector settings for these accelerometers (``sim.constants``).

    Parameters
    ----------
    sensors : Accelerometers
    **overrides
        Fields of :class:`orient.detect.DetectorSettings` to change.
    """
    kw = {"threshold": DETECTOR_THRESHOLD_M_S2,
          "relative_threshold": DETECTOR_RELATIVE_THRESHOLD,
          "window_samples": DETECTOR_WINDOW_SAMPLES,
          "hop_samples": DETECTOR_HOP_SAMPLES, "harmonic_base": DETECTOR_HARMONIC_BASE}
    kw.update(overrides)
    return DetectorSettings(sensors.sample_rate_hz, **kw)
