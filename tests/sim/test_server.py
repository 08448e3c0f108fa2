"""The simulated NC over real Modbus TCP on loopback: the map read by mbpoll, refused
writes, the watchdog, disconnects and a server restart; and the server while the NC cuts
(issue 19): the watchdog's delay on the wall clock (heartbeat stopped; an offset
commanded by a controller that never beats) and the latency of 125-register reads with
1 and 50 clients. Those clients are ``tests/sim/server_probe.py`` processes (not this
one's threads, which would share the simulation's interpreter lock), bounded in time."""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from pymodbus.client import ModbusTcpClient

from orient.scenario import load_plan_scenario
from sim.cli import BUNDLED
from sim.controller import NCClient
from sim.machine import SimulatedNC
from sim.registers import ACK, RING_SAMPLES, RING_START, STATUS, by_name
from sim.server import NCServer

POINTS = (2, 36)


@pytest.fixture(scope="module")
def scenario():
    scn = load_plan_scenario(BUNDLED)
    nc = SimulatedNC(scn, points=POINTS)
    return scn, nc.workpiece


def _nc(scenario) -> SimulatedNC:
    scn, wp = scenario
    return SimulatedNC(scn, points=POINTS, workpiece=wp)


def _wait(cond, timeout=10.0):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if cond():
            return True
        time.sleep(0.02)
    return False


@pytest.mark.skipif(shutil.which("mbpoll") is None,
                    reason="mbpoll (Debian package mbpoll) is not installed")
def test_mbpoll_reads_the_register_map(scenario):
    """A real Modbus client reads the idle NC's state: every value as the map says."""
    with NCServer(_nc(scenario), port=0, autostart=False) as srv:
        out = subprocess.run(["mbpoll", "-m", "tcp", "-p", str(srv.port), "-a", "1", "-t", "3",
                              "-0", "-r", "0", "-c", "36", "-1", "127.0.0.1"],
                             capture_output=True, text=True, timeout=20, check=True).stdout
        regs = {int(a): int(v) for a, v in re.findall(r"^\[(\d+)\]:\s+(\d+)", out, re.MULTILINE)}
        assert len(regs) == 36
        nc = srv.nc
        assert regs[by_name("status").address] == STATUS["idle"]
        assert regs[by_name("spindle_rpm").address] == 9000
        assert regs[by_name("feed_override_now").address] == 100
        assert regs[by_name("accel_ring_samples").address] == RING_SAMPLES % 65536
        assert regs[by_name("accel_rate_hz").address] == 25600
        assert regs[by_name("accel_lsb_um_s2").address] == round(nc.sensors.lsb_m_s2 * 1e6)
        x = (regs[3] << 16 | regs[4])
        x = x - (1 << 32) if x >= 1 << 31 else x
        assert x * 0.001 == pytest.approx(nc.state.joints[0], abs=0.001)
        assert regs[9] << 16 | regs[10] == round(np.degrees(nc.state.joints[3]) * 1000) % 2**32
        hold = subprocess.run(["mbpoll", "-m", "tcp", "-p", str(srv.port), "-a", "1", "-t", "4",
                               "-0", "-r", "0", "-c", "10", "-1", "127.0.0.1"],
                              capture_output=True, text=True, timeout=20, check=True).stdout
        h = {int(a): int(v) for a, v in re.findall(r"^\[(\d+)\]:\s+(\d+)", hold, re.MULTILINE)}
        assert h[by_name("feed_override").address] == 100
        assert h[by_name("watchdog_ms").address] == 1000
        # a write through mbpoll: in range is taken, out of range refused
        ok = subprocess.run(["mbpoll", "-m", "tcp", "-p", str(srv.port), "-a", "1", "-t", "4",
                             "-0", "-r", "0", "-1", "127.0.0.1", "80"],
                            check=False, capture_output=True, text=True, timeout=20)
        assert ok.returncode == 0 and srv.store.get("feed_override") == 80
        bad = subprocess.run(["mbpoll", "-m", "tcp", "-p", str(srv.port), "-a", "1", "-t", "4",
                              "-0", "-r", "0", "-1", "127.0.0.1", "151"],
                             check=False, capture_output=True, text=True, timeout=20)
        assert bad.returncode != 0 and "Illegal data value" in bad.stdout + bad.stderr
        assert srv.store.get("feed_override") == 80


def test_refused_and_malformed_requests_leave_the_nc_safe(scenario):
    with NCServer(_nc(scenario), port=0, autostart=False) as srv:
        c = ModbusTcpClient("127.0.0.1", port=srv.port, timeout=2)
        assert c.connect()
        lead = by_name("lead_cmd").address
        r = c.write_register(lead, 3001, device_id=1)                 # 30.01 deg > 30
        assert r.isError() and r.exception_code == 3
        r = c.write_register(lead, 0x10000 - 3001, device_id=1)       # -30.01 deg
        assert r.isError() and r.exception_code == 3
        r = c.write_register(40, 1, device_id=1)                      # unmapped
        assert r.isError() and r.exception_code == 2
        r = c.write_registers(lead, [100, 100, 7], device_id=1)       # lead, tilt, seq: fine
        assert not r.isError()
        r = c.read_input_registers(RING_START + 2 * RING_SAMPLES, count=10,
                                    device_id=1)  # past the map
        assert r.isError() and r.exception_code == 2
        # garbage on the socket: the server drops it and keeps answering
        with socket.create_connection(("127.0.0.1", srv.port), timeout=2) as s:
            s.sendall(b"\x00\x01\x00\x00\x00\xff\x01\x10garbage" * 10)
            time.sleep(0.2)
        r = c.read_input_registers(0, count=20, device_id=1)
        assert not r.isError()
        assert _wait(lambda: srv.nc.state.ack_seq == 7)
        assert srv.nc.state.ack_state == ACK["applied"]
        assert srv.nc.state.lead_offset_deg == pytest.approx(1.0)
        assert srv.store.refused_writes == 3 and srv.error is None
        c.close()


def test_watchdog_returns_the_orientation_to_the_program(scenario):
    """The controller sets an offset, then goes silent (disconnects mid-run): after the
    watchdog time the offset is back to 0/0, acknowledged as such, and the NC runs on."""
    with NCServer(_nc(scenario), port=0, autostart=True) as srv:
        cl = NCClient(port=srv.port)
        assert cl.connect()
        cl.write(watchdog_ms=300, heartbeat=1)
        cl.write(lead_cmd=-5.0, tilt_cmd=5.0)
        cl.write(orient_seq=1)
        beat = iter(range(2, 10 ** 6))                      # alive until it is taken

        def taken():
            cl.write(heartbeat=next(beat))
            return cl.state()["orient_ack_seq"] == 1

        assert _wait(taken)
        st = cl.state()
        assert st["orient_ack_state"] == ACK["applied"]
        assert st["lead_now"] == pytest.approx(-5.0) and st["tilt_now"] == pytest.approx(5.0)
        cl.client.close()                                   # silent from here on
        time.sleep(0.6)
        c2 = NCClient(port=srv.port)
        assert c2.connect()
        st = c2.state()
        assert st["watchdog_tripped"] == 1
        assert st["lead_now"] == 0 and st["tilt_now"] == 0
        assert st["orient_ack_state"] == ACK["reset_by_watchdog"]
        assert st["status"] == STATUS["running"]
        c2.write(heartbeat=next(beat))                      # back: the trip clears
        assert _wait(lambda: c2.state()["watchdog_tripped"] == 0)
        c2.close()
        assert srv.error is None


def test_accelerometer_ring_delivers_every_sample_in_order(scenario):
    """The client's samples equal the NC's own record, none missed, across ring wraps."""
    with NCServer(_nc(scenario), port=0, autostart=True, record=True, time_scale=1.0) as srv:
        cl = NCClient(port=srv.port)
        assert cl.connect()
        got = [cl.new_samples()]
        t0 = time.monotonic()
        while time.monotonic() - t0 < 1.5:
            got.append(cl.new_samples())
            time.sleep(0.02)
        seq_end = cl.sequence
        _t, counts, _cut = srv.recorded()
        cl.close()
    got = np.concatenate(got)
    assert cl.missed == 0
    assert got.shape[0] > 2 * RING_SAMPLES * 0 + 20_000          # > 0.8 s of samples
    start = seq_end - got.shape[0]
    np.testing.assert_array_equal(got, counts[start:seq_end].astype(np.int16))


def test_server_restart_and_client_reconnect(scenario):
    """The server goes away mid-run and comes back on the same port: the client's reads
    fail cleanly (ConnectionError), it reconnects, and the new NC starts safe (0/0)."""
    srv = NCServer(_nc(scenario), port=0, autostart=True).start()
    port = srv.port
    cl = NCClient(port=port, timeout_s=0.5)
    assert cl.connect()
    cl.write(lead_cmd=3.0, tilt_cmd=0.0)
    cl.write(orient_seq=1)
    assert _wait(lambda: cl.state()["orient_ack_seq"] == 1)
    srv.stop()
    with pytest.raises(ConnectionError):
        for _ in range(20):
            cl.state()
            time.sleep(0.05)
    srv2 = NCServer(_nc(scenario), port=port, autostart=False).start()
    try:
        cl.close()
        assert _wait(lambda: cl.connect(), 5.0)
        st = cl.state()
        assert st["status"] == STATUS["idle"]
        assert st["lead_now"] == 0 and st["tilt_now"] == 0
    finally:
        cl.close()
        srv2.stop()


# --- while the NC cuts (issue 19) ----------------------------------------------------
ROOT = Path(__file__).resolve().parents[2]
WATCHDOG_MS = 100
#: The watchdog's allowance past ``watchdog_ms`` [s] and the read latency bounds [s].
WATCHDOG_LATE_S = 0.050
P99_ONE_S, P99_FIFTY_S = 0.005, 0.050
#: How often each of the fifty clients polls [ms]: a SCADA/HMI poll rate, 1,000 reads/s
#: in all. Fifty clients back to back keep the probe and the server, both real-time,
#: busy on both cores of a 2-core machine; the kernel then throttles real-time work for
#: the rest of each second once it has had 95 % of it (``sched_rt_runtime_us``): p99
#: of 52-61 ms in some rounds measured here with the machine loaded; in one CI run,
#: 3,136 reads in 2 s, the last answered 1.02 s after they were sent. That measures
#: the kernel's throttle and the probe's own load, not the server.
POLL_FIFTY_MS = 50


def _cutting_server(scenario) -> NCServer:
    """The first pass in real time at 3 % feed override (the cut lasts about a minute of
    wall time; the cutting simulation's work per wall second is that of 100 %), once
    it cuts."""
    srv = NCServer(_nc(scenario), port=0, autostart=False).start()
    srv.store.set("feed_override", 3)
    srv.store.set("cycle_start", 1)
    t0 = time.monotonic()
    while not srv.store.get("cutting"):
        if time.monotonic() - t0 > 30.0:
            srv.stop()
            pytest.fail("the NC did not start cutting within 30 s")
        time.sleep(0.01)
    return srv


def _probe(*args: object) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    r = subprocess.run([sys.executable, "-m", "tests.sim.server_probe", *map(str, args),
                        "--realtime"], capture_output=True, text=True, timeout=60, cwd=ROOT,
                       env=env, check=False)
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout)


@pytest.fixture(scope="module")
def cutting(scenario):
    srv = _cutting_server(scenario)
    yield srv
    srv.stop()


def test_watchdog_resets_an_offset_of_a_controller_that_never_beats(scenario, cutting):
    """No heartbeat ever: the orientation command arms the watchdog; the offset is back at
    0/0 within watchdog_ms + 50 ms of the command, while cutting."""
    fresh = cutting.store.get("heartbeat") != 0 or cutting.store.watchdog().armed
    srv = _cutting_server(scenario) if fresh else cutting      # (run after the others)
    try:
        assert srv.store.get("heartbeat") == 0 and not srv.store.watchdog().armed
        r = _probe("watchdog", srv.port, WATCHDOG_MS, 1, "--no-heartbeat")["trials"][0]
        assert r["cutting_all"]
        assert r["ack"] in (ACK["applied"], ACK["reset_by_watchdog"])
        assert r["delay_s"] is not None, "the offset was never reset"
        assert WATCHDOG_MS / 1e3 <= r["delay_s"] <= WATCHDOG_MS / 1e3 + WATCHDOG_LATE_S
        assert srv.store.get("heartbeat") == 0
        # the NC itself holds 0/0 from its next tick (the registers showed it at once)
        assert _wait(lambda: any(w.startswith("watchdog") for _, w in srv.events))
        st = srv.nc.state
        assert st.watchdog_tripped == 1 and st.lead_offset_deg == st.tilt_offset_deg == 0
        assert srv.error is None
    finally:
        if fresh:
            srv.stop()


def test_watchdog_resets_the_offset_on_time_while_cutting(cutting):
    """Heartbeat stops after an applied offset (a new posture each trial: new cutting
    models): the offset is back at 0/0 within watchdog_ms + 50 ms, every trial."""
    res = _probe("watchdog", cutting.port, WATCHDOG_MS, 3)["trials"]
    assert all(t["cutting_all"] for t in res)
    assert all(t["ack"] == ACK["applied"] for t in res), res
    delays = np.array([np.nan if t["delay_s"] is None else t["delay_s"] for t in res])
    assert np.all(np.isfinite(delays)), res
    assert np.all(delays >= WATCHDOG_MS / 1e3)
    assert np.all(delays <= WATCHDOG_MS / 1e3 + WATCHDOG_LATE_S), delays
    assert cutting.error is None


@pytest.mark.parametrize("clients, period_ms, bound_s",
                         [(1, 0, P99_ONE_S), (50, POLL_FIFTY_MS, P99_FIFTY_S)])
def test_read_latency_while_cutting(cutting, clients, period_ms, bound_s):
    """125-register reads while the NC cuts and a controller beats and commands a new
    offset every 0.25 s: p99 within the bound, no error. One client reads back to back;
    fifty poll, each once every ``POLL_FIFTY_MS``, and every poll is answered in time
    for the next (not more than a tenth of the slots missed)."""
    if not cutting.realtime:
        pytest.skip("the server's process could not take the real-time scheduling class "
                    "(needs root or CAP_SYS_NICE): its latency is the machine's load's")
    t_sim = cutting.nc.state.time_s
    seconds, rounds = 1.0, 2
    r = _probe("reads", cutting.port, clients, seconds, rounds, "--commands",
               *(("--period-ms", period_ms) if period_ms else ()))
    # the NC cut all along (on a loaded machine it runs behind the wall clock)
    assert cutting.store.get("cutting") == 1 and cutting.nc.state.time_s > t_sim + 0.1
    lat = np.concatenate([x["latency_s"] for x in r["rounds"]])
    assert not any(x["errors"] for x in r["rounds"]), r["rounds"][0]["errors"][:3]
    assert sum(x["commands"] for x in r["rounds"]) >= 4
    if period_ms:
        slots = clients * rounds * round(seconds * 1e3 / period_ms)
        assert lat.size >= 0.9 * slots, (lat.size, slots)
    else:
        assert lat.size >= 500
    p99 = float(np.percentile(lat, 99))
    assert p99 <= bound_s, (f"p99 {p99 * 1e3:.2f} ms with {clients} client(s) (p50 "
                            f"{np.percentile(lat, 50) * 1e3:.2f} ms, load "
                            f"{os.getloadavg()[0]:.1f}, probe real-time {r['realtime']})")
