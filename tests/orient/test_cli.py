"""``python -m orient``: plan and lobes on a light copy of the thin-wall scenario; bad
scenarios end in one line naming file and key, and nothing is written."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from orient.cli import main
from orient.scenario import ScenarioError, load_plan_scenario
from tests.thin_wall import thin_wall_copy, wall_mode

ROOT = Path(__file__).resolve().parents[2]
LIGHT = {
    "grid = [17, 17]": "grid = [5, 5]",
    "[orient]\n": "[orient]\nverify_sdm = false\n",
}
MODES = wall_mode(6.0e6)


def _copy(tmp_path: Path, edits: dict | None = None, workpiece: str | None = MODES) -> Path:
    return thin_wall_copy(tmp_path / "scn", {**LIGHT, **(edits or {})}, workpiece)


def test_plan_writes_program_report_and_plots(tmp_path, capsys, lcnc_agrees):
    scn = _copy(tmp_path)
    out = tmp_path / "out" / "planned.ngc"
    out.parent.mkdir()
    assert main(["plan", str(scn), "-o", str(out), "--plots", str(tmp_path / "plots")]) == 0
    text = capsys.readouterr().out
    assert "round trip through xyzac-trt" in text and "collisions of the planned postures: 0" \
        in text
    rep = json.loads((tmp_path / "out" / "planned-plan.json").read_text())
    s = rep["summary"]
    assert s["cutting_points"] == sum(p["cutting"] for p in rep["points"]) > 1000
    assert s["margin_min"] >= s["cam_margin_min"]
    pt = next(p for p in rep["points"] if p["cutting"])
    assert {"lead_deg", "tilt_deg", "margin", "cam_margin", "reason", "normal"} <= set(pt)
    assert abs(math.sqrt(sum(a * a for a in pt["axis"])) - 1) < 1e-6
    for png in ("margin_along_path.png", "margin_grid.png"):
        assert (tmp_path / "plots" / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    lcnc_agrees(out)


def test_lobes_plot(tmp_path, capsys):
    """End to end on (a light copy of) the bundled thin wall, on a later pass (so that
    the pick feed enters): both postures' lobes, the time-periodic check, a suggested
    speed inside the range, the limits divided by the safety factor, the plot."""
    scn = _copy(tmp_path)
    png = tmp_path / "lobes.png"
    assert main(["lobes", str(scn), "--plot", str(png), "--speeds", "40",
                 "--rpm", "6000", "12000", "--point", "400", "--safety-factor", "2"]) == 0
    text = capsys.readouterr().out
    assert "CAM posture (lead" in text and "planned posture (lead" in text
    assert "time-periodic check: lowest limit" in text and "lobes command time" in text
    rpm = float(text.split("suggested spindle speed ")[1].split()[0])
    assert 6000 <= rpm <= 12000
    for what in ("depth", "pick feed"):
        line = next(x for x in text.splitlines() if x.startswith(f"largest stable {what} "))
        lim = float(line.split(f"largest stable {what} ")[1].split()[-2 if "at least" in
                                                                        line else 0])
        use = float(line.split("use at most ")[1].split()[-2 if "at least" in
                                                           line.split("use")[1] else 0])
        assert use == pytest.approx(lim / 2, rel=2e-2)
    assert png.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("args, key", [
    (["--rpm", "9000", "6000"], "--rpm"),
    (["--rpm", "0", "6000"], "--rpm"),
    (["--speeds", "1"], "--speeds"),
    (["--safety-factor", "0.5"], "--safety-factor"),
    (["--safety-factor", "nan"], "--safety-factor"),
    (["--point", "0"], "--point"),
])
def test_lobes_bad_options_end_in_one_line(tmp_path, capsys, args, key):
    scn = _copy(tmp_path)
    png = tmp_path / "lobes.png"
    assert main(["lobes", str(scn), "--plot", str(png)] + args) == 2
    msg = capsys.readouterr().err
    assert msg.startswith("error: ") and key in msg and len(msg.strip().splitlines()) == 1
    assert not png.exists()


@pytest.mark.parametrize("edit, key", [
    ({"depth_mm = 0.2": "depth_mm = nan"}, "orient.cut.depth_mm"),
    ({"depth_mm = 0.2": "depth_m = 0.2"}, "orient.cut.depth_m"),
    ({'type = "ball"': 'type = "radius"\ncorner_radius_mm = 1.0'}, "tool.type"),
    ({'design_stl = "design.stl"': 'design_stl = "nowhere.stl"'}, "stock.design_stl"),
    ({"grid = [5, 5]": "grid = [5, 0]"}, "orient.grid"),
    ({"max_rate_deg_per_mm = 2.0": "max_rate_deg_per_mm = -2.0"},
     "orient.max_rate_deg_per_mm"),
])
def test_bad_scenarios_name_file_and_key_and_write_nothing(tmp_path, capsys, edit, key):
    scn = _copy(tmp_path, edit)
    with pytest.raises(ScenarioError) as err:
        load_plan_scenario(scn)
    assert str(scn) in str(err.value) and key in str(err.value)
    out = tmp_path / "o.ngc"
    assert main(["plan", str(scn), "-o", str(out)]) == 2
    msg = capsys.readouterr().err
    assert msg.startswith("error: ") and key in msg and len(msg.strip().splitlines()) == 1
    assert not out.exists() and not (tmp_path / "o-plan.json").exists()


def test_plan_needs_an_output_program_and_is_not_the_job(tmp_path, capsys):
    """``orient plan`` is the planner alone: without ``-o`` one line naming it and the
    main job's command, status 2, nothing written; the job's options are not its own."""
    scn = _copy(tmp_path)
    assert main(["plan", str(scn), "--plots", str(tmp_path / "p")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "-o OUT.nc: missing" in err[0] and "python -m sim job" in err[0]
    for job_only in (["--out", str(tmp_path / "job")], ["--no-dask"]):
        with pytest.raises(SystemExit) as exc:
            main(["plan", str(scn), "-o", str(tmp_path / "p.ngc"), *job_only])
        assert exc.value.code == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scn"]


def test_thin_wall_keys_are_checked(tmp_path):
    scn = _copy(tmp_path, workpiece=None, edits={"normal = [0.0, 1.0, 0.0]":
                                                 "normal = [1.0, 1.0, 0.0]"})
    with pytest.raises(ScenarioError, match="workpiece.thin_wall.normal"):
        load_plan_scenario(scn)


def test_module_runs_as_a_program(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "orient", "plan", "-o",
                           str(tmp_path / "x" / "p.ngc")], capture_output=True, text=True,
                          cwd=ROOT)
    assert proc.returncode == 2 and "does not exist" in proc.stderr


def test_spindle_speed_chosen_from_the_lobes(tmp_path):
    from orient.plan import plan

    scn = load_plan_scenario(_copy(tmp_path, {
        "range_rpm = [6000.0, 13000.0]\nsteps = 71": "range_rpm = [6000.0, 12000.0]\nsteps = 7"}))
    fixed = plan(scn, spindle_rpm=9000.0)
    res = plan(scn)
    speeds = np.linspace(6000.0, 12000.0, 7)
    assert np.min(np.abs(speeds - res.spindle_rpm)) < 1e-9
    feed = ~res.cl.rapid
    np.testing.assert_allclose(res.cl.feed_mm_min[feed],
                               res.cam.feed_mm_min[feed] * res.spindle_rpm / 9000.0)
    idx = res.touching_index
    print("chosen", res.spindle_rpm, "min margin", res.margin[idx].min(), "at 9000:",
          fixed.margin[idx].min())
    assert res.margin[idx].min() >= 0.95 * fixed.margin[idx].min()
    assert np.allclose(res.cam_margin[idx], fixed.cam_margin[idx])   # CAM at CAM's speed


def test_safety_factor_plans_for_a_heavier_cut(tmp_path):
    from orient.pointwise import point_gain, point_setup

    base = load_plan_scenario(_copy(tmp_path / "a"))
    heavy = load_plan_scenario(_copy(tmp_path / "b", {"[orient]\n":
                                                       "[orient]\nsafety_factor = 1.5\n"}))
    g0 = point_gain(base, point_setup(base))
    g1 = point_gain(heavy, point_setup(heavy))
    assert point_setup(heavy).cut.depth_mm == pytest.approx(1.5 * 0.2)
    assert np.linalg.norm(g1.P) > 1.2 * np.linalg.norm(g0.P)
    bad = _copy(tmp_path / "c", {"[orient]\n": "[orient]\nsafety_factor = 0.5\n"})
    with pytest.raises(ScenarioError, match="orient.safety_factor"):
        load_plan_scenario(bad)
