"""Reading TOML files: typed values whose every error names the file and the dotted key.

:class:`TableReader` reads a TOML file (:meth:`TableReader.load`) and gives
numbers (finite unless asked otherwise, with a sign and an upper bound), whole
numbers, strings, arrays of numbers, tables and file paths out of it; whatever is
wrong raises the reader's error class (:class:`nc.errors.TableError` or a
subclass, an :class:`nc.errors.InputError`) as ``FILE: KEY: what was expected``.
Every TOML file of the project is read through it: machine files
(:mod:`nc.machine_files`, raising ``MachineFileError``), errpred's scenarios
(``errpred.tables``, ``ScenarioError``) and orient's planning sections.
"""

from __future__ import annotations

import difflib
import math
import os
import tomllib
from pathlib import Path
from typing import Any

from .errors import TableError

__all__ = ["TableReader", "value_kind"]

_MISSING = object()


class TableReader:
    """Typed access to one TOML file's tables; every error names file and key.

    Parameters
    ----------
    path : str or path-like
        The TOML file; relative paths inside it (:meth:`path`) are relative to its
        folder.

    Subclasses set :attr:`error`, the class raised (called as ``error(file, key,
    message)``).
    """

    error: type[TableError] = TableError

    def __init__(self, path: str | os.PathLike) -> None:
        self.file = os.fspath(path)
        self.base = Path(self.file).resolve().parent

    def fail(self, key: str | None, message: str) -> TableError:
        """The error (not raised) naming this file, ``key`` (None: the whole file)."""
        return self.error(self.file, key, message)

    def load(self, what: str = "file") -> dict:
        """The parsed file; a missing file (``what`` names it), another OS error, or
        text that is not TOML (or not UTF-8) is refused naming the file."""
        try:
            with open(self.file, "rb") as fh:
                return tomllib.load(fh)
        except FileNotFoundError:
            raise self.fail(None, f"{what} not found: {Path(self.file).resolve()}") from None
        except OSError as exc:
            raise self.fail(None, f"cannot read: {exc.strerror or exc}") from None
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise self.fail(None, f"not valid TOML: {exc}") from None

    def table(self, value: Any, key: str) -> dict:
        """``value`` if it is a table (the one at ``key``)."""
        if not isinstance(value, dict):
            raise self.fail(key, f"expected a table ([{key}]), got {value_kind(value)}")
        return value

    def keys(self, d: dict, prefix: str, required: tuple, optional: tuple = ()) -> None:
        """Refuse a key of table ``d`` (at ``prefix``) that is neither required nor
        optional (with a suggestion), then a required one that is missing."""
        allowed = tuple(required) + tuple(optional)
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
               sign: str = "", maximum: float = math.inf, limit: str = "",
               allow_inf: bool = False) -> float:
        """A finite number (``sign``: ``">0"`` or ``">=0"``) at most ``maximum`` in
        magnitude (the constant ``limit`` names it in the message); with
        ``allow_inf``, infinity too (never NaN)."""
        key = _dot(prefix, k)
        if not self.given(d, k, key, default):
            return default
        v = d[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.fail(key, f"expected a number, got {value_kind(v)}")
        v = float(v)
        if math.isnan(v) or (math.isinf(v) and not allow_inf):
            raise self.fail(key, f"expected a {'' if allow_inf else 'finite '}number, got {v}")
        if (sign == ">0" and v <= 0) or (sign == ">=0" and v < 0):
            raise self.fail(key, f"expected a value {sign[:-1]} 0, got {v:g}")
        if abs(v) > maximum and not (allow_inf and math.isinf(v)):
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
            raise self.fail(key, f"expected a whole number, got {value_kind(v)}")
        if v < minimum:
            raise self.fail(key, f"expected a whole number >= {minimum}, got {v}")
        if v > maximum:
            raise self.fail(key, f"expected at most {maximum:g}{_named(limit)}, got {v}")
        return v

    def string(self, d: dict, k: str, prefix: str, *, default: Any = _MISSING,
               choices: tuple = ()) -> str:
        """A string, one of ``choices`` when given."""
        key = _dot(prefix, k)
        if not self.given(d, k, key, default):
            return default
        v = d[k]
        if not isinstance(v, str):
            raise self.fail(key, f"expected a string, got {value_kind(v)}")
        if choices and v not in choices:
            raise self.fail(key, f"unknown value {v!r}; expected one of "
                                 f"{', '.join(map(repr, choices))}")
        return v

    def numbers(self, d: dict, k: str, prefix: str, *, default: Any = _MISSING,
                length: int | None = None, sign: str = "", maximum: float = math.inf,
                limit: str = "", allow_inf: bool = False) -> list[float]:
        """A non-empty array of numbers (``length`` of them when given), each as
        :meth:`number` reads it; the element's key is ``prefix.k[i]``."""
        key = _dot(prefix, k)
        if not self.given(d, k, key, default):
            return default
        v = d[k]
        if not isinstance(v, list) or not v:
            raise self.fail(key, f"expected a non-empty array of numbers, got {value_kind(v)}")
        if length is not None and len(v) != length:
            raise self.fail(key, f"expected {length} numbers, got {len(v)}")
        return [self.number({f"{k}[{i}]": x}, f"{k}[{i}]", prefix, sign=sign,
                            maximum=maximum, limit=limit, allow_inf=allow_inf)
                for i, x in enumerate(v)]

    def path(self, d: dict, k: str, prefix: str) -> Path:
        """An existing file named by a string, relative to this file's folder."""
        key = _dot(prefix, k)
        v = self.string(d, k, prefix)
        p = (self.base / v).resolve()
        if not p.is_file():
            raise self.fail(key, f"file not found: {p}")
        return p


def value_kind(v: Any) -> str:
    """What a TOML value is, for a message: ``an integer (3)``, ``a table``..."""
    if isinstance(v, dict):
        return "a table"
    names = {bool: "a boolean", str: "a string", list: "an array", int: "an integer",
             float: "a number"}
    return f"{names.get(type(v), type(v).__name__)} ({v!r})"


def _named(limit: str) -> str:
    """`` (NAME)`` for a limit's constant in a message, or nothing."""
    return f" ({limit})" if limit else ""


def _dot(prefix: str, k: str) -> str:
    return f"{prefix}.{k}" if prefix else k


def _suggest(k: str, allowed: tuple) -> str | None:
    stem = k.split("_")[0]
    same_stem = [a for a in allowed if a.split("_")[0] == stem]
    if len(same_stem) == 1:
        return same_stem[0]
    close = difflib.get_close_matches(k, allowed, n=1, cutoff=0.6)
    return close[0] if close else None
