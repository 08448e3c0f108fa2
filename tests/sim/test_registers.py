"""The register map's codec: one table of known-good pairs for encode, decode and round trip."""

from __future__ import annotations

import pytest

from sim.registers import HOLDING, REGISTERS, by_name, decode, encode, markdown_table

# (register, engineering value, raw words)
PAIRS = [
    ("status", 1, [1]),
    ("block", 70000, [1, 4464]),
    ("pos_x", -12.048, [0xFFFF, 0xD0F0]),
    ("pos_r1", 60.0, [0, 60000]),
    ("spindle_rpm", 9000, [9000]),
    ("lead_now", -20.0, [0xF830]),
    ("lead_cmd", 12.34, [1234]),
    ("tilt_cmd", -30.0, [0xF448]),
    ("accel_sequence", 4_000_000_000, [61035, 10240]),
    ("watchdog_ms", 1000, [1000]),
]


@pytest.mark.parametrize("name, value, words", PAIRS)
def test_encode_decode_round_trip(name, value, words):
    reg = by_name(name)
    assert encode(reg, value) == words
    assert decode(reg, words) == pytest.approx(value, abs=reg.scale / 2)
    assert encode(reg, decode(reg, words)) == words


def test_map_is_consistent():
    seen = {}
    for r in REGISTERS:
        for a in range(r.address, r.address + r.words):
            assert (r.table, a) not in seen, f"{r.name} overlaps {seen.get((r.table, a))}"
            seen[(r.table, a)] = r.name
        assert r.words in (1, 2)
        lo, hi = r.count_range
        bits = 16 * r.words
        if r.signed:
            assert -(2 ** (bits - 1)) <= lo <= hi < 2 ** (bits - 1)
        else:
            assert 0 <= lo <= hi < 2 ** bits
    table = markdown_table()
    assert all(f"`{r.name}`" in table for r in REGISTERS)
    assert all(r.low < r.high for r in REGISTERS if r.table == HOLDING)


def test_encode_clips_and_refuses_nan():
    assert encode(by_name("lead_cmd"), 99.0) == [3000]
    with pytest.raises(ValueError, match="lead_cmd"):
        encode(by_name("lead_cmd"), float("nan"))
    with pytest.raises(KeyError, match="no register"):
        by_name("spindle_torque")


def test_readme_register_table_is_the_map():
    import os

    with open(os.path.join(os.path.dirname(__file__), "..", "..", "README.md"),
              encoding="utf-8") as fh:
        readme = fh.read()
    assert markdown_table() in readme
