"""The simulated NC: runs a 5-axis program and cuts where the tool is in the workpiece.

``docs/method.md`` §8. The NC follows the program's cutter locations (nc's
reader and kinematics) along the tip polyline at the programmed feed times
the feed override, one interpolation period (``TICK_S``) at a time. An orientation offset command
(lead and tilt added to the program's posture at each cutter location, the
ball centre kept) is taken only after it is checked at the current and the
next ``LOOKAHEAD_POINTS`` cutter locations against the axis limits (nc's
kinematics) and shank/holder interference (orient's FCL checker); otherwise it
is refused and the offset in effect stays. Where the ball touches the design
(a feed move within ``CUTTING_GAP_MM`` of it or deeper in it, a gouge included:
:class:`sim.program.PartProgram`), the cutting simulation (:mod:`sim.cutting`)
runs with the local cut and the posture in effect: along the segment into a
cutter location the force goes linearly from the previous cutter location's
engagement to this one's (the
posture changes continuously, :class:`sim.cutter.Cut`; a tick is split where
it passes a cutter location), with the dynamics at the cutter location (the
wall's modes there); the vibration and the surface memory carry on across
every change (:meth:`sim.cutter.Cutter.switch`). Elsewhere the modes ring down. The tool's acceleration goes to the
two accelerometers (:class:`sim.sensors.AccelerometerStream`).

The NC does no I/O: the Modbus server (:mod:`sim.server`) reads its state and
passes the commands.
"""

from __future__ import annotations

import bisect
import dataclasses
import math
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from errpred.spindle import tooth_period
from nc.kinematics import solve_path
from orient.dynamics import ModalSystem
from orient.geometry import posture_axis
from orient.scenario import PlanScenario
from orient.workpiece import WorkpieceModel

from .constants import (
    LOOKAHEAD_POINTS,
    MATERIAL_SCATTER,
    MATERIAL_SCATTER_STREAM,
    MICRO_EDGES_ENVELOPE,
    MODEL_CACHE,
    RAPID_MM_MIN,
    TICK_S,
)
from .cutter import Cut, Cutter
from .cutting import CuttingModel, prepare_cut, steps_per_rev_for, with_system
from .program import PartProgram
from .registers import ACK, STATUS
from .sensors import Accelerometers, AccelerometerStream

__all__ = ["NO_WALL", "NCState", "SimulatedNC", "SurfaceRecord", "TickRun", "carry_wall_state"]


@dataclass
class NCState:
    """What the NC shows (the Modbus input registers in engineering units)."""

    status: int = STATUS["idle"]
    block: int = 0
    joints: np.ndarray = field(default_factory=lambda: np.zeros(5))
    spindle_rpm: float = 0.0
    feed_override_pct: float = 100.0
    lead_offset_deg: float = 0.0
    tilt_offset_deg: float = 0.0
    ack_seq: int = 0
    ack_state: int = ACK["none"]
    watchdog_tripped: int = 0
    cutting: int = 0
    time_s: float = 0.0


@dataclass
class SurfaceRecord:
    """The generated surface, once per tooth while cutting.

    Attributes
    ----------
    time_s, point, offset_mm, lead_offset_deg, tilt_offset_deg : list
        Per tooth: time [s], cutter location index, relative displacement
        along the surface normal at the generating instant [mm] (the surface's
        deviation), and the orientation offset in effect [deg].
    """

    time_s: list = field(default_factory=list)
    point: list = field(default_factory=list)
    offset_mm: list = field(default_factory=list)
    lead_offset_deg: list = field(default_factory=list)
    tilt_offset_deg: list = field(default_factory=list)

    def arrays(self) -> dict:
        return {k: np.asarray(getattr(self, k)) for k in
                ("time_s", "point", "offset_mm", "lead_offset_deg", "tilt_offset_deg")}


class TickRun(NamedTuple):
    """Interpolation periods run at once (:meth:`SimulatedNC.run_ticks`).

    Attributes
    ----------
    time_s : ndarray, shape (k,) [s]
        The simulation instants of all the periods, in order.
    tool_acceleration_m_s2 : ndarray, shape (k, 3) [m/s^2]
        Tool acceleration at those instants (workpiece frame).
    steps : ndarray of int, shape (periods,)
        Instants per period (they sum to ``k``).
    cutting : ndarray of bool, shape (periods,)
        Whether the tool was in the cut at the end of each period (``NCState.cutting``).
    """

    time_s: np.ndarray
    tool_acceleration_m_s2: np.ndarray
    steps: np.ndarray
    cutting: np.ndarray


#: No workpiece modes: ``(level, index, amp)`` of :meth:`WorkpieceModel.shape_at`.
NO_WALL = (-1, np.zeros(0, dtype=np.int64), np.zeros(0))


def carry_wall_state(state: np.ndarray, n_tool: int, old: tuple, new: tuple) -> np.ndarray:
    """The modal state ``(eta, eta')`` when the cut moves to another point of the part.

    The tool modes (the first ``n_tool`` rows) are the same. A workpiece mode's
    row is its displacement at the cutting point, ``a q`` with ``q`` its modal
    coordinate: the vibration goes on, so ``q`` is kept and the row becomes
    ``a_new / a_old`` times the old one (a node between the points flips its
    sign). A mode that was not in the old set (or another level of the wall)
    starts at rest.

    Parameters
    ----------
    state : ndarray, shape (n_tool + k_old, 2) [m, m/s]
    n_tool : int
    old, new : tuple (level, index, amp)
        :meth:`orient.workpiece.WorkpieceModel.shape_at` at the two points.

    Returns
    -------
    ndarray, shape (n_tool + k_new, 2)
    """
    lev0, idx0, amp0 = old
    lev1, idx1, amp1 = new
    out = np.zeros((n_tool + len(idx1), 2))
    k = min(n_tool, state.shape[0])
    out[:k] = state[:k]
    if lev0 == lev1 and lev0 >= 0:
        row = {int(m): r for r, m in enumerate(idx0)}
        for r, m in enumerate(idx1):
            j = row.get(int(m))
            if j is not None and n_tool + j < state.shape[0] and amp0[j] != 0.0:
                out[n_tool + r] = state[n_tool + j] * (amp1[r] / amp0[j])
    return out


class SimulatedNC:
    """A 5-axis NC with a cutting simulation behind it.

    Parameters
    ----------
    scn : orient.scenario.PlanScenario
        Program, machine, tool, stock, tool modes and workpiece model.
    sensors : Accelerometers, optional
    points : tuple (first, last), optional
        Run only the cutter locations ``first .. last`` (indices into the
        program's cutter locations) instead of the whole program.
    seed : int
        Seed of the sensor noise and of the work material's scatter
        (``sim.constants.MATERIAL_SCATTER``).
    workpiece : orient.workpiece.WorkpieceModel, optional
        A workpiece model already built for this scenario (its finite elements
        take seconds); default: built here.
    part : sim.program.PartProgram, optional
        This scenario's program and part with their local cuts, already derived (for
        any stretch: :meth:`~sim.program.PartProgram.stretch` takes ``points``; a
        program's stretches run apart share it); default: derived here.

    Attributes
    ----------
    cut_at : ndarray of bool, shape (n,)
        Per cutter location of the program: the cutting simulation ran on the
        segment into it (what :func:`sim.verify.verify_program` counts as covered).
    """

    def __init__(self, scn: PlanScenario, *, sensors: Accelerometers | None = None,
                 points: tuple[int, int] | None = None, seed: int = 0,
                 workpiece: WorkpieceModel | None = None,
                 part: PartProgram | None = None) -> None:
        self.scn = scn
        base = scn.base
        if part is None:
            part = PartProgram(scn, points)
        else:
            if not part.with_cuts or part.scn.path != scn.path \
                    or part.scn.base.program_path != base.program_path:
                raise ValueError(f"part: expected the program and part of {scn.path} "
                                 f"({base.program_path}) with their local cuts, got those of "
                                 f"{part.scn.path} ({part.scn.base.program_path})"
                                 f"{'' if part.with_cuts else ' without local cuts'}")
            part = part.stretch(points)
        self.part = part
        self.machine, self.cam, self.contacts = part.machine, part.cam, part.contacts
        first = part.first
        self.first, self.last, self.rpm = first, part.last, part.rpm
        self.cuts = part.cuts
        self.cam_lead, self.cam_tilt = part.cam_lead, part.cam_tilt
        self.tool = base.tool
        design = part.design
        self.workpiece = workpiece if workpiece is not None else \
            WorkpieceModel(scn.workpiece, self.contacts.point[part.touch])
        self.tool_system = ModalSystem.tool(base.compliance)
        f_max = float(self.tool_system.natural_frequency_rad_s.max()) / (2 * math.pi)
        for lev in self.workpiece.levels:
            f_max = max(f_max, float(np.max(lev.frequencies_hz)))
        self.steps_per_rev = steps_per_rev_for(f_max, self.rpm, self.tool.flutes)
        self.dt_s = tooth_period(self.rpm, self.steps_per_rev)
        self.edges = self.tool.micro_edges(MICRO_EDGES_ENVELOPE)
        self.cutter = Cutter(self.steps_per_rev, len(self.edges))
        self.sensors = sensors if sensors is not None else Accelerometers()
        self.stream = AccelerometerStream(self.sensors, self.dt_s, seed=seed)
        self._scatter = np.random.default_rng([MATERIAL_SCATTER_STREAM, seed])
        self._scatter_tooth, self._scatter_now = -1, 1.0
        self.checker = scn.interference_checker(design)
        seg = np.linalg.norm(np.diff(self.cam.tip, axis=0), axis=1)
        self.arc = np.concatenate([[0.0], np.cumsum(seg)])
        self.s = self.arc[first]
        # per cutter location, as plain Python values for the per-period bookkeeping
        self._arc = self.arc.tolist()
        self._feed = [RAPID_MM_MIN if r else float(f)
                      for r, f in zip(self.cam.rapid.tolist(), self.cam.feed_mm_min.tolist())]
        self._block = [int(b) for b in self.cam.block]
        self._touching = [bool(t) for t in self.contacts.touching]
        self._idle_at: tuple | None = None
        self.state = NCState(spindle_rpm=self.rpm)
        self.surface = SurfaceRecord()
        self.cut_at = np.zeros(len(self.cam), bool)
        self._models: OrderedDict = OrderedDict()
        self._current, self._current_key, self._current_at = None, None, None
        self._shapes: dict[int, tuple] = {}
        self._shape_now = NO_WALL
        self._joints = solve_path(self.machine, self.cam.tip[first:first + 1],
                                  self.cam.axis[first:first + 1]).joints[0]
        self.state.joints = self._joints.copy()
        self.state.block = int(self.cam.block[first])

    # --- commands ----------------------------------------------------------------
    def set_feed_override(self, percent: float) -> None:
        """Feed override [%] (0 holds the feed; the spindle keeps turning)."""
        if not (math.isfinite(percent) and 0.0 <= percent <= 150.0):
            raise ValueError(f"feed override: expected 0..150 %, got {percent!r}")
        self.state.feed_override_pct = float(percent)

    def command_orientation(self, lead_deg: float, tilt_deg: float, seq: int) -> int:
        """Check and take an orientation offset; returns the acknowledgement (``ACK``)."""
        if not (math.isfinite(lead_deg) and math.isfinite(tilt_deg)):
            raise ValueError("orientation command: expected finite lead and tilt")
        i = self.point_index()
        rows = np.arange(i, min(i + LOOKAHEAD_POINTS, self.last) + 1)
        rows = rows[self.contacts.touching[rows]] if np.any(self.contacts.touching[rows]) \
            else rows[:1]
        tips, axes = self._posture(rows, math.radians(lead_deg), math.radians(tilt_deg))
        ack = ACK["applied"]
        try:
            solve_path(self.machine, tips, axes, start=self._joints)
        except ValueError:
            ack = ACK["refused_axis_limit"]
        if ack == ACK["applied"] and np.any(self.contacts.touching[rows]) \
                and not np.all(self.checker.check(tips, axes).feasible):
            ack = ACK["refused_interference"]
        if ack == ACK["applied"]:
            self.state.lead_offset_deg = float(lead_deg)
            self.state.tilt_offset_deg = float(tilt_deg)
        self.state.ack_seq = int(seq)
        self.state.ack_state = ack
        return ack

    def reset_orientation(self) -> None:
        """The safe default: the program's own posture (the watchdog's action)."""
        self.state.lead_offset_deg = self.state.tilt_offset_deg = 0.0
        self.state.ack_state = ACK["reset_by_watchdog"]

    # --- motion ------------------------------------------------------------------
    def point_index(self) -> int:
        """Cutter location the tool is moving toward (index into the program)."""
        j = bisect.bisect_right(self._arc, self.s)     # np.searchsorted(side="right")
        return min(max(j, self.first), self.last)

    def _posture(self, rows: np.ndarray, dlead: float, dtilt: float
                 ) -> tuple[np.ndarray, np.ndarray]:
        """Tips and axes at cutter locations ``rows`` with the offset applied (ball centre
        kept where the ball touches; elsewhere the program's posture)."""
        tips = self.cam.tip[rows].copy()
        axes = self.cam.axis[rows].copy()
        t = self.contacts.touching[rows]
        if np.any(t) and (dlead or dtilt):
            r = rows[t]
            u = posture_axis(self.contacts.normal[r], self.contacts.feed[r],
                             self.cam_lead[r] + dlead, self.cam_tilt[r] + dtilt)
            axes[t] = u
            tips[t] = self.contacts.centre[r] - self.tool.radius_mm * u
        return tips, axes

    def _key(self, i: int) -> tuple:
        """What the engagement at cutter location ``i`` depends on, with the offset in
        effect: posture relative to the local frame, the local frame, the cut."""
        lead = float(self.cam_lead[i]) + math.radians(self.state.lead_offset_deg)
        tilt = float(self.cam_tilt[i]) + math.radians(self.state.tilt_offset_deg)
        n, f = self.contacts.normal[i], self.contacts.feed[i]
        return (round(lead, 5), round(tilt, 5), tuple(np.round(n, 6)), tuple(np.round(f, 6)),
                tuple(np.round(self.cuts[i].row(), 9)))

    def _base(self, i: int, key: tuple, system: ModalSystem, axis: bool = True):
        """The engagement at cutter location ``i`` (cached by ``key``: shared by the
        cutter locations of a pass; built with ``system``, which the engagement does
        not depend on), the tool axis there (None when ``axis`` is False and the
        engagement was cached: not needed), and whether it was made now."""
        lead, tilt = key[0], key[1]
        n, f = self.contacts.normal[i], self.contacts.feed[i]
        if key in self._models:
            self._models.move_to_end(key)
            return self._models[key], posture_axis(n, f, lead, tilt) if axis else None, False
        u = posture_axis(n, f, lead, tilt)
        base = prepare_cut(self.tool, self.scn.base.coefficients, u, n, f, self.cuts[i],
                           system, self.rpm, edges=self.edges, steps_per_rev=self.steps_per_rev)
        self._models[key] = base
        if len(self._models) > MODEL_CACHE:
            self._models.popitem(last=False)
        return base, u, True

    def _model(self, i: int) -> tuple[CuttingModel, CuttingModel | None]:
        """Cutting model on the segment into cutter location ``i`` with the offset in
        effect: ``i``'s engagement with the dynamics at ``i`` (the wall modes at the
        point), and the engagement of the cutter location before it with the same
        dynamics (None where the tool was not cutting there, or the engagement is the
        same), which the segment blends from (:class:`sim.cutter.Cut`)."""
        at = (i, self.state.lead_offset_deg, self.state.tilt_offset_deg)
        if at == self._current_at:         # the keys depend on nothing else
            return self._current
        self._current_at = at
        key = self._key(i)
        prev_key = None
        j = i - 1
        if j >= self.first and self.contacts.touching[j] and j in self.cuts \
                and not self.cam.rapid[i]:
            prev_key = self._key(j)
            if prev_key == key:
                prev_key = None
        if (i, key, prev_key) != self._current_key:
            system = self.workpiece.system_at(self.tool_system, self.contacts.point[i])
            base, u, fresh = self._base(i, key, system)
            # made with this system just now, the base is with_system(base, system, u)
            # already (the same modes turned to u, the same step map)
            model = base if fresh else with_system(base, system, u)
            start = None
            if prev_key is not None:
                before, _, _ = self._base(j, prev_key, system, axis=False)
                start = dataclasses.replace(model, table=before.table,
                                            generating=before.generating)
            self._current = (model, start)
            self._current_key = (i, key, prev_key)
        return self._current

    def _weight(self, i: int, s: float) -> float:
        """Share of cutter location ``i``'s engagement at arc length ``s`` [mm] on the
        segment into it (0 at the one before, 1 at ``i``)."""
        a, b = self._arc[max(i - 1, 0)], self._arc[i]
        if i <= self.first or b <= a:
            return 1.0
        return min(max((s - a) / (b - a), 0.0), 1.0)

    def _pieces(self, s0: float, s1: float, n: int) -> list[tuple[int, int, float, float]]:
        """The tick's ``n`` steps from arc length ``s0`` to ``s1`` split where it passes a
        cutter location: ``(i, steps, weight at start, weight at end)`` per segment."""
        if s1 <= s0:
            i = self.point_index()
            w = self._weight(i, s1)
            return [(i, n, w, w)]
        # the cutter locations strictly between (arc is non-decreasing: a slice); plain
        # floats, the arithmetic of numpy's searchsorted and round (half to even)
        arc = self._arc
        marks = [s0, *arc[bisect.bisect_right(arc, s0):bisect.bisect_left(arc, s1)], s1]
        steps = [round(n * (m - s0) / (s1 - s0)) for m in marks]
        out = []
        for a, b, ka, kb in zip(marks[:-1], marks[1:], steps[:-1], steps[1:]):
            if kb > ka:
                i = min(max(bisect.bisect_right(arc, 0.5 * (a + b)), self.first), self.last)
                out.append((i, kb - ka, self._weight(i, a), self._weight(i, b)))
        return out

    @property
    def done(self) -> bool:
        return self.s >= self.arc[self.last] - 1e-12

    def tick(self, dt_s: float = TICK_S):
        """Advance the NC by one interpolation period; returns the new accelerometer samples.

        Returns
        -------
        SensorSignals
        """
        return self.stream.push(*self.tick_motion(dt_s))

    def tick_motion(self, dt_s: float = TICK_S) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`tick` without the accelerometers: the period's simulation instants [s]
        and tool acceleration [m/s^2] (shapes (k,) and (k, 3)), which the caller hands to
        ``self.stream`` in order (several periods at once: :meth:`run_ticks` and
        :meth:`sim.sensors.AccelerometerStream.push_chunks`, the same samples)."""
        run = self.run_ticks(1, dt_s)
        return run.time_s, run.tool_acceleration_m_s2

    def run_ticks(self, count: int, dt_s: float = TICK_S, *, to_end: bool = False,
                  until_s: float | None = None) -> TickRun:
        """``count`` interpolation periods, as :meth:`tick_motion` runs them one by one (the
        same numbers bit for bit), with one kernel call for each stretch of steps whose
        cut does not change (the periods between two cutter locations, an air move)
        instead of one a period: the NC's state after each period (path position,
        clock, pieces split at cutter locations) is worked out in plain floats first,
        the cutting simulation then runs stretch by stretch, and the cut is changed
        (:meth:`_switch`) between stretches where the path passes a cutter location.

        Parameters
        ----------
        count : int
            Periods to run at most.
        dt_s : float [s]
            The interpolation period.
        to_end : bool
            Stop before a period when the NC has finished (the end of its stretch).
        until_s : float, optional [s]
            Stop before a period when the NC's clock has reached this time.

        Returns
        -------
        TickRun
        """
        st = self.state
        arc = self._arc
        feed = self._feed
        steps, cutting, times, accel = [], [], [], []
        gathered: list = []                   # the stretch in hand: [cut, system, pieces]
        now_cut, now_shape = self.cutter.cut, self._shape_now   # after the gathered pieces
        t_cut = self.cutter.time_s
        for _ in range(int(count)):
            if to_end and self.done or until_s is not None and st.time_s >= until_s:
                break
            s0 = self.s
            if self.done:
                st.status = STATUS["finished"]
            else:
                st.status = STATUS["running"]
                i = self.point_index()
                self.s = min(self.s + feed[i] * st.feed_override_pct / 100.0 / 60.0 * dt_s,
                             arc[self.last])
                st.block = self._block[i]
            n = max(1, round((st.time_s + dt_s - t_cut) / self.dt_s))
            moving = self.s > s0
            for i, k, w0, w1 in self._pieces(s0, self.s, n):
                touching = (moving or not self.done) and self._touching[i] and i in self.cuts
                if touching and st.feed_override_pct > 0:
                    model, start = self._model(i)
                    cut = Cut(model, start, w0)
                    system, dt = model.system, model.dt_s
                else:
                    cut, system, dt = None, self._idle_system(i), self.dt_s
                shape = self._shape(i)
                same = shape is now_shape and (cut is None and now_cut is None
                                               or cut is not None and cut.same_as(now_cut))
                if not (same and gathered and gathered[1] is system):
                    self._flush(gathered, times, accel)
                    self._switch(i, cut)
                    gathered = [cut, system, []]
                gathered[2].append((i, k, w0, w1))
                t_cut += k * dt
                now_cut = None if cut is None else Cut(cut.model, cut.previous, w1)
                now_shape = shape
            st.cutting = int(touching)
            st.time_s = t_cut
            steps.append(n)
            cutting.append(touching)
        self._flush(gathered, times, accel)
        if times and self.cutter.time_s != st.time_s:      # the plan and the run disagree
            raise RuntimeError("run_ticks: the cutter's clock left the NC's")
        return TickRun(time_s=np.concatenate([np.zeros(0), *times]),
                       tool_acceleration_m_s2=np.concatenate([np.zeros((0, 3)), *accel]),
                       steps=np.array(steps, dtype=np.int64),
                       cutting=np.array(cutting, dtype=bool))

    def _flush(self, gathered: list, times: list, accel: list) -> None:
        """Run the stretch of pieces in hand (``[cut, system, [(i, steps, w0, w1), ...]]``,
        one cut or one idle system) in one call of the cutter; its instants and tool
        acceleration go to ``times`` and ``accel``, its surface to :attr:`surface`."""
        if not gathered or not gathered[2]:
            return
        cut, system, pieces = gathered
        idx, counts, w0, w1 = zip(*pieces)
        if cut is None:
            run = self.cutter.idle_pieces(self.dt_s, counts, system)
        else:
            run, teeth = self.cutter.advance_pieces(
                cut.model, counts, previous=cut.previous, weights=(w0, w1),
                variation=self._variation(int(sum(counts))))
            self.cut_at[list(idx)] = True
            self._record(run, idx, counts, teeth)
        times.append(run.time_s)
        accel.append(run.tool_acceleration_m_s2)

    def _record(self, run, idx: tuple, counts: tuple, teeth: np.ndarray) -> None:
        """The generated surface of a stretch's pieces (cutter locations ``idx``, ``counts``
        steps, ``teeth`` offsets each) to :attr:`surface`, as each piece's run gives it."""
        st, rec = self.state, self.surface
        t = run.time_s
        off = run.surface_offset_mm.tolist()
        a = b = 0
        for i, k, m in zip(idx, counts, teeth.tolist()):
            if m:
                rec.time_s.extend(np.linspace(t[a], t[a + k - 1], m))
                rec.point.extend([i] * m)
                rec.offset_mm.extend(off[b:b + m])
                rec.lead_offset_deg.extend([st.lead_offset_deg] * m)
                rec.tilt_offset_deg.extend([st.tilt_offset_deg] * m)
            a += k
            b += m

    def _idle_system(self, i: int) -> ModalSystem:
        """The dynamics the modes ring down in on the segment into ``i`` when the tool does
        not cut: the wall's at ``i`` where the ball touches it, else the tool's (the last
        point's kept: a stretch of idle periods there is one call)."""
        if not self.contacts.touching[i]:
            return self.tool_system
        if self._idle_at is None or self._idle_at[0] != i:
            self._idle_at = (i, self.workpiece.system_at(self.tool_system,
                                                         self.contacts.point[i]))
        return self._idle_at[1]

    def _shape(self, i: int) -> tuple:
        """The wall's mode shapes at cutter location ``i`` (``NO_WALL`` off the part)."""
        if not self.contacts.touching[i]:
            return NO_WALL
        if i not in self._shapes:
            self._shapes[i] = self.workpiece.shape_at(self.contacts.point[i])
        return self._shapes[i]

    def _variation(self, n: int) -> np.ndarray:
        """Chip-width factors of the next ``n`` steps: one draw per tooth pass, held over
        it (``sim.constants.MATERIAL_SCATTER``; the same pass keeps its draw across
        ticks)."""
        spt = self.steps_per_rev // self.tool.flutes
        tooth = (self.cutter.step + np.arange(n)) // spt
        first, last = int(tooth[0]), int(tooth[-1])
        held = first <= self._scatter_tooth          # the stretch goes on with a pass drawn
        start = first + 1 if held else first
        draws = 1.0 + MATERIAL_SCATTER * self._scatter.standard_normal(max(last - start + 1, 0))
        values = np.maximum(draws, 0.0)
        if held:
            values = np.concatenate([[self._scatter_now], values])
        self._scatter_tooth, self._scatter_now = last, float(values[-1])
        return values[tooth - first]

    def _switch(self, i: int, cut: Cut | None) -> None:
        """Take ``cut`` on the segment into cutter location ``i`` (None: not cutting) as
        a machine would, moving continuously: the vibration goes on in the workpiece's
        modes at the new point (:func:`carry_wall_state`) and follows the change of
        the cut's forced response (:meth:`sim.cutter.Cutter.switch`)."""
        shape = self._shape(i)
        now = self.cutter.cut
        if shape is self._shape_now and (cut is None and now is None
                                         or cut is not None and cut.same_as(now)):
            return
        n_tool, before = self.tool_system.n_modes, self._shape_now
        self.cutter.switch(cut, lambda x: carry_wall_state(x, n_tool, before, shape))
        self._shape_now = shape

    def update_joints(self) -> None:
        """Machine joints of the current posture (for the display; costs a kinematic solve)."""
        i = self.point_index()
        a = int(max(self.first, i - 1))
        w = (self.s - self.arc[a]) / max(self.arc[i] - self.arc[a], 1e-12) if i > a else 1.0
        tips, axes = self._posture(np.array([a, i]), math.radians(self.state.lead_offset_deg),
                                   math.radians(self.state.tilt_offset_deg))
        tip = (1 - w) * tips[0] + w * tips[1]
        ax = (1 - w) * axes[0] + w * axes[1]
        ax /= np.linalg.norm(ax)
        try:
            self._joints = solve_path(self.machine, tip[None], ax[None],
                                      start=self._joints).joints[0]
        except ValueError:
            self.state.status = STATUS["fault"]
        self.state.joints = self._joints.copy()
