"""Sinumerik text into blocks, and blocks into words.

A block is one line without its ``N``/``:`` block number, ``;`` comment,
jump label (``NAME:``) and ``/`` skip mark; the ``%_N_name_MPF`` header
gives the program's name and type. Columns reported in errors are the raw
line's. A word is one of

* ``A``: an address letter and a number, ``X-10.5``, ``G1``, ``M30``;
* ``E``: a name, ``=`` and an expression, ``X=R1*2``, ``A3=0.5``, ``CR=10``,
  ``R1=5``, ``I=AC(10)``, ``T="MILL"``;
* ``C``: a name and a parenthesised argument list, ``CYCLE800(...)``, ``MSG("...")``;
* ``K``: a bare keyword, ``TRAORI``, ``SUPA``, ``G642`` is an ``A`` word.

Words may follow each other without blanks (``G1X10Y20``), as on the control.
"""

from __future__ import annotations

import re
from typing import NamedTuple

from .errors import NCParseError
from .program import split_lines

__all__ = ["SBlock", "Word", "split_blocks", "lex", "split_args", "HEADER"]

HEADER = re.compile(r"%_N_([A-Z0-9_]+?)_(MPF|SPF)\s*", re.IGNORECASE)
_NUMBER = re.compile(r"\s*(?:N(\d+)|:(\d+))(?=[^0-9.]|$)")
_LABEL = re.compile(r"\s*([A-Z_][A-Z0-9_]*):(?!=)")
_ADDR = re.compile(r"([A-Z])([+-]?(?:\d+\.?\d*|\.\d+))(?![0-9_.]|\s*=)")
_NAME = re.compile(r"([A-Z_$][A-Z0-9_]*)\s*([=(])?")
#: The words most blocks are made of, in one match: an address and a number
#: (``X10.5``), a name, '=' and a plain number ending the word (``A3=0.5``), a
#: bare keyword; anything else takes the general path below.
_FAST = re.compile(r" *(?:([A-Z])([+-]?(?:\d+\.?\d*|\.\d+))(?![0-9_.]| *=)"
                   r"|([A-Z_][A-Z0-9_]*) *= *([+-]?(?:\d+\.?\d*|\.\d+))(?= |$)"
                   r"(?! *(?:[-+*/)=<>]|DIV|MOD))|([A-Z_][A-Z0-9_]*)(?= |$)(?! *[=(]))")
#: A plain number after '=' that ends the word (most words CAM writes: A3=0.5).
_PLAIN = re.compile(r" *([+-]?(?:\d+\.?\d*|\.\d+))(?= |$)")
_UPPER = {c: c - 32 for c in range(ord("a"), ord("z") + 1)}


class SBlock(NamedTuple):
    """One block: 1-based ``line``, ``col`` of the statement, ASCII-upper-case ``stmt``
    (empty on a line that holds only a label), the ``/`` mark, the jump ``labels``
    of the block (its label and its ``N``/``:`` number, e.g. ``("MARK1", "N20")``)."""

    line: int
    col: int
    stmt: str
    skip: bool
    labels: tuple[str, ...] = ()


class Word(NamedTuple):
    """One word of a block: ``kind`` (A E C K), ``name``, ``text`` (value, expression
    or arguments, upper case), 1-based columns of the word and of its text in the
    raw line."""

    kind: str
    name: str
    text: str
    col: int
    tcol: int


def split_blocks(text: str, file: str) -> tuple[list[str], str, list[SBlock], str | None]:
    """Lines (no terminators), the newline, the blocks and the header's program name."""
    lines, newline = split_lines(text)
    blocks: list[SBlock] = []
    name = None
    for i, raw in enumerate(lines):
        body = raw
        if '"' in body:
            body = _cut_comment(body, file, i + 1, raw)
        else:
            k = body.find(";")
            if k >= 0:
                body = body[:k]
        if "\t" in body:
            body = body.replace("\t", " ")
        stripped = body.lstrip()
        if not stripped:
            continue
        if stripped[0] == "%":
            if stripped.rstrip() == "%":  # an ISO tape mark: nothing to read
                continue
            m = HEADER.fullmatch(stripped.rstrip())
            if m is None or blocks or name is not None:
                col = len(body) - len(stripped) + 1
                raise NCParseError("expected one header '%_N_name_MPF' (or _SPF) before the "
                                   f"first block, found {stripped.strip()[:30]!r}", file=file,
                                   line=i + 1, column=col, text=raw)
            name = m.group(1)
            continue
        up = body.translate(_UPPER)
        pos = len(body) - len(stripped)
        skip = False
        if up[pos] == "/":
            skip = True
            pos += 1
            if pos < len(up) and up[pos].isdigit():
                pos += 1
        labels: tuple[str, ...] = ()
        m = _NUMBER.match(up, pos)
        if m:
            labels = (f"N{int(m.group(1))}" if m.group(1) else f":{int(m.group(2))}",)
            pos = m.end()
            while pos < len(up) and up[pos] == " ":
                pos += 1
            if not skip and pos < len(up) and up[pos] == "/":  # N10 /X1, as some posts write
                skip = True
                pos += 1
                if pos < len(up) and up[pos].isdigit():
                    pos += 1
        m = _LABEL.match(up, pos)
        if m:
            labels = labels + (m.group(1),)
            pos = m.end()
        while pos < len(up) and up[pos] == " ":
            pos += 1
        stmt = up[pos:].rstrip()
        if stmt or labels:
            blocks.append(SBlock(i + 1, pos + 1, stmt, skip, labels))
    return lines, newline, blocks, name


def _cut_comment(body: str, file: str, line: int, raw: str) -> str:
    """``body`` up to its ``;`` comment, ``;`` inside double quotes kept."""
    quoted = False
    for k, c in enumerate(body):
        if c == '"':
            quoted = not quoted
        elif c == ";" and not quoted:
            return body[:k]
    if quoted:
        raise NCParseError("string not closed; expected a closing '\"'", file=file,
                           line=line, column=body.rfind('"') + 1, text=raw)
    return body


_CONT_PREV = frozenset("+-*/(,=<>")
_CONT_NEXT = frozenset("+-*/),=<>")


def _scan_expr(s: str, i: int) -> int:
    """End of the expression that starts at ``s[i]`` (blanks inside parentheses, or
    next to an operator, belong to it)."""
    n = len(s)
    depth = 0
    start = i
    while i < n:
        c = s[i]
        if c == '"':
            j = s.find('"', i + 1)
            i = n if j < 0 else j + 1
            continue
        if c == "(" or c == "[":
            depth += 1
        elif c == ")" or c == "]":
            depth -= 1
            if depth < 0:
                return i
        elif c == " " and depth == 0:
            j = i
            while j < n and s[j] == " ":
                j += 1
            if j == n:
                return i
            head = s[start:i].rstrip()
            if (head[-1:] in _CONT_PREV or s[j] in _CONT_NEXT or head.endswith((" DIV", " MOD"))
                    or s.startswith(("DIV ", "MOD "), j)):
                i = j
                continue
            return i
        i += 1
    return i


def _scan_args(s: str, i: int) -> int:
    """Index of the ``)`` closing the argument list opened just before ``s[i]``; -1 if none."""
    depth = 1
    n = len(s)
    while i < n:
        c = s[i]
        if c == '"':
            j = s.find('"', i + 1)
            if j < 0:
                return -1
            i = j + 1
            continue
        if c == "(":
            depth += 1
        elif c == ")":
            depth -= 1
            if depth == 0:
                return i
        i += 1
    return -1


def lex(b: SBlock, file: str, lines: list[str]) -> list[Word]:
    """The words of a block, left to right."""
    s = b.stmt
    out: list[Word] = []
    n = len(s)
    i = 0
    col0 = b.col
    fast = _FAST.match
    while i < n:
        m = fast(s, i)
        if m is not None:
            k = m.lastindex
            if k == 2:
                out.append(Word("A", m.group(1), m.group(2), col0 + m.start(1),
                                col0 + m.start(2)))
            elif k == 4:
                out.append(Word("E", m.group(3), m.group(4), col0 + m.start(3),
                                col0 + m.start(4)))
            else:
                out.append(Word("K", m.group(5), "", col0 + m.start(5), col0 + m.end()))
            i = m.end()
            continue
        c = s[i]
        if c == " ":
            i += 1
            continue
        m = _ADDR.match(s, i)
        if m:
            out.append(Word("A", m.group(1), m.group(2), col0 + i, col0 + m.start(2)))
            i = m.end()
            continue
        m = _NAME.match(s, i)
        if m is None:
            raise NCParseError(f"unexpected {s[i:].split()[0][:16]!r}; expected words such "
                               "as G1, X10.5, X=R1+2, A3=0.5, TRAORI, CYCLE800(...)",
                               file=file, line=b.line, column=col0 + i, text=lines[b.line - 1])
        name, sep = m.group(1), m.group(2)
        if sep is None:
            out.append(Word("K", name, "", col0 + i, col0 + m.end()))
            i = m.end()
        elif sep == "=":
            p = _PLAIN.match(s, m.end())
            if p is not None:
                nxt = p.end() + 1
                while nxt < n and s[nxt] == " ":
                    nxt += 1
                if nxt >= n or s[nxt] not in "+-*/)=<>" and not s.startswith(("DIV", "MOD"),
                                                                              nxt):
                    out.append(Word("E", name, p.group(1), col0 + i, col0 + p.start(1)))
                    i = p.end()
                    continue
            j = m.end()
            while j < n and s[j] == " ":
                j += 1
            end = _scan_expr(s, j)
            if s.startswith("=", j) or end == j:
                raise NCParseError(f"{name}= without a value; expected {name}=expression",
                                   file=file, line=b.line, column=col0 + i,
                                   text=lines[b.line - 1])
            out.append(Word("E", name, s[j:end].strip(), col0 + i, col0 + j))
            i = end
        else:
            end = _scan_args(s, m.end())
            if end < 0:
                raise NCParseError(f"{name}( not closed; expected ')'", file=file,
                                   line=b.line, column=col0 + i, text=lines[b.line - 1])
            out.append(Word("C", name, s[m.end():end], col0 + i, col0 + m.end()))
            i = end + 1
    return out


def split_args(text: str) -> list[str]:
    """``'1,"TC1",,57'`` -> ``['1', '"TC1"', '', '57']`` (commas in quotes and
    parentheses kept)."""
    out = []
    depth = 0
    cur = 0
    quoted = False
    for k, c in enumerate(text):
        if c == '"':
            quoted = not quoted
        elif quoted:
            continue
        elif c == "(":
            depth += 1
        elif c == ")":
            depth -= 1
        elif c == "," and depth == 0:
            out.append(text[cur:k].strip())
            cur = k + 1
    out.append(text[cur:].strip())
    return out
