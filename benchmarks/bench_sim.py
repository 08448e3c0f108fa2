"""Timings of the simulated machine (issue 5).

Prints:

1. simulated time per wall-clock time of the thin-wall scenario on one core
   (target: faster than real time): the NC alone (no server), the bundled
   closed-loop scenario's default stretch, as fast as it goes; with the
   cutting-model builds and without them;
2. the Modbus round trip of a 125-register read on loopback (pymodbus
   client and server), the NC idle and the NC running in real time;
3. the chatter detector's time per window (orient.detect, the simulated
   machine's settings).

Usage: python benchmarks/bench_sim.py [--reads N]
"""

from __future__ import annotations

import argparse
import os
import sys
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")                  # one core

import numpy as np

sys.path.insert(0, os.path.abspath(os.path.join(os.path.dirname(__file__), "..")))

from pymodbus.client import ModbusTcpClient

from orient.detect import ChatterDetector
from orient.scenario import load_plan_scenario
from sim.cli import BUNDLED
from sim.constants import DEFAULT_POINTS, TICK_S
from sim.machine import SimulatedNC
from sim.sensors import detector_settings
from sim.server import NCServer


def sim_speed(scn, wp) -> None:
    nc = SimulatedNC(scn, points=DEFAULT_POINTS, workpiece=wp)
    from sim import machine

    built = [0.0]
    orig = machine.prepare_cut

    def timed(*a, **k):
        t = time.perf_counter()
        try:
            return orig(*a, **k)
        finally:
            built[0] += time.perf_counter() - t

    machine.prepare_cut = timed
    t0 = time.perf_counter()
    ticks = 0
    while not nc.done:
        nc.tick(TICK_S)
        ticks += 1
    wall = time.perf_counter() - t0
    machine.prepare_cut = orig
    sim_t = nc.state.time_s
    cut_t = len(nc.surface.offset_mm) / (nc.rpm / 60.0 * nc.tool.flutes)
    print(f"1. NC alone, cutter locations {DEFAULT_POINTS[0]}..{DEFAULT_POINTS[1]}, "
          f"{nc.steps_per_rev} steps/rev at {nc.rpm:g} rev/min ({nc.dt_s * 1e6:.2f} us step), "
          f"{nc.workpiece.levels and len(nc.workpiece.levels)} wall levels, {ticks} ticks of "
          f"{TICK_S * 1e3:g} ms:")
    print(f"   simulated {sim_t:.2f} s ({cut_t:.2f} s cutting) in {wall:.2f} s wall: "
          f"{sim_t / wall:.2f}x real time (target > 1: "
          f"{'met' if sim_t / wall > 1 else 'NOT met'}); cutting-model builds "
          f"{built[0]:.2f} s ({len(nc._models)} distinct engagements); without them "
          f"{sim_t / max(wall - built[0], 1e-9):.2f}x")


def modbus_rtt(scn, wp, reads: int) -> None:
    for label, autostart in (("NC idle", False), ("NC running in real time", True)):
        nc = SimulatedNC(scn, points=DEFAULT_POINTS, workpiece=wp)
        with NCServer(nc, port=0, autostart=autostart) as srv:
            c = ModbusTcpClient("127.0.0.1", port=srv.port, timeout=2)
            c.connect()
            for _ in range(50):
                c.read_input_registers(100, count=125, device_id=1)
            ts = np.empty(reads)
            for i in range(reads):
                t = time.perf_counter()
                rr = c.read_input_registers(100 + (i % 100) * 125, count=125, device_id=1)
                ts[i] = time.perf_counter() - t
                assert not rr.isError()
            c.close()
        print(f"2. Modbus read of 125 input registers, loopback, {label}: median "
              f"{np.median(ts) * 1e3:.3f} ms, p99 {np.percentile(ts, 99) * 1e3:.3f} ms "
              f"({reads} reads; {125 * reads / ts.sum():,.0f} registers/s)")


def detector_time() -> None:
    from sim.sensors import Accelerometers

    s = Accelerometers()
    det = ChatterDetector(detector_settings(s))
    rng = np.random.default_rng(0)
    n = int(s.sample_rate_hz * 10)
    a = rng.normal(0, 3, size=(n, 2))
    t = time.perf_counter()
    out = det.feed(a[:, 0], a[:, 1], 9000.0, 2)
    dt = time.perf_counter() - t
    st = det.settings
    print(f"3. detector: {len(out)} windows of {st.window_samples} samples (hop "
          f"{st.hop_samples}) in {dt:.3f} s = {dt / len(out) * 1e6:.0f} us per window, "
          f"{st.hop_samples / st.sample_rate_hz * 1e3:.1f} ms of signal per hop")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reads", type=int, default=2000)
    args = ap.parse_args(argv)
    print(f"load average at start {', '.join(f'{x:.2f}' for x in os.getloadavg())}; "
          f"NUMBA_NUM_THREADS={os.environ['NUMBA_NUM_THREADS']}")
    scn = load_plan_scenario(BUNDLED)
    wp = SimulatedNC(scn, points=DEFAULT_POINTS).workpiece
    sim_speed(scn, wp)
    modbus_rtt(scn, wp, args.reads)
    detector_time()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
