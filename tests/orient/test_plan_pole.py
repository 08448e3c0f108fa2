"""The planner keeps the tool axis off the machine's pole (``[orient] pole_floor_deg``).

A plate whose top rises 3 deg toward +X, finished by a 3-axis raster along +X (the
tool vertical) on a B/C head-table machine. Below 5 deg of inclination the CAM
posture is refused, and with every posture stable the planner prefers the one
nearest the CAM's: 5 deg from the normal, leaning back, which is 2 deg from
vertical -- the machine's pole (B = 0), where C is undefined and nc's writer turns
it while the tip stands. With the floor every planned axis keeps at least the floor
from the pole; without it (the default, 0) the same plan goes within it (the scenario
bites).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from nc.errors import InputError
from orient.plan import plan
from orient.scenario import load_plan_scenario

LEAN_DEG = 3.0                      # the plate top rises toward +X [deg]
R_BALL = 5.0


def _plate(lean_deg: float, top_mm: float):
    """A plate 60 x 40 x 10 mm whose top (``top_mm`` above the origin at x = 0) rises
    ``lean_deg`` [deg] toward +X."""
    import trimesh

    box = trimesh.creation.box(extents=(60.0, 40.0, 10.0))
    box.apply_translation((0.0, 0.0, top_mm - 5.0))
    box.apply_transform(trimesh.transformations.rotation_matrix(
        math.radians(-lean_deg), (0.0, 1.0, 0.0)))
    assert box.is_watertight and box.volume > 0
    return box


def _scenario(folder: Path, orient_extra: str = "") -> Path:
    """Write the leaning plate's scenario; returns its TOML path."""
    from nc.kinematics import get_machine
    from nc.path import CutterLocations
    from nc.writer import PostOptions, write_program

    folder.mkdir(parents=True, exist_ok=True)
    _plate(LEAN_DEG, 0.0).export(folder / "design.stl")
    _plate(LEAN_DEG, 0.15).export(folder / "stock.stl")
    a = math.radians(LEAN_DEG)
    n = np.array([-math.sin(a), 0.0, math.cos(a)])     # the top rises toward +X
    tips, rapid = [], []
    for y in (-3.0, -2.5):                                 # two passes along +X
        xs = np.arange(-10.0, 10.01, 1.0)
        centres = np.c_[xs, np.full_like(xs, y), xs * math.tan(a)] + R_BALL * n \
            * np.ones((len(xs), 1))
        t = centres - [0.0, 0.0, R_BALL]
        tips += [t[0] + [0.0, 0.0, 10.0], *t]
        rapid += [True, *([False] * len(t))]
    tips = np.array(tips)
    cl = CutterLocations.from_arrays(tips, np.tile([0.0, 0.0, 1.0], (len(tips), 1)),
                                     np.where(rapid, np.nan, 1600.0), 10000.0,
                                     rapid=np.array(rapid))
    write_program(folder / "cam.nc", cl, get_machine("xyzbc-head-table"),
                  PostOptions(dialect="linuxcnc", source="leaning plate CAM"))
    (folder / "scenario.toml").write_text(f"""name = "leaning-plate"
description = "Plate leaning 3 deg, vertical 3-axis raster, head-table B/C (tests)."

[stock]
stl = "stock.stl"
design_stl = "design.stl"

[tool]
type = "ball"
diameter_mm = 10.0
flutes = 2
helix_deg = 30.0
flute_length_mm = 15.0
overhang_mm = 35.0
rotation = "cw"
shank_diameter_mm = 10.0

[program]
gcode = "cam.nc"
machine = "xyzbc-head-table"

[cutting]
Ktc_N_mm2 = 3680.0
Krc_N_mm2 = 1470.0
Kac_N_mm2 = 550.0
Kte0_N_mm = 37.7
Kre0_N_mm = 45.2
Kae0_N_mm = 11.3

[dynamics]
model = "dynamic"

[[dynamics.modes]]
direction = "x"
frequency_hz = 3600.0
damping_ratio = 0.05
stiffness_N_m = 5.0e7

[[dynamics.modes]]
direction = "y"
frequency_hz = 3700.0
damping_ratio = 0.05
stiffness_N_m = 5.0e7

[orient]
lead_deg = [-20.0, 20.0]
tilt_deg = [-20.0, 20.0]
grid = [9, 9]
verify_sdm = false
{orient_extra}
[orient.cut]
depth_mm = 0.15
pick_mm = 0.5
machined_side = [0.0, -1.0, 0.0]
""")
    return folder / "scenario.toml"


def _pole_deg(axes: np.ndarray) -> np.ndarray:
    """Angle between tool axes and the head-table machine's C axis (+Z) [deg]."""
    return np.degrees(np.arccos(np.clip(np.abs(axes[:, 2]), -1.0, 1.0)))


@pytest.fixture(scope="module")
def plans(tmp_path_factory):
    root = tmp_path_factory.mktemp("pole")
    on = plan(load_plan_scenario(_scenario(root / "on", "pole_floor_deg = 5.0\n")))
    off = plan(load_plan_scenario(_scenario(root / "off")))          # the default: no floor
    return on, off


def test_without_the_floor_the_plan_goes_near_the_pole(plans):
    _, off = plans
    idx = off.touching_index
    assert len(idx) > 30
    assert _pole_deg(off.cl.axis[idx]).min() < 4.0


def test_with_the_floor_every_planned_axis_keeps_off_the_pole(plans):
    on, _ = plans
    idx = on.touching_index
    assert len(on.infeasible) == 0
    feed = ~on.cl.rapid
    assert _pole_deg(on.cl.axis[feed]).min() >= 5.0 - 1e-6
    # the candidates near the pole are refused for that reason, the inclination still held
    incl = np.degrees(np.arccos(np.clip(np.sum(on.cl.axis[idx] * on.contacts.normal[idx],
                                               axis=1), -1, 1)))
    assert incl.min() >= 5.0 - 1e-6
    assert all("pole" not in on.reason[i] or "CAM posture" in on.reason[i] for i in idx)


def test_the_written_program_keeps_b_off_zero(plans):
    """Read back, the planned program's B stays at the floor or beyond, nothing is held at
    the singularity, and C does not turn where the tip stands."""
    from nc.gcode import parse_program
    from nc.kinematics import solve_path
    from nc.path import cutter_locations
    from nc.writer import PostOptions, post

    res = plans[0]
    text = post(res.cl, res.machine, PostOptions(dialect="linuxcnc")).text
    back = cutter_locations(parse_program(text, file="<pole>"), res.machine)
    feed = ~back.rapid
    sol = solve_path(res.machine, back.tip[feed], back.axis[feed])
    assert not sol.singular.any()
    assert np.degrees(np.abs(sol.joints[:, 3])).min() >= 5.0 - 1e-3     # |B| >= the floor
    step = np.linalg.norm(np.diff(back.tip[feed], axis=0), axis=1)
    dc = np.degrees(np.abs(np.diff(sol.joints[:, 4])))
    assert dc[step < 1e-3].max(initial=0.0) < 1e-6


def test_pole_floor_is_checked_at_load(tmp_path):
    for bad in ("-1.0", "90.0", '"5"'):
        path = _scenario(tmp_path / bad.strip('"-.'), f"pole_floor_deg = {bad}\n")
        with pytest.raises(InputError, match="pole_floor_deg"):
            load_plan_scenario(path)
