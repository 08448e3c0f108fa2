"""Rewrite the feed (``F`` words) of chosen blocks, keeping everything else.

``errpred schedule`` gives each cutting block its own feed. The new program must read
like the original: same lines, words, order, comments and coordinates; only ``F``
numbers change, and an ``F`` word is added where a block's feed differs from the one in
effect before it (a feed is modal: a block that inherited its feed from an earlier line
whose ``F`` changed gets its own). The result is checked by reading it back: every block
must end where it did and move at the feed asked for.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from . import constants as K
from .gcode import parse_program
from .lexer import words_with_spans
from .program import RAPID, Program
from .rewrite import RewriteError, refuse_expressions

__all__ = ["rewrite_feeds"]

#: Decimals of a rewritten F word: 0.001 mm/min (or in/min) is far below any
#: controller's feed resolution, and the read-back compares at half of it.
_F_DECIMALS = 3


def _format_feed(value: float) -> str:
    s = f"{value:.{_F_DECIMALS}f}".rstrip("0").rstrip(".")
    return s or "0"


def rewrite_feeds(program: Program, feeds: Mapping[int, float]) -> str:
    """New program text in which block ``b`` (a feed move) moves at ``feeds[b]``.

    Parameters
    ----------
    program : Program
        The parsed original (its source lines are reused).
    feeds : mapping of int to float [mm/min]
        Block index -> new feed; blocks not given keep theirs. Blocks sharing a
        source line must be given the same feed.

    Returns
    -------
    str
        The new program, lines joined with the original's line terminator.

    Raises
    ------
    RewriteError
        For a block index out of range, a rapid block, a feed that is not finite and
        > 0, an inverse-time (G93) block, a dialect or syntax the rewrite does not
        write, or when the result does not read back as requested.
    """
    dialect = program.metadata.get("dialect")
    if dialect in ("heidenhain", "siemens"):
        raise RewriteError(f"{program.file}: rewriting the feeds of {dialect} programs is "
                           "not supported; expected a G-code program")
    refuse_expressions(program)
    n = len(program)
    feed_mode = program.modal_column("feed_mode") if n else np.zeros(0)
    units = program.modal_column("units") if n else np.zeros(0)
    want = np.asarray(program.feed, float).copy()
    for b, f in feeds.items():
        if not 0 <= b < n:
            raise RewriteError(f"feeds: block index {b} out of range (program has {n})")
        if int(program.motion[b]) == RAPID:
            raise RewriteError(f"line {program.line[b]}: a rapid move has no feed to set")
        if int(feed_mode[b]) == 93:
            raise RewriteError(f"line {program.line[b]}: inverse-time feed (G93); rewriting "
                               "its feed is not supported")
        f = float(f)
        if not (math.isfinite(f) and f > 0):
            raise RewriteError(f"feeds[{b}]: expected a finite feed > 0 mm/min, got {f!r}")
        want[b] = f
    per_line: dict[int, float] = {}
    for b in range(n):
        if int(program.motion[b]) == RAPID:
            continue
        li = int(program.line[b])
        if li in per_line and abs(per_line[li] - want[b]) > 1e-9 * max(1.0, want[b]):
            raise RewriteError(f"line {li}: its feed moves were given different feeds; "
                               "expected one feed per line")
        per_line[li] = float(want[b])
    inch = units == 20
    if inch.any() and not inch.all():
        raise RewriteError(f"{program.file}: the program switches between G20 and G21; "
                           "rewriting its feeds is not supported")
    if (feed_mode == 93).any():
        i = int(np.argmax(feed_mode == 93))
        raise RewriteError(f"line {program.line[i]}: inverse-time feed (G93); rewriting the "
                           "feeds of such programs is not supported")
    scale = K.MM_PER_INCH if inch.any() else 1.0
    lines = list(program.lines)
    current = math.nan                      # feed in effect in the new text [mm/min]
    for i, raw in enumerate(lines):
        words = words_with_spans(raw)
        fw = [w for w in words if w[0] == "F"]
        target = per_line.get(i + 1)
        if target is None:                  # no feed move here: an F word sets the feed
            if fw:
                try:
                    current = float(fw[-1][1]) * scale
                except ValueError:
                    current = math.nan
            continue
        if fw:
            try:
                written = float(fw[-1][1]) * scale
            except ValueError:
                written = math.nan
            if _differs(written, target):
                lines[i] = _set_feed(raw, words, fw, target / scale)
        elif _differs(current, target):
            lines[i] = _set_feed(raw, words, fw, target / scale)
        current = target
    text = program.newline.join(lines) + program.newline
    _verify(program, text, want)
    return text


def _differs(current: float, target: float) -> bool:
    """Whether a feed in effect differs from the one wanted by more than the rounding of
    the digits written (half of ``10**-_F_DECIMALS`` mm/min, or in/min) [mm/min]."""
    return not (math.isfinite(current)
                and abs(current - target) <= 0.5 * 10.0 ** -_F_DECIMALS)


def _set_feed(raw: str, words, fw, value: float) -> str:
    text = _format_feed(value)
    if fw:
        _, _, start, end = fw[-1]
        return raw[:start] + "F" + text + raw[end:]
    if not words:
        return raw + (" " if raw and not raw[-1].isspace() else "") + "F" + text
    end = words[-1][3]
    return raw[:end] + " F" + text + raw[end:]


def _verify(program: Program, text: str, want: np.ndarray) -> None:
    try:
        back = parse_program(text, file=program.file, allow=program.allowed,
                             block_delete=program.block_delete)
    except ValueError as exc:
        raise RewriteError(f"the program with new feeds does not read back: {exc}") from exc
    if len(back) != len(program):
        raise RewriteError(f"the program with new feeds has {len(back)} motion blocks; "
                           f"{len(program)} were expected")
    same = np.array_equal(back.end, program.end, equal_nan=True)
    if not same:
        i = int(np.argmax(np.nanmax(np.abs(back.end - program.end), axis=1)))
        raise RewriteError(f"line {program.line[i]}: a block ends elsewhere after rewriting "
                           "its feed")
    feed = program.motion != RAPID
    err = np.abs(back.feed[feed] - want[feed])
    bad = ~(err <= 0.5e-3 * K.MM_PER_INCH + 1e-9)
    if bad.any():
        i = int(np.flatnonzero(feed)[np.argmax(bad)])
        raise RewriteError(f"line {program.line[i]}: feed {back.feed[i]:g} mm/min after "
                           f"rewriting; {want[i]:g} was asked for")
