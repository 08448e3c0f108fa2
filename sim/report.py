"""Figures of a simulated run: chatter onset and stop, surface, spectra (no I/O).

The verdicts are recomputed offline from the recorded accelerometer stream
with the same detector settings as the controller, window by window, so open
and closed loop are judged alike. Definitions:

* only windows that end while the tool cuts count;
* *first detection*: end of the first window with a chatter verdict;
* *chatter stops*: the first window after the first detection from which, over
  the next ``STOP_WINDOW_S``, at most ``STOP_FRACTION`` of the windows call
  chatter; reported in spindle revolutions after the first detection;
* *chatter share*: the share of windows calling chatter from the first
  detection to the end;
* *episode*: chatter calls whose windows overlap their neighbour's (end times
  less than one window length apart); *sustained* when its first and last
  windows do not overlap (the non-harmonic vibration outlived a whole window),
  *transient* otherwise. Chatter is self-excited: once set off it goes on, and
  the windows after its onset call it too. A step of the cut (the tool entering
  or leaving the material, a change of posture) rings the structure at its
  natural frequency, away from the tooth harmonics, and the ringing of a stable
  cut dies within the window; a cut so lightly damped that its ringing outlives
  a window counts as sustained;
* *surface*: the generated surface's deviation once per tooth
  (:class:`sim.machine.SurfaceRecord`): its mean (location error) and the
  standard deviation of its tooth-to-tooth change (chatter marks), over the
  whole cut and over its last ``TAIL_FRACTION``.
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np

from errpred.spindle import tooth_period
from orient.detect import ChatterDetector

from .constants import (
    DETECTOR_CHUNK_WINDOWS,
    STOP_FRACTION,
    STOP_WINDOW_S,
    TAIL_FRACTION,
)

__all__ = ["chatter_episodes", "chatter_timeline", "spectrum", "summarize_run"]


def chatter_timeline(time_s: np.ndarray, accel_m_s2: np.ndarray, detector: ChatterDetector,
                     spindle_rpm: float, teeth: int,
                     chunk_windows: int = DETECTOR_CHUNK_WINDOWS) -> dict[str, np.ndarray]:
    """The detector's verdict on every window of a recorded run.

    The samples are fed to the detector (reset first) in chunks of ``chunk_windows``
    hops, so that it holds at most about that many windows and their spectra at once,
    whatever the run's length; the detector keeps the samples a window needs across
    :meth:`~orient.detect.ChatterDetector.feed` calls and judges each window from its
    own samples, so the verdicts are those of feeding the whole run at once.

    Parameters
    ----------
    time_s : ndarray, shape (k,) [s]
        Sample times (the first one is the stream's start).
    accel_m_s2 : ndarray, shape (k, 2) [m/s^2]
        X and Y acceleration.
    detector : orient.detect.ChatterDetector
    spindle_rpm : float [rev/min]
    teeth : int [-]
    chunk_windows : int [-]
        Windows judged per call of the detector (>= 2; the last call may take one more).

    Returns
    -------
    dict of ndarray, each shape (w,)
        ``end_s`` window end time [s], ``chatter`` verdict, ``amplitude`` [m/s^2] and
        ``frequency_hz`` [Hz] of the strongest non-harmonic component, ``cause``
        (``'tool'``, ``'workpiece'`` or ``''``).
    """
    if isinstance(chunk_windows, bool) or not isinstance(chunk_windows, int) \
            or chunk_windows < 2:
        raise ValueError(f"chunk_windows: expected an integer >= 2, got {chunk_windows!r}")
    detector.reset()
    parts: dict[str, list[np.ndarray]] = {"index": [], "chatter": [], "amplitude": [],
                                          "frequency_hz": [], "cause": []}
    cuts = _chunk_bounds(accel_m_s2.shape[0], detector.settings.window_samples,
                         detector.settings.hop_samples, chunk_windows)
    for a, b in itertools.pairwise(cuts):
        out = detector.feed(accel_m_s2[a:b, 0], accel_m_s2[a:b, 1], spindle_rpm, teeth)
        parts["index"].append(np.array([d.sample_index for d in out], dtype=np.int64))
        parts["chatter"].append(np.array([d.chatter for d in out], dtype=bool))
        parts["amplitude"].append(np.array([d.amplitude for d in out], dtype=float))
        parts["frequency_hz"].append(np.array([d.frequency_hz for d in out], dtype=float))
        parts["cause"].append(np.array([d.cause or "" for d in out], dtype=object))
    cat = {key: np.concatenate(v) if v else np.zeros(0, dtype) for (key, v), dtype in
           zip(parts.items(), (np.int64, bool, float, float, object))}
    t0 = float(time_s[0]) if time_s.size else 0.0
    fs = detector.settings.sample_rate_hz
    return {"end_s": t0 + cat["index"].astype(float) / fs,
            "chatter": cat["chatter"],
            "amplitude": cat["amplitude"],
            "frequency_hz": cat["frequency_hz"],
            "cause": cat["cause"].astype(str)}


def _chunk_bounds(samples: int, window: int, hop: int, chunk_windows: int) -> list[int]:
    """Sample indices where :func:`chatter_timeline` splits a run of ``samples`` samples:
    each piece completes ``chunk_windows`` windows of ``window`` samples every ``hop``,
    the last one the rest, never a single window (merged into the piece before it: a
    batch of one window takes numpy's vector product where the batch of many takes the
    matrix one, whose sums differ in the last bit)."""
    if samples < window:
        return [0, samples]
    windows = (samples - window) // hop + 1
    ends = [window + (i * chunk_windows - 1) * hop
            for i in range(1, (windows - 1) // chunk_windows + 1)]
    if ends and windows - len(ends) * chunk_windows == 1:
        ends.pop()
    return [0, *ends, samples]


def chatter_episodes(end_s: np.ndarray, chatter: np.ndarray, window_s: float
                     ) -> list[tuple[float, float, int, bool]]:
    """Episodes of chatter calls (module notes): runs of calls whose windows overlap.

    Parameters
    ----------
    end_s : ndarray, shape (k,) [s]
        End time of each judged window, increasing.
    chatter : ndarray of bool, shape (k,)
        The detector's verdict per window.
    window_s : float [s]
        Window length.

    Returns
    -------
    list of (first_end_s, last_end_s, windows, sustained)
        One entry per episode: the end times of its first and last calls [s], its
        number of calls, and whether the first and last windows do not overlap.
    """
    t = np.asarray(end_s, dtype=float)[np.asarray(chatter, dtype=bool)]
    if t.size == 0:
        return []
    cuts = np.flatnonzero(np.diff(t) >= window_s) + 1
    out = []
    for run in np.split(t, cuts):
        span = float(run[-1] - run[0])
        out.append((float(run[0]), float(run[-1]), int(run.size), span >= window_s))
    return out


def _stop_index(end_s: np.ndarray, chatter: np.ndarray, first: int) -> int | None:
    for i in range(first + 1, end_s.size):
        if chatter[i]:
            continue
        ahead = (end_s >= end_s[i]) & (end_s < end_s[i] + STOP_WINDOW_S)
        if end_s[-1] - end_s[i] < STOP_WINDOW_S:
            return None
        if chatter[ahead].mean() <= STOP_FRACTION:
            return i
    return None


def spectrum(accel_m_s2: np.ndarray, fs_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Single-sided amplitude spectrum (Hann) of the vector acceleration: f [Hz], A [m/s^2]."""
    x = np.asarray(accel_m_s2, dtype=float)
    n = x.shape[0]
    w = np.hanning(n)
    X = np.fft.rfft((x - x.mean(axis=0)) * w[:, None], axis=0)
    amp = 2.0 * np.sqrt(np.sum(np.abs(X) ** 2, axis=1)) / w.sum()
    return np.fft.rfftfreq(n, 1.0 / fs_hz), amp


def summarize_run(time_s: np.ndarray, accel_m_s2: np.ndarray, surface: dict[str, np.ndarray],
                  detector: ChatterDetector, spindle_rpm: float, teeth: int,
                  commands: list | None = None, cutting: np.ndarray | None = None
                  ) -> dict[str, Any]:
    """The figures of one run (JSON-ready). With ``cutting`` (k,) bool per sample,
    only the windows that end while the tool cuts are judged (the air moves
    between passes are neither chatter nor its end)."""
    tl = chatter_timeline(time_s, accel_m_s2, detector, spindle_rpm, teeth)
    if cutting is not None and time_s.size:
        k = np.clip(np.searchsorted(time_s, tl["end_s"]) - 1, 0, time_s.size - 1)
        keep = np.asarray(cutting, dtype=bool)[k]
        tl = {key: v[keep] for key, v in tl.items()}
    rev_s = tooth_period(spindle_rpm)
    hits = np.flatnonzero(tl["chatter"])
    window_s = detector.settings.window_samples / detector.settings.sample_rate_hz
    episodes = chatter_episodes(tl["end_s"], tl["chatter"], window_s)
    out: dict[str, Any] = {"windows": int(tl["chatter"].size),
                           "chatter_windows": int(hits.size),
                           "episodes": [{"first_s": a, "last_s": b, "windows": n,
                                         "sustained": bool(sus)}
                                        for a, b, n, sus in episodes],
                           "sustained_episodes": int(sum(e[3] for e in episodes)),
                           "simulated_s": float(time_s[-1]) if time_s.size else 0.0}
    if hits.size:
        first = int(hits[0])
        stop = _stop_index(tl["end_s"], tl["chatter"], first)
        t_det = float(tl["end_s"][first])
        out.update(first_detection_s=t_det,
                   first_cause=str(tl["cause"][first]),
                   first_frequency_hz=float(tl["frequency_hz"][first]),
                   chatter_share_after_detection=float(tl["chatter"][first:].mean()),
                   chatter_stops_s=None if stop is None else float(tl["end_s"][stop]),
                   chatter_stops_after_rev=None if stop is None else
                   float((tl["end_s"][stop] - t_det) / rev_s),
                   peak_amplitude_m_s2=float(np.nanmax(tl["amplitude"][hits])))
    else:
        out.update(first_detection_s=None, chatter_share_after_detection=0.0)
    off = np.asarray(surface.get("offset_mm", np.zeros(0)), dtype=float)
    if off.size > 2:
        tail = off[int((1 - TAIL_FRACTION) * off.size):]
        out["surface"] = {
            "teeth": int(off.size),
            "mean_offset_um": float(off.mean() * 1e3),
            "chatter_marks_um": float(np.std(np.diff(off)) * 1e3),
            "peak_to_peak_um": float(np.ptp(off) * 1e3),
            "tail_mean_offset_um": float(tail.mean() * 1e3),
            "tail_chatter_marks_um": float(np.std(np.diff(tail)) * 1e3) if tail.size > 2
            else math.nan,
            "tail_peak_to_peak_um": float(np.ptp(tail) * 1e3),
        }
    out["commands"] = [] if commands is None else [
        {"time_s": c[0], "lead_deg": c[1], "tilt_deg": c[2], "reason": c[3], "ack": c[4]}
        for c in commands]
    return out
