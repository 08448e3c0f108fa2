"""Copies of the bundled thin-wall planning scenario, edited for tests (orient and sim)."""

from __future__ import annotations

import shutil
from pathlib import Path

from orient.scenario import bundled_scenario


def wall_mode(stiffness_N_m: float) -> str:
    """A ``[workpiece]`` table of one wall mode along the normal, instead of the FEM."""
    return f"""[workpiece]
source = "one wall mode along the normal (test)"

[[workpiece.modes]]
direction = [0.0, 1.0, 0.0]
frequency_hz = 3500.0
damping_ratio = 0.01
stiffness_N_m = {stiffness_N_m:.1e}
"""


def thin_wall_copy(folder: Path, edits: dict | None = None, workpiece: str | None = None,
                   cam_lines: int | None = None) -> Path:
    """Copy the bundled thin wall into ``folder`` (created) and return its TOML path.

    ``edits``: text replacements of the scenario file (each must be present);
    ``workpiece``: a table replacing ``[workpiece]`` (default: kept); ``cam_lines``:
    keep only this many lines of the CAM program, then end it.
    """
    shutil.copytree(bundled_scenario("thin-wall").parent, folder)
    if cam_lines is not None:
        cam = (folder / "cam.nc").read_text().splitlines()
        (folder / "cam.nc").write_text("\n".join(cam[:cam_lines] + ["M5", "M30"]) + "\n")
    text = (folder / "scenario.toml").read_text()
    for a, b in (edits or {}).items():
        assert a in text, a
        text = text.replace(a, b, 1)
    if workpiece is not None:
        text = text[:text.index("[workpiece]")] + workpiece
    (folder / "scenario.toml").write_text(text)
    return folder / "scenario.toml"
