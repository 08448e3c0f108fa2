"""Klartext text into blocks, and blocks into words.

A block is one line (or several joined by a trailing ``~``) without its
block number and ``;`` comment; ``*`` structure lines and empty blocks are
dropped. Columns reported in errors are the raw line's.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import NamedTuple

from .errors import NCParseError
from .program import split_lines

__all__ = ["TNCBlock", "split_blocks", "words", "BEGIN", "END", "LBL", "CALL_LBL",
           "normalise_allow_m", "M_SUPPORTED", "M_NOT_ALLOWABLE"]

BEGIN = re.compile(r"BEGIN\s+PGM\s+(\S+)\s+(MM|INCH)")
END = re.compile(r"END\s+PGM\s+(\S+)\s+(MM|INCH)")
LBL = re.compile(r"LBL\s*(\d+|\"[^\"]*\"|'[^']*')")
CALL_LBL = re.compile(r"CALL\s+LBL\s*(\d+|\"[^\"]*\"|'[^']*')(?:\s+REP\s*(\d+)(?:\s*/\s*\d+)?)?")

#: M functions the reader understands (state or no effect on the path).
M_SUPPORTED = frozenset({0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 13, 14, 30, 126, 127, 128, 129, 140})
#: M functions that move the tool or the frame in ways the reader does not model.
M_NOT_ALLOWABLE = {
    91: "a move in machine coordinates", 92: "a move in machine coordinates",
    94: "a reduction of the rotary axis display", 114: "automatic compensation of "
    "machine geometry", 118: "handwheel superimposition", 120: "look-ahead radius "
    "compensation", 136: "feed per revolution", 144: "compensation of the machine's "
    "kinematics", 116: "a change of the rotary feed", 138: "a choice of tilting axes",
}

_NUMBER = re.compile(r"^\s*(\d+)(?=\s|$)")
_WORD = re.compile(
    r"(FMAX|FAUTO|F\s*AUTO|FU|FZ|IPA|IPR|PA|PR|DR|NX|NY|NZ|TX|TY|TZ|MB|RL|RR|"
    r"IX|IY|IZ|IA|IB|IC|IU|IV|IW|[XYZABCUVWRFMS])"
    r"\s*([+-]?\s*(?:\d+(?:[.,]\d*)?|[.,]\d+)|[+-]?\s*Q[LR]?\d+|MAX|[+-](?![\d.,Q]))?"
    r"|(\S)")


class TNCBlock(NamedTuple):
    """One block: 1-based ``line``, ``col`` of the statement, upper-case ``stmt``."""

    line: int
    col: int
    stmt: str
    orig: str
    skip: bool


def split_blocks(text: str, file: str) -> tuple[list[str], str, list[TNCBlock]]:
    """Lines (no terminators), the newline, and the blocks of a program."""
    lines, newline = split_lines(text)
    blocks: list[TNCBlock] = []
    pending: list = []  # [line, col, parts, skip] of a block continued with '~'
    for i, raw in enumerate(lines):
        body = raw
        k = body.find(";")
        if k >= 0:
            body = body[:k]
        cont = raw.rstrip().endswith("~")
        if cont:
            j = body.rfind("~")
            if j >= 0:
                body = body[:j]
        if pending:
            pending[2].append(body.strip())
            if not cont:
                _emit(blocks, pending[0], pending[1], " ".join(pending[2]), pending[3])
                pending = []
            continue
        start = 0
        stripped = body.lstrip()
        skip = False
        if stripped.startswith("/"):
            skip = True
            body = body.replace("/", " ", 1)
        m = _NUMBER.match(body)
        if m:
            start = m.end()
        rest = body[start:]
        rs = rest.lstrip()
        if rs.startswith("/"):
            skip = True
            rest = rest.replace("/", " ", 1)
            rs = rest.lstrip()
        col = len(body) - len(rs) + 1 if rs else 1
        if not rs or rs.startswith("*"):
            if cont:
                pending = [i + 1, col, [], skip]
            continue
        if "\t" in rs:
            rs = rs.replace("\t", " ")
        if cont:
            pending = [i + 1, col, [rs.rstrip()], skip]
            continue
        _emit(blocks, i + 1, col, rs.rstrip(), skip)
    if pending:
        _emit(blocks, pending[0], pending[1], " ".join(pending[2]), pending[3])
    return lines, newline, blocks


def _emit(blocks: list[TNCBlock], line: int, col: int, s: str, skip: bool) -> None:
    if s:
        blocks.append(TNCBlock(line, col, s.upper(), s, skip))


def words(b: TNCBlock, start: int, lines: list[str], file: str
          ) -> list[tuple[str, str | None, int]]:
    """The words of ``b.stmt[start:]``: (name, value text or None, column)."""
    s = b.stmt
    out = []
    col = b.col
    for m in _WORD.finditer(s, start):
        name = m.group(1)
        if name is None:
            pos = m.start()
            tok = s[pos:].split()[0]
            raise NCParseError(f"unexpected {tok[:16]!r}; expected words such as X+10, "
                               "IX-5, F500, FMAX, R0, DR+, M3", file=file, line=b.line,
                               column=col + pos, text=lines[b.line - 1])
        out.append((name, m.group(2), col + m.start()))
    return out


def normalise_allow_m(allow: Iterable[str]) -> frozenset[int]:
    """``["M110", "M8"]`` -> {110, 8}; refuses codes that move the tool."""
    out = set()
    for item in allow:
        s = str(item).strip().upper()
        m = re.fullmatch(r"M\s*(\d+)", s)
        if not m:
            raise ValueError(f"allow: {item!r} is not an M function such as 'M110'")
        k = int(m.group(1))
        if k in M_NOT_ALLOWABLE:
            raise ValueError(f"allow: M{k} is {M_NOT_ALLOWABLE[k]}; ignoring it would "
                             "misplace the tool")
        out.add(k)
    return frozenset(out)
