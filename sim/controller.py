"""The controller side: a Modbus client that watches for chatter and re-orients the tool.

It talks to the NC only through the register map (:mod:`sim.registers`), as
it would to a real controller: it reads the accelerometer ring, feeds orient's
chatter detector, asks one of orient's strategies (the detector-driven rule of
the patent) for a new posture at the current cutter location, and writes the
orientation offset command; it beats the heartbeat so that the NC's watchdog
stays quiet. It knows the program and the part (a CAM-aware controller): the
surface normal and feed direction at each cutter location give the rules'
posture geometry (inclination, up/down-cut degree); it does no cutting
simulation.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ModbusException

from errpred.spindle import tooth_period
from orient.detect import ChatterDetector, Detection
from orient.dynamics import ModalSystem
from orient.gain import process_gain_batch
from orient.geometry import inclination, posture_axis
from orient.scenario import PlanScenario
from orient.stability import zoa_margin, zoa_margin_batch
from orient.strategies import DetectorRule, EigenCriterion
from orient.strategy_types import PostureState
from orient.workpiece import WorkpieceModel

from .constants import (
    CONTROLLER_CONFIRM,
    CONTROLLER_HOLDOFF_REV,
    CONTROLLER_POLL_S,
    CONTROLLER_STEP_DEG,
    MAX_READ_REGISTERS,
)
from .program import PartProgram
from .registers import (
    CAUSE,
    HOLDING,
    INPUT,
    REGISTERS,
    RING_SAMPLES,
    RING_START,
    by_name,
    decode,
    encode,
)
from .sensors import Accelerometers, detector_settings

__all__ = ["Controller", "NCClient", "ProgramGeometry"]

_INPUT_STATE = [r for r in REGISTERS if r.table == INPUT]
_STATE_COUNT = max(r.address + r.words for r in _INPUT_STATE)


class NCClient:
    """Typed access to the simulated NC's register map over Modbus TCP."""

    def __init__(self, host: str = "127.0.0.1", port: int = 5020, *, timeout_s: float = 2.0,
                 device_id: int = 1) -> None:
        self.client = ModbusTcpClient(host, port=port, timeout=timeout_s)
        self.device_id = device_id
        self.sequence: int | None = None
        self.missed = 0

    def connect(self) -> bool:
        return bool(self.client.connect())

    def close(self) -> None:
        self.client.close()

    def _read(self, fc: int, address: int, count: int) -> list[int]:
        out: list[int] = []
        while count > 0:
            k = min(count, MAX_READ_REGISTERS)
            try:
                rr = (self.client.read_input_registers if fc == 4 else
                      self.client.read_holding_registers)(address, count=k,
                                                           device_id=self.device_id)
            except ModbusException as exc:
                raise ConnectionError(f"Modbus read at {address}: {exc}") from exc
            if rr.isError():
                raise ConnectionError(f"Modbus read of {k} registers at {address} failed: {rr}")
            out.extend(rr.registers)
            address += k
            count -= k
        return out

    def state(self) -> dict[str, float]:
        """All input registers of the state, decoded."""
        words = self._read(4, 0, _STATE_COUNT)
        return {r.name: decode(r, words[r.address:r.address + r.words]) for r in _INPUT_STATE}

    def holding(self, name: str) -> float:
        """One holding register by name (engineering units)."""
        reg = by_name(name)
        if reg.table != HOLDING:
            raise KeyError(f"{name} is not a holding register")
        return decode(reg, self._read(3, reg.address, reg.words))

    def write(self, **values: float) -> None:
        """Write holding registers by name (engineering units)."""
        for name, v in values.items():
            reg = by_name(name)
            if reg.table != HOLDING:
                raise KeyError(f"{name} is not a holding register")
            try:
                rr = self.client.write_register(reg.address, encode(reg, v)[0],
                                                device_id=self.device_id)
            except ModbusException as exc:
                raise ConnectionError(f"Modbus write of {name}: {exc}") from exc
            if rr.isError():
                raise ConnectionError(f"Modbus write of {name}={v} refused: {rr}")

    def new_samples(self) -> np.ndarray:
        """Accelerometer samples (k, 2) [counts] written since the last call (the first call
        returns none); counts the samples lost to the ring's wrap in :attr:`missed`."""
        reg = by_name("accel_sequence")
        seq = int(decode(reg, self._read(4, reg.address, 2)))
        if self.sequence is None:
            self.sequence = seq
            return np.zeros((0, 2), dtype=np.int16)
        new = (seq - self.sequence) % 2 ** 32
        if new > RING_SAMPLES:
            self.missed += new - RING_SAMPLES
            new = RING_SAMPLES
        start = (seq - new) % RING_SAMPLES
        first = min(new, RING_SAMPLES - start)
        words = self._read(4, RING_START + 2 * start, 2 * first)
        if new > first:
            words += self._read(4, RING_START, 2 * (new - first))
        self.sequence = seq
        return np.array(words, dtype=np.uint16).view(np.int16).reshape(-1, 2)


class ProgramGeometry(PartProgram):
    """What the controller knows of the part (:class:`sim.program.PartProgram`: per
    cutter location the surface normal, feed direction, the CAM's lead and tilt, and
    the local cut); it implements orient's ``PostureModel`` for one location."""

    def __init__(self, scn: PlanScenario) -> None:
        super().__init__(scn)
        self.point = int(self.touch[0]) if self.touch.size else 0
        self._P: dict = {}
        self._incl: dict = {}
        self._margin: dict = {}
        self._systems: dict = {}
        self._workpiece: WorkpieceModel | None = None
        self._tool_system: ModalSystem | None = None

    def point_of_block(self, block: int) -> int:
        """Cutter location of a program block (the nearest touching one)."""
        rows = np.flatnonzero(self.cam.block == block)
        i = int(rows[-1]) if rows.size else self.point
        if self.touch.size and not self.contacts.touching[i]:
            i = int(self.touch[np.argmin(np.abs(self.touch - i))])
        return i

    # --- orient's PostureModel at self.point -----------------------------------------
    def _axis(self, lead: float, tilt: float) -> np.ndarray:
        i = self.point
        return posture_axis(self.contacts.normal[i], self.contacts.feed[i], lead, tilt)

    def inclination(self, lead: float, tilt: float) -> float:
        key = (self.point, round(lead, 9), round(tilt, 9))
        if key not in self._incl:
            self._incl[key] = float(inclination(self._axis(lead, tilt),
                                                self.contacts.normal[self.point]))
        return self._incl[key]

    def cut_sense(self, lead: float, tilt: float) -> float:
        self._gain_P(lead, tilt)
        return self._P[(self.point, round(lead, 9), round(tilt, 9))][1]

    def _gain_P(self, lead: float, tilt: float) -> np.ndarray:
        i = self.point
        key = (i, round(lead, 9), round(tilt, 9))
        if key not in self._P:
            g = process_gain_batch(self.scn.base.tool, self.scn.base.coefficients,
                                   self._axis(lead, tilt), self.contacts.normal[i],
                                   self.contacts.feed[i], self.cuts[i])
            self._P[key] = (np.asarray(g.P), float(g.cut_sense))
        return self._P[key][0]

    def prefetch(self, postures: np.ndarray, margins: bool = True) -> None:
        """Evaluate many postures (k, 2) [rad] at the current cutter location at once
        (one batch of process gains and margins) into the caches the rules read."""
        i = self.point
        lt = np.atleast_2d(np.asarray(postures, dtype=float))
        keys = [(i, round(float(a), 9), round(float(b), 9)) for a, b in lt]
        todo = [k for k, key in enumerate(keys) if key not in self._P
                or (margins and key not in self._margin)]
        if not todo:
            return
        lt = lt[todo]
        n, f = self.contacts.normal[i], self.contacts.feed[i]
        axes = posture_axis(n[None], f[None], lt[:, 0], lt[:, 1])
        g = process_gain_batch(self.scn.base.tool, self.scn.base.coefficients, axes, n, f,
                               self.cuts[i])
        inc = inclination(axes, n[None])
        m = None
        if margins:
            sys_ = self.system_at(i)
            m = zoa_margin_batch(g.P, sys_, self.rpm, self.scn.base.tool.flutes,
                                 mode_directions=sys_.directions_for_axes(axes))
        for r, k in enumerate(todo):
            key = keys[k]
            self._P[key] = (np.asarray(g.P[r]), float(g.cut_sense[r]))
            self._incl[key] = float(inc[r])
            if m is not None:
                self._margin[key] = float(m[r])

    def system_at(self, i: int) -> ModalSystem:
        """Tool modes plus the workpiece's at cutter location ``i`` (orient's models)."""
        if self._workpiece is None:
            self._workpiece = WorkpieceModel(self.scn.workpiece, self.contacts.point[self.touch])
            self._tool_system = ModalSystem.tool(self.scn.base.compliance)
        if i not in self._systems:
            self._systems[i] = self._workpiece.system_at(self._tool_system,
                                                         self.contacts.point[i])
        return self._systems[i]

    def margin(self, lead: float, tilt: float) -> float:
        """Zero-order stability margin of a posture at the current cutter location."""
        key = (self.point, round(lead, 9), round(tilt, 9))
        if key not in self._margin:
            sys_ = self.system_at(self.point).with_tool_axis(self._axis(lead, tilt))
            self._margin[key] = float(zoa_margin(self._gain_P(lead, tilt), sys_, self.rpm,
                                                 self.scn.base.tool.flutes))
        return self._margin[key]

    def gain(self, lead: float, tilt: float, direction: np.ndarray) -> float:
        e = np.asarray(direction, dtype=float)
        e = e / np.linalg.norm(e)
        return float(e @ self._gain_P(lead, tilt) @ e)

    def feasible(self, lead: float, tilt: float) -> bool:
        """Within the offset range of the register map and the planner's inclination
        bounds (the NC checks interference and axis limits itself)."""
        i, opt = self.point, self.scn.options
        lim = math.radians(by_name("lead_cmd").high)
        if abs(lead - self.cam_lead[i]) > lim + 1e-9 or abs(tilt - self.cam_tilt[i]) > lim + 1e-9:
            return False
        inc = self.inclination(lead, tilt)
        return opt.min_inclination_rad - 1e-9 <= inc <= opt.max_inclination_rad + 1e-9


@dataclass
class ControllerLog:
    """What the controller saw and did (times are the NC's simulated time [s])."""

    detections: list = field(default_factory=list)
    commands: list = field(default_factory=list)
    missed_samples: int = 0


class Controller:
    """Chatter watch and re-orientation over Modbus.

    Parameters
    ----------
    client : NCClient
    geometry : ProgramGeometry
    sensors : Accelerometers
        The NC's sensor chain (its rate and LSB are also read from the map).
    strategy : str
        ``'eigen'``: orient's :class:`~orient.strategies.EigenCriterion` (the
        posture of the largest zero-order margin within +-20 deg, from the
        controller's own models of the tool and the wall); ``'detector'``:
        :class:`~orient.strategies.DetectorRule` (the patent's cause rules, a
        ``step_deg`` step toward smaller or larger inclination).
    step_deg : float [deg]
        The detector rule's posture step.
    act : bool
        False: detect and report only (open loop).
    """

    def __init__(self, client: NCClient, geometry: ProgramGeometry, *,
                 sensors: Accelerometers | None = None, strategy: str = "eigen",
                 step_deg: float = CONTROLLER_STEP_DEG, act: bool = True) -> None:
        self.client = client
        self.geometry = geometry
        st = client.state()
        sensors = sensors if sensors is not None else Accelerometers(
            sample_rate_hz=st["accel_rate_hz"])
        self.lsb = st["accel_lsb_um_s2"] * 1e-6
        self.detector = ChatterDetector(detector_settings(sensors))
        if strategy == "eigen":
            self.rule = EigenCriterion(geometry)
        elif strategy == "detector":
            self.rule = DetectorRule(geometry, step_rad=math.radians(step_deg))
        else:
            raise ValueError(f"strategy: expected 'eigen' or 'detector', got {strategy!r}")
        self.strategy = strategy
        self.act = act
        self.log = ControllerLog()
        self._beat = 0
        self._hold_until = -math.inf
        self._seq = int(client.holding("orient_seq"))
        self._last_cause: str | None = None
        # compile and load orient's kernels (and the wall's modes) now, not at the
        # first chatter; a controller that only watches (open loop) never needs the
        # margins, nor the wall's finite elements behind them (10-15 s of set-up)
        if geometry.touch.size:
            i = int(geometry.touch[0])
            geometry.point = i
            lead0, tilt0 = float(geometry.cam_lead[i]), float(geometry.cam_tilt[i])
            geometry.cut_sense(lead0, tilt0)
            if strategy == "eigen" and act:
                geometry.margin(lead0, tilt0)
                geometry.prefetch(np.array([[lead0 + 0.01, tilt0], [lead0, tilt0 + 0.01]]))

    def step(self) -> dict[str, float]:
        """One poll: heartbeat, new samples through the detector, maybe a command."""
        c = self.client
        self._beat = (self._beat + 1) % 65536
        c.write(heartbeat=self._beat)
        st = c.state()
        counts = c.new_samples()
        self.log.missed_samples = c.missed
        rpm = st["spindle_rpm"]
        if counts.shape[0] == 0 or rpm <= 0:
            return st
        a = counts.astype(float) * self.lsb
        found = [d for d in self.detector.feed(a[:, 0], a[:, 1], rpm,
                                               self.geometry.scn.base.tool.flutes)
                 if d.chatter]
        t = st["sim_time_ms"] / 1000.0
        if found:
            d = found[-1]
            self.log.detections.append((t, d.cause, d.frequency_hz, d.amplitude))
            c.write(chatter_flag=1, chatter_cause=CAUSE.get(d.cause or "unknown", 3),
                    chatter_freq_hz=min(d.frequency_hz, 65535.0))
            # act on a cause seen in two verdicts running (one window can mislead)
            causes = [x.cause for x in found[-CONTROLLER_CONFIRM:]]
            if self._last_cause is not None and len(causes) < CONTROLLER_CONFIRM:
                causes = [self._last_cause] + causes
            confirmed = len(causes) >= CONTROLLER_CONFIRM and len(set(causes)) == 1
            self._last_cause = d.cause
            if self.act and confirmed and t >= self._hold_until and st["cutting"]:
                self._react(d, st, t)
        else:
            self._last_cause = None
            c.write(chatter_flag=0, chatter_cause=0)
        return st

    def _react(self, d: Detection, st: dict[str, float], t: float) -> None:
        g = self.geometry
        i = g.point_of_block(int(st["block"]))
        g.point = i
        lead = float(g.cam_lead[i]) + math.radians(st["lead_now"])
        tilt = float(g.cam_tilt[i]) + math.radians(st["tilt_now"])
        if self.strategy == "eigen":
            g.prefetch(np.vstack([[lead, tilt], self.rule.candidates.around(lead, tilt)]))
        state = PostureState.from_model(g, lead, tilt, st["spindle_rpm"])
        change = self.rule.propose(state, d)
        if change is None:
            self.log.commands.append((t, None, None, self.rule.last_reason, None))
            return
        dl = math.degrees(change.lead_rad - g.cam_lead[i])
        dt = math.degrees(change.tilt_rad - g.cam_tilt[i])
        self._seq = (self._seq + 1) % 65536
        self.client.write(lead_cmd=dl, tilt_cmd=dt)
        self.client.write(orient_seq=self._seq)
        ack = self._wait_ack()
        self.log.commands.append((t, dl, dt, change.reason, ack))
        # the detector's window still holds the chatter: start afresh after a hold-off
        self.detector.reset()
        self._hold_until = t + CONTROLLER_HOLDOFF_REV * tooth_period(st["spindle_rpm"])

    def _wait_ack(self, timeout_s: float = 2.0) -> int:
        t0 = time.monotonic()
        while time.monotonic() - t0 < timeout_s:
            st = self.client.state()
            if int(st["orient_ack_seq"]) == self._seq:
                return int(st["orient_ack_state"])
            time.sleep(0.002)
        return -1

    def run(self, *, until_finished: bool = True, max_s: float = math.inf,
            poll_s: float = CONTROLLER_POLL_S) -> ControllerLog:
        """Poll until the program has finished (or ``max_s`` wall seconds)."""
        t0 = time.monotonic()
        while time.monotonic() - t0 < max_s:
            seq = self.client.sequence
            st = self.step()
            if until_finished and int(st["status"]) in (2, 3):
                break
            got = 0 if seq is None or self.client.sequence is None else \
                (self.client.sequence - seq) % 2 ** 32
            if got < self.detector.settings.hop_samples:     # caught up: wait for more
                time.sleep(poll_s)
        return self.log

