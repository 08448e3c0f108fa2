"""The simulated NC's Modbus register map: one table for the server, the client and the docs.

Protocol addresses are 0-based (``mbpoll -0``); one device, any unit id.
Input registers (function 4) hold the machine's state, holding registers
(functions 3, 6, 16) the commands. 32-bit values take two registers, high
word first; signed values are two's complement. A value in engineering units
is ``counts * scale``.

The accelerometer stream is a ring of ``RING_SAMPLES`` sample pairs (X, Y
interleaved, signed counts of the converter) starting at ``RING_START``: the
sample with sequence number ``k`` (counted from 0 since the server started)
sits at pair ``k mod RING_SAMPLES``. ``accel_sequence`` is the number of
samples written so far, so a client that last read up to ``k0`` knows that
samples ``k0 .. sequence - 1`` are new, and that it missed some if
``sequence - k0 > RING_SAMPLES``.

The watchdog runs on the wall clock in the server's process, independent of the
simulation (:mod:`sim.modbus`). The controller counts as alive at every write that
changes ``heartbeat`` or ``orient_seq``; the first such write arms the watchdog (a
controller that commands an offset and never beats is covered). A silence longer than
``watchdog_ms`` trips it within a few milliseconds: ``watchdog_tripped`` 1,
``lead_now`` and ``tilt_now`` 0 and, when an offset was in effect, ``orient_ack_state``
4; the NC holds the program's posture (0/0) from its next interpolation period while
the trip lasts, and drops a command whose check ends during it. The next sign of life
clears the trip (measured while cutting, ``watchdog_ms`` 100: reset 101-128 ms after
the last write, send to answer).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = [
    "ACK",
    "CAUSE",
    "HOLDING",
    "INPUT",
    "REGISTERS",
    "RING_SAMPLES",
    "RING_START",
    "STATUS",
    "Register",
    "by_name",
    "decode",
    "encode",
    "markdown_table",
]

#: Machine status (``status``).
STATUS = {"idle": 0, "running": 1, "finished": 2, "fault": 3}
#: Orientation command acknowledgement (``orient_ack_state``).
ACK = {"none": 0, "applied": 1, "refused_interference": 2, "refused_axis_limit": 3,
       "reset_by_watchdog": 4}
#: Chatter cause as the controller reports it (``chatter_cause``).
CAUSE = {"none": 0, "tool": 1, "workpiece": 2, "unknown": 3}

INPUT = "input"
HOLDING = "holding"
#: Accelerometer ring: sample pairs and their first register. 24,576 pairs hold 0.96 s
#: at 25.6 kHz: a controller on a loaded 2-core machine was seen to stall for 0.35 s
#: (a ring of 0.32 s lost 638 samples); the map's 65,536 registers bound it.
RING_SAMPLES = 24576
RING_START = 100


@dataclass(frozen=True)
class Register:
    """One value of the map.

    Attributes
    ----------
    name : str
    table : str
        ``'input'`` (read-only) or ``'holding'`` (read/write).
    address : int
        First protocol address (0-based).
    words : int
        1 or 2 registers.
    signed : bool
    scale : float
        Engineering units per count.
    unit : str
    low, high : float
        Allowed range in engineering units (holding registers refuse writes
        outside it; input registers are clipped to it).
    doc : str
    """

    name: str
    table: str
    address: int
    words: int
    signed: bool
    scale: float
    unit: str
    low: float
    high: float
    doc: str

    @property
    def count_range(self) -> tuple[int, int]:
        """Allowed raw counts (inclusive)."""
        return (math.ceil(self.low / self.scale - 1e-9), math.floor(self.high / self.scale + 1e-9))


def _r(name, table, address, words, signed, scale, unit, low, high, doc) -> Register:
    return Register(name, table, address, words, signed, scale, unit, low, high, doc)


_I32 = 2 ** 31 - 1
REGISTERS: tuple[Register, ...] = (
    # --- state (input registers) ------------------------------------------------
    _r("status", INPUT, 0, 1, False, 1, "-", 0, 3,
       "0 idle, 1 running, 2 finished, 3 fault"),
    _r("block", INPUT, 1, 2, False, 1, "-", 0, _I32,
       "Program block (line) being executed, 1-based; 0 before the start"),
    _r("pos_x", INPUT, 3, 2, True, 0.001, "mm", -_I32 * 0.001, _I32 * 0.001, "X axis position"),
    _r("pos_y", INPUT, 5, 2, True, 0.001, "mm", -_I32 * 0.001, _I32 * 0.001, "Y axis position"),
    _r("pos_z", INPUT, 7, 2, True, 0.001, "mm", -_I32 * 0.001, _I32 * 0.001, "Z axis position"),
    _r("pos_r1", INPUT, 9, 2, True, 0.001, "deg", -_I32 * 0.001, _I32 * 0.001,
       "First rotary axis (A or B) position"),
    _r("pos_r2", INPUT, 11, 2, True, 0.001, "deg", -_I32 * 0.001, _I32 * 0.001,
       "Second rotary axis (C) position"),
    _r("spindle_rpm", INPUT, 13, 1, False, 1, "rev/min", 0, 65535, "Spindle speed"),
    _r("feed_override_now", INPUT, 14, 1, False, 1, "%", 0, 200, "Feed override in effect"),
    _r("lead_now", INPUT, 15, 1, True, 0.01, "deg", -90, 90,
       "Lead offset in effect (added to the program's posture)"),
    _r("tilt_now", INPUT, 16, 1, True, 0.01, "deg", -90, 90, "Tilt offset in effect"),
    _r("orient_ack_seq", INPUT, 17, 1, False, 1, "-", 0, 65535,
       "Sequence number of the last orientation command handled"),
    _r("orient_ack_state", INPUT, 18, 1, False, 1, "-", 0, 4,
       "0 none, 1 applied, 2 refused (interference), 3 refused (axis limit), "
       "4 reset to 0/0 by the watchdog"),
    _r("watchdog_tripped", INPUT, 19, 1, False, 1, "-", 0, 1,
       "1 while the controller is silent longer than the timeout"),
    _r("cutting", INPUT, 20, 1, False, 1, "-", 0, 1, "1 while the tool is in the workpiece"),
    _r("accel_sequence", INPUT, 30, 2, False, 1, "-", 0, 2 ** 32 - 1,
       "Accelerometer samples written since the start (mod 2^32)"),
    _r("accel_ring_samples", INPUT, 32, 1, False, 1, "-", 0, 65535,
       "Sample pairs in the ring"),
    _r("accel_rate_hz", INPUT, 33, 1, False, 1, "Hz", 0, 65535, "Accelerometer sample rate"),
    _r("accel_lsb_um_s2", INPUT, 34, 1, False, 1, "um/s^2", 0, 65535,
       "One converter count in um/s^2"),
    _r("sim_time_ms", INPUT, 35, 2, False, 1, "ms", 0, 2 ** 32 - 1, "Simulated time"),
    # --- commands (holding registers) --------------------------------------------
    _r("feed_override", HOLDING, 0, 1, False, 1, "%", 0, 150, "Feed override command"),
    _r("lead_cmd", HOLDING, 1, 1, True, 0.01, "deg", -30, 30,
       "Lead offset command (taken when orient_seq changes)"),
    _r("tilt_cmd", HOLDING, 2, 1, True, 0.01, "deg", -30, 30,
       "Tilt offset command (taken when orient_seq changes)"),
    _r("orient_seq", HOLDING, 3, 1, False, 1, "-", 0, 65535,
       "Write a new value to submit lead_cmd/tilt_cmd (counts as alive for the watchdog)"),
    _r("heartbeat", HOLDING, 4, 1, False, 1, "-", 0, 65535,
       "Controller heartbeat: any change counts as alive"),
    _r("watchdog_ms", HOLDING, 5, 1, False, 1, "ms", 100, 10000,
       "Silence (no change of heartbeat or orient_seq, wall clock) after which the "
       "orientation offset returns to 0/0"),
    _r("chatter_flag", HOLDING, 6, 1, False, 1, "-", 0, 1,
       "Controller's verdict: 1 chatter"),
    _r("chatter_cause", HOLDING, 7, 1, False, 1, "-", 0, 3,
       "0 none, 1 tool, 2 workpiece, 3 unknown"),
    _r("chatter_freq_hz", HOLDING, 8, 1, False, 1, "Hz", 0, 65535, "Controller's chatter frequency"),
    _r("cycle_start", HOLDING, 9, 1, False, 1, "-", 0, 1,
       "1 starts the program (a server started without autostart waits for it)"),
)

_BY_NAME = {r.name: r for r in REGISTERS}


def by_name(name: str) -> Register:
    """The register called ``name`` (KeyError names the unknown one)."""
    try:
        return _BY_NAME[name]
    except KeyError:
        raise KeyError(f"no register named {name!r}") from None


def encode(reg: Register, value: float) -> list[int]:
    """Engineering value -> raw 16-bit words (clipped to the register's range)."""
    if not math.isfinite(value):
        raise ValueError(f"{reg.name}: expected a finite value, got {value!r}")
    lo, hi = reg.count_range
    c = min(max(round(value / reg.scale), lo), hi)
    bits = 16 * reg.words
    c &= (1 << bits) - 1
    return [(c >> 16) & 0xFFFF, c & 0xFFFF] if reg.words == 2 else [c]


def decode(reg: Register, words: list[int]) -> float:
    """Raw words -> engineering value."""
    if len(words) != reg.words:
        raise ValueError(f"{reg.name}: expected {reg.words} words, got {len(words)}")
    c = (words[0] << 16) | words[1] if reg.words == 2 else words[0]
    bits = 16 * reg.words
    if reg.signed and c >= 1 << (bits - 1):
        c -= 1 << bits
    return c * reg.scale


def raw_in_range(reg: Register, words: list[int]) -> bool:
    """Whether raw words decode to a value inside the register's range."""
    lo, hi = reg.count_range
    v = round(decode(reg, words) / reg.scale)
    return lo <= v <= hi


def markdown_table() -> str:
    """The map as a Markdown table (the README's copy is checked against it)."""
    rows = ["| table | address | words | name | unit | scale | range | meaning |",
            "|---|---|---|---|---|---|---|---|"]
    for r in REGISTERS:
        rng = f"{r.low:g} .. {r.high:g}" if r.table == HOLDING else "-"
        rows.append(f"| {r.table} | {r.address} | {r.words} | `{r.name}` | {r.unit} | "
                    f"{r.scale:g} | {rng} | {r.doc} |")
    rows.append(f"| input | {RING_START} | {2 * RING_SAMPLES} | accelerometer ring | counts | "
                f"`accel_lsb_um_s2` | - | X, Y pairs; sample k at pair k mod "
                f"{RING_SAMPLES} |")
    return "\n".join(rows)
