"""A G-code program's text into the straight-line lines the interpreter reads.

The file's lines are split as controls count them; a program with control
flow is run first, each produced line keeping the source line it comes from
(errors and :attr:`nc.program.Program.line` name the source file:line:col):
LinuxCNC O-words (:mod:`nc.owords`), Fanuc macro B and subprograms
(:mod:`nc.macro_b`), and ``#`` parameters and ``[ ]`` expressions without
control flow (:mod:`nc.macro`, line for line). :class:`Source` holds the
result for :class:`nc.gcode_interp.Interpreter`.
"""

from __future__ import annotations

from dataclasses import dataclass

from .macro import expand_parameters, needs_expansion
from .macro_b import expand_macro_b, needs_macro_b
from .owords import expand_owords, has_owords
from .program import split_lines

__all__ = ["Source", "prepare_source"]


@dataclass(slots=True)
class Source:
    """A program's text as lines, and the straight-line lines the interpreter reads.

    Attributes
    ----------
    lines : list of str
        The file's lines, without line ends.
    newline : str
        The file's line end (``"\\n"`` or ``"\\r\\n"``).
    source : list of str
        The lines to read: ``lines`` itself, or what the control flow produced.
    source_lines : list of int or None
        The 1-based line of ``lines`` each line of ``source`` comes from, when
        they differ (O-words, macro B); None when ``source`` is line for line.
    rewritten : set of int
        Lines whose produced text is not the line itself.
    main_m99_line : int
        Line of the M99 that ended the main program (:mod:`nc.macro_b`), 0 if none.
    main_open_end_line : int
        Line of the ``O`` program the main program's text ran into without M30 or
        M02 (:mod:`nc.macro_b`), 0 if none.
    """

    lines: list[str]
    newline: str
    source: list[str]
    source_lines: list[int] | None = None
    rewritten: set[int] | None = None
    main_m99_line: int = 0
    main_open_end_line: int = 0


def prepare_source(text: str, file: str, block_delete: bool = False,
                   strict: bool = False) -> Source:
    """The program's lines, and its control flow run into straight-line lines.

    Lines are split on ``"\\n"`` only, as controls count them (``str.splitlines``
    would also split on form feeds and shift line numbers). LinuxCNC O-word
    programs run through :mod:`nc.owords`, Fanuc macro B and subprograms
    through :mod:`nc.macro_b`, ``#`` parameters and ``[ ]`` expressions without
    control flow are substituted by :mod:`nc.macro`; other text is read as it is.

    Parameters
    ----------
    text : str
        The program.
    file : str
        Name for error messages.
    block_delete : bool
        Skip blocks starting with ``/`` while running macro B.
    strict : bool
        Passed to :func:`nc.macro_b.expand_macro_b` (M99 ending the main program, a
        main program running into the next ``O`` program).

    Raises
    ------
    NCParseError
        From the control flow, naming file, line and column.
    """
    lines, newline = split_lines(text)
    if has_owords(text):  # LinuxCNC O-word control flow: run first (nc.owords)
        source, numbers = expand_owords(lines, file)
        return Source(lines, newline, source, numbers,
                      {n for n in set(numbers) if "#" in lines[n - 1] or "[" in lines[n - 1]})
    if needs_macro_b(text):  # Fanuc macro B, subprograms: run first (nc.macro_b)
        source, numbers, rewritten, m99, open_end = expand_macro_b(
            lines, file, block_delete, strict=strict)
        return Source(lines, newline, source, numbers, rewritten, m99, open_end)
    if needs_expansion(text):  # '#' parameters and '[ ]' without control flow
        return Source(lines, newline, expand_parameters(lines, file))
    return Source(lines, newline, lines)
