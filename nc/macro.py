"""LinuxCNC parameters in straight-line programs: ``#`` values substituted, line by line.

A program with ``#`` parameters or ``[ ]`` expressions but no O-word control
flow is expanded before the reader reads it: each line's words get their
values (``X[#1*2]`` -> ``X4``) and its assignments (``#1=5``, ``#<name>=[..]``)
take effect after all of the line's reads, as LinuxCNC does. A parameter read
before the program sets it is refused (``rs274`` reads 0 for a numbered one, or
what an earlier run left in #31-#5000; it refuses a named one); system
parameters (#5000 and up, predefined ``#<_name>``) are refused, since they
need the control's state. Expansion
stops after the line with M2 or M30, where the reader stops.
"""

from __future__ import annotations

import re

from .errors import NCParseError
from .expressions import LINUXCNC, ExprError, compile_expression
from .lexer import blank_comments, foreign_syntax

__all__ = ["needs_expansion", "expand_parameters", "expression_line"]

_CONTROL = re.compile(r"(?im)^[\s/]*(?:N\s*\d+\s*)?O\s*(?:<|\d+\s*[A-Z])")
_END = re.compile(r"M\s*0*(?:2|30)(?![\d.])")
_FIRST_SYSTEM = 5000
_PREFIX = "parameters and expressions: "


def needs_expansion(text: str) -> bool:
    """True for a program with ``#`` or ``[`` and no O-word control flow."""
    return ("#" in text or "[" in text) and _CONTROL.search(text) is None


def expression_line(lines) -> int | None:
    """The first line (1-based) with ``#`` or ``[`` outside its comments, else None.

    A program whose only ``#`` or ``[`` are in comments (a post's ``(Set units to
    inches [G21 for mm])``, ``(TOOL #3)``) has plain numbers in every word.
    """
    for k, raw in enumerate(lines):
        if "#" in raw or "[" in raw:
            s = blank_comments(raw)
            if "#" in s or "[" in s:
                return k + 1
    return None


class _Store:
    def __init__(self) -> None:
        self.values: dict = {}

    def read(self, key, offset):
        if isinstance(key, str):
            if key not in self.values:
                what = ("a predefined (system) parameter" if key.startswith("_")
                        else "used before it is set")
                raise ExprError(f"#<{key}> is {what}; expected a parameter the program "
                                "sets", offset)
            return self.values[key]
        if key >= _FIRST_SYSTEM:
            raise ExprError(f"system parameter #{key} needs the control's state and is not "
                            "supported; expected #1-#4999 or #<name>", offset)
        if key not in self.values:  # LinuxCNC reads 0, or what an earlier run left in #31-
            raise ExprError(f"#{key} is used before it is set in this program; expected a "
                            "parameter the program sets", offset)
        return self.values[key]

    def exists(self, key):
        return key in self.values


def _text(v: float) -> str:
    s = repr(float(v))
    return f"{v:.20f}".rstrip("0").rstrip(".") if "e" in s else s


def _strip(raw: str) -> str:
    """Comments blanked (same length); unbalanced ones are left for the reader."""
    out, depth = [], False
    for c in raw:
        if depth:
            depth = c != ")"
            out.append(" ")
        elif c == "(":
            depth = True
            out.append(" ")
        elif c == ";":
            break
        else:
            out.append(c)
    return "".join(out).upper()


def expand_parameters(lines: list[str], file: str) -> list[str]:
    """The lines with parameters substituted and assignments removed (same count).

    Raises
    ------
    NCParseError
        For an expression this evaluator does not read, a system parameter,
        a named parameter read before it is set, naming file, line and column.
    """
    store = _Store()
    out = list(lines)
    for k, raw in enumerate(lines):
        if "#" not in raw and "[" not in raw:
            if ("M" in raw or "m" in raw) and _END.search(_strip(raw)):
                break
            continue
        s = _strip(raw)
        if foreign_syntax(s) is not None:  # left for the reader, which names the dialect
            continue
        try:
            words, sets = _line(s, store)
        except ExprError as exc:
            raise NCParseError(_PREFIX + str(exc), file=file, line=k + 1,
                               column=exc.offset + 1, text=raw) from None
        except RecursionError:
            raise NCParseError(_PREFIX + "brackets nested too deeply; expected at most a "
                               "few hundred levels", file=file, line=k + 1, column=1,
                               text=raw) from None
        for key, v in sets:
            store.values[key] = v
        out[k] = " ".join(words)
        if _END.search(out[k]):
            break
    return out


def _line(s: str, store: _Store) -> tuple[list[str], list]:
    """The words with values and the assignments (key, value) of one line."""
    words: list[str] = []
    sets: list = []
    i, n = 0, len(s)
    while i < n:
        c = s[i]
        if c.isspace():
            i += 1
        elif c == "#":
            node, j = compile_expression(s, LINUXCNC, i, whole=False)
            key = _target(s, i + 1, store)
            j = _skip(s, j)
            if j >= n or s[j] != "=":
                raise ExprError("expected '=' after a parameter at the start of an "
                                "assignment", j)
            value, i = compile_expression(s, LINUXCNC, j + 1, whole=False)
            sets.append((key, value(store)))
        elif c.isalpha() and c.isascii():
            j = _skip(s, i + 1)
            if j < n and (s[j].isdigit() or s[j] == "."):
                m = re.match(r"\d*\.?\d*", s[j:])
                words.append(c + s[j:j + m.end()])
                i = j + m.end()
            elif j < n and s[j] in "-+" and _skip(s, j + 1) < n and (
                    s[_skip(s, j + 1)].isdigit() or s[_skip(s, j + 1)] == "."):
                j2 = _skip(s, j + 1)
                m = re.match(r"\d*\.?\d*", s[j2:])
                words.append(c + s[j] + s[j2:j2 + m.end()])
                i = j2 + m.end()
            else:
                node, i = compile_expression(s, LINUXCNC, j, whole=False)
                words.append(c + _text(node(store)))
        elif c == "/" and not words and not sets:
            words.append("/")
            i += 1
        else:
            raise ExprError(f"unexpected character {c!r}; expected words and #-assignments", i)
    return words, sets


def _skip(s: str, i: int) -> int:
    while i < len(s) and s[i].isspace():
        i += 1
    return i


def _target(s: str, i: int, store: _Store):
    """The key an assignment at ``s[i-1] == '#'`` writes."""
    j = _skip(s, i)
    m = re.match(r"<([^<>]*)>|(\d+)", s[j:])
    if m is None:
        node, _ = compile_expression(s, LINUXCNC, i - 1, whole=False)
        raise ExprError("expected #number or #<name> before '='", i - 1)
    if m.group(1) is not None:
        return "".join(m.group(1).split()).lower()
    key = int(m.group(2))
    if key >= _FIRST_SYSTEM or key < 1:
        raise ExprError(f"assignment to #{key}; expected #1-#4999 or #<name> (system "
                        "parameters are not supported)", i - 1)
    return key
