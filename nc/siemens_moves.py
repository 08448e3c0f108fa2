"""What one Sinumerik block does: its words sorted, then applied in the control's order.

Order within a block: assignments (left to right, as written), G codes,
keywords (TRAORI, TRAFOOF, SUPA...), F S T D, M functions acting at the
start (M3 M4 M6), calls (CYCLE800...), the move, M functions acting at the
end (M5, M2/M17/M30). Every word a block does not use is refused by name.
"""

from __future__ import annotations

import math

import numpy as np

from .arcs import ArcWordError, arc_from_words
from .siemens_blocks import SBlock, Word, lex
from .siemens_state import G_IGNORED, G_REFUSED, K_IGNORED, K_REFUSED, SUPPORTED_BLOCKS, SState

__all__ = ["execute"]

_ADDR_WORDS = frozenset({"X", "Y", "Z", "A", "B", "C", "I", "J", "K", "F", "S", "T", "D",
                         "CR", "AR", "TURN", "A3", "B3", "C3"})
_MOVE_WORDS = ("X", "Y", "Z", "A", "B", "C", "I", "J", "K", "CR", "AR", "TURN", "A3", "B3",
               "C3")
_LIN = (("X", 0), ("Y", 1), ("Z", 2))
_ROT = (("A", 0), ("B", 1), ("C", 2))
_TWO_PI = 2.0 * math.pi
_FRAME_WORDS = frozenset({"TRANS", "ATRANS", "ROT", "AROT", "ROTS", "AROTS"})



def execute(st: SState, b: SBlock) -> bool:
    """Run one block; True when it ends the program (M2, M17, M30, RET)."""
    st.b = b
    s = b.stmt
    if not s:  # a label alone on its line
        return False
    if s.startswith("DEF "):
        st.define(s)
        return False
    gs: list[tuple[int, int]] = []
    ms: list[tuple[int, int]] = []
    ax: dict[str, Word] = {}
    calls: list[Word] = []
    keys: list[Word] = []
    unknown: Word | None = None
    if b.line in st.lex_keep:  # a block in a loop: its words are kept
        words = st.lexed.get(b.line)
        if words is None:
            words = st.lexed[b.line] = lex(b, st.file, st.lines)
    else:
        words = lex(b, st.file, st.lines)
    for w in words:
        kind, name = w.kind, w.name
        if kind == "A":
            if name == "G" or name == "M":
                if "." in w.text or w.text[0] in "+-":
                    raise st.err(f"{name}{w.text}: expected a whole number", w.col)
                (gs if name == "G" else ms).append((int(w.text), w.col))
            elif name in _ADDR_WORDS:
                _put(st, ax, w)
            elif name == "N":
                raise st.err("block number N inside a block; expected it first", w.col)
            elif name == "L":
                raise st.err(f"L{w.text}: subprogram calls are not read", w.col)
            elif name == "H" and f"H{w.text}" in st.allowed:
                st.ignore(f"H{w.text}")
            else:
                raise st.err(f"unsupported address {name}{w.text[:12]}; supported: "
                             f"{SUPPORTED_BLOCKS}", w.col)
        elif kind == "E":
            if name in _ADDR_WORDS:
                _put(st, ax, w)
            elif name in st.params or (name[0] == "R" and name[1:].isdigit()):
                st.assign(w)
            elif unknown is None:
                unknown = w  # refused after the G codes, which may name the reason
        elif kind == "C":
            calls.append(w)
        else:
            keys.append(w)

    frame_kw = [w for w in keys if w.name in _FRAME_WORDS]
    if frame_kw:
        w = frame_kw[0]
        if len(keys) > 1 or gs or ms or calls:
            other = next(k for k in (*keys, *calls) if k is not w) if len(keys) > 1 or calls \
                else None
            raise st.err(f"{w.name} with other words in its block; expected {w.name} and "
                         "its X Y Z alone", other.col if other else w.col)
        st.frame_statement(w, ax)
        return False
    dwell = suppress = False
    for code, col in gs:
        if code <= 3:
            st.motion = code
        elif code == 4:
            dwell = True
        elif code in (17, 18, 19):
            st.plane = code
        elif code in (90, 91):
            st.distance = code
        elif code in (93, 94):
            st.feed_mode = code
        elif code == 700:
            st.scale, st.units = 25.4, 20
        elif code in (71, 710):
            st.scale, st.units = 1.0, 21
        elif code in (53, 153):
            suppress = True
        elif 54 <= code <= 57:
            st.wcs = code - 53
        elif code == 500 or 505 <= code <= 599:
            st.wcs = 1
            st.ignore(f"G{code} (offset taken as zero)")
        elif code in G_IGNORED:
            if code != 40:
                st.ignore(f"G{code}")
        elif code in G_REFUSED:
            raise st.err(f"G{code} is not read ({G_REFUSED[code]}); supported: "
                         f"{SUPPORTED_BLOCKS}", col)
        elif f"G{code}" in st.allowed:
            st.ignore(f"G{code}")
        else:
            raise st.err(f"unsupported G{code}; supported: {SUPPORTED_BLOCKS}", col)
    if unknown is not None:
        raise st.err(f"unknown name {unknown.name[:20]}= (only R parameters, DEF REAL/INT "
                     f"variables and the words of {SUPPORTED_BLOCKS} can be set)", unknown.col)
    end = False
    for w in keys:
        name = w.name
        if name == "TRAORI":
            st.traori_on()
        elif name == "TRAFOOF":
            st.traori, st.vector = False, None
        elif name == "SUPA":
            suppress = True
        elif name == "RET":
            end = True
        elif name in K_IGNORED:
            st.ignore(name)
        elif name == "DEF":
            raise st.err("DEF inside a block; expected it at the start of its own block",
                         w.col)
        elif name in K_REFUSED:
            raise st.err(f"{name}: {K_REFUSED[name]}; supported: {SUPPORTED_BLOCKS}", w.col)
        elif name in st.allowed:
            st.ignore(name)
        else:
            raise st.err(f"unsupported {name[:20]!r}; supported: {SUPPORTED_BLOCKS}", w.col)

    if "F" in ax:
        w = ax.pop("F")
        if not dwell:
            f = st.number(w)
            if f < 0:
                raise st.err("negative feed; expected F >= 0", w.col)
            st.feed = f * (st.scale if st.feed_mode == 94 else 1.0)
    if "S" in ax:
        w = ax.pop("S")
        v = st.number(w)
        if not dwell:
            if v < 0:
                raise st.err("negative spindle speed; expected S >= 0", w.col)
            st.rpm = v
    if "T" in ax:
        w = ax.pop("T")
        if w.kind == "E" and w.text.startswith('"'):
            st.metadata.setdefault("tool_names", []).append(st.as_written(w).strip('"'))
            st.tool_sel = 0
        else:
            t = st.number(w)
            if not (t >= 0 and t == int(t)):
                raise st.err(f"T{w.text}: expected a tool number >= 0", w.col)
            st.tool_sel = int(t)
    if "D" in ax:
        w = ax.pop("D")
        v = st.number(w)
        if not (v >= 0 and v == int(v)):
            raise st.err(f"D{w.text}: expected a cutting edge number >= 0", w.col)
        st.d = int(v)
    st.m_start(ms)
    for w in calls:
        st.call(w)
    if ax:
        if dwell:
            raise st.err("axis words in a G4 (dwell) block; expected F or S (the dwell) only",
                         next(iter(ax.values())).col)
        _move(st, ax, suppress)
    return st.m_end(ms) or end


def _put(st: SState, ax: dict, w: Word) -> None:
    if w.name in ax:
        raise st.err(f"word {w.name} appears twice in one block; expected it once", w.col)
    ax[w.name] = w


def _move(st: SState, ax: dict, suppress: bool) -> None:
    mode = st.motion
    if mode is None:
        w = next(iter(ax.values()))
        raise st.err("axis words without a motion mode; expected G0, G1, G2 or G3 in effect",
                     w.col)
    inc_block = st.distance == 91
    scale = st.scale
    target = st.ppos.copy()
    if suppress:
        if mode > 1 or inc_block or st.traori:
            raise st.err("SUPA/G53/G153 needs G0 or G1, G90 and no TRAORI")
        wpos = st.world(st.ppos).copy()
        for c, a in _LIN:
            w = ax.get(c)
            if w is not None:
                v, fn = st.axis_value(w)
                if fn not in (None, "AC"):
                    raise st.err(f"{c}={fn}(..) with SUPA/G53; expected absolute values",
                                 w.col)
                wpos[a] = v * scale
        if st.tilted:
            sw = st.frame
            target = sw.R.T @ (wpos - sw.shift)
        else:
            target = wpos
    else:
        for c, a in _LIN:
            w = ax.get(c)
            if w is not None:
                v, fn = st.axis_value(w)
                v *= scale
                if fn == "AC" or (fn is None and not inc_block):
                    target[a] = v
                elif fn == "IC" or fn is None:
                    target[a] += v
                else:
                    raise st.err(f"{c}={fn}(..): DC, ACP and ACN apply to rotary axes", w.col)
    rot_words = [(c, k) for c, k in _ROT if c in ax]
    if rot_words:
        if st.traori and st.vector is not None:
            raise st.err("rotary axis word after an A3/B3/C3 tool vector under TRAORI: the "
                         "reader does not know the machine angles of that vector",
                         ax[rot_words[0][0]].col)
        for c, k in rot_words:
            w = ax[c]
            v, fn = st.axis_value(w)
            rad = math.radians(v)
            cur = st.rot[k]
            if fn == "AC" or (fn is None and (suppress or not inc_block)):
                new = rad
            elif fn == "IC" or fn is None:
                new = cur + rad
            elif fn == "DC":
                new = cur + ((rad - cur + math.pi) % _TWO_PI - math.pi)
            elif fn == "ACP":
                new = cur + (rad - cur) % _TWO_PI
            else:  # ACN
                new = cur - (cur - rad) % _TWO_PI
            st.rot[k] = new
    vec = [ax.get(c) for c in ("A3", "B3", "C3")]
    if any(w is not None for w in vec):
        first = next(w for w in vec if w is not None)
        if not st.traori:
            raise st.err("A3/B3/C3 tool vector without TRAORI; expected TRAORI before it",
                         first.col)
        comps = np.array([0.0 if w is None else st.number(w) for w in vec])
        norm = float(np.linalg.norm(comps))
        if not norm > 1e-9:
            raise st.err("A3/B3/C3 tool vector of zero length; expected a direction",
                         first.col)
        comps /= norm
        st.vector = (float(comps[0]), float(comps[1]), float(comps[2]))
    arc_words = [c for c in ("I", "J", "K", "CR", "AR", "TURN") if c in ax]
    if mode <= 1:
        if arc_words:
            raise st.err(f"{arc_words[0]} in a G{mode} block; expected it with G2/G3",
                         ax[arc_words[0]].col)
        st.emit(mode, target, machine=suppress)
        return
    if suppress:
        raise st.err("SUPA/G53/G153 needs G0 or G1, G90 and no TRAORI")
    if rot_words or any(w is not None for w in vec):
        w = ax[rot_words[0][0]] if rot_words else first
        raise st.err("rotary axis or tool-vector words on an arc are not read; expected "
                     "them on G0/G1 blocks", w.col)
    if "AR" in ax:
        raise st.err("AR= (opening angle) arcs are not read; expected I J K or CR=",
                     ax["AR"].col)
    start = st.ppos
    vals: dict[str, float] = {}
    for c, a in (("I", 0), ("J", 1), ("K", 2)):
        w = ax.get(c)
        if w is not None:
            v, fn = st.axis_value(w)
            v *= scale
            if fn == "AC":
                v -= start[a]
            elif fn not in (None, "IC"):
                raise st.err(f"{c}={fn}(..): expected a value, AC(..) or IC(..)", w.col)
            vals[c] = v
    if "CR" in ax:
        vals["R"] = st.number(ax["CR"]) * scale
    if "TURN" in ax:
        t = st.number(ax["TURN"])
        vals["P"] = t + 1.0
    s6 = [*start, 0.0, 0.0, 0.0]
    e6 = [*target, 0.0, 0.0, 0.0]
    try:
        centre, radii, sweep = arc_from_words(vals, mode, st.plane, 1.0, 911, s6, e6)
    except ArcWordError as exc:
        letter = {"R": "CR", "P": "TURN"}.get(exc.letter, exc.letter)
        msg = str(exc).replace(" R arc", " CR= arc").replace("(or R)", "(or CR=)")
        msg = msg.replace("expected P (arc turns) to be a whole number from 1",
                          "expected TURN (extra full turns) to be a whole number from 0")
        raise st.err(msg, ax[letter].col if letter in ax else None) from None
    st.emit(mode, target, arc=(centre, radii, sweep))
