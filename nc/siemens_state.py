"""The state a Sinumerik program runs under, and what each block does to it.

:class:`SState` keeps position (program frame: the swivelled plane of
CYCLE800, if any), modal G groups, feed, spindle, tool, TRAORI and its tool
vector, R parameters and DEF variables, and appends one row per move to the
output columns (:mod:`nc.siemens_moves` makes the moves);
:meth:`SState.program` makes the :class:`~nc.program.Program`.
"""

from __future__ import annotations

import math
import re

import numpy as np

from . import constants as K
from .errors import NCParseError
from .heidenhain_geom import arc_points
from .program import PLANE_AXES, TCP_ANGLES, TCP_OFF, TCP_VECTOR, Modal, Program, ProgramRows
from .siemens_blocks import SBlock, Word, split_args
from .siemens_expr import ExprError, evaluate
from .siemens_frames import PARAMS as C800_PARAMS
from .siemens_frames import (FrameError, Swivel, cycle800, plane_order, projection_frame,
                             rotation)

__all__ = ["SState", "SUPPORTED_BLOCKS", "G_IGNORED", "G_REFUSED", "K_IGNORED", "K_REFUSED"]

SUPPORTED_BLOCKS = ("G0 G1 G2 G3 (I J K, I=AC(..), CR=, TURN=), X Y Z A B C with AC/IC, "
                    "G17-G19, G90/G91, G93/G94, G700/G71/G710, G54-G57/G500/G505-G599, "
                    "G53/G153/SUPA, F S T D, M0-M9 M17 M30, TRAORI/TRAFOOF with A3= B3= C3=, "
                    "TRANS ATRANS ROT AROT ROTS AROTS, CYCLE800, CYCLE832, MSG, DEF REAL/INT, "
                    "R parameters, "
                    "labels with GOTOF/GOTOB/GOTO/GOTOC, IF/ELSE/ENDIF, WHILE, FOR, LOOP, "
                    "REPEAT/UNTIL, REPEAT/REPEATB label P=n")
_M_START = {3: 1, 4: -1}
_M_NOTHING = frozenset({0, 1, 6, 7, 8, 9})  # M6 handled apart; coolant, stops
_M_END = frozenset({2, 17, 30})
#: Path-control and other modal codes that do not move the programmed path.
G_IGNORED = {9: "exact stop (this block)", 60: "exact stop", 64: "continuous path",
              641: "blending", 642: "blending", 643: "blending", 644: "blending",
              645: "blending", 601: "exact stop window", 602: "exact stop window",
              603: "exact stop window", 40: "", 450: "corner behaviour",
              451: "corner behaviour", 97: "constant spindle speed", 25: "working area",
              26: "working area"}
G_REFUSED = {41: "cutter radius compensation moves the tool off the programmed path",
              42: "cutter radius compensation moves the tool off the programmed path",
              95: "feed per revolution", 96: "constant cutting speed",
              70: "inch geometry with feed in the machine's basic unit (use G700)",
              33: "thread cutting", 331: "tapping", 332: "tapping", 63: "tapping",
              110: "polar coordinates", 111: "polar coordinates", 112: "polar coordinates",
              5: "oblique plunge cutting", 7: "oblique plunge cutting", 74: "reference point "
              "approach (machine coordinates)", 75: "fixed point approach (machine "
              "coordinates)", 58: "programmable offset", 59: "programmable offset",
              147: "soft approach", 148: "soft retract", 247: "soft approach",
              248: "soft retract", 347: "soft approach", 348: "soft retract"}
#: Keywords read and passed over: they change how the control follows the path,
#: not the path (blending, look-ahead, compressor, acceleration, orientation
#: interpolation, preprocessing stop).
K_IGNORED = frozenset({"FFWON", "FFWOF", "SOFT", "BRISK", "DRIVE", "COMPOF", "COMPON",
                        "COMPCURV", "COMPCAD", "COMPSURF", "UPATH", "SPATH", "CFC", "CFTCP",
                        "CFIN", "STOPRE", "ORIAXES", "ORIVECT", "ORIWKS", "ORIPLANE",
                        "G642", "DYNNORM", "DYNPOS", "DYNROUGH", "DYNSEMIFIN", "DYNFINISH",
                        "TRAILOF", "PATHOFF", "WAITM", "ORISON", "ORISOF"})
K_REFUSED = {
    "SCALE": "scaling and mirroring frames (SCALE ASCALE MIRROR AMIRROR) are not read",
    "ASCALE": "scaling frames are not read", "MIRROR": "mirroring frames are not read",
    "AMIRROR": "mirroring frames are not read", "RPL": "rotations in the plane (RPL) are "
    "not read", "TCARR": "tool carriers (TCARR) need the "
    "machine's swivel data", "TOROT": "frame rotations (TOROT/PAROT) are not read",
    "PAROT": "frame rotations (TOROT/PAROT) are not read", "CIP": "circles through an "
    "intermediate point (CIP) are not read", "CT": "tangential circles (CT) are not read",
    "ASPLINE": "splines are not read", "BSPLINE": "splines are not read",
    "CSPLINE": "splines are not read", "POLY": "polynomials are not read",
    "ORIMKS": "tool vectors in machine coordinates (ORIMKS) are not read",
    "ORICURVE": "orientation curves (ORICURVE) are not read",
    "TRACYL": "cylinder transformations are not read", "TRANSMIT": "TRANSMIT is not read",
    "TRAANG": "inclined-axis transformations are not read",
    "GOTOF": "a jump must be its block's only statement (GOTOF label, or IF condition "
    "GOTOF label)", "GOTOB": "a jump must be its block's only statement",
    "GOTO": "a jump must be its block's only statement",
    "GOTOC": "a jump must be its block's only statement",
}
_CONTROL = ("IF", "ELSE", "ENDIF", "WHILE", "ENDWHILE", "FOR", "ENDFOR", "LOOP", "ENDLOOP",
            "REPEAT", "REPEATB", "UNTIL", "CASE", "TO", "ENDLABEL")
K_REFUSED.update({k: f"{k} must begin its own block (control statements stand alone)"
                  for k in _CONTROL[:13]})
K_REFUSED.update({
    "CALL": "subprogram calls are not read",
    "PCALL": "subprogram calls are not read", "MCALL": "modal subprogram calls are not read",
    "EXTCALL": "external subprogram calls are not read",
})
_DEF = re.compile(r"DEF\s+(REAL|INT)\s+(.+)")
_DEF_ITEM = re.compile(r"\s*([A-Z_][A-Z0-9_]*)\s*(?:=\s*(.+?))?\s*")
_AXIS_FN = re.compile(r"(AC|IC|DC|ACP|ACN)\s*\((.*)\)")
_RPARAM = re.compile(r"R\d+")
_PLAIN = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")
_RESERVED = frozenset({"X", "Y", "Z", "A", "B", "C", "I", "J", "K", "F", "S", "T", "D", "M",
                       "G", "N", "H", "L", "P", "R", "CR", "AR", "TURN", "A3", "B3", "C3",
                       "DIV", "MOD", "SIN", "COS", "TAN", "SQRT", "ABS", "POT", "TRUNC",
                       "ROUND", "ATAN2", "AC", "IC", "DC", "AND", "OR", "XOR", "NOT",
                       *_CONTROL})


class SState(ProgramRows):
    """Modal state and output columns of one run."""

    def __init__(self, file: str, lines: list[str], allowed: frozenset[str],
                 machine: object = None) -> None:
        self.file, self.lines, self.allowed = file, lines, allowed
        self.machine = machine  # nc.machines.Machine for CYCLE800's direct mode, or None
        self.scale, self.units = 1.0, 21
        self.distance, self.plane, self.feed_mode = 90, 17, 94
        self.motion: int | None = None
        self.ppos = np.zeros(3)
        self.rot = [0.0, 0.0, 0.0]
        self.swivel = Swivel(np.eye(3), np.zeros(3))   # CYCLE800
        self.pframe = Swivel(np.eye(3), np.zeros(3))   # TRANS/ROT/ATRANS/AROT
        self.frame = self.swivel                       # both: swivel, then pframe inside
        self.tilted = False                            # frame is not the identity
        self.turned = False                            # frame turns the tool axis
        self.feed = math.nan
        self.rpm, self.spindle, self.tool, self.tool_sel, self.d = 0.0, 0, 0, 0, 0
        self.wcs = 1
        self.traori = False
        self.vector: tuple[float, float, float] | None = None  # program frame
        self.params: dict[str, float] = {}
        self.ints: set[str] = set()
        self.metadata: dict = {}
        self.ignored: dict[str, list[int]] = {}
        self.init_rows()
        self.o_machine: list[int] = []
        self.b: SBlock | None = None
        #: lines of blocks whose words are kept once lexed (blocks in loops), and those
        self.lex_keep: set[int] | frozenset[int] = frozenset()
        self.lexed: dict[int, list[Word]] = {}

    # -- helpers ---------------------------------------------------------
    def err(self, msg: str, col: int | None = None) -> NCParseError:
        b = self.b
        return NCParseError(msg, file=self.file, line=b.line, column=col or b.col,
                            text=self.lines[b.line - 1])

    def as_written(self, w: Word) -> str:
        """The text of ``w`` in the case it was written (names, messages)."""
        raw = self.lines[self.b.line - 1]
        return raw[w.tcol - 1:w.tcol - 1 + len(w.text)].replace("\t", " ")

    def ignore(self, code: str) -> None:
        rec = self.ignored.get(code)
        if rec is None:
            self.ignored[code] = [1, self.b.line]
        else:
            rec[0] += 1

    def expr(self, text: str, col: int, what: str) -> float:
        """Value of an expression whose text starts at column ``col``."""
        try:
            v = evaluate(text, self.params)
        except ExprError as exc:
            raise self.err(f"{what}: {exc}", col + exc.offset) from None
        if not abs(v) <= K.MAX_ABS_WORD_VALUE:
            raise self.err(f"{what} = {v:g} is out of range; expected |value| <= "
                           f"{K.MAX_ABS_WORD_VALUE:g}", col)
        return v

    def number(self, w: Word) -> float:
        """The value of an address word (``X10`` or ``X=expr``), no AC/IC."""
        if w.kind == "A":
            v = float(w.text)
            if not abs(v) <= K.MAX_ABS_WORD_VALUE:
                raise self.err(f"{w.name}{w.text} is out of range; expected |value| <= "
                               f"{K.MAX_ABS_WORD_VALUE:g}", w.col)
            return v
        if _PLAIN.fullmatch(w.text):
            v = float(w.text)
            if not abs(v) <= K.MAX_ABS_WORD_VALUE:
                raise self.err(f"{w.name}={w.text} is out of range; expected |value| <= "
                               f"{K.MAX_ABS_WORD_VALUE:g}", w.col)
            return v
        if _AXIS_FN.fullmatch(w.text):
            raise self.err(f"{w.name}={w.text[:12]}: AC/IC/DC apply to axis and centre "
                           "words only", w.col)
        return self.expr(w.text, w.tcol, w.name)

    def axis_value(self, w: Word) -> tuple[float, str | None]:
        """Value and AC/IC/DC/ACP/ACN mode (None: the block's G90/G91) of an axis word."""
        if w.kind == "A" or _PLAIN.fullmatch(w.text):
            return self.number(w), None
        m = _AXIS_FN.fullmatch(w.text)
        if m:
            return (self.expr(m.group(2), w.tcol + m.start(2), f"{w.name}={m.group(1)}(..)"),
                    m.group(1))
        return self.expr(w.text, w.tcol, w.name), None

    def world(self, p: np.ndarray) -> np.ndarray:
        if not self.tilted:
            return p
        return self.frame.shift + self.frame.R @ p

    def modal_id(self, tcp: int) -> int:
        key = (self.plane, self.units, self.distance, 911, self.feed_mode, self.rpm,
               self.spindle, self.tool, self.d, tcp, self.wcs, 0)
        i = self.modal_ids.get(key)
        if i is None:
            i = self.modal_ids[key] = len(self.modals)
            self.modals.append(Modal(*key))
        return i

    def tcp_and_vector(self) -> tuple[int, tuple[float, float, float]]:
        nan3 = (math.nan, math.nan, math.nan)
        if self.traori:
            if self.vector is None:
                return TCP_ANGLES, nan3
            v = self.frame.R @ np.array(self.vector) if self.tilted else self.vector
            return TCP_VECTOR, (float(v[0]), float(v[1]), float(v[2]))
        if self.turned:
            v = self.frame.R[:, 2]
            return TCP_VECTOR, (float(v[0]), float(v[1]), float(v[2]))
        return TCP_OFF, nan3

    def emit(self, motion: int, pend: np.ndarray, arc=None, machine: bool = False) -> None:
        """One row ending at program-frame ``pend``; ``arc`` = (centre3, radii, sweep)."""
        if motion != 0 and not self.feed > 0:
            raise self.err("cutting move with no feed; expected F > 0 in this block or "
                           "before it")
        tcp, tv = self.tcp_and_vector()
        start = self.ppos
        if arc is not None and self.tilted and np.any(self.frame.R != np.eye(3)):
            centre, radii, sweep = arc
            axes = PLANE_AXES[self.plane]
            c2 = (centre[axes[0]], centre[axes[1]])
            for p in arc_points(axes, start, pend, c2, radii, sweep, K.CHORD_TOL_MM):
                self._row(1, self.world(p), tcp, tv, -1)
        else:
            k = -1
            if arc is not None:
                centre, radii, sweep = arc
                c = self.world(np.asarray(centre, dtype=float))
                k = len(self.a_sweep)
                self.a_centre.extend(c.tolist())
                self.a_radius.extend(radii)
                self.a_sweep.append(sweep)
                self.a_plane.append(self.plane)
            if machine:
                self.o_machine.append(len(self.o_line))
            self._row(motion, self.world(pend), tcp, tv, k)
        self.ppos = pend

    def _row(self, motion, w, tcp, tv, k) -> None:
        self.o_line.append(self.b.line)
        self.o_motion.append(motion)
        self.o_end.extend(w.tolist() if isinstance(w, np.ndarray) else w)
        self.o_end.extend(self.rot)
        self.o_feed.append(self.feed)
        self.o_modal.append(self.modal_id(tcp))
        self.o_tv.extend(tv)
        self.o_arc.append(k)

    # -- statements ---------------------------------------------------------
    def define(self, s: str) -> None:
        """``DEF REAL|INT name[=expr], ...``."""
        m = _DEF.fullmatch(s)
        if not m:
            what = s.split()[1] if len(s.split()) > 1 else ""
            raise self.err(f"DEF {what[:12]} is not read; supported: DEF REAL and DEF INT "
                           "variables (name or name=value, separated by commas)")
        typ = m.group(1)
        rest = m.group(2)
        off = self.b.col + m.start(2)
        for item in split_args(rest):
            im = _DEF_ITEM.fullmatch(item)
            if not im or "[" in item:
                raise self.err(f"DEF {typ}: expected name or name=value, found {item[:20]!r} "
                               "(arrays are not read)", off)
            name = im.group(1)
            if name in _RESERVED or _RPARAM.fullmatch(name) or re.fullmatch(r"[A-Z]\d*",
                                                                             name):
                raise self.err(f"DEF {typ} {name}: the name is an address or function of "
                               "the control; expected a name of two or more letters", off)
            if name in self.params:
                raise self.err(f"DEF {name}: defined twice", off)
            v = 0.0 if im.group(2) is None else self.expr(im.group(2), off, name)
            if typ == "INT":
                self.ints.add(name)
                v = _round_int(v)
            self.params[name] = v

    def assign(self, w: Word) -> None:
        v = self.expr(w.text, w.tcol, w.name)
        if w.name in self.ints:
            v = _round_int(v)
        self.params[w.name] = v

    def cycle800(self, w: Word) -> None:
        if self.traori:
            raise self.err("CYCLE800 while TRAORI is on; expected TRAFOOF before it", w.col)
        args = split_args(w.text) if w.text.strip() else []
        vals: list = []
        for k, a in enumerate(args):
            if a == "":
                vals.append(None)
            elif k == 1:
                vals.append(a.strip('"'))
            else:
                name = C800_PARAMS[k] if k < len(C800_PARAMS) else f"parameter {k + 1}"
                if a.startswith('"') or a.startswith("_"):
                    raise self.err(f"CYCLE800 {name} = {a[:16]}: expected a number", w.col)
                vals.append(self.expr(a, w.col, f"CYCLE800 {name}"))
        try:
            sw = cycle800(vals, self.swivel, self.machine)
        except FrameError as exc:
            raise self.err(str(exc), w.col) from None
        self.set_frames(sw, self.pframe)
        if vals and vals[0]:
            self.ignore("CYCLE800 retraction")
        if len(vals) > 1 and vals[1]:
            self.metadata.setdefault("swivel_data", []).append(vals[1])

    def set_frames(self, swivel: Swivel, pframe: Swivel) -> None:
        """New swivel and programmable frames; the tool stays where it is."""
        wpos = self.world(self.ppos)
        self.swivel, self.pframe = swivel, pframe
        fr = self.frame = swivel.then(pframe)
        self.tilted = not fr.identity
        self.turned = bool(np.any(fr.R[:, 2] != (0.0, 0.0, 1.0)))
        self.ppos = fr.R.T @ (wpos - fr.shift) if self.tilted else wpos

    def frame_statement(self, w: Word, ax: dict) -> None:
        """``TRANS ATRANS ROT AROT ROTS AROTS`` and their axis words: the programmable
        frame.

        ``ROTS``/``AROTS`` take one axis (as ``ROT``) or two solid angles
        (``X.. Y..``, ``Z.. X..``, ``Y.. Z..``:
        :func:`~nc.siemens_frames.projection_frame`).
        ``TRANS X..`` / ``ROT Z..`` replace it (no words: reset), ``ATRANS`` /
        ``AROT`` act on top of it; a rotation names one axis per block (the
        order of several depends on the machine's FRAME_ANGLE_INPUT_MODE).
        """
        name = w.name
        extra = [k for k in ax if k not in ("X", "Y", "Z")]
        if extra:
            raise self.err(f"{extra[0]} with {name}; expected X Y Z only", ax[extra[0]].col)
        vals = {k: self.number(v) for k, v in ax.items()}
        if name in ("TRANS", "ATRANS"):
            t = np.array([vals.get(k, 0.0) * self.scale for k in "XYZ"])
            new = Swivel(np.eye(3), t)
        elif name in ("ROTS", "AROTS") and len(vals) >= 2:
            if len(vals) > 2:
                raise self.err(f"{name} with three axes; expected at most two solid angles "
                               f"({name} X.. Y.., Z.. X.. or Y.. Z..)", w.col)
            first, second = plane_order(*("XYZ".index(k) for k in vals))
            try:
                R = projection_frame(first, second, vals["XYZ"[first]], vals["XYZ"[second]])
            except FrameError as exc:
                raise self.err(str(exc).replace("CYCLE800 projection", f"{name} solid"),
                               w.col) from None
            new = Swivel(R, np.zeros(3))
        else:
            if len(vals) > 1:
                raise self.err(f"{name} with more than one axis: the order of the rotations "
                               "is the machine's (FRAME_ANGLE_INPUT_MODE); expected one axis "
                               f"per block ({name} Z.. then AROT Y..)", w.col)
            new = Swivel(np.eye(3), np.zeros(3))
            for k, v in vals.items():
                new = Swivel(rotation("XYZ".index(k), v), np.zeros(3))
        pf = self.pframe.then(new) if name[0] == "A" else new
        self.set_frames(self.swivel, pf)

    def call(self, w: Word) -> None:
        name = w.name
        if name == "CYCLE800":
            self.cycle800(w)
        elif name == "CYCLE832":
            self.ignore("CYCLE832")
        elif name == "MSG":
            text = self.as_written(w).strip()
            if text:
                self.metadata.setdefault("messages", []).append(text.strip('"'))
        elif name == "WORKPIECE":
            self.metadata.setdefault("workpiece", []).append(self.as_written(w).strip())
        elif name == "TRAORI":
            args = split_args(w.text)
            if len(args) > 1 or (args[0] not in ("", "1")):
                raise self.err("TRAORI with parameters other than (1) is not read; expected "
                               "TRAORI or TRAORI(1)", w.col)
            self.traori_on()
        elif name in ("FFWON", "SOFT", "G642"):
            self.ignore(name)
        elif name.startswith("CYCLE") or name.startswith("POCKET") or name.startswith("SLOT"):
            raise self.err(f"{name} is not read (machining and measuring cycles move the "
                           "tool by the control's rules); supported: CYCLE800 (swivel "
                           "plane), CYCLE832 (tolerance)", w.col)
        else:
            raise self.err(f"unsupported call {name[:20]}(...) (subprograms and functions "
                           f"are not read); supported: CYCLE800, CYCLE832, MSG, TRAORI(1), "
                           "WORKPIECE", w.col)

    def traori_on(self) -> None:
        self.traori = True
        self.vector = None

    def m_start(self, ms: list[tuple[int, int]]) -> None:
        for m, col in ms:
            if m in _M_START:
                self.spindle = _M_START[m]
            elif m == 6:
                self.tool = self.tool_sel
            elif m in _M_NOTHING or m == 5 or m in _M_END:
                if m in (7, 8, 9):
                    self.ignore(f"M{m}")
            elif f"M{m}" in self.allowed:
                self.ignore(f"M{m}")
            else:
                raise self.err(f"unsupported M{m}; supported: M0 M1 M3 M4 M5 M6 M7 M8 M9 "
                               f"M17 M30 (if M{m} is harmless here, pass it in allow, e.g. "
                               f"allow=['M{m}'])", col)

    def m_end(self, ms: list[tuple[int, int]]) -> bool:
        end = False
        for m, _ in ms:
            if m == 5:
                self.spindle = 0
            elif m in _M_END:
                end = True
        return end

    # -- result ------------------------------------------------------------
    def program(self, file: str, lines: tuple[str, ...], newline: str, name: str | None,
                block_delete: bool) -> Program:
        ignored = tuple(sorted(((c, v[0], v[1]) for c, v in self.ignored.items()),
                               key=lambda t: (t[2], t[0])))
        return self.build_program(file, lines, newline, name, block_delete, self.metadata,
                                  allowed=self.allowed, ignored=ignored,
                                  machine_moves=np.array(self.o_machine, dtype=np.int64))


def _round_int(v: float) -> float:
    return float(math.floor(abs(v) + 0.5)) * (1.0 if v >= 0 else -1.0)
