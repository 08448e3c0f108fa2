"""The simulated NC behind a real Modbus TCP server (pymodbus 3.x).

The register map is :mod:`sim.registers`. The server binds to 127.0.0.1
unless told otherwise. Writes are checked against the map: an unmapped
address is answered with exception 2 (illegal data address), a value outside
the register's range with exception 3 (illegal data value), and nothing is
stored. The machine runs in its own thread, paced to the wall clock
(``time_scale`` simulated seconds per wall second); every tick it takes the
commands from the holding registers, advances the NC, and publishes the state
and the new accelerometer samples. A watchdog puts the orientation offset
back to the program's posture (0/0) when the controller's heartbeat has not
changed for ``watchdog_ms``.
"""

from __future__ import annotations

import asyncio
import math
import threading
import time
from typing import Any, Self

import numpy as np
from pymodbus.constants import ExcCodes
from pymodbus.datastore import ModbusServerContext
from pymodbus.server import ModbusTcpServer

from .constants import DEFAULT_PORT, DEFAULT_WATCHDOG_MS, TICK_S
from .machine import SimulatedNC
from .registers import (
    HOLDING,
    INPUT,
    REGISTERS,
    RING_SAMPLES,
    RING_START,
    STATUS,
    by_name,
    decode,
    encode,
)

__all__ = ["NCServer", "RegisterStore"]

_HOLDING_SIZE = max(r.address + r.words for r in REGISTERS if r.table == HOLDING)
_INPUT_SIZE = RING_START + 2 * RING_SAMPLES


class RegisterStore:
    """The two register tables, their checks, and the accelerometer ring (thread-safe)."""

    def __init__(self) -> None:
        self.input = np.zeros(_INPUT_SIZE, dtype=np.uint16)
        self.holding = np.zeros(_HOLDING_SIZE, dtype=np.uint16)
        self.lock = threading.Lock()
        self.sequence = 0
        self.refused_writes = 0
        self._holding_regs = {r.address: r for r in REGISTERS if r.table == HOLDING}
        self.set("accel_ring_samples", RING_SAMPLES)

    # --- server side ---------------------------------------------------------------
    def set(self, name: str, value: float) -> None:
        reg = by_name(name)
        words = encode(reg, value)
        table = self.input if reg.table == INPUT else self.holding
        with self.lock:
            table[reg.address:reg.address + reg.words] = words

    def get(self, name: str) -> float:
        reg = by_name(name)
        table = self.input if reg.table == INPUT else self.holding
        with self.lock:
            return decode(reg, [int(w) for w in table[reg.address:reg.address + reg.words]])

    def push_samples(self, counts: np.ndarray) -> None:
        """Append converter samples (k, 2) to the ring and advance the sequence."""
        c = np.asarray(counts, dtype=np.int64).reshape(-1, 2)
        if c.shape[0] == 0:
            return
        if c.shape[0] > RING_SAMPLES:
            skip = c.shape[0] - RING_SAMPLES
            self.sequence += skip
            c = c[skip:]
        k = np.arange(self.sequence, self.sequence + c.shape[0]) % RING_SAMPLES
        words = (c & 0xFFFF).astype(np.uint16)
        with self.lock:
            self.input[RING_START + 2 * k] = words[:, 0]
            self.input[RING_START + 2 * k + 1] = words[:, 1]
            self.sequence += c.shape[0]
            reg = by_name("accel_sequence")
            self.input[reg.address:reg.address + 2] = encode(reg, self.sequence % 2 ** 32)

    # --- protocol side -------------------------------------------------------------
    def read(self, func_code: int, address: int, count: int) -> list[int] | ExcCodes:
        table = self.input if func_code == 4 else self.holding if func_code in (3, 6, 16, 23) \
            else None
        if table is None:
            return ExcCodes.ILLEGAL_FUNCTION
        if address < 0 or count < 1 or address + count > table.size:
            return ExcCodes.ILLEGAL_ADDRESS
        with self.lock:
            return [int(v) for v in table[address:address + count]]

    def write(self, func_code: int, address: int, values: list[int]) -> ExcCodes | None:
        if func_code not in (6, 16):
            return ExcCodes.ILLEGAL_FUNCTION
        regs = []
        for a in range(address, address + len(values)):
            reg = self._holding_regs.get(a)
            if reg is None:
                self.refused_writes += 1
                return ExcCodes.ILLEGAL_ADDRESS
            regs.append(reg)
        for reg, v in zip(regs, values, strict=True):
            lo, hi = reg.count_range
            raw = int(v) & 0xFFFF
            c = raw - 0x10000 if reg.signed and raw >= 0x8000 else raw
            if not lo <= c <= hi:
                self.refused_writes += 1
                return ExcCodes.ILLEGAL_VALUE
        with self.lock:
            self.holding[address:address + len(values)] = [int(v) & 0xFFFF for v in values]
        return None


class _Context(ModbusServerContext):
    """pymodbus context answering from a :class:`RegisterStore` (any device id)."""

    def __init__(self, store: RegisterStore) -> None:       # no base init: no datastore
        self.store = store
        self.old_simulator = True
        self.simdevices = []

    async def async_getValues(self, device_id: int, func_code: int, address: int,
                              count: int = 1) -> list[int] | ExcCodes:
        return self.store.read(func_code, address, count)

    async def async_setValues(self, device_id: int, func_code: int, address: int,
                              values: Any) -> ExcCodes | None:
        return self.store.write(func_code, address, list(values))

    def device_ids(self) -> list[int]:
        return [1]


class NCServer:
    """A :class:`SimulatedNC` served over Modbus TCP.

    Parameters
    ----------
    nc : SimulatedNC
    host : str
        Address to bind (default loopback only).
    port : int
        TCP port (0: any free port; see :attr:`port` after :meth:`start`).
    time_scale : float
        Simulated seconds per wall-clock second (1: real time; ``inf``: as fast
        as the simulation goes).
    tick_s : float [s]
        Simulated time per machine step.
    record : bool
        Keep every accelerometer sample (:meth:`recorded`) for the report.
    autostart : bool
        Run the program at once; otherwise wait (status idle) until a client
        writes ``cycle_start = 1``.
    """

    def __init__(self, nc: SimulatedNC, *, host: str = "127.0.0.1", port: int = DEFAULT_PORT,
                 time_scale: float = 1.0, tick_s: float = TICK_S, record: bool = False,
                 autostart: bool = True) -> None:
        self.nc = nc
        self.host = host
        self.port = int(port)
        if not (time_scale > 0):
            raise ValueError(f"time_scale: expected > 0, got {time_scale!r}")
        self.time_scale = float(time_scale)
        self.tick_s = float(tick_s)
        self.store = RegisterStore()
        self.record = bool(record)
        self._rec_t: list[np.ndarray] = []
        self._rec_c: list[np.ndarray] = []
        self._rec_cut: list[tuple[float, int]] = []
        self.store.set("feed_override", nc.state.feed_override_pct)
        self.store.set("watchdog_ms", DEFAULT_WATCHDOG_MS)
        self.store.set("accel_rate_hz", nc.sensors.sample_rate_hz)
        self.store.set("accel_lsb_um_s2", nc.sensors.lsb_m_s2 * 1e6)
        self.store.set("spindle_rpm", nc.rpm)
        self.store.set("cycle_start", 1 if autostart else 0)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: ModbusTcpServer | None = None
        self._threads: list[threading.Thread] = []
        self._stop = threading.Event()
        self._started = threading.Event()
        self._machine_done = threading.Event()
        self.error: BaseException | None = None
        self.events: list[tuple[float, str]] = []
        self._publish()

    # --- lifecycle -----------------------------------------------------------------
    def start(self) -> NCServer:
        """Start the Modbus server and the machine; returns when the port listens."""
        t = threading.Thread(target=self._serve, name="modbus", daemon=True)
        t.start()
        self._threads.append(t)
        if not self._started.wait(10.0) or self._server is None:
            raise RuntimeError(f"Modbus server did not start on {self.host}:{self.port}: "
                               f"{self.error!r}")
        m = threading.Thread(target=self._machine, name="machine", daemon=True)
        m.start()
        self._threads.append(m)
        return self

    def stop(self) -> None:
        """Stop the machine and the server (idempotent)."""
        self._stop.set()
        for t in self._threads:             # the server thread shuts itself down
            t.join(5.0)
        self._threads.clear()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def wait_finished(self, timeout_s: float | None = None) -> bool:
        """Wait until the program has run to its end (or the machine stopped)."""
        return self._machine_done.wait(timeout_s)

    def recorded(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """All accelerometer samples so far: times (k,) [s], counts (k, 2), and whether
        the tool was cutting at each sample (k,) bool."""
        if not self._rec_t:
            return np.zeros(0), np.zeros((0, 2), dtype=np.int32), np.zeros(0, dtype=bool)
        t = np.concatenate(self._rec_t)
        ticks = np.array(self._rec_cut, dtype=float).reshape(-1, 2)
        j = np.clip(np.searchsorted(ticks[:, 0], t), 0, len(ticks) - 1)
        return t, np.concatenate(self._rec_c), ticks[j, 1] > 0

    # --- threads -------------------------------------------------------------------
    def _serve(self) -> None:
        async def main() -> None:
            self._loop = asyncio.get_running_loop()
            self._server = ModbusTcpServer(_Context(self.store), address=(self.host, self.port))
            await self._server.serve_forever(background=True)
            sock = self._server.transport.sockets[0] if self._server.transport else None
            if sock is not None:
                self.port = int(sock.getsockname()[1])
            self._started.set()
            while not self._stop.is_set():
                await asyncio.sleep(0.05)
            await self._server.shutdown()

        try:
            asyncio.run(main())
        except BaseException as exc:  # noqa: BLE001 - reported by start()
            self.error = exc
            self._started.set()

    def _machine(self) -> None:
        nc, store = self.nc, self.store
        seq_seen = int(store.get("orient_seq"))
        beat_seen = int(store.get("heartbeat"))
        last_alive = time.monotonic()
        alive_once = False
        t0 = time.monotonic()
        try:
            while not self._stop.is_set():
                # commands
                nc.set_feed_override(store.get("feed_override"))
                beat = int(store.get("heartbeat"))
                now = time.monotonic()
                if beat != beat_seen:
                    beat_seen, last_alive, alive_once = beat, now, True
                    if nc.state.watchdog_tripped:
                        nc.state.watchdog_tripped = 0
                        self.events.append((nc.state.time_s, "controller back"))
                seq = int(store.get("orient_seq"))
                if seq != seq_seen:
                    seq_seen = seq
                    ack = nc.command_orientation(store.get("lead_cmd"), store.get("tilt_cmd"),
                                                 seq)
                    what = (f"orientation command {seq}: lead {store.get('lead_cmd'):+.2f} "
                            f"tilt {store.get('tilt_cmd'):+.2f} deg -> ack {ack}")
                    self.events.append((nc.state.time_s, what))
                timeout = store.get("watchdog_ms") / 1000.0
                if alive_once and not nc.state.watchdog_tripped and now - last_alive > timeout:
                    nc.state.watchdog_tripped = 1
                    if nc.state.lead_offset_deg or nc.state.tilt_offset_deg:
                        nc.reset_orientation()
                    what = "watchdog: controller silent, orientation back to the program's"
                    self.events.append((nc.state.time_s, what))
                # machine
                if not store.get("cycle_start"):
                    self._publish()
                    time.sleep(0.005)
                    t0 = time.monotonic() - nc.state.time_s / self.time_scale \
                        if math.isfinite(self.time_scale) else t0
                    continue
                if nc.done:
                    nc.state.status = STATUS["finished"]
                    self._publish()
                    self._machine_done.set()
                    time.sleep(0.01)
                    continue
                sig = nc.tick(self.tick_s)
                store.push_samples(sig.counts)
                if self.record:
                    self._rec_cut.append((nc.state.time_s, nc.state.cutting))
                    if sig.time_s.size:
                        self._rec_t.append(sig.time_s)
                        self._rec_c.append(sig.counts)
                self._publish()
                if math.isfinite(self.time_scale):
                    lag = nc.state.time_s / self.time_scale - (time.monotonic() - t0)
                    if lag > 0:
                        time.sleep(lag)
        except BaseException as exc:  # noqa: BLE001 - the NC faults, the server stays up
            self.error = exc
            nc.state.status = STATUS["fault"]
            self._publish()
            self._machine_done.set()

    def _publish(self) -> None:
        st, store = self.nc.state, self.store
        if int(st.time_s / 0.05) != int(getattr(self, "_last_joint_t", -1.0) / 0.05):
            self.nc.update_joints()                 # the display: every 50 ms of sim time
            self._last_joint_t = st.time_s
        j = st.joints
        values = {"status": st.status, "block": st.block, "pos_x": j[0], "pos_y": j[1],
                  "pos_z": j[2], "pos_r1": math.degrees(j[3]), "pos_r2": math.degrees(j[4]),
                  "spindle_rpm": st.spindle_rpm, "feed_override_now": st.feed_override_pct,
                  "lead_now": st.lead_offset_deg, "tilt_now": st.tilt_offset_deg,
                  "orient_ack_seq": st.ack_seq, "orient_ack_state": st.ack_state,
                  "watchdog_tripped": st.watchdog_tripped, "cutting": st.cutting,
                  "sim_time_ms": (st.time_s * 1000.0) % 2 ** 32}
        for k, v in values.items():
            store.set(k, v)
