"""Reading a scenario's TOML tables: nc's reader with the scenario's error and program.

:class:`TableReader` is :class:`nc.tables.TableReader` (typed values, every error
naming file and dotted key) raising :class:`ScenarioError` (an
:class:`nc.errors.TableError`), with the scenario's program read under
``program.gcode``. :mod:`errpred.scenario` reads its sections with it, and so does
``orient``'s planning scenario for its own.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nc.errors import TableError
from nc.tables import TableReader as BaseTableReader

from . import constants as K

__all__ = ["ScenarioError", "TableReader", "check_program_lines"]


class ScenarioError(TableError):
    """A scenario file that cannot be used: names the file and the dotted key.

    Attributes
    ----------
    file : str
        The scenario file as given.
    key : str or None
        Dotted key (``tool.diameter_mm``), None for the file as a whole.
    """


class TableReader(BaseTableReader):
    """:class:`nc.tables.TableReader` raising :class:`ScenarioError`, and the scenario's
    program.

    Public so that packages whose scenarios extend this format (``orient``)
    read their own sections with the same checks and messages.
    """

    error = ScenarioError

    def read_program(self, gcode: Path, allow: tuple[str, ...], dialect: str = "auto"):
        """The program (``nc.read_any`` in ``dialect``, "auto" to detect it), refused
        under ``program.gcode`` (with the program's file, line and column) when it
        cannot be read or has no motion block."""
        from nc import read_any
        from nc.cycles import refuse_drilling
        from nc.errors import NCParseError

        try:
            program = read_any(gcode, None if dialect == "auto" else dialect, allow=allow)
            refuse_drilling(program, "the error prediction")
        except NCParseError as exc:  # one line: where, and what was expected
            where = ":".join(str(x) for x in (exc.file, exc.line, exc.column) if x is not None)
            raise self.fail("program.gcode", f"{where}: {exc.message}") from None
        if len(program) == 0:
            raise self.fail("program.gcode", f"{gcode}: no motion block (G0-G3); expected a "
                                             f"program that moves the tool")
        return program


def _limit(name: str) -> dict:
    """``maximum`` and ``limit`` for :meth:`TableReader.number`: the constant ``name`` of
    :mod:`errpred.constants`."""
    return {"maximum": getattr(K, name), "limit": f"errpred.constants.{name}"}


def check_program_lines(program, lines: tuple[int, int] | None, file: str,
                        key: str = "program.lines") -> None:
    """Refuse a line range (``[program] lines`` or ``--lines``) that selects no motion
    block of ``program``; ``file`` and ``key`` name where the range was given."""
    if lines is None:
        return
    lo, hi = lines
    if np.any((program.line >= lo) & (program.line <= hi)):
        return
    raise ScenarioError(file, key, f"lines {lo}-{hi} hold no motion block of {program.file} "
                                   f"({len(program.lines)} lines; motion blocks on lines "
                                   f"{int(program.line.min())}-{int(program.line.max())})")
