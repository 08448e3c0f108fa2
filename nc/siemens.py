"""Read Siemens Sinumerik 840D programs into a :class:`~nc.program.Program`.

What is read:

* ``%_N_name_MPF`` (or ``_SPF``) header, ``;`` comments (``;$PATH=...``
  among them), ``N`` and ``:`` block numbers, jump labels ``NAME:``, ``/``
  block skip, ``MSG("...")`` (kept in ``Program.metadata``), ``WORKPIECE(...)``.
* Words with a number (``X10.5``, ``G1``) or ``=`` and an expression
  (``X=R1*2``, ``Z=IC(-1)``); ``R`` parameters and ``DEF REAL|INT``
  variables, with ``+ - * / DIV MOD`` and ``SIN COS TAN ASIN ACOS ATAN2 SQRT
  ABS POT TRUNC ROUND EXP LN MINVAL MAXVAL`` (:mod:`nc.siemens_expr`).
* ``G0 G1 G2 G3``; arcs with ``I J K`` (incremental from the start whatever
  G90/G91; ``I=AC(..)`` absolute), ``CR=`` radius (negative: more than 180
  deg), ``TURN=`` extra turns, helices; ``G17 G18 G19``, ``G90 G91``,
  ``AC()``/``IC()`` on axis words, ``DC() ACP() ACN()`` on rotary axes;
  ``G93 G94``, ``G700 G71 G710``; ``F S T D M6``, ``M3 M4 M5``, coolant;
  ``G54``-``G57``, ``G500``, ``G505``-``G599`` (offsets taken as zero: the
  positions are in the program's frame); ``SUPA``, ``G53``, ``G153``
  (machine coordinates, the block only: the base frame without offsets).
* Path-control codes read and passed over (``Program.ignored``): ``G64
  G641``-``G645 G60 G601``-``G603 G9``, ``CYCLE832`` (tolerance), ``FFWON
  SOFT BRISK COMPCAD COMPCURV ORIWKS ORIAXES ORIVECT STOPRE`` and the like.
* ``TRAORI`` (tool tip programmed): ``A3= B3= C3=`` tool vectors (stored as
  G43.5 vectors; components not programmed are 0, as on the control) or
  rotary axis words ``A B C`` (machine angles, stored as G43.4 would be);
  ``TRAFOOF``.
* ``CYCLE800`` (swivel plane, :mod:`nc.siemens_frames`): axis-by-axis modes
  (e.g. 57 = X Y Z, 27 = Z Y X), solid angle (64) and projection angle (128 +
  axis sequence, e.g. 185); the following moves are turned into the workpiece
  frame, carry the swivelled tool axis as a tool vector, and arcs in a
  swivelled plane are stored as chords.
* ``TRANS ATRANS ROT AROT`` (one rotation axis per block), ``ROTS AROTS`` (one
  axis or two solid angles): the programmable frame, inside the CYCLE800 swivel.
* Control flow (:mod:`nc.siemens_flow`): jump labels (``MARK1:``) and block
  numbers as targets of ``GOTOF GOTOB GOTO GOTOC``, alone or after ``IF
  condition``; ``IF/ELSE/ENDIF``, ``WHILE/ENDWHILE``, ``FOR/ENDFOR``,
  ``LOOP/ENDLOOP``, ``REPEAT/UNTIL``; ``REPEAT``/``REPEATB label P=n`` section
  repeats; bounded by ``SIEMENS_MAX_EXECUTED_BLOCKS``, ``SIEMENS_MAX_LOOP_PASSES``
  and ``SIEMENS_MAX_REPEAT_DEPTH``.
* ``M30 M2 M17 RET`` end the program.

Everything else ends the read with one :class:`~nc.errors.NCParseError`
(``file:line:col: message``) naming what was found and what is supported.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable

from .errors import NCParseError
from .program import Program
from .siemens_blocks import split_blocks
from .siemens_flow import plan, run
from .siemens_moves import execute
from .siemens_state import SState

__all__ = ["read_siemens", "parse_siemens", "normalise_allow"]

_ALLOW = re.compile(r"(?:[GMH]\d+|[A-Z_][A-Z0-9_]*)")
#: Codes that move the tool or the frame: never passed over.
_NOT_ALLOWABLE = frozenset({"G41", "G42", "G95", "G96", "G70", "G74", "G75", "TRANS",
                            "ATRANS", "ROT", "AROT", "ROTS", "AROTS", "SCALE", "MIRROR",
                            "TCARR", "TOROT", "PAROT", "CIP", "CT", "ASPLINE", "BSPLINE",
                            "CSPLINE", "POLY"})


def read_siemens(path: str | os.PathLike, **options) -> Program:
    """Read a Sinumerik file; see :func:`parse_siemens` for ``options``."""
    name = os.fspath(path)
    with open(name, "rb") as fh:
        data = fh.read()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        text = data.decode("latin-1")  # umlauts in comments; latin-1 decodes every byte
    if "\x00" in text:
        line = text.count("\n", 0, text.index("\x00")) + 1
        raise NCParseError("expected text, found a NUL byte", file=name, line=line)
    return parse_siemens(text, file=name, **options)


def normalise_allow(allow: Iterable[str], file: str = "<string>") -> frozenset[str]:
    """``["m110", "FGROUP"]`` -> {"M110", "FGROUP"}; refuses codes that move the tool
    (:class:`~nc.errors.NCParseError` naming ``file``)."""
    out = set()
    for item in allow:
        s = str(item).strip().upper().replace(" ", "")
        if not _ALLOW.fullmatch(s):
            raise NCParseError(f"allow: {str(item)[:20]!r} is not an M, G or H code or a "
                               "keyword (Siemens reader)", file=file)
        if s in _NOT_ALLOWABLE:
            raise NCParseError(f"allow: {s} moves the tool or the frame; passing it over "
                               "would misplace the tool", file=file)
        out.add(s)
    return frozenset(out)


def parse_siemens(text: str, *, file: str = "<string>", block_delete: bool = False,
                  allow: Iterable[str] = (), machine: object = None) -> Program:
    """Interpret Sinumerik text.

    Parameters
    ----------
    text : str
        The program.
    file : str
        Name used in error messages and kept in the result.
    block_delete : bool
        Skip blocks that start with ``/``; when False they run.
    allow : iterable of str
        Further codes (``"M110"``, ``"H1"``, ``"G26"``, a keyword such as
        ``"FGROUP"`` without parameters) to pass over without effect; those
        that move the tool or the frame cannot be allowed.
    machine : nc.machines.Machine, optional
        The machine the program runs on: CYCLE800's direct mode (192) takes
        its plane from the machine's kinematics and is refused without it.

    Returns
    -------
    Program
        ``number`` is the header's program name (None without a header);
        ``metadata`` has ``dialect`` and, if present, ``name``, ``messages``,
        ``tool_names``, ``swivel_data``, ``workpiece``.
    """
    allowed = normalise_allow(allow, file)
    lines, newline, blocks, name = split_blocks(text, file)
    if not blocks:
        raise NCParseError("empty program; expected blocks such as G1 X10 F500", file=file)
    st = SState(file, lines, allowed, machine)
    st.metadata["dialect"] = "siemens"
    if name is not None:
        st.metadata["name"] = name
    flow = plan(blocks, file, lines)
    run(st, blocks, flow, block_delete, execute)
    return st.program(file, tuple(lines), newline, name, block_delete)

