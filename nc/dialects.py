"""Which NC dialect a program speaks, and reading it with the matching reader.

``heidenhain``: the first block is ``BEGIN PGM name MM|INCH`` (after an
optional block number); anything else is ``gcode`` (ISO/Fanuc, LinuxCNC).
"""

from __future__ import annotations

import os
import re

from .errors import NCParseError
from .program import Program

__all__ = ["DIALECT_NAMES", "detect_dialect", "read_any"]

DIALECT_NAMES = ("gcode", "heidenhain")
_BEGIN = re.compile(r"\s*(?:\d+\s+)?BEGIN\s+PGM\s+\S+\s+(?:MM|INCH)\b", re.IGNORECASE)
#: Bytes of the file looked at for detection (the first blocks) [-].
_HEAD_BYTES = 4096


def detect_dialect(text: str) -> str:
    """``"heidenhain"`` when the first non-empty line is ``[n] BEGIN PGM name MM|INCH``."""
    for line in text[:_HEAD_BYTES].splitlines():
        if line.strip():
            return "heidenhain" if _BEGIN.match(line) else "gcode"
    return "gcode"


def read_any(path: str | os.PathLike, dialect: str | None = None, **options) -> Program:
    """Read an NC program with the reader of its dialect.

    Parameters
    ----------
    path : path-like
    dialect : str, optional
        ``"gcode"`` or ``"heidenhain"`` to force a reader; None detects it
        from the first block (:func:`detect_dialect`).
    **options
        Passed to :func:`nc.gcode.read_program` or
        :func:`nc.heidenhain.read_heidenhain`.
    """
    name = os.fspath(path)
    if dialect is None:
        with open(name, "rb") as fh:
            head = fh.read(_HEAD_BYTES).decode("latin-1")
        dialect = detect_dialect(head)
    if dialect == "heidenhain":
        from .heidenhain import read_heidenhain

        return read_heidenhain(name, **options)
    if dialect == "gcode":
        from .gcode import read_program

        return read_program(name, **options)
    raise NCParseError(f"unknown dialect {dialect!r}; expected one of "
                       f"{', '.join(DIALECT_NAMES)}", file=name)
