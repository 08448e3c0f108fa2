"""Shared fixtures: real external tools are used when present, else skipped."""

from __future__ import annotations

import pytest
from hypothesis import settings

from nc.linuxcnc import rs274_path

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
