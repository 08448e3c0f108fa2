"""Canned drilling cycles (G73, G74, G81...G87, G89) expanded into moves, as LinuxCNC does.

A cycle block becomes the straight moves LinuxCNC's interpreter makes of it
(``interp_cycles.cc``; checked against its ``rs274`` in the tests), each a
row of the :class:`~nc.program.Program` (G0 at rapid, G1 at the programmed
feed) marked in :attr:`Program.drilling`. In the XY plane (G18 and G19 the
same with their axes: ``aa bb`` in the plane, ``cc`` along its normal):

* the *initial level* is Z when the cycles began (the first cycle block after
  another motion mode); G98 returns there, G99 to the R plane;
* first, when Z is below R, a rapid straight up to R; then per repeat (``L``;
  Fanuc's ``K``) a rapid to X Y (at the current Z on the first repeat, at the
  clearance level on the others) and down to R;
* G81 feed to Z, rapid out; G82 the same with a dwell; G83 pecks of ``Q``, a
  rapid out to the R plane after each and back to 0.254 mm (0.010 in)
  above the last depth; G73 pecks with a 0.254 mm rapid back-off; G85 feed in,
  feed out to R, rapid to the clearance level; G89 feed in, dwell, feed out;
  G86 feed in, dwell, spindle stop, rapid out; G74/G84 (tapping) feed in,
  spindle reversed, feed out; G87 (back boring) off the hole's axis by
  ``I J``, down at rapid, feed up to ``K`` and back;
* under G90 X Y R Z are absolute; under G91 X Y are increments per repeat, R
  is from the initial level and Z from R.

G88 is refused by the reader (the operator retracts the spindle by hand, so
no program can say where the tool is after it). Refused here, each with the
word and what is expected: G87 outside G17, rotary words in a cycle block, R below Z, a missing Z, R, P, Q or I J K when
the cycle starts, Q <= 0, inverse-time feed, tool centre point control, and
more than :data:`nc.constants.MAX_CYCLE_MOVES` moves from one block (or
:data:`~nc.constants.MAX_CYCLE_MOVES_PROGRAM` from all cycles of a program).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from . import constants as K
from .errors import NCParseError
from .lexer import find_token
from .program import PLANE_AXES, TCP_OFF, Program

__all__ = ["CYCLE_CODES", "CycleBlocks", "CycleError", "CycleState", "cycle_moves",
           "refuse_drilling"]

#: Motion-group keys (10 x G number) of the cycles -> motion mode (the G number).
CYCLE_CODES = {730: 73, 740: 74, 810: 81, 820: 82, 830: 83, 840: 84, 850: 85, 860: 86,
               870: 87, 890: 89}
_PECK = (73, 83)
_DWELL = (82, 86, 89)
_SPINDLE = {74: "counter-clockwise (M4)", 84: "clockwise (M3)"}


class CycleError(Exception):
    """A cycle block that cannot run; ``letter`` is the word to point at (or None)."""

    def __init__(self, message: str, letter: str | None = None) -> None:
        super().__init__(message)
        self.letter = letter


@dataclass
class CycleState:
    """What LinuxCNC keeps between cycle blocks (program units, not mm).

    ``mode`` is the cycle of the last cycle block while cycles go on (None
    once another motion mode came); ``initial`` the initial level (None
    likewise); ``z r p q i j k`` the sticky words.
    """

    mode: int | None = None
    initial: float | None = None
    z: float = math.nan
    r: float = math.nan
    p: float = 0.0
    q: float = math.nan
    i: float = math.nan
    j: float = math.nan
    k: float = math.nan
    #: the position the last cycle block left [mm, rad] and the same in
    #: program units (a b c of its plane), so that the next block compares
    #: the numbers LinuxCNC compares, not their round trip through mm
    last: tuple = ()
    #: moves made by cycles so far in the program
    made: int = 0

    def leave(self) -> None:
        """Another motion mode (G0...G3, G80): the next cycle starts afresh."""
        self.mode = None
        self.initial = None
        self.last = ()


def _repeats(vals: dict[str, float], code: int) -> int:
    """L (LinuxCNC, Haas) or K (Fanuc; not in G87, whose K is the top of the bore)."""
    letter = "L" if "L" in vals else ("K" if "K" in vals and code != 87 else None)
    if letter is None:
        return 1
    if "L" in vals and "K" in vals and code != 87:
        raise CycleError("both L and K given; expected the repeat count once (L, or "
                         "Fanuc's K)", "K")
    n = vals[letter]
    if n != int(n) or n < 0 or (n == 0 and letter == "L"):
        raise CycleError(f"{letter}{n:g}: expected the number of repeats, a whole number "
                         f">= 1" + (" (K0: the cycle is stored, nothing drilled)"
                                    if letter == "K" else ""), letter)
    return int(n)


def cycle_moves(code: int, vals: dict[str, float], state: CycleState, pos: list[float],
                plane: int, incremental: bool, retract_to_r: bool, scale: float,
                spindle_dir: int) -> tuple[list[tuple[int, list[float]]], list[float]]:
    """The moves of one cycle block, and the position after it.

    Parameters
    ----------
    code : int
        73, 74, 81...87, 89.
    vals : dict
        The block's words, in program units (X Y Z R Q, I J K: length; P [s]; L, K).
    state : CycleState
        Sticky words and the initial level; updated.
    pos : list of 6 float [mm, rad]
        Position before the block (program frame).
    plane : int
        17, 18 or 19.
    incremental : bool
        G91 in effect.
    retract_to_r : bool
        G99 (return to the R plane) in effect; else G98 (initial level).
    scale : float [mm per program unit]
        1 or 25.4.
    spindle_dir : int
        +1 M3, -1 M4, 0 stopped.

    Returns
    -------
    moves : list of (motion, end)
        motion 0 (rapid) or 1 (feed); ``end`` the 6 coordinates [mm, rad].
    pos : list of 6 float [mm, rad]
        Where the interpreter takes the tool to be afterwards (X Y of the last
        hole, Z at the clearance level).

    Raises
    ------
    CycleError
        With the word to point at.
    """
    ia, ib, ic = PLANE_AXES[plane]
    la, lb, lc = "XYZ"[ia], "XYZ"[ib], "XYZ"[ic]
    for c in "ABC":
        if c in vals:
            raise CycleError(f"{c} word in a canned cycle; expected rotary axes to stay "
                             "still (move them before the cycle)", c)
    if code == 87 and plane != 17:
        raise CycleError("G87 (back boring) outside G17; expected it in the XY plane")
    fresh = state.mode != code
    if fresh and lc not in vals:
        raise CycleError(f"{lc} missing in the first G{code} block; expected the bottom of "
                         f"the hole ({lc}) with R when a cycle starts")
    if "R" not in vals and fresh:
        raise CycleError(f"R missing in the first G{code} block; expected the R plane "
                         "(retract level) when a cycle starts")
    if code in _DWELL:
        if "P" in vals:
            if not vals["P"] >= 0:
                raise CycleError("negative dwell P; expected P >= 0 [s]", "P")
            state.p = vals["P"]
        elif fresh:
            raise CycleError(f"P missing in the first G{code} block; expected the dwell "
                             "time P [s]")
    elif code in (74, 84) and "P" in vals:
        state.p = vals["P"]
    elif "P" in vals:
        raise CycleError(f"P word in G{code}; expected P only in G82, G86, G89 (dwell) "
                         "and G74/G84", "P")
    if code in _PECK:
        if "Q" in vals:
            state.q = vals["Q"]
        elif fresh:
            raise CycleError(f"Q missing in the first G{code} block; expected the peck "
                             "depth Q > 0")
        if not state.q > 0:
            raise CycleError(f"Q{state.q:g}: expected a peck depth Q > 0", "Q")
    elif "Q" in vals:
        raise CycleError(f"Q word in G{code}; expected Q only in G73 and G83 (peck depth)",
                         "Q")
    if code == 87:
        for c in "IJK":
            if c in vals:
                setattr(state, c.lower(), vals[c])
            elif fresh:
                raise CycleError(f"{c} missing in the first G87 block; expected I J (the "
                                 "offset off the hole's axis) and K (the top of the bore)")
    else:
        for c in "IJ":
            if c in vals:
                raise CycleError(f"{c} word in G{code}; expected I J only in G87", c)
    if code in (74, 84) and spindle_dir != (-1 if code == 74 else 1):
        raise CycleError(f"G{code} (tapping) needs the spindle turning "
                         f"{_SPINDLE[code]}")
    if code in (86, 87) and spindle_dir == 0:
        raise CycleError(f"G{code} needs the spindle turning (M3 or M4)")
    repeats = _repeats(vals, code)

    # in program units from here, as LinuxCNC computes (its loop ends compare
    # the numbers the program wrote)
    if state.last and state.last[0] == pos:
        cur = list(state.last[1])
    else:
        cur = [pos[ia] / scale, pos[ib] / scale, pos[ic] / scale]
    if not all(math.isfinite(v) for v in cur):
        raise CycleError("canned cycle at a position not known (after a G28/G30 whose "
                         "point was not given); expected an absolute move first")
    state.z = vals.get(lc, state.z)
    state.r = vals.get("R", state.r)
    current_cc = cur[2]
    if state.initial is None:
        state.initial = current_cc
    old_cc = state.initial
    if incremental:
        inc_a, inc_b = vals.get(la, 0.0), vals.get(lb, 0.0)
        r = state.r + old_cc
        bottom = r + state.z
        aa, bb = cur[0], cur[1]
    else:
        inc_a = inc_b = 0.0
        r, bottom = state.r, state.z
        aa, bb = vals.get(la, cur[0]), vals.get(lb, cur[1])
    if r < bottom:
        raise CycleError(f"R plane {r:g} below the bottom {lc}{bottom:g}; expected R >= "
                         f"{lc} (incremental: R from the initial level, {lc} from R)", "R")
    pecks = 0
    if code in _PECK:
        pecks = max(0, math.ceil((r - bottom) / state.q))
    per = 3 * pecks + 9
    if repeats * per > K.MAX_CYCLE_MOVES:
        raise CycleError(f"the cycle would make about {repeats * per} moves; expected at "
                         f"most {K.MAX_CYCLE_MOVES} from one block (fewer repeats, a larger "
                         "Q)", "L" if "L" in vals else ("Q" if code in _PECK else None))

    if state.made + repeats * per > K.MAX_CYCLE_MOVES_PROGRAM:
        raise CycleError(f"canned cycles would make more than {K.MAX_CYCLE_MOVES_PROGRAM} "
                         "moves in this program; expected fewer holes or pecks per program")
    base = list(pos)
    moves: list[tuple[int, list[float]]] = []

    def go(motion: int, a: float, b: float, c: float) -> None:
        end = base[:]
        end[ia], end[ib], end[ic] = a * scale, b * scale, c * scale
        moves.append((motion, end))

    if old_cc < r:  # below the R plane: straight up to it first
        go(0, cur[0], cur[1], r)
        old_cc = r
        current_cc = r
    clear = r if retract_to_r else old_cc
    delta = K.CYCLE_PECK_RETRACT_MM / scale
    for rep in range(repeats, 0, -1):
        aa += inc_a
        bb += inc_b
        if rep == repeats and current_cc > r:
            go(0, aa, bb, current_cc)
            go(0, aa, bb, r)
        else:
            go(0, aa, bb, clear)
            if clear > r:
                go(0, aa, bb, r)
        if code in _PECK:
            depth = r - state.q
            while depth > bottom:
                go(1, aa, bb, depth)
                go(0, aa, bb, r if code == 83 else depth + delta)
                if code == 83:
                    go(0, aa, bb, depth + delta)
                depth -= state.q
            go(1, aa, bb, bottom)
            go(0, aa, bb, clear)
        elif code in (81, 82, 86):
            go(1, aa, bb, bottom)
            go(0, aa, bb, clear)
        elif code == 85:
            go(1, aa, bb, bottom)
            go(1, aa, bb, r)
            go(0, aa, bb, clear)
        elif code in (74, 84, 89):
            go(1, aa, bb, bottom)
            go(1, aa, bb, clear)
        else:  # 87: back boring
            top = bottom + state.k if incremental else state.k
            oa, ob = aa + state.i, bb + state.j
            go(0, oa, ob, r)
            go(0, oa, ob, bottom)
            go(0, aa, bb, bottom)
            go(1, aa, bb, top)
            go(1, aa, bb, bottom)
            go(0, oa, ob, bottom)
            go(0, oa, ob, clear)
            go(0, aa, bb, clear)
    state.mode = code
    state.made += len(moves)
    after = base[:]
    after[ia], after[ib], after[ic] = aa * scale, bb * scale, clear * scale
    state.last = (after, (aa, bb, clear))
    return moves, after


def refuse_drilling(program: Program, purpose: str) -> None:
    """Refuse a program with canned drilling cycles for work that models milling only.

    Parameters
    ----------
    program : Program
    purpose : str
        What refuses, e.g. ``"the error prediction"``.

    Raises
    ------
    NCParseError
        At the first cycle block's line: a drilled hole is not a milled
        surface, and its moves must not be taken for milling moves.
    """
    if not len(program.drilling):
        return
    row = int(program.drilling[0])
    line = int(program.line[row])
    text = program.lines[line - 1] if line - 1 < len(program.lines) else ""
    raise NCParseError(f"canned drilling cycle ({len(program.drilling)} moves from line "
                       f"{line} on): {purpose} models milling only; expected a program "
                       "without drilling cycles (drill in a program of its own)",
                       file=program.file, line=line,
                       column=len(text) - len(text.lstrip()) + 1, text=text)


class CycleBlocks:
    """The reader's part for cycle blocks (a base of :class:`nc.gcode_interp.Interpreter`,
    beside :class:`nc.blockreader.BlockReader`, whose ``_error`` it uses)."""

    @staticmethod
    def _cycle_words(gcodes: dict[str, int], motion_mode: int | None) -> bool:
        """Whether the block runs a canned cycle (whose words include L and Q), or is G68.x."""
        key = gcodes.get("motion") if gcodes else None
        if key is not None:
            return key in CYCLE_CODES
        if gcodes and "rotation" in gcodes:  # G68.2 Q: refused by nc.rotation, by name
            return True
        return motion_mode is not None and motion_mode > 3

    def _cycle(self, lineno: int, toks: list, gs: list[str] | None, fc: int | None,
               feed_mode: int, tcp: int, feed: float, code: int, vals: dict[str, float],
               state: CycleState, pos: list[float], plane: int, incremental: bool,
               retract_to_r: bool, scale: float, spindle_dir: int, rot
               ) -> tuple[list[tuple[int, list[float]]], list[float]]:
        """A cycle block's moves and the position after it, in the program frame
        (through ``rot``, a :class:`nc.rotation.Rotation`, when one is in effect)."""
        if fc == 530:
            raise self._error(lineno, "G53 with a canned cycle; expected G0 or G1",
                              token=find_token(toks, "G", gs[0]))
        if feed_mode == 93 or tcp != TCP_OFF:
            raise self._error(lineno, "canned cycle under inverse-time feed (G93) or tool "
                              "centre point control; expected G94/G95 and G49 or G43")
        if not feed > 0:
            raise self._error(lineno, "canned cycle with no feed; expected an F > 0 in this "
                              "block or before it")
        try:
            moves, after = cycle_moves(code, vals, state, pos if rot is None else
                                       rot.to_program(pos), plane, incremental, retract_to_r,
                                       scale, spindle_dir)
        except CycleError as exc:
            if exc.letter is None:
                raise self._error(lineno, str(exc)) from None
            raise self._word_error(lineno, toks, exc.letter, str(exc)) from None
        if rot is not None:
            moves = [(m, rot.to_world(e)) for m, e in moves]
            after = rot.to_world(after)
        return moves, after
