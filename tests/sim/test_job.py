"""The main job on a light copy of the bundled thin wall (its first three passes): one
process and a two-worker Dask LocalCluster give the same report and program; the report's
figures hold; the page opens in Chromium; bad scenario files end in one line and leave
nothing behind.

The light copy does not pass every check (its plan chatters lightly in the simulated
machine and its surface ratio misses 25 %; the bundled default passes them), so the job
ends with exit status 1, one line naming the failed checks, and its programs written as
``*.NOT-FOR-CUTTING.nc``: the refusal is tested here too."""

from __future__ import annotations

import html
import json

import pytest

from sim.cli import main as sim_main

from tests.chromium import open_page
from .job_scenario import light_scenario


def _without_times(rep: dict) -> dict:
    return {k: v for k, v in rep.items() if k != "seconds"}


FINAL = "thin-wall.NOT-FOR-CUTTING.nc"
PLANNED = "thin-wall-planned.NOT-FOR-CUTTING.nc"


@pytest.fixture(scope="module")
def jobs(tmp_path_factory):
    root = tmp_path_factory.mktemp("job")
    scn = light_scenario(root / "scn")
    one, two = root / "one-process", root / "local-cluster"
    assert sim_main(["job", str(scn), "--out", str(one), "--no-dask"]) == 1
    assert sim_main(["job", str(scn), "--out", str(two), "--dask", "2"]) == 1
    return scn, one, two


def test_failed_checks_mark_the_programs_not_for_cutting(jobs):
    _, one, _ = jobs
    rep = json.loads((one / "report.json").read_text())
    failed = sorted(k for k, v in rep["checks"].items() if not v)
    assert failed == ["no_chatter_in_simulation", "surface_error_reduced_to_25pct"]
    # one line each, why: the figures the report holds
    why = rep["checks_why"]
    assert sorted(why) == failed and all(w and "\n" not in w for w in why.values())
    sim = rep["simulation"]
    assert why["no_chatter_in_simulation"].startswith(
        f"{sim['corrected']['sustained_chatter_episodes']} sustained chatter episode(s)")
    assert f"(ratio {sim['surface_rms_ratio']})" in why["surface_error_reduced_to_25pct"]
    page = html.unescape((one / "report.html").read_text())
    assert all(w in page for w in why.values())
    for name in (FINAL, PLANNED):
        first = (one / name).read_text().splitlines()[:2]
        assert any(ln.startswith("(NOT FOR CUTTING: the job's checks failed: ") and
                   all(f in ln for f in failed) for ln in first), first
    assert not (one / "thin-wall.nc").exists() and not (one / "thin-wall-planned.nc").exists()


def test_local_cluster_gives_the_same_report_and_program(jobs):
    _, one, two = jobs
    a = json.loads((one / "report.json").read_text())
    b = json.loads((two / "report.json").read_text())
    assert _without_times(a) == _without_times(b)
    assert (one / FINAL).read_text() == (two / FINAL).read_text()
    assert sorted(p.name for p in one.iterdir()) == sorted(["report.html", "report.json",
                                                            PLANNED, FINAL])


@pytest.mark.xfail(strict=True, reason=(
    "known gap: on the light copy (its first three passes) the simulated RMS after "
    "correction is 31.0 % of before (2.22 of 7.18 um; predicted 0.30 of 5.25 um): its "
    "plan chatters lightly (one sustained episode, the marks the correction does not "
    "remove) and the top pass, a third of its points, holds half the corrected run's "
    "squared error (figures from before the simulated cut came from the part). The "
    "bundled default holds it (23.05 %, 1.785 of 7.746 um)."))
def test_the_simulated_surface_error_after_correction_is_a_quarter_of_before(jobs):
    _, one, _ = jobs
    s = json.loads((one / "report.json").read_text())["simulation"]
    assert s["corrected"]["surface_rms_um"] <= 0.25 * s["planned"]["surface_rms_um"]


def test_the_job_plans_corrects_and_verifies(jobs, lcnc_agrees):
    _, one, _ = jobs
    rep = json.loads((one / "report.json").read_text())
    p, c, s = rep["plan"], rep["correction"], rep["simulation"]
    # the CAM posture chatters at the top pass (margin < 1) and the simulated machine,
    # running it, calls chatter in nearly every window; the plan is above 1 everywhere
    assert p["cam_points_below_1"] > 0 and p["points_below_1"] == 0
    # the CAM posture chatters: from the first detection on, nearly every window, and
    # the first detection comes early in the pass
    cam = s["cam_worst_pass"]
    assert cam["chatter_share_after_first"] > 0.9
    assert cam["first_chatter_s"] < 0.5 * cam["machining_s"]
    assert rep["checks"]["margin_above_1_where_cutting"] and rep["checks"]["no_collisions"]
    # the prediction's own error after the correction (verified on the dense points:
    # nowhere worse), and the simulated one's
    assert c["verified"] and c["verification"]["ok"]
    assert rep["checks"]["correction_verified_nowhere_worse"]
    # (the bound was 5 % before the verification: a correction that holds the points
    # where a candidate made the surface worse ends at 6.4 % on this copy)
    assert c["predicted_rms_um"][c["best_pass"]] < 0.1 * c["predicted_rms_um"][0]
    assert c["predicted_max_abs_um"][c["best_pass"]] < 0.5 * c["predicted_max_abs_um"][0]
    # the simulated surface error comes down too (the job's own 25 % check: below)
    assert s["corrected"]["surface_rms_um"] <= 0.5 * s["planned"]["surface_rms_um"]
    assert s["corrected"]["cutter_locations"] == s["planned"]["cutter_locations"]
    # written, read back, accepted by LinuxCNC's interpreter
    assert rep["program"]["round_trip_tip_mm"] < 1e-3
    lcnc_agrees(one / FINAL)
    # the corrected program differs from the planned one by micrometres (and the
    # points inserted where the error changes along a segment)
    planned = (one / PLANNED).read_text().splitlines()
    final = (one / FINAL).read_text().splitlines()
    assert len(final) >= len(planned) and planned != final


def test_report_page_opens_in_headless_chromium(jobs, tmp_path):
    _, one, _ = jobs
    page = one / "report.html"
    text = page.read_text()
    assert "<script" not in text and "http" not in text.replace("http-equiv", "")
    seen = open_page(page, tmp_path)
    assert seen["screenshot_bytes"] > 20_000
    assert "CONSOLE" not in seen["stderr"]
    # margin along the path, lead/tilt and rotary axes, error maps, lobes, spectra: all
    # decoded
    assert seen["images"] == 5 and seen["broken"] == 0
    assert "Error map before and after correction" in seen["dom"]
    assert "Posture along the path" in seen["dom"]
    # each margin curve says at which spindle speed it is; the run table is there once
    plan = json.loads((one / "report.json").read_text())["plan"]
    words = html.unescape(text)
    assert (f"CAM program's spindle speed, {plan['cam_spindle_rpm']:.0f} min^-1" in words
            and f"planned speed, {plan['spindle_rpm']:.0f} min^-1" in words)
    assert text.count("<th>simulated run</th>") == 1


BAD = [
    ("missing key", {"diameter_mm = 10.0\n": ""}, "tool.diameter_mm"),
    ("wrong unit", {"diameter_mm = 10.0": "diameter_in = 10.0"}, "tool.diameter_mm"),
    ("unknown tool type", {'type = "ball"': 'type = "drill"'}, "tool.type"),
    ("file that does not exist", {'gcode = "cam.nc"': 'gcode = "missing.nc"'}, "missing.nc"),
    ("NaN value", {"stiffness_N_m = 1.6e7": "stiffness_N_m = nan"},
     "dynamics.modes[0].stiffness_N_m"),
]


@pytest.mark.parametrize(("what", "edits", "key"), BAD, ids=[b[0] for b in BAD])
def test_bad_scenario_ends_in_one_line_and_writes_nothing(tmp_path, capsys, what, edits, key):
    scn = light_scenario(tmp_path / "scn", edits)
    out = tmp_path / "out"
    assert sim_main(["job", str(scn), "--out", str(out), "--no-dask"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert str(scn) in err[0] and key in err[0], err[0]
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scn"]


def test_one_correction_pass_where_the_scenario_asks_for_it(tmp_path):
    """``[correction] max_iterations = 1``: the job makes one pass, the share of its fit
    the scenario's ``relaxation`` says (as the mold core's), at most the fallbacks'
    predictions after it, and the result is still verified nowhere worse than the
    planned path."""
    from errpred.constants import FALLBACK_SCALINGS
    from orient.scenario import load_plan_scenario
    from sim.job import run_job

    scn = load_plan_scenario(light_scenario(
        tmp_path / "scn", {"[orient]\n": "[correction]\nmax_iterations = 1\nrelaxation = 0.8\n\n[orient]\n"}))
    assert scn.base.correction.max_iterations == 1
    out = tmp_path / "out"
    out.mkdir()
    res = run_job(scn, out)
    v = res.compensation.verified
    assert {p.index for p in v.passes} == {1}
    assert all(p.relaxation == 0.8 for p in v.passes)
    assert 2 <= len(res.compensation.predictions) <= 1 + 1 + FALLBACK_SCALINGS + 1
    assert v.corrected and v.comparison.ok
    assert v.comparison.after.rms_um < v.before_stats.rms_um


def test_the_warm_up_runs_apart_and_a_failure_is_logged(tmp_path, caplog):
    # the warm-up compiles in a child process (its memory ends with it); it gets the
    # scenario through a pipe and this process's sys.path; a failure there is logged
    # with the child's last line of error output and its status returned
    from orient.scenario import load_plan_scenario
    from sim.warmup import warm_apart

    scn = load_plan_scenario(light_scenario(tmp_path / "scn"))
    assert warm_apart(scn, ()) == 0
    with caplog.at_level("WARNING", logger="sim.warmup"):
        assert warm_apart(scn, ("no-such-part",)) != 0
    assert "unknown part 'no-such-part'" in caplog.text


def entries_files(path) -> list[str]:
    """The cache index files a warm-up manifest lists."""
    import pickle

    with open(path, "rb") as fh:
        return pickle.load(fh)[2]


def test_a_warm_up_part_runs_once_then_loads_its_manifest(tmp_path, monkeypatch, caplog):
    # the first time a part runs its kernels and writes the signatures numba compiled,
    # stamped with the sources; then, while the sources are the same, it only asks numba
    # for them (no running); other sources, or a signature that no longer compiles, and
    # it runs again
    import pickle

    import numba

    from orient.scenario import load_plan_scenario
    from sim import warmup

    scn = load_plan_scenario(light_scenario(tmp_path / "scn"))
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path / "cache"))
    ran: list[str] = []
    real = warmup.run_part

    def spy(s, part):
        ran.append(part)
        real(s, part)

    monkeypatch.setattr(warmup, "run_part", spy)
    warmup.warm_kernels(scn, ("margins",))
    assert ran == ["margins"]
    path = warmup.manifest_path("margins")
    assert path.parent == tmp_path / "cache"
    with open(path, "rb") as fh:
        stamp, entries, _files = pickle.load(fh)
    assert stamp == warmup.sources_stamp()
    names = {(m, a) for m, a, sigs in entries if sigs}
    # the one-thread kernel the job's Dask tasks use (the manifest lists every kernel
    # this process has compiled, so other tests' threaded one may be in it too)
    assert ("orient.stability._kernels", "margin_batch_serial") in names

    warmup.warm_kernels(scn, ("margins",))
    assert ran == ["margins"]                   # from the manifest: not run

    # with the manifest current and its kernels' cache index files there, warm_apart
    # starts no child; one index file missing and it does
    assert all(f.endswith(".nbi") for f in entries_files(path))
    started: list = []

    def child(args, **_kw):
        started.append(args)
        return warmup.subprocess.CompletedProcess(args, 0, b"", b"")

    monkeypatch.setattr(warmup.subprocess, "run", child)
    assert warmup.cached(("margins",)) and warmup.warm_apart(scn, ("margins",)) == 0
    assert started == []
    with open(path, "rb") as fh:
        stamp, entries, files = pickle.load(fh)
    with open(path, "wb") as fh:
        pickle.dump((stamp, entries, files + [str(tmp_path / "gone.nbi")]), fh)
    assert not warmup.cached(("margins",))
    assert warmup.warm_apart(scn, ("margins",)) == 0 and len(started) == 1
    monkeypatch.undo()
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(warmup, "run_part", spy)
    # a manifest with a missing index file, or without its index files (the former
    # format), is written again with them when it loads (not run)
    warmup.warm_kernels(scn, ("margins",))
    assert ran == ["margins"] and warmup.cached(("margins",))
    with open(path, "wb") as fh:
        pickle.dump((stamp, entries), fh)
    assert not warmup.cached(("margins",))
    warmup.warm_kernels(scn, ("margins",))
    assert ran == ["margins"] and warmup.cached(("margins",))

    monkeypatch.setattr(warmup, "sources_stamp", lambda: "other sources")
    warmup.warm_kernels(scn, ("margins",))
    assert ran == ["margins", "margins"]

    with open(path, "rb") as fh:
        stamp, entries, _files = pickle.load(fh)
    assert stamp == "other sources"
    entries.append(("orient.stability._kernels", "no_such_kernel", ["int64"]))
    with open(path, "wb") as fh:
        pickle.dump((stamp, entries), fh)
    with caplog.at_level("WARNING", logger="sim.warmup"):
        warmup.warm_kernels(scn, ("margins",))
    assert ran == ["margins"] * 3
    assert "no_such_kernel" in caplog.text and "running the part" in caplog.text
    with pytest.raises(ValueError, match="unknown part 'x'"):
        warmup.warm_kernels(scn, ("x",))


def test_the_sources_stamp_is_the_same_from_any_working_directory(tmp_path):
    # errpred is a namespace package: its path lists the folder again where the
    # working directory holds it; a stamp that counted it twice made a job started
    # from another folder than the last one run the simulated machine's part again
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    code = "from sim.warmup import sources_stamp; print(sources_stamp())"
    env = dict(os.environ, PYTHONPATH=str(root))
    stamps = {subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, check=True,
                             capture_output=True, text=True).stdout.strip()
              for cwd in (root, tmp_path)}
    assert len(stamps) == 1 and len(stamps.pop()) == 64
