"""A light copy of the bundled thin wall for the job's tests: its first three passes, a
coarse lead/tilt grid, one wall mode instead of the finite elements."""

from __future__ import annotations

import shutil
from pathlib import Path

from orient.scenario import bundled_scenario

#: Lines of the bundled CAM program kept: the header and the first three passes.
PASSES_LINES = 124
EDITS = {
    "grid = [17, 17]": "grid = [9, 9]",
    "[orient]\n": "[orient]\nverify_sdm = false\n",
}
WALL = """[workpiece]
source = "one wall mode along the normal (test)"

[[workpiece.modes]]
direction = [0.0, 1.0, 0.0]
frequency_hz = 3500.0
damping_ratio = 0.01
stiffness_N_m = 2.0e7
"""


def light_scenario(folder: Path, edits: dict | None = None) -> Path:
    """Write the light scenario into ``folder`` (created) and return its TOML path."""
    src = bundled_scenario("thin-wall").parent
    shutil.copytree(src, folder)
    cam = (src / "cam.nc").read_text().splitlines()
    (folder / "cam.nc").write_text("\n".join(cam[:PASSES_LINES] + ["M5", "M30"]) + "\n")
    text = (folder / "scenario.toml").read_text()
    for a, b in {**EDITS, **(edits or {})}.items():
        assert a in text, a
        text = text.replace(a, b, 1)
    text = text[:text.index("[workpiece]")] + WALL
    (folder / "scenario.toml").write_text(text)
    return folder / "scenario.toml"
