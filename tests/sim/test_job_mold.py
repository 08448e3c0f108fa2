"""The main job's second bundled scenario, ``orient/scenarios/mold-core``: errpred's
mold-ball core finished from its 3-axis raster operation on a head-table machine.

The whole scenario is too long for the suite (README, "The main job"); here: the
scenario is what it says (the raster operation of errpred's program, at least 10,000
cutter locations, the machine, the rigid part), and the job page shows a free-form part
from above and a wall from the side."""

from __future__ import annotations

import numpy as np
import pytest

from nc.path import cutter_locations
from orient.scenario import bundled_scenario, load_plan_scenario
from sim.job_plots import error_map_png
from sim.job_report import _map_view

ERRPRED_PROGRAM = "errpred/scenarios/mold-ball/finish.nc"


@pytest.fixture(scope="module")
def mold():
    return load_plan_scenario(bundled_scenario("mold-core"))


def test_mold_core_is_the_raster_operation_of_errpreds_mold_ball(mold):
    from errpred.scenario import bundled_scenario as errpred_bundled
    from errpred.scenario import load_scenario

    ball = load_scenario(errpred_bundled("mold-ball"))
    # the same part, tool and data as errpred's (meshes referenced, not copied)
    assert mold.base.stock.path == ball.stock.path
    assert mold.base.stock.design_path == ball.stock.design_path
    assert mold.base.tool == ball.tool
    assert mold.base.coefficients == ball.coefficients
    # the program: finish.nc's raster lines, line L here is line L + 13820 there
    raster = mold.base.program_path.read_text().splitlines()
    finish = ball.program_path.read_text().splitlines()
    assert raster[15:] == finish[13835:]
    assert mold.machine().name == "xyzbc-head-table"
    assert mold.workpiece.kind == "rigid"
    cl = cutter_locations(mold.base.read_program(), mold.machine())
    assert len(cl) >= 10_000
    # a 3-axis program: the tool along Z, the tips the program's X Y Z
    assert np.allclose(cl.axis, [0.0, 0.0, 1.0])
    cut = mold.options.cut
    assert (cut.depth_mm, cut.pick_mm) == (0.15, 0.35)


def test_error_map_is_seen_from_above_on_a_free_form_part_and_from_the_side_on_a_wall():
    rng = np.random.default_rng(3)
    # a dome: normals mostly up
    p = rng.uniform(-10, 10, (200, 3))
    n = np.c_[0.2 * p[:, :2] / 10, np.ones(200)]
    n /= np.linalg.norm(n, axis=1)[:, None]
    assert _map_view(n, p)[0] == (0, 1)
    # a wall along Y: normals along X
    w = np.c_[np.zeros(200), rng.uniform(0, 60, 200), rng.uniform(0, 30, 200)]
    assert _map_view(np.tile([1.0, 0.0, 0.0], (200, 1)), w)[0] == (1, 2)
    png = error_map_png([("a", p, rng.normal(size=200))], 0, 1)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_job_takes_a_bundled_scenarios_name(tmp_path, monkeypatch):
    from sim.job_cli import _scenario_path

    assert _scenario_path("mold-core") == bundled_scenario("mold-core")
    assert _scenario_path(None) == bundled_scenario("thin-wall")
    # a file of that name in the working folder wins
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mold-core").write_text("")
    assert _scenario_path("mold-core").name == "mold-core"


def mold_slice(folder, first: int, last: int, edits: dict | None = None, *,
               speed_choice: bool = True):
    """The mold-core scenario on raster.nc's lines ``first``-``last`` (whole raster runs)
    after its header, written into ``folder`` (without ``[orient.spindle]`` unless
    ``speed_choice``); returns the TOML's path."""
    src = bundled_scenario("mold-core")
    lines = (src.parent / "raster.nc").read_text().splitlines()
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "slice.nc").write_text("\n".join(lines[:15] + lines[first - 1:last]
                                               + ["M9", "M5", "G0 Z50", "M30", "%"]) + "\n")
    text = src.read_text().replace("../../../errpred/", f"{src.parents[3].as_posix()}/errpred/")
    text = text.replace('gcode = "raster.nc"', 'gcode = "slice.nc"')
    if not speed_choice:
        text = text.split("[orient.spindle]")[0]
    for a, b in (edits or {}).items():
        assert a in text, a
        text = text.replace(a, b)
    (folder / "scenario.toml").write_text(text)
    return folder / "scenario.toml"


#: one raster pass over the saddle's top and the base (Y 20.15; raster.nc lines
#: 5283-5368: the pass's runs and their links), planned on a coarse grid without the
#: speed choice and the time-periodic check, so that it takes seconds
SADDLE_PASS = (5283, 5368)
FAST = {"grid = [15, 15]": "grid = [7, 7]\nverify_sdm = false"}


def test_the_planner_on_a_free_form_pass_keeps_the_ball_centre_within_limits(tmp_path):
    from orient.plan import plan

    scn = load_plan_scenario(mold_slice(tmp_path, *SADDLE_PASS, FAST,
                                                speed_choice=False))
    res = plan(scn)
    idx = res.touching_index
    assert idx.size > 40 and res.infeasible.size == 0
    R = scn.base.tool.radius_mm
    np.testing.assert_allclose(res.cl.tip[idx] + R * res.cl.axis[idx],
                               res.contacts.centre[idx], atol=1e-9)
    incl = np.degrees(np.arccos(np.clip(np.sum(res.cl.axis[idx] * res.contacts.normal[idx],
                                               axis=1), -1, 1)))
    assert incl.min() >= 5.0 - 1e-6 and incl.max() <= 60.0 + 1e-6
    # the 3-axis CAM posture has the ball's tip cutting on the flat base (inclination
    # below 5 deg): the planner tilts away from it there
    cam = np.degrees(np.arccos(np.clip(res.contacts.normal[idx, 2], -1, 1)))
    assert np.any(cam < 5.0)
    assert np.all(np.isfinite(res.margin[idx]) & (res.margin[idx] > 0))
