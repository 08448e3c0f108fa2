"""Write 5-axis tool paths as Heidenhain TNC conversational (Klartext) programs.

Two forms, both under tool centre point control (``FUNCTION TCPM F TCP AXIS
POS PATHCTRL AXIS``, or ``M128`` on older controls):

``tcpm-angles``
    ``L X Y Z <rotary> <rotary>``: tool tip in the workpiece frame and the
    machine's rotary axis angles from :func:`nc.kinematics.solve_path`
    (continuous branch, inside the limits), as the Fanuc G43.4 writer does.
``ln-vector``
    ``LN X Y Z NX NY NZ TX TY TZ``: tip and unit tool vector (tip toward the
    spindle); the control chooses the angles (limits are still checked here).
    No surface normal is known, so ``N`` is written equal to ``T``: with no
    delta radii (none are written) the TNC places the tool tip on X Y Z.

Every program is read back by :func:`nc.heidenhain.parse_heidenhain` and
compared with what was meant before :func:`write_heidenhain` writes it.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass

import numpy as np

from . import constants as K
from .errors import InputError
from .heidenhain import parse_heidenhain
from .kinematics import Machine
from .path import CutterLocations
from .writer import PostResult, check_post_options, prepare_post, read_back_errors, write_if_read_back

__all__ = ["TNC_FORMS", "TNCPostOptions", "post_heidenhain", "write_heidenhain",
           "heidenhain_round_trip"]

TNC_FORMS = ("tcpm-angles", "ln-vector")


@dataclass(frozen=True)
class TNCPostOptions:
    """How a Klartext program is written.

    Attributes
    ----------
    form : str
        One of :data:`TNC_FORMS`.
    tcpm : str
        ``"function"`` (FUNCTION TCPM, TNC 640) or ``"m128"``.
    program_name : str
        Name in BEGIN/END PGM: letters, digits, ``_`` and ``-``.
    tool : int
        Tool number of the TOOL CALL.
    spindle_rpm : float or None [rev/min]
        None takes the first cutter location's.
    linear_decimals, angle_decimals, vector_decimals : int
        Digits after the point for mm, degrees and unit vectors.
    clearance_mm : float [mm]
        Approach and retract distance along the tool axis.
    singular_cone_rad : float [rad]
        See :class:`nc.writer.PostOptions`.
    header : bool
        Write ``;`` comment lines naming the source, machine and form.
    source : str
        Name of the data the program was made from, for the header.
    """

    form: str = "tcpm-angles"
    tcpm: str = "function"
    program_name: str = "NCPATH"
    tool: int = 1
    spindle_rpm: float | None = None
    linear_decimals: int = K.LINEAR_DECIMALS
    angle_decimals: int = K.ANGLE_DECIMALS
    vector_decimals: int = K.TNC_VECTOR_DECIMALS
    clearance_mm: float = 10.0
    singular_cone_rad: float = K.SINGULAR_CONE_RAD
    header: bool = True
    source: str = ""

    def __post_init__(self) -> None:
        if self.form not in TNC_FORMS:
            raise ValueError(f"form: {self.form!r}; expected one of {', '.join(TNC_FORMS)}")
        if self.tcpm not in ("function", "m128"):
            raise ValueError(f"tcpm: {self.tcpm!r}; expected 'function' or 'm128'")
        if not re.fullmatch(r"[A-Za-z0-9_-]{1,64}", self.program_name):
            raise ValueError(f"program_name: {self.program_name!r}; expected 1-64 letters, "
                             "digits, '_' or '-'")
        check_post_options(self)


def _n(v: float, d: int) -> str:
    s = f"{v:+.{d}f}"
    return "+" + s[1:] if s[0] == "-" and not s.strip("-+0.") else s


def _f(v: float) -> str:
    s = f"{v:.3f}".rstrip("0").rstrip(".")
    return s or "0"


def post_heidenhain(cl: CutterLocations, machine: Machine,
                    options: TNCPostOptions = TNCPostOptions()) -> PostResult:
    """Turn cutter locations into a Klartext program for ``machine``.

    Parameters
    ----------
    cl : CutterLocations
        Cutting points; rapids in ``cl`` are written with FMAX.
    machine : Machine
        Kinematics and limits (angles of ``tcpm-angles``; limits for both).
    options : TNCPostOptions

    Returns
    -------
    PostResult
        ``text``, the points written (tip, axis, joints), no inserted points.

    Raises
    ------
    nc.errors.KinematicsError
        When a point cannot be reached within the machine's limits.
    """
    o = options
    tip, axis, sol, spindle = prepare_post(cl, machine, o.singular_cone_rad, o.spindle_rpm)
    joints = sol.joints
    ld, ad, vd = o.linear_decimals, o.angle_decimals, o.vector_decimals
    names = machine.rotary_names
    out: list[str] = []
    add = out.append
    add(f"BEGIN PGM {o.program_name} MM")
    if o.header:
        src = (o.source or "cutter locations").replace(";", ",").replace("\n", " ")
        add(f"; PROGRAM: {src} - {len(tip)} points")
        add(f"; MACHINE: {machine.name}, ROTARY {names[0]}/{names[1]}, FORM {o.form.upper()}")
        add(f"; TOOL: {o.tool}, UNITS: MM, FEED: MM/MIN, TOOL TIP PROGRAMMED")
    add(f"TOOL CALL {o.tool} Z S{_f(spindle)}")
    add("FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS" if o.tcpm == "function" else "M128")

    first = int(np.argmax(~cl.rapid)) if np.any(~cl.rapid) else 0
    app = tip[first] + o.clearance_mm * axis[first]
    ret = tip[-1] + o.clearance_mm * axis[-1]
    big = max(float(np.max(np.abs(tip))), float(np.max(np.abs(app))), float(np.max(np.abs(ret))))
    fmax = float(np.nanmax(np.where(cl.rapid, 0.0, cl.feed_mm_min)))
    if big > K.TNC_MAX_COORDINATE_MM or fmax > K.TNC_MAX_FEED or spindle > K.TNC_MAX_FEED:
        raise InputError(f"a coordinate ({big:.6g} mm), feed ({fmax:.6g} mm/min) or spindle "
                         f"speed ({spindle:.6g} rev/min) beyond what a TNC accepts "
                         f"({K.TNC_MAX_COORDINATE_MM:g} mm, {K.TNC_MAX_FEED:g})")
    xyz = tip.tolist()
    if o.form == "tcpm-angles":
        deg = np.degrees(joints[:, 3:]).tolist()
        tails = [f" {names[0]}{_n(a, ad)} {names[1]}{_n(c, ad)}" for a, c in deg]
        verb = "L"
    else:
        tails = []
        for i, j, k in axis.tolist():
            v = f"{_n(i, vd)} NY{_n(j, vd)} NZ{_n(k, vd)}"
            tails.append(f" NX{v} TX{_n(i, vd)} TY{_n(j, vd)} TZ{_n(k, vd)}")
        verb = "LN"

    def xyz_words(p) -> str:
        return f"X{_n(p[0], ld)} Y{_n(p[1], ld)} Z{_n(p[2], ld)}"

    rapid = cl.rapid.tolist()
    feed = cl.feed_mm_min.tolist()
    r0 = " R0" if verb == "L" else ""
    add(f"{verb} {xyz_words(app)}{tails[first]}{r0} FMAX M3")
    last_feed = None
    for i in range(first, len(tip)):
        words = f"{verb} {xyz_words(xyz[i])}{tails[i]}{r0}"
        if rapid[i] and i != first:
            add(words + " FMAX")
            continue
        f = feed[i]
        if last_feed is None or abs(f - last_feed) > 1e-9:
            words += f" F{_f(f)}"
            last_feed = f
        add(words)
    add(f"{verb} {xyz_words(ret)}{tails[-1]}{r0} FMAX")
    add("FUNCTION RESET TCPM" if o.tcpm == "function" else "M129")
    add("M5")
    add("M30")
    add(f"END PGM {o.program_name} MM")
    text = "\n".join(f"{i} {line}" for i, line in enumerate(out)) + "\n"
    return PostResult(text=text, tip=tip, axis=axis, joints=joints,
                      source=np.arange(len(cl), dtype=float), inverse_time_moves=0,
                      singular_points=int(np.sum(sol.singular)))


def heidenhain_round_trip(result: PostResult, machine: Machine, form: str
                          ) -> tuple[float, float]:
    """Read ``result.text`` back; largest tip error [mm] and angle error [deg].

    For ``tcpm-angles`` the angle error is that of the rotary words; for
    ``ln-vector`` the angle between written and read tool vectors.
    """
    return read_back_errors(parse_heidenhain(result.text, file="<written>"), result, machine,
                            form == "tcpm-angles", "TCPM")


def write_heidenhain(path: str | os.PathLike, cl: CutterLocations, machine: Machine,
                     options: TNCPostOptions = TNCPostOptions(), *,
                     tol_mm: float = 1.0e-3, tol_deg: float = 1.0e-4) -> PostResult:
    """Post ``cl``, read it back, and write it atomically only if it matches.

    Raises
    ------
    nc.errors.InputError
        When the program read back differs from the path by more than
        ``tol_mm`` [mm] or ``tol_deg`` [deg] (nothing is written).
    """
    res = post_heidenhain(cl, machine, options)
    return write_if_read_back(path, res, heidenhain_round_trip(res, machine, options.form), tol_mm,
                              tol_deg)
