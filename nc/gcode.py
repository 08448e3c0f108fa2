"""Read ISO/Fanuc and LinuxCNC style G-code into a :class:`~nc.program.Program`.

The dialect is what CAM systems write for milling: G0/G1/G2/G3 (IJK centre
and R forms, full circles, helical arcs, LinuxCNC's P turns), G17/G18/G19,
G90/G91, G90.1/G91.1, G20/G21, G93/G94/G95, F, S, M3/M4/M5, T and M6, G43 H,
G43.4/G43.5/G49 (tool centre point on/off; under G43.5 the words I J K of a
G0/G1 block are the tool vector), G54...G59 (offsets from a table), comments
in parentheses and after ``;``, block delete ``/``, N numbers, ``%`` and O
program numbers. G40 and G80 (which assert the state the reader assumes;
G80 may share a block with G0...G3), and M0/M1/M2/M30 are understood.

Codes that neither move the tool nor change the frame (coolant M7/M8/M9,
clamps M10/M11, dwell G4, path blending G61/G64, Fanuc look-ahead G05 P,
G05.1 Q, G08 P, ...: :data:`nc.dialect.PASSIVE`) are passed over with
their own parameter words and counted in :attr:`Program.ignored`; with
``strict=True`` they are refused unless the caller lists them in ``allow``.
Codes that move the tool in ways the reader does not model (canned cycles,
cutter compensation, splines...) are refused, and cannot be allowed.

Frame and reference codes are modelled as LinuxCNC does (:mod:`nc.frames`):
G92/G92.1/G92.2/G92.3, G52, G10 L2/L20, G53, G28/G30 (through the
intermediate point; to the machine's point when ``reference_points`` gives
it, else to a position not known, NaN, until absolute coordinates come
again) and G28.1/G30.1.

Anything else is refused with an :class:`~nc.errors.NCParseError` naming the
file, line and column; Siemens, Heidenhain and Fanuc macro B programs with a
sentence that names the dialect as not supported yet.

The execution order inside a block follows LinuxCNC (feed mode, F, S, T, M6,
spindle, plane, units, tool length, work offset, distance mode, motion), so a
block ``G20 X1`` moves to one inch.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from . import constants as K
from .arcs import ArcWordError, arc_from_words
from .dialect import (
    ALLOWABLE_EXAMPLES,
    AXIS_INDEX,
    AXIS_LETTERS,
    BASE_WORDS,
    G_GROUPS,
    M_GROUPS,
    MOTION_CODES,
    PARAM_WORDS,
    PASSIVE,
    STRICT_REFUSED,
    code_key,
    code_name,
    normalise_allow,
    why_not,
)
from .errors import NCParseError
from .frames import Frames, reference_table
from .lexer import (TOKEN, blank_comments, find_token, foreign_syntax, raw_column,
                    token_column)
from .program import TCP_ANGLES, TCP_OFF, TCP_VECTOR, Modal, Program

__all__ = ["read_program", "parse_program", "ALLOWABLE_EXAMPLES"]

def _convert(pos: list[float], old: list[float], new: list[float]) -> list[float]:
    """The same machine position in a frame whose offset changed from ``old`` to ``new``."""
    return [p if o == n else p + o - n for p, o, n in zip(pos, old, new)]


_PROGRAM_NUMBER = re.compile(r"(\d+)\s*(?:\([^()]*\)\s*)?")

#: Codes commonly worth allowing in CAM output, for the CLI help and docs.
def _offset_table(work_offsets: Mapping[str, Sequence[float]] | None) -> np.ndarray:
    """G54...G59 offsets from ``{"G55": (x, y, z[, a, b, c])}`` [mm, deg]."""
    table = np.zeros((6, 6))
    for key, value in (work_offsets or {}).items():
        m = re.fullmatch(r"G5([4-9])", str(key).strip().upper())
        if not m:
            raise ValueError(f"work_offsets: key {key!r} must be one of G54...G59")
        v = np.asarray(value, dtype=float)
        if v.ndim != 1 or v.size not in (3, 6) or not np.all(np.isfinite(v)):
            raise ValueError(f"work_offsets[{key!r}]: expected 3 or 6 finite numbers "
                             f"(x y z [mm], a b c [deg]), got {value!r}")
        row = int(m.group(1)) - 4
        table[row, :3] = v[:3]
        if v.size == 6:
            table[row, 3:] = np.radians(v[3:])
    return table


def read_program(path: str | os.PathLike, **options) -> Program:
    """Read a G-code file; see :func:`parse_program` for ``options``.

    Raises
    ------
    NCParseError
        Naming the file, line and column, for anything outside the dialect
        and for bytes that are not text.
    """
    name = os.fspath(path)
    with open(name, "rb") as fh:
        data = fh.read()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        col = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise NCParseError("expected text (UTF-8 or ASCII), found a non-text byte "
                           f"0x{data[exc.start]:02x}", file=name, line=line,
                           column=col) from None
    if text.startswith("\ufeff"):  # a byte-order mark some editors write: not code
        text = text[1:]
    return parse_program(text, file=name, **options)


def parse_program(
    text: str,
    *,
    file: str = "<string>",
    allow: Iterable[str] = (),
    block_delete: bool = False,
    work_offsets: Mapping[str, Sequence[float]] | None = None,
    strict: bool = False,
    reference_points: Mapping[str, Sequence[float]] | None = None,
) -> Program:
    """Interpret G-code text.

    Parameters
    ----------
    text : str
        The program.
    file : str
        Name used in error messages and kept in the result.
    allow : iterable of str
        Codes (``"G64"``, ``"M8"``) that may appear and are passed over, beyond
        those passed over anyway (:data:`nc.dialect.PASSIVE`: coolant, clamps,
        dwell, path blending, look-ahead...). Every code passed over is
        counted in :attr:`Program.ignored`.
    block_delete : bool
        Skip lines that start with ``/`` (the operator's block-delete switch);
        when False they run like any other line.
    work_offsets : mapping, optional
        ``{"G55": (x, y, z)}`` or ``(x, y, z, a, b, c)`` [mm, deg]: the work
        offset table, used by :attr:`Program.end_machine`.
    strict : bool
        Refuse what the reader once refused: codes that do nothing here
        (coolant, G64...) unless listed in ``allow``, and the frame and
        reference codes (G10, G28, G30, G52, G53, G92) and G95.
    reference_points : mapping, optional
        ``{"G28": (x, y, z)}`` or ``(x, y, z, a, b, c)`` [mm, deg]: the machine's
        G28 and G30 points in machine coordinates. Where a program goes to a
        point not given here, the axes it sends there are unknown (NaN in
        :attr:`Program.end`, False in :attr:`Program.known`) until absolute
        coordinates give them a value again (see :mod:`nc.frames`).

    Returns
    -------
    Program
    """
    return _Interpreter(text, file, normalise_allow(allow), block_delete,
                        _offset_table(work_offsets), strict,
                        reference_table(reference_points)).run()


# ---------------------------------------------------------------------------
class _Interpreter:
    """One pass over the lines; appends columns as plain Python lists."""

    def __init__(self, text: str, file: str, allow: dict[str, set[int]],
                 block_delete: bool, offsets: np.ndarray, strict: bool = False,
                 references: dict | None = None) -> None:
        # split on "\n" only, as controls count lines (str.splitlines would also
        # split on form feeds and other separators and shift line numbers)
        lines = text.split("\n")
        if lines and lines[-1] == "":
            lines.pop()
        self.newline = "\n"
        if "\r" in text:
            self.newline = "\r\n" if "\r\n" in text[:65536] else "\n"
            lines = [ln[:-1] if ln.endswith("\r") else ln for ln in lines]
        self.lines = lines
        self.file = file
        self.allow = allow
        self.allowed_names = frozenset(
            code_name(letter, k) for letter, ks in allow.items() for k in ks)
        self.block_delete = block_delete
        self.offsets = offsets
        self.strict = strict
        self.frames = Frames(offsets, references or reference_table(None))
        #: distinct offsets program -> machine [mm, rad] (Modal.frame indexes them)
        self.frame_rows: list[list[float]] = []
        #: line of the G28/G30 that made the position unknown
        self.unknown_line = 0
        self.number: str | None = None
        #: code name -> [count, first line] of codes passed over
        self.ignored: dict[str, list[int]] = {}

    # -- errors -----------------------------------------------------------
    def _error(self, lineno: int, message: str, token: int | None = None,
               column: int | None = None) -> NCParseError:
        raw = self.lines[lineno - 1]
        if token is not None and column is None:
            column = token_column(raw, token)
        return NCParseError(message, file=self.file, line=lineno, column=column, text=raw)

    def _word_error(self, lineno: int, toks: list, letter: str, message: str) -> NCParseError:
        idx = next((i for i, t in enumerate(toks) if t[0] == letter), None)
        return self._error(lineno, message, token=idx)

    # -- main loop -------------------------------------------------------
    def run(self) -> Program:  # noqa: C901 - one flat loop is the fast form
        lines = self.lines
        findall = TOKEN.findall
        axis_index = AXIS_INDEX
        max_word = K.MAX_ABS_WORD_VALUE
        allow_g, allow_m = self.allow["G"], self.allow["M"]

        # modal state
        plane, units, distance, arc_distance, feed_mode = 17, 21, 90, 911, 94
        spindle_rpm, spindle_dir, tool, selected, length_offset, tcp, wcs = (
            0.0, 0, 0, 0, 0, TCP_OFF, 1)
        motion_mode: int | None = None
        feed = math.nan
        scale = 1.0
        tv = (math.nan, math.nan, math.nan)
        pos = [0.0] * 6
        frames = self.frames
        total = frames.total(wcs)
        frame_id = self._frame_id(total)
        reframe = False  # the position was converted to a new frame since the last row
        rotary_used = False
        reframed: list[int] = []
        reframed_start: list[float] = []
        machine_rows: list[int] = []
        modal_ids: dict[tuple, int] = {}
        modals: list[Modal] = []
        modal_id = -1
        dirty = True

        # output columns
        out_line: list[int] = []
        out_motion: list[int] = []
        out_end: list[float] = []
        out_feed: list[float] = []
        out_modal: list[int] = []
        out_tv: list[float] = []
        out_arc: list[int] = []
        arc_centre: list[float] = []
        arc_radius: list[float] = []
        arc_sweep: list[float] = []
        arc_plane: list[int] = []

        percent_seen = False
        first_content = True
        ended = False
        for lineno0, raw in enumerate(lines):
            lineno = lineno0 + 1
            s = raw.strip()
            if not s:
                continue
            if ended:
                if s == "%":
                    break
                continue  # after M2/M30 the control reads no further
            c0 = s[0]
            if c0 == "%":
                if first_content:
                    # the tape start, maybe with a name: '%_N_PART_MPF' (Siemens),
                    # '%PM' / '%1234' (other controls' headers)
                    if s.rstrip().endswith("*"):
                        raise self._error(lineno, foreign_syntax(s.upper()), column=1)
                    percent_seen = True
                    first_content = False
                    continue
                if s.strip("% \t") and not s.lstrip("%").lstrip().startswith("("):
                    raise self._error(lineno, "expected '%' alone on its line", column=1)
                break  # the closing '%': the tape ends here
            if first_content and c0 == "$":
                # Okuma's header '$NAME.MIN%': the tape start with the file's name
                percent_seen = True
                first_content = False
                continue
            if c0 == ":" and s[1:2].isdigit():
                # Fanuc's ISO program number ':1234' (the EIA 'O')
                m = _PROGRAM_NUMBER.fullmatch(s[1:])
                if m is None:
                    raise self._error(lineno, "expected a program number ':1234' alone on "
                                      "its line", column=raw.index(":") + 1)
                self.number = m.group(1)
                first_content = False
                continue
            first_content = False
            if c0 == "/":
                if self.block_delete:
                    continue
                s = s[1:]
            if "(" in s or ";" in s:
                s = self._strip_comments(s, lineno)
            s = s.upper()
            toks = findall(s)
            if not toks:
                continue

            # -- words ----------------------------------------------------
            gs: list[str] | None = None
            ms: list[str] | None = None
            w: dict[str, str] = {}
            for i, (letter, num, bad) in enumerate(toks):
                if bad:
                    raise self._bad_token(lineno, i, bad, s)
                if letter == "G":
                    if gs is None:
                        gs = [num]
                    else:
                        gs.append(num)
                elif letter == "M":
                    if ms is None:
                        ms = [num]
                    else:
                        ms.append(num)
                elif letter in w:
                    raise self._error(lineno, f"word {letter} appears twice in one block; "
                                      "expected each word at most once", token=i)
                else:
                    w[letter] = num

            if "O" in w:
                if len(toks) != 1 or gs or ms:
                    raise self._word_error(lineno, toks, "O", "expected an O program number "
                                           "alone on its line (O-word subroutines are not "
                                           "supported)")
                self.number = w["O"]
                continue

            gcodes: dict[str, int] = {}
            mcodes: dict[str, int] = {}
            allowed_here = False
            owned = ""
            if gs is not None:
                gcodes, owned, allowed_here = self._group_codes(lineno, toks, "G", gs,
                                                                G_GROUPS, allow_g, w)
            if ms is not None:
                mcodes, owned_m, allowed_m = self._group_codes(lineno, toks, "M", ms,
                                                               M_GROUPS, allow_m, w)
                allowed_here = allowed_here or allowed_m
                owned += owned_m
            pvals = self._take_words(lineno, toks, w, owned) if owned else None

            # values; axis words are noted on the way
            vals: dict[str, float] = {}
            axes: list[tuple[int, float]] | None = None
            for letter, num in w.items():
                if letter not in BASE_WORDS and not (allowed_here and letter in PARAM_WORDS):
                    raise self._word_error(lineno, toks, letter,
                                           f"unknown word {letter}; expected one of "
                                           "N G M X Y Z A B C I J K R F S T H P")
                v = float(num)
                if not abs(v) <= max_word:
                    raise self._word_error(lineno, toks, letter,
                                           f"{letter}{num} is out of range; expected |value| "
                                           f"<= {max_word:g}")
                vals[letter] = v
                k = axis_index.get(letter)
                if k is not None:
                    if axes is None:
                        axes = [(k, v)]
                    else:
                        axes.append((k, v))

            changed = False
            # 1. feed mode, F, S, T, M6, spindle
            if gcodes:
                fm = gcodes.get("feed_mode")
                if fm is not None and fm // 10 != feed_mode:
                    feed_mode = fm // 10
                    feed = math.nan  # LinuxCNC: a new feed mode needs a new F
                    changed = True
            if "F" in vals:
                f = vals["F"]
                if f < 0:
                    raise self._word_error(lineno, toks, "F", "negative feed; expected F >= 0")
                feed = f * (1.0 if feed_mode == 93 else scale)
            if "S" in vals:
                if vals["S"] < 0:
                    raise self._word_error(lineno, toks, "S",
                                           "negative spindle speed; expected S >= 0")
                spindle_rpm = vals["S"]
                changed = True
            if "T" in vals:
                t = vals["T"]
                if t < 0 or t != int(t):
                    raise self._word_error(lineno, toks, "T",
                                           "expected a tool number: a whole number >= 0")
                selected = int(t)
            if mcodes:
                if "toolchange" in mcodes:
                    tool = selected
                    changed = True
                sp = mcodes.get("spindle")
                if sp is not None:
                    spindle_dir = {30: 1, 40: -1, 50: 0}[sp]
                    changed = True
            # 2. plane, units, tool length, wcs, distance
            if gcodes:
                v = gcodes.get("plane")
                if v is not None:
                    plane = v // 10
                    changed = True
                v = gcodes.get("units")
                if v is not None:
                    units = v // 10
                    scale = K.MM_PER_INCH if units == 20 else 1.0
                    changed = True
                    if "F" in vals and feed_mode != 93:
                        feed = vals["F"] * scale
                v = gcodes.get("length")
                if v is not None:
                    changed = True
                    if v == 490:
                        length_offset, tcp = 0, TCP_OFF
                        if "H" in vals:
                            raise self._word_error(lineno, toks, "H", "H word with G49; "
                                                   "expected H only with G43, G43.4, G43.5")
                    else:
                        h = vals.get("H", float(tool))
                        if h < 0 or h != int(h):
                            raise self._word_error(lineno, toks, "H",
                                                   "expected an H number: a whole number >= 0")
                        length_offset = int(h)
                        tcp = {430: TCP_OFF, 434: TCP_ANGLES, 435: TCP_VECTOR}[v]
                        if tcp != TCP_VECTOR:
                            tv = (math.nan, math.nan, math.nan)
                elif "H" in vals:
                    raise self._word_error(lineno, toks, "H", "H word without G43, G43.4 "
                                           "or G43.5; expected it with a tool length code")
                v = gcodes.get("wcs")
                if v is not None:
                    if v // 10 - 53 != wcs:
                        wcs = v // 10 - 53
                        new_total = frames.total(wcs)
                        if new_total != total:  # the tool stays: convert its position
                            pos = _convert(pos, total, new_total)
                            total, frame_id, reframe = new_total, self._frame_id(new_total), True
                    changed = True
                v = gcodes.get("distance")
                if v is not None:
                    distance = v // 10
                    changed = True
                v = gcodes.get("arc_distance")
                if v is not None:
                    arc_distance = v
                    changed = True
                v = gcodes.get("motion")
                if v is not None:
                    motion_mode = MOTION_CODES[v]
                elif "cycle" in gcodes:
                    motion_mode = None  # G80 alone: no motion mode (LinuxCNC)
            elif "H" in vals:
                raise self._word_error(lineno, toks, "H", "H word without G43, G43.4 or "
                                       "G43.5; expected it with a tool length code")
            if changed:
                dirty = True

            fc = gcodes.get("frame") if gcodes else None
            if fc is not None and fc != 530:
                # G10, G28/G30 (.1), G52, G92 (.1 .2 .3): the axis words are theirs
                if tcp != TCP_OFF:
                    raise self._error(lineno, f"{code_name('G', fc)} under tool centre "
                                      "point control; expected G49 first",
                                      token=find_token(toks, "G", gs[0]))
                named = [(i, v * scale if i < 3 else math.radians(v)) for i, v in axes or ()]
                rotary_used = rotary_used or any(i >= 3 for i, _ in named)
                for c in ("I", "J", "K", "R", "P"):
                    if c in vals:
                        raise self._word_error(lineno, toks, c, f"{c} word with "
                                               f"{code_name('G', fc)}; expected axis words only")
                if fc in (280, 300):
                    mid, end = frames.home(fc, named, distance == 91, pos, wcs, rotary_used)
                    if not all(e == e for e in end):
                        self.unknown_line = lineno
                    if dirty:
                        modal_id = self._modal_id(modal_ids, modals, (
                            plane, units, distance, arc_distance, feed_mode, spindle_rpm,
                            spindle_dir, tool, length_offset, tcp, wcs, frame_id))
                        dirty = False
                    for row in (mid, end):
                        if reframe:
                            reframed.append(len(out_line))
                            reframed_start.extend(pos)
                            reframe = False
                        out_line.append(lineno)
                        out_motion.append(0)
                        out_end.extend(row)
                        out_feed.append(feed)
                        out_modal.append(modal_id)
                        out_tv.extend(tv)
                        out_arc.append(-1)
                    machine_rows.append(len(out_line) - 1)
                    pos = end
                else:
                    old_total = total
                    if fc in (281, 301):
                        if named:
                            raise self._error(lineno, "axis words with G28.1/G30.1; "
                                              "expected none", token=find_token(toks, "G", gs[0]))
                        frames.store_reference(fc, pos, wcs)
                    elif fc == 100:
                        self._g10(lineno, toks, pvals, named, pos, wcs)
                    else:
                        msg = frames.g92(fc, named, pos)
                        if msg is not None:
                            raise self._error(lineno, msg, token=find_token(toks, "G", gs[0]))
                    new_total = frames.total(wcs)
                    if new_total != old_total:
                        pos = _convert(pos, old_total, new_total)
                        total, frame_id, reframe, dirty = (
                            new_total, self._frame_id(new_total), True, True)
                    if fc == 920:  # the named axes read the given values, known or not
                        for i, v in named:
                            pos[i] = v
                if mcodes and mcodes.get("stop") in (20, 300):
                    ended = True
                continue

            # 3. motion
            has_axes = axes is not None
            explicit_motion = gcodes.get("motion") is not None if gcodes else False
            vector_words = tcp == TCP_VECTOR and motion_mode in (0, 1) and (
                "I" in vals or "J" in vals or "K" in vals)
            if not (has_axes or vector_words or (explicit_motion and motion_mode is not None)):
                for c in ("I", "J", "K", "R"):
                    if c in vals:
                        raise self._word_error(lineno, toks, c, f"{c} word with no arc; "
                                               "expected it in a G2/G3 block")
                if "P" in vals and not allowed_here:
                    raise self._word_error(lineno, toks, "P",
                                           "P word with nothing to use it")
                if mcodes and mcodes.get("stop") in (20, 300):
                    ended = True
                continue
            if motion_mode is None:
                col_letter = next(c for c in "XYZABCIJK" if c in vals)
                raise self._word_error(lineno, toks, col_letter,
                                       "axis words without a motion mode; expected G0, G1, "
                                       "G2 or G3 in effect (G80 cancels it)")

            start = pos
            new = pos[:]
            inc = distance == 91
            if fc == 530:  # G53: this block's axis words are machine coordinates
                if motion_mode not in (0, 1) or inc or tcp != TCP_OFF:
                    raise self._error(lineno, "G53 needs G0 or G1, G90 and no tool centre "
                                      "point control", token=find_token(toks, "G", gs[0]))
                for i, v in axes or ():
                    v = v * scale if i < 3 else math.radians(v)
                    new[i] = frames.machine_to_program(i, v, wcs)
                machine_rows.append(len(out_line))
            elif axes is not None:
                for i, v in axes:
                    if i < 3:
                        v *= scale
                    else:
                        if tcp == TCP_VECTOR:
                            c = AXIS_LETTERS[i]
                            raise self._word_error(lineno, toks, c, f"rotary word {c} under "
                                                   "G43.5; expected the tool vector as I J K")
                        v = math.radians(v)
                        rotary_used = True
                    new[i] = new[i] + v if inc else v

            if motion_mode >= 2:
                if not (start[0] == start[0] and start[1] == start[1] and start[2] == start[2]
                        and new[0] == new[0] and new[1] == new[1] and new[2] == new[2]):
                    raise self._error(lineno, "arc at a position that is not known (after "
                                      f"G28/G30 at line {self.unknown_line}, whose point was "
                                      "not given); expected an absolute move in X Y Z first, "
                                      "or the machine's reference point")
                try:
                    arc = arc_from_words(vals, motion_mode, plane, scale, arc_distance,
                                         start, new)
                except ArcWordError as exc:
                    if exc.letter is None:
                        raise self._error(lineno, str(exc)) from None
                    raise self._word_error(lineno, toks, exc.letter, str(exc)) from None
                out_arc.append(len(arc_sweep))
                arc_centre.extend(arc[0])
                arc_radius.extend(arc[1])
                arc_sweep.append(arc[2])
                arc_plane.append(plane)
            else:
                for c in ("R",):
                    if c in vals:
                        raise self._word_error(lineno, toks, c,
                                               "R word in a straight move; expected it with G2/G3")
                if vector_words:
                    tv = self._tool_vector(lineno, toks, vals, tv)
                elif ("I" in vals or "J" in vals or "K" in vals):
                    c = next(c for c in "IJK" if c in vals)
                    raise self._word_error(lineno, toks, c, f"{c} word in a straight move; "
                                           "expected I J K only in G2/G3 (or as the tool "
                                           "vector under G43.5)")
                if "P" in vals and not allowed_here:
                    raise self._word_error(lineno, toks, "P", "P word in a straight move")
                out_arc.append(-1)

            if motion_mode != 0:
                if feed_mode == 93:
                    if "F" not in vals:
                        raise self._error(lineno, "F word missing in an inverse-time (G93) "
                                          "feed move; expected F in every G1/G2/G3 block")
                    if not feed > 0:
                        raise self._word_error(lineno, toks, "F",
                                               "inverse-time feed F0; expected F > 0")
                elif not feed > 0:
                    raise self._error(lineno, "cutting move with no feed; expected an F > 0 "
                                      "in this block or before it")
                elif feed_mode == 95 and not spindle_rpm > 0:
                    raise self._error(lineno, "feed per revolution (G95) with no spindle "
                                      "speed; expected an S > 0 in this block or before it")

            if dirty:
                key = (plane, units, distance, arc_distance, feed_mode, spindle_rpm,
                       spindle_dir, tool, length_offset, tcp, wcs, frame_id)
                modal_id = modal_ids.get(key, -1)
                if modal_id < 0:
                    modal_id = modal_ids[key] = len(modals)
                    modals.append(Modal(*key))
                dirty = False
            if reframe:
                reframed.append(len(out_line))
                reframed_start.extend(pos)
                reframe = False
            out_line.append(lineno)
            out_motion.append(motion_mode)
            out_end.extend(new)
            out_feed.append(feed)
            out_modal.append(modal_id)
            out_tv.extend(tv)
            pos = new
            if mcodes and mcodes.get("stop") in (20, 300):
                ended = True

        n = len(out_line)
        m = len(arc_sweep)
        return Program(
            file=self.file,
            lines=tuple(lines),
            line=np.array(out_line, dtype=np.int64),
            motion=np.array(out_motion, dtype=np.int8),
            end=np.array(out_end, dtype=float).reshape(n, 6),
            initial=np.zeros(6),
            feed=np.array(out_feed, dtype=float),
            modal_index=np.array(out_modal, dtype=np.int64),
            modals=tuple(modals),
            tool_vector=np.array(out_tv, dtype=float).reshape(n, 3),
            arc_index=np.array(out_arc, dtype=np.int64),
            arc_centre=np.array(arc_centre, dtype=float).reshape(m, 3),
            arc_radius=np.array(arc_radius, dtype=float).reshape(m, 2),
            arc_sweep=np.array(arc_sweep, dtype=float),
            arc_plane=np.array(arc_plane, dtype=np.int64),
            work_offsets=self.offsets,
            number=self.number,
            frames=np.array(self.frame_rows, dtype=float).reshape(-1, 6),
            reframed=np.array(reframed, dtype=np.int64),
            reframed_start=np.array(reframed_start, dtype=float).reshape(-1, 6),
            machine_moves=np.array(machine_rows, dtype=np.int64),
            newline=self.newline,
            allowed=self.allowed_names,
            block_delete=self.block_delete,
            ignored=tuple((name, c, first) for name, (c, first) in
                          sorted(self.ignored.items(), key=lambda kv: (kv[1][1], kv[0]))),
            strict=self.strict,
        )

    # -- pieces ------------------------------------------------------------
    def _group_codes(self, lineno: int, toks: list, letter: str, nums: list[str],
                     groups: dict[int, str], allowed: set[int], w: dict[str, str]
                     ) -> tuple[dict[str, int], str, bool]:
        """The block's G (or M) codes by modal group; refuses unknown and clashing codes.

        Returns the codes by group, the parameter words owned by the codes
        passed over, and whether a code the caller allowed is in the block.
        """
        out: dict[str, int] = {}
        owned = ""
        allowed_here = False
        strict = self.strict
        for num in nums:
            key = code_key(letter, num)
            group = groups.get(key) if key is not None else None
            if group is not None and strict and letter == "G" and key in STRICT_REFUSED:
                group = None
            if group is None:
                passive = None if key is None else PASSIVE[letter].get(key)
                if key is not None and key in allowed:
                    allowed_here = True
                    self._note_ignored(letter, key, lineno)
                    if passive is not None:  # its words are its own (G04 X: seconds)
                        owned += self._passive_words(letter, key, passive[0], nums, w) or ""
                    continue
                if passive is not None and not strict:
                    words = self._passive_words(letter, key, passive[0], nums, w)
                    if words is not None:
                        owned += words
                        self._note_ignored(letter, key, lineno)
                        continue
                raise self._error(lineno, f"unknown or unsupported code {letter}{num}"
                                  + why_not(letter, key, strict),
                                  token=find_token(toks, letter, num))
            if group in out:
                raise self._error(lineno, f"two codes of the {group} group in one block; "
                                  "expected at most one", token=find_token(toks, letter, num))
            out[group] = key
            if key == 100:  # G10's L P R are its own
                owned += "LPR"
        return out, owned, allowed_here

    @staticmethod
    def _passive_words(letter: str, key: int, words: str, nums: list[str],
                       w: dict[str, str]) -> str | None:
        """The words a passed-over code owns here; None when it is not the passive code.

        G5 and G5.1 are Fanuc's high-speed modes (G05 P10000, G05.1 Q1) only
        without axis and I J words; otherwise they are LinuxCNC's splines.
        G4 owns X (Fanuc's dwell in seconds) only in a block without a motion code.
        """
        if letter == "G":
            if key in (50, 51):
                if words[0] not in w or any(c in w for c in "XYZABCIJ"):
                    return None
            elif key == 40 and any(code_key("G", n) in MOTION_CODES for n in nums):
                return "P"
        return words

    def _note_ignored(self, letter: str, key: int, lineno: int) -> None:
        name = code_name(letter, key)
        rec = self.ignored.get(name)
        if rec is None:
            self.ignored[name] = [1, lineno]
        else:
            rec[0] += 1

    def _take_words(self, lineno: int, toks: list, w: dict[str, str],
                    owned: str) -> dict[str, float]:
        """Remove the words owned by codes passed over (and G10's), checked in range."""
        out = {}
        for c in set(owned):
            num = w.pop(c, None)
            if num is not None:
                if not abs(float(num)) <= K.MAX_ABS_WORD_VALUE:
                    raise self._word_error(lineno, toks, c, f"{c}{num} is out of range; "
                                           f"expected |value| <= {K.MAX_ABS_WORD_VALUE:g}")
                out[c] = float(num)
        return out

    def _frame_id(self, total: list[float]) -> int:
        """Index of the offset ``total`` in :attr:`frame_rows` (NaN rows are never shared)."""
        for k, row in enumerate(self.frame_rows):
            if row == total:
                return k
        self.frame_rows.append(list(total))
        return len(self.frame_rows) - 1

    @staticmethod
    def _modal_id(modal_ids: dict, modals: list, key: tuple) -> int:
        modal_id = modal_ids.get(key, -1)
        if modal_id < 0:
            modal_id = modal_ids[key] = len(modals)
            modals.append(Modal(*key))
        return modal_id

    def _g10(self, lineno: int, toks: list, pvals: dict[str, float],
             named: list[tuple[int, float]], pos: list[float], wcs: int) -> None:
        """G10 L2 / L20 (work offsets); L1/L10/L11 (tool table) are passed over."""
        level = pvals.get("L")
        if level in (1.0, 10.0, 11.0):
            self._note_ignored("G", 100, lineno)
            return
        if level not in (2.0, 20.0):
            raise self._word_error(lineno, toks, "L" if level is not None else "G",
                                   "expected G10 L2 or L20 (work offsets; L1/L10/L11 for "
                                   "the tool table are passed over)")
        number = pvals.get("P", 0.0)
        if number != int(number) or not 0 <= number <= 6:
            raise self._word_error(lineno, toks, "P", "expected P0...P6 (0 the active "
                                   "system, 1...6 G54...G59; G59.1-G59.3 are not supported)")
        if pvals.get("R", 0.0) != 0.0:
            raise self._word_error(lineno, toks, "R", "rotation of a work offset (G10 R) "
                                   "is not supported; expected R0 or none")
        msg = self.frames.g10(int(level), int(number), named, pos, wcs)
        if msg is not None:
            raise self._word_error(lineno, toks, "G", msg)

    def _strip_comments(self, s: str, lineno: int) -> str:
        out = []
        i = 0
        n = len(s)
        while i < n:
            c = s[i]
            if c == "(":
                j = s.find(")", i + 1)
                if j < 0:
                    raise self._error(lineno, "comment not closed; expected ')'",
                                      column=raw_column(self.lines[lineno - 1], s, i))
                if "(" in s[i + 1:j]:
                    raise self._error(lineno, "nested comment; expected ')' before '('",
                                      column=raw_column(self.lines[lineno - 1], s,
                                                         s.index("(", i + 1)))
                out.append(" ")
                i = j + 1
            elif c == ";":
                break
            elif c == ")":
                raise self._error(lineno, "')' without '('",
                                  column=raw_column(self.lines[lineno - 1], s, i))
            else:
                out.append(c)
                i += 1
        return "".join(out)

    def _bad_token(self, lineno: int, i: int, bad: str, s: str) -> NCParseError:
        raw = self.lines[lineno - 1]
        blank = blank_comments(raw)
        foreign = foreign_syntax(blank)
        if foreign is not None:
            return self._error(lineno, foreign, column=len(blank) - len(blank.lstrip()) + 1)
        if "#" in blank or "[" in blank:
            col = min(k for k in (blank.find("#"), blank.find("[")) if k >= 0) + 1
            return self._error(lineno, "parameters and expressions ('#', '[') are not "
                               "supported; expected plain numbers", column=col)
        if s.startswith("O"):
            return self._error(lineno, "O-word subroutines and control flow are not "
                               "supported; expected O and a number alone (a program number)",
                               column=blank.find("O") + 1)
        if bad.isalpha():
            msg = f"expected a number after {bad}"
        elif bad in "#[":
            msg = ("parameters and expressions ('#', '[') are not supported; "
                   "expected plain numbers")
        elif bad == "%":
            msg = "expected '%' alone on its line"
        else:
            msg = f"unexpected character {bad!r}; expected a letter followed by a number"
        return self._error(lineno, msg, token=i)

    def _tool_vector(self, lineno, toks, vals, tv):
        vec = [vals.get(c, tv[k] if not math.isnan(tv[k]) else 0.0)
               for k, c in enumerate("IJK")]
        norm = math.sqrt(vec[0] ** 2 + vec[1] ** 2 + vec[2] ** 2)
        if not norm > 1e-9:
            raise self._word_error(lineno, toks, next(c for c in "IJK" if c in vals),
                                   "tool vector I J K of zero length; expected a direction")
        return (vec[0] / norm, vec[1] / norm, vec[2] / norm)
