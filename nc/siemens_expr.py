"""Arithmetic of Siemens Sinumerik programs, as CAM output and shop programs use it.

Supported: numbers, ``R`` parameters (``R1``), variables defined with ``DEF
REAL|INT``, ``+ - * /``, ``DIV`` (integer division), ``MOD``, parentheses,
unary signs, and the functions ``SIN COS TAN ASIN ACOS ATAN2`` (degrees, as
the 840D), ``SQRT ABS POT`` (square), ``TRUNC ROUND EXP LN``, ``MINVAL
MAXVAL``; conditions (:func:`condition`, for ``IF``) compare with ``== <> < > <=
>=`` and join with ``AND OR XOR NOT``. Anything else raises :class:`ExprError` naming what was found and
what is supported; a parameter used before it is set is refused (the control
would take whatever an earlier program left in it).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from functools import lru_cache

from .errors import InputError

__all__ = ["ExprError", "evaluate", "condition", "SUPPORTED"]

SUPPORTED = ("numbers, R parameters, DEF variables, + - * / DIV MOD, parentheses, "
             "SIN COS TAN ASIN ACOS ATAN2 (degrees), SQRT ABS POT TRUNC ROUND EXP LN "
             "MINVAL MAXVAL; in IF conditions == <> < > <= >= AND OR XOR NOT")

_TOKEN = re.compile(r"\s*(?:(\d+\.?\d*(?:EX[+-]?\d+)?|\.\d+(?:EX[+-]?\d+)?)"
                    r"|([A-Z_][A-Z0-9_]*)|(\$[A-Z0-9_]+)|(==|<>|<=|>=|[-+*/(),<>])|(\S))")
_COMPARE = {"==": lambda a, b: a == b, "<>": lambda a, b: a != b, "<": lambda a, b: a < b,
            ">": lambda a, b: a > b, "<=": lambda a, b: a <= b, ">=": lambda a, b: a >= b}


def _round(v: float) -> float:
    """Half away from zero, as the 840D's ROUND."""
    return float(math.floor(abs(v) + 0.5)) * (1.0 if v >= 0 else -1.0)


_FUNCS1 = {
    "SIN": lambda v: math.sin(math.radians(v)),
    "COS": lambda v: math.cos(math.radians(v)),
    "TAN": lambda v: math.tan(math.radians(v)),
    "ASIN": lambda v: math.degrees(math.asin(v)),
    "ACOS": lambda v: math.degrees(math.acos(v)),
    "SQRT": math.sqrt,
    "ABS": abs,
    "POT": lambda v: v * v,
    "TRUNC": lambda v: float(math.trunc(v)),
    "ROUND": _round,
    "EXP": math.exp,
    "LN": math.log,
}
_FUNCS2 = {
    "ATAN2": lambda y, x: math.degrees(math.atan2(y, x)),
    "MINVAL": min,
    "MAXVAL": max,
}


class ExprError(InputError):
    """An expression could not be evaluated; ``offset`` is the 0-based character."""

    def __init__(self, message: str, offset: int) -> None:
        self.offset = offset
        super().__init__(message)


def condition(text: str, params: Mapping[str, float]) -> bool:
    """Truth of a condition: comparisons ``== <> < > <= >=`` of expressions joined by
    ``AND OR XOR`` and ``NOT``, parentheses (an expression alone: true when not 0).

    Raises
    ------
    ExprError
        As :func:`evaluate`.
    """
    parser = _Parser(_tokens(text), params, len(text))
    value = parser.logic()
    if parser.i != len(parser.toks):
        t = parser.toks[parser.i]
        raise ExprError(f"unexpected {t[1]!r} in a condition", t[2])
    return bool(value)


@lru_cache(maxsize=4096)
def _tokens(text: str) -> tuple[tuple[str, str, int], ...]:
    """The tokens of ``text`` (kept: a loop evaluates the same texts again)."""
    toks: list[tuple[str, str, int]] = []
    pos = 0
    n = len(text)
    while pos < n:
        m = _TOKEN.match(text, pos)
        if m is None:  # only trailing blanks are left
            break
        k = m.lastindex
        s = m.group(k)
        if k == 3:
            raise ExprError(f"system variable {s[:20]} is not read (its value is the "
                            f"control's); supported: {SUPPORTED}", m.start(k))
        if k == 5:
            raise ExprError(f"unexpected {text[m.start(k):].split()[0][:12]!r} in an "
                            f"expression; supported: {SUPPORTED}", m.start(k))
        toks.append((("num", "name", "", "op")[k - 1], s, m.start(k)))
        pos = m.end()
    return tuple(toks)


def evaluate(text: str, params: Mapping[str, float]) -> float:
    """Value of a Sinumerik arithmetic expression.

    Parameters
    ----------
    text : str
        The expression, upper case, e.g. ``"R1*2+SIN(30)"``.
    params : mapping of str to float
        Parameters and variables set so far (``"R1"``, ``"DEPTH"``...).

    Returns
    -------
    float

    Raises
    ------
    ExprError
        Unsupported token or function, unset parameter, division by zero,
        a result that is not finite.
    """
    toks = _tokens(text)
    parser = _Parser(toks, params, len(text))
    value = parser.expr()
    if parser.i != len(toks):
        t = toks[parser.i]
        raise ExprError(f"unexpected {t[1]!r} in an expression", t[2])
    if not math.isfinite(value):
        raise ExprError("expression gives a value that is not finite", 0)
    return value


class _Parser:
    def __init__(self, toks, params, end) -> None:
        self.toks, self.params, self.i, self.end = toks, params, 0, end

    def _peek(self):
        return self.toks[self.i] if self.i < len(self.toks) else None

    def _expect(self, ch: str, off: int) -> None:
        t = self._peek()
        if t is None or t[1] != ch:
            raise ExprError(f"expected {ch!r} in an expression", t[2] if t else self.end)
        self.i += 1

    def logic(self) -> float:
        v = self.compare()
        while (t := self._peek()) and t[0] == "name" and t[1] in ("AND", "OR", "XOR"):
            self.i += 1
            r = self.compare()
            a, b = v != 0, r != 0
            v = float(a and b if t[1] == "AND" else a or b if t[1] == "OR" else a != b)
        return v

    def compare(self) -> float:
        t = self._peek()
        if t and t[0] == "name" and t[1] == "NOT":
            self.i += 1
            return float(self.compare() == 0)
        v = self.expr()
        t = self._peek()
        if t and t[0] == "op" and t[1] in _COMPARE:
            self.i += 1
            return float(_COMPARE[t[1]](v, self.expr()))
        return v

    def expr(self) -> float:
        v = self.term()
        while (t := self._peek()) and t[0] == "op" and t[1] in "+-":
            self.i += 1
            r = self.term()
            v = v + r if t[1] == "+" else v - r
        return v

    def term(self) -> float:
        v = self.unary()
        while (t := self._peek()) and ((t[0] == "op" and t[1] in "*/")
                                       or (t[0] == "name" and t[1] in ("DIV", "MOD"))):
            self.i += 1
            r = self.unary()
            if t[1] == "*":
                v = v * r
                continue
            if r == 0:
                raise ExprError(f"division by zero ({t[1]}) in an expression", t[2])
            if t[1] == "/":
                v = v / r
            elif t[1] == "DIV":
                v = float(math.trunc(v / r))
            else:
                v = math.fmod(v, r)
        return v

    def unary(self) -> float:
        t = self._peek()
        if t and t[0] == "op" and t[1] in "+-":
            self.i += 1
            v = self.unary()
            return -v if t[1] == "-" else v
        return self.atom()

    def atom(self) -> float:
        t = self._peek()
        if t is None:
            raise ExprError("expression ends early; expected a number or a parameter",
                            self.end)
        kind, s, off = t
        self.i += 1
        if kind == "num":
            return float(s.replace("EX", "E"))
        if kind == "name":
            if s in _FUNCS1 or s in _FUNCS2:
                self._expect("(", off)
                args = [self.expr()]
                while (c := self._peek()) and c[1] == ",":
                    self.i += 1
                    args.append(self.expr())
                self._expect(")", off)
                want = 1 if s in _FUNCS1 else 2
                if len(args) != want:
                    raise ExprError(f"{s} takes {want} argument(s), got {len(args)}", off)
                try:
                    return float(_FUNCS1[s](*args) if want == 1 else _FUNCS2[s](*args))
                except (ValueError, OverflowError):
                    raise ExprError(f"{s} of {', '.join(f'{a:g}' for a in args)} is not "
                                    "defined", off) from None
            if s not in self.params:
                if re.fullmatch(r"R\d+", s):
                    raise ExprError(f"{s} is used before it is set in this program", off)
                raise ExprError(f"unknown name {s[:20]} in an expression (not an R "
                                f"parameter or a DEF variable); supported: {SUPPORTED}", off)
            return self.params[s]
        if s == "(":
            v = self.logic()
            c = self._peek()
            if c is None or c[1] != ")":
                raise ExprError("'(' not closed; expected ')'", off)
            self.i += 1
            return v
        raise ExprError(f"unexpected {s!r} in an expression; expected a number or a "
                        "parameter", off)
