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

__all__ = ["InputError", "NCParseError", "CLFileError", "KinematicsError", "MachineFileError"]


class InputError(ValueError):
    """Bad input: a file, line, key or value that the project cannot use.

    The message names where (file, line and column, or file and key) and what
    was expected. Every package's input errors derive from this class.
    """


class NCParseError(InputError):
    """A G-code program could not be read.

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
        The source line, shown under the message with a caret.
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
        super().__init__(self._format())

    def _format(self) -> str:
        where = self.file
        if self.line is not None:
            where += f":{self.line}"
            if self.column is not None:
                where += f":{self.column}"
        out = f"{where}: {self.message}"
        if self.text is not None:
            out += "\n    " + self.text.rstrip("\r\n").replace("\t", " ")
            if self.column is not None:
                out += "\n    " + " " * (self.column - 1) + "^"
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


class MachineFileError(InputError):
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
