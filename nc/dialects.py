"""Which NC dialect a program speaks, and reading it with the matching reader.

``heidenhain``: the first block is ``BEGIN PGM name MM|INCH`` (after an
optional block number); ``siemens``: the first line is a ``%_N_name_MPF``
(or ``_SPF``) header or a ``;$PATH=`` line, or the first blocks use what only a
Sinumerik reads (``CYCLE800``, ``CYCLE832``, ``TRAORI``, ``TRAFOOF``, ``SUPA``,
``G641``-``G645``, ``DEF REAL|INT``, ``MSG("``, ``CR=``, ``A3=``, ``X=AC(``),
parenthesised comments left out; anything else is ``gcode`` (ISO/Fanuc, LinuxCNC).
"""

from __future__ import annotations

import os
import re

from .errors import NCParseError
from .program import Program

__all__ = ["DIALECT_NAMES", "detect_dialect", "read_any"]

DIALECT_NAMES = ("gcode", "heidenhain", "siemens")
_BEGIN = re.compile(r"\s*(?:\d+\s+)?BEGIN\s+PGM\s+\S+\s+(?:MM|INCH)\b", re.IGNORECASE)
_SIEMENS_HEAD = re.compile(r"\s*(?:%_N_\w+_(?:MPF|SPF)\b|;\s*\$PATH\s*=)", re.IGNORECASE)
_SIEMENS_WORDS = re.compile(r"(?<![A-Z0-9_])(?:(?:CYCLE800|CYCLE832|TRAORI|TRAFOOF|SUPA"
                            r"|G64[1-5]|DEF\s+(?:REAL|INT))(?![A-Z0-9_])|MSG\s*\(\s*\""
                            r"|CR\s*=|[ABC]3\s*=|[XYZIJK]\s*=\s*[AI]C\s*\()", re.IGNORECASE)
_PAREN_COMMENT = re.compile(r"\([^()\n\"]*\)")
#: Bytes of the file looked at for detection (the first blocks) [-].
_HEAD_BYTES = 4096


def detect_dialect(text: str) -> str:
    """``"heidenhain"``, ``"siemens"`` or ``"gcode"`` from the first blocks (see the
    module's docstring)."""
    head = text[:_HEAD_BYTES]
    for line in head.splitlines():
        if line.strip():
            if _BEGIN.match(line):
                return "heidenhain"
            if _SIEMENS_HEAD.match(line):
                return "siemens"
            break
    if _SIEMENS_WORDS.search(_PAREN_COMMENT.sub("", head)):
        return "siemens"
    return "gcode"


def read_any(path: str | os.PathLike, dialect: str | None = None, *, machine: object = None,
             **options) -> Program:
    """Read an NC program with the reader of its dialect.

    Parameters
    ----------
    path : path-like
    dialect : str, optional
        ``"gcode"``, ``"heidenhain"`` or ``"siemens"`` to force a reader; None
        detects it from the first blocks (:func:`detect_dialect`).
    machine : nc.machines.Machine, optional
        The machine the program runs on; used by the Siemens reader
        (CYCLE800's direct mode), not needed by the others.
    **options
        Passed to :func:`nc.gcode.read_program`,
        :func:`nc.heidenhain.read_heidenhain` or :func:`nc.siemens.read_siemens`.
    """
    name = os.fspath(path)
    if dialect is None:
        with open(name, "rb") as fh:
            head = fh.read(_HEAD_BYTES).decode("latin-1")
        dialect = detect_dialect(head)
    if dialect == "heidenhain":
        from .heidenhain import read_heidenhain

        return read_heidenhain(name, **options)
    if dialect == "siemens":
        from .siemens import read_siemens

        return read_siemens(name, machine=machine, **options)
    if dialect == "gcode":
        from .gcode import read_program

        return read_program(name, **options)
    raise NCParseError(f"unknown dialect {dialect!r}; expected one of "
                       f"{', '.join(DIALECT_NAMES)}", file=name)
