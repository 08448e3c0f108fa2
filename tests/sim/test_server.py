"""The simulated NC over real Modbus TCP on loopback: the map read by mbpoll, refused
writes, the watchdog, disconnects and a server restart."""

from __future__ import annotations

import re
import shutil
import socket
import subprocess
import time

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
