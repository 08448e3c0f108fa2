"""The Modbus server's reliability figures while the NC cuts (issue 19).

Prints, for the bundled thin wall's first pass (cutter locations 2..36) run in real time
with the feed override at 3 % (so that the cut lasts about 65 s; the cutting
simulation's work per wall second is the same as at 100 %):

1. the watchdog's delay (the send of the last heartbeat, or of the command when the
   controller never beats, to the first answer showing the offset back at 0/0) over
   ``--trials`` trials, with ``watchdog_ms`` 100 and 300, while cutting and idle;
2. the round trip of a 125-register read with 1 and 50 clients while cutting, in
   ``--rounds`` rounds of ``--seconds``, alone and while a controller beats and commands
   a new orientation offset every 0.25 s (the NC checks it and builds cutting models).

The clients are the probes of ``tests/sim/server_probe.py``, each a process of its own
in the real-time scheduling class where permitted (so that their own waits for a CPU on
a loaded machine do not count).

Usage: python benchmarks/bench_server.py [--trials N] [--seconds S] [--rounds R]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, ROOT)

from orient.scenario import load_plan_scenario  # noqa: E402
from sim.cli import BUNDLED  # noqa: E402
from sim.machine import SimulatedNC  # noqa: E402
from sim.server import NCServer  # noqa: E402

POINTS = (2, 36)


def probe(*args: object) -> dict:
    env = dict(os.environ, PYTHONPATH=ROOT)
    r = subprocess.run([sys.executable, "-m", "tests.sim.server_probe", *map(str, args),
                        "--realtime"],
                       capture_output=True, text=True, timeout=120, check=True, cwd=ROOT,
                       env=env)
    return json.loads(r.stdout)


def summary(delays: list) -> str:
    d = [x for x in delays if x is not None]
    missing = len(delays) - len(d)
    if not d:
        return f"none of {len(delays)} came within the limit"
    d_ms = np.array(d) * 1e3
    return (f"min {d_ms.min():.0f} median {np.median(d_ms):.0f} max {d_ms.max():.0f} ms "
            f"({len(d)} trials{f', {missing} never reset' if missing else ''})")


def watchdog(srv: NCServer, label: str, trials: int) -> None:
    for ms in (100, 300):
        r = probe("watchdog", srv.port, ms, trials)["trials"]
        cut = all(t["cutting_all"] for t in r)
        acks = sorted({t["ack"] for t in r}, key=str)
        print(f"1. watchdog {ms} ms, {label}, heartbeat stops: "
              f"{summary([t['delay_s'] for t in r])}; acks {acks}; cutting all along: {cut}",
              flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=1.5)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args(argv)
    print(f"load average at start {', '.join(f'{x:.2f}' for x in os.getloadavg())}",
          flush=True)
    scn = load_plan_scenario(BUNDLED)
    wp = SimulatedNC(scn, points=POINTS).workpiece

    nc = SimulatedNC(scn, points=POINTS, workpiece=wp)
    nc.set_feed_override(3.0)
    with NCServer(nc, port=0, autostart=False) as srv:
        srv.store.set("feed_override", 3)
        srv.store.set("cycle_start", 1)
        t0 = time.monotonic()
        while not srv.store.get("cutting"):
            if time.monotonic() - t0 > 60:
                raise SystemExit("the NC did not start cutting")
            time.sleep(0.01)
        r = probe("watchdog", srv.port, 100, 1, "--no-heartbeat")["trials"]
        print(f"1. watchdog 100 ms, cutting, heartbeat never written: "
              f"{summary([t['delay_s'] for t in r])}; ack {r[0]['ack']}; cutting all along: "
              f"{r[0]['cutting_all']}", flush=True)
        watchdog(srv, "cutting", args.trials)
        for n in (1, 50):
            for cmds in ((), ("--commands",)):
                before = srv.store.get("cutting")
                r = probe("reads", srv.port, n, args.seconds, args.rounds, *cmds)["rounds"]
                after = srv.store.get("cutting")
                rounds = [np.array(x["latency_s"]) * 1e3 for x in r]
                lat = np.concatenate(rounds)
                per = ", ".join(f"{np.percentile(x, 99):.1f}" for x in rounds)
                print(f"2. read of 125 registers, {n} client(s)"
                      f"{', controller commanding' if cmds else ''}, cutting "
                      f"{before:g}/{after:g}: {lat.size} reads, p50 "
                      f"{np.percentile(lat, 50):.2f} ms, p99 {np.percentile(lat, 99):.2f} ms "
                      f"(per round of {args.seconds:g} s: {per}), max {lat.max():.1f} ms; "
                      f"{sum(len(x['errors']) for x in r)} errors, "
                      f"{sum(x['commands'] for x in r)} commands; load "
                      f"{os.getloadavg()[0]:.1f}", flush=True)
        print(f"   (simulated {nc.state.time_s:.2f} s in {time.monotonic() - t0:.1f} s wall; "
              f"server error {srv.error!r}; server real-time: "
              f"{getattr(srv, 'realtime', 'n/a')})")

    nc = SimulatedNC(scn, points=POINTS, workpiece=wp)
    with NCServer(nc, port=0, autostart=False) as srv:
        watchdog(srv, "idle", args.trials)
    print(f"load average at end {', '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
