"""One Fanuc macro B block compiled into a statement, and the variables it reads.

External output (POPEN, DPRNT, BPRNT, PCLOS) moves nothing: such blocks are
passed over.

:func:`compile_block` reads one line (comments blanked, upper case, same
length as the source line so that offsets are its columns) into a
:class:`Statement`; :mod:`nc.macro_b` executes the statements. The
expressions are :mod:`nc.expressions`' ``FANUC`` grammar; :class:`Variables`
is the store they read:

=================  ===========================================================
``#0``             always vacant (null); cannot be set
``#1``-``#33``     local, one set per G65 macro call level (vacant at entry
                   except the arguments); M98 subprograms share their caller's
``#100``-``#499``  common, vacant at the start (``#200``-``#499`` are the
                   extended common variables of the option)
``#500``-``#999``  common, kept by the control from earlier runs: reading one
                   before the program sets it is refused (the value is unknown)
``#3000``          ``#3000=n (MESSAGE)`` raises alarm n: the read stops there
``#3006``          ``#3006=n (MESSAGE)`` stops with a message, like M0: passed
other ``#1000``+   system variables need the control's state: refused by name
=================  ===========================================================
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from .expressions import FANUC, ExprError, compile_expression

__all__ = ["Statement", "Variables", "MacroError", "compile_block", "comment_text", "ARGUMENTS",
           "number_text"]

#: G65 argument specification I: address -> local variable
ARGUMENTS = {"A": 1, "B": 2, "C": 3, "I": 4, "J": 5, "K": 6, "D": 7, "E": 8, "F": 9,
             "H": 11, "M": 13, "Q": 17, "R": 18, "S": 19, "T": 20, "U": 21, "V": 22,
             "W": 23, "X": 24, "Y": 25, "Z": 26}

_NUMBER = re.compile(r"[-+]?\s*(?:\d+\.?\d*|\.\d+)")
_LABEL = re.compile(r"\s*N\s*(\d+)")
_KEYWORD = re.compile(r"(IF|WHILE|GOTO|DO|END|THEN)(?![A-Z])|(IF|WHILE|GOTO|DO|END)(?=\s*[\d#\[])")
_OUTPUT = re.compile(r"(?:POPEN|PCLOS|DPRNT|BPRNT)(?![A-Z])")
_COMMENT = re.compile(r"\(([^()]*)\)")
_VARIABLES = "#0, #1-#33, #100-#999"


class MacroError(ExprError):
    """A macro statement that cannot run; ``offset`` is the 0-based column."""


class Variables:
    """The variables of one expansion (see the module's table)."""

    def __init__(self) -> None:
        self.local: list = [None] * 34
        self.common: dict[int, float | None] = {}

    def read(self, key: int, offset: int) -> float | None:
        if 0 < key < 34:
            return self.local[key]
        if key == 0:
            return None
        if 100 <= key < 500:
            return self.common.get(key)
        if 500 <= key < 1000:
            if key not in self.common:
                raise MacroError(f"#{key} is read before the program sets it; #500-#999 "
                                 "keep values from earlier runs, which this reader does "
                                 "not know", offset)
            return self.common[key]
        raise MacroError(_unsupported(key), offset)

    def write(self, key: int, value: float | None, offset: int) -> None:
        if 0 < key < 34:
            self.local[key] = value
        elif 100 <= key < 1000:
            self.common[key] = value
        elif key == 0:
            raise MacroError("#0 is always vacant and cannot be set; expected "
                             f"{_VARIABLES}", offset)
        else:
            raise MacroError(_unsupported(key), offset)


def _unsupported(key: int) -> str:
    if key >= 1000:
        return (f"system variable #{key} needs the control's state and is not supported; "
                f"expected {_VARIABLES} (or #3000/#3006 set to stop)")
    return f"variable #{key} does not exist in Fanuc macro B; expected {_VARIABLES}"


@dataclass
class Statement:
    """One compiled block. ``kind``: "pass" (the source line as is), "words"
    (NC words with values to fill in), "none" (nothing to do), "assign", "if",
    "goto", "while", "do", "end", "m98", "m97", "m99", "g65"."""

    kind: str
    column: int = 0                    # 0-based offset of the statement's keyword
    words: list = field(default_factory=list)   # (letter, text or node, offset)
    ends: bool = False                 # M30 / M02: the program ends after it
    cond: object = None                # node of IF / WHILE
    target: object = None              # node of GOTO / P of a call or M99
    count: object = None               # node of L
    assigns: list = field(default_factory=list)  # (key or node, value node, offset)
    loop: int = 0                      # m of DOm / ENDm
    args: list = field(default_factory=list)     # G65: (local number, node)
    then: object = None                # IF: the Statement run when true
    text: str = ""                     # #3000 / #3006: the comment (message)


def number_text(v: float) -> str:
    """The shortest text that reads back as ``v`` (whole values without '.')."""
    if v == int(v) and abs(v) < 1e15:
        return str(int(v))
    s = repr(float(v))
    return f"{v:.20f}".rstrip("0").rstrip(".") if "e" in s else s


def _skip(s: str, i: int) -> int:
    n = len(s)
    while i < n and s[i].isspace():
        i += 1
    return i


def _value(s: str, i: int):
    """(node, end) of the bracketed/variable value at ``s[i]``."""
    return compile_expression(s, FANUC, i, whole=False)


def _condition(s: str, i: int, what: str):
    i = _skip(s, i)
    if i >= len(s) or s[i] != "[":
        raise MacroError(f"expected '[' and a condition after {what}", i)
    return _value(s, i)


def compile_block(blank: str) -> Statement:
    """The statement of one line, ``blank`` upper case with comments blanked.

    Raises
    ------
    ExprError
        With the 0-based offset and what was expected.
    """
    i = _skip(blank, 0)
    n = len(blank)
    if i == n:
        return Statement("none")
    m = _LABEL.match(blank, i)
    if m is not None:
        i = _skip(blank, m.end())
        if i == n:
            return Statement("none")
    if _OUTPUT.match(blank, i) is not None:  # output to a device: nothing moves
        return Statement("none", column=i)
    c = blank[i]
    if c == "#":
        st = Statement("assign", column=i)
        i = _assignments(blank, i, st.assigns)
        if i < n:
            raise MacroError("expected one macro statement per block (#i=..., IF, WHILE, "
                             "GOTO, END); found words after an assignment", i)
        return st
    k = _KEYWORD.match(blank, i)
    if k is not None:
        return _control(blank, i, k.group(1) or k.group(2))
    return _nc_words(blank, i)


def _assignments(s: str, i: int, out: list) -> int:
    """Read ``#i=expr`` statements from ``s[i] == '#'``; returns the end."""
    n = len(s)
    while i < n and s[i] == "#":
        off = i
        j = _skip(s, i + 1)
        m = re.compile(r"\d+").match(s, j)
        if m is not None:
            key: object = int(m.group())
            j = m.end()
        elif j < n and s[j] == "[":
            key, j = _value(s, j)
        else:
            raise MacroError("expected a variable number or '[' after '#'", j)
        j = _skip(s, j)
        if j >= n or s[j] != "=":
            raise MacroError("expected '=' after the variable of an assignment", j)
        value, i = compile_expression(s, FANUC, j + 1, whole=True)
        out.append((key, value, off))
        i = _skip(s, i)
    return i


def _control(s: str, i: int, word: str) -> Statement:
    n = len(s)
    j = i + len(word)
    if word == "IF":
        cond, j = _condition(s, j, "IF")
        j = _skip(s, j)
        st = Statement("if", column=i, cond=cond)
        if s.startswith("GOTO", j):
            at = j
            target, j = compile_expression(s, FANUC, j + 4, whole=True)
            st.then = Statement("goto", column=at, target=target)
        else:
            if s.startswith("THEN", j):
                j = _skip(s, j + 4)
            if j >= n or s[j] != "#":
                raise MacroError("expected GOTO n or THEN #i=... after IF [condition]", j)
            st.then = Statement("assign", column=j)
            j = _assignments(s, j, st.then.assigns)
    elif word == "GOTO":
        target, j = compile_expression(s, FANUC, j, whole=True)
        st = Statement("goto", column=i, target=target)
    elif word == "WHILE":
        cond, j = _condition(s, j, "WHILE")
        j = _skip(s, j)
        if not s.startswith("DO", j):
            raise MacroError("expected DOm (m = 1, 2 or 3) after WHILE [condition]", j)
        st = Statement("while", column=i, cond=cond)
        st.loop, j = _loop_number(s, j + 2)
    elif word in ("DO", "END"):
        st = Statement(word.lower(), column=i)
        st.loop, j = _loop_number(s, j)
    else:  # THEN without IF
        raise MacroError("THEN without IF [condition]; expected IF [condition] THEN #i=...", i)
    j = _skip(s, j)
    if j < n:
        raise MacroError(f"unexpected {s[j:].split()[0][:12]!r} after {word}; expected one "
                         "macro statement per block", j)
    return st


def _loop_number(s: str, j: int) -> tuple[int, int]:
    j = _skip(s, j)
    m = re.compile(r"\d+").match(s, j)
    if m is None or int(m.group()) not in (1, 2, 3):
        raise MacroError("expected a loop number 1, 2 or 3 after DO / END", j)
    return int(m.group()), m.end()


def _nc_words(s: str, i: int) -> Statement:
    """NC words, values maybe '#' variables or '[ ]' expressions; calls and returns."""
    words: list = []
    n = len(s)
    plain = True
    while i < n:
        c = s[i]
        if c.isspace():
            i += 1
            continue
        if not ("A" <= c <= "Z"):
            raise MacroError(f"unexpected character {c!r}; expected NC words (a letter and "
                             "a number, '#' variable or '[ ]' expression) or one macro "
                             "statement", i)
        start = i
        j = _skip(s, i + 1)
        m = _NUMBER.match(s, j)
        if m is not None:
            words.append((c, "".join(m.group().split()), start))
            i = m.end()
        else:
            node, i = _value(s, j)
            words.append((c, node, start))
            plain = False
    codes = {(w[0], float(w[1])) for w in words if w[0] in "GM" and isinstance(w[1], str)}
    for g in (66.0, 66.1):
        if ("G", g) in codes:
            off = next(w[2] for w in words if w[0] == "G" and w[1] != "" and
                       isinstance(w[1], str) and float(w[1]) == g)
            raise MacroError(f"G{number_text(g)}: modal macro calls (G66/G66.1) are not "
                             "supported; expected G65 or M98 calls", off)
    ends = ("M", 30.0) in codes or ("M", 2.0) in codes
    for code, kind in ((("G", 65.0), "g65"), (("M", 98.0), "m98"), (("M", 97.0), "m97"),
                       (("M", 99.0), "m99")):
        if code in codes:
            return _call(kind, words, ends)
    return Statement("pass" if plain else "words", words=words, ends=ends)


def _call(kind: str, words: list, ends: bool) -> Statement:
    col = next(w[2] for w in words if w[0] == kind[0].upper() and isinstance(w[1], str)
               and float(w[1]) == float(kind[1:]))
    st = Statement(kind, column=col, ends=ends)
    for letter, v, off in words:
        if off == col:
            continue
        if letter == "P":
            st.target = v
        elif letter == "L" and kind != "m99":
            st.count = v
        elif kind == "g65":
            if letter not in ARGUMENTS:
                raise MacroError(f"{letter} is not a G65 argument; expected P, L and "
                                 f"{' '.join(ARGUMENTS)} (argument specification I)", off)
            st.args.append((ARGUMENTS[letter], v, off))
        else:
            st.words.append((letter, v, off))
    if st.target is None and kind != "m99":
        raise MacroError(f"{kind.upper()} without P; expected P and the program number "
                         "(or N number for M97)", col)
    if kind == "g65" and len({a[0] for a in st.args}) != len(st.args):
        raise MacroError("an argument appears twice in one G65 block", col)
    return st


def comment_text(raw: str) -> str:
    """The first parenthesised comment of ``raw``, or ''."""
    m = _COMMENT.search(raw)
    return m.group(1).strip() if m else ""
