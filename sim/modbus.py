"""The register tables in shared memory, and the Modbus TCP server's process with the watchdog.

The simulated NC (:mod:`sim.server`) runs in the main process; the Modbus server
(pymodbus, in its asyncio loop) runs in a process of its own, forked from it, and
both see the same register tables (:class:`RegisterStore`, shared memory under one
inter-process lock). The server's process thus never waits for the simulation's
interpreter lock: a thread was not enough, the cutting simulation holds the lock for
10-160 ms at a time (numpy and scipy calls, numba's dispatch, lazy imports; measured
with a sampling probe along the bundled thin wall's cut).

The watchdog is a task of the server's event loop, on the wall clock, independent of
the simulation: the controller counts as alive at every write that changes
``heartbeat`` or ``orient_seq`` (a new orientation command); from the first such write
on, a silence longer than ``watchdog_ms`` trips it: the registers show the offset at
0/0 (``lead_now``, ``tilt_now``, ``orient_ack_state`` 4 when an offset was in effect)
and ``watchdog_tripped`` 1 at once, and the NC holds its offset at 0/0 from its next
interpolation period for as long as the trip lasts (``NCServer``). The next sign of
life clears the trip.
"""

from __future__ import annotations

import asyncio
import multiprocessing as mp
import os
import signal
import time
from typing import Any

import numpy as np
from pymodbus.constants import ExcCodes
from pymodbus.datastore import ModbusServerContext
from pymodbus.server import ModbusTcpServer

from .constants import SERVER_RT_PRIORITY, WATCHDOG_POLL_S
from .registers import (
    ACK,
    HOLDING,
    INPUT,
    REGISTERS,
    RING_SAMPLES,
    RING_START,
    Register,
    by_name,
    decode,
    encode,
)

__all__ = ["RegisterStore", "ServerProcess", "WatchdogState", "serve"]

_HOLDING_SIZE = max(r.address + r.words for r in REGISTERS if r.table == HOLDING)
_INPUT_SIZE = RING_START + 2 * RING_SAMPLES
# the control block (float64 slots, shared)
_REFUSED, _ALIVE_AT, _ARMED, _TRIPPED, _TRIPS, _BACKS, _STOP = range(7)
_CONTROL = 8
#: The processes share memory by fork (the server's process is a copy of this one).
_CTX = mp.get_context("fork")


def _reg_slice(reg: Register) -> slice:
    return slice(reg.address, reg.address + reg.words)


class WatchdogState:
    """A snapshot of the watchdog: ``armed``, ``tripped``, and how many times it
    tripped and cleared (``trips``, ``backs``) since the start."""

    __slots__ = ("armed", "backs", "tripped", "trips")

    def __init__(self, armed: bool, tripped: bool, trips: int, backs: int) -> None:
        self.armed, self.tripped, self.trips, self.backs = armed, tripped, trips, backs


class RegisterStore:
    """The two register tables, their checks, the accelerometer ring and the watchdog's
    state, in memory shared with the server's process (any access under :attr:`lock`,
    an inter-process lock)."""

    def __init__(self) -> None:
        self._shared = (_CTX.RawArray("H", _INPUT_SIZE), _CTX.RawArray("H", _HOLDING_SIZE),
                        _CTX.RawArray("d", _CONTROL))
        self.input = np.frombuffer(self._shared[0], dtype=np.uint16)
        self.holding = np.frombuffer(self._shared[1], dtype=np.uint16)
        self.control = np.frombuffer(self._shared[2], dtype=np.float64)
        self.lock = _CTX.Lock()
        self.sequence = 0                      # the simulation's side only
        self._holding_regs = {r.address: r for r in REGISTERS if r.table == HOLDING}
        self._alive = (by_name("heartbeat"), by_name("orient_seq"))
        self._tripped_reg = by_name("watchdog_tripped")
        self._zeroed = (by_name("lead_now"), by_name("tilt_now"))
        self._ack_reg = by_name("orient_ack_state")
        self.set("accel_ring_samples", RING_SAMPLES)

    @property
    def refused_writes(self) -> int:
        """Writes refused (unmapped address or value out of range) since the start."""
        return int(self.control[_REFUSED])

    # --- the simulation's side -----------------------------------------------------
    def set(self, name: str, value: float) -> None:
        reg = by_name(name)
        words = encode(reg, value)
        table = self.input if reg.table == INPUT else self.holding
        with self.lock:
            table[_reg_slice(reg)] = words

    def get(self, name: str) -> float:
        reg = by_name(name)
        table = self.input if reg.table == INPUT else self.holding
        with self.lock:
            words = [int(w) for w in table[_reg_slice(reg)]]
        return decode(reg, words)

    def set_unlocked(self, values: dict[str, float]) -> None:
        """Write input or holding registers by name; the caller holds :attr:`lock`."""
        for name, v in values.items():
            reg = by_name(name)
            table = self.input if reg.table == INPUT else self.holding
            table[_reg_slice(reg)] = encode(reg, v)

    def watchdog(self) -> WatchdogState:
        """The watchdog's state (locks)."""
        with self.lock:
            return self.watchdog_unlocked()

    def watchdog_unlocked(self) -> WatchdogState:
        """The watchdog's state; the caller holds :attr:`lock`."""
        c = self.control
        return WatchdogState(bool(c[_ARMED]), bool(c[_TRIPPED]), int(c[_TRIPS]), int(c[_BACKS]))

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
        reg = by_name("accel_sequence")
        seq_words = encode(reg, (self.sequence + c.shape[0]) % 2 ** 32)
        with self.lock:
            self.input[RING_START + 2 * k] = words[:, 0]
            self.input[RING_START + 2 * k + 1] = words[:, 1]
            self.input[_reg_slice(reg)] = seq_words
        self.sequence += c.shape[0]

    # --- the protocol's side (the server's process) ---------------------------------
    def read(self, func_code: int, address: int, count: int) -> list[int] | ExcCodes:
        table = self.input if func_code == 4 else self.holding if func_code in (3, 6, 16, 23) \
            else None
        if table is None:
            return ExcCodes.ILLEGAL_FUNCTION
        if address < 0 or count < 1 or address + count > table.size:
            return ExcCodes.ILLEGAL_ADDRESS
        with self.lock:
            return table[address:address + count].tolist()

    def write(self, func_code: int, address: int, values: list[int]) -> ExcCodes | None:
        """Check and store a write; a change of ``heartbeat`` or ``orient_seq`` counts as
        the controller alive (the watchdog's clock, :func:`time.monotonic`)."""
        if func_code not in (6, 16):
            return ExcCodes.ILLEGAL_FUNCTION
        regs = []
        for a in range(address, address + len(values)):
            reg = self._holding_regs.get(a)
            if reg is None:
                with self.lock:
                    self.control[_REFUSED] += 1
                return ExcCodes.ILLEGAL_ADDRESS
            regs.append(reg)
        for reg, v in zip(regs, values, strict=True):
            lo, hi = reg.count_range
            raw = int(v) & 0xFFFF
            c = raw - 0x10000 if reg.signed and raw >= 0x8000 else raw
            if not lo <= c <= hi:
                with self.lock:
                    self.control[_REFUSED] += 1
                return ExcCodes.ILLEGAL_VALUE
        words = np.array([int(v) & 0xFFFF for v in values], dtype=np.uint16)
        now = time.monotonic()
        with self.lock:
            old = self.holding[address:address + len(values)].copy()
            self.holding[address:address + len(values)] = words
            alive = any(address <= r.address < address + len(values)
                        and old[r.address - address] != words[r.address - address]
                        for r in self._alive)
            if alive:
                c = self.control
                c[_ALIVE_AT], c[_ARMED] = now, 1.0
                if c[_TRIPPED]:
                    c[_TRIPPED] = 0.0
                    c[_BACKS] += 1
                    self.input[_reg_slice(self._tripped_reg)] = 0
        return None

    def watchdog_check(self, now: float) -> bool:
        """Trip the watchdog when it is armed and the controller has been silent for
        longer than ``watchdog_ms`` at ``now`` [s, monotonic]; returns whether it tripped
        now. The registers show the offset at 0/0 at once."""
        with self.lock:
            c = self.control
            if not c[_ARMED] or c[_TRIPPED]:
                return False
            wd = by_name("watchdog_ms")
            timeout_s = decode(wd, self.holding[_reg_slice(wd)].tolist()) / 1000.0
            if now - c[_ALIVE_AT] <= timeout_s:
                return False
            c[_TRIPPED] = 1.0
            c[_TRIPS] += 1
            self.input[_reg_slice(self._tripped_reg)] = 1
            if any(self.input[_reg_slice(r)].any() for r in self._zeroed):
                for r in self._zeroed:
                    self.input[_reg_slice(r)] = 0
                self.input[_reg_slice(self._ack_reg)] = ACK["reset_by_watchdog"]
            return True

    def request_stop(self) -> None:
        with self.lock:
            self.control[_STOP] = 1.0

    def stopping(self) -> bool:
        with self.lock:
            return bool(self.control[_STOP])


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


def serve(store: RegisterStore, host: str, port: int, conn: Any, parent_pid: int) -> None:
    """The server's process: Modbus TCP on ``host:port`` and the watchdog task, until
    the store's stop flag is set or the parent process is gone. It asks for the
    real-time scheduling class (``SERVER_RT_PRIORITY``; taken where permitted, else it
    stays time-shared). Sends ``("ok", port, realtime)`` on ``conn`` once it listens, or
    ``("error", text)``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)            # the parent stops it
    realtime = True
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(SERVER_RT_PRIORITY))
    except (AttributeError, OSError):                       # not permitted: time-shared
        realtime = False

    async def main() -> None:
        server = ModbusTcpServer(_Context(store), address=(host, port))
        await server.serve_forever(background=True)
        sock = server.transport.sockets[0] if server.transport else None
        if sock is None:
            raise OSError(f"Modbus server did not listen on {host}:{port}")
        conn.send(("ok", int(sock.getsockname()[1]), realtime))
        try:
            while not store.stopping() and os.getppid() == parent_pid:
                store.watchdog_check(time.monotonic())
                await asyncio.sleep(WATCHDOG_POLL_S)
        finally:
            await server.shutdown()

    try:
        asyncio.run(main())
    except BaseException as exc:  # noqa: BLE001 - reported to the parent
        conn.send(("error", repr(exc)))


class ServerProcess:
    """:func:`serve` in a forked process; returns once the port listens.

    Parameters
    ----------
    store : RegisterStore
    host : str
    port : int
        0: any free port (the one taken is :attr:`port`).
    timeout_s : float [s]
        How long to wait for the port to listen (RuntimeError after it).
    """

    def __init__(self, store: RegisterStore, host: str, port: int, timeout_s: float) -> None:
        self.store = store
        here, there = _CTX.Pipe(duplex=False)
        self.process = _CTX.Process(target=serve, args=(store, host, port, there, os.getpid()),
                                    name="modbus-server", daemon=True)
        self.process.start()
        there.close()
        msg = here.recv() if here.poll(timeout_s) else ("error", f"no answer in {timeout_s} s")
        self._conn = here
        if msg[0] != "ok":
            self.stop()
            raise RuntimeError(f"Modbus server did not start on {host}:{port}: {msg[1]}")
        self.port = int(msg[1])
        #: Whether the process runs in the real-time scheduling class.
        self.realtime = bool(msg[2])

    def stop(self, timeout_s: float = 5.0) -> str | None:
        """Stop the process (idempotent); returns the error it reported, if any."""
        self.store.request_stop()
        self.process.join(timeout_s)
        if self.process.is_alive():
            self.process.kill()
            self.process.join(timeout_s)
        err = None
        if self._conn.closed:
            return None
        try:
            while self._conn.poll(0):
                msg = self._conn.recv()
                if msg[0] == "error":
                    err = msg[1]
        except EOFError:                        # the process has closed its end
            pass
        self._conn.close()
        return err
