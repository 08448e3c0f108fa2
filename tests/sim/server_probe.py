"""Probes of the simulated NC's Modbus server, run as a process of their own (so that
their clients do not share the server's interpreter lock), each printing one JSON line.

``python -m tests.sim.server_probe reads PORT CLIENTS SECONDS ROUNDS [--commands]
[--period-ms P]``
    ``ROUNDS`` rounds of ``SECONDS`` wall seconds each: ``CLIENTS`` connections to
    127.0.0.1:PORT, each reading 125 input registers of the accelerometer ring in a
    loop (one request in flight per connection): back to back, or with ``--period-ms``
    once every ``P`` ms as a polling client does (the clients' phases spread evenly
    over the period; a slot that passed while an answer was awaited is read at once,
    the slots missed entirely are skipped, not made up: a server that cannot keep up
    shows as fewer reads). Per round: the round trip of every
    read [s] and the errors (exception answers, wrong lengths, a connection lost). The
    frames are built by hand (function 4, MBAP header): the client's own cost is a few
    microseconds a read. With ``--commands`` one more connection acts as a controller
    meanwhile: it beats the heartbeat every 20 ms and commands a new orientation offset
    every 0.25 s (so the NC checks it and builds new cutting models while it is read).

``python -m tests.sim.server_probe watchdog PORT WATCHDOG_MS TRIALS [--no-heartbeat]``
    ``TRIALS`` times: beat the heartbeat, command an orientation offset (small, a
    different one each trial, so that the NC builds new cutting models), keep beating
    until it is acknowledged, then fall silent and poll until the NC shows the offset
    back at 0/0 reset by the watchdog. With ``--no-heartbeat`` the heartbeat is never
    written (one trial: the silence is counted from the command). Per trial: the
    delay [s] from the send of the last heartbeat (or of the command) to the receipt of
    the first answer that shows the reset (an upper bound of the NC's own delay), or
    None when it did not come within ``WATCHDOG_MS`` + 3 s; and the acknowledgement the
    command had.

With ``--realtime`` the probe asks for the real-time scheduling class (SCHED_FIFO 1,
where permitted) so that its own waits for a CPU on a loaded machine do not count in
the server's figures; the JSON says whether it got it (``realtime``).
"""

from __future__ import annotations

import asyncio
import importlib.util
import json
import math
import os
import socket
import struct
import sys
import time
from pathlib import Path


def _load_registers():
    """``sim/registers.py`` alone: importing it through the ``sim`` package brings numba,
    scipy and orient, seconds of start-up on a loaded machine for a probe that needs
    only the map."""
    path = Path(__file__).resolve().parents[2] / "sim" / "registers.py"
    spec = importlib.util.spec_from_file_location("_probe_registers", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


_regs = _load_registers()
ACK, RING_SAMPLES, RING_START = _regs.ACK, _regs.RING_SAMPLES, _regs.RING_START
by_name, decode, encode = _regs.by_name, _regs.decode, _regs.encode

COUNT = 125
#: Offsets [deg] commanded in turn by the watchdog trials (small: feasible along the cut).
OFFSETS = ((2.0, -2.0), (-2.0, 2.0), (3.0, 0.0), (0.0, 3.0), (-3.0, 0.0), (0.0, -3.0),
           (1.5, 1.5), (-1.5, -1.5))


async def _reader(port: int, k: int, stop_at: float, budget: list[int],
                  out: list[float], errors: list[str], period_s: float = 0.0,
                  phase_s: float = 0.0) -> None:
    try:
        reader, writer = await asyncio.open_connection("127.0.0.1", port)
    except OSError as exc:
        errors.append(f"connect: {exc}")
        return
    tid = 0
    next_at = time.monotonic() + phase_s
    try:
        while time.monotonic() < stop_at and budget[0] > 0:
            if period_s > 0.0:
                now = time.monotonic()
                if next_at > now:
                    await asyncio.sleep(next_at - now)
                    if time.monotonic() >= stop_at:
                        break
                # the next slot after now (one on when on time)
                late = time.monotonic() - next_at
                next_at += period_s * max(1, math.ceil(late / period_s))
            budget[0] -= 1
            tid = (tid + 1) & 0xFFFF
            addr = RING_START + ((k * 37 + tid) * COUNT) % (2 * RING_SAMPLES - COUNT)
            frame = struct.pack(">HHHBBHH", tid, 0, 6, 1, 4, addr, COUNT)
            t0 = time.perf_counter()
            writer.write(frame)
            head = await reader.readexactly(9)
            rtid, _proto, length, _unit, fc, nbytes = struct.unpack(">HHHBBB", head)
            body = await reader.readexactly(length - 3)
            dt = time.perf_counter() - t0
            if fc != 4 or rtid != tid or nbytes != 2 * COUNT or len(body) != 2 * COUNT:
                errors.append(f"bad answer fc {fc} tid {rtid}/{tid} bytes {nbytes}")
                continue
            out.append(dt)
    except (OSError, asyncio.IncompleteReadError) as exc:
        errors.append(f"connection: {exc!r}")
    finally:
        writer.close()


async def _commander(port: int, stop_at: float, errors: list[str]) -> int:
    """Beat every 20 ms and command a new offset every 0.25 s until ``stop_at``; returns
    how many commands it sent."""
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    tid, beat, sent = 0, 0, 0
    seq = int(time.monotonic() * 10) % 60000
    next_cmd = 0.0

    async def write(name: str, value: float) -> None:
        nonlocal tid
        reg = by_name(name)
        tid = (tid + 1) & 0xFFFF
        writer.write(struct.pack(">HHHBBHH", tid, 0, 6, 1, 6, reg.address,
                                 encode(reg, value)[0]))
        head = await reader.readexactly(8)
        body = await reader.readexactly(struct.unpack(">H", head[4:6])[0] - 2)
        if head[7] != 6:
            errors.append(f"write {name}={value}: exception {body!r}")

    try:
        while time.monotonic() < stop_at:
            beat = (beat + 1) % 65536
            await write("heartbeat", beat)
            if time.monotonic() >= next_cmd:
                lead, tilt = OFFSETS[sent % len(OFFSETS)]
                seq += 1
                await write("lead_cmd", lead)
                await write("tilt_cmd", tilt)
                await write("orient_seq", seq)
                sent += 1
                next_cmd = time.monotonic() + 0.25
            await asyncio.sleep(0.02)
    finally:
        writer.close()
    return sent


async def _reads(port: int, clients: int, seconds: float, commands: bool,
                 period_s: float = 0.0) -> dict:
    out: list[float] = []
    errors: list[str] = []
    budget = [10 ** 9]
    stop_at = time.monotonic() + seconds
    jobs = [_reader(port, k, stop_at, budget, out, errors, period_s, k * period_s / clients)
            for k in range(clients)]
    if commands:
        jobs.append(_commander(port, stop_at, errors))
    res = await asyncio.gather(*jobs)
    return {"latency_s": out, "errors": errors, "commands": res[-1] if commands else 0}


class _Client:
    """A blocking Modbus TCP client of its own (functions 3, 4 and 6; raw frames)."""

    def __init__(self, port: int) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=2.0)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.tid = 0

    def _recv(self, n: int) -> bytes:
        out = b""
        while len(out) < n:
            chunk = self.sock.recv(n - len(out))
            if not chunk:
                raise ConnectionError("the server closed the connection")
            out += chunk
        return out

    def _ask(self, fc: int, a: int, b: int) -> bytes:
        self.tid = (self.tid + 1) & 0xFFFF
        self.sock.sendall(struct.pack(">HHHBBHH", self.tid, 0, 6, 1, fc, a, b))
        head = self._recv(8)
        tid, _proto, length, _unit, rfc = struct.unpack(">HHHBB", head)
        body = self._recv(length - 2)
        if tid != self.tid or rfc != fc:
            raise ConnectionError(f"function {fc} at {a}: answer {rfc} {body!r}")
        return body

    def registers(self, fc: int, address: int, count: int) -> list[int]:
        body = self._ask(fc, address, count)
        return list(struct.unpack(f">{count}H", body[1:1 + 2 * count]))

    def write(self, name: str, value: float) -> float:
        """Write one holding register; returns the wall time [s] the request was sent."""
        reg = by_name(name)
        t = time.perf_counter()
        self._ask(6, reg.address, encode(reg, value)[0])
        return t

    def holding(self, name: str) -> float:
        reg = by_name(name)
        return decode(reg, self.registers(3, reg.address, reg.words))

    def state(self) -> tuple[dict, float]:
        """The input registers 0..20 decoded, and the wall time [s] the answer came."""
        w = self.registers(4, 0, 21)
        t = time.perf_counter()
        names = ("lead_now", "tilt_now", "orient_ack_seq", "orient_ack_state",
                 "watchdog_tripped", "cutting")
        out = {}
        for n in names:
            reg = by_name(n)
            out[n] = decode(reg, w[reg.address:reg.address + reg.words])
        return out, t

    def close(self) -> None:
        self.sock.close()


def _watchdog(port: int, watchdog_ms: int, trials: int, heartbeat: bool) -> dict:
    c = _Client(port)
    c.write("watchdog_ms", watchdog_ms)
    seq, beat = int(c.holding("orient_seq")), int(c.holding("heartbeat"))
    limit = watchdog_ms / 1000.0 + 3.0
    out = []
    for k in range(trials if heartbeat else 1):
        lead, tilt = OFFSETS[(seq + k) % len(OFFSETS)]
        seq = (seq + 1) % 65536
        if heartbeat:
            t_end = time.perf_counter() + 0.1        # alive: the trip (if any) clears
            while time.perf_counter() < t_end:
                beat = (beat + 1) % 65536
                c.write("heartbeat", beat)
                time.sleep(0.02)
        c.write("lead_cmd", lead)
        c.write("tilt_cmd", tilt)
        t_alive = c.write("orient_seq", seq)
        st, _ = c.state()
        while heartbeat and st["orient_ack_seq"] != seq:     # beat until it is taken
            beat = (beat + 1) % 65536
            t_alive = c.write("heartbeat", beat)
            time.sleep(0.01)
            st, _ = c.state()
        if heartbeat:                                 # the last sign of life
            beat = (beat + 1) % 65536
            t_alive = c.write("heartbeat", beat)
        ack = st["orient_ack_state"] if st["orient_ack_seq"] == seq else None
        cutting = [st["cutting"]]
        delay = None
        while True:                                   # silent from here on
            st, t = c.state()
            cutting.append(st["cutting"])
            if st["orient_ack_seq"] == seq and ack is None:
                ack = st["orient_ack_state"]
            if (st["orient_ack_seq"] == seq and st["watchdog_tripped"] == 1
                    and st["orient_ack_state"] == ACK["reset_by_watchdog"]
                    and st["lead_now"] == 0 and st["tilt_now"] == 0):
                delay = t - t_alive
                break
            if t - t_alive > limit:
                break
            time.sleep(0.002)
        out.append({"delay_s": delay, "ack": ack, "offset": [lead, tilt],
                    "cutting_all": all(v == 1 for v in cutting)})
    c.close()
    return {"trials": out}


def main(argv: list[str]) -> int:
    what, port = argv[0], int(argv[1])
    if "--realtime" in argv:        # the client's own waits on a loaded machine not counted
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
        except (AttributeError, OSError):
            pass
    if what == "reads":
        clients, seconds, rounds = int(argv[2]), float(argv[3]), int(argv[4])
        period_s = float(argv[argv.index("--period-ms") + 1]) / 1e3 \
            if "--period-ms" in argv else 0.0
        res = {"rounds": [asyncio.run(_reads(port, clients, seconds, "--commands" in argv,
                                             period_s)) for _ in range(rounds)]}
    elif what == "watchdog":
        res = _watchdog(port, int(argv[2]), int(argv[3]), "--no-heartbeat" not in argv)
    else:
        raise SystemExit(f"server_probe: expected 'reads' or 'watchdog', got {what!r}")
    res["realtime"] = hasattr(os, "sched_getscheduler") and \
        os.sched_getscheduler(0) == os.SCHED_FIFO
    print(json.dumps(res))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
