"""Read ISO/Fanuc and LinuxCNC style G-code into a :class:`~nc.program.Program`.

The dialect is what CAM systems write for milling: G0/G1/G2/G3 (IJK centre
and R forms, full circles, helical arcs, LinuxCNC's P turns), G17/G18/G19,
G90/G91, G90.1/G91.1, G20/G21, G93/G94/G95, F, S, M3/M4/M5, T and M6, G43 H,
G43.4/G43.5/G49 (tool centre point on/off; under G43.5 the words I J K of a
G0/G1 block are the tool vector), G54...G59 (offsets from a table), comments
in parentheses and after ``;``, block delete ``/``, N numbers, ``%`` and O
program numbers. G40 and G80 (which assert the state the reader assumes;
G80 may share a block with G0...G3; after G80 alone the G0...G3 mode in
effect before the cycle moves again, as on Fanuc, where the cycles are a
modal group of their own), and M0/M1/M2/M30 are understood.

Codes that neither move the tool nor change the frame (coolant M7/M8/M9,
clamps M10/M11, dwell G4, path blending G61/G64, Fanuc look-ahead G05 P,
G05.1 Q, G08 P, ...: :data:`nc.dialect.PASSIVE`) are passed over with
their own parameter words and counted in :attr:`Program.ignored`; with
``strict=True`` they are refused unless the caller lists them in ``allow``.
Codes that move the tool in ways the reader does not model (cutter
compensation, splines, G88...) are refused, and cannot be allowed.

Canned drilling cycles G73, G74, G81-G87, G89 with G98/G99 are expanded into
their moves as LinuxCNC does (:mod:`nc.cycles`, rows listed in
:attr:`Program.drilling`); Fanuc's G68/G69 rotation and G68.2/G53.1 tilted
plane are read into the program frame (:mod:`nc.rotation`).

Frame and reference codes are modelled as LinuxCNC does (:mod:`nc.frames`):
G92/G92.1/G92.2/G92.3, G52, G10 L2/L20, G53, G28/G30 (through the
intermediate point; to the machine's point when ``reference_points`` gives
it, else to a position not known, NaN, until absolute coordinates come
again) and G28.1/G30.1.

Fanuc macro B programs and subprograms in the same file (:mod:`nc.macro_b`)
are run first into the straight-line blocks read here, each with its source
line; LinuxCNC ``#`` parameters without control flow are substituted
(:mod:`nc.macro`).

Anything else is refused with an :class:`~nc.errors.NCParseError` naming the
file, line and column; Siemens and Heidenhain programs with a sentence that
names the dialect.

The execution order inside a block follows LinuxCNC (feed mode, F, S, T, M6,
spindle, plane, units, tool length, work offset, distance mode, motion), so a
block ``G20 X1`` moves to one inch.

This module is the reader's entry; :mod:`nc.gcode_source` turns the text into
straight-line lines (running the control flow), and :mod:`nc.gcode_interp`
interprets them in one flat loop.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence

from .dialect import ALLOWABLE_EXAMPLES, normalise_allow
from .errors import NCParseError
from .frames import reference_table, work_offset_table
from .gcode_interp import Interpreter
from .gcode_source import prepare_source
from .program import Program

__all__ = ["read_program", "parse_program", "ALLOWABLE_EXAMPLES"]


def read_program(path: str | os.PathLike, **options) -> Program:
    """Read a G-code file; see :func:`parse_program` for ``options``.

    Raises
    ------
    NCParseError
        Naming the file, line and column, for anything outside the dialect
        and for bytes that are not text.
    """
    name = os.fspath(path)
    with open(name, "rb") as fh:
        data = fh.read()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        col = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise NCParseError("expected text (UTF-8 or ASCII), found a non-text byte "
                           f"0x{data[exc.start]:02x}", file=name, line=line,
                           column=col) from None
    if text.startswith("\ufeff"):  # a byte-order mark some editors write: not code
        text = text[1:]
    return parse_program(text, file=name, **options)


def parse_program(
    text: str,
    *,
    file: str = "<string>",
    allow: Iterable[str] = (),
    block_delete: bool = False,
    work_offsets: Mapping[str, Sequence[float]] | None = None,
    strict: bool = False,
    reference_points: Mapping[str, Sequence[float]] | None = None,
) -> Program:
    """Interpret G-code text.

    Parameters
    ----------
    text : str
        The program.
    file : str
        Name used in error messages and kept in the result.
    allow : iterable of str
        Codes (``"G64"``, ``"M8"``) that may appear and are passed over, beyond
        those passed over anyway (:data:`nc.dialect.PASSIVE`: coolant, clamps,
        dwell, path blending, look-ahead...). Every code passed over is
        counted in :attr:`Program.ignored`.
    block_delete : bool
        Skip lines that start with ``/`` (the operator's block-delete switch);
        when False they run like any other line.
    work_offsets : mapping, optional
        ``{"G55": (x, y, z)}`` or ``(x, y, z, a, b, c)`` [mm, deg]: the work
        offset table, used by :attr:`Program.end_machine`.
    strict : bool
        Refuse what the reader once refused: codes that do nothing here
        (coolant, G64...) unless listed in ``allow``, and the frame and
        reference codes (G10, G28, G30, G52, G53, G92), G95, and an M99 ending
        the main program (read otherwise as its end: :mod:`nc.macro_b`).
    reference_points : mapping, optional
        ``{"G28": (x, y, z)}`` or ``(x, y, z, a, b, c)`` [mm, deg]: the machine's
        G28 and G30 points in machine coordinates. Where a program goes to a
        point not given here, the axes it sends there are unknown (NaN in
        :attr:`Program.end`, False in :attr:`Program.known`) until absolute
        coordinates give them a value again (see :mod:`nc.frames`).

    Returns
    -------
    Program
    """
    return Interpreter(prepare_source(text, file, block_delete, strict), file,
                       normalise_allow(allow), block_delete, work_offset_table(work_offsets),
                       strict, reference_table(reference_points)).run()
