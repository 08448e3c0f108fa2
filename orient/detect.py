"""Chatter detection from two accelerometer signals (``docs/method.md`` §7, *Detection*).

Implements the chatter detector of JP2010-260120 (Nagoya), second embodiment
([0076]-[0080], claim 5, items (9)-(10)): two accelerometers near the spindle
nose, along machine X and Y; a frequency analysis over a window; chatter when
a strong component does not sit at an integer multiple of the spindle
frequency; the cause from the X/Y phase difference at that frequency
(a whirling tool: tool side; a one-directional vibration: workpiece side).

The detector works on any pair of sampled signals (a real machine or a
simulator) and knows nothing of where they come from. Units: the amplitudes
are in the units of the samples (m/s^2 for accelerometers); frequencies in Hz;
spindle speed in rev/min; angles in radians.

Algorithm per window of ``N`` samples (vectorized over all windows of a chunk):

1. remove each channel's mean, multiply by the window ``w`` (periodic Hann by
   default), ``X = rfft(x w)``, ``Y = rfft(y w)``;
2. combined power ``P_k = |X_k|^2 + |Y_k|^2`` (invariant to a rotation of the
   sensor pair in the X-Y plane);
3. *harmonic bins*: within ``band(m) = harmonic_band_hz + speed_tolerance *
   m * f_base`` of a multiple ``m >= 0`` of the base frequency ``f_base`` (the
   spindle frequency ``rpm / 60``, which includes every tooth-passing multiple;
   or, with ``harmonic_base='tooth'``, the tooth-passing frequency). The rest,
   inside ``[min_frequency_hz, max_frequency_hz]``, are *candidate bins*;
4. the chatter peak: the largest local maximum of ``P`` among candidate bins
   (a local maximum, so that the flank of a harmonic's main lobe never counts);
5. frequency refined by a parabola through ``ln P`` at the peak bin and its two
   neighbours (offset ``d`` in bins, ``|d| <= 1/2``);
6. amplitude: single-sided, window-corrected, ``A = 2 |X_k| / (sum(w) W(d))``
   with ``W(d) = |sum_n w_n exp(-2 pi i d n / N)| / sum(w)`` the window's
   normalized response at the refined offset (removes the scalloping loss);
   the reported ``amplitude`` is the vector amplitude ``sqrt(A_x^2 + A_y^2)``:
   the amplitude of a one-directional vibration, ``sqrt(2)`` times the per-axis
   amplitude of a circular whirl;
7. chatter when ``amplitude > threshold`` and ``amplitude >= relative_threshold
   * harmonic_amplitude`` (``harmonic_amplitude``: the largest component at the
   spindle harmonics, order >= 1, refined the same way);
8. cause from the cross spectrum ``S = sum X_j conj(Y_j)`` over the peak bin and
   its neighbours: ``phase_rad = angle(S)`` (phase of X minus phase of Y) and
   the *whirl* ``2 |Im S| / sum(|X_j|^2 + |Y_j|^2)``, which is
   ``2 a b |sin(dphi)| / (a^2 + b^2)`` for X, Y amplitudes a, b: 1 for a circular
   whirl, 0 for a straight-line vibration. With equal amplitudes it is
   ``|sin(dphi)|``, the patent's phase criterion; with unequal amplitudes it
   also calls a vibration mostly along one axis one-directional, whose phase
   alone would be meaningless. ``whirl > sin(phase_threshold_rad)`` -> ``'tool'``
   (whirling), else ``'workpiece'`` (in phase or anti-phase, one-directional).

The patent's text reads "exceeds a threshold, *or* its frequency is not a
multiple of the spindle speed"; this module follows ``method.md`` (the
strongest *non-harmonic* component above the threshold), since a strong
tooth-passing line is not chatter.

Known limitation: with an even number of teeth, period-doubling (flip) chatter
at odd multiples of half the tooth-passing frequency sits exactly on spindle
harmonics and is excluded with ``harmonic_base='spindle'``. With
``harmonic_base='tooth'`` only tooth-passing multiples are excluded: flip chatter
is seen, but so is runout (spindle-harmonic lines) when it exceeds the threshold.
"""

from __future__ import annotations

import math
import numbers
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy.signal import get_window

from errpred.spindle import tooth_frequency
from nc.checks import real_number as _real
from .constants import (
    DEFAULT_BAND_BINS,
    DEFAULT_HOP_SAMPLES,
    DEFAULT_PHASE_THRESHOLD_RAD,
    DEFAULT_WINDOW_SAMPLES,
    LOG_FLOOR_REL,
    MIN_WINDOW_SAMPLES,
    WINDOW_LINE_REL,
    WINDOW_MAINLOBE_BINS,
)

__all__ = [
    "DEFAULT_HOP_SAMPLES",
    "DEFAULT_PHASE_THRESHOLD_RAD",
    "DEFAULT_WINDOW_SAMPLES",
    "ChatterDetector",
    "Detection",
    "DetectorSettings",
    "window_lines",
    "window_response",
]

_CAUSES = ("tool", "workpiece")


def window_lines(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The lines of a periodic window's DFT: where it is not zero.

    Parameters
    ----------
    w : ndarray, shape (N,)
        The window (``fftbins=True``).

    Returns
    -------
    bins : ndarray, shape (L,) [bins]
        Signed bin of each line (``-N/2 < m <= N/2``).
    values : ndarray of complex, shape (L,)
        The DFT there (lines at or below ``WINDOW_LINE_REL`` of the largest dropped).
    """
    w = np.asarray(w, dtype=float)
    n = w.size
    spec = np.fft.fft(w)
    mag = np.abs(spec)
    keep = np.flatnonzero(mag > WINDOW_LINE_REL * mag.max())
    return np.where(keep > n // 2, keep - n, keep).astype(float), spec[keep]


def window_response(lines: tuple[np.ndarray, np.ndarray], n: int, d: np.ndarray
                    ) -> np.ndarray:
    """``|sum_n w_n exp(-2 pi i d n / N)|`` at offsets ``d`` from the window's DFT lines.

    The window is the inverse DFT of its lines, so its response is their sum of
    Dirichlet kernels, ``(1/N) sum_m W_m D(d - m)`` with ``D(x) = sum_n exp(-2 pi i x n
    / N) = exp(-i pi x (N-1)/N) sin(pi x) / sin(pi x / N)`` (``N`` at ``x = 0``): exact,
    and a few terms per offset for the cosine-sum windows instead of ``N``.

    Parameters
    ----------
    lines : tuple of ndarray
        :func:`window_lines` of the window.
    n : int [samples]
        Window length ``N``.
    d : ndarray, any shape [bins]
        Offsets, ``|d| < N/2`` from every line.

    Returns
    -------
    ndarray, shape like ``d``
    """
    bins, values = lines
    x = np.asarray(d, dtype=float)[..., None] - bins
    at_line = x == 0.0
    s = np.sin(np.pi * x / n)
    ratio = np.where(at_line, float(n), np.sin(np.pi * x) / np.where(at_line, 1.0, s))
    return np.abs((np.exp(-1j * np.pi * x * ((n - 1) / n)) * ratio) @ values) / n


def _int(name: str, value: Any, minimum: int) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name}: expected an integer, got {value!r}")
    if int(value) < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {value!r}")
    return int(value)


@dataclass(frozen=True)
class DetectorSettings:
    """Parameters of :class:`ChatterDetector`.

    Parameters
    ----------
    sample_rate_hz : float [Hz]
        Sampling rate of both channels, > 0.
    threshold : float [signal units, e.g. m/s^2]
        Absolute threshold on the vector amplitude of the chatter component,
        > 0. Set it above the noise floor: white noise of standard deviation
        ``sigma`` gives per-bin amplitudes of rms ``2 sigma sqrt(sum(w^2)) /
        sum(w)`` per channel (``2 sigma sqrt(1.5 / N)`` for Hann); four to five
        times that keeps false alarms from noise rare.
    window_samples : int [samples]
        Window length ``N``; frequency resolution ``sample_rate_hz / N``.
    hop_samples : int [samples]
        Samples between the ends of consecutive windows in :meth:`ChatterDetector.feed`,
        1 <= hop <= N.
    window : str
        Window function, one of ``WINDOW_MAINLOBE_BINS`` (periodic form).
    harmonic_band_hz : float or None [Hz]
        Half-width of the excluded band around each harmonic; None: three bins.
        At least the window's main-lobe half-width (two bins for Hann).
    speed_tolerance : float [-]
        Relative spindle-speed uncertainty; widens the band of harmonic ``m`` by
        ``speed_tolerance * m * f_base`` (0 <= value < 0.5).
    harmonic_base : str
        ``'spindle'`` (exclude multiples of ``rpm/60``) or ``'tooth'`` (only
        multiples of the tooth-passing frequency; see the module notes).
    phase_threshold_rad : float [rad]
        In (0, pi/2). Whirl above ``sin(phase_threshold_rad)``: tool side.
    relative_threshold : float [-]
        Also require ``amplitude >= relative_threshold * harmonic_amplitude``;
        0 (default) disables this check.
    min_frequency_hz, max_frequency_hz : float [Hz]
        Range searched for chatter; ``max_frequency_hz`` None: Nyquist.
    """

    sample_rate_hz: float
    threshold: float
    window_samples: int = DEFAULT_WINDOW_SAMPLES
    hop_samples: int = DEFAULT_HOP_SAMPLES
    window: str = "hann"
    harmonic_band_hz: float | None = None
    speed_tolerance: float = 0.0
    harmonic_base: str = "spindle"
    phase_threshold_rad: float = DEFAULT_PHASE_THRESHOLD_RAD
    relative_threshold: float = 0.0
    min_frequency_hz: float = 0.0
    max_frequency_hz: float | None = None

    def __post_init__(self) -> None:
        fs = _real("sample_rate_hz", self.sample_rate_hz, ">0")
        _real("threshold", self.threshold, ">0")
        n = _int("window_samples", self.window_samples, MIN_WINDOW_SAMPLES)
        hop = _int("hop_samples", self.hop_samples, 1)
        if hop > n:
            raise ValueError(f"hop_samples: expected <= window_samples ({n}), got {hop}")
        if self.window not in WINDOW_MAINLOBE_BINS:
            raise ValueError(f"window: expected one of {sorted(WINDOW_MAINLOBE_BINS)}, "
                             f"got {self.window!r}")
        df = fs / n
        if self.harmonic_band_hz is not None:
            band = _real("harmonic_band_hz", self.harmonic_band_hz, ">0")
            lobe = WINDOW_MAINLOBE_BINS[self.window] * df
            if band < lobe:
                raise ValueError(f"harmonic_band_hz: expected >= the {self.window} window's "
                                 f"main-lobe half-width {lobe:.6g} Hz, got {band!r}")
        tol = _real("speed_tolerance", self.speed_tolerance, ">=0")
        if tol >= 0.5:
            raise ValueError(f"speed_tolerance: expected a value in [0, 0.5), got {tol!r}")
        if self.harmonic_base not in ("spindle", "tooth"):
            raise ValueError("harmonic_base: expected 'spindle' or 'tooth', "
                             f"got {self.harmonic_base!r}")
        ph = _real("phase_threshold_rad", self.phase_threshold_rad)
        if not 0.0 < ph < math.pi / 2:
            raise ValueError(f"phase_threshold_rad: expected a value in (0, pi/2), got {ph!r}")
        _real("relative_threshold", self.relative_threshold, ">=0")
        fmin = _real("min_frequency_hz", self.min_frequency_hz, ">=0")
        if self.max_frequency_hz is not None:
            fmax = _real("max_frequency_hz", self.max_frequency_hz, ">0")
            if fmax <= fmin or fmax > fs / 2:
                raise ValueError(f"max_frequency_hz: expected a value in (min_frequency_hz, "
                                 f"Nyquist {fs / 2:g} Hz], got {fmax!r}")
        elif fmin >= fs / 2:
            raise ValueError(f"min_frequency_hz: expected < Nyquist {fs / 2:g} Hz, got {fmin!r}")

    @classmethod
    def from_durations(cls, sample_rate_hz: float, threshold: float, window_s: float,
                       hop_s: float, **kwargs: Any) -> DetectorSettings:
        """Settings with the window and hop given in seconds (rounded to samples).

        Parameters
        ----------
        sample_rate_hz : float [Hz]
        threshold : float [signal units]
        window_s, hop_s : float [s]
            Window length and hop.
        **kwargs
            Other fields of :class:`DetectorSettings`.
        """
        fs = _real("sample_rate_hz", sample_rate_hz, ">0")
        n = round(_real("window_s", window_s, ">0") * fs)
        hop = max(1, round(_real("hop_s", hop_s, ">0") * fs))
        return cls(fs, threshold, window_samples=n, hop_samples=hop, **kwargs)

    @property
    def bin_hz(self) -> float:
        """Frequency resolution ``sample_rate_hz / window_samples`` [Hz]."""
        return self.sample_rate_hz / self.window_samples

    @property
    def window_s(self) -> float:
        """Window length [s]."""
        return self.window_samples / self.sample_rate_hz

    @property
    def band_hz(self) -> float:
        """Harmonic exclusion half-width actually used [Hz]."""
        if self.harmonic_band_hz is None:
            return DEFAULT_BAND_BINS * self.bin_hz
        return float(self.harmonic_band_hz)


@dataclass(frozen=True)
class Detection:
    """The detector's verdict on one window.

    Attributes
    ----------
    chatter : bool
        A non-harmonic component above the threshold(s).
    frequency_hz : float [Hz]
        Refined frequency of the strongest non-harmonic component (nan if the
        window has no candidate bin, e.g. harmonics closer than two bands).
    amplitude : float [signal units]
        Its vector amplitude ``sqrt(amplitude_x^2 + amplitude_y^2)``.
    cause : {'tool', 'workpiece'} or None
        Side of the chatter from the whirl; None when ``chatter`` is False.
    phase_rad : float [rad]
        Phase of X minus phase of Y at that frequency, in (-pi, pi].
    harmonic_ratio : float [-]
        ``amplitude / harmonic_amplitude`` (inf when there is no harmonic content).
    amplitude_x, amplitude_y : float [signal units]
        Per-channel amplitudes of the component.
    whirl : float [-]
        ``2 a b |sin(dphi)| / (a^2 + b^2)`` in [0, 1]: 1 circular, 0 one-directional.
    harmonic_amplitude : float [signal units]
        Largest vector amplitude at the spindle harmonics (order >= 1).
    spindle_hz, tooth_hz : float [Hz]
        Spindle and tooth-passing frequencies used.
    sample_index : int [samples]
        Stream index one past the window's last sample (its length for
        :meth:`ChatterDetector.analyze`).
    elapsed_s : float [s]
        Computing time per window (wall clock).
    """

    chatter: bool
    frequency_hz: float
    amplitude: float
    cause: str | None
    phase_rad: float
    harmonic_ratio: float
    amplitude_x: float
    amplitude_y: float
    whirl: float
    harmonic_amplitude: float
    spindle_hz: float
    tooth_hz: float
    sample_index: int
    elapsed_s: float


class ChatterDetector:
    """Chatter detector on two acceleration channels (X, Y).

    Parameters
    ----------
    settings : DetectorSettings

    Notes
    -----
    :meth:`analyze` judges one window; :meth:`feed` is the streaming form: it
    keeps the samples it needs between calls and returns one detection per
    hop. Both refuse NaN/inf samples. The object holds no other state, so one
    detector per signal stream.
    """

    def __init__(self, settings: DetectorSettings) -> None:
        if not isinstance(settings, DetectorSettings):
            raise TypeError(f"settings: expected DetectorSettings, got {type(settings).__name__}")
        self.settings = settings
        n = settings.window_samples
        self._w = get_window(settings.window, n, fftbins=True).astype(float)
        self._wsum = float(self._w.sum())
        self._freqs = np.fft.rfftfreq(n, 1.0 / settings.sample_rate_hz)
        self._lines = window_lines(self._w)
        self.reset()

    # --- streaming ---------------------------------------------------------
    def reset(self) -> None:
        """Forget buffered samples; the next sample fed has stream index 0."""
        self._bx = np.zeros(0)
        self._by = np.zeros(0)
        self._buf_start = 0          # stream index of the buffer's first sample
        self._next_end = self.settings.window_samples   # end of the next window
        self._total = 0

    @property
    def samples_seen(self) -> int:
        """Number of samples fed since the last :meth:`reset` [samples]."""
        return self._total

    def feed(self, ax_chunk: Any, ay_chunk: Any, spindle_rpm: float,
             teeth: int) -> list[Detection]:
        """Append samples; analyze every window that is now complete.

        Parameters
        ----------
        ax_chunk, ay_chunk : array_like, shape (k,) [signal units]
            New samples of X and Y (same length, may be empty).
        spindle_rpm : float [rev/min]
            Spindle speed during these samples (used for all windows returned).
        teeth : int [-]
            Number of teeth (flutes).

        Returns
        -------
        list of Detection
            One per hop whose window ended within this chunk, in stream order;
            ``sample_index`` is the window's end. Empty until ``window_samples``
            samples have been fed.
        """
        x, y = self._check_pair(ax_chunk, ay_chunk, exact=False)
        f_sp, f_tooth = self._check_speed(spindle_rpm, teeth)
        self._bx = np.concatenate([self._bx, x])
        self._by = np.concatenate([self._by, y])
        self._total += x.size
        n, hop = self.settings.window_samples, self.settings.hop_samples
        ends = np.arange(self._next_end, self._total + 1, hop)
        out: list[Detection] = []
        if ends.size:
            starts = ends - n - self._buf_start
            wx = sliding_window_view(self._bx, n)[starts]
            wy = sliding_window_view(self._by, n)[starts]
            out = self._analyze_batch(wx, wy, f_sp, f_tooth, ends)
            self._next_end = int(ends[-1]) + hop
        keep_from = max(0, self._next_end - n - self._buf_start)
        if keep_from:
            self._bx = self._bx[keep_from:]
            self._by = self._by[keep_from:]
            self._buf_start += keep_from
        return out

    # --- one window ----------------------------------------------------------
    def analyze(self, ax: Any, ay: Any, spindle_rpm: float, teeth: int) -> Detection:
        """Judge one window.

        Parameters
        ----------
        ax, ay : array_like, shape (window_samples,) [signal units]
            X and Y samples of the window.
        spindle_rpm : float [rev/min]
        teeth : int [-]

        Returns
        -------
        Detection
        """
        x, y = self._check_pair(ax, ay, exact=True)
        f_sp, f_tooth = self._check_speed(spindle_rpm, teeth)
        return self._analyze_batch(x[None, :], y[None, :], f_sp, f_tooth,
                                   np.array([x.size]))[0]

    # --- internals -------------------------------------------------------------
    def _check_pair(self, ax: Any, ay: Any, exact: bool) -> tuple[np.ndarray, np.ndarray]:
        x = np.asarray(ax, dtype=float)
        y = np.asarray(ay, dtype=float)
        for name, a in (("ax", x), ("ay", y)):
            if a.ndim != 1:
                raise ValueError(f"{name}: expected a 1-D array, got shape {a.shape}")
            if exact and a.size != self.settings.window_samples:
                raise ValueError(f"{name}: expected window_samples = "
                                 f"{self.settings.window_samples} samples, got {a.size}")
            bad = np.flatnonzero(~np.isfinite(a))
            if bad.size:
                raise ValueError(f"{name}: expected finite samples, got {a[bad[0]]} at "
                                 f"index {bad[0]} ({bad.size} non-finite)")
        if x.size != y.size:
            raise ValueError(f"ax, ay: expected equal lengths, got {x.size} and {y.size}")
        return x, y

    def _check_speed(self, spindle_rpm: float, teeth: int) -> tuple[float, float]:
        rpm = _real("spindle_rpm", spindle_rpm, ">0")
        z = _int("teeth", teeth, 1)
        return tooth_frequency(rpm), tooth_frequency(rpm, z)

    def _masks(self, f_sp: float, f_tooth: float) -> tuple[np.ndarray, np.ndarray]:
        """(candidate bins, spindle-harmonic bins of order >= 1), shape (N//2+1,)."""
        s = self.settings
        f = self._freqs
        fmax = s.sample_rate_hz / 2 if s.max_frequency_hz is None else s.max_frequency_hz
        in_range = (f >= s.min_frequency_hz) & (f <= fmax)

        def near(base: float) -> tuple[np.ndarray, np.ndarray]:
            order = np.rint(f / base)
            width = s.band_hz + s.speed_tolerance * order * base
            return np.abs(f - order * base) <= width, order

        near_sp, order_sp = near(f_sp)
        near_base = near_sp if s.harmonic_base == "spindle" else near(f_tooth)[0]
        return in_range & ~near_base, near_sp & (order_sp >= 1) & (f <= fmax)

    def _refine(self, p: np.ndarray, k: np.ndarray) -> np.ndarray:
        """Offset [bins] of the log-parabola vertex through p[k-1], p[k], p[k+1]."""
        rows = np.arange(p.shape[0])
        floor = np.maximum(LOG_FLOOR_REL * p.max(axis=1), np.finfo(float).tiny)
        lp = np.log(p + floor[:, None])
        km = np.clip(k - 1, 0, p.shape[1] - 1)
        kp = np.clip(k + 1, 0, p.shape[1] - 1)
        a, b, c = lp[rows, km], lp[rows, k], lp[rows, kp]
        den = a - 2.0 * b + c
        with np.errstate(divide="ignore", invalid="ignore"):
            d = np.where(den < 0, 0.5 * (a - c) / den, 0.0)
        edge = (k == 0) | (k == p.shape[1] - 1)
        return np.where(edge, 0.0, np.clip(d, -0.5, 0.5))

    def _kernel(self, d: np.ndarray) -> np.ndarray:
        """Normalized window response ``W(d)`` at offsets d [bins], shape like d."""
        return window_response(self._lines, self.settings.window_samples, d) / self._wsum

    def _analyze_batch(self, wx: np.ndarray, wy: np.ndarray, f_sp: float, f_tooth: float,
                       ends: np.ndarray) -> list[Detection]:
        t0 = time.perf_counter()
        s = self.settings
        m = wx.shape[0]
        X = np.fft.rfft((wx - wx.mean(axis=1, keepdims=True)) * self._w, axis=1)
        Y = np.fft.rfft((wy - wy.mean(axis=1, keepdims=True)) * self._w, axis=1)
        P = X.real**2 + X.imag**2 + Y.real**2 + Y.imag**2
        cand, harm = self._masks(f_sp, f_tooth)
        nb = P.shape[1]
        rows = np.arange(m)
        scale = 2.0 / self._wsum

        # chatter peak: the largest local maximum among candidate bins
        lm = np.zeros_like(P, dtype=bool)
        lm[:, 1:-1] = (P[:, 1:-1] > P[:, :-2]) & (P[:, 1:-1] >= P[:, 2:])
        score = np.where(lm & cand, P, -1.0)
        k = np.argmax(score, axis=1)
        valid = score[rows, k] > 0.0
        d = self._refine(P, k)
        corr = scale / self._kernel(d)
        ampx = np.abs(X[rows, k]) * corr
        ampy = np.abs(Y[rows, k]) * corr
        amp = np.hypot(ampx, ampy)
        freq = (k + d) * s.bin_hz

        # cross spectrum over the peak bin and its neighbours
        lo = np.clip(k - 1, 0, nb - 1)
        hi = np.clip(k + 1, 0, nb - 1)
        idx = np.stack([lo, k, hi], axis=1)
        idx_u = np.where(np.diff(idx, axis=1, prepend=-1) > 0, idx, -1)  # drop clipped repeats
        take = idx_u >= 0
        xs = np.where(take, X[rows[:, None], idx], 0.0)
        ys = np.where(take, Y[rows[:, None], idx], 0.0)
        cross = np.sum(xs * np.conj(ys), axis=1)
        power = np.sum(np.abs(xs) ** 2 + np.abs(ys) ** 2, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            whirl = np.where(power > 0, 2.0 * np.abs(cross.imag) / power, 0.0)
        phase = np.angle(cross)
        phase = np.where(phase <= -np.pi, np.pi, phase)

        # largest harmonic component (order >= 1)
        hscore = np.where(harm, P, -1.0)
        kh = np.argmax(hscore, axis=1)
        hvalid = hscore[rows, kh] > 0.0
        hamp = np.where(hvalid, np.sqrt(np.maximum(P[rows, kh], 0.0)) * scale
                        / self._kernel(self._refine(P, kh)), 0.0)

        chatter = valid & (amp > s.threshold) & (amp >= s.relative_threshold * hamp)
        tool = whirl > math.sin(s.phase_threshold_rad)
        elapsed = (time.perf_counter() - t0) / max(m, 1)
        out = []
        for i in range(m):
            ok = bool(valid[i])
            nan = math.nan
            a = float(amp[i]) if ok else 0.0
            out.append(Detection(
                chatter=bool(chatter[i]),
                frequency_hz=float(freq[i]) if ok else nan,
                amplitude=a,
                cause=(_CAUSES[0] if tool[i] else _CAUSES[1]) if chatter[i] else None,
                phase_rad=float(phase[i]) if ok else nan,
                harmonic_ratio=(a / float(hamp[i]) if hamp[i] > 0 else math.inf) if ok else 0.0,
                amplitude_x=float(ampx[i]) if ok else 0.0,
                amplitude_y=float(ampy[i]) if ok else 0.0,
                whirl=float(whirl[i]) if ok else nan,
                harmonic_amplitude=float(hamp[i]),
                spindle_hz=f_sp, tooth_hz=f_tooth,
                sample_index=int(ends[i]), elapsed_s=elapsed))
        return out
