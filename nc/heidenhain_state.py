"""The state a Klartext program runs under, and what each block does to it.

:class:`TNCState` keeps position (program frame and workpiece frame), feed,
spindle, tool, circle centre, tool-centre-point mode, tilted plane and datum
shift, Q parameters, and appends one row per move to the output columns;
:meth:`TNCState.program` makes the :class:`~nc.program.Program`.
"""

from __future__ import annotations

import math
import re

import numpy as np

from . import constants as K
from .errors import NCParseError
from .heidenhain_blocks import M_NOT_ALLOWABLE, M_SUPPORTED, TNCBlock, words
from .heidenhain_expr import SUPPORTED as EXPR_SUPPORTED
from .heidenhain_expr import ExprError, evaluate
from .heidenhain_geom import arc_points, spatial_rotation
from .heidenhain_moves import MOVES
from .program import TCP_ANGLES, TCP_OFF, TCP_VECTOR, Modal, Program, ProgramRows

__all__ = ["TNCState"]

_AX = {"X": 0, "Y": 1, "Z": 2}
_ROT = {"A": 0, "B": 1, "C": 2}
_M_START = {3: 1, 4: -1, 13: 1, 14: -1}          # spindle on at the block's start
_VALUE = re.compile(r"[+-]?(?:\d+(?:[.,]\d*)?|[.,]\d+|Q[LR]?\d+)")
_Q_ASSIGN = re.compile(r"(Q[LR]?\d+)\s*=\s*(.+)")
_FN = re.compile(r"FN\s*(\d+)\s*:\s*(.*)")
_TOOL_CALL = re.compile(r"TOOL\s+CALL(?:\s+(\d+(?:\.\d+)?|\"[^\"]*\"|'[^']*'|Q\d+))?"
                        r"(?:\s+([XYZUVW])(?![+\-\d]))?(.*)")
_TOOL_WORD = re.compile(r"\s*(DR2|DL|DR|S|F)\s*([+-]?\s*(?:\d+(?:[.,]\d*)?|[.,]\d+)|"
                        r"[+-]?Q[LR]?\d+)")
_CYCL = re.compile(r"CYCL\s+DEF\s+(\d+)(?:\.(\d+))?\s*(.*)")
_SPATIAL = re.compile(r"PLANE\s+SPATIAL\s+SPA\s*(\S+?)\s+SPB\s*(\S+?)\s+SPC\s*(\S+)(.*)")
_PLANE_TAIL = re.compile(r"(?:\s+(?:TURN|MOVE|STAY|MB\s*(?:MAX|[+-]?[\d.,]+)|FMAX|"
                         r"F\s*[+-]?[\d.,]+|DIST\s*[+-]?[\d.,]+|ABST\s*[+-]?[\d.,]+|SYM[+-]|"
                         r"SEQ[+-]|COORD\s+ROT|TABLE\s+ROT))*\s*")
_TCPM_TAIL = re.compile(r"(?:\s+(?:F\s+TCP|AXIS\s+POS|PATHCTRL\s+(?:AXIS|VECTOR)|"
                        r"REFPNT\s+TIP-TIP))*\s*")
_REFUSED = {
    "APPR": "approach contours (APPR) depend on the tool radius",
    "DEP": "departure contours (DEP) depend on the tool radius",
    "RND": "corner rounding (RND) changes the contour",
    "CHF": "chamfers (CHF) change the contour",
    "FK": "FK free contours", "FPOL": "FK free contours", "FL": "FK free contours",
    "FC": "FK free contours", "FLT": "FK free contours", "FCT": "FK free contours",
    "TCH": "touch probe cycles", "CYCL": "machining cycles", "SEL": "program selection",
    "PATTERN": "point patterns", "SPL": "splines",
}


class TNCState(ProgramRows):
    """Modal state and output columns of one run."""

    def __init__(self, file: str, lines: list[str], allowed: frozenset[int],
                 retract_limit: float | None) -> None:
        self.file, self.lines, self.allowed = file, lines, allowed
        self.retract_limit = retract_limit
        self.scale, self.feed_scale, self.units = 1.0, 1.0, 21
        self.ppos = np.zeros(3)        # program frame [mm]
        self.rot = [0.0, 0.0, 0.0]     # A B C [rad]
        self.R = np.eye(3)
        self.tilted = False
        self.shift = np.zeros(3)
        self.shifted = False
        self.tool_axis = 2
        self.feed = math.nan
        self.auto_feed = math.nan
        self.rpm, self.spindle, self.tool = 0.0, 0, 0
        self.tcpm = False
        self.vector: tuple[float, float, float] | None = None
        self.m126 = False
        self.rot_unknown = False  # rotary axes turned by PLANE ... TURN|MOVE
        self.cc: tuple[int, float, float] | None = None
        self.tangent: np.ndarray | None = None
        self.q: dict[str, float] = {}
        self.metadata: dict = {}
        self.init_rows()
        self.b: TNCBlock | None = None

    # -- helpers ---------------------------------------------------------
    def set_units(self, unit: str) -> None:
        if unit == "INCH":
            self.scale, self.feed_scale, self.units = K.MM_PER_INCH, K.MM_PER_INCH / 10, 20

    def err(self, msg: str, col: int | None = None) -> NCParseError:
        b = self.b
        return NCParseError(msg, file=self.file, line=b.line, column=col or b.col,
                            text=self.lines[b.line - 1])

    def value(self, name: str, text: str | None, col: int) -> float:
        if text is None or text in "+-" or text == "MAX":
            raise self.err(f"expected a number after {name}", col)
        t = text.replace(" ", "") if " " in text else text
        if "Q" not in t and "," not in t:
            try:
                v = float(t)
            except ValueError:
                v = math.nan
            if abs(v) <= K.MAX_ABS_WORD_VALUE and _VALUE.fullmatch(t):
                return v
        if not _VALUE.fullmatch(t):
            raise self.err(f"expected a number or a Q parameter after {name}, found "
                           f"{text[:16]!r}", col)
        if "Q" in t:
            neg = t.startswith("-")
            key = t.lstrip("+-")
            if key not in self.q:
                raise self.err(f"{key} is used before it is set in this program", col)
            v = -self.q[key] if neg else self.q[key]
        else:
            v = float(t.replace(",", "."))
        if not abs(v) <= K.MAX_ABS_WORD_VALUE:
            raise self.err(f"{name}{text} is out of range; expected |value| <= "
                           f"{K.MAX_ABS_WORD_VALUE:g}", col)
        return v

    def parse_words(self, start: int) -> tuple[dict, list]:
        d: dict[str, tuple[str | None, int]] = {}
        ms: list[tuple[int, int]] = []
        for name, val, col in words(self.b, start, self.lines, self.file):
            if name == "M":
                v = self.value("M", val, col)
                if v != int(v) or v < 0:
                    raise self.err(f"M{val}: expected a whole number", col)
                ms.append((int(v), col))
                continue
            if name[0] == "F" and " " in name:  # "F AUTO"
                name = "FAUTO"
            if name in d:
                raise self.err(f"word {name} appears twice in one block; expected it once", col)
            d[name] = (val, col)
        return d, ms

    def world(self, p: np.ndarray) -> np.ndarray:
        if not self.tilted and not self.shifted:
            return p
        return self.shift + (self.R @ p if self.tilted else p)

    def reframe(self, R: np.ndarray, tilted: bool, shift: np.ndarray) -> None:
        w = self.world(self.ppos)
        self.R, self.tilted, self.shift = R, tilted, shift
        self.shifted = bool(np.any(shift != 0))
        self.ppos = (R.T @ (w - shift)) if tilted else (w - shift)
        self.cc = None
        self.tangent = None

    def modal_id(self, plane: int, tcp: int) -> int:
        key = (plane, self.units, 90, 911, 94, self.rpm, self.spindle, self.tool,
               self.tool, tcp, 1)
        i = self.modal_ids.get(key)
        if i is None:
            i = self.modal_ids[key] = len(self.modals)
            self.modals.append(Modal(*key))
        return i

    def tcp_and_vector(self) -> tuple[int, tuple[float, float, float]]:
        nan3 = (math.nan, math.nan, math.nan)
        if self.tcpm:
            return (TCP_VECTOR, self.vector) if self.vector is not None else (TCP_ANGLES, nan3)
        if self.tilted or self.tool_axis != 2:
            axis = np.zeros(3)
            axis[self.tool_axis] = 1.0
            v = self.R @ axis if self.tilted else axis
            return TCP_VECTOR, (float(v[0]), float(v[1]), float(v[2]))
        return TCP_OFF, nan3

    def emit(self, motion: int, pend: np.ndarray, plane: int, arc=None) -> None:
        """One row ending at program-frame ``pend``; ``arc`` = (centre2, radii, sweep, axes)."""
        tcp, tv = self.tcp_and_vector()
        if self.rot_unknown and tcp != TCP_VECTOR:
            raise self.err("the rotary axes stand where PLANE ... TURN|MOVE put them, at angles "
                           "the reader does not know; expected PLANE RESET TURN|MOVE or "
                           "rotary words (L B.. C..) before this move")
        if motion != 0 and not self.feed > 0:
            raise self.err("cutting move with no feed; expected F > 0 in this block or "
                           "before it (FMAX is rapid for its block only)")
        feed = self.feed
        start = self.ppos
        if arc is not None and self.tilted:
            centre, radii, sweep, axes = arc
            for p in arc_points(axes, start, pend, centre, radii, sweep, K.CHORD_TOL_MM):
                self._row(1, self.world(p), feed, plane, tcp, tv, -1)
        else:
            k = -1
            if arc is not None:
                centre, radii, sweep, axes = arc
                c = np.zeros(3)
                c[axes[0]], c[axes[1]], c[axes[2]] = centre[0], centre[1], start[axes[2]]
                c = self.world(c)
                k = len(self.a_sweep)
                self.a_centre.extend(c.tolist())
                self.a_radius.extend(radii)
                self.a_sweep.append(sweep)
                self.a_plane.append(plane)
            self._row(motion, self.world(pend), feed, plane, tcp, tv, k)
        self.ppos = pend

    def _row(self, motion, w, feed, plane, tcp, tv, k) -> None:
        self.o_line.append(self.b.line)
        self.o_motion.append(motion)
        self.o_end.extend(w.tolist())
        self.o_end.extend(self.rot)
        self.o_feed.append(feed)
        self.o_modal.append(self.modal_id(plane, tcp))
        self.o_tv.extend(tv)
        self.o_arc.append(k)

    # -- blocks ----------------------------------------------------------
    def execute(self, b: TNCBlock) -> bool:
        """Run one block; True when it ends the program (M2, M30)."""
        self.b = b
        s = b.stmt
        verb = s.split(" ", 1)[0]
        fn = MOVES.get(verb)
        if fn is not None:
            return fn(self)
        if s[0] == "M" and s[1:2].isdigit():
            d, ms = self.parse_words(0)
            if d:
                raise self.err(f"unexpected {next(iter(d))} in an M block; expected M "
                               "functions only")
            return self.m_functions(ms, at_end=False) | self.m_functions(ms, at_end=True)
        if verb == "STOP":
            d, ms = self.parse_words(4)
            if d:
                raise self.err("unexpected words after STOP; expected M functions only")
            return self.m_functions(ms, at_end=False) | self.m_functions(ms, at_end=True)
        if verb == "TOOL":
            return self.tool_block(s)
        if verb == "BLK":
            self.metadata.setdefault("blk_form", []).append(b.orig.strip())
            return False
        if s.startswith("Q"):
            return self.q_assign(s, 0)
        if verb == "FN" or s.startswith("FN"):
            m = _FN.fullmatch(s)
            if not m:
                raise self.err("expected FN n: Q.. = ...")
            n = int(m.group(1))
            if n > 5:
                raise self.err(f"FN {n} is not supported (jumps, SYSREAD, PLC and file "
                               "functions need the control); supported: FN 0-5 and "
                               f"Q formulas with {EXPR_SUPPORTED}")
            return self.q_assign(m.group(2), s.index(m.group(2)))
        if verb == "CYCL":
            return self.cycle(s)
        if verb == "PLANE":
            return self.plane(s)
        if verb == "FUNCTION":
            return self.function(s)
        reason = _REFUSED.get(verb)
        word = verb[:20]
        raise self.err(f"unsupported block {word!r}" + (f" ({reason})" if reason else "")
                       + "; supported: L LN LP C CC CR CT CP, TOOL CALL/DEF, M functions, "
                       "Q/FN 0-5, LBL/CALL LBL, CYCL DEF 7/19/32/9, PLANE SPATIAL/RESET, "
                       "FUNCTION TCPM/RESET TCPM, BLK FORM, STOP")

    def m_functions(self, ms: list[tuple[int, int]], at_end: bool) -> bool:
        if not ms:
            return False
        end = False
        for m, col in ms:
            if m not in M_SUPPORTED and m not in self.allowed:
                why = M_NOT_ALLOWABLE.get(m)
                raise self.err(f"unsupported M{m}" + (f" ({why}, which this reader does not "
                               "model)" if why else f"; if it is harmless here, pass it in "
                               f"allow (e.g. allow=['M{m}'])"), col)
            if not at_end:
                if m in _M_START:
                    self.spindle = _M_START[m]
                elif m == 126:
                    self.m126 = True
                elif m == 127:
                    self.m126 = False
                elif m == 128:
                    self.tcpm_on()
            else:
                if m == 5:
                    self.spindle = 0
                elif m == 129:
                    self.tcpm, self.vector = False, None
                elif m in (2, 30):
                    end = True
        return end

    def tcpm_on(self) -> None:
        if self.tilted:
            raise self.err("tool centre point control (M128/TCPM) in a tilted plane is not "
                           "supported; expected PLANE RESET before it")
        if self.tool_axis != 2:
            raise self.err("tool centre point control with a tool axis other than Z is not "
                           "supported")
        self.tcpm = True

    def q_assign(self, s: str, offset: int) -> bool:
        m = _Q_ASSIGN.fullmatch(s)
        if not m:
            if s.startswith("QS"):
                raise self.err("string parameters (QS) are not supported")
            raise self.err(f"expected Qn = formula; supported: {EXPR_SUPPORTED}")
        try:
            self.q[m.group(1)] = evaluate(m.group(2), self.q)
        except ExprError as exc:
            raise self.err(str(exc), self.b.col + offset + m.start(2) + exc.offset) from None
        return False

    def tool_block(self, s: str) -> bool:
        if s.startswith("TOOL DEF"):
            return False
        m = _TOOL_CALL.fullmatch(s)
        if not m:
            raise self.err("expected TOOL CALL [n] [X|Y|Z] [S..] [F..] or TOOL DEF n")
        num, axis, rest = m.groups()
        if num is not None:
            if num.startswith(("\"", "'")):
                self.metadata.setdefault("tool_names", []).append(num.strip("\"'"))
                self.tool = 0
            else:
                t = self.q.get(num, math.nan) if num.startswith("Q") else float(num)
                if not t >= 0:
                    raise self.err(f"TOOL CALL {num}: expected a tool number >= 0")
                self.tool = int(t)
        if axis is not None:
            if axis not in _AX:
                raise self.err(f"tool axis {axis}: expected X, Y or Z")
            if self.tcpm and axis != "Z":
                raise self.err("tool axis other than Z under TCPM is not supported")
            self.tool_axis = _AX[axis]
            self.cc = None
        pos = 0
        rest = rest or ""
        while pos < len(rest.rstrip()):
            w = _TOOL_WORD.match(rest, pos)
            if not w:
                raise self.err(f"unexpected {rest[pos:].split()[0][:16]!r} in TOOL CALL; "
                               "expected S, F, DL, DR, DR2")
            name, v = w.group(1), self.value(w.group(1), w.group(2), self.b.col)
            if name == "S":
                if v < 0:
                    raise self.err("negative spindle speed; expected S >= 0")
                self.rpm = v
            elif name == "F":
                if v < 0:
                    raise self.err("negative feed; expected F >= 0")
                self.auto_feed = self.feed = v * self.feed_scale
            elif v != 0:
                what = "length" if name == "DL" else "radius"
                raise self.err(f"{name}{w.group(2)}: a delta {what} moves the tool off the "
                               "programmed path; expected 0")
            pos = w.end()
        return False

    def cycle(self, s: str) -> bool:
        m = _CYCL.fullmatch(s)
        if not m:
            raise self.err("expected CYCL DEF n.m ...")
        n, sub, rest = int(m.group(1)), m.group(2), m.group(3)
        if n in (9, 32):  # dwell, contour tolerance: no effect on the path
            return False
        if n not in (7, 19):
            raise self.err(f"cycle {n} is not read (machining and probing cycles move the "
                           "tool by the control's rules); supported: CYCL DEF 7 datum "
                           "shift, 19 working plane, 32 tolerance, 9 dwell")
        if sub in (None, "0"):
            return False
        if "#" in rest:
            raise self.err("datum tables (#) are not supported; expected X Y Z values")
        start = s.index(rest) if rest else len(s)
        d, ms = self.parse_words(start)
        if ms:
            raise self.err("M functions in a cycle definition; expected coordinates")
        if n == 7:
            if self.tilted:
                raise self.err("a datum shift while the plane is tilted is not supported; "
                               "expected it before PLANE / cycle 19")
            shift = self.shift.copy()
            for name, (val, col) in d.items():
                inc = name.startswith("I")
                a = _AX.get(name[-1])
                if a is None or len(name) > 1 + inc:
                    raise self.err(f"{name} in a datum shift; expected X Y Z (or IX IY IZ)", col)
                v = self.value(name, val, col) * self.scale
                shift[a] = shift[a] + v if inc else v
            self.reframe(self.R, self.tilted, shift)
            return False
        ang = [0.0, 0.0, 0.0]
        for name, (val, col) in d.items():
            if name not in _ROT:
                raise self.err(f"{name} in cycle 19; expected A B C (spatial angles)", col)
            ang[_ROT[name]] = self.value(name, val, col)
        self.set_tilt(ang)
        return False

    def set_tilt(self, ang) -> None:
        if self.tcpm and any(ang):
            raise self.err("a tilted plane under tool centre point control is not "
                           "supported; expected M129 / FUNCTION RESET TCPM before it")
        if any(ang):
            self.reframe(spatial_rotation(*ang), True, self.shift)
        else:
            self.reframe(np.eye(3), False, self.shift)

    def plane(self, s: str) -> bool:
        if s.startswith("PLANE RESET"):
            if not _PLANE_TAIL.fullmatch(s[len("PLANE RESET"):]):
                raise self.err("unexpected words after PLANE RESET; expected TURN, MOVE or "
                               "STAY and their options")
            self.set_tilt((0.0, 0.0, 0.0))
            if re.search(r"\b(?:TURN|MOVE)\b", s):
                self.rot = [0.0, 0.0, 0.0]  # the axes go back to their zero posture
                self.rot_unknown = False
            return False
        m = _SPATIAL.fullmatch(s)
        if not m:
            kind = s.split()[1] if len(s.split()) > 1 else ""
            raise self.err(f"PLANE {kind[:12]} is not supported; supported: PLANE SPATIAL "
                           "SPA.. SPB.. SPC.. and PLANE RESET")
        if not _PLANE_TAIL.fullmatch(m.group(4)):
            raise self.err(f"unexpected {m.group(4).split()[0][:16]!r} in PLANE; expected "
                           "TURN|MOVE|STAY and MB, FMAX, F, DIST, SYM, SEQ, COORD/TABLE ROT")
        ang = [self.value(nm, v, self.b.col) for nm, v in zip(("SPA", "SPB", "SPC"),
                                                               m.group(1, 2, 3))]
        self.set_tilt(ang)
        if re.search(r"\b(?:TURN|MOVE)\b", m.group(4)):
            self.rot_unknown = True
        return False

    def function(self, s: str) -> bool:
        if s == "FUNCTION RESET TCPM":
            self.tcpm, self.vector = False, None
            return False
        if s.startswith("FUNCTION MODE MILL"):
            return False
        if s.startswith("FUNCTION TCPM"):
            if not _TCPM_TAIL.fullmatch(s[len("FUNCTION TCPM"):]):
                raise self.err("unsupported FUNCTION TCPM options; supported: F TCP, "
                               "AXIS POS, PATHCTRL AXIS|VECTOR, REFPNT TIP-TIP (F CONT, AXIS "
                               "SPAT and other reference points are not read)")
            self.tcpm_on()
            return False
        raise self.err(f"unsupported {s[:30]!r}; supported: FUNCTION TCPM ..., FUNCTION RESET "
                       "TCPM, FUNCTION MODE MILL")

    # -- result ------------------------------------------------------------
    def program(self, file: str, lines: tuple[str, ...], newline: str, name: str,
                block_delete: bool) -> Program:
        return self.build_program(file, lines, newline, name, block_delete, self.metadata)

