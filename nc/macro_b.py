"""Fanuc Custom Macro B and subprograms of one file, expanded into straight-line blocks.

For Fanuc, Haas, Makino and Okuma (ISO) programs with control flow or calls:
the program is run here, block by block, as the control runs it, and the
blocks that move the tool come out as plain ISO lines that
:mod:`nc.gcode` reads, each keeping its source line number (errors name the
source file:line:col).

- The file holds programs ``O1234`` (or ``:1234``) up to the next one or the
  closing ``%``. The main program is the text before the first ``O`` (after
  ``%``) if it has blocks, else the first ``O`` program; the others are
  subprograms. M30 or M02 ends the run (also inside a subprogram); the main
  program's end without M30 ends it too. Where that end is the next ``O``
  program's line (no M30, M02 or ``%`` between them), a control that runs on
  through the file (LinuxCNC, Mach3) would execute that program's blocks as
  well: the line is recorded (:attr:`nc.program.Program.main_open_end_line`,
  shown by ``python -m nc parse``) and ``strict=True`` refuses it.
- ``#`` variables, ``#i=expr``, arithmetic, functions and comparisons
  (:mod:`nc.expressions`, ``FANUC`` grammar; variables: :mod:`nc.macro_b_blocks`).
  A word whose value is a vacant variable (``X#1``, #1 vacant) is left out,
  as the control does; values go into words at full precision (a control
  rounds them to its least input increment, 0.001 mm on IS-B).
- ``IF [cond] GOTO n``, ``IF [cond] THEN #i=...``, ``GOTO n`` (the control's
  search: forward from the block, then from the program's start),
  ``WHILE [cond] DOm ... ENDm`` (m = 1...3, at most 3 nested; ``DOm`` alone
  loops until a GOTO leaves).
- ``M98 P.. L..`` and ``M98 Pxxxxnnnn`` (count, program) call a program of
  the file; Haas' ``M97 P..`` calls the N number of the same program;
  ``M99`` returns after the call (``M99 Pn``: to the block Nn of the caller);
  a plain ``M99`` in the main program (no call active) ends the run there,
  recorded as :attr:`nc.program.Program.main_m99_line` and shown by the
  summary: Centroid's controls end the job there (its M-series operator's
  manual: M99 met in the main job file is read as the end of the job), which
  is what CAM posts that end with it (FreeCAD's centroid post) mean, and
  Milltronics lists M99 among its program end codes; Fanuc-type controls
  start the program again instead (CNC Concepts' note on M99: rewind and
  continue, for bar feeders and pallet changers), so the moves read are one
  pass of it, never a loop. With
  ``strict=True`` it is refused, and ``M99 Pn`` in the main program (a jump
  to Nn) always is;
  ``G65 P.. L..`` calls a macro with the arguments of argument
  specification I (A->#1 ... Z->#26) in a new set of locals. Words in an
  M98/M97/M99 block other than P and L are executed before the call.

Refused, each in one line naming it: G66/G66.1 modal macro calls, system
variables (#1000 and up, except #3000 alarms and #3006 stops), a call to a
program not in the file, M99 Pn in the main program, GOTO to a missing N,
an unclosed WHILE and an END without its DO, a vacant condition, and a run
of more than :data:`nc.constants.MACRO_B_MAX_EXECUTED_BLOCKS` blocks or
:data:`nc.constants.MACRO_B_MAX_CALL_DEPTH` nested calls.
"""

from __future__ import annotations

import bisect
import re
from dataclasses import dataclass

from . import constants as K
from .errors import NCParseError
from .expressions import ExprError
from .lexer import blank_comments
from .macro_b_blocks import (
    MacroError,
    Statement,
    Variables,
    comment_text,
    compile_block,
    number_text,
)
from .owords import has_owords

__all__ = ["needs_macro_b", "expand_macro_b"]

# detection runs on every ISO program read, so it is kept to fast scans: a
# keyword at a line's start (after N), a call word (checked not to follow a letter)
_KEYWORDS = re.compile(r"\n[ \t/]*(?:[Nn][ \t]*\d+[ \t]*)?(?:[Ii][Ff][ \t]*\[|"
                       r"[Ww][Hh][Ii][Ll][Ee][ \t]*\[|[Gg][Oo][Tt][Oo][ \t]*[\d#\[]|"
                       r"[Dd][Oo][ \t]*\d|[Ee][Nn][Dd][ \t]*\d)")
_HINTS = ("[", "GOTO", "goto", "END", "end")  # (IF/WHILE need '[', a DO loop its END)
# (one pattern per letter and case: a pattern starting with a literal is searched
# ~10x faster than one starting with a class or an alternation)
_CALLS = tuple(re.compile(letter + r"[ \t]*0*" + number + r"(?![\d.])")
               for letter, number in (("M", "9[789]"), ("m", "9[789]"),
                                      ("G", r"6(?:5|6(?:\.1)?)"), ("g", r"6(?:5|6(?:\.1)?)")))
_O_LINE = re.compile(r"(?m)^[ \t]*[Oo:][ \t]*\d+[ \t]*(?:\([^()\n]*\))?[ \t]*\r?$")
_PROGRAM = re.compile(r"\s*[O:]\s*(\d+)\s*$")
_SPECIAL = re.compile(r"[#\[]|(?<![A-Z])(?:M\s*0*9[789]|G\s*0*6[567])(?![\d.])|"
                      r"^\s*(?:N\s*\d+\s*)?(?:IF|WHILE|GOTO|DO|END|THEN|POPEN|PCLOS|DPRNT|BPRNT)"
                      r"(?![A-Z])")
_END = re.compile(r"(?<![A-Z])M\s*0*(?:2|30)(?![\d.])")
_LOOP = re.compile(r"\s*(?:N\s*\d+\s*)?(?:WHILE|DO|END)(?![A-Z])")
_LABEL = re.compile(r"\s*N\s*(\d+)")
_ASSIGN = re.compile(r"\s*(?:N\s*\d+\s*)?#")
_PREFIX = "Fanuc macro B: "


def needs_macro_b(text: str) -> bool:
    """True for an ISO program with Fanuc control flow, M98/M97/M99 or G65/G66,
    or with ``#`` variables or ``[ ]`` and an ``O1234`` program number line;
    False for a program with LinuxCNC's O-words or ``#<name>`` parameters."""
    if _fanuc_signs(text):
        return "#<" not in text and not has_owords(text)
    return False


def _fanuc_signs(text: str) -> bool:
    for pattern in _CALLS:
        for m in pattern.finditer(text):
            k = m.start()
            if k == 0 or not text[k - 1].isalpha():
                return True
    # IF and WHILE need '['; the others are looked for only where their letters are
    if any(h in text for h in _HINTS) and _KEYWORDS.search("\n" + text):
        return True
    return ("#" in text or "[" in text) and _O_LINE.search(text) is not None


@dataclass
class _Program:
    number: int | None
    head: int            # index of the O line (-1 for the text before the first O)
    start: int           # first block
    end: int             # one past the last block
    labels: dict | None = None
    loops: dict | None = None
    blocks: bool = False  # the text before the first O: has blocks, not just assignments


def _blank(raw: str) -> str:
    if "(" in raw or ";" in raw:
        return blank_comments(raw)
    s = raw.upper()
    body = s.lstrip()
    if body.startswith("/"):
        k = len(s) - len(body)
        s = s[:k] + " " + s[k + 1:]
    return s


class _Run:
    """The state of one expansion."""

    def __init__(self, lines: list[str], file: str, block_delete: bool) -> None:
        self.lines = lines
        self.file = file
        self.block_delete = block_delete
        self.cache: dict[int, Statement] = {}
        self.programs: dict[int, _Program] = {}
        self.main: _Program | None = None
        #: the program run after the main one (when the text before the first O
        #: holds only assignments)
        self.then: _Program | None = None
        self.prelude = 0
        self._split()

    # -- the programs of the file ------------------------------------------
    def _split(self) -> None:
        cur: _Program | None = None
        header: _Program | None = None
        content = False
        first: _Program | None = None
        for k, raw in enumerate(self.lines):
            s = raw.strip()
            if not s:
                continue
            if s[0] == "%":
                if content:  # a closing '%' ends the program before it (the reader
                    for prog in (cur, header):  # stops there); later O programs
                        if prog is not None:    # of the file may still be called
                            prog.end = min(prog.end, k)
                    cur = None
                continue
            if s[0] == "$" and not content:
                content = True  # Okuma's header line
                continue
            b = _blank(raw)
            m = _PROGRAM.match(b)
            if m is not None:
                if cur is not None:
                    cur.end = k
                if header is not None and header.end > k:
                    header.end = k
                number = int(m.group(1))
                if number in self.programs:
                    raise NCParseError(f"{_PREFIX}program O{number} appears twice in the file;"
                                       " expected one program per number", file=self.file,
                                       line=k + 1, column=1, text=raw)
                cur = _Program(number, k, k + 1, len(self.lines))
                self.programs[number] = cur
                first = first or cur
                content = True
            elif b.strip():
                if header is None and first is None:
                    header = _Program(None, -1, k, len(self.lines))
                # assignments alone before the tape start are not blocks: the
                # program still starts at '%' or at its O number
                if _ASSIGN.match(b) is None:
                    content = True
                    if header is not None and first is None:
                        header.blocks = True
        if header is not None and not header.blocks and first is not None:
            self.then = first  # assignments only: they run, then the first O program
        self.main = header or first
        if self.main is not None:
            self.prelude = self.main.start

    def error(self, pc: int, message: str, offset: int | None = None) -> NCParseError:
        raw = self.lines[pc]
        col = len(raw) - len(raw.lstrip()) + 1 if offset is None else offset + 1
        return NCParseError(_PREFIX + message, file=self.file, line=pc + 1, column=col,
                            text=raw)

    def statement(self, pc: int) -> Statement:
        st = self.cache.get(pc)
        if st is None:
            raw = self.lines[pc]
            if self.block_delete and raw.lstrip().startswith("/"):
                st = Statement("none")
            else:
                b = _blank(raw)
                if _SPECIAL.search(b) is None:
                    st = Statement("pass" if b.strip() else "none",
                                   ends=_END.search(b) is not None)
                else:
                    try:
                        st = compile_block(b)
                    except RecursionError:
                        raise self.error(pc, "brackets nested too deeply; expected at most "
                                         "a few hundred levels") from None
                    a = st.then if st.kind == "if" else st
                    if a is not None and any(x[0] == 3000 for x in a.assigns):
                        a.text = comment_text(raw)
            self.cache[pc] = st
        return st

    def scan_loops(self, prog: _Program) -> dict:
        """DO/END partners of ``prog``: pc of WHILE/DO -> pc of END, and back."""
        if prog.loops is not None:
            return prog.loops
        pairs: dict[int, int] = {}
        stack: list[tuple[int, int]] = []
        for pc in range(prog.start, prog.end):
            b = _blank(self.lines[pc])
            if _LOOP.match(b) is None:
                continue
            try:
                st = self.statement(pc)
            except ExprError as exc:
                raise self.error(pc, str(exc), exc.offset) from None
            if st.kind in ("while", "do"):
                if any(m == st.loop for m, _ in stack):
                    raise self.error(pc, f"DO{st.loop} inside the range of DO{st.loop}; "
                                     "expected different numbers for nested loops", st.column)
                if len(stack) == 3:
                    raise self.error(pc, "loops nested more than 3 deep; expected at most "
                                     "3 levels of WHILE ... DO", st.column)
                stack.append((st.loop, pc))
            elif st.kind == "end":
                if not stack or stack[-1][0] != st.loop:
                    inner = f" (DO{stack[-1][0]} is open)" if stack else ""
                    raise self.error(pc, f"END{st.loop} without its DO{st.loop}{inner}; "
                                     "expected WHILE [condition] DOm ... ENDm, ranges "
                                     "not crossing", st.column)
                _, start = stack.pop()
                pairs[start] = pc
                pairs[pc] = start
        if stack:
            m, pc = stack[-1]
            raise self.error(pc, f"DO{m} has no END{m} in {_name(prog)}; expected "
                             f"END{m} to close the loop", self.statement(pc).column)
        prog.loops = pairs
        return pairs

    def label(self, prog: _Program, n: int, after: int, pc: int, what: str, off: int) -> int:
        """pc of block N``n`` of ``prog``: the first after ``after``, else the first."""
        if prog.labels is None:
            labels: dict[int, list[int]] = {}
            for k in range(prog.start, prog.end):
                m = _LABEL.match(_blank(self.lines[k]))
                if m is not None:
                    labels.setdefault(int(m.group(1)), []).append(k)
            prog.labels = labels
        found = prog.labels.get(n)
        if not found:
            raise self.error(pc, f"{what}: no block N{n} in {_name(prog)}; expected an N "
                             "number of the same program", off)
        i = bisect.bisect_right(found, after)
        return found[i] if i < len(found) else found[0]


def _name(prog: _Program) -> str:
    return "the main program" if prog.number is None else f"program O{prog.number}"


def _whole(v: float | None, what: str, off: int, low: int = 0) -> int:
    if v is None:
        raise MacroError(f"{what} is vacant; expected a whole number", off)
    if v != int(v) or v < low or v > 99_999_999:
        raise MacroError(f"{what} is {v:g}; expected a whole number {low}-99999999", off)
    return int(v)


def _val(v, store: Variables) -> float | None:
    """A word's value: its number text, or its expression's value."""
    return float(v) if isinstance(v, str) else v(store)


def _words(words: list, store: Variables) -> str:
    out = []
    for letter, v, _ in words:
        if not isinstance(v, str):
            v = v(store)
            if v is None:  # a vacant variable: the address is left out
                continue
            v = number_text(v)
        out.append(letter + v)
    return " ".join(out)


def expand_macro_b(lines: list[str], file: str, block_delete: bool = False,
                   max_blocks: int | None = None, strict: bool = False
                   ) -> tuple[list[str], list[int], set[int], int, int]:
    """Run the macro program ``lines``: the blocks that reach the reader.

    Parameters
    ----------
    lines : list of str
        The file's lines (without line ends).
    file : str
        Name for error messages.
    block_delete : bool
        Skip blocks starting with ``/`` (else they run).
    max_blocks : int, optional [blocks]
        Most blocks executed; :data:`nc.constants.MACRO_B_MAX_EXECUTED_BLOCKS`
        when None.
    strict : bool
        Refuse a plain M99 in the main program instead of reading it as the
        program's end, and a main program that runs into the next ``O``
        program's line without M30 or M02 (see the module's docstring).

    Returns
    -------
    (out, numbers, rewritten, main_m99, open_end)
        The produced lines, the 1-based source line of each, the source
        lines whose produced text is not the source line itself, the
        1-based line of the M99 that ended the main program (0 when the
        program ended otherwise), and the 1-based line of the ``O`` program
        the main program's text ran into without M30 or M02 (0 if none).

    Raises
    ------
    NCParseError
        One line naming file, line, column and what was expected.
    """
    run = _Run(lines, file, block_delete)
    main = run.main
    if main is None:
        return list(lines), list(range(1, len(lines) + 1)), set(), 0
    limit = K.MACRO_B_MAX_EXECUTED_BLOCKS if max_blocks is None else max_blocks
    out = lines[:run.prelude]
    numbers = list(range(1, run.prelude + 1))
    rewritten: set[int] = set()
    store = Variables()
    stack: list[tuple] = []
    prog, pc = main, main.start
    executed = 0
    main_m99 = 0
    open_end = 0
    try:
        while True:
            if pc >= prog.end:
                if not stack and prog is main and run.then is not None:
                    prog = run.then  # after the assignments before the first O
                    out.append(lines[prog.head])
                    numbers.append(prog.head + 1)
                    pc = prog.start
                    continue
                if not stack:
                    nxt = next((p for p in run.programs.values() if p.head == prog.end), None)
                    if prog is main and nxt is not None:  # runs into the next O program
                        if strict:
                            raise run.error(prog.end, f"the main program ends where program "
                                            f"O{nxt.number} begins, without M30 or M02 (a "
                                            "control that runs on through the file would "
                                            f"execute O{nxt.number}; strict reading refuses "
                                            "it); expected M30 or M02 before it", 0)
                        open_end = prog.end + 1
                    break
                raise run.error(prog.head, f"{_name(prog)} ends at line {prog.end} without "
                                "M99; expected M99 to return to the caller")
            executed += 1
            if executed > limit:
                raise run.error(pc, f"more than {limit:,} blocks executed (a loop that does "
                                "not end?); expected a program that reaches M30 or its end")
            st = run.statement(pc)
            kind = st.kind
            if kind == "pass":
                out.append(lines[pc])
                numbers.append(pc + 1)
                if st.ends:
                    break
                pc += 1
            elif kind == "none":
                pc += 1
            elif kind == "words":
                text = _words(st.words, store)
                if text:
                    out.append(text)
                    numbers.append(pc + 1)
                    rewritten.add(pc + 1)
                if st.ends:
                    break
                pc += 1
            elif kind == "assign":
                _assign(run, pc, st, store)
                pc += 1
            elif kind == "if":
                cond = st.cond(store)
                if cond is None:
                    raise MacroError("the IF condition is vacant; expected a comparison "
                                     "[a EQ|NE|GT|GE|LT|LE b]", st.column)
                if cond == 0:
                    pc += 1
                elif st.then.kind == "goto":
                    n = _whole(st.then.target(store), "GOTO's N number", st.then.column)
                    pc = run.label(prog, n, pc, pc, f"GOTO {n}", st.then.column)
                else:
                    _assign(run, pc, st.then, store)
                    pc += 1
            elif kind == "goto":
                n = _whole(st.target(store), "GOTO's N number", st.column)
                pc = run.label(prog, n, pc, pc, f"GOTO {n}", st.column)
            elif kind == "while":
                loops = run.scan_loops(prog)
                cond = st.cond(store)
                if cond is None:
                    raise MacroError("the WHILE condition is vacant; expected a comparison "
                                     "[a EQ|NE|GT|GE|LT|LE b]", st.column)
                pc = pc + 1 if cond != 0 else loops[pc] + 1
            elif kind == "do":
                run.scan_loops(prog)
                pc += 1
            elif kind == "end":
                pc = run.scan_loops(prog)[pc]
            elif kind == "m99":
                if st.words:
                    _emit(st, store, pc, out, numbers, rewritten)
                if not stack:  # M99 in the main program: one pass, then the end
                    if st.target is not None:
                        raise MacroError("M99 P in the main program (a jump to a block N "
                                         "that runs the program again); expected M30 or "
                                         "M02, or a plain M99 at its end", st.column)
                    if strict:
                        raise MacroError("M99 in the main program (a Fanuc control runs "
                                         "the program again from its start; strict reading "
                                         "refuses it); expected M30 or M02", st.column)
                    main_m99 = pc + 1
                    break
                back = None if st.target is None else _whole(_val(st.target, store), "M99's P",
                                                             st.column)
                frame = stack[-1]
                frame[2] -= 1
                if frame[2] > 0:  # repeat the call
                    pc = frame[4]
                    if frame[5] is not None:
                        store.local = list(frame[5])
                    continue
                stack.pop()
                prog, ret, _, saved, _, _ = frame
                store.local = saved
                pc = ret if back is None else run.label(prog, back, ret - 1, pc,
                                                        f"M99 P{back}", st.column)
            else:  # calls: m98, m97, g65
                if st.words:
                    _emit(st, store, pc, out, numbers, rewritten)
                if st.ends:
                    break
                prog, pc = _call(run, st, store, stack, prog, pc)
    except ExprError as exc:
        raise run.error(pc, str(exc), exc.offset) from None
    return out, numbers, rewritten, main_m99, open_end


def _emit(st: Statement, store: Variables, pc: int, out: list, numbers: list,
          rewritten: set) -> None:
    text = _words(st.words, store)
    if text:
        out.append(text)
        numbers.append(pc + 1)
        rewritten.add(pc + 1)


def _assign(run: _Run, pc: int, st: Statement, store: Variables) -> None:
    for key, node, off in st.assigns:
        if not isinstance(key, int):
            key = _whole(key(store), "the variable number", off)
        value = node(store)
        if key == 3000:
            code = "" if value is None else f" {number_text(value)}"
            raise run.error(pc, f"the program raises alarm{code} (#3000)"
                            + (f": {st.text}" if st.text else ""), off)
        if key == 3006:  # a stop with a message, like M0: nothing moves
            continue
        store.write(key, value, off)


def _call(run: _Run, st: Statement, store: Variables, stack: list, prog: _Program,
          pc: int) -> tuple[_Program, int]:
    """Enter the subprogram or macro of the call ``st`` at ``pc``."""
    if len(stack) >= K.MACRO_B_MAX_CALL_DEPTH:
        raise MacroError(f"calls nested more than {K.MACRO_B_MAX_CALL_DEPTH} deep (a call "
                         "that recurses without end?); expected fewer nested M98/G65 calls",
                         st.column)
    name = st.kind.upper()
    p = _whole(_val(st.target, store), f"{name}'s P", st.column)
    count = None if st.count is None else _whole(_val(st.count, store), f"{name}'s L",
                                                 st.column)
    if st.kind == "m97":
        target = prog
        start = run.label(prog, p, target.start - 1, pc, f"M97 P{p}", st.column)
    else:
        if p not in run.programs and count is None and p > 9999:
            count, p = divmod(p, 10000)  # Pxxxxnnnn: count, then program number
        target = run.programs.get(p)
        if target is None:
            raise MacroError(f"{name} P{p}: no program O{p} in this file; expected a program "
                             "of the same file (calls to other files are not supported)",
                             st.column)
        start = target.start
    count = 1 if count is None else count
    if count == 0:
        return prog, pc + 1
    init = None
    saved = store.local
    if st.kind == "g65":
        local: list = [None] * 34
        for number, v, off in st.args:
            local[number] = _val(v, store)
        init = tuple(local)
        store.local = local
    stack.append([prog, pc + 1, count, saved, start, init])
    return target, start
