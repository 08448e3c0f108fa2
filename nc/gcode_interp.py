"""The G-code reader's interpreter: straight-line blocks into a :class:`~nc.program.Program`.

:mod:`nc.gcode` reads the file and runs its control flow first (LinuxCNC
O-words, Fanuc macro B, ``#`` parameters) into a
:class:`~nc.gcode_source.Source`, the straight-line lines each with its source line; :class:`Interpreter` then
makes one pass over them in one flat loop (the fast form), in LinuxCNC's
in-block execution order, and appends the program's columns as plain Python
lists. What it does for one block away from the loop is in its bases:
:class:`~nc.blockreader.BlockReader` (errors, code groups, frame codes),
:class:`~nc.cycles.CycleBlocks` (canned cycles) and
:class:`~nc.rotation.RotationBlocks` (G68, G68.2, G53.1). The dialect it
reads is described in :mod:`nc.gcode`.
"""

from __future__ import annotations

import math
import re

import numpy as np

from . import constants as K
from .arcs import ArcWordError, arc_from_words
from .blockreader import BlockReader
from .cycles import CycleBlocks, CycleState
from .dialect import (
    AXIS_INDEX,
    AXIS_LETTERS,
    BASE_WORDS,
    CYCLE_WORDS,
    G_GROUPS,
    M_GROUPS,
    MOTION_CODES,
    PARAM_WORDS,
    code_key,
    code_name,
)
from .frames import Frames, convert_position, reference_table
from .lexer import TOKEN, find_token, foreign_syntax
from .program import TCP_ANGLES, TCP_OFF, TCP_VECTOR, Modal, Program, ProgramRows
from .gcode_source import Source
from .rotation import RotationBlocks, RotationError

__all__ = ["Interpreter"]

#: Fanuc's ISO program number after ':' (digits, maybe a comment)
_PROGRAM_NUMBER = re.compile(r"(\d+)\s*(?:\([^()]*\)\s*)?")


class Interpreter(BlockReader, CycleBlocks, RotationBlocks, ProgramRows):
    """One pass over the lines; appends columns as plain Python lists."""

    def __init__(self, src: Source, file: str, allow: dict[str, set[int]],
                 block_delete: bool, offsets: np.ndarray, strict: bool = False,
                 references: dict | None = None) -> None:
        self.lines = src.lines
        self.newline = src.newline
        self.source = src.source
        #: source line number of each line of self.source, when they differ (O-words,
        #: macro B)
        self.source_lines = src.source_lines
        #: source lines whose expanded text is not the source line
        self.rewritten = src.rewritten if src.rewritten is not None else set()
        #: line of the M99 that ended the main program (nc.macro_b), 0 if none
        self.main_m99_line = src.main_m99_line
        #: line of the O program the main program ran into (nc.macro_b), 0 if none
        self.main_open_end_line = src.main_open_end_line
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
        #: chords tilted arcs may still make (nc.rotation)
        self.chord_budget = K.MAX_TILTED_ARC_CHORDS
        #: code name -> [count, first line] of codes passed over
        self.ignored: dict[str, list[int]] = {}

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
        base_motion: int | None = None  # the G0...G3 mode a canned cycle leaves standing
        cycle = CycleState()  # canned cycles (nc.cycles): sticky words, initial level
        retract_to_r = False  # G99 (else G98)
        rot = None  # G68/G68.2 in effect, or G53.1's tool axis held (nc.rotation)
        drilling: list[int] = []  # rows made by canned cycles
        rotated: list[int] = []  # rows under G68/G68.2/G53.1
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

        first_content = True
        ended = False
        numbers = self.source_lines or range(1, len(self.source) + 1)
        for lineno, raw in zip(numbers, self.source):
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
                    first_content = False
                    continue
                if s.strip("% \t") and not s.lstrip("%").lstrip().startswith("("):
                    raise self._error(lineno, "expected '%' alone on its line", column=1)
                break  # the closing '%': the tape ends here
            if first_content and c0 == "$":
                # Okuma's header '$NAME.MIN%': the tape start with the file's name
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
                if letter not in BASE_WORDS and not (allowed_here and letter in PARAM_WORDS) \
                        and not (letter in CYCLE_WORDS and self._cycle_words(gcodes,
                                                                             motion_mode)):
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
                if 0 < f < K.MIN_FEED:
                    raise self._word_error(lineno, toks, "F", f"feed F{w['F']} below "
                                           f"{K.MIN_FEED:g}; expected F0 or F >= {K.MIN_FEED:g}")
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
                            pos = convert_position(pos, total, new_total)
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
                    if motion_mode < 4:
                        base_motion = motion_mode
                        cycle.leave()
                    elif "cycle" in gcodes:
                        raise self._error(lineno, "G80 with a canned cycle in one block; "
                                          "expected one of them", token=find_token(
                                              toks, "G", next(g for g in gs if code_key(
                                                  "G", g) == 800)))
                elif "cycle" in gcodes:
                    # G80 alone: the cycles are a modal group of their own on Fanuc
                    # (group 09), so the G0...G3 mode in effect before moves again;
                    # LinuxCNC refuses axis words here, its programs never have them
                    motion_mode = base_motion
                    cycle.leave()
                v = gcodes.get("retract")
                if v is not None:
                    retract_to_r = v == 990
            elif "H" in vals:
                raise self._word_error(lineno, toks, "H", "H word without G43, G43.4 or "
                                       "G43.5; expected it with a tool length code")
            if changed:
                dirty = True

            fc = gcodes.get("frame") if gcodes else None
            if rot is not None or (gcodes and ("rotation" in gcodes or "orient" in gcodes)):
                rot, done = self._rotation(lineno, toks, gs, gcodes, vals, axes, pos, plane,
                                           scale, rot, tcp, fc)
                if done:
                    if mcodes and mcodes.get("stop") in (20, 300):
                        ended = True
                    continue
            if fc is not None and fc != 530:
                # G10, G28/G30 (.1), G52, G92 (.1 .2 .3): the axis words are theirs
                rows, pos, new_total, rotary_used = self._frame_block(
                    fc, lineno, toks, gs, vals, axes, pvals, scale, distance == 91, pos, wcs,
                    tcp, total, rotary_used)
                if new_total is not None:
                    total, frame_id, reframe, dirty = (
                        new_total, self._frame_id(new_total), True, True)
                if rows:  # G28/G30: to the intermediate point, then to the reference
                    if dirty:
                        modal_id = self._modal_id(modal_ids, modals, (
                            plane, units, distance, arc_distance, feed_mode, spindle_rpm,
                            spindle_dir, tool, length_offset, tcp, wcs, frame_id))
                        dirty = False
                    if reframe:
                        reframed.append(len(out_line))
                        reframed_start.extend(rows[0])
                        reframe = False
                    for row in rows[1:]:
                        out_line.append(lineno)
                        out_motion.append(0)
                        out_end.extend(row)
                        out_feed.append(feed)
                        out_modal.append(modal_id)
                        out_tv.extend(tv)
                        out_arc.append(-1)
                    machine_rows.append(len(out_line) - 1)
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
                                       "G2 or G3 in effect")

            if motion_mode > 3:  # a canned cycle: its moves, one row each
                before = pos
                moves, pos = self._cycle(lineno, toks, gs, fc, feed_mode, tcp, feed, motion_mode,
                                         vals, cycle, pos, plane, distance == 91, retract_to_r,
                                         scale, spindle_dir, rot)
                row_tv = tv
                if dirty or rot is not None:
                    modal_id = self._modal_id(modal_ids, modals, (
                        plane, units, distance, arc_distance, feed_mode, spindle_rpm,
                        spindle_dir, tool, length_offset,
                        TCP_VECTOR if rot is not None and rot.axis else tcp, wcs, frame_id))
                    dirty = rot is not None
                if rot is not None:
                    row_tv = rot.axis or tv
                if reframe and moves:
                    reframed.append(len(out_line))
                    reframed_start.extend(before)
                    reframe = False
                for motion, row in moves:
                    if rot is not None:
                        rotated.append(len(out_line))
                    drilling.append(len(out_line))
                    out_line.append(lineno)
                    out_motion.append(motion)
                    out_end.extend(row)
                    out_feed.append(feed)
                    out_modal.append(modal_id)
                    out_tv.extend(row_tv)
                    out_arc.append(-1)
                if mcodes and mcodes.get("stop") in (20, 300):
                    ended = True
                continue

            start = pos if rot is None else rot.to_program(pos)
            new = start[:]
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
                if rot is None:
                    out_arc.append(len(arc_sweep))
                    arc_centre.extend(arc[0])
                    arc_radius.extend(arc[1])
                    arc_sweep.append(arc[2])
                    arc_plane.append(plane)
            else:
                arc = None
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
                if rot is None:
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

            if rot is not None:  # G68/G68.2 or G53.1's tool axis: the rows in the program frame
                if reframe:
                    reframed.append(len(out_line))
                    reframed_start.extend(pos)
                    reframe = False
                modal_id = self._modal_id(modal_ids, modals, (
                    plane, units, distance, arc_distance, feed_mode, spindle_rpm, spindle_dir,
                    tool, length_offset, TCP_VECTOR if rot.axis else tcp, wcs, frame_id))
                dirty = True
                row_tv = rot.axis or tv
                try:
                    rrows = rot.rows(motion_mode, start, new, arc, plane, self.chord_budget)
                except RotationError as exc:
                    raise self._error(lineno, str(exc)) from None
                if arc is not None and rrows[0][2] is None:
                    self.chord_budget -= len(rrows)
                for motion, row, rarc in rrows:
                    if rarc is None:
                        out_arc.append(-1)
                    else:
                        out_arc.append(len(arc_sweep))
                        arc_centre.extend(rarc[0])
                        arc_radius.extend(rarc[1])
                        arc_sweep.append(rarc[2])
                        arc_plane.append(rarc[3])
                    rotated.append(len(out_line))
                    out_line.append(lineno)
                    out_motion.append(motion)
                    out_end.extend(row)
                    out_feed.append(feed)
                    out_modal.append(modal_id)
                    out_tv.extend(row_tv)
                    pos = row
                if mcodes and mcodes.get("stop") in (20, 300):
                    ended = True
                continue

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

        self.o_line, self.o_motion, self.o_end, self.o_feed = (out_line, out_motion, out_end,
                                                               out_feed)
        self.o_modal, self.o_tv, self.o_arc, self.modals = out_modal, out_tv, out_arc, modals
        self.a_centre, self.a_radius, self.a_sweep, self.a_plane = (arc_centre, arc_radius,
                                                                    arc_sweep, arc_plane)
        return self.build_program(
            self.file, tuple(lines), self.newline, self.number, self.block_delete, {},
            work_offsets=self.offsets,
            frames=np.array(self.frame_rows, dtype=float).reshape(-1, 6),
            reframed=np.array(reframed, dtype=np.int64),
            reframed_start=np.array(reframed_start, dtype=float).reshape(-1, 6),
            machine_moves=np.array(machine_rows, dtype=np.int64),
            drilling=np.array(drilling, dtype=np.int64),
            rotated=np.array(rotated, dtype=np.int64),
            allowed=self.allowed_names,
            ignored=tuple((name, c, first) for name, (c, first) in
                          sorted(self.ignored.items(), key=lambda kv: (kv[1][1], kv[0]))),
            strict=self.strict,
            main_m99_line=self.main_m99_line,
            main_open_end_line=self.main_open_end_line,
        )
