"""LinuxCNC O-word control flow, run into the straight-line program the reader reads.

A program with O-word lines (``o100 if [...]``, ``o<name> call [..]``) is
executed here as LinuxCNC's interpreter does (``interp_o_word.cc``), and
every line it runs comes out with its ``#`` parameters and ``[ ]``
expressions replaced by values (as :mod:`nc.macro` does for programs without
O-words), tagged with the source line it came from: moves and errors name
the source file's line, however often a loop or a call ran it.

Supported: ``sub``/``endsub`` (``[args]`` -> #1..#30, local to the call and
0 when not passed; ``return [v]`` and ``endsub [v]`` -> ``#<_value>`` and
``#<_value_returned>``), ``call``, ``if``/``elseif``/``else``/``endif``,
``while``/``endwhile``, ``do``/``while``, ``repeat``/``endrepeat``,
``break``, ``continue``; numbered (``o100``) and named (``o<name>``) labels.
Named parameters without a leading ``_`` are local to the subroutine (or
the main program) that sets them; ``#<_name>`` and #31-#4999 are global.

As LinuxCNC: a subroutine may be defined before or after its call, but the
main program must not run into the definition of one it already called;
labels of ``if``/``while``/``do``/``repeat`` run from one line only per
subroutine (and in the main program; checked when the line runs, as rs274
does); calls nest at most :data:`nc.constants.LINUXCNC_MAX_CALL_DEPTH` deep;
``break``/``continue`` name a ``while`` or ``do`` loop. LinuxCNC's own loop
state is kept, quirks included (checked against ``rs274``): a ``break`` out
of a ``while`` loop also ends the next ``do`` loop after one pass; a
``continue`` in a ``do`` loop makes the next ``while``/``repeat`` that ends
run its test (a repeat: all its passes) once more; repeat counts are shared
by every call of a sub. Blocks must nest (a sub at the top level, each block
closed by its own label inside the block around it); LinuxCNC, which skips
by label, would run some programs that do not. Refused, each with one line naming file,
line and column: a sub not defined in this file (LinuxCNC would look for a
file of that name; this reader does not), blocks that are not closed or
closed by another label, an ``endsub`` or ``return`` outside a sub, and a
program that runs more than :data:`nc.constants.LINUXCNC_MAX_EXECUTED_LINES`
lines (a loop that does not end). Expansion stops after the line with M2
or M30, or a closing ``%``.
"""

from __future__ import annotations

import math
import re

from . import constants as K
from .errors import NCParseError
from .expressions import LINUXCNC, ExprError, compile_expression
from .lexer import foreign_syntax
from .macro import _END, _FIRST_SYSTEM, _PREFIX, _skip, _strip, _target, _text

__all__ = ["has_owords", "expand_owords"]

#: an O-word command at a line's start: o<name>, or a number and a word of letters
#: (within the line: 'O1000' then a block, or 'O12 G0 X1', is a program number)
_CONTROL = re.compile(r"(?im)^[ \t/]*(?:N[ \t]*\d+[ \t]*)?O[ \t]*(?:<|\d+[ \t]*[A-Z][A-Z])")
#: a line that may be an O-word line (raw text; the full parse follows)
_MAYBE_O = re.compile(r"\s*(?:/\s*)?(?:[Nn]\s*\d+(?:\.\d*)?\s*)?[Oo]")
#: the head of an O-word line, comments blanked and upper case
_HEAD = re.compile(r"(\s*)(/\s*)?(?:N\s*\d+(?:\.\d*)?\s*)?O\s*(?:<([^<>]*)>|(\d+))\s*([A-Z]*)")
_KINDS = ("SUB", "ENDSUB", "CALL", "DO", "WHILE", "REPEAT", "IF", "ELSEIF", "ELSE", "ENDIF",
          "BREAK", "CONTINUE", "ENDWHILE", "ENDREPEAT", "RETURN")
#: a program with fewer letters O is checked line by line, else by one regex [-]
_FEW_OS = 10_000
_OPENERS = ("IF", "WHILE", "DO", "REPEAT")
_CLOSER = {"IF": "endif", "WHILE": "endwhile", "DO": "while", "REPEAT": "endrepeat"}
_READ_ONLY = ("_value", "_value_returned")
_LABELLED = frozenset(("IF", "WHILE", "DO", "REPEAT"))
_WHAT = "O-word control flow: "


def has_owords(text: str) -> bool:
    """True for a program with LinuxCNC O-word lines (``o100 sub``, ``o<x> if``...)."""
    if "[" not in text and "#" not in text and (
            text.count("O") + text.count("o") < _FEW_OS):
        # a plain ISO program: only the lines with an 'O' are looked at (C-speed
        # scans instead of a regex at every line start: 2 ms instead of 34 on 120k lines)
        for letter in "Oo":
            i = text.find(letter)
            while i >= 0:
                if _CONTROL.match(text, text.rfind("\n", 0, i) + 1) is not None:
                    return True
                i = text.find(letter, i + 1)
        return False
    return _CONTROL.search(text) is not None


class _FlowError(ExprError):
    """What the control flow refuses while it runs (the O-word's column is named)."""

    def __init__(self, message: str) -> None:
        super().__init__(message, 0)


class _Op:
    """One O-word line: its kind, label, expressions and the lines it jumps to."""

    __slots__ = ("kind", "key", "label", "col", "expr", "args", "target", "end", "scope")

    def __init__(self, kind: str, key: str, label: str, col: int, scope: str) -> None:
        self.kind, self.key, self.label, self.col, self.scope = kind, key, label, col, scope
        self.expr = None
        self.args: list = []
        self.target = -1  # partner line (0-based), see _structure
        self.end = -1     # if/elseif/else: the endif


class _Store:
    """Parameters: #1-#30 per call, #31-#4999 and #<_name> global, #<name> per call."""

    __slots__ = ("num", "glob", "local", "value", "returned")

    def __init__(self) -> None:
        self.num: dict = {}
        self.glob: dict = {}
        self.local: dict = {}
        self.value = 0.0
        self.returned = 0.0

    def read(self, key, offset):
        if key.__class__ is int:
            v = self.num.get(key)
            if v is not None:
                return v
            if key >= _FIRST_SYSTEM:
                raise ExprError(f"system parameter #{key} needs the control's state and is "
                                "not supported; expected #1-#4999 or #<name>", offset)
            raise ExprError(f"#{key} is used before it is set in this program; expected a "
                            "parameter the program sets", offset)
        if key.startswith("_"):
            if key == "_value":
                return self.value
            if key == "_value_returned":
                return self.returned
            v = self.glob.get(key)
            if v is None:
                raise ExprError(f"#<{key}> is a predefined (system) parameter; expected a "
                                "parameter the program sets", offset)
            return v
        v = self.local.get(key)
        if v is None:
            raise ExprError(f"#<{key}> is used before it is set; expected a parameter the "
                            "program sets (names without a leading '_' are local to the "
                            "subroutine or main program that sets them)", offset)
        return v

    def exists(self, key):
        if key.startswith("_"):
            return key in _READ_ONLY or key in self.glob
        return key in self.local

    def set(self, key, v) -> None:
        if key.__class__ is int:
            self.num[key] = v
        elif key.startswith("_"):
            self.glob[key] = v
        else:
            self.local[key] = v


def _error(file: str, k: int, lines: list[str], message: str, col: int) -> NCParseError:
    return NCParseError(message, file=file, line=k + 1, column=col, text=lines[k])


# -- reading the lines --------------------------------------------------------
def _parse_o(s: str, m: re.Match, scope: str) -> _Op:
    """The O-word line ``s`` (comments blanked, upper case) whose head ``m`` matched."""
    col = m.end(1) + 1
    if m.group(2):
        raise ExprError("block delete '/' on an O-word line is not supported; expected "
                        "the O-word at the start of the line", m.start(2))
    if m.group(3) is not None:
        key = "".join(m.group(3).split()).lower()
        label = f"o<{key}>"
    else:
        key = str(int(m.group(4)))
        label = f"o{key}"
    word = m.group(5)
    if word not in _KINDS:
        what = f"unknown O-word command {word!r}" if word else f"no command after {label}"
        raise ExprError(f"{what}; expected sub, endsub, call, if, elseif, else, endif, "
                        "while, endwhile, do, repeat, endrepeat, break, continue or return",
                        m.start(5))
    op = _Op(word, key, label, col, scope)
    i = _skip(s, m.end())
    n = len(s)
    if word in ("IF", "ELSEIF", "WHILE", "REPEAT"):
        if i >= n or s[i] != "[":
            raise ExprError(f"expected '[' and a condition after {label} {word.lower()}", i)
        op.expr, i = compile_expression(s, LINUXCNC, i, whole=False)
    elif word in ("RETURN", "ENDSUB") and i < n and s[i] == "[":
        op.expr, i = compile_expression(s, LINUXCNC, i, whole=False)
    elif word == "CALL":
        while i < n and s[i] == "[":
            if len(op.args) == K.LINUXCNC_SUB_ARGS:
                raise ExprError(f"more than {K.LINUXCNC_SUB_ARGS} arguments to {label}; "
                                f"expected at most {K.LINUXCNC_SUB_ARGS} (#1-#30)", i)
            node, i = compile_expression(s, LINUXCNC, i, whole=False)
            op.args.append(node)
            i = _skip(s, i)
    i = _skip(s, i)
    if i < n:
        raise ExprError(f"unexpected {s[i:].split()[0][:12]!r} after {label} "
                        f"{word.lower()}; expected only comments", i)
    return op


def _structure(lines: list[str], file: str) -> tuple[list, dict]:
    """Every line's O-word (None for other lines) with its partners, and the subs.

    Blocks must nest: a sub at the top level, each if/while/do/repeat closed by
    the same label before its enclosing block ends.
    """
    ops: list = [None] * len(lines)
    subs: dict[str, int] = {}
    stack: list[tuple[_Op, int]] = []
    sub: tuple[_Op, int] | None = None
    for k, raw in enumerate(lines):
        if _MAYBE_O.match(raw) is None:
            continue
        s = _strip(raw)
        m = _HEAD.match(s)
        if m is None:
            continue
        if not m.group(5) and not s[m.end():].strip() and m.group(4) is not None:
            continue  # a bare 'O1234': a program number, for the reader
        scope = sub[0].key if sub else ""
        try:
            op = _parse_o(s, m, scope)
        except ExprError as exc:
            raise _error(file, k, lines, _WHAT + str(exc), exc.offset + 1) from None
        except RecursionError:
            raise _error(file, k, lines, _WHAT + "brackets nested too deeply; expected at "
                         "most a few hundred levels", 1) from None
        ops[k] = op
        kind, label = op.kind, op.label

        def fail(message: str) -> NCParseError:
            return _error(file, k, lines, _WHAT + message, op.col)

        if kind == "SUB":
            if sub is not None:
                raise fail(f"{label} sub inside {sub[0].label} sub (line {sub[1] + 1}); "
                           f"expected {sub[0].label} endsub first")
            if stack:
                raise fail(f"{label} sub inside {stack[-1][0].label} "
                           f"{stack[-1][0].kind.lower()} (line {stack[-1][1] + 1}); expected "
                           "subroutines defined outside if/while/do/repeat blocks")
            if op.key in subs:
                raise fail(f"{label} sub is defined twice (first at line {subs[op.key] + 1}); "
                           "expected each subroutine once")
            subs[op.key] = k
            sub = (op, k)
        elif kind == "ENDSUB":
            if sub is None or sub[0].key != op.key:
                raise fail(f"{label} endsub without {label} sub" + (
                    f" (open: {sub[0].label} sub, line {sub[1] + 1})" if sub else "") +
                    "; expected endsub to close its own sub")
            if stack:
                raise _unclosed(file, lines, stack[-1], f"before {label} endsub")
            sub[0].target = k
            op.target = sub[1]
            sub = None
        elif kind == "RETURN":
            if sub is None:
                raise fail(f"{label} return outside a subroutine; expected it between "
                           "o... sub and o... endsub")
        elif kind == "CALL":
            pass
        elif kind in _OPENERS and not (kind == "WHILE" and stack and stack[-1][0].kind == "DO"
                                       and stack[-1][0].key == op.key):
            stack.append((op, k))
        else:
            opener = "IF" if kind in ("ELSEIF", "ELSE", "ENDIF") else {
                "WHILE": "DO", "ENDWHILE": "WHILE", "ENDREPEAT": "REPEAT"}.get(kind)
            if kind in ("BREAK", "CONTINUE"):
                for top, j in reversed(stack):
                    if top.key == op.key:
                        if top.kind not in ("WHILE", "DO"):
                            raise fail(f"{label} {kind.lower()} names a {top.kind.lower()} "
                                       f"(line {j + 1}); expected a while or do loop")
                        op.target = j
                        break
                else:
                    raise fail(f"{label} {kind.lower()} outside a loop {label}; expected it "
                               f"inside {label} while or {label} do")
                continue
            if not stack or stack[-1][0].key != op.key or stack[-1][0].kind != opener:
                if stack and stack[-1][0].key != op.key and any(
                        t.key == op.key and t.kind == opener for t, _ in stack):
                    raise _unclosed(file, lines, stack[-1], f"before {label} {kind.lower()}")
                raise fail(f"{label} {kind.lower()} without {label} {opener.lower()}; "
                           f"expected {label} {opener.lower()} before it")
            top, j = stack[-1]
            if kind in ("ELSEIF", "ELSE"):
                last = top.end if top.end >= 0 else j
                if ops[last].kind == "ELSE":
                    raise fail(f"{label} {kind.lower()} after {label} else (line {last + 1}); "
                               f"expected {label} endif")
                ops[last].target = k
                top.end = k
                continue
            stack.pop()
            if kind == "ENDIF":
                last = top.end if top.end >= 0 else j
                ops[last].target = k
                b = j
                while b != k:  # every branch jumps to the endif when it is done
                    ops[b].end = k
                    b = ops[b].target
            else:
                top.target, op.target = k, j
                if kind == "WHILE":
                    op.kind = "DOWHILE"
    if stack:
        raise _unclosed(file, lines, stack[-1], "before the end of the file")
    if sub is not None:
        raise _error(file, sub[1], lines, _WHAT + f"{sub[0].label} sub is not closed before "
                     f"the end of the file; expected {sub[0].label} endsub", sub[0].col)
    return ops, subs


def _unclosed(file: str, lines: list[str], top: tuple[_Op, int], where: str) -> NCParseError:
    op, j = top
    return _error(file, j, lines, _WHAT + f"{op.label} {op.kind.lower()} is not closed "
                  f"{where}; expected {op.label} {_CLOSER[op.kind]}", op.col)


def _compile_line(s: str) -> tuple[list, list]:
    """A line's words (text, or (letter, value node)) and assignments (key, node)."""
    parts: list = []
    sets: list = []
    i, n = 0, len(s)
    while i < n:
        c = s[i]
        if c.isspace():
            i += 1
        elif c == "#":
            _, j = compile_expression(s, LINUXCNC, i, whole=False)
            key = _target(s, i + 1, None)
            if key in _READ_ONLY:
                raise ExprError(f"#<{key}> is read-only (return and endsub set it); "
                                "expected another parameter", i)
            j = _skip(s, j)
            if j >= n or s[j] != "=":
                raise ExprError("expected '=' after a parameter at the start of an "
                                "assignment", j)
            node, i = compile_expression(s, LINUXCNC, j + 1, whole=False)
            sets.append((key, node))
        elif c.isalpha() and c.isascii():
            m = _NUMBER.match(s, i + 1)
            if m is not None:
                parts.append(c + m.group(1) + m.group(2))
                i = m.end()
            else:
                node, i = compile_expression(s, LINUXCNC, _skip(s, i + 1), whole=False)
                parts.append((c, node))
        elif c == "/" and not parts and not sets:
            parts.append("/")
            i += 1
        else:
            raise ExprError(f"unexpected character {c!r}; expected words and #-assignments", i)
    return parts, sets


#: a plain number after a word's letter: sign and digits (as nc.macro reads them)
_NUMBER = re.compile(r"\s*([-+]?)\s*(\d+\.?\d*|\.\d*)")


# -- running them ---------------------------------------------------------------
def expand_owords(lines: list[str], file: str) -> tuple[list[str], list[int]]:
    """Run the program's O-word control flow; the lines it runs and their line numbers.

    Parameters
    ----------
    lines : list of str
        The program's lines.
    file : str
        Name for error messages.

    Returns
    -------
    (texts, numbers)
        Each executed line other than O-word lines, parameters replaced by
        values, and its 1-based source line number.

    Raises
    ------
    NCParseError
        One line naming file, line and column, for what the module refuses.
    """
    ops, subs = _structure(lines, file)
    store = _Store()
    texts: list[str] = []
    numbers: list[int] = []
    plain: dict[int, object] = {}
    registered: set[str] = set()
    used: dict[tuple[str, str], int] = {}  # (sub, label) -> line of its first use
    frames: list[tuple] = []       # (return line, saved #1-#30, named locals)
    # LinuxCNC's loop state, kept as its interpreter keeps it: passes left per repeat
    # line (shared by every call, as its label table), and the flags break and
    # continue set for the line that closes the loop (a break out of a while loop
    # also ends the next do loop's pass; LinuxCNC clears the flag only there)
    repeats: dict[int, int] = {}
    skipping = doing_break = doing_continue = False
    limit = K.LINUXCNC_MAX_EXECUTED_LINES
    steps = 0
    n = len(lines)
    first = next((k for k, ln in enumerate(lines) if ln.strip()), n)
    pc = 0
    while pc < n:
        steps += 1
        if steps > limit:
            raise _error(file, pc, lines, _WHAT + f"more than {limit:,} lines executed (a "
                         "loop that does not end?); expected a program that ends", 1)
        op = ops[pc]
        try:
            if op is None:
                entry = plain.get(pc)
                if entry is None:
                    entry = plain[pc] = _plain(lines[pc])
                if entry.__class__ is tuple:
                    text = _run_line(entry, store)
                    texts.append(text)
                    numbers.append(pc + 1)
                    if _END.search(text):
                        break
                else:
                    texts.append(lines[pc])
                    numbers.append(pc + 1)
                    if entry is _ENDS:
                        break
                    if entry is _PERCENT and pc != first:
                        break  # the closing '%': the tape ends here
                pc += 1
                continue
            kind = op.kind
            if kind in _LABELLED:
                first = used.setdefault((op.scope, op.key), pc)
                if first != pc:
                    raise _FlowError(f"{op.label} is used again (first at line {first + 1}); "
                                     "LinuxCNC expects each if/while/do/repeat label once "
                                     "per subroutine")
            if kind == "SUB":
                if op.key in registered:
                    raise _FlowError(f"{op.label} sub is reached after a call already ran it "
                                    "(LinuxCNC refuses: 'found in illegal location'); "
                                    "expected M2 before the definition, or the definition "
                                    "before the call")
                registered.add(op.key)
                pc = op.target + 1
            elif kind == "CALL":
                args = [a(store) for a in op.args]
                start = subs.get(op.key)
                if op.key not in registered:
                    if start is None:
                        raise _FlowError(f"{op.label} call: no {op.label} sub in this file; "
                                        "expected the subroutine defined in the program "
                                        "(subroutine files are not read)")
                    if start < pc:
                        raise _FlowError(f"{op.label} call before LinuxCNC has read the "
                                        f"definition at line {start + 1}; expected the "
                                        "definition before the code that calls it")
                    registered.add(op.key)
                if len(frames) >= K.LINUXCNC_MAX_CALL_DEPTH:
                    raise _FlowError(f"{op.label} call: subroutine calls nested deeper than "
                                    f"{K.LINUXCNC_MAX_CALL_DEPTH} (LinuxCNC's limit); "
                                    "expected a recursion that ends sooner")
                num = store.num
                saved = {q: num[q] for q in range(1, K.LINUXCNC_SUB_ARGS + 1) if q in num}
                frames.append((pc + 1, saved, store.local))
                for q in range(1, K.LINUXCNC_SUB_ARGS + 1):
                    num[q] = args[q - 1] if q <= len(args) else 0.0
                store.local = {}
                pc = start + 1
            elif kind == "ENDSUB" or kind == "RETURN":
                if op.expr is not None:
                    store.value, store.returned = op.expr(store), 1.0
                else:
                    store.value, store.returned = 0.0, 0.0
                if not frames:  # only a sub's body has these; the main program skips it
                    raise _FlowError(f"{op.label} {kind.lower()} reached outside a call")
                pc, saved, store.local = frames.pop()
                num = store.num
                for q in range(1, K.LINUXCNC_SUB_ARGS + 1):
                    if q in saved:
                        num[q] = saved[q]
                    else:
                        num.pop(q, None)
            elif kind == "IF":
                if op.expr(store) != 0.0:
                    pc += 1
                else:
                    pc = op.target
                    while ops[pc].kind == "ELSEIF":
                        op = ops[pc]
                        steps += 1
                        if op.expr(store) != 0.0:
                            break
                        pc = op.target
                    pc += 1
            elif kind == "ELSEIF" or kind == "ELSE":
                pc = op.end + 1  # the branch before ran: on to the endif
            elif kind == "WHILE":
                if op.expr(store) != 0.0:
                    pc += 1
                else:
                    pc, skipping = op.target, True
            elif kind == "ENDWHILE" or kind == "ENDREPEAT":
                if skipping:  # came by break, continue or a loop test that failed
                    skipping = False
                    if doing_continue:
                        doing_continue = False
                        pc = op.target
                    else:
                        pc += 1
                else:
                    pc = op.target
            elif kind == "DOWHILE":
                skipping = False
                if op.expr(store) != 0.0 and not doing_break:
                    pc = op.target + 1
                else:
                    doing_break = False
                    pc += 1
            elif kind == "REPEAT":
                count = op.expr(store)
                left = repeats.get(pc)
                if left is None:
                    if not math.isfinite(count):
                        raise ExprError(f"repeat count {count} is not a finite number; "
                                        "expected a whole number of passes", op.col - 1)
                    left = round(count)  # LinuxCNC: nearest, halves to even
                if left > 0:
                    repeats[pc] = left - 1
                    pc += 1
                else:
                    repeats.pop(pc, None)
                    pc, skipping = op.target, True
            elif kind == "BREAK":
                doing_break = skipping = True
                pc = ops[op.target].target
            elif kind == "CONTINUE":
                doing_continue = skipping = True
                pc = ops[op.target].target
            else:  # ENDIF, DO
                pc += 1
        except _FlowError as exc:
            raise _error(file, pc, lines, _WHAT + str(exc), op.col) from None
        except ExprError as exc:
            raise _error(file, pc, lines, _PREFIX + str(exc), exc.offset + 1) from None
        except RecursionError:
            raise _error(file, pc, lines, _PREFIX + "brackets nested too deeply; expected "
                         "at most a few hundred levels", 1) from None
    return texts, numbers


_VERBATIM = object()
_ENDS = object()
_PERCENT = object()


def _plain(raw: str):
    """How a line without an O-word runs: compiled (a tuple), or as it is."""
    if "#" not in raw and "[" not in raw:
        if ("M" in raw or "m" in raw) and _END.search(_strip(raw)):
            return _ENDS
        if raw.lstrip().startswith("%"):
            return _PERCENT
        return _VERBATIM
    s = _strip(raw)
    if foreign_syntax(s) is not None:  # left for the reader, which names the dialect
        return _VERBATIM
    return _compile_line(s)


def _run_line(entry: tuple, store: _Store) -> str:
    parts, sets = entry
    words = [p if p.__class__ is str else p[0] + _text(p[1](store)) for p in parts]
    if sets:
        values = [(key, node(store)) for key, node in sets]
        for key, v in values:
            store.set(key, v)
    return " ".join(words)
