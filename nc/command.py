"""How every command line of the project ends (``nc``, ``errpred``, ``orient``, ``sim``).

A result the command refuses (:class:`Refused`: a program that must not be cut)
ends in one line ``error: ...`` on stderr and exit status 1.

Bad input -- an :class:`nc.errors.InputError` (the one base class of every
package's input errors: ``NCParseError``, ``KinematicsError``, ``ScenarioError``,
``MeshFileError``, ...) or a file that is missing, exists, is a directory or may
not be read -- ends in one line ``error: ...`` on stderr and exit status 2;
output piped into ``head`` and the like ends quietly.

Anything else is a bug, not the user's fault: it is not caught here, so Python
prints its traceback and the exit status is 1.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable

from .errors import InputError

__all__ = ["INPUT_ERRORS", "Refused", "run_command"]

#: Exceptions that mean bad input, not a bug: the project's input errors and the
#: operating system's answers about a file named on the command line or in a scenario.
INPUT_ERRORS: tuple[type[BaseException], ...] = (
    InputError, FileNotFoundError, FileExistsError, IsADirectoryError, PermissionError)


class Refused(Exception):
    """The command ran and refuses its result: a program that must not be cut (worse
    than its original somewhere, a colliding posture, a rapid move into material, a
    failed check). Ends in one line ``error: ...`` and exit status 1; nothing that
    would be cut is written."""


def run_command(func: Callable[[argparse.Namespace], int], args: argparse.Namespace,
                extra: tuple[type[BaseException], ...] = ()) -> int:
    """``func(args)``, with bad input (``INPUT_ERRORS`` and ``extra``) reported in one line.

    Any other exception (a ``ValueError`` that is not an :class:`~nc.errors.InputError`
    included) propagates: a bug, shown with its traceback, exit status 1.

    Returns
    -------
    int
        ``func``'s exit status; 2 for bad input; 1 when the command refused its
        result (:class:`Refused`); 0 when stdout was closed early.
    """
    try:
        return func(args)
    except Refused as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except (*INPUT_ERRORS, *extra) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into head & co.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0

