"""How every command line ends: bad input in one line (exit 2), a bug with its
traceback (exit 1), a refused result in one line (exit 1)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

from nc.command import Refused, run_command
from nc.errors import InputError, NCParseError

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")


def _raise(exc):
    def func(args):
        raise exc
    return func


@pytest.mark.parametrize("exc", [
    InputError("s.toml: tool.diameter_mm: expected a value > 0, got -1"),
    NCParseError("unknown word Q", file="p.nc", line=3, column=4),
    FileNotFoundError("nope.nc: no such file"),
    FileExistsError("out: exists and is not a directory"),
    IsADirectoryError("out.nc: is a directory"),
    PermissionError("out.nc: permission denied"),
])
def test_bad_input_is_one_line_and_exit_2(exc, capsys):
    assert run_command(_raise(exc), None) == 2
    err = capsys.readouterr().err
    assert err == f"error: {exc}\n"


def test_refused_is_one_line_and_exit_1(capsys):
    assert run_command(_raise(Refused("p.nc: worse somewhere")), None) == 1
    assert capsys.readouterr().err == "error: p.nc: worse somewhere\n"


@pytest.mark.parametrize("exc", [ValueError("internal: shapes (3,) and (4,)"),
                                 KeyError("x"), ZeroDivisionError("division by zero")])
def test_anything_else_is_not_caught(exc):
    # a ValueError that is not an InputError is a bug, not the user's fault
    with pytest.raises(type(exc)):
        run_command(_raise(exc), None)


def test_internal_value_error_gives_traceback_and_exit_1(tmp_path):
    """An internal (non-input) ValueError inside a real command: a traceback, exit 1."""
    script = tmp_path / "run.py"
    script.write_text(textwrap.dedent("""
        import sys
        import errpred.cli as cli

        def broken(path):  # a bug while loading: not the scenario's fault
            raise ValueError("operands could not be broadcast together")

        cli._scenario = broken
        sys.exit(cli.main(["predict", "any.toml", "-q"]))
    """))
    env = dict(os.environ, PYTHONPATH=os.path.abspath(ROOT))
    r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                       env=env, timeout=120)
    assert r.returncode == 1, r.stderr
    assert "Traceback (most recent call last)" in r.stderr
    assert "ValueError: operands could not be broadcast together" in r.stderr
    assert "error: operands" not in r.stderr
