"""Verify a program in the simulated machine, offline: the surface it leaves and whether it
chatters (no I/O; the program is read through the scenario).

The NC (:class:`sim.machine.SimulatedNC`) runs the program as fast as the
computer allows, tick by tick, with no controller: no feed override, no
orientation offsets. Per cutter location where the ball cuts:

* *surface error* [um]: where the generated surface lies against the design,
  along its outward normal (positive: material left) -- the programmed ball's
  gap to the design (``Contacts.gap_mm``, zero for the planned path, the
  correction for a corrected one) plus the mean relative displacement at the
  generating instant of each tooth (:class:`sim.machine.SurfaceRecord`);
* *chatter marks* [um]: the standard deviation of that displacement over the
  teeth at the cutter location.

The accelerometer stream is judged window by window with the controller's
detector (:func:`sim.report.summarize_run`, only windows that end while the
tool cuts; chatter is a sustained episode, a call that outlives its window),
and its spectrum while cutting is averaged (Welch).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from orient.detect import ChatterDetector
from orient.scenario import PlanScenario

from .constants import SPECTRUM_SEGMENT
from .machine import SimulatedNC
from .report import summarize_run
from .sensors import detector_settings

__all__ = ["Verification", "scenario_with_program", "verify_program"]


@dataclass(frozen=True, eq=False)
class Verification:
    """What the simulated machine made of a program.

    Attributes
    ----------
    points : ndarray of int, shape (m,)
        Cutter locations (of the program read through the machine) where the ball cut.
    contact_mm : ndarray, shape (m, 3) [mm]
        Their contact points on the design (workpiece frame).
    surface_um : ndarray, shape (m,) [um]
        Surface error against the design (positive: material left).
    marks_um : ndarray, shape (m,) [um]
        Tooth-to-tooth standard deviation of the generated surface.
    summary : dict
        :func:`sim.report.summarize_run`'s figures (chatter windows, first detection).
    spectrum_hz, spectrum_m_s2 : ndarray, shape (k,)
        Averaged amplitude spectrum of the acceleration while cutting [Hz, m/s^2].
    spindle_rpm : float [rev/min]
    machining_s : float [s]
        Simulated time of the run.
    """

    points: np.ndarray
    contact_mm: np.ndarray
    surface_um: np.ndarray
    marks_um: np.ndarray
    summary: dict
    spectrum_hz: np.ndarray
    spectrum_m_s2: np.ndarray
    spindle_rpm: float
    machining_s: float

    @property
    def chatter_windows(self) -> int:
        """Detector windows (while cutting) that called chatter."""
        return int(self.summary["chatter_windows"])

    @property
    def sustained_chatter(self) -> int:
        """Chatter episodes that outlived a detector window (:func:`sim.report.chatter_episodes`)."""
        return int(self.summary["sustained_episodes"])


def scenario_with_program(scn: PlanScenario, program: str | Path) -> PlanScenario:
    """The scenario with another NC program (same machine, tool, part)."""
    return dataclasses.replace(scn, base=dataclasses.replace(scn.base,
                                                             program_path=Path(program)))


def welch_spectrum(accel_m_s2: np.ndarray, fs_hz: float, segment: int = SPECTRUM_SEGMENT
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Averaged amplitude spectrum of the vector acceleration: f [Hz], A [m/s^2]
    (Hann segments of ``segment`` samples, half overlapping; the amplitude of a
    sine is its peak)."""
    from scipy import signal

    x = np.asarray(accel_m_s2, dtype=float)
    n = min(segment, x.shape[0])
    if n < 8:
        return np.zeros(0), np.zeros(0)
    f, p = signal.welch(x, fs=fs_hz, window="hann", nperseg=n, axis=0, scaling="spectrum")
    return f, np.sqrt(2.0 * p.sum(axis=1))


def verify_program(scn: PlanScenario, *, points: tuple[int, int] | None = None,
                   workpiece=None, progress: Callable[[int, int], None] | None = None,
                   seed: int = 0) -> Verification:
    """Run the scenario's program in the simulated machine and judge it.

    Parameters
    ----------
    scn : PlanScenario
        Its ``program`` is the one run (see :func:`scenario_with_program`).
    points : tuple (first, last), optional
        Run only these cutter locations.
    workpiece : orient.workpiece.WorkpieceModel, optional
        Already built for this part (saves its finite elements).
    progress : callable, optional
        ``progress(done, total)`` in cutter locations.
    seed : int
        Sensor noise seed.
    """
    nc = SimulatedNC(scn, points=points, seed=seed, workpiece=workpiece)
    times, accel, cutting = [], [], []
    total = nc.last - nc.first
    k = 0
    while not nc.done:
        sig = nc.tick()
        if sig.time_s.size:
            times.append(sig.time_s)
            accel.append(sig.acceleration_m_s2)
            cutting.append(np.full(sig.time_s.size, bool(nc.state.cutting)))
        k += 1
        if progress is not None and k % 200 == 0:
            progress(nc.point_index() - nc.first, total)
    if progress is not None:
        progress(total, total)
    t = np.concatenate(times) if times else np.zeros(0)
    acc = np.concatenate(accel) if accel else np.zeros((0, 2))
    cut = np.concatenate(cutting) if cutting else np.zeros(0, bool)
    det = ChatterDetector(detector_settings(nc.sensors))
    surf = nc.surface.arrays()
    summ = summarize_run(t, acc, surf, det, nc.rpm, nc.tool.flutes, cutting=cut)
    pts = surf["point"].astype(np.int64)
    off = surf["offset_mm"]
    u, inv = np.unique(pts, return_inverse=True)
    cnt = np.bincount(inv).astype(float)
    mean = np.bincount(inv, off) / cnt
    var = np.maximum(np.bincount(inv, off * off) / cnt - mean * mean, 0.0)
    gap = nc.contacts.gap_mm[u]
    f, a = welch_spectrum(acc[cut], nc.sensors.sample_rate_hz)
    return Verification(points=u, contact_mm=nc.contacts.point[u], surface_um=(mean + gap) * 1e3,
                        marks_um=np.sqrt(var) * 1e3, summary=summ, spectrum_hz=f,
                        spectrum_m_s2=a, spindle_rpm=nc.rpm, machining_s=float(nc.state.time_s))

