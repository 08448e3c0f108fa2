"""Arithmetic of Siemens Sinumerik programs, as CAM output and shop programs use it.

Supported: numbers, ``R`` parameters (``R1``), variables defined with ``DEF
REAL|INT``, ``+ - * /``, ``DIV`` (integer division), ``MOD``, parentheses,
unary signs, and the functions ``SIN COS TAN ASIN ACOS ATAN2`` (degrees, as
the 840D), ``SQRT ABS POT`` (square), ``TRUNC ROUND EXP LN``, ``MINVAL
MAXVAL``; conditions (:func:`condition`, for ``IF WHILE UNTIL``) compare with
``== <> < > <= >=`` and join with ``AND OR XOR NOT``. Anything else raises
:class:`ExprError` naming what was found and what is supported; a parameter
used before it is set is refused (the control would take whatever an earlier
program left in it). Each text is parsed once into a function of the
parameters and kept (a loop evaluates the same texts again): syntax errors
are raised when it is parsed, the others (unset parameter, division by zero,
a function outside its domain) when it is evaluated.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping
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
    return bool(_compiled(text, True)(params))


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
    value = _compiled(text, False)(params)
    if not math.isfinite(value):
        raise ExprError("expression gives a value that is not finite", 0)
    return value


@lru_cache(maxsize=4096)
def _compiled(text: str, logic: bool) -> Callable[[Mapping[str, float]], float]:
    """``text`` made once into a function of the parameters (kept: a loop evaluates
    the same texts again); syntax errors are raised here, the others when run."""
    toks = _tokens(text)
    parser = _Parser(toks, len(text))
    fn = parser.logic() if logic else parser.expr()
    if parser.i != len(toks):
        t = toks[parser.i]
        raise ExprError(f"unexpected {t[1]!r} in {'a condition' if logic else 'an expression'}",
                        t[2])
    return fn


def _const(v: float) -> Callable:
    return lambda p: v


def _name(s: str, off: int) -> Callable:
    def get(p):
        try:
            return p[s]
        except KeyError:
            if re.fullmatch(r"R\d+", s):
                raise ExprError(f"{s} is used before it is set in this program", off) from None
            raise ExprError(f"unknown name {s[:20]} in an expression (not an R parameter or "
                            f"a DEF variable); supported: {SUPPORTED}", off) from None
    return get


def _logic_op(op: str, a: Callable, b: Callable) -> Callable:
    if op == "AND":
        return lambda p: float((a(p) != 0) & (b(p) != 0))
    if op == "OR":
        return lambda p: float((a(p) != 0) | (b(p) != 0))
    return lambda p: float((a(p) != 0) != (b(p) != 0))


def _arith(op: str, a: Callable, b: Callable, off: int) -> Callable:
    if op == "+":
        return lambda p: a(p) + b(p)
    if op == "-":
        return lambda p: a(p) - b(p)
    if op == "*":
        return lambda p: a(p) * b(p)

    def div(p):
        x, y = a(p), b(p)
        if y == 0:
            raise ExprError(f"division by zero ({op}) in an expression", off)
        if op == "/":
            return x / y
        if op == "DIV":
            return float(math.trunc(x / y))
        return math.fmod(x, y)
    return div


def _call(s: str, args: list[Callable], off: int) -> Callable:
    fn = _FUNCS1.get(s) or _FUNCS2[s]

    def call(p):
        vals = [f(p) for f in args]
        try:
            return float(fn(*vals))
        except (ValueError, OverflowError):
            raise ExprError(f"{s} of {', '.join(f'{a:g}' for a in vals)} is not defined",
                            off) from None
    return call


class _Parser:
    """Recursive descent over the tokens, making one closure per node."""

    def __init__(self, toks, end) -> None:
        self.toks, self.i, self.end = toks, 0, end

    def _peek(self):
        return self.toks[self.i] if self.i < len(self.toks) else None

    def _expect(self, ch: str) -> None:
        t = self._peek()
        if t is None or t[1] != ch:
            raise ExprError(f"expected {ch!r} in an expression", t[2] if t else self.end)
        self.i += 1

    def logic(self) -> Callable:
        v = self.compare()
        while (t := self._peek()) and t[0] == "name" and t[1] in ("AND", "OR", "XOR"):
            self.i += 1
            v = _logic_op(t[1], v, self.compare())
        return v

    def compare(self) -> Callable:
        t = self._peek()
        if t and t[0] == "name" and t[1] == "NOT":
            self.i += 1
            inner = self.compare()
            return lambda p: float(inner(p) == 0)
        v = self.expr()
        t = self._peek()
        if t and t[0] == "op" and t[1] in _COMPARE:
            self.i += 1
            cmp, r = _COMPARE[t[1]], self.expr()
            return lambda p: float(cmp(v(p), r(p)))
        return v

    def expr(self) -> Callable:
        v = self.term()
        while (t := self._peek()) and t[0] == "op" and t[1] in "+-":
            self.i += 1
            v = _arith(t[1], v, self.term(), t[2])
        return v

    def term(self) -> Callable:
        v = self.unary()
        while (t := self._peek()) and ((t[0] == "op" and t[1] in "*/")
                                       or (t[0] == "name" and t[1] in ("DIV", "MOD"))):
            self.i += 1
            v = _arith(t[1], v, self.unary(), t[2])
        return v

    def unary(self) -> Callable:
        t = self._peek()
        if t and t[0] == "op" and t[1] in "+-":
            self.i += 1
            v = self.unary()
            return (lambda p: -v(p)) if t[1] == "-" else v
        return self.atom()

    def atom(self) -> Callable:
        t = self._peek()
        if t is None:
            raise ExprError("expression ends early; expected a number or a parameter",
                            self.end)
        kind, s, off = t
        self.i += 1
        if kind == "num":
            return _const(float(s.replace("EX", "E")))
        if kind == "name":
            if s in _FUNCS1 or s in _FUNCS2:
                self._expect("(")
                args = [self.expr()]
                while (c := self._peek()) and c[1] == ",":
                    self.i += 1
                    args.append(self.expr())
                self._expect(")")
                want = 1 if s in _FUNCS1 else 2
                if len(args) != want:
                    raise ExprError(f"{s} takes {want} argument(s), got {len(args)}", off)
                return _call(s, args, off)
            return _name(s, off)
        if s == "(":
            v = self.logic()
            c = self._peek()
            if c is None or c[1] != ")":
                raise ExprError("'(' not closed; expected ')'", off)
            self.i += 1
            return v
        raise ExprError(f"unexpected {s!r} in an expression; expected a number or a "
                        "parameter", off)
