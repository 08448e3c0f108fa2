"""Q-parameter arithmetic of Heidenhain Klartext, as CAM output uses it.

Supported: numbers (dot or comma decimal), ``Q``/``QL``/``QR`` parameters,
``+ - * /`` and ``^`` with the usual precedence, parentheses, unary signs,
and the functions ``SIN COS TAN`` (degrees, as the TNC), ``SQRT ABS INT NEG``.
Anything else raises :class:`ExprError` naming the offending character and
what is supported; a parameter used before it is set is refused (the
control would take whatever an earlier program left in it).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping

from .errors import InputError

__all__ = ["ExprError", "evaluate", "SUPPORTED"]

SUPPORTED = ("numbers, Q/QL/QR parameters, + - * / ^, parentheses, "
             "SIN COS TAN (degrees), SQRT ABS INT NEG")

_TOKEN = re.compile(r"\s*(?:(\d+(?:[.,]\d*)?|[.,]\d+)|(Q[LR]?\d+)|(SIN|COS|TAN|SQRT|ABS|INT|NEG)"
                    r"|([-+*/^()]))")
_FUNCS = {
    "SIN": lambda v: math.sin(math.radians(v)),
    "COS": lambda v: math.cos(math.radians(v)),
    "TAN": lambda v: math.tan(math.radians(v)),
    "SQRT": math.sqrt,
    "ABS": abs,
    "INT": lambda v: float(math.trunc(v)),
    "NEG": lambda v: -v,
}


class ExprError(InputError):
    """A formula could not be evaluated; ``offset`` is the 0-based character."""

    def __init__(self, message: str, offset: int) -> None:
        self.offset = offset
        super().__init__(message)


def evaluate(text: str, params: Mapping[str, float]) -> float:
    """Value of a Klartext formula.

    Parameters
    ----------
    text : str
        The formula, e.g. ``"+Q1 * 2"`` or ``"(Q2 + 3,5) / 2"``.
    params : mapping of str to float
        Parameters set so far (``"Q1"``, ``"QL3"``...).

    Returns
    -------
    float

    Raises
    ------
    ExprError
        Unsupported character or function, unset parameter, division by zero,
        a result that is not finite.
    """
    toks: list[tuple[str, str, int]] = []
    pos = 0
    n = len(text)
    while pos < n:
        if text[pos:].strip() == "":
            break
        m = _TOKEN.match(text, pos)
        if not m:
            k = pos + len(text[pos:]) - len(text[pos:].lstrip())
            raise ExprError(f"unexpected {text[k:].split()[0][:12]!r} in a formula; "
                            f"supported: {SUPPORTED}", k)
        kind = ("num" if m.group(1) else "q" if m.group(2) else "fn" if m.group(3) else "op")
        toks.append((kind, m.group(m.lastindex), m.start(m.lastindex)))
        pos = m.end()
    parser = _Parser(toks, params, len(text))
    value = parser.expr()
    if parser.i != len(toks):
        raise ExprError(f"unexpected {toks[parser.i][1]!r} in a formula", toks[parser.i][2])
    if not math.isfinite(value):
        raise ExprError("formula gives a value that is not finite", 0)
    return value


class _Parser:
    def __init__(self, toks, params, end) -> None:
        self.toks, self.params, self.i, self.end = toks, params, 0, end

    def _peek(self):
        return self.toks[self.i] if self.i < len(self.toks) else None

    def expr(self) -> float:
        v = self.term()
        while (t := self._peek()) and t[1] in "+-" and t[0] == "op":
            self.i += 1
            r = self.term()
            v = v + r if t[1] == "+" else v - r
        return v

    def term(self) -> float:
        v = self.power()
        while (t := self._peek()) and t[0] == "op" and t[1] in "*/":
            self.i += 1
            r = self.power()
            if t[1] == "/":
                if r == 0:
                    raise ExprError("division by zero in a formula", t[2])
                v = v / r
            else:
                v = v * r
        return v

    def power(self) -> float:
        v = self.unary()
        t = self._peek()
        if t and t[0] == "op" and t[1] == "^":
            self.i += 1
            e = self.power()
            try:
                v = float(v ** e)
            except (OverflowError, ZeroDivisionError, TypeError):
                raise ExprError("power out of range in a formula", t[2]) from None
            if isinstance(v, complex):
                raise ExprError("power of a negative number in a formula", t[2])
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
            raise ExprError("formula ends early; expected a number or a parameter", self.end)
        kind, s, off = t
        self.i += 1
        if kind == "num":
            return float(s.replace(",", "."))
        if kind == "q":
            if s not in self.params:
                raise ExprError(f"{s} is used before it is set in this program", off)
            return self.params[s]
        if kind == "fn":
            arg = self.unary()
            try:
                return float(_FUNCS[s](arg))
            except ValueError:
                raise ExprError(f"{s} of {arg:g} is not defined", off) from None
        if s == "(":
            v = self.expr()
            c = self._peek()
            if c is None or c[1] != ")":
                raise ExprError("'(' not closed; expected ')'", off)
            self.i += 1
            return v
        raise ExprError(f"unexpected {s!r} in a formula; expected a number or a parameter", off)
