"""The flexible-wall planning scenario of issue 16, made reproducibly for tests.

A rib like the bundled thin wall (``orient/scenarios/thin-wall``, the same
generator: ``scripts/make_orient_scenarios.py``) but 40 mm high and 2.5 mm
thick, finished with a D6 ball end mill on a head-table B/C machine
(``xyzbc-head-table``): one-way passes along +X, 0.5 mm apart in Z from the
top down, the tool axis inclined 30 deg from the wall normal toward +Z.

The tool: a D6 two-flute carbide ball end mill, 12 mm of flutes (2 D, the usual
length of a finishing ball), 40 mm gauge from a shrink-fit holder (21 mm nose,
the HSK63 shrink chucks' for a 6 mm shank): long enough that the holder stays
above a 40 mm wall's top whatever the posture the planner tries. Its modes are
representative, not measured: a clamped carbide bar D6 x 40 mm alone has
k = 3 E I / L^3 = 1.8e6 N/m and f1 = 3.4 kHz; the holder and the spindle in
series about halve the stiffness and lower the frequency (the bundled D10 x 35
mm: 3.4e7 N/m alone, 1.6e7 N/m given).
"""

from __future__ import annotations

import dataclasses
import importlib.util
import sys
from pathlib import Path

from tests.thin_wall import thin_wall_copy

ROOT = Path(__file__).resolve().parents[2]

#: Wall height, thickness, stock left on it [mm].
HEIGHT_MM, THICKNESS_MM, ALLOWANCE_MM = 40.0, 2.5, 0.2
#: Ball radius of the D6 tool [mm].
R_BALL_MM = 3.0
#: The tool's overhang: the machine's tool length its CAM program is written with, as
#: the scenario's readers resolve the machine
#: (:meth:`errpred.scenario.Scenario.resolve_machine`) [mm].
OVERHANG_MM = 40.0
#: Spindle speed and feed: 12000 rev/min (210 m/min on a D6 ball's equator, carbide in
#: P20) and 1440 mm/min (fz 0.06 mm, two flutes) [rev/min, mm/min].
SPINDLE_RPM, FEED_MM_MIN = 12000.0, 1440.0
#: The machine of the report.
MACHINE = "xyzbc-head-table"


def _generator():
    """``scripts/make_orient_scenarios.py`` as a module (registered in ``sys.modules``, as
    its dataclass needs)."""
    name = "make_orient_scenarios"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(
            name, ROOT / "scripts" / "make_orient_scenarios.py")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
    return sys.modules[name]


def flexible_rib(passes: int | None = None, machine: str = MACHINE):
    """The rib and its CAM program (:class:`make_orient_scenarios.Rib`).

    Parameters
    ----------
    passes : int, optional
        Keep only the first (top) passes; default: top (Z 39.5) down to Z 6, as the
        bundled thin wall's program goes to 6 mm above the plate.
    machine : str
        Named machine the CAM program is written for.
    """
    gen = _generator()
    # contacts from x = -4 to 64: the D6 ball clear of the rib at both ends (as the
    # bundled D10's -6 to 66)
    rib = dataclasses.replace(gen.THIN_WALL, wall_h=HEIGHT_MM, wall_t=THICKNESS_MM,
                              allowance=ALLOWANCE_MM, r_ball=R_BALL_MM,
                              z_top=HEIGHT_MM - 0.5, x_start=-4.0, x_end=64.0,
                              spindle_rpm=SPINDLE_RPM, feed_mm_min=FEED_MM_MIN,
                              machine=machine, tool_length_mm=OVERHANG_MM)
    if passes is not None:
        rib = dataclasses.replace(rib, z_low=rib.z_top - (passes - 1) * rib.pick)
    return gen, rib


def flexible_wall(folder: Path, *, passes: int | None = None, machine: str = MACHINE,
                  edits: dict | None = None, workpiece: str | None = None) -> Path:
    """Write the flexible-wall scenario into ``folder`` (created); returns its TOML path.

    Parameters
    ----------
    folder : Path
        Must not exist yet.
    passes : int, optional
        Only the first (top) passes of the CAM program (a short test).
    machine : str
        Named machine of the program and the scenario.
    edits : dict, optional
        Further text replacements of the scenario file (each must be present).
    workpiece : str, optional
        A ``[workpiece]`` table replacing the finite elements of the wall
        (:func:`tests.thin_wall.wall_mode`), for tests that need no FEM.
    """
    gen, rib = flexible_rib(passes, machine)
    stock_t = THICKNESS_MM + ALLOWANCE_MM
    toml = thin_wall_copy(folder, {
        'name = "thin-wall"': 'name = "flexible-wall"',
        'description = "A steel rib 60 mm long, 30 mm high, 3.5 mm thick':
            'description = "Issue 16\'s flexible wall (tests/sim/flexible_wall.py): a steel '
            'rib 60 mm long, 40 mm high, 2.5 mm thick, a D6 ball on xyzbc-head-table. '
            'Otherwise as the bundled thin wall: a steel rib 60 mm long, 30 mm high, 3.5 mm '
            'thick',
        "diameter_mm = 10.0": f"diameter_mm = {2 * R_BALL_MM}",
        "flute_length_mm = 15.0": "flute_length_mm = 12.0",
        "overhang_mm = 35.0": f"overhang_mm = {OVERHANG_MM}",
        "shank_diameter_mm = 10.0": "shank_diameter_mm = 6.0",
        "diameter_mm = 32.0": "diameter_mm = 21.0",
        'machine = "xyzac-trt"': f'machine = "{machine}"',
        'source = "Representative values, not from a measurement: a short carbide D10':
            'source = "Representative values, not from a measurement '
            '(tests/sim/flexible_wall.py): a D6 x 40 mm carbide ball in a shrink-fit holder, '
            'half the stiffness of the clamped bar (1.8e6 N/m, 3.4 kHz). The bundled thin '
            'wall\'s: a short carbide D10',
        "frequency_hz = 3600.0\ndamping_ratio = 0.03\nstiffness_N_m = 1.6e7":
            "frequency_hz = 2800.0\ndamping_ratio = 0.03\nstiffness_N_m = 9.0e5",
        "frequency_hz = 3700.0\ndamping_ratio = 0.03\nstiffness_N_m = 1.7e7":
            "frequency_hz = 2900.0\ndamping_ratio = 0.03\nstiffness_N_m = 9.5e5",
        "range_rpm = [6000.0, 13000.0]": "range_rpm = [8000.0, 16000.0]",
        "origin_mm = [0.0, 20.35, 0.0]":
            f"origin_mm = [0.0, {rib.wall_y0 + stock_t / 2:.2f}, 0.0]",
        "height_mm = 30.0": f"height_mm = {HEIGHT_MM}",
        "thickness_mm = 3.5": f"thickness_mm = {THICKNESS_MM}",
        "stock_thickness_mm = 3.7": f"stock_thickness_mm = {stock_t}",
        **(edits or {})}, workpiece=workpiece)
    gen.write_rib(str(folder), rib, design_title="flexible-wall design: rib 60 x 40 x 2.5 mm",
                  stock_title="flexible-wall stock: rib with 0.2 mm on the +Y face",
                  source=f"flexible-wall CAM default [inclination 30 deg toward +Z, "
                         f"{machine}]")
    return toml
