"""Write 5-axis tool paths as Siemens Sinumerik 840D programs under TRAORI.

Two forms, both with the 5-axis transformation on (``TRAORI``): X Y Z is the
tool tip in the workpiece frame, feed the tip's (G94).

``vector`` (post ``siemens-traori``)
    ``G1 X Y Z A3= B3= C3=``: tip and unit tool vector (tip toward the
    spindle, orientation in the workpiece frame, ``ORIWKS``); the control
    chooses the angles (the machine's limits are still checked here).
``rotary`` (post ``siemens-traori-rot``)
    ``G1 X Y Z <rotary> <rotary>``: tip and the machine's rotary axis angles
    from :func:`nc.kinematics.solve_path` (continuous branch, inside the
    limits), as the Fanuc G43.4 writer does.

Every program is read back by :func:`nc.siemens.parse_siemens` and compared
with what was meant before :func:`write_siemens` writes it.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass

import numpy as np

from . import constants as K
from .errors import InputError
from .kinematics import Machine
from .path import CutterLocations
from .siemens import parse_siemens
from .writer import PostResult, check_post_options, prepare_post, read_back_errors, write_if_read_back

__all__ = ["SIEMENS_FORMS", "SIEMENS_POSTS", "SiemensPostOptions", "post_siemens",
           "write_siemens", "siemens_round_trip"]

SIEMENS_FORMS = ("vector", "rotary")
#: Post names (``python -m nc post --dialect``) and their forms.
SIEMENS_POSTS = {"siemens-traori": "vector", "siemens-traori-rot": "rotary"}


@dataclass(frozen=True)
class SiemensPostOptions:
    """How a Sinumerik program is written.

    Attributes
    ----------
    form : str
        One of :data:`SIEMENS_FORMS`.
    program_name : str
        Name in the ``%_N_name_MPF`` header: upper-case letters, digits, ``_``.
    tool : int
        Tool number (``T`` and ``M6``), cutting edge ``D1``.
    spindle_rpm : float or None [rev/min]
        None takes the first cutter location's.
    linear_decimals, angle_decimals, vector_decimals : int
        Digits after the point for mm, degrees and unit vectors.
    clearance_mm : float [mm]
        Approach and retract distance along the tool axis.
    singular_cone_rad : float [rad]
        See :class:`nc.writer.PostOptions`.
    line_numbers : bool
        Write ``N`` block numbers (10, 20, ...).
    header : bool
        Write ``;`` comment lines naming the source, machine and form.
    source : str
        Name of the data the program was made from, for the header.
    """

    form: str = "vector"
    program_name: str = "NCPATH"
    tool: int = 1
    spindle_rpm: float | None = None
    linear_decimals: int = K.LINEAR_DECIMALS
    angle_decimals: int = K.ANGLE_DECIMALS
    vector_decimals: int = K.SIEMENS_VECTOR_DECIMALS
    clearance_mm: float = 10.0
    singular_cone_rad: float = K.SINGULAR_CONE_RAD
    line_numbers: bool = True
    header: bool = True
    source: str = ""

    def __post_init__(self) -> None:
        if self.form not in SIEMENS_FORMS:
            raise ValueError(f"form: {self.form!r}; expected one of {', '.join(SIEMENS_FORMS)}")
        if not re.fullmatch(r"[A-Z][A-Z0-9_]{0,23}", self.program_name):
            raise ValueError(f"program_name: {self.program_name!r}; expected 1-24 upper-case "
                             "letters, digits or '_', a letter first")
        check_post_options(self)


def _n(v: float, d: int) -> str:
    s = f"{v:.{d}f}"
    return s[1:] if s[0] == "-" and not s.strip("-0.") else s


def _f(v: float) -> str:
    s = f"{v:.3f}".rstrip("0").rstrip(".")
    return s or "0"


def post_siemens(cl: CutterLocations, machine: Machine,
                 options: SiemensPostOptions = SiemensPostOptions()) -> PostResult:
    """Turn cutter locations into a Sinumerik TRAORI program for ``machine``.

    Parameters
    ----------
    cl : CutterLocations
        Cutting points; rapids in ``cl`` are written with G0.
    machine : Machine
        Kinematics and limits (angles of the ``rotary`` form; limits for both).
    options : SiemensPostOptions

    Returns
    -------
    PostResult
        ``text``, the points written (tip, axis, joints), no inserted points.

    Raises
    ------
    nc.errors.KinematicsError
        When a point cannot be reached within the machine's limits.
    nc.errors.InputError
        A coordinate, feed or speed beyond what the writer puts in a word.
    """
    o = options
    tip, axis, sol, spindle = prepare_post(cl, machine, o.singular_cone_rad, o.spindle_rpm)
    joints = sol.joints
    ld, ad, vd = o.linear_decimals, o.angle_decimals, o.vector_decimals
    names = machine.rotary_names
    # approach above the first point along its tool axis; every point is written
    # (rapids in cl as G0, leading ones too)
    app = tip[0] + o.clearance_mm * axis[0]
    ret = tip[-1] + o.clearance_mm * axis[-1]
    big = max(float(np.max(np.abs(tip))), float(np.max(np.abs(app))), float(np.max(np.abs(ret))))
    fmax = float(np.nanmax(np.where(cl.rapid, 0.0, cl.feed_mm_min)))
    if big > K.SIEMENS_MAX_WORD or fmax > K.SIEMENS_MAX_WORD or spindle > K.SIEMENS_MAX_WORD:
        raise InputError(f"a coordinate ({big:.6g} mm), feed ({fmax:.6g} mm/min) or spindle "
                         f"speed ({spindle:.6g} rev/min) beyond what the writer puts in a "
                         f"word ({K.SIEMENS_MAX_WORD:g})")
    body: list[str] = []
    add = body.append
    add("G17 G40 G90 G71 G94")
    add(f"T{o.tool} M6")
    add("D1")
    add(f"S{_f(spindle)} M3")
    add("TRAORI")
    if o.form == "vector":
        add("ORIWKS")
        tails = [f" A3={_n(i, vd)} B3={_n(j, vd)} C3={_n(k, vd)}" for i, j, k in axis.tolist()]
    else:
        deg = np.degrees(joints[:, 3:]).tolist()
        tails = [f" {names[0]}{_n(a, ad)} {names[1]}{_n(c, ad)}" for a, c in deg]

    def xyz(p) -> str:
        return f"X{_n(p[0], ld)} Y{_n(p[1], ld)} Z{_n(p[2], ld)}"

    rapid = cl.rapid.tolist()
    feed = cl.feed_mm_min.tolist()
    pts = tip.tolist()
    add(f"G0 {xyz(app)}{tails[0]}")
    last_feed = None
    mode = 0
    for i in range(len(pts)):
        if rapid[i]:
            add(f"G0 {xyz(pts[i])}{tails[i]}")
            mode = 0
            continue
        words = f"{xyz(pts[i])}{tails[i]}"
        if mode != 1:
            words = "G1 " + words
            mode = 1
        f = feed[i]
        if last_feed is None or abs(f - last_feed) > 1e-9:
            words += f" F{_f(f)}"
            last_feed = f
        add(words)
    add(f"G0 {xyz(ret)}{tails[-1]}")
    add("TRAFOOF")
    add("M5")
    add("M30")
    out = [f"%_N_{o.program_name}_MPF", ";$PATH=/_N_MPF_DIR"]
    if o.header:
        src = (o.source or "cutter locations").replace("\n", " ").replace(";", ",")
        out.append(f"; PROGRAM: {src} - {len(tip)} points")
        out.append(f"; MACHINE: {machine.name}, ROTARY {names[0]}/{names[1]}, "
                   f"FORM {o.form.upper()}")
        out.append(f"; TOOL: T{o.tool} D1, UNITS: MM, FEED: MM/MIN, TOOL TIP PROGRAMMED")
    if o.line_numbers:
        out.extend(f"N{10 * (k + 1)} {line}" for k, line in enumerate(body))
    else:
        out.extend(body)
    text = "\n".join(out) + "\n"
    return PostResult(text=text, tip=tip, axis=axis, joints=joints,
                      source=np.arange(len(cl), dtype=float), inverse_time_moves=0,
                      singular_points=int(np.sum(sol.singular)))


def siemens_round_trip(result: PostResult, machine: Machine, form: str
                       ) -> tuple[float, float]:
    """Read ``result.text`` back; largest tip error [mm] and angle error [deg].

    For ``rotary`` the angle error is that of the rotary words; for ``vector``
    the angle between written and read tool vectors.
    """
    return read_back_errors(parse_siemens(result.text, file="<written>"), result, machine,
                            form == "rotary", "TRAORI")


def write_siemens(path: str | os.PathLike, cl: CutterLocations, machine: Machine,
                  options: SiemensPostOptions = SiemensPostOptions(), *,
                  tol_mm: float = 1.0e-3, tol_deg: float = 1.0e-4) -> PostResult:
    """Post ``cl``, read it back, and write it atomically only if it matches.

    Raises
    ------
    nc.errors.InputError
        When the program read back differs from the path by more than
        ``tol_mm`` [mm] or ``tol_deg`` [deg] (nothing is written).
    """
    res = post_siemens(cl, machine, options)
    return write_if_read_back(path, res, siemens_round_trip(res, machine, options.form), tol_mm,
                              tol_deg)
