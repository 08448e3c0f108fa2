"""nc.tables.TableReader: the one TOML reader (machine files, offsets, scenarios)."""

from __future__ import annotations

import math

import pytest

from nc.errors import InputError, MachineFileError, TableError
from nc.tables import TableReader, value_kind


def _reader(tmp_path, text: str = "") -> TableReader:
    f = tmp_path / "t.toml"
    f.write_text(text)
    return TableReader(f)


@pytest.mark.parametrize("value, kwargs, part", [
    (math.nan, {}, "expected a finite number, got nan"),
    (math.inf, {}, "expected a finite number, got inf"),
    (math.nan, {"allow_inf": True}, "expected a number, got nan"),
    ("3", {}, "expected a number, got a string ('3')"),
    (True, {}, "expected a number, got a boolean (True)"),
    (0.0, {"sign": ">0"}, "expected a value > 0, got 0"),
    (-1.0, {"sign": ">=0"}, "expected a value >= 0, got -1"),
    (11.0, {"maximum": 10.0, "limit": "K.MAX"}, "expected -10 to 10 (K.MAX), got 11"),
])
def test_number_refusals_name_file_and_key(tmp_path, value, kwargs, part) -> None:
    r = _reader(tmp_path)
    with pytest.raises(TableError) as ei:
        r.number({"x": value}, "x", "sec", **kwargs)
    assert str(ei.value) == f"{r.file}: sec.x: {part}"
    assert (ei.value.file, ei.value.key) == (r.file, "sec.x")
    assert isinstance(ei.value, InputError)


def test_number_values_and_defaults(tmp_path) -> None:
    r = _reader(tmp_path)
    assert r.number({"x": 3}, "x", "") == 3.0 and isinstance(r.number({"x": 3}, "x", ""), float)
    assert r.number({}, "x", "", default=None) is None
    assert r.number({"x": -math.inf}, "x", "", allow_inf=True, maximum=5.0) == -math.inf
    with pytest.raises(TableError, match=r"t.toml: s.x: missing"):
        r.number({}, "x", "s")


def test_numbers_integer_string_table_keys(tmp_path) -> None:
    r = _reader(tmp_path)
    assert r.numbers({"v": [1, 2.5]}, "v", "", length=2) == [1.0, 2.5]
    assert r.numbers({}, "v", "", default=(0.0,)) == (0.0,)
    with pytest.raises(TableError, match=r": v: expected 3 numbers, got 2"):
        r.numbers({"v": [1, 2]}, "v", "", length=3)
    with pytest.raises(TableError, match=r": a.v\[1\]: expected a finite number"):
        r.numbers({"v": [1, math.nan]}, "v", "a")
    with pytest.raises(TableError, match=r": n: expected a whole number >= 1, got 0"):
        r.integer({"n": 0}, "n", "")
    with pytest.raises(TableError, match=r"unknown value 'q'; expected one of 'a', 'b'"):
        r.string({"s": "q"}, "s", "", choices=("a", "b"))
    with pytest.raises(TableError, match=r": t: expected a table \(\[t\]\), got an array"):
        r.table([1], "t")
    with pytest.raises(TableError, match=r": s.diameter: unknown key; did you mean "
                                         r"'s.diameter_mm'\?"):
        r.keys({"diameter": 1}, "s", ("diameter_mm",))
    with pytest.raises(TableError, match=r": s.length_mm: missing"):
        r.keys({}, "s", ("length_mm",))
    assert value_kind({}) == "a table" and value_kind(3) == "an integer (3)"


def test_load_and_path(tmp_path) -> None:
    r = _reader(tmp_path, 'a = 1\nf = "t.toml"\ng = "none.txt"\n')
    doc = r.load()
    assert doc["a"] == 1 and r.path(doc, "f", "") == (tmp_path / "t.toml").resolve()
    with pytest.raises(TableError, match="g: file not found"):
        r.path(doc, "g", "")
    with pytest.raises(TableError, match="not valid TOML"):
        _reader(tmp_path, "a = \n").load()
    (tmp_path / "u.toml").write_bytes(b'a = "\xff"\n')
    with pytest.raises(TableError, match="not valid TOML"):
        TableReader(tmp_path / "u.toml").load()
    with pytest.raises(TableError, match="widget file not found"):
        TableReader(tmp_path / "none.toml").load("widget file")
    with pytest.raises(TableError, match="cannot read"):
        TableReader(tmp_path).load()


def test_subclass_raises_its_error(tmp_path) -> None:
    class R(TableReader):
        error = MachineFileError

    with pytest.raises(MachineFileError, match="t.toml: k: missing"):
        R(tmp_path / "t.toml").number({}, "k", "")
