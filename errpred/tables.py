"""Reading a scenario's TOML tables: typed values whose every error names file and key.

:class:`TableReader` gives numbers (finite, with a sign and an upper bound),
whole numbers, strings, arrays, tables and file paths out of a parsed TOML
document; whatever is wrong raises :class:`ScenarioError` (an
:class:`nc.errors.InputError`) naming the scenario file and the dotted key.
:mod:`errpred.scenario` reads its sections with it, and so does ``orient``'s
planning scenario for its own.
"""

from __future__ import annotations

import difflib
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from nc.errors import InputError

from . import constants as K

__all__ = ["ScenarioError", "TableReader", "check_program_lines"]

_MISSING = object()


class ScenarioError(InputError):
    """A scenario file that cannot be used: names the file and the dotted key.

    Attributes
    ----------
    file : str
        The scenario file as given.
    key : str or None
        Dotted key (``tool.diameter_mm``), None for the file as a whole.
    """

    def __init__(self, file: str, key: str | None, message: str) -> None:
        self.file, self.key = file, key
        super().__init__(f"{file}: {key}: {message}" if key else f"{file}: {message}")


class TableReader:
    """Typed access to one TOML file's tables; every error names file and key.

    Public so that packages whose scenarios extend this format (``orient``)
    read their own sections with the same checks and messages.
    """

    def __init__(self, path: str | os.PathLike) -> None:
        self.file = os.fspath(path)
        self.base = Path(self.file).resolve().parent

    def fail(self, key: str | None, message: str) -> ScenarioError:
        return ScenarioError(self.file, key, message)

    def table(self, value: Any, key: str) -> dict:
        if not isinstance(value, dict):
            raise self.fail(key, f"expected a table ([{key}]), got {_kind(value)}")
        return value

    def keys(self, d: dict, prefix: str, required: tuple, optional: tuple = ()) -> None:
        allowed = required + optional
        for k in d:
            if k not in allowed:
                hint = _suggest(k, allowed)
                raise self.fail(_dot(prefix, k), "unknown key" + (
                    f"; did you mean {_dot(prefix, hint)!r}?" if hint else "")
                    + f" (expected {', '.join(allowed)})")
        for k in required:
            if k not in d:
                raise self.fail(_dot(prefix, k), "missing")

    def given(self, d: dict, k: str, key: str, default: Any) -> bool:
        """True if ``k`` is in ``d``; False if absent with a default; else 'missing'."""
        if k not in d and default is _MISSING:
            raise self.fail(key, "missing")
        return k in d

    def number(self, d: dict, k: str, prefix: str, *, default: Any = _MISSING,
               sign: str = "", maximum: float = math.inf, limit: str = "") -> float:
        """A finite number (``sign``: ``">0"`` or ``">=0"``) at most ``maximum`` in
        magnitude (the constant ``limit`` names it in the message)."""
        key = _dot(prefix, k)
        if not self.given(d, k, key, default):
            return default
        v = d[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.fail(key, f"expected a number, got {_kind(v)}")
        v = float(v)
        if not math.isfinite(v):
            raise self.fail(key, f"expected a finite number, got {v}")
        if (sign == ">0" and v <= 0) or (sign == ">=0" and v < 0):
            raise self.fail(key, f"expected a value {sign[:-1]} 0, got {v:g}")
        if abs(v) > maximum:
            bound = f"at most {maximum:g}" if sign else f"-{maximum:g} to {maximum:g}"
            raise self.fail(key, f"expected {bound}{_named(limit)}, got {v:g}")
        return v

    def integer(self, d: dict, k: str, prefix: str, *, default: Any = _MISSING,
                minimum: int = 1, maximum: float = math.inf, limit: str = "") -> int:
        """A whole number from ``minimum`` to ``maximum`` (named by ``limit``)."""
        key = _dot(prefix, k)
        if not self.given(d, k, key, default):
            return default
        v = d[k]
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.fail(key, f"expected a whole number, got {_kind(v)}")
        if v < minimum:
            raise self.fail(key, f"expected a whole number >= {minimum}, got {v}")
        if v > maximum:
            raise self.fail(key, f"expected at most {maximum:g}{_named(limit)}, got {v}")
        return v

    def string(self, d: dict, k: str, prefix: str, *, default: Any = _MISSING,
               choices: tuple = ()) -> str:
        key = _dot(prefix, k)
        if not self.given(d, k, key, default):
            return default
        v = d[k]
        if not isinstance(v, str):
            raise self.fail(key, f"expected a string, got {_kind(v)}")
        if choices and v not in choices:
            raise self.fail(key, f"unknown value {v!r}; expected one of "
                                 f"{', '.join(map(repr, choices))}")
        return v

    def numbers(self, d: dict, k: str, prefix: str, *, length: int | None = None,
                sign: str = "", maximum: float = math.inf, limit: str = "") -> list[float]:
        key = _dot(prefix, k)
        v = d[k]
        if not isinstance(v, list) or not v:
            raise self.fail(key, f"expected a non-empty array of numbers, got {_kind(v)}")
        if length is not None and len(v) != length:
            raise self.fail(key, f"expected {length} numbers, got {len(v)}")
        return [self.number({f"{k}[{i}]": x}, f"{k}[{i}]", prefix, sign=sign,
                            maximum=maximum, limit=limit) for i, x in enumerate(v)]

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

    def path(self, d: dict, k: str, prefix: str) -> Path:
        key = _dot(prefix, k)
        v = self.string(d, k, prefix)
        p = (self.base / v).resolve()
        if not p.is_file():
            raise self.fail(key, f"file not found: {p}")
        return p


def _limit(name: str) -> dict:
    """``maximum`` and ``limit`` for :meth:`TableReader.number`: the constant ``name`` of
    :mod:`errpred.constants`."""
    return {"maximum": getattr(K, name), "limit": f"errpred.constants.{name}"}


def _named(limit: str) -> str:
    """`` (NAME)`` for a limit's constant in a message, or nothing."""
    return f" ({limit})" if limit else ""


def _dot(prefix: str, k: str) -> str:
    return f"{prefix}.{k}" if prefix else k


def _kind(v: Any) -> str:
    if isinstance(v, dict):
        return "a table"
    names = {bool: "a boolean", str: "a string", list: "an array", int: "an integer",
             float: "a number"}
    return f"{names.get(type(v), type(v).__name__)} ({v!r})"


def _suggest(k: str, allowed: tuple) -> str | None:
    stem = k.split("_")[0]
    same_stem = [a for a in allowed if a.split("_")[0] == stem]
    if len(same_stem) == 1:
        return same_stem[0]
    close = difflib.get_close_matches(k, allowed, n=1, cutoff=0.6)
    return close[0] if close else None


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
