"""Read Heidenhain TNC conversational (Klartext) programs into a :class:`~nc.program.Program`.

What is read (TNC 640 semantics):

* ``BEGIN PGM name MM|INCH`` ... ``END PGM``, block numbers, ``;`` comments,
  ``*`` structure lines, ``~`` continuation lines, ``/`` block skip,
  ``BLK FORM`` (kept in ``Program.metadata``), ``STOP``.
* ``L`` lines: absolute and incremental (``IX``) coordinates, ``FMAX`` (rapid,
  this block only), ``F`` (modal; in INCH programs 1/10 inch/min), ``FAUTO``
  (the ``TOOL CALL`` feed), ``R0``; ``RL``/``RR``/``R+``/``R-`` radius
  compensation are refused (they move the tool off the programmed path).
* Arcs: ``CC`` (centre/pole; its two axes choose the arc plane), ``C``
  (``DR+`` counter-clockwise), ``CR`` (``R<0``: more than 180 deg), ``CT``
  (tangential), ``LP``/``CP`` polar with ``PR PA IPR IPA``; a third (axial)
  coordinate makes a helix.
* ``TOOL CALL n X|Y|Z S F`` (tool axis sets the working plane), ``TOOL DEF``;
  ``M3 M4 M5 M13 M14`` spindle, ``M8 M9 M7`` coolant, ``M0 M1 M2 M30 M6``,
  ``M126/M127`` (shortest rotary path), ``M140 MB`` (retract along the tool axis).
* ``M128``/``FUNCTION TCPM F TCP AXIS POS`` (tool tip programmed, rotary words
  are axis angles: stored as G43.4 would be), ``M129``/``FUNCTION RESET TCPM``;
  ``LN`` with ``TX TY TZ`` (stored as G43.5 tool vectors).
* Tilted plane: ``PLANE SPATIAL`` / ``PLANE RESET`` and cycle 19; datum shift
  cycle 7. Coordinates are turned into the workpiece frame; blocks under a
  tilt (or a tool axis other than Z) carry the frame's tool axis as a tool
  vector, and arcs under a tilt are stored as chords.
* ``LBL``/``CALL LBL [REP]`` expanded; ``Q``/``QL``/``QR`` assignments and
  ``FN 0``..``FN 5``, parameters in words (``X+Q1``, ``FQ5``).

Everything else ends the read with one :class:`~nc.errors.NCParseError`
(``file:line:col: message``) naming what was found and what is supported.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable

from . import constants as K
from . import heidenhain_blocks as HB
from .errors import NCParseError
from .heidenhain_blocks import TNCBlock, split_blocks
from .heidenhain_state import TNCState
from .program import Program

__all__ = ["read_heidenhain", "parse_heidenhain"]


def read_heidenhain(path: str | os.PathLike, **options) -> Program:
    """Read a Klartext file; see :func:`parse_heidenhain` for ``options``."""
    name = os.fspath(path)
    with open(name, "rb") as fh:
        data = fh.read()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        try:  # TNC files are often Latin-1 (umlauts in comments)
            text = data.decode("latin-1")
        except UnicodeDecodeError:  # pragma: no cover - latin-1 decodes every byte
            raise NCParseError("expected text", file=name) from None
    if "\x00" in text:
        line = text.count("\n", 0, text.index("\x00")) + 1
        raise NCParseError("expected text, found a NUL byte", file=name, line=line)
    return parse_heidenhain(text, file=name, **options)


def parse_heidenhain(text: str, *, file: str = "<string>", block_delete: bool = False,
                     allow: Iterable[str] = (), retract_limit_mm: float | None = None
                     ) -> Program:
    """Interpret Klartext text.

    Parameters
    ----------
    text : str
        The program.
    file : str
        Name used in error messages and kept in the result.
    block_delete : bool
        Skip blocks that start with ``/``; when False they run.
    allow : iterable of str
        Further M functions (``"M110"``) to pass over without effect; those
        that move the tool or the frame (M91, M92, M94, M114, M118, M120,
        M136, M144) cannot be allowed.
    retract_limit_mm : float, optional [mm]
        Where ``M140 MB MAX`` takes the tool: this Z (program frame, tool
        axis Z only). Without it, ``MB MAX`` is refused (the travel limit is
        the machine's, unknown to the reader).

    Returns
    -------
    Program
        ``number`` is the program name; ``metadata`` has ``dialect``,
        ``name``, ``units`` and, if present, ``blk_form``.
    """
    allowed = HB.normalise_allow_m(allow)
    if retract_limit_mm is not None and not math.isfinite(retract_limit_mm):
        raise ValueError(f"retract_limit_mm: expected a finite value, got {retract_limit_mm!r}")
    lines, newline, blocks = split_blocks(text, file)
    return _Runner(file, lines, newline, blocks, block_delete, allowed,
                   retract_limit_mm).run()


class _Runner:
    """Walks the blocks in execution order (labels, calls, repeats)."""

    def __init__(self, file, lines, newline, blocks, block_delete, allowed, retract_limit):
        self.file, self.lines, self.newline, self.blocks = file, lines, newline, blocks
        self.block_delete = block_delete
        self.state = TNCState(file, lines, allowed, retract_limit)

    def err(self, b: TNCBlock, msg: str, col: int | None = None) -> NCParseError:
        return NCParseError(msg, file=self.file, line=b.line, column=col or b.col,
                            text=self.lines[b.line - 1])

    def run(self) -> Program:
        blocks = self.blocks
        if not blocks:
            raise NCParseError("empty program; expected BEGIN PGM name MM|INCH",
                               file=self.file)
        first = blocks[0]
        m = HB.BEGIN.fullmatch(first.stmt)
        if not m:
            raise self.err(first, f"expected 'BEGIN PGM name MM' or '... INCH' as the first "
                           f"block, found {first.stmt[:30]!r}")
        name, unit = m.group(1), m.group(2)
        m_orig = HB.BEGIN.fullmatch(first.orig.upper())
        if m_orig:  # the name as written (upper-case only for matching END PGM)
            name_as_written = first.orig[m_orig.start(1):m_orig.end(1)]
        else:  # pragma: no cover - the upper-case form matched
            name_as_written = name
        last = blocks[-1]
        m_end = HB.END.fullmatch(last.stmt)
        if not m_end:
            raise self.err(last, f"expected 'END PGM {name} {unit}' as the last block, found "
                           f"{last.stmt[:30]!r} (a truncated file?)")
        if m_end.group(1) != name or m_end.group(2) != unit:
            raise self.err(last, f"END PGM {m_end.group(1)} {m_end.group(2)} does not match "
                           f"BEGIN PGM {name} {unit}")
        st = self.state
        st.set_units(unit)
        st.metadata.update(dialect="heidenhain", name=name_as_written, units=unit)

        labels: dict[str, int] = {}
        for i, b in enumerate(blocks):
            if b.stmt.startswith("LBL"):
                lm = HB.LBL.fullmatch(b.stmt)
                if not lm:
                    raise self.err(b, "expected LBL and a number or a quoted name")
                key = lm.group(1)
                if key != "0":
                    if key in labels:
                        raise self.err(b, f"label {key} defined twice (first at line "
                                       f"{blocks[labels[key]].line})")
                    labels[key] = i

        stack: list[int] = []          # return addresses of subprogram calls
        repeats: dict[int, int] = {}   # CALL block index -> repeats left
        executed = 0
        limit = K.TNC_MAX_EXECUTED_BLOCKS
        pc = 1
        n = len(blocks) - 1  # the END PGM block
        while pc < n:
            b = blocks[pc]
            pc += 1
            executed += 1
            if executed > limit:
                raise self.err(b, f"more than {limit:,} blocks executed (TNC_MAX_EXECUTED_"
                               "BLOCKS): a label loop that does not end, or repeats too deep")
            s = b.stmt
            if b.skip and self.block_delete:
                continue
            c0 = s[:1]
            if c0 == "L" and s.startswith("LBL"):
                if s == "LBL 0" or HB.LBL.fullmatch(s).group(1) == "0":
                    if stack:
                        pc = stack.pop()
                continue
            if c0 == "C" and s.startswith("CALL"):
                cm = HB.CALL_LBL.fullmatch(s)
                if not cm:
                    raise self.err(b, f"unsupported call {s[:40]!r}; supported: CALL LBL n "
                                   "[REP m] (CALL PGM and cycles are not read)")
                key, rep = cm.group(1), cm.group(2)
                if key not in labels:
                    raise self.err(b, f"CALL LBL {key}: no LBL {key} in this program")
                target = labels[key] + 1
                if rep is not None:
                    here = pc - 1
                    left = repeats.get(here)
                    if left is None:
                        left = int(rep)
                    if left > 0:
                        repeats[here] = left - 1
                        pc = target
                    else:
                        repeats.pop(here, None)
                    continue
                if len(stack) >= K.TNC_MAX_CALL_DEPTH:
                    raise self.err(b, f"subprogram calls nested deeper than "
                                   f"{K.TNC_MAX_CALL_DEPTH} (TNC_MAX_CALL_DEPTH): recursion?")
                stack.append(pc)
                pc = target
                continue
            if st.execute(b):
                break  # M2 / M30: the program ends here
        else:
            if stack:
                b = blocks[n]
                raise self.err(b, "END PGM reached inside a subprogram: expected LBL 0 "
                               "at its end")
        return st.program(self.file, tuple(self.lines), self.newline, name_as_written,
                          self.block_delete)

