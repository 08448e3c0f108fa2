"""Control flow of Sinumerik programs: jumps, structured blocks and section repeats.

Read as the 840D's Job Planning manual defines them, every control statement
its block's only statement (after an ``N`` number and a label):

* jumps ``GOTOF`` (search forward), ``GOTOB`` (backward), ``GOTO`` (forward,
  then backward), ``GOTOC`` (as ``GOTO``, but a target not found is no error:
  the next block runs), to a label (``MARK1:``) or a block number (``N120``),
  alone or after ``IF condition``; a jump into a structured block (from
  outside its IF/ELSE branch or loop) is refused, as the control does;
* ``IF cond`` / ``ELSE`` / ``ENDIF``, ``WHILE cond`` / ``ENDWHILE``, ``FOR var
  = a TO b`` / ``ENDFOR`` (``var`` an R parameter or a DEF variable, counted up
  by 1 while ``var <= b``; ``b`` evaluated once, on entry; not run at all when
  ``a > b``), ``LOOP`` / ``ENDLOOP`` (left only by a jump or M30), ``REPEAT`` /
  ``UNTIL cond`` (the body runs at least once); matched before the program runs,
  so an unclosed or stray one is refused before any block runs;
* section repeats ``REPEATB label P=n`` (the one block with that label, searched
  backward, then forward), ``REPEAT label P=n`` (from the label, searched backward,
  to the block before the REPEAT or to an ``ENDLABEL:`` block between them; a
  label found forward runs to the next ``ENDLABEL:``), ``REPEAT start end P=n``
  (from ``start`` to the block labelled ``end``), ``P`` 1 when not given; then
  the block after the REPEAT runs. A repeated section must hold whole
  structured blocks, and no jump may leave it while it repeats.

Bounds: at most ``SIEMENS_MAX_EXECUTED_BLOCKS`` blocks run in one read, at most
``SIEMENS_MAX_LOOP_PASSES`` passes of one loop (counted from its last entry; for a
jump back, the times in a row it is taken: a conditional one not taken ends its loop)
and ``SIEMENS_MAX_REPEAT_DEPTH`` nested section repeats; past a bound the read
ends with one :class:`~nc.errors.NCParseError`. ``CASE`` is refused by name.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import NamedTuple

from . import constants as K
from .errors import NCParseError
from .siemens_blocks import SBlock
from .siemens_expr import ExprError, condition, evaluate

__all__ = ["Flow", "plan", "run", "CONTROL_KEYWORDS"]

CONTROL_KEYWORDS = ("IF", "ELSE", "ENDIF", "WHILE", "ENDWHILE", "FOR", "ENDFOR", "LOOP",
                    "ENDLOOP", "REPEAT", "REPEATB", "UNTIL", "GOTOF", "GOTOB", "GOTOC",
                    "GOTO", "CASE")
_HEAD = re.compile(r"(" + "|".join(sorted(CONTROL_KEYWORDS, key=len, reverse=True))
                   + r")(?![A-Z0-9_$])")
_TARGET = r"([A-Z_][A-Z0-9_]*|N\d+|:\d+)"
_JUMP = re.compile(r"(GOTOF|GOTOB|GOTOC|GOTO)\s+" + _TARGET)
_IF_JUMP = re.compile(r"IF(?=[ (])\s*(.+?)\s*(GOTOF|GOTOB|GOTOC|GOTO)\s+" + _TARGET)
_COND = re.compile(r"(IF|WHILE|UNTIL)(?=[ (])\s*(\S.*)")
_FOR = re.compile(r"FOR\s+([A-Z_][A-Z0-9_]*)\s*=\s*(.+?)\s+TO\s+(.+)")
_SECTION = re.compile(r"(REPEATB|REPEAT)\s+" + _TARGET + r"(?:\s+" + _TARGET
                      + r")?(?:\s+P\s*=\s*(.+))?")
_RPARAM = re.compile(r"R\d+")
_OPEN = {"IF": "ENDIF", "WHILE": "ENDWHILE", "FOR": "ENDFOR", "LOOP": "ENDLOOP",
         "REPEAT": "UNTIL"}
_CLOSE = {v: k for k, v in _OPEN.items()}
_END_LABEL = "ENDLABEL"


class Op(NamedTuple):
    """One control statement: ``kind`` (IF ELSE ENDIF WHILE ... JUMP SECTION), text
    pieces ``a b c d`` and their columns ``ca cb cc`` in the raw line."""

    kind: str
    a: str = ""
    b: str = ""
    c: str = ""
    d: str = ""
    ca: int = 0
    cb: int = 0
    cc: int = 0


class Flow:
    """What the pre-pass found: control statements, their partners, scopes, labels."""

    def __init__(self) -> None:
        self.ops: dict[int, Op] = {}
        #: opener -> ELSE or closer; ELSE -> ENDIF; closer -> opener
        self.partner: dict[int, int] = {}
        #: innermost structure (opener or ELSE index) holding each block; -1: none
        self.scope: list[int] = []
        self.parent: dict[int, int] = {-1: -1}
        self.labels: dict[str, list[int]] = {}
        #: line numbers of the blocks inside WHILE/FOR/LOOP/REPEAT loops (run again:
        #: their words are worth keeping)
        self.looped: set[int] = set()


def _err(msg: str, file: str, lines: list[str], b: SBlock, col: int | None = None):
    return NCParseError(msg, file=file, line=b.line, column=col or b.col,
                        text=lines[b.line - 1])


def _norm(target: str) -> str:
    if target[0] == "N" and target[1:].isdigit():
        return f"N{int(target[1:])}"
    if target[0] == ":" and target[1:].isdigit():
        return f":{int(target[1:])}"
    return target


def _parse(s: str, b: SBlock, file: str, lines: list[str]) -> Op | None:
    """The control statement ``s`` (None when the block is not one)."""
    m = _HEAD.match(s)
    if m is None:
        return None
    key = m.group(1)
    col = b.col
    if key == "CASE":
        raise _err("CASE ... OF ... DEFAULT is not read; expected IF ... ELSE ... ENDIF or "
                   "IF condition GOTOF label", file, lines, b)
    if key in ("ELSE", "ENDIF", "ENDWHILE", "ENDFOR", "LOOP", "ENDLOOP") or (
            key == "REPEAT" and s == "REPEAT"):
        if s != key:
            raise _err(f"{key} with more in its block ({s[len(key):].strip()[:20]!r}); "
                       f"expected {key} alone", file, lines, b, col + len(key))
        return Op(key)
    if key.startswith("GOTO"):
        j = _JUMP.fullmatch(s)
        if j is None:
            raise _err(f"{key}: expected {key} label or {key} N<number> alone in its block "
                       "(targets in variables are not read)", file, lines, b)
        return Op("JUMP", j.group(1), _norm(j.group(2)), ca=col + j.start(2))
    if key == "IF":
        j = _IF_JUMP.fullmatch(s)
        if j is not None:
            return Op("JUMP", j.group(2), _norm(j.group(3)), j.group(1), ca=col + j.start(3),
                      cb=col + j.start(1))
    if key in ("IF", "WHILE", "UNTIL"):
        c = _COND.fullmatch(s)
        if c is None:
            raise _err(f"{key} without a condition; expected {key} condition", file, lines, b)
        return Op(key, c.group(2), ca=col + c.start(2))
    if key == "FOR":
        f = _FOR.fullmatch(s)
        if f is None:
            raise _err("FOR: expected FOR variable = start TO end (steps of 1)", file,
                       lines, b)
        return Op("FOR", f.group(1), f.group(2), f.group(3), ca=col + f.start(1),
                  cb=col + f.start(2), cc=col + f.start(3))
    r = _SECTION.fullmatch(s)
    if r is None:
        raise _err(f"{key}: expected {key} label P=count" + (" or REPEAT start end P=count"
                                                              if key == "REPEAT" else ""),
                   file, lines, b)
    if key == "REPEATB" and r.group(3):
        raise _err("REPEATB repeats one block: expected REPEATB label P=count", file, lines,
                   b, col + r.start(3))
    last = _norm(r.group(3)) if r.group(3) else ""
    return Op("SECTION", key, _norm(r.group(2)), last, r.group(4) or "", col + r.start(2),
              cc=col + (r.start(4) if r.group(4) else 0))


def plan(blocks: list[SBlock], file: str, lines: list[str]) -> Flow:
    """Labels, control statements and how they nest; refuses unclosed or stray ones."""
    fl = Flow()
    labels = fl.labels
    stack: list[tuple[str, int, int]] = []  # (opener keyword, opener index, scope id)
    cur = -1
    scope = fl.scope
    loops = 0
    for i, b in enumerate(blocks):
        if loops:
            fl.looped.add(b.line)
        for lab in b.labels:
            at = labels.setdefault(lab, [])
            if lab[0] not in "N:" and lab != _END_LABEL and at:
                raise _err(f"label {lab} defined twice (first at line "
                           f"{blocks[at[0]].line})", file, lines, b, 1)
            at.append(i)
        s = b.stmt
        op = _parse(s, b, file, lines) if s and s[0] in "IEWFLRUGC" else None
        if op is None:
            scope.append(cur)
            continue
        fl.ops[i] = op
        k = op.kind
        if k in _OPEN:
            loops += k != "IF"
            scope.append(cur)
            fl.parent[i] = cur
            stack.append((k, i, i))
            cur = i
        elif k == "ELSE":
            if not stack or stack[-1][0] != "IF" or stack[-1][2] != stack[-1][1]:
                what = "ELSE without IF" if not stack or stack[-1][0] != "IF" else \
                    "a second ELSE for one IF"
                raise _err(f"{what}; expected IF condition ... ELSE ... ENDIF", file, lines, b)
            scope.append(cur)
            _, opener, _ = stack[-1]
            fl.partner[opener] = i
            fl.parent[i] = fl.parent[opener]
            stack[-1] = ("IF", opener, i)
            cur = i
        elif k in _CLOSE:
            want = _CLOSE[k]
            if not stack:
                raise _err(f"{k} without {want}", file, lines, b)
            top, opener, sid = stack[-1]
            if top != want:
                raise _err(f"{k} closes the {top} of line {blocks[opener].line}; expected "
                           f"{_OPEN[top]} first", file, lines, b)
            scope.append(cur)
            loops -= k != "ENDIF"
            stack.pop()
            fl.partner[sid] = i
            fl.partner[i] = opener
            cur = fl.parent[opener]
        else:
            scope.append(cur)
    for i, op in fl.ops.items():  # blocks a jump back or a section repeat may run again
        if op.kind == "JUMP" and op.a != "GOTOF" or op.kind == "SECTION":
            back = [k for k in labels.get(op.b, ()) if k <= i]
            if back:
                fl.looped.update(blocks[k].line for k in range(back[-1], i + 1))
    if stack:
        top, opener, _ = stack[-1]
        raise _err(f"{top} not closed; expected {_OPEN[top]} before the program's end", file,
                   lines, blocks[opener])
    return fl


def _inside(fl: Flow, inner: int, outer: int) -> bool:
    """Whether scope ``outer`` is ``inner`` or holds it."""
    while True:
        if inner == outer:
            return True
        if inner == -1:
            return False
        inner = fl.parent[inner]


class _Run:
    """One run's control state."""

    def __init__(self, st, blocks: list[SBlock], fl: Flow) -> None:
        self.st, self.blocks, self.fl = st, blocks, fl
        self.reps: list[list[int]] = []   # [start, end, passes left, REPEAT index]
        self.for_end: dict[int, float] = {}
        self.passes: dict[int, int] = {}
        self.back = -1                     # WHILE reached from its ENDWHILE
        self.targets: dict[int, int] = {}  # jump block -> its target (-1: none, GOTOC)

    def err(self, msg: str, col: int | None = None) -> NCParseError:
        return self.st.err(msg, col)

    def cond(self, text: str, col: int, what: str) -> bool:
        try:
            return condition(text, self.st.params)
        except ExprError as exc:
            raise self.err(f"{what}: {exc}", col + exc.offset) from None

    def again(self, opener: int) -> None:
        """One more pass of the loop opened at ``opener``."""
        n = self.passes.get(opener, 0) + 1
        if n > K.SIEMENS_MAX_LOOP_PASSES:
            ob = self.blocks[opener]
            op = self.fl.ops[opener]
            what = (f"{op.a} {op.b} at line {ob.line} jumping back" if op.kind == "JUMP"
                    else f"the {op.kind} at line {ob.line}")
            raise self.err(f"more than {K.SIEMENS_MAX_LOOP_PASSES:,} passes of {what} "
                           "(SIEMENS_MAX_LOOP_PASSES): a loop that does not end?")
        self.passes[opener] = n

    def find(self, here: int, kind: str, target: str, col: int) -> int:
        """Index of the target block of a jump at ``here``; -1: GOTOC found none."""
        t = self.targets.get(here)
        if t is None:
            t = self.targets[here] = self._find(here, kind, target, col)
        if self.reps and t >= 0:
            start, end = self.reps[-1][0], self.reps[-1][1]
            if not start <= t <= end:
                raise self.err(f"{kind} {target}: a jump out of the section a REPEAT at line "
                               f"{self.blocks[self.reps[-1][3]].line} repeats is not read",
                               col)
        return t

    def _find(self, here: int, kind: str, target: str, col: int) -> int:
        at = self.fl.labels.get(target, [])
        after = [i for i in at if i > here]
        before = [i for i in at if i < here]
        found = (after[:1] if kind == "GOTOF" else before[-1:] if kind == "GOTOB"
                 else after[:1] or before[-1:])
        if not found:
            if kind == "GOTOC":
                return -1
            where = {"GOTOF": "after", "GOTOB": "before"}.get(kind, "in")
            raise self.err(f"{kind} {target}: no label or block number {target} {where} "
                           "this block", col)
        t = found[0]
        fl = self.fl
        if not _inside(fl, fl.scope[here], fl.scope[t]):
            raise self.err(f"{kind} {target}: the target (line {self.blocks[t].line}) is "
                           "inside a structured block (IF/ELSE/WHILE/FOR/LOOP/REPEAT) the jump "
                           "is not in; jumps may leave such blocks, not enter them", col)
        return t

    def section(self, i: int, op: Op) -> int:
        """Start a section repeat at REPEAT block ``i``; the next block index."""
        fl = self.fl
        key, first, last, ptext = op.a, op.b, op.c, op.d
        at = fl.labels.get(first, [])
        before = [k for k in at if k < i]
        after = [k for k in at if k > i]
        if not at or at == [i]:
            raise self.err(f"{key} {first}: no label or block number {first} in the program",
                           op.ca)
        start = before[-1] if before else after[0]
        if key == "REPEATB":
            end = start
        elif last:
            ends = [k for k in fl.labels.get(last, []) if k >= start]
            if not ends:
                raise self.err(f"REPEAT {first} {last}: no label {last} at or after {first}",
                               op.ca)
            end = ends[0]
        else:
            marks = [k for k in fl.labels.get(_END_LABEL, []) if k >= start]
            if start < i:
                end = min([k for k in marks if k < i] or [i - 1])
            elif marks:
                end = marks[0]
            else:
                raise self.err(f"REPEAT {first}: the label is after the REPEAT and no "
                               "ENDLABEL: block follows it", op.ca)
        if start <= i <= end:
            raise self.err(f"{key} {first}: the section repeated holds the REPEAT itself",
                           op.ca)
        for k in range(start, end + 1):
            p = fl.partner.get(k)
            if p is not None and not start <= p <= end:
                raise self.err(f"{key} {first}: the section (lines {self.blocks[start].line}-"
                               f"{self.blocks[end].line}) cuts through the "
                               f"{fl.ops[k].kind} of line {self.blocks[k].line}; expected "
                               "whole structured blocks", op.ca)
        count = 1.0
        if op.d:
            try:
                count = evaluate(ptext, self.st.params)
            except ExprError as exc:
                raise self.err(f"{key} P: {exc}", op.cc + exc.offset) from None
            if not (count == int(count) and 1 <= count <= K.SIEMENS_MAX_LOOP_PASSES):
                raise self.err(f"{key} P={count:g}: expected a whole count from 1 to "
                               f"{K.SIEMENS_MAX_LOOP_PASSES:,}", op.cc)
        if len(self.reps) >= K.SIEMENS_MAX_REPEAT_DEPTH:
            raise self.err(f"{key}: more than {K.SIEMENS_MAX_REPEAT_DEPTH} section repeats "
                           "nested (SIEMENS_MAX_REPEAT_DEPTH)")
        self.reps.append([start, end, int(count), i])
        return start

    def step(self, i: int, op: Op) -> int:
        """Run control statement ``op`` at block ``i``; the index of the next block (-1:
        none)."""
        k = op.kind
        fl = self.fl
        nxt = i + 1
        if k == "JUMP":
            if op.c and not self.cond(op.c, op.cb, "IF"):
                self.passes[i] = 0  # the loop this jump closes has ended
                return nxt
            t = self.find(i, op.a, op.b, op.ca)
            if t < 0:
                return nxt
            if t <= i:
                self.again(i)
            return t
        if k == "IF":
            return nxt if self.cond(op.a, op.ca, "IF") else fl.partner[i] + 1
        if k == "ELSE":
            return fl.partner[i] + 1
        if k == "WHILE":
            if self.back != i:
                self.passes[i] = 0
            self.back = -1
            return nxt if self.cond(op.a, op.ca, "WHILE") else fl.partner[i] + 1
        if k == "ENDWHILE":
            w = fl.partner[i]
            self.again(w)
            self.back = w
            return w
        if k in ("LOOP", "REPEAT"):
            self.passes[i] = 0
            return nxt
        if k == "ENDLOOP":
            lp = fl.partner[i]
            self.again(lp)
            return lp + 1
        if k == "UNTIL":
            if self.cond(op.a, op.ca, "UNTIL"):
                return nxt
            r = fl.partner[i]
            self.again(r)
            return r + 1
        if k == "FOR":
            return self.for_start(i, op)
        if k == "ENDFOR":
            f = fl.partner[i]
            var = fl.ops[f].a
            params = self.st.params
            if var not in params:
                raise self.err(f"ENDFOR: the counter {var} of the FOR at line "
                               f"{self.blocks[f].line} is not set")
            v = params[var] + 1.0
            params[var] = v
            if v <= self.for_end[f]:
                self.again(f)
                return f + 1
            return nxt
        if k == "SECTION":
            return self.section(i, op)
        return nxt  # ENDIF

    def for_start(self, i: int, op: Op) -> int:
        st = self.st
        var = op.a
        if var not in st.params and not _RPARAM.fullmatch(var):
            raise self.err(f"FOR {var}: the counter must be an R parameter or a DEF "
                           "variable defined before the FOR", op.ca)
        a = st.expr(op.b, op.cb, f"FOR {var} start")
        b = st.expr(op.c, op.cc, f"FOR {var} end")
        if var in st.ints and (a != int(a) or b != int(b)):
            a, b = float(round(a)), float(round(b))
        st.params[var] = a
        self.for_end[i] = b
        self.passes[i] = 0
        return i + 1 if a <= b else self.fl.partner[i] + 1


def run(st, blocks: list[SBlock], fl: Flow, block_delete: bool,
        execute: Callable[[object, SBlock], bool]) -> int:
    """Run ``blocks`` from the first in execution order until the program ends.

    ``execute(st, block)`` runs a block that is not a control statement and is
    True when it ends the program (M2, M17, M30, RET). Returns the number of
    blocks executed [blocks].
    """
    limit = K.SIEMENS_MAX_EXECUTED_BLOCKS
    r = _Run(st, blocks, fl)
    st.lex_keep = fl.looped
    ops = fl.ops
    reps = r.reps
    executed = 0
    pc = 0
    n = len(blocks)
    while 0 <= pc < n:
        i = pc
        b = blocks[i]
        pc = i + 1
        if not (b.skip and block_delete):
            executed += 1
            if executed > limit:
                st.b = b
                raise st.err(f"more than {limit:,} blocks executed (SIEMENS_MAX_EXECUTED_"
                             "BLOCKS): a jump loop that does not end?")
            op = ops.get(i)
            if op is None:
                if execute(st, b):
                    return executed
            else:
                st.b = b
                pc = r.step(i, op)
        while reps:  # the section ends when control leaves its last block forward
            top = reps[-1]
            if pc != top[1] + 1 or not top[0] <= i <= top[1]:
                break
            top[2] -= 1
            if top[2] > 0:
                pc = top[0]
            else:
                reps.pop()
                i = top[3]
                pc = i + 1
    return executed
