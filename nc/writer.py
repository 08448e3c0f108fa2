"""Write 5-axis NC programs from cutter locations.

Three dialects:

``linuxcnc``
    Machine-axis program: X Y Z and the machine's two rotary words, from
    :func:`nc.kinematics.solve_path` (continuous branch, unwrapped, singular
    points held) and :func:`nc.kinematics.linearize` (points inserted where
    the linear interpolation of the machine axes would take the tip off the
    programmed line). Moves that turn a rotary axis are fed in inverse time
    (G93, ``F = 1/t`` with ``t`` the move's time at the programmed tip feed);
    pure linear moves in G94. LinuxCNC has no G43.4, so this form carries the
    kinematics in the numbers; it is what ``rs274`` checks.
``fanuc-g43.4``
    Tool centre point control, type 1: X Y Z is the tool tip in the
    workpiece frame, rotary words the machine angles; feed is tip feed (G94).
``fanuc-g43.5``
    Tool centre point control, type 2: X Y Z tip and I J K the unit tool
    vector; no rotary words.

Files are written atomically. Every program starts with a header of
comments (source, machine, tool, units), sets its modes explicitly and ends
with the configured end code.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from . import constants as K
from .atomic import atomic_write
from .errors import InputError, KinematicsError
from .kinematics import Machine, PathSolution, linearize, solve_path
from .path import CutterLocations
from .program import TCP_ANGLES, TCP_VECTOR

__all__ = ["DIALECTS", "PostOptions", "PostResult", "check_post_options", "post", "prepare_post", "read_back_errors",
           "round_trip_error", "write_if_read_back", "write_program"]

DIALECTS = ("linuxcnc", "fanuc-g43.4", "fanuc-g43.5")


@dataclass(frozen=True)
class PostOptions:
    """How a program is written.

    Attributes
    ----------
    dialect : str
        One of :data:`DIALECTS`.
    tool : int
        Tool number (T and H words).
    spindle_rpm : float or None [rev/min]
        Spindle speed; None takes the first cutter location's.
    linear_decimals, angle_decimals, vector_decimals : int
        Digits after the point for mm, degrees and unit vectors.
    line_numbers : bool
        Write N words.
    line_number_start, line_number_step : int
        First N and increment.
    header : bool
        Write the comment header (source, machine, tool, units, date-free).
    program_number : int or None
        O number for Fanuc dialects (None: no O word).
    percent : bool or None
        Enclose the program in ``%`` lines; None: for Fanuc dialects only.
    end_code : str or None
        ``"M30"``, ``"M2"`` or None (no end code).
    clearance_mm : float [mm]
        Approach and retract distance along the tool axis.
    linearize_tol_mm : float [mm]
        Tolerance of :func:`nc.kinematics.linearize` (``linuxcnc`` only).
    singular_cone_rad : float [rad]
        Half-angle of the cone around the rotary (C) axis inside which C is
        held (:func:`nc.kinematics.solve_path`). Widen it for CAM output whose
        tool axes wobble near vertical; the orientation error stays below it.
    rotary_only_feed_deg_min : float [deg/min]
        Rate for moves that turn rotary axes without moving the tip.
    source : str
        Name of the data the program was made from, for the header.
    """

    dialect: str = "linuxcnc"
    tool: int = 1
    spindle_rpm: float | None = None
    linear_decimals: int = K.LINEAR_DECIMALS
    angle_decimals: int = K.ANGLE_DECIMALS
    vector_decimals: int = K.VECTOR_DECIMALS
    line_numbers: bool = False
    line_number_start: int = 10
    line_number_step: int = 10
    header: bool = True
    program_number: int | None = 1000
    percent: bool | None = None
    end_code: str | None = "M30"
    clearance_mm: float = 10.0
    linearize_tol_mm: float = K.LINEARIZE_TOL_MM
    singular_cone_rad: float = K.SINGULAR_CONE_RAD
    rotary_only_feed_deg_min: float = K.ROTARY_ONLY_FEED_DEG_MIN
    source: str = ""

    def __post_init__(self) -> None:
        if self.dialect not in DIALECTS:
            raise ValueError(f"dialect: {self.dialect!r}; expected one of {', '.join(DIALECTS)}")
        for name in ("linear_decimals", "angle_decimals", "vector_decimals"):
            v = getattr(self, name)
            if not (isinstance(v, int) and 0 <= v <= 9):
                raise ValueError(f"{name}: expected an integer 0..9, got {v!r}")
        if self.end_code not in ("M30", "M2", None):
            raise ValueError(f"end_code: {self.end_code!r}; expected 'M30', 'M2' or None")
        if not (isinstance(self.tool, int) and self.tool >= 0):
            raise ValueError(f"tool: expected a whole number >= 0, got {self.tool!r}")
        for name in ("clearance_mm", "linearize_tol_mm", "rotary_only_feed_deg_min",
                     "singular_cone_rad"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name}: expected a finite value > 0, got {v!r}")
        if self.spindle_rpm is not None and not (math.isfinite(self.spindle_rpm)
                                                 and self.spindle_rpm >= 0):
            raise ValueError(f"spindle_rpm: expected a finite value >= 0, got {self.spindle_rpm!r}")


@dataclass(frozen=True)
class PostResult:
    """A written program and what it was computed from.

    Attributes
    ----------
    text : str
        The program.
    tip, axis : ndarray, shape (m, 3)
        Cutting points written, after linearization [mm], unit axis.
    joints : ndarray, shape (m, 5) [mm, rad]
        Machine axes of those points (X Y Z and the two rotary axes).
    source : ndarray, shape (m,)
        Fractional index of each written point in the input path.
    inverse_time_moves : int
        Moves written in G93.
    singular_points : int
        Points where the free rotary axis was held (inside the singular cone).
    first_written : int
        Index of the first of ``tip`` written as a move of its own: :func:`post` does
        not write the rapid points before the first feed point (the approach above that
        point replaces them), so that a read-back program starts there.
    """

    text: str
    tip: np.ndarray
    axis: np.ndarray
    joints: np.ndarray
    source: np.ndarray
    inverse_time_moves: int
    singular_points: int = 0
    notes: tuple[str, ...] = field(default_factory=tuple)
    first_written: int = 0


class _Lines:
    def __init__(self, opts: PostOptions) -> None:
        self.opts = opts
        self.out: list[str] = []
        self.n = opts.line_number_start

    def add(self, text: str, numbered: bool = True) -> None:
        if self.opts.line_numbers and numbered:
            text = f"N{self.n} {text}"
            self.n += self.opts.line_number_step
        self.out.append(text)


#: Comment text must not open or close a comment: parentheses become brackets.
_COMMENT_SAFE = str.maketrans({"(": "[", ")": "]", ";": ","})


def _num(v: float, decimals: int) -> str:
    s = f"{v:.{decimals}f}"
    return s[1:] if s[0] == "-" and not s.strip("-0.") else s


def check_post_options(opts) -> None:
    """The checks every dialect's post options share (the Heidenhain and Siemens
    options' ``__post_init__``): decimals 0..9, a whole tool number, a positive
    clearance [mm] and singular cone [rad], a spindle speed >= 0 [rev/min] if given.

    Raises
    ------
    ValueError
        Naming the option and what was expected.
    """
    self = opts
    for name in ("linear_decimals", "angle_decimals", "vector_decimals"):
        v = getattr(self, name)
        if not (isinstance(v, int) and 0 <= v <= 9):
            raise ValueError(f"{name}: expected an integer 0..9, got {v!r}")
    if not (isinstance(self.tool, int) and self.tool >= 0):
        raise ValueError(f"tool: expected a whole number >= 0, got {self.tool!r}")
    for name in ("clearance_mm", "singular_cone_rad"):
        v = getattr(self, name)
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name}: expected a finite value > 0, got {v!r}")
    if self.spindle_rpm is not None and not (math.isfinite(self.spindle_rpm)
                                             and self.spindle_rpm >= 0):
        raise ValueError(f"spindle_rpm: expected a finite value >= 0, got {self.spindle_rpm!r}")


def prepare_post(cl: CutterLocations, machine: Machine, singular_cone_rad: float,
                 spindle_rpm: float | None
                 ) -> tuple[np.ndarray, np.ndarray, PathSolution, float]:
    """What every writer starts from: the tips and axes of ``cl``, the machine's
    solution for them (``solve_path``: joints on a continuous branch within the axis
    limits, the points at the singularity), and the spindle speed written
    (``spindle_rpm``, else the first point's) [mm, -, -, rev/min].

    Raises
    ------
    nc.errors.InputError
        For no cutter locations.
    nc.errors.KinematicsError
        When a point cannot be reached within the machine's limits.
    """
    if len(cl) == 0:
        raise InputError("cl: no cutter locations to post")
    sol = solve_path(machine, cl.tip, cl.axis, singular_cone_rad=singular_cone_rad)
    spindle = spindle_rpm if spindle_rpm is not None else float(cl.spindle_rpm[0])
    return cl.tip, cl.axis, sol, spindle


def post(cl: CutterLocations, machine: Machine, options: PostOptions = PostOptions()
         ) -> PostResult:
    """Turn cutter locations into an NC program for ``machine``.

    Parameters
    ----------
    cl : CutterLocations
        Cutting points (rapids in ``cl`` are written as G0 moves).
    machine : Machine
        The machine: kinematics and axis limits (all dialects check limits;
        ``linuxcnc`` also writes its machine axes).
    options : PostOptions

    Returns
    -------
    PostResult

    Raises
    ------
    nc.errors.KinematicsError
        When a point cannot be reached within the machine's limits.
    """
    o = options
    tip, axis, sol, spindle = prepare_post(cl, machine, o.singular_cone_rad, o.spindle_rpm)
    joints = sol.joints
    source = np.arange(len(cl), dtype=float)
    if o.dialect == "linuxcnc":
        # rapids turn the tool by the machine's own interpolation of the angles (a link's
        # turn at the clearance height may pass near the pole, where a slerp cannot be
        # linearized); feed moves by slerp
        lin = linearize(machine, tip, axis, joints, tol_mm=o.linearize_tol_mm,
                        singular_cone_rad=o.singular_cone_rad,
                        joint_segments=np.asarray(cl.rapid, bool)[1:])
        if lin.max_deviation_mm > o.linearize_tol_mm:
            seg = np.diff(lin.source)
            raise KinematicsError(
                f"cannot keep the tool tip within {o.linearize_tol_mm:g} mm of the programmed "
                f"line: {lin.max_deviation_mm:.3g} mm remain after linearization; the rotary "
                "axes swing between neighbouring points (a noisy tool axis near the "
                "singularity?): widen singular_cone_rad or smooth the tool axes",
                index=int(np.floor(lin.source[int(np.argmin(seg))])) if len(seg) else None)
        tip, axis, joints, source = lin.tip, lin.axis, lin.joints, lin.source
    # the move ending at an inserted point belongs to the segment it splits
    seg = np.clip(np.ceil(source - 1e-9).astype(int), 0, len(cl) - 1)
    feed = cl.feed_mm_min[seg]
    rapid = cl.rapid[seg]
    names = machine.rotary_names
    L = _Lines(o)
    ld, ad, vd = o.linear_decimals, o.angle_decimals, o.vector_decimals
    fanuc = o.dialect.startswith("fanuc")
    percent = fanuc if o.percent is None else o.percent
    if percent:
        L.add("%", numbered=False)
    if fanuc and o.program_number is not None:
        L.add(f"O{o.program_number:04d}", numbered=False)
    if o.header:
        name = (o.source or "cutter locations").translate(_COMMENT_SAFE)
        L.add(f"(PROGRAM: {name} - {len(tip)} points)", numbered=False)
        L.add(f"(MACHINE: {machine.name}, ROTARY {names[0]}/{names[1]}, "
              f"DIALECT {o.dialect.upper()})", numbered=False)
        L.add(f"(TOOL: T{o.tool} H{o.tool}, UNITS: MM, FEED: MM/MIN)", numbered=False)
    L.add("G21 G90 G94 G17 G40 G49 G80")
    L.add(f"T{o.tool} M6")
    L.add(f"S{_num(spindle, 0)} M3")

    # every point's words at once (numpy to Python floats, then f-strings)
    lcnc = o.dialect == "linuxcnc"
    xyz = (joints[:, :3] if lcnc else tip).tolist()
    if o.dialect == "fanuc-g43.5":
        tails = [f" I{_num(i, vd)} J{_num(j, vd)} K{_num(k, vd)}" for i, j, k in axis.tolist()]
    else:
        r0, r1 = names
        tails = [f" {r0}{_num(a, ad)} {r1}{_num(c, ad)}"
                 for a, c in np.degrees(joints[:, 3:]).tolist()]
    words = [f"X{_num(x, ld)} Y{_num(y, ld)} Z{_num(z, ld)}{t}"
             for (x, y, z), t in zip(xyz, tails)]

    # approach: above the first point along its tool axis, same angles
    first = int(np.argmax(~rapid)) if np.any(~rapid) else 0
    app = _offset_point(machine, tip[first], axis[first], joints[first], o.clearance_mm)
    if lcnc:
        L.add(f"G43 H{o.tool}")
        L.add(f"G0 X{_num(app[0], ld)} Y{_num(app[1], ld)} Z{_num(app[2], ld)}{tails[first]}")
    else:
        code = "G43.4" if o.dialect == "fanuc-g43.4" else "G43.5"
        t_app = tip[first] + o.clearance_mm * axis[first]
        L.add(f"G0 {code} H{o.tool} X{_num(t_app[0], ld)} Y{_num(t_app[1], ld)} "
              f"Z{_num(t_app[2], ld)}{tails[first]}")

    # per move: tip distance, rotary turn, time; inverse time where rotaries turn
    n = len(tip)
    dist = np.zeros(n)
    dist[1:] = np.linalg.norm(np.diff(tip, axis=0), axis=1)
    dist[first] = o.clearance_mm  # the descent from the approach point
    turn = np.zeros(n)
    turn[1:] = np.abs(np.diff(joints[:, 3:], axis=0)).max(axis=1)
    turn[first] = 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        minutes = np.where(dist > 0, dist / feed,
                           np.degrees(turn) / o.rotary_only_feed_deg_min)
        inverse = 1.0 / minutes
    use_g93 = (lcnc & (turn > K.ROTARY_STILL_RAD) & ~rapid).tolist()
    rapid_l, feed_l, inverse_l = rapid.tolist(), feed.tolist(), inverse.tolist()

    mode = 94
    last_feed = None
    n_inv = 0
    for i in range(first, n):
        if rapid_l[i] and i != first:
            L.add(f"G0 {words[i]}")
            continue
        if use_g93[i]:
            lead = "G93 " if mode != 93 else ""
            mode = 93
            L.add(f"{lead}G1 {words[i]} F{_fmt_feed(inverse_l[i])}")
            last_feed = None
            n_inv += 1
        else:
            lead = "G94 " if mode != 94 else ""
            if mode != 94:
                last_feed = None
            mode = 94
            f_mm = feed_l[i]
            fw = f" F{_fmt_feed(f_mm)}" if (last_feed is None or abs(f_mm - last_feed) > 1e-9) else ""
            L.add(f"{lead}G1 {words[i]}{fw}")
            last_feed = f_mm

    last = len(tip) - 1
    if mode != 94:
        L.add("G94")
    ret = _offset_point(machine, tip[last], axis[last], joints[last], o.clearance_mm)
    if o.dialect == "linuxcnc":
        L.add(f"G0 X{_num(ret[0], ld)} Y{_num(ret[1], ld)} Z{_num(ret[2], ld)}")
    else:
        t_ret = tip[last] + o.clearance_mm * axis[last]
        L.add(f"G0 X{_num(t_ret[0], ld)} Y{_num(t_ret[1], ld)} Z{_num(t_ret[2], ld)}")
        L.add("G49")
    L.add("M5")
    if o.end_code:
        L.add(o.end_code)
    if percent:
        L.add("%", numbered=False)
    return PostResult(text="\n".join(L.out) + "\n", tip=tip, axis=axis, joints=joints,
                      source=source, inverse_time_moves=n_inv,
                      singular_points=int(np.sum(sol.singular)), first_written=first)


def _fmt_feed(f: float) -> str:
    """Feed with 4 significant decimals, no trailing zeros beyond one."""
    s = f"{f:.4f}".rstrip("0")
    return s + "0" if s.endswith(".") else s


def _offset_point(machine: Machine, tip, axis, joints, clearance_mm: float) -> np.ndarray:
    """Machine XYZ of the point ``clearance_mm`` up the tool axis, same angles."""
    up = np.asarray(tip) + clearance_mm * np.asarray(axis)
    sol = solve_path(machine, up[None, :], np.asarray(axis)[None, :], start=joints)
    return sol.joints[0, :3]


def write_program(path: str | os.PathLike, cl: CutterLocations, machine: Machine,
                  options: PostOptions = PostOptions()) -> PostResult:
    """Post ``cl`` (see :func:`post`) and write the program atomically to ``path``."""
    result = post(cl, machine, options)
    with atomic_write(path) as fh:
        fh.write(result.text)
    return result


def round_trip_error(post_res: PostResult, back: CutterLocations) -> tuple[float, float]:
    """Largest tip [mm] and axis [rad] difference between written and read-back points
    (the writer's approach and retract points are skipped by the best alignment; the
    rapid points before the first feed point, which the writer leaves out, are not
    compared: ``PostResult.first_written``)."""
    tip = post_res.tip[post_res.first_written:]
    axis = post_res.axis[post_res.first_written:]
    n = min(len(tip), len(back))
    best = (math.inf, math.inf)
    for off in range(max(1, len(back) - len(tip) + 1)):
        a = back.tip[off:off + n]
        if len(a) != n:
            break
        e_t = float(np.max(np.linalg.norm(a - tip[:n], axis=1)))
        c = np.clip(np.sum(back.axis[off:off + n] * axis[:n], axis=1), -1, 1)
        e_a = float(np.max(np.arccos(c)))
        if e_t < best[0]:
            best = (e_t, e_a)
    return best


def read_back_errors(prog, result: PostResult, machine: Machine, angles: bool,
                     mode: str) -> tuple[float, float]:
    """Largest tip error [mm] and angle error [deg] of a program read back by its own
    reader (the Heidenhain and Siemens posts: their first and last rows are the writer's
    approach and retract).

    Parameters
    ----------
    prog : nc.program.Program
        The written text as read back.
    result : PostResult
        What was written.
    machine : Machine
    angles : bool
        The rows carry rotary angles (the error is that of the rotary words); otherwise
        tool vectors (the angle between written and read vectors).
    mode : str
        The dialect's name for tool-centre-point control, for the message (``TCPM``,
        ``TRAORI``).
    """
    rows = slice(1, len(prog) - 1)
    tip = prog.end[rows, :3]
    if tip.shape[0] != len(result.tip):
        raise InputError(f"read back {tip.shape[0]} cutting rows, wrote {len(result.tip)}")
    e_tip = float(np.max(np.linalg.norm(tip - result.tip, axis=1)))
    tcp = prog.modal_column("tcp")[rows]
    if angles:
        if not np.all(tcp == TCP_ANGLES):
            raise InputError(f"read back rows not under {mode} with angles")
        cols = ["XYZABC".index(c) for c in machine.rotary_names]
        e_ang = float(np.degrees(np.max(np.abs(prog.end[rows][:, cols] - result.joints[:, 3:]))))
    else:
        if not np.all(tcp == TCP_VECTOR):
            raise InputError(f"read back rows not under {mode} with tool vectors")
        c = np.clip(np.sum(prog.tool_vector[rows] * result.axis, axis=1), -1.0, 1.0)
        e_ang = float(np.degrees(np.max(np.arccos(c))))
    return e_tip, e_ang


def write_if_read_back(path: str | os.PathLike, result: PostResult,
                       errors: tuple[float, float], tol_mm: float, tol_deg: float) -> PostResult:
    """Write ``result`` atomically to ``path`` if its read-back ``errors`` (tip [mm],
    angle [deg]) are within ``tol_mm`` and ``tol_deg``; otherwise write nothing and raise
    :class:`nc.errors.InputError` naming the file and both differences."""
    e_tip, e_ang = errors
    if not (e_tip <= tol_mm and e_ang <= tol_deg):
        raise InputError(f"{os.fspath(path)}: not written: read back differs by "
                         f"{e_tip:.3g} mm / {e_ang:.3g} deg (limits {tol_mm:g} mm, "
                         f"{tol_deg:g} deg); raise the decimals")
    with atomic_write(path) as fh:
        fh.write(result.text)
    return result
