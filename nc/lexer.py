"""Splitting a G-code line into words, and finding words' columns.

The reader's fast path tokenizes a line with comments removed; when it must
report an error, or when :mod:`nc.rewrite` edits a line, the same pattern is
run on the raw line with comments blanked, so columns are the raw line's.
"""

from __future__ import annotations

import re

__all__ = ["TOKEN", "blank_comments", "token_column", "raw_column", "find_token",
           "words_with_spans"]

#: A word (letter, number) or, in group 3, any other non-blank character.
#: ASCII only: digits of other scripts (``X\u0663``, full-width ``X\uff11``),
#: which ``float`` would read, and non-ASCII spaces are characters to refuse.
TOKEN = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+))|(\S)", re.ASCII)


def find_token(toks: list, letter: str, num: str) -> int | None:
    for i, t in enumerate(toks):
        if t[0] == letter and t[1] == num:
            return i
    return None


def blank_comments(raw: str) -> str:
    """Same length as ``raw``, comments and the block-delete slash blanked."""
    chars = list(raw)
    depth = False
    for i, c in enumerate(chars):
        if depth:
            if c == ")":
                depth = False
            chars[i] = " "
        elif c == "(":
            depth = True
            chars[i] = " "
        elif c == ";":
            for j in range(i, len(chars)):
                chars[j] = " "
            break
    s = "".join(chars)
    stripped = s.lstrip()
    if stripped.startswith("/"):
        k = len(s) - len(stripped)
        s = s[:k] + " " + s[k + 1:]
    return s.upper()


def token_column(raw: str, index: int | None) -> int | None:
    """1-based column of token ``index`` of ``raw`` (comments skipped)."""
    if index is None:
        return None
    for i, m in enumerate(TOKEN.finditer(blank_comments(raw))):
        if i == index:
            return m.start() + 1
    return None


def raw_column(raw: str, s: str, i: int) -> int:
    """Column in ``raw`` of character ``i`` of its stripped form ``s``."""
    offset = raw.find(s)
    if offset < 0:  # a leading '/' was removed
        offset = raw.find(s[1:]) - 1 if len(s) > 1 else 0
    return max(offset, 0) + i + 1


def words_with_spans(raw: str) -> list[tuple[str, str, int, int]]:
    """(letter, number text, start, end) of every word of a raw line."""
    out = []
    for m in TOKEN.finditer(blank_comments(raw)):
        if m.group(1):
            out.append((m.group(1), raw[m.start(2):m.end(2)], m.start(), m.end()))
    return out
