"""The reader's per-block pieces: errors, code groups, words, comments.

:class:`BlockReader` is the base of :class:`nc.gcode_interp.Interpreter`; it holds
what the reader does for one block away from its main loop (refusing
unknown and clashing codes, taking the words of codes passed over, G10,
comments, the sentence for a bad token), so that the loop stays one flat,
fast function.
"""

from __future__ import annotations

import math

from . import constants as K
from .dialect import MOTION_CODES, PASSIVE, STRICT_REFUSED, code_key, code_name, why_not
from .errors import NCParseError
from .frames import Frames, convert_position
from .lexer import blank_comments, find_token, foreign_syntax, raw_column, token_column
from .program import Modal

__all__ = ["BlockReader"]


class BlockReader:
    """Per-block helpers; the subclass sets ``lines``, ``file``, ``strict``,
    ``frames``, ``frame_rows`` and ``ignored``."""

    lines: list[str]
    source: list[str]
    source_lines: list[int] | None
    rewritten: set[int]
    file: str
    strict: bool
    frames: Frames
    frame_rows: list[list[float]]
    ignored: dict[str, list[int]]
    unknown_line: int

    def _error(self, lineno: int, message: str, token: int | None = None,
               column: int | None = None) -> NCParseError:
        raw = self.lines[lineno - 1]
        same = (self.source[lineno - 1] is raw if self.source_lines is None
                else lineno not in self.rewritten)
        if token is not None and column is None and same:
            column = token_column(raw, token)  # (an expanded line's tokens are not raw's)
        if column is None:  # the block as a whole: its first character
            column = len(raw) - len(raw.lstrip()) + 1
        return NCParseError(message, file=self.file, line=lineno, column=column, text=raw)

    def _word_error(self, lineno: int, toks: list, letter: str, message: str) -> NCParseError:
        idx = next((i for i, t in enumerate(toks) if t[0] == letter), None)
        return self._error(lineno, message, token=idx)

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
        if not named and "R" not in pvals:
            raise self._word_error(lineno, toks, "G", "expected axis words (or R0) with G10 "
                                   "L2 / L20")
        self.frames.g10(int(level), int(number), named, pos, wcs)

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

    def _frame_block(self, fc: int, lineno: int, toks: list, gs: list[str],
                     vals: dict[str, float], axes: list | None, pvals: dict | None,
                     scale: float, inc: bool, pos: list[float], wcs: int, tcp: int,
                     total: list[float], rotary_used: bool
                     ) -> tuple[list, list[float], list[float] | None, bool]:
        """G10, G28/G30 (.1), G52, G92 (.1 .2 .3): their axis words are theirs.

        Returns the rows to emit (G28/G30: the start, then the intermediate
        point and the end), the position after the block, the new total
        offset (None when unchanged) and whether rotary axes were named.
        """
        frames = self.frames
        if tcp != 0:
            raise self._error(lineno, f"{code_name('G', fc)} under tool centre point "
                              "control; expected G49 first", token=find_token(toks, "G", gs[0]))
        named = [(i, v * scale if i < 3 else math.radians(v)) for i, v in axes or ()]
        rotary_used = rotary_used or any(i >= 3 for i, _ in named)
        for c in ("I", "J", "K", "R", "P"):
            if c in vals:
                raise self._word_error(lineno, toks, c, f"{c} word with {code_name('G', fc)}; "
                                       "expected axis words only")
        if fc in (280, 300):
            mid, end = frames.home(fc, named, inc, pos, wcs, rotary_used)
            if not all(e == e for e in end):
                self.unknown_line = lineno
            return [pos, mid, end], end, None, rotary_used
        if fc in (281, 301):
            if named:
                raise self._error(lineno, "axis words with G28.1/G30.1; expected none",
                                  token=find_token(toks, "G", gs[0]))
            frames.store_reference(fc, pos, wcs)
        elif fc == 100:
            self._g10(lineno, toks, pvals or {}, named, pos, wcs)
        else:
            msg = frames.g92(fc, named, pos)
            if msg is not None:
                raise self._error(lineno, msg, token=find_token(toks, "G", gs[0]))
        new_total = frames.total(wcs)
        changed = new_total != total
        if changed:
            pos = convert_position(pos, total, new_total)
        if fc == 920:  # the named axes read the given values, known or not
            pos = pos[:]
            for i, v in named:
                pos[i] = v
        return [], pos, new_total if changed else None, rotary_used
