"""The README's two commands are the ones CI and users run."""

from __future__ import annotations

import os
import re

ROOT = os.path.join(os.path.dirname(__file__), "..")


def _commands():
    text = open(os.path.join(ROOT, "README.md"), encoding="utf-8").read()
    setup = text.split("## Set up and run", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```sh\n(.*?)\n```", setup, flags=re.S)


def test_readme_has_exactly_two_setup_commands():
    cmds = _commands()
    assert len(cmds) == 2
    assert all("\n" not in c and c.startswith("python3 -m venv .venv") for c in cmds)


def test_ci_runs_the_readme_test_command_verbatim():
    test_cmd = _commands()[1]
    ci = open(os.path.join(ROOT, ".ci", "run"), encoding="utf-8").read()
    assert test_cmd in ci.splitlines()


def test_main_command_names_bundled_files_that_exist():
    main_cmd = _commands()[0]
    for path in re.findall(r"\S+\.(?:csv|toml)", main_cmd):
        assert os.path.exists(os.path.join(ROOT, path)), path
