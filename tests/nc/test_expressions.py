"""nc.expressions: known values (LinuxCNC's checked with rs274), and Python's arithmetic."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nc.expressions import FANUC, LINUXCNC, ExprError, compile_expression, evaluate


class Store:
    def __init__(self, values=None):
        self.values = dict(values or {})

    def read(self, key, offset):
        if isinstance(key, str) and key not in self.values:
            raise ExprError(f"#<{key}> is not defined", offset)
        return self.values.get(key, 0.0)

    def exists(self, key):
        return key in self.values


class Vacant(Store):
    def read(self, key, offset):
        return self.values.get(key)


# (expression, value); the LinuxCNC rows were run through rs274 (G0 X[...])
LINUXCNC_TABLE = [
    ("1+2*3**2", 19.0), ("1 LT 2 + 3", 1.0), ("-#1", -2.0), ("FIX[-1.5]", -2.0),
    ("FUP[-1.5]", -1.0), ("ROUND[2.5]", 3.0), ("ROUND[-2.5]", -3.0), ("7 MOD 3", 1.0),
    ("-7 MOD 3", 2.0), ("7 MOD -3", 1.0), ("1 OR 0 AND 0", 0.0), ("#3", 0.0),
    ("ATAN[1]/[1]", 45.0), ("2 XOR 3", 0.0), ("-2**2", 4.0), ("1 EQ 1 + 1", 0.0),
    ("1 EQ 1.00001", 1.0), ("1 GE 1.00001", 0.0), ("1 LT 1.00001", 1.0),
    ("-[1+2]", -3.0), ("#<_a> * 2", 3.0), ("EXISTS[#<_a>]", 1.0), ("EXISTS[#<nope>]", 0.0),
    ("##1", 3.0), ("2**3**2", 64.0), ("#[1+1]", 3.0), ("SQRT[16] + ABS[-2]", 6.0), ("SIN[30]", 0.5),
]


@pytest.mark.parametrize("text,value", LINUXCNC_TABLE)
def test_linuxcnc_known_values(text, value):
    store = Store({1: 2.0, 2: 3.0, "_a": 1.5})
    assert evaluate(text, LINUXCNC, store) == pytest.approx(value, abs=1e-12)


FANUC_TABLE = [
    ("FIX[-1.2]", -1.0), ("FUP[-1.2]", -2.0), ("FUP[1.2]", 2.0), ("ATAN[-1]/[-1]", 225.0),
    ("#1 + #2 * 2", 8.0), ("[#1 + #2] * 2", 10.0), ("5 AND 3", 1.0), ("5 OR 3", 7.0),
    ("#10 EQ #0", 1.0), ("#10 EQ 0", 0.0), ("#10 + 1", 1.0), ("-7 MOD 3", -1.0),
    ("#1 GT 1", 1.0), ("ROUND[-0.5]", -1.0),
    # the 30i table's other functions: ATAN[a,b] = ATAN[a]/[b]; ATAN[x] = ATAN[x]/[1]
    ("ATAN[-1,-1]", 225.0), ("ATAN[1,0]", 90.0), ("ATAN[1]", 45.0), ("ATAN[-1]", 315.0),
    ("[ATAN[1]]/2", 22.5), ("ATAN[#1,#2] + 1", math.degrees(math.atan2(2, 3)) + 1),
    ("POW[2,10]", 1024.0), ("POW[#1,0.5]", math.sqrt(2)), ("POW[-2,3]", -8.0),
    ("BCD[12]", 18.0), ("BCD[99999999]", float(0x99999999)), ("BIN[18]", 12.0),
    ("BIN[BCD[4095]]", 4095.0), ("BCD[0]", 0.0),
]


@pytest.mark.parametrize("text,value", FANUC_TABLE)
def test_fanuc_known_values(text, value):
    assert evaluate(text, FANUC, Vacant({1: 2.0, 2: 3.0})) == pytest.approx(value)


@pytest.mark.parametrize("text,grammar,offset,words", [
    ("1/0", LINUXCNC, 1, "division by zero"),
    ("SQRT[-1]", LINUXCNC, 0, "SQRT of -1"),
    ("2**", LINUXCNC, 3, "ends early"),
    ("[1+2", LINUXCNC, 4, "expected ']'"),
    ("FOO[1]", FANUC, 0, "supported: numbers"),
    ("1 ** 2", FANUC, 2, "unexpected"),
    ("#<x>", FANUC, 0, "after '#'"),
    ("#1.5", LINUXCNC, 1, "whole number"),
    ("#<nope>", LINUXCNC, 0, "not defined"),
    ("ATAN[1]", LINUXCNC, 7, "expected '/'"),
    ("ATAN[1]/2", FANUC, 8, "expected '['"),
    ("1+POW[-8,0.5]", FANUC, 2, "POW of -8, 0.5 is not defined"),
    ("POW[0,-1]", FANUC, 0, "POW of 0, -1"),
    ("POW[2]", FANUC, 5, "expected ','"),
    ("BCD[1.5]", FANUC, 0, "BCD of 1.5"),
    ("BCD[-1]", FANUC, 0, "BCD of -1"),
    ("BCD[100000000]", FANUC, 0, "BCD of 1e.08"),
    ("BIN[10]", FANUC, 0, "BIN of 10"),
    ("2*ADP[#1]", FANUC, 2, "ADP .add a decimal point"),
])
def test_errors_name_the_place(text, grammar, offset, words):
    with pytest.raises(ExprError, match=words.replace("[", r"\[").replace("*", r"\*")) as exc:
        evaluate(text, grammar, Store())
    assert exc.value.offset == offset


def test_one_value_after_a_letter_stops_at_the_next_word():
    node, end = compile_expression("X-#1Y2", LINUXCNC, 1, whole=False)
    assert node(Store({1: 4.0})) == -4.0 and end == 4


# property: the evaluator agrees with Python on + - * / and brackets
_ops = st.sampled_from(["+", "-", "*", "/"])


@st.composite
def _expressions(draw, depth=0):
    if depth > 3 or draw(st.booleans()):
        v = draw(st.integers(0, 999)) / draw(st.sampled_from([1, 4, 10]))
        return repr(v), v
    (ta, a), (tb, b) = draw(_expressions(depth + 1)), draw(_expressions(depth + 1))
    op = draw(_ops)
    if op == "/" and b == 0:
        op = "+"
    v = {"+": a + b, "-": a - b, "*": a * b, "/": a / b if b else 0.0}[op]
    return f"[{ta} {op} {tb}]", v


@settings(max_examples=300, deadline=None, derandomize=True)
@given(_expressions())
def test_bracketed_arithmetic_matches_python(case):
    text, value = case
    for grammar in (LINUXCNC, FANUC):
        got = evaluate(text, grammar, Store())
        assert got == value or math.isclose(got, value, rel_tol=1e-12, abs_tol=1e-12)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.lists(st.integers(-50, 50), min_size=2, max_size=6),
       st.lists(st.sampled_from(["+", "-", "*"]), min_size=5, max_size=5))
def test_precedence_matches_python(nums, ops):
    text = str(nums[0])
    for n, op in zip(nums[1:], ops):
        text += f" {op} {n}" if n >= 0 else f" {op} [{n}]"
    for grammar in (LINUXCNC, FANUC):
        assert evaluate(text, grammar, Store()) == eval(text.replace("[", "(").replace("]", ")"))
