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

Coverage: the run is asked to cut every cutter location of its stretch where the
ball is in the material (:attr:`Verification.asked`: a feed move whose ball is
within ``CUTTING_GAP_MM`` of the design or deeper in it, and a rapid move whose
ball ends inside the design); :attr:`Verification.covered` are those the cutting
simulation ran on. A run that leaves any out is not complete
(:attr:`Verification.complete`) and says why (:attr:`Verification.stopped_reason`):
the NC stopped before the end of the stretch, or a rapid move goes into the
material (a crash on a machine; the simulation cuts at feed moves only).

The accelerometer stream is judged window by window with the controller's
detector (:func:`sim.report.summarize_run`, only windows that end while the
tool cuts; chatter is a sustained episode, a call that outlives its window),
and its spectrum while cutting is averaged (Welch).

A run can be made in stretches (:func:`simulate_stretch`), run apart, and judged as one
run (:func:`judge`): the main job splits each whole program's run at air moves
(:func:`split_at_air`) so that its workers share it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from orient.detect import ChatterDetector
from orient.scenario import PlanScenario

from .constants import (COVERAGE_LISTED, RAPID_MM_MIN, SPECTRUM_CHUNK_SEGMENTS,
                        SPECTRUM_SEGMENT, SPLIT_AIR_MIN_S, VERIFY_TICKS_PER_PUSH)
from .machine import SimulatedNC
from .program import PartProgram
from .report import summarize_run
from .sensors import detector_settings

__all__ = ["StretchRun", "Verification", "judge", "scenario_with_program", "simulate_stretch",
           "split_at_air", "verify_program"]


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
    stretch : tuple (int, int)
        First and last cutter location of the run (indices into the program read
        through the machine); the NC starts at the first, so the moves run are those
        into ``first + 1 .. last``.
    asked : ndarray of int, shape (a,)
        Cutter locations of the stretch (``first + 1 .. last``) where the ball is in the
        material: the ones the run must cut (a cutter location at the same place as the
        one before it, a move of zero length, is left out: there is nothing to run).
    covered : ndarray of int, shape (c,)
        Those of ``asked`` the cutting simulation ran on (the segment into each). A
        cutter location can be covered and still miss from ``points``: no tooth
        generated its surface on a segment shorter than a feed per tooth.
    reached : int
        The cutter location the NC was moving toward when the run ended (``last``
        when it ran to the end).
    stopped_reason : str or None
        Why the run did not cover every cutter location asked for; None when it did.
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
    stretch: tuple[int, int] = (0, 0)
    asked: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, np.int64))
    covered: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, np.int64))
    reached: int = 0
    stopped_reason: str | None = None

    @property
    def complete(self) -> bool:
        """The run cut every cutter location asked for (and no reason says otherwise):
        False is a failed verification, whatever its surface and chatter figures say."""
        return self.stopped_reason is None and self.missed.size == 0

    @property
    def missed(self) -> np.ndarray:
        """Cutter locations asked for that the run did not cut (indices, ascending)."""
        return np.setdiff1d(self.asked, self.covered)

    @property
    def coverage(self) -> str:
        """One line: how much of what was asked the run cut, and why not all."""
        head = (f"{self.covered.size} of {self.asked.size} cutter locations in the material "
                f"cut (stretch {self.stretch[0]}-{self.stretch[1]})")
        return head if self.complete else f"{head}: {self.stopped_reason}"

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


def welch_spectrum(accel_m_s2: np.ndarray, fs_hz: float, segment: int = SPECTRUM_SEGMENT,
                   chunk: int = SPECTRUM_CHUNK_SEGMENTS) -> tuple[np.ndarray, np.ndarray]:
    """Averaged amplitude spectrum of the vector acceleration: f [Hz], A [m/s^2]
    (Hann segments of ``segment`` samples, half overlapping; the amplitude of a
    sine is its peak).

    ``scipy.signal.welch``'s arithmetic (its ``ShortTimeFFT`` spectrogram, the
    one-sided doubling, the mean over segments: the same bits), the segments'
    spectra computed ``chunk`` segments at a time: scipy's own call holds its
    detrended, windowed and transformed segments of the whole run at once (231 MB
    over a 58 MB signal of 141 s), this the segments' spectra and one chunk (79 MB).
    """
    from scipy.signal import ShortTimeFFT, get_window

    x = np.asarray(accel_m_s2, dtype=float)
    n = min(segment, x.shape[0])
    if n < 8:
        return np.zeros(0), np.zeros(0)
    noverlap = n // 2
    sft = ShortTimeFFT(get_window("hann", n), n - noverlap, fs_hz, fft_mode="onesided",
                       mfft=n, scale_to="magnitude", phase_shift=None)
    segments = (x.shape[0] - noverlap) // sft.hop
    per = None
    for a in range(0, segments, max(1, int(chunk))):
        b = min(a + max(1, int(chunk)), segments)
        part = sft.spectrogram(x, x, detr="constant", p0=a, p1=b, k_offset=n // 2, axis=0)
        if per is None:                 # (frequencies, 2, segments)
            per = np.empty(part.shape[:-1] + (segments,), dtype=part.dtype)
        per[..., a:b] = part
    per[1:-1 if sft.mfft % 2 == 0 else None] *= 2        # one-sided, as welch doubles
    p = per.mean(axis=-1).real if segments > 1 else per[..., 0].real
    return sft.f, np.sqrt(2.0 * p.sum(axis=1))


@dataclass(frozen=True, eq=False)
class StretchRun:
    """One stretch of a program run in the simulated machine, not judged yet
    (:func:`simulate_stretch`; :func:`judge` makes the :class:`Verification` of one or
    more consecutive stretches).

    Attributes
    ----------
    time_s : ndarray, shape (k,) [s]
        The accelerometer samples' times, from the stretch's start.
    acceleration_m_s2 : ndarray, shape (k, 2) [m/s^2]
    cutting : ndarray of bool, shape (k,)
        The tool cut during the sample's tick.
    surface : dict of ndarray
        :meth:`sim.machine.SurfaceRecord.arrays` (per tooth; ``time_s`` from the
        stretch's start).
    gap_mm, contact_mm : ndarray, shapes (n,), (n, 3) [mm]
        The programmed ball's gap to the design and its contact point, per cutter
        location of the program.
    machining_s : float [s]
        Simulated time of the stretch.
    stretch, asked, covered, reached
        As :class:`Verification`'s, for this stretch.
    finished : bool
        The NC ran to the end of the stretch (:func:`judge` ends the joined run at the
        first stretch that did not).
    why : list of str
        Why the stretch did not cover what it was asked to (empty when it did): the parts
        of the joined run's :attr:`Verification.stopped_reason`.
    spindle_rpm : float [rev/min]
    flutes : int
    sensors : sim.sensors.Accelerometers
    """

    time_s: np.ndarray
    acceleration_m_s2: np.ndarray
    cutting: np.ndarray
    surface: dict
    gap_mm: np.ndarray
    contact_mm: np.ndarray
    machining_s: float
    stretch: tuple[int, int]
    asked: np.ndarray
    covered: np.ndarray
    reached: int
    finished: bool
    why: list
    spindle_rpm: float
    flutes: int
    sensors: object


def verify_program(scn: PlanScenario, *, points: tuple[int, int] | None = None,
                   workpiece=None, progress: Callable[[int, int], None] | None = None,
                   seed: int = 0, max_machining_s: float | None = None) -> Verification:
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
    max_machining_s : float, optional
        Time budget of the run in simulated seconds [s]: the NC stops when its clock
        passes it (the verification is then not complete and says so); default none.

    Returns
    -------
    Verification
        Its ``complete`` is False, with ``stopped_reason``, when the run did not cut every
        cutter location of the stretch where the ball is in the material.
    """
    return judge([simulate_stretch(scn, points=points, workpiece=workpiece, progress=progress,
                                   seed=seed, max_machining_s=max_machining_s)])


def simulate_stretch(scn: PlanScenario, *, points: tuple[int, int] | None = None,
                     workpiece=None, progress: Callable[[int, int], None] | None = None,
                     seed: int = 0, max_machining_s: float | None = None,
                     part: PartProgram | None = None) -> StretchRun:
    """:func:`verify_program`'s run, without the judgement: the accelerometer stream and
    the surface record of the stretch (the same arguments; ``part``, optional: the
    program's :class:`~sim.program.PartProgram` with its local cuts, derived once for
    all its stretches)."""
    if max_machining_s is not None and not max_machining_s > 0:
        raise ValueError(f"max_machining_s: expected a time > 0 s, got {max_machining_s!r}")
    nc = SimulatedNC(scn, points=points, seed=seed, workpiece=workpiece, part=part)
    times, accel, cutting = [], [], []
    total = nc.last - nc.first
    k = 0
    stop = None
    while not nc.done:
        if max_machining_s is not None and nc.state.time_s >= max_machining_s:
            stop = f"the run's time budget ({max_machining_s:g} s simulated) ran out"
            break
        # up to the next multiple of VERIFY_TICKS_PER_PUSH servo ticks at once, to the
        # accelerometers in one call (the same samples as tick by tick)
        run = nc.run_ticks(VERIFY_TICKS_PER_PUSH - k % VERIFY_TICKS_PER_PUSH, to_end=True,
                           until_s=max_machining_s)
        k += run.steps.size
        sig, per_tick = nc.stream.push_chunks(run.time_s, run.tool_acceleration_m_s2,
                                              run.steps)
        if sig.time_s.size:
            times.append(sig.time_s)
            accel.append(sig.acceleration_m_s2)
            cutting.append(np.repeat(run.cutting, per_tick))
        if progress is not None and k % 200 == 0:
            progress(nc.point_index() - nc.first, total)
    if progress is not None:
        progress(nc.point_index() - nc.first if stop else total, total)
    t = np.concatenate(times) if times else np.zeros(0)
    acc = np.concatenate(accel) if accel else np.zeros((0, 2))
    cut = np.concatenate(cutting) if cutting else np.zeros(0, bool)
    for parts in (times, accel, cutting):   # the run's samples held once from here, not twice
        parts.clear()
    asked, covered, reached, why = _coverage(nc, stop)
    return StretchRun(time_s=t, acceleration_m_s2=acc, cutting=cut, surface=nc.surface.arrays(),
                      gap_mm=nc.contacts.gap_mm, contact_mm=nc.contacts.point,
                      machining_s=float(nc.state.time_s), stretch=(nc.first, nc.last),
                      asked=asked, covered=covered, reached=reached, finished=bool(nc.done),
                      why=why, spindle_rpm=nc.rpm, flutes=nc.tool.flutes, sensors=nc.sensors)


def judge(runs: list[StretchRun]) -> Verification:
    """The :class:`Verification` of consecutive stretches of one program, run one after the
    other or apart (:func:`split_at_air`): their streams and surface records joined, each
    stretch's times after the ones before, then judged as one run's (the detector, the
    surface per cutter location, the averaged spectrum, the coverage).

    Parameters
    ----------
    runs : list of StretchRun
        In program order, each starting where the one before ended, with one spindle
        speed, tool and accelerometers.
    """
    if not runs:
        raise ValueError("runs: expected at least one stretch")
    for a, b in zip(runs[:-1], runs[1:]):
        if b.stretch[0] != a.stretch[1] or b.spindle_rpm != a.spindle_rpm \
                or b.flutes != a.flutes or b.sensors != a.sensors:
            raise ValueError(f"runs: stretch {b.stretch} does not follow {a.stretch} with "
                             f"the same spindle speed, tool and accelerometers")
    # a stretch whose NC stopped before its end ends the run there, as one run would
    stopped = next((k for k, r in enumerate(runs) if not r.finished), None)
    if stopped is not None:
        runs = runs[:stopped + 1]
    head = runs[0]
    start = np.cumsum([0.0] + [r.machining_s for r in runs[:-1]])
    if len(runs) == 1:
        t, acc, cut, surf = head.time_s, head.acceleration_m_s2, head.cutting, head.surface
    else:
        t = np.concatenate([r.time_s + s for r, s in zip(runs, start)])
        acc = np.concatenate([r.acceleration_m_s2 for r in runs])
        cut = np.concatenate([r.cutting for r in runs])
        surf = {k: np.concatenate([r.surface[k] + (s if k == "time_s" else 0)
                                   for r, s in zip(runs, start)]) for k in head.surface}
    det = ChatterDetector(detector_settings(head.sensors))
    summ = summarize_run(t, acc, surf, det, head.spindle_rpm, head.flutes, cutting=cut)
    # the spectrum reads the cutting samples alone: the stream's times and the whole
    # stream are let go before it holds its segments' spectra (the run's memory peak)
    del t
    acc = acc[cut]
    pts = surf["point"].astype(np.int64)
    off = surf["offset_mm"]
    u, inv = np.unique(pts, return_inverse=True)
    cnt = np.bincount(inv).astype(float)
    mean = np.bincount(inv, off) / cnt
    var = np.maximum(np.bincount(inv, off * off) / cnt - mean * mean, 0.0)
    gap = head.gap_mm[u]
    f, a = welch_spectrum(acc, head.sensors.sample_rate_hz)
    asked = np.concatenate([r.asked for r in runs])
    covered = np.concatenate([r.covered for r in runs])
    why = [w for r in runs for w in r.why]
    missed = np.setdiff1d(asked, covered)
    reason = None if not why else (f"{missed.size} of {asked.size} cutter locations in the "
                                   f"material not cut: " + "; ".join(why))
    return Verification(points=u, contact_mm=head.contact_mm[u], surface_um=(mean + gap) * 1e3,
                        marks_um=np.sqrt(var) * 1e3, summary=summ, spectrum_hz=f,
                        spectrum_m_s2=a, spindle_rpm=head.spindle_rpm,
                        machining_s=float(sum(r.machining_s for r in runs)),
                        stretch=(head.stretch[0], runs[-1].stretch[1]),
                        asked=asked, covered=covered, reached=runs[-1].reached,
                        stopped_reason=reason)


def split_at_air(scn: PlanScenario, parts: int, part: PartProgram | None = None
                 ) -> list[tuple[int, int]]:
    """Up to ``parts`` consecutive stretches of the scenario's program, split where the
    tool is in the air, of about equal cutting time: stretches that can run apart
    (:func:`simulate_stretch`) and be judged as one run (:func:`judge`).

    A split is at a cutter location whose move in and the move before are both out of
    the material, with cutting before and after it, in an air gap of at least
    ``SPLIT_AIR_MIN_S`` from the last move in the material to the next (an air move
    between passes: the cut's vibration has rung down, and the next cut's surface memory
    is set where it starts, as in one run). Fewer stretches where the program has fewer
    such places. The stretches take the whole program's local cuts and spindle speed
    only where it has one speed (:func:`judge` refuses stretches at different speeds).

    Parameters
    ----------
    scn : PlanScenario
    parts : int
        Stretches wanted (>= 1).
    part : PartProgram, optional
        The scenario's program and part, if already made (default: made here, without
        the local cuts).

    Returns
    -------
    list of (first, last)
        Cutter location stretches (the program read through the machine), each starting
        where the one before ends, from 0 to the last.
    """
    if not (isinstance(parts, (int, np.integer)) and parts >= 1):
        raise ValueError(f"parts: expected an integer >= 1, got {parts!r}")
    if part is None:
        part = PartProgram(scn, cuts=False)
    n = len(part.cam)
    material = part.contacts.touching | part.rapid_in_material
    seg = np.zeros(n)
    seg[1:] = np.linalg.norm(np.diff(part.cam.tip, axis=0), axis=1)
    feed = np.where(part.cam.rapid, RAPID_MM_MIN, part.cam.feed_mm_min)
    move_s = 60.0 * seg / np.maximum(feed, 1e-9)
    cutting_s = np.where(material, move_s, 0.0)
    done = np.cumsum(cutting_s)                      # cutting time up to each location
    clock = np.cumsum(move_s)                        # programmed time up to each location
    air = np.zeros(n, bool)
    air[2:n - 1] = ~material[1:n - 2] & ~material[2:n - 1]
    # cutting on both sides, and an air gap long enough for the vibration to ring down:
    # from the last location in the material before to the first one after
    cut_at = np.flatnonzero(material)
    before = np.searchsorted(cut_at, np.arange(n), side="left") - 1
    after = np.searchsorted(cut_at, np.arange(n), side="right")
    inside = (before >= 0) & (after < cut_at.size)
    gap = np.zeros(n)
    gap[inside] = clock[cut_at[after[inside]] - 1] - clock[cut_at[before[inside]]]
    where = np.flatnonzero(air & inside & (gap >= SPLIT_AIR_MIN_S))
    cuts: list[int] = []
    if where.size and done[-1] > 0:
        for k in range(1, parts):
            c = int(where[np.argmin(np.abs(done[where] - done[-1] * k / parts))])
            if c not in cuts:
                cuts.append(c)
    bounds = [0, *sorted(cuts), n - 1]
    return list(zip(bounds[:-1], bounds[1:]))


def _listed(idx: np.ndarray, most: int = COVERAGE_LISTED) -> str:
    """``'3, 4, 9'`` or ``'3, 4, 9, ... (12 in all)'``."""
    head = ", ".join(str(int(i)) for i in idx[:most])
    return head if idx.size <= most else f"{head}, ... ({idx.size} in all)"


def _coverage(nc: SimulatedNC, stop: str | None = None
              ) -> tuple[np.ndarray, np.ndarray, int, list[str]]:
    """What the run was asked to cut, what it cut, where the NC got to, and why not all
    (:class:`Verification`'s ``asked``, ``covered``, ``reached``, and the parts of its
    ``stopped_reason``: empty when it covered everything); ``stop``: why the run was
    ended before the NC finished."""
    first, last = nc.first, nc.last
    rows = np.arange(first + 1, last + 1)
    moves = nc.arc[rows] > nc.arc[rows - 1]
    material = nc.contacts.touching[rows] | nc.part.rapid_in_material[rows]
    asked = rows[moves & material]
    covered = asked[nc.cut_at[asked]]
    reached = last if nc.done else nc.point_index()
    if not nc.done:                 # the move into ``reached`` was cut short
        covered = covered[covered < reached]
    missed = np.setdiff1d(asked, covered)
    if missed.size == 0 and stop is None:
        return asked, covered, reached, []
    why = []
    if not nc.done:
        why.append(f"{stop or 'the NC stopped'} on the move into cutter location {reached} "
                   f"(stretch {first}-{last})")
    rapid = missed[nc.cam.rapid[missed]]
    if rapid.size:
        why.append(f"{rapid.size} rapid move(s) into the material, not simulated (a crash on "
                   f"a machine): cutter locations {_listed(rapid)}, program lines "
                   f"{_listed(nc.part.cam_line[rapid])}")
    other = missed[~nc.cam.rapid[missed]]
    if nc.done and other.size:
        why.append(f"{other.size} feed move(s) in the material not cut: cutter locations "
                   f"{_listed(other)}")
    return asked, covered, reached, why

