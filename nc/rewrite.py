"""Rewrite the coordinates of chosen blocks, keeping everything else.

``errpred`` corrects a program by moving end points (and arc centres) by a
few micrometres. The corrected program must read like the original: same
lines, words, order, comments, N numbers and number style; only coordinate
numbers change. Where a changed point would silently move a later block (a
modal coordinate it inherits, an incremental word, an arc centre given
relative to the start), that block gets the word it needs to stay where it
was.

The result is checked by reading it back: every block must end where it was
asked to, within the resolution of the digits written.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping

import numpy as np

from . import constants as K
from .atomic import atomic_write
from .errors import InputError
from .gcode import parse_program
from .lexer import words_with_spans
from .macro import expression_line, needs_expansion
from .macro_b import needs_macro_b
from .owords import has_owords
from .program import PLANE_AXES, TCP_VECTOR, Program

__all__ = ["rewrite_coordinates", "write_rewritten", "RewriteError", "check_rewritable",
           "refuse_expressions"]

_AXES = "XYZABC"
#: Decimals for words the rewrite inserts or must extend, by units.
_MIN_DECIMALS = {21: 3, 20: 4}
_ANGLE_DECIMALS = 4


class RewriteError(InputError):
    """The requested coordinates cannot be written into the program."""


def _decimals(text: str) -> int:
    return len(text.split(".", 1)[1]) if "." in text else 0


def _format_like(original: str | None, value: float, decimals: int) -> str:
    """Format ``value`` in the style of ``original`` (sign, leading zero, dot)."""
    s = f"{value:.{decimals}f}"
    if float(s) == 0.0:
        s = s.lstrip("-")
    if original is None:
        return s
    body = original.lstrip("+-")
    if body.startswith(".") and decimals > 0:  # no leading zero: ".5"
        if s.startswith("0."):
            s = s[1:]
        elif s.startswith("-0."):
            s = "-" + s[2:]
    if original.startswith("+") and not s.startswith("-"):
        s = "+" + s
    if decimals == 0 and body.endswith("."):
        s += "."
    return s


def refuse_expressions(program: Program) -> None:
    """Refuse a program with ``#`` parameters or ``[ ]`` expressions outside its
    comments, naming its first such line: a rewrite (of its coordinates, of its feeds)
    would write over words the source computes."""
    k = (expression_line(program.lines) if needs_expansion("\n".join(program.lines))
         else None)
    if k is not None:
        raise RewriteError(f"{program.file}:{k}: rewriting programs with '#' parameters or "
                           "'[ ]' expressions is not supported; expected plain numbers in "
                           "every word (the program reads and predicts; to rewrite it, "
                           "write it with the values in place of the parameters)")


def check_rewritable(program: Program) -> None:
    """Refuse, before any work, a program :func:`rewrite_coordinates` cannot rewrite.

    Raises
    ------
    RewriteError
        For a Heidenhain or Siemens program, ``#`` parameters or ``[ ]`` expressions
        outside comments, Fanuc macro B, O-word control flow, frame changes or
        machine-coordinate moves, canned drilling cycles or rotated coordinates.
    """
    if program.metadata.get("dialect") == "heidenhain":
        raise RewriteError(f"{program.file}: rewriting Heidenhain (Klartext) programs is not "
                           "supported; expected a G-code program (post the corrected path "
                           "with nc.heidenhain_writer instead)")
    if program.metadata.get("dialect") == "siemens":
        raise RewriteError(f"{program.file}: rewriting Siemens Sinumerik programs is not "
                           "supported; expected a G-code program (post the corrected path "
                           "with nc.siemens_writer instead)")
    refuse_expressions(program)
    text = "\n".join(program.lines)
    if needs_macro_b(text):
        raise RewriteError(f"{program.file}: rewriting Fanuc macro B programs and "
                           "subprograms (M98/G65 calls, loops: one source line, many moves) "
                           "is not supported; expected a straight-line program")
    if has_owords(text):
        raise RewriteError(f"{program.file}: rewriting programs with O-word control flow "
                           "(subroutines, loops) is not supported; expected a straight-line "
                           "program (one block, one move)")
    if len(program.reframed) or len(program.machine_moves):
        i = int((list(program.reframed) + list(program.machine_moves))[0])
        raise RewriteError(f"{program.file}:{program.line[i]}: the program changes its frame "
                           "or moves in machine coordinates (G92, G52, G10, G28/G30, G53, a "
                           "work offset switch); rewriting such programs is not supported yet")
    for rows, what in ((program.drilling, "canned drilling cycles (one block, many moves)"),
                       (program.rotated, "coordinates in a rotated frame (G68, G68.2, "
                                         "G53.1)")):
        if len(rows):
            raise RewriteError(f"{program.file}:{program.line[int(rows[0])]}: the program "
                               f"has {what}; rewriting such programs is not supported yet")


def rewrite_coordinates(
    program: Program,
    ends: Mapping[int, np.ndarray] | None = None,
    *,
    centres: Mapping[int, np.ndarray] | None = None,
    splits: Mapping[int, np.ndarray] | None = None,
    min_decimals: int | Mapping[int, int] | None = None,
) -> str:
    """New program text with changed end points and arc centres.

    Parameters
    ----------
    program : Program
        The parsed original (its source lines are reused).
    ends : mapping of int to ndarray, shape (6,) or (3,) [mm, rad]
        Block index -> new absolute end point (X Y Z [A B C]), program frame.
    centres : mapping of int to ndarray, shape (3,) [mm]
        Arc block index -> new absolute arc centre (in-plane coordinates are
        used). Arcs whose start moved keep their old centre unless given.
    splits : mapping of int to ndarray, shape (k, 3) [mm]
        Straight feed block index -> points (absolute X Y Z, program frame) at which
        the block is split: the block's own line then ends at the first of them,
        and one line per further point and for the block's end follows it
        (``G1`` and the coordinates only; the block's other words stay on its own
        line). Only for ``G1`` blocks that do not move rotary axes.
    min_decimals : int or dict of int -> int, optional
        Decimals for changed or inserted linear words when the original has
        fewer (default 3 in mm, 4 in inch programs), or per unit mode of the block
        (``{21: 4, 20: 5}``: G21 mm, G20 inch). Rotary words: 4.

    Returns
    -------
    str
        The new program, lines joined with the original's line terminator.

    Raises
    ------
    RewriteError
        For an unknown block index, non-finite coordinates, a rotary change
        under G43.5, or when the result does not read back as requested.
    """
    check_rewritable(program)
    n = len(program)
    target = program.end.copy()
    for i, e in (ends or {}).items():
        if not 0 <= i < n:
            raise RewriteError(f"ends: block index {i} out of range (program has {n})")
        e = np.asarray(e, dtype=float)
        if e.shape not in ((3,), (6,)) or not np.all(np.isfinite(e)):
            raise RewriteError(f"ends[{i}]: expected 3 or 6 finite numbers, got {e!r}")
        target[i, : e.size] = e
    new_centre: dict[int, np.ndarray] = {}
    for i, c in (centres or {}).items():
        if not 0 <= i < n or program.arc_index[i] < 0:
            raise RewriteError(f"centres: block {i} is not an arc")
        c = np.asarray(c, dtype=float)
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise RewriteError(f"centres[{i}]: expected 3 finite numbers, got {c!r}")
        new_centre[i] = c
    split_pts: dict[int, np.ndarray] = {}
    for i, pts in (splits or {}).items():
        if not 0 <= i < n:
            raise RewriteError(f"splits: block index {i} out of range (program has {n})")
        pts = np.asarray(pts, dtype=float).reshape(-1, 3)
        if not np.all(np.isfinite(pts)):
            raise RewriteError(f"splits[{i}]: expected finite points")
        if int(program.motion[i]) != 1 or program.arc_index[i] >= 0:
            raise RewriteError(f"line {program.line[i]}: block {i} is not a straight feed "
                               "move (G1); only those can be split")
        if np.any(np.abs(program.end[i, 3:] - program.start[i, 3:]) > 1e-12):
            raise RewriteError(f"line {program.line[i]}: block {i} moves rotary axes; it "
                               "cannot be split")
        if len(pts):
            split_pts[i] = pts

    lines = list(program.lines)
    after: dict[int, list[str]] = {}      # source line index -> lines to add after it
    cur = program.initial.astype(float).copy()
    modal_index = program.modal_index
    for i in range(n):
        m = program.modals[int(modal_index[i])]
        scale = K.MM_PER_INCH if m.units == 20 else 1.0
        lin_dec = (_MIN_DECIMALS[m.units] if min_decimals is None
                   else int(min_decimals[m.units]) if isinstance(min_decimals, Mapping)
                   else min_decimals)
        res_lin = 0.5 * 10.0 ** -lin_dec * scale
        li = int(program.line[i]) - 1
        raw = lines[li]
        words = words_with_spans(raw)
        present = {w[0]: w for w in words}
        edits: list[tuple[int, int, str]] = []  # (start, end, text) replacements
        inserts: list[tuple[str, str]] = []  # (letter, text) to insert
        reached = cur.copy()
        inc = m.distance == 91
        pieces = split_pts.get(i)
        final = target[i].copy()
        if pieces is not None:
            target[i, :3] = pieces[0]
        for a, letter in enumerate(_AXES):
            want = target[i, a]
            if a >= 3 and m.tcp == TCP_VECTOR:
                if want != program.end[i, a]:
                    raise RewriteError(f"line {li + 1}: block {i} is under G43.5; rotary "
                                       "axes cannot be rewritten there")
                continue
            if a < 3:
                to_word, from_word, dec, res = (1.0 / scale), scale, lin_dec, res_lin
            else:
                to_word, from_word = math.degrees(1.0), math.radians(1.0)
                dec, res = _ANGLE_DECIMALS, math.radians(0.5 * 10.0 ** -_ANGLE_DECIMALS)
            base = cur[a] if inc else 0.0
            w = present.get(letter)
            if w is not None:
                orig_text = w[1]
                if abs(base + float(orig_text) * from_word - want) <= 1e-12:
                    text = orig_text  # untouched: keep it exactly
                else:
                    text = _format_like(orig_text, (want - base) * to_word,
                                        max(_decimals(orig_text), dec))
                    if text != orig_text:
                        start = w[2] + raw[w[2]:w[3]].index(orig_text, 1)
                        edits.append((start, w[3], text))
            else:
                if abs(want - cur[a]) <= res:
                    continue  # the inherited value is as close as a word could be
                text = _format_like(None, (want - base) * to_word, dec)
                inserts.append((letter, text))
            reached[a] = base + float(text) * from_word

        k = int(program.arc_index[i])
        if k >= 0:
            a1, a2, _ = PLANE_AXES[int(program.arc_plane[k])]
            ijk = "IJK"
            centre = new_centre.get(i, program.arc_centre[k])
            start_orig = program.start[i]
            if "R" in present:
                if i in new_centre:
                    r_new = math.hypot(cur[a1] - centre[a1], cur[a2] - centre[a2]) / scale
                    w = present["R"]
                    sign = -1.0 if float(w[1]) < 0 else 1.0
                    text = _format_like(w[1], sign * r_new, max(_decimals(w[1]), lin_dec))
                    if text != w[1]:
                        edits.append((w[2] + raw[w[2]:w[3]].index(w[1], 1), w[3], text))
            else:
                start_moved = (abs(cur[a1] - start_orig[a1]) > 1e-12
                               or abs(cur[a2] - start_orig[a2]) > 1e-12)
                if i in new_centre or start_moved:
                    for ax in (a1, a2):
                        letter = ijk[ax]
                        value = (centre[ax] - (cur[ax] if m.arc_distance == 911 else 0.0))
                        value /= scale
                        w = present.get(letter)
                        if w is not None:
                            text = _format_like(w[1], value, max(_decimals(w[1]), lin_dec))
                            if text != w[1]:
                                edits.append((w[2] + raw[w[2]:w[3]].index(w[1], 1), w[3],
                                              text))
                        else:
                            text = _format_like(None, value, lin_dec)
                            if float(text) != 0.0:
                                inserts.append((letter, text))
        if edits or inserts:
            lines[li] = _apply(raw, words, edits, inserts)
        cur = reached
        if pieces is not None:
            extra = after.setdefault(li, [])
            lower = _lower_case(raw, words)
            for p in list(pieces[1:]) + [final[:3]]:
                text, cur = _g1_line(p, cur, inc, scale, lin_dec)
                extra.append(text.lower() if lower else text)
            target[i] = final

    if after:
        out_lines = []
        for li, text in enumerate(lines):
            out_lines.append(text)
            out_lines.extend(after.get(li, ()))
        lines = out_lines

    text = program.newline.join(lines) + program.newline
    _verify(program, text, target, {i: len(p) for i, p in split_pts.items()})
    return text


def _g1_line(point: np.ndarray, cur: np.ndarray, inc: bool, scale: float, dec: int
             ) -> tuple[str, np.ndarray]:
    """``G1 X.. Y.. Z..`` to ``point`` [mm] from ``cur`` in the block's units and distance
    mode; returns the line and the position it reaches (as written)."""
    reached = cur.copy()
    words = ["G1"]
    for a, letter in enumerate("XYZ"):
        base = cur[a] if inc else 0.0
        text = _format_like(None, (point[a] - base) / scale, dec)
        words.append(f"{letter}{text}")
        reached[a] = base + float(text) * scale
    return " ".join(words), reached


def _apply(raw: str, words, edits, inserts) -> str:
    """Replace number spans, then insert words in X Y Z A B C I J K order."""
    out = raw
    for start, end, text in sorted(edits, reverse=True):
        out = out[:start] + text + out[end:]
    order = "XYZABCIJK"
    spaced = any(raw[w[3]:w[3] + 1].isspace() for w in words[:-1]) or len(words) < 2
    sep = " " if spaced else ""
    lower = _lower_case(raw, words)
    for letter, text in inserts:
        current = words_with_spans(out)
        rank = order.index(letter)
        before = [w for w in current if w[0] in order and order.index(w[0]) < rank]
        after = [w for w in current if w[0] in order and order.index(w[0]) > rank]
        if before:
            pos, word = before[-1][3], f"{sep}{letter}{text}"
        elif after:
            pos, word = after[0][2], f"{letter}{text}{sep}"
        else:  # after the last word that is not N, F, S or T
            others = [w for w in current if w[0] not in "NFST"] or current
            pos, word = others[-1][3], f"{sep}{letter}{text}"
        out = out[:pos] + (word.lower() if lower else word) + out[pos:]
    return out


def _lower_case(raw: str, words) -> bool:
    """Whether a line writes its words' letters in lower case (all of them): words
    added to it are then written so too."""
    letters = [raw[w[2]] for w in words if raw[w[2]].isalpha()]
    return bool(letters) and all(c.islower() for c in letters)


def _verify(program: Program, text: str, target: np.ndarray,
            inserted: Mapping[int, int] | None = None) -> None:
    try:
        back = parse_program(text, file=program.file, allow=program.allowed,
                             block_delete=program.block_delete)
    except ValueError as exc:
        raise RewriteError(f"the rewritten program does not read back: {exc}") from exc
    extra = np.zeros(len(program), np.int64)
    for i, k in (inserted or {}).items():
        extra[i] = k
    expected = len(program) + int(extra.sum())
    if len(back) != expected:
        raise RewriteError(f"the rewritten program has {len(back)} motion blocks; "
                           f"{expected} were expected")
    index = np.arange(len(program)) + np.cumsum(extra)   # each original block's last piece
    units = program.modal_column("units")
    res = np.where(units == 20, 0.5e-4 * K.MM_PER_INCH, 0.5e-3) + 1e-9
    err = np.abs(back.end[index, :3] - target[:, :3]).max(axis=1)
    bad = err > res * 6  # a few roundings may add up in incremental mode
    if np.any(bad):
        i = int(np.argmax(bad))
        raise RewriteError(f"line {program.line[i]}: block ends {err[i]:.3g} mm from the "
                           "requested point after rewriting")


def write_rewritten(path: str | os.PathLike, program: Program,
                    ends: Mapping[int, np.ndarray] | None = None, **kwargs) -> None:
    """Rewrite coordinates (see :func:`rewrite_coordinates`) into ``path``, atomically."""
    text = rewrite_coordinates(program, ends, **kwargs)
    with atomic_write(path, newline="") as fh:
        fh.write(text)
