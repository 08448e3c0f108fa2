"""The simulated NC behind a real Modbus TCP server (pymodbus 3.x).

The register map is :mod:`sim.registers`. The server binds to 127.0.0.1
unless told otherwise. Writes are checked against the map: an unmapped
address is answered with exception 2 (illegal data address), a value outside
the register's range with exception 3 (illegal data value), and nothing is
stored. The Modbus server and the watchdog run in a process of their own
(:mod:`sim.modbus`), sharing the register tables with this one; the machine runs
in a thread of this process, paced to the wall clock (``time_scale`` simulated
seconds per wall second): every tick it takes the commands from the holding
registers, advances the NC, and publishes the state and the new accelerometer
samples. The watchdog (on the wall clock, armed by the controller's first
heartbeat or orientation command) shows the orientation offset back at the
program's posture (0/0) when neither ``heartbeat`` nor ``orient_seq`` has changed
for ``watchdog_ms``; the machine holds it there from its next tick for as long as
the trip lasts.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Self

import numpy as np

from .constants import DEFAULT_PORT, DEFAULT_WATCHDOG_MS, SERVER_START_S, TICK_S
from .machine import SimulatedNC
from .modbus import RegisterStore, ServerProcess
from .registers import STATUS

__all__ = ["NCServer", "RegisterStore"]


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
        self._process: ServerProcess | None = None
        self._threads: list[threading.Thread] = []
        self._stop = threading.Event()
        self._machine_done = threading.Event()
        self.error: BaseException | None = None
        self.events: list[tuple[float, str]] = []
        self._watch_seen = (0, 0)
        self._publish()

    # --- lifecycle -----------------------------------------------------------------
    def start(self) -> NCServer:
        """Start the Modbus server's process and the machine; returns when the port
        listens."""
        self._process = ServerProcess(self.store, self.host, self.port, SERVER_START_S)
        self.port = self._process.port
        m = threading.Thread(target=self._machine, name="machine", daemon=True)
        m.start()
        self._threads.append(m)
        return self

    def stop(self) -> None:
        """Stop the machine and the server (idempotent)."""
        self._stop.set()
        for t in self._threads:
            t.join(5.0)
        self._threads.clear()
        if self._process is not None:
            err = self._process.stop()
            if err is not None and self.error is None:
                self.error = RuntimeError(err)
            self._process = None

    @property
    def realtime(self) -> bool:
        """Whether the Modbus server's process runs in the real-time scheduling class
        (``sim.constants.SERVER_RT_PRIORITY``; False before :meth:`start`)."""
        return self._process is not None and self._process.realtime

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
    def _machine(self) -> None:
        nc, store = self.nc, self.store
        seq_seen = int(store.get("orient_seq"))
        t0 = time.monotonic()
        try:
            while not self._stop.is_set():
                # commands (the watchdog is the server process's: see _publish)
                nc.set_feed_override(store.get("feed_override"))
                seq = int(store.get("orient_seq"))
                if seq != seq_seen:
                    seq_seen = seq
                    lead, tilt = store.get("lead_cmd"), store.get("tilt_cmd")
                    ack = nc.command_orientation(lead, tilt, seq)
                    self.events.append((nc.state.time_s, f"orientation command {seq}: lead "
                                        f"{lead:+.2f} tilt {tilt:+.2f} deg -> ack {ack}"))
                    self._publish()             # a trip during the check undoes it at once
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
        """The NC's state into the input registers. While the watchdog is tripped the
        NC's orientation offset is held at 0/0 (the check and the write under the store's
        lock, so the server's process never sees an offset the trip has undone)."""
        st, store = self.nc.state, self.store
        if int(st.time_s / 0.05) != int(getattr(self, "_last_joint_t", -1.0) / 0.05):
            self.nc.update_joints()                 # the display: every 50 ms of sim time
            self._last_joint_t = st.time_s
        j = st.joints
        with store.lock:
            wd = store.watchdog_unlocked()
            if wd.tripped and (st.lead_offset_deg or st.tilt_offset_deg):
                self.nc.reset_orientation()
            st.watchdog_tripped = int(wd.tripped)
            values = {"status": st.status, "block": st.block, "pos_x": j[0], "pos_y": j[1],
                      "pos_z": j[2], "pos_r1": math.degrees(j[3]),
                      "pos_r2": math.degrees(j[4]), "spindle_rpm": st.spindle_rpm,
                      "feed_override_now": st.feed_override_pct, "lead_now": st.lead_offset_deg,
                      "tilt_now": st.tilt_offset_deg, "orient_ack_seq": st.ack_seq,
                      "orient_ack_state": st.ack_state, "cutting": st.cutting,
                      "sim_time_ms": (st.time_s * 1000.0) % 2 ** 32}
            store.set_unlocked(values)
        if (wd.trips, wd.backs) != self._watch_seen:
            if wd.trips != self._watch_seen[0]:
                self.events.append((st.time_s, "watchdog: controller silent, orientation "
                                    "back to the program's"))
            if wd.backs != self._watch_seen[1]:
                self.events.append((st.time_s, "controller back"))
            self._watch_seen = (wd.trips, wd.backs)
