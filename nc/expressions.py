"""Parameter arithmetic of LinuxCNC and Fanuc macro B: one evaluator, two grammars.

An expression is compiled once into a tree of closures (a loop body is
evaluated many times) and evaluated against a parameter store, an object
with ``read(key, offset) -> float | None`` (``key`` an int for ``#12``, a
lower-case str for LinuxCNC's ``#<name>``; None is Fanuc's vacant value).

Supported, both dialects: numbers, ``#n``, ``#[expr]``, ``##n``, brackets
``[ ]``, ``+ - * / MOD``, comparisons ``EQ NE GT GE LT LE`` (1 or 0), ``AND OR
XOR``, unary signs, and the functions ``SIN COS TAN ASIN ACOS`` (degrees),
``ATAN[a]/[b]``, ``SQRT ABS EXP LN ROUND FIX FUP``. LinuxCNC adds ``**``,
``#<name>`` and ``EXISTS[#<name>]``. Fanuc macro B adds (Series 30i custom macro
table) ``ATAN[a,b]`` (the same as ``ATAN[a]/[b]``), the one-argument ``ATAN[x]``,
``POW[a,b]`` (a to the power b), ``BCD[x]`` (binary to BCD: 12 -> 0x12 = 18) and
``BIN[x]`` (BCD to binary: 18 -> 12), both on whole numbers 0...99999999 only
(the BCD digits of a 32-bit signal); other values are refused, as the control's
treatment of them is not known here. ``ADP`` (add a decimal point to a G65
argument written without one) depends on how the argument was written, which
the store does not keep: it is refused by name.

Fanuc's arc tangent range is set by parameter 6004#0 (NAT): 0 (the default)
gives 0...360 deg, 1 gives -180...180 deg; this reader takes the default.
The one-argument ``ATAN[x]`` is read as ``ATAN[x]/[1]``, so with the default
a negative x gives 270...360 deg. Whether the control gives -90...0 there
instead was not found in the sources at hand; the two differ by exactly 360
deg, so the same angle reaches SIN/COS and every rotation (only a comparison
or a linear use of the angle itself would tell them apart). After
``ATAN[a]`` a ``/`` always starts the two-argument form (``/[b]``); to divide
the one-argument result, bracket it: ``[ATAN[a]]/2``.

Where the dialects differ, each follows its control (checked against
LinuxCNC's ``rs274`` for LinuxCNC):

========================  ==========================  ==========================
what                      LinuxCNC                    Fanuc macro B
========================  ==========================  ==========================
precedence (low to high)  AND OR XOR; EQ...; + -;      EQ...; + - OR XOR;
                          * / MOD; **                 * / AND MOD
AND OR XOR                logical (0 or 1)            bitwise on whole numbers
EQ / NE                   within 0.0001               exact; vacant only EQ vacant
FIX / FUP of -1.5         -2 / -1 (floor / ceil)      -1 / -2 (toward / away from 0)
ATAN[a]/[b]               -180...180 deg              0...360 deg (NAT=0)
ATAN[x], ATAN[a,b], POW   refused                     read (see above)
a MOD b                   fmod, made >= 0             fmod (sign of a)
========================  ==========================  ==========================

ROUND rounds halves away from zero in both. Anything else raises
:class:`ExprError` with the 0-based character offset and what is supported.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field

from .constants import MACRO_EQ_TOL
from .errors import InputError

__all__ = ["ExprError", "Grammar", "LINUXCNC", "FANUC", "compile_expression", "evaluate"]

Node = Callable[[object], "float | None"]


class ExprError(InputError):
    """An expression could not be read or evaluated; ``offset`` is the 0-based character."""

    def __init__(self, message: str, offset: int) -> None:
        self.offset = offset
        super().__init__(message)


def _num(v: float | None) -> float:
    return 0.0 if v is None else v


def _lmod(a: float, b: float) -> float:
    r = math.fmod(a, b)
    return r + abs(b) if r < 0 else r


def _bits(f: Callable[[int, int], int]) -> Callable[[float, float], float]:
    return lambda a, b: float(f(int(a), int(b)))


def _bcd(v: float) -> float:
    """Binary -> BCD: the decimal digits of a whole 0...99999999 as hexadecimal digits."""
    if v != int(v) or not 0 <= v <= 99_999_999:
        raise ValueError(v)
    return float(int(str(int(v)), 16))


def _bin(v: float) -> float:
    """BCD -> binary: hexadecimal digits 0-9 read as decimal digits (inverse of :func:`_bcd`)."""
    if v != int(v) or not 0 <= v <= 0x99999999:
        raise ValueError(v)
    digits = f"{int(v):x}"
    if any(c not in "0123456789" for c in digits):
        raise ValueError(v)
    return float(int(digits))


def _round(v: float) -> float:
    return float(math.floor(abs(v) + 0.5)) * (1.0 if v >= 0 else -1.0)


_COMMON_FUNCS: dict[str, Callable[[float], float]] = {
    "SIN": lambda v: math.sin(math.radians(v)),
    "COS": lambda v: math.cos(math.radians(v)),
    "TAN": lambda v: math.tan(math.radians(v)),
    "ASIN": lambda v: math.degrees(math.asin(v)),
    "ACOS": lambda v: math.degrees(math.acos(v)),
    "SQRT": math.sqrt,
    "ABS": abs,
    "EXP": math.exp,
    "LN": math.log,
    "ROUND": _round,
}


@dataclass(frozen=True)
class Grammar:
    """One dialect's operators and functions (see the module's table)."""

    name: str
    levels: tuple[tuple[str, ...], ...]          # binary operators, lowest first
    ops: dict[str, Callable[[float, float], float]]
    functions: dict[str, Callable[[float], float]]
    atan: Callable[[float, float], float]
    vacant: bool                                  # Fanuc: None is a value of its own
    named: bool                                   # LinuxCNC's #<name> and EXISTS
    supported: str
    #: two-argument functions ``NAME[a,b]`` (Fanuc's POW)
    pairs: dict[str, Callable[[float, float], float]] = field(default_factory=dict)
    #: Fanuc's one-argument ATAN[x] and ATAN[a,b] are read
    atan_forms: bool = False
    #: functions refused by name: name -> why
    refused: dict[str, str] = field(default_factory=dict)


def _cmp(tol: float) -> dict[str, Callable[[float, float], float]]:
    return {
        "EQ": lambda a, b: float(abs(a - b) < tol) if tol else float(a == b),
        "NE": lambda a, b: float(not abs(a - b) < tol) if tol else float(a != b),
        "GT": lambda a, b: float(a > b), "GE": lambda a, b: float(a >= b),
        "LT": lambda a, b: float(a < b), "LE": lambda a, b: float(a <= b),
    }


_ARITH = {"+": lambda a, b: a + b, "-": lambda a, b: a - b, "*": lambda a, b: a * b,
          "/": lambda a, b: a / b}

LINUXCNC = Grammar(
    name="LinuxCNC",
    levels=(("AND", "OR", "XOR"), ("EQ", "NE", "GT", "GE", "LT", "LE"), ("+", "-"),
            ("*", "/", "MOD"), ("**",)),
    ops={**_ARITH, **_cmp(MACRO_EQ_TOL), "MOD": _lmod, "**": lambda a, b: a ** b,
         "AND": lambda a, b: float(a != 0 and b != 0),
         "OR": lambda a, b: float(a != 0 or b != 0),
         "XOR": lambda a, b: float((a != 0) != (b != 0))},
    functions={**_COMMON_FUNCS, "FIX": lambda v: float(math.floor(v)),
               "FUP": lambda v: float(math.ceil(v))},
    atan=lambda a, b: math.degrees(math.atan2(a, b)),
    vacant=False, named=True,
    supported=("numbers, #n, #<name>, [ ], + - * / MOD **, EQ NE GT GE LT LE, AND OR XOR, "
               "SIN COS TAN ASIN ACOS ATAN[a]/[b] SQRT ABS EXP LN ROUND FIX FUP EXISTS"))

FANUC = Grammar(
    name="Fanuc macro B",
    levels=(("EQ", "NE", "GT", "GE", "LT", "LE"), ("+", "-", "OR", "XOR"),
            ("*", "/", "AND", "MOD")),
    ops={**_ARITH, **_cmp(0.0), "MOD": math.fmod,
         "AND": _bits(lambda a, b: a & b), "OR": _bits(lambda a, b: a | b),
         "XOR": _bits(lambda a, b: a ^ b)},
    functions={**_COMMON_FUNCS, "FIX": lambda v: float(math.trunc(v)),
               "FUP": lambda v: float(math.trunc(v) + (v > math.trunc(v)) - (v < math.trunc(v))),
               "BCD": _bcd, "BIN": _bin},
    atan=lambda a, b: math.degrees(math.atan2(a, b)) % 360.0,
    vacant=True, named=False,
    supported=("numbers, #n, [ ], + - * / MOD, EQ NE GT GE LT LE, AND OR XOR, "
               "SIN COS TAN ASIN ACOS ATAN[a]/[b] ATAN[a,b] ATAN[x] POW[a,b] SQRT ABS EXP "
               "LN ROUND FIX FUP BIN BCD"),
    pairs={"POW": lambda a, b: a ** b},
    atan_forms=True,
    refused={"ADP": "ADP (add a decimal point to a G65 argument) depends on how the "
                    "argument was written, which this reader does not keep; expected the "
                    "argument written with a decimal point and no ADP"})

_TOKEN = re.compile(r"\s*(?:(\d+\.?\d*|\.\d+)|(<[^<>]*>)|([A-Z]+)|(\*\*|[-+*/\[\]#,=]))")


def compile_expression(text: str, grammar: Grammar, start: int = 0,
                       whole: bool = True) -> tuple[Node, int]:
    """Compile the expression at ``text[start:]`` (upper case).

    Parameters
    ----------
    text : str
        The line or expression.
    grammar : Grammar
        :data:`LINUXCNC` or :data:`FANUC`.
    start : int
        0-based offset where the expression begins.
    whole : bool
        Read a full expression (True) or one value: a number, a parameter,
        a bracketed expression, a function call, maybe signed (False, as
        after a word's letter).

    Returns
    -------
    (node, end)
        ``node(store)`` gives the value; ``end`` is the offset after it.
    """
    p = _Parser(text, grammar, start)
    node = p.expr(0) if whole else p.unary()
    return node, p.pos


def evaluate(text: str, grammar: Grammar, store: object) -> float | None:
    """Value of a whole expression ``text`` against ``store`` (see the module)."""
    node, end = compile_expression(text.upper(), grammar)
    if text[end:].strip():
        raise ExprError(f"unexpected {text[end:].split()[0][:12]!r} in an expression; "
                        f"supported: {grammar.supported}", end + len(text[end:]) -
                        len(text[end:].lstrip()))
    return node(store)


def _checked(f, what: str, off: int):
    def run(*args):
        try:
            v = f(*args)
        except (ValueError, OverflowError, ZeroDivisionError, TypeError):
            v = math.nan
        if isinstance(v, complex) or not math.isfinite(v):
            shown = ", ".join(f"{a:g}" for a in args)
            raise ExprError(f"{what} of {shown} is not defined or out of range", off)
        return v
    return run


class _Parser:
    def __init__(self, text: str, g: Grammar, pos: int) -> None:
        self.s, self.g, self.pos = text, g, pos
        self.ops = {op: k for k, lvl in enumerate(g.levels) for op in lvl}

    def peek(self):
        m = _TOKEN.match(self.s, self.pos)
        if m is None:
            return None, "", self.pos
        return m.lastindex, m.group(m.lastindex), m.start(m.lastindex), m.end()

    def take(self):
        t = self.peek()
        if t[0] is None:
            rest = self.s[self.pos:].strip()
            if not rest:
                raise ExprError("expression ends early; expected a number, a parameter "
                                "or '['", len(self.s))
            raise ExprError(f"unexpected {rest[:12]!r} in an expression; supported: "
                            f"{self.g.supported}", self.s.index(rest[0], self.pos))
        self.pos = t[3]
        return t

    def expect(self, sym: str) -> None:
        t = self.peek()
        if t[0] is None or t[1] != sym:
            raise ExprError(f"expected {sym!r} in an expression", t[2] if t[0] else self.pos)
        self.pos = t[3]

    def expr(self, level: int) -> Node:
        if level == len(self.g.levels):
            return self.unary()
        left = self.expr(level + 1)
        while True:
            t = self.peek()
            if t[0] is None or self.ops.get(t[1]) != level:
                return left
            self.pos = t[3]
            right = self.expr(level + 1)
            left = self._binary(t[1], t[2], left, right)

    def _binary(self, op: str, off: int, a: Node, b: Node) -> Node:
        f = _checked(self.g.ops[op], op, off)
        if op == "/":
            def div(st, a=a, b=b):
                d = _num(b(st))
                if d == 0:
                    raise ExprError("division by zero in an expression", off)
                return f(_num(a(st)), d)
            return div
        if self.g.vacant and op in ("EQ", "NE"):
            def eqv(st, a=a, b=b, ne=op == "NE"):
                x, y = a(st), b(st)
                same = (x is None and y is None) or (
                    x is not None and y is not None and x == y)
                return float(same != ne)
            return eqv
        return lambda st: f(_num(a(st)), _num(b(st)))

    def unary(self) -> Node:
        kind, s, off, end = self.take()
        if kind == 4 and s in "+-":
            inner = self.unary()
            return (lambda st: -_num(inner(st))) if s == "-" else inner
        if kind == 1:
            v = float(s)
            return lambda st: v
        if kind == 4 and s == "[":
            inner = self.expr(0)
            self.expect("]")
            return inner
        if kind == 4 and s == "#":
            return self.param(off)
        if kind == 3:
            return self.function(s, off)
        raise ExprError(f"unexpected {s!r} in an expression; expected a number, a "
                        "parameter or '['", off)

    def param_key(self, off: int):
        """A constant key (int, or str for #<name>), or a node giving the number."""
        t = self.peek()
        if t[0] == 2 and self.g.named:
            self.pos = t[3]
            return "".join(t[1][1:-1].split()).lower()
        if t[0] == 1:
            self.pos = t[3]
            v = float(t[1])
            if not math.isfinite(v) or v != int(v):  # (400 digits make an infinity)
                raise ExprError(f"parameter number #{t[1][:20]} is not a whole number", t[2])
            return int(v)
        if t[0] == 4 and t[1] in "[#":
            return self.unary()
        raise ExprError("expected a parameter number or " + (
            "<name> " if self.g.named else "") + "after '#'", off)

    def param(self, off: int) -> Node:
        key = self.param_key(off)
        if callable(key):
            def indirect(st):
                v = _num(key(st))
                if not math.isfinite(v) or v != int(v) or v < 0:
                    raise ExprError(f"parameter number {v:g} is not a whole number >= 0", off)
                return st.read(int(v), off)
            return indirect
        return lambda st: st.read(key, off)

    def function(self, name: str, off: int) -> Node:
        g = self.g
        if name == "EXISTS" and g.named:
            self.expect("[")
            self.expect("#")
            key = self.param_key(off)
            self.expect("]")
            if not isinstance(key, str):
                raise ExprError("EXISTS takes a named parameter #<name>", off)
            return lambda st: float(st.exists(key))
        if name == "ATAN":
            self.expect("[")
            a = self.expr(0)
            t = self.peek()
            if g.atan_forms and t[0] == 4 and t[1] == ",":  # ATAN[a,b]
                self.pos = t[3]
                b = self.expr(0)
                self.expect("]")
            else:
                self.expect("]")
                t = self.peek()
                if g.atan_forms and not (t[0] == 4 and t[1] == "/"):  # ATAN[x]
                    b = lambda st: 1.0
                else:
                    self.expect("/")
                    self.expect("[")
                    b = self.expr(0)
                    self.expect("]")
            f = _checked(g.atan, "ATAN", off)
            return lambda st: f(_num(a(st)), _num(b(st)))
        if name in g.refused:
            raise ExprError(g.refused[name], off)
        pair = g.pairs.get(name)
        if pair is not None:
            self.expect("[")
            a = self.expr(0)
            self.expect(",")
            b = self.expr(0)
            self.expect("]")
            f = _checked(pair, name, off)
            return lambda st: f(_num(a(st)), _num(b(st)))
        fn = g.functions.get(name)
        if fn is None:
            raise ExprError(f"unknown function or word {name!r} in an expression; "
                            f"supported: {g.supported}", off)
        self.expect("[")
        a = self.expr(0)
        self.expect("]")
        f = _checked(fn, name, off)
        return lambda st: f(_num(a(st)))
