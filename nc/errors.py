"""Exceptions of the ``nc`` package, and the project's input-error base class.

:class:`InputError` is the one base of every error that reports bad input
(a file, a line, a key, a value), in every package: ``nc``, ``errpred``,
``orient`` and ``sim`` derive their input errors from it. The command lines
(:func:`nc.command.run_command`) report it in one line with exit status 2;
any other exception is a bug and keeps its traceback (exit status 1).
It derives from ``ValueError`` so that callers catching ``ValueError`` keep
working.
"""

from __future__ import annotations

import re

from . import constants as K

__all__ = ["InputError", "NCParseError", "CLFileError", "TableError", "KinematicsError",
           "MachineFileError"]


class InputError(ValueError):
    """Bad input: a file, line, key or value that the project cannot use.

    The message names where (file, line and column, or file and key) and what
    was expected. Every package's input errors derive from this class.
    """


class NCParseError(InputError):
    """A G-code program could not be read.

    ``str(error)`` is one line, ``FILE:LINE:COLUMN: message`` (as the command
    lines print it); :meth:`excerpt` adds the source line and a caret under
    the column, for a caller that wants to show them.

    Parameters
    ----------
    message : str
        What was found and what was expected.
    file : str, optional
        Path or name of the program; ``"<string>"`` for text given directly.
    line : int, optional
        1-based line number in the file.
    column : int, optional
        1-based column of the offending word or character.
    text : str, optional
        The source line (kept as an attribute; shown by :meth:`excerpt`).
    """

    def __init__(
        self,
        message: str,
        *,
        file: str = "<string>",
        line: int | None = None,
        column: int | None = None,
        text: str | None = None,
    ) -> None:
        self.message = message
        self.file = file
        self.line = line
        self.column = column
        self.text = text
        where = file
        if line is not None:
            where += f":{line}"
            if column is not None:
                where += f":{column}"
        super().__init__(f"{_printable(where)}: {_one_line(message)}")

    def excerpt(self, width: int = K.ERROR_EXCERPT_CHARS) -> str:
        """The one-line message, then the source line and a caret under the column.

        Parameters
        ----------
        width : int [characters]
            The source line is cut to this many characters around the column.
        """
        out = str(self)
        if self.text is None:
            return out
        src = self.text.rstrip("\r\n").replace("\t", " ")
        col = self.column
        first = 0
        if len(src) > width:
            first = 0 if col is None else max(0, min(col - 1 - width // 2, len(src) - width))
            src = src[first:first + width]
        out += "\n    " + "".join(c if c.isprintable() else "?" for c in src)
        if col is not None:
            out += "\n    " + " " * (col - 1 - first) + "^"
        return out


_LONG_DIGITS = re.compile(r"\d{%d,}" % (K.ERROR_MAX_DIGITS + 1))


def _printable(text: str) -> str:
    """Control characters (newlines among them) escaped: ``\\n``, ``\\x00``."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def _one_line(text: str) -> str:
    """``text`` on one line: control characters escaped, runs of digits longer
    than ``ERROR_MAX_DIGITS`` shortened, cut at ``ERROR_MAX_CHARS``."""
    out = _LONG_DIGITS.sub(lambda m: f"{m.group()[:8]}...({len(m.group())} digits)",
                           _printable(text))
    if len(out) > K.ERROR_MAX_CHARS:
        out = out[:K.ERROR_MAX_CHARS - 3] + "..."
    return out


class CLFileError(InputError):
    """A cutter-location file could not be read (names file, line, column)."""

    def __init__(self, message: str, *, file: str, line: int | None = None,
                 column: str | None = None) -> None:
        self.message, self.file, self.line, self.column = message, file, line, column
        where = file if line is None else f"{file}:{line}"
        if column is not None:
            where += f" (column {column!r})"
        super().__init__(f"{where}: {message}")


class TableError(InputError):
    """A TOML file's value that cannot be used (:class:`nc.tables.TableReader`).

    The message is ``FILE: KEY: what was expected`` (``FILE: ...`` for the file as
    a whole).

    Attributes
    ----------
    file : str
        The file as given.
    key : str or None
        Dotted key (``tool.diameter_mm``), None for the file as a whole.
    """

    def __init__(self, file: str, key: str | None, message: str) -> None:
        self.file, self.key = file, key
        super().__init__(f"{file}: {key}: {message}" if key else f"{file}: {message}")


class MachineFileError(TableError):
    """A machine definition (TOML) is missing a key or has a bad value."""


class KinematicsError(InputError):
    """A posture cannot be reached: outside axis limits, or no solution.

    Attributes
    ----------
    index : int or None
        Index of the first offending point in the path, when known.
    """

    def __init__(self, message: str, *, index: int | None = None) -> None:
        self.index = index
        super().__init__(message if index is None else f"point {index}: {message}")
