"""A light copy of the bundled thin wall for the job's tests: its first three passes, a
coarse lead/tilt grid, one wall mode instead of the finite elements."""

from __future__ import annotations

from pathlib import Path

from tests.thin_wall import thin_wall_copy, wall_mode

#: Lines of the bundled CAM program kept: the header and the first three passes.
PASSES_LINES = 124
EDITS = {
    "grid = [17, 17]": "grid = [9, 9]",
    "[orient]\n": "[orient]\nverify_sdm = false\n",
}


def light_scenario(folder: Path, edits: dict | None = None) -> Path:
    """Write the light scenario into ``folder`` (created) and return its TOML path."""
    return thin_wall_copy(folder, {**EDITS, **(edits or {})}, wall_mode(2.0e7),
                          cam_lines=PASSES_LINES)
