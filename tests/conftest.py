"""Shared fixtures: real external tools are used when present, else skipped."""

from __future__ import annotations

import pytest
from hypothesis import settings

from nc import read_program
from nc.linuxcnc import compare_with_rs274, rs274_path

settings.register_profile("ci", deadline=None, derandomize=True, print_blob=True)
settings.load_profile("ci")


@pytest.fixture(scope="session")
def rs274():
    """Path of LinuxCNC's rs274; skips the test when it is not installed."""
    path = rs274_path()
    if path is None:
        pytest.skip("LinuxCNC's rs274 not installed (Debian: apt-get install "
                    "--no-install-recommends linuxcnc-uspace); .ci/run installs it")
    return path


@pytest.fixture(scope="session")
def lcnc_agrees():
    """``check(path, **read_options)``: rs274 and this reader agree on a file.

    For tests whose subject is not rs274 but that write LinuxCNC programs:
    when rs274 is installed (always in CI) every such program is checked;
    when it is not, the check is a no-op and the test's own assertions run.
    """
    def check(path, **options):
        if rs274_path() is None:
            return None
        result = compare_with_rs274(path, read_program(path, **options))
        assert result.ok, result.message
        return result
    return check
