"""``python -m errpred schedule``: per-block feeds from the predicted error and force,
verified by a dense re-prediction of the written program (here again, independently
of the loop that made it), the change per block limited, refused in one line when no
allowed feed keeps a block within; the cycle time before and after; the page.

The slices run on a copy of the bundled scenarios at a coarser resolution (pixel
0.625 mm, 40 micro edges, 4 deg) so that each test stays within ~20 s; the physics is
the same."""

from __future__ import annotations

import math
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from errpred.cli import main
from errpred.pipeline import blocks_in_scope, build_predictor, load
from errpred.schedule import (
    FeedLimits,
    block_loads,
    cycle_time,
    limit_steps,
    schedule_feeds,
)
from errpred.scenario import bundled_scenario
from nc import parse_program
from nc.errors import InputError
from nc.path import block_lengths
from nc.program import RAPID
from tests.chromium import open_page


def _slice(tmp_path: Path, name: str, lines: tuple[int, int], *, no_edge: bool = False
           ) -> Path:
    """A copy of a bundled scenario on ``lines`` at the coarser resolution; with
    ``no_edge`` the edge coefficients (and their wear growth) are 0: the force is then
    the cutting part alone, linear in the feed per tooth."""
    src = bundled_scenario(name).parent
    t = (src / "scenario.toml").read_text()
    for k, f in (("stl", "stock.stl"), ("design_stl", "design.stl"), ("gcode", "finish.nc")):
        t = t.replace(f'{k} = "{f}"', f'{k} = "{src / f}"')
    t = t.replace(f'gcode = "{src / "finish.nc"}"',
                  f'gcode = "{src / "finish.nc"}"\nlines = [{lines[0]}, {lines[1]}]')
    if no_edge:
        t, k = re.subn(r"^(K[tra]e[01]_N_mm2?) = .*$", r"\1 = 0.0", t, flags=re.M)
        assert k == 6
    t += "\n[resolution]\npixel_mm = 0.625\nmicro_edges = 40\nangle_step_deg = 4.0\n"
    out = tmp_path / f"{name}.toml"
    out.write_text(t)
    return out


def _dense(scenario_path: Path, text: str | None = None):
    """The dense prediction, per block, of the scenario's program (or of ``text``, a
    program written from it) over the scenario's lines, and that program."""
    s = load(scenario_path)
    prog = s.read_program() if text is None else parse_program(text, file="written.nc")
    pred = build_predictor(s, prog, s.resolution.dense(), sensitivity=False)
    blocks = np.array(blocks_in_scope(s, prog))
    return prog, blocks[prog.motion[blocks] != RAPID], block_loads(pred.run(blocks), len(prog))


def _factor_steps_within(orig, prog, blocks, step: float) -> None:
    """Consecutive scheduled feed blocks' factors on the programmed feed differ by at most
    ``step`` both ways; from an unscheduled neighbour (factor 1: not predicted, kept as
    programmed) the factor rises by at most ``step`` (it may fall more: a block that must
    slow down cannot wait for a block outside the scope)."""
    r = prog.feed / orig.feed
    for a, b in zip(blocks[:-1], blocks[1:], strict=True):
        if b == a + 1:
            assert r[b] <= r[a] * (1 + step) + 1e-9 and r[a] <= r[b] * (1 + step) + 1e-9
    for inside, outside in ((blocks[0], blocks[0] - 1), (blocks[-1], blocks[-1] + 1)):
        if 0 <= outside < len(prog) and prog.motion[outside] != RAPID:
            assert r[outside] == 1.0 and r[inside] <= 1 + step + 1e-9


# --- the solver alone, on a predictor whose force and error are known in closed form ----


def _fake_predictor(program, k_force, e0, k_err):
    """A 'prediction' with, per feed block b, one point: force k_force[b] * f and error
    e0[b] + k_err[b] * f (f the block's feed)."""

    def predict(prog):
        pts = []
        for b in range(len(prog)):
            if prog.motion[b] == RAPID:
                continue
            f = float(prog.feed[b])
            res = SimpleNamespace(peak_force_N=k_force[b] * f, E_um=e0[b] + k_err[b] * f)
            pts.append(SimpleNamespace(block=b, status="predicted", result=res))
        return SimpleNamespace(points=pts)

    return predict


PROG = "G21 G90\nG0 X0 Y0 Z0\n" + "".join(f"G1 X{i + 1} F1000\n" for i in range(8))


def test_the_highest_feed_under_a_linear_force_is_the_ratio_and_steps_are_limited():
    prog = parse_program(PROG, file="t.nc")
    n = len(prog)
    k_force = np.full(n, 0.1)                    # 100 N at F1000
    k_force[5] = 0.4                             # one block 4x as loaded
    predict = _fake_predictor(prog, k_force, np.zeros(n), np.zeros(n))
    lim = FeedLimits(100.0, 3000.0, 0.2)
    s = schedule_feeds(prog, predict, np.arange(n), lim, tolerance_um=10.0,
                       force_limit_N=200.0, margin=0.0)
    assert s.ok
    f = s.feeds_after
    # the loaded block: 200 N / 0.4 N per mm/min = 500 mm/min exactly
    assert f[5] == 500.0
    # the others would run at 2000 (200 / 0.1) but rise by 20 % a block from 500
    assert f[4] == f[6] == 600.0 and f[3] == f[7] == 720.0
    assert f[1] == 1036.0 and f[8] == 864.0
    _factor_steps_within(prog, parse_program(s.text, file="t.nc"), np.arange(1, n), 0.2)


def test_a_block_the_line_overrates_is_lowered_in_later_rounds_until_verified():
    """A force that rises steeply past the programmed feed and then levels off (the line
    through F1000 and the probe at F3000 promises too much): the verified rounds lower
    the feed until the force is within, and the accepted schedule is the last round."""
    prog = parse_program("G21 G90\nG0 X0 Y0 Z0\nG1 X10 F1000\n", file="t.nc")

    def force(f):
        return 100.0 + 300.0 * (1.0 - math.exp(-max(f - 1000.0, 0.0) / 300.0))

    def predict(p):
        res = SimpleNamespace(peak_force_N=force(float(p.feed[1])), E_um=1.0)
        return SimpleNamespace(points=[SimpleNamespace(block=1, status="predicted",
                                                       result=res)])

    s = schedule_feeds(prog, predict, np.array([1]), FeedLimits(100.0, 3000.0),
                       tolerance_um=10.0, force_limit_N=200.0)
    assert s.ok and len(s.rounds) >= 2
    feeds = [r.feeds[1] for r in s.rounds]
    assert all(a > b for a, b in zip(feeds[:-1], feeds[1:], strict=False))
    assert force(feeds[-1]) <= 200.0 and feeds[-1] > 1000.0
    assert all(force(f) > 200.0 for f in feeds[:-1])


def test_limit_steps_keeps_the_programs_own_feed_steps_and_the_fixed_neighbours():
    text = ("G21 G90\nG0 X0 Y0 Z5\nG1 Z0 F250\nG1 X1 F1000\nG1 X2\nG1 X3\nG0 Z5\n"
            "G1 Z0 F500\nG1 X4 F1000\n")
    prog = parse_program(text, file="t.nc")
    lim = FeedLimits(10.0, 5000.0, 0.2)
    # blocks 1 (plunge at 250), 2, 3 scheduled to 2x; block 4 (X3) not scheduled
    out = limit_steps(prog, {1: 500.0, 2: 2000.0, 3: 2000.0}, lim)
    # the plunge may double (factor 2); the cut after it keeps the factor within 20 %
    # going back from the fixed block 4 (factor 1): 1.2 then 1.44 then 1.728
    assert out[3] == 1200.0 and out[2] == 1440.0 and out[1] == 432.0
    assert 5 not in out and 6 not in out                  # after the rapid: not asked


def test_a_block_that_no_allowed_feed_brings_within_is_refused():
    prog = parse_program(PROG, file="t.nc")
    n = len(prog)
    e0 = np.full(n, 1.0)
    e0[3] = 12.0                                 # 12 um at any feed: over 10 um
    predict = _fake_predictor(prog, np.full(n, 0.01), e0, np.full(n, 1e-3))
    s = schedule_feeds(prog, predict, np.arange(n), FeedLimits(100.0, 2000.0),
                       tolerance_um=10.0, force_limit_N=1e4)
    assert not s.ok and s.text is None
    assert "line 5" in s.reason and "lowest allowed feed is 100" in s.reason


# --- the command on the bundled parts ------------------------------------------------


def test_generous_limits_raise_every_feed_to_the_max_and_the_cycle_time_drops(tmp_path,
                                                                              capsys):
    scn = _slice(tmp_path, "wall-radius", (376, 378))
    out = tmp_path / "fast.nc"
    assert main(["schedule", str(scn), "-o", str(out), "--tolerance-um", "200",
                 "--force-limit-n", "5000", "--max-feed", "2000", "--max-feed-step", "60",
                 "--rapid-mm-min", "10000"]) == 0
    text = capsys.readouterr().out
    orig = load(scn).read_program()
    prog, blocks, after = _dense(scn, out.read_text())
    np.testing.assert_array_equal(prog.end, orig.end)
    assert np.all(orig.feed[blocks] == 1300.0)
    assert np.all(prog.feed[blocks] == 2000.0)          # 1300 -> the max, within 60 %
    _factor_steps_within(orig, prog, blocks, 0.6)
    assert after.over(blocks, 200.0, 5000.0).size == 0
    # the lines are all feed moves: the feed-limited time scales as 1300 / 2000
    m = re.search(r"cycle time \(scheduled lines.*?: ([\d.]+) s -> ([\d.]+) s", text)
    assert float(m.group(2)) == pytest.approx(float(m.group(1)) * 1300 / 2000, abs=0.01)
    page = out.with_suffix(".html")
    seen = open_page(page, tmp_path)
    assert seen["images"] == 2 and seen["broken"] == 0
    assert "Feeds scheduled, verified" in page.read_text()


def test_a_tight_tolerance_lowers_the_feeds_and_the_written_program_is_within(tmp_path):
    from errpred.schedule_run import schedule_scenario

    scn = _slice(tmp_path, "wall-radius", (376, 378))
    s = load(scn)
    orig, blocks, before = _dense(scn)
    tol = round(0.8 * float(np.nanmax(before.E_max_um[blocks])), 1)
    over0 = before.over(blocks, tol, 1e4)
    assert over0.size > 0                                # the program as it is: over
    sc = schedule_scenario(s, tolerance_um=tol, force_limit_N=1e4).schedule
    assert sc.ok
    prog, _, after = _dense(scn, sc.text)                # re-predicted here, from the text
    assert after.over(blocks, tol, 1e4).size == 0
    assert np.all(prog.feed[over0] < orig.feed[over0])   # the blocks over: slower
    f = prog.feed[blocks]
    assert np.all((f >= 325.0) & (f <= 2600.0))          # the default limits
    _factor_steps_within(orig, prog, blocks, 0.2)


def test_the_highest_feed_for_a_force_limit_is_the_analytic_ratio(tmp_path):
    """Without edge forces the force is linear in the feed per tooth: the highest feed
    for a force limit is the programmed feed times limit / force, per block."""
    from errpred.schedule_run import schedule_scenario

    scn = _slice(tmp_path, "wall-radius", (376, 378), no_edge=True)
    s = load(scn)
    run = schedule_scenario(s, tolerance_um=1e3, force_limit_N=50.0, max_step_pct=1000.0)
    sc = run.schedule
    assert sc.ok
    b = sc.blocks
    f0, F0 = sc.feeds_before[b], sc.before.force_N[b]
    assert np.all(F0 > 50.0)                               # each block must slow down
    analytic = f0 * 50.0 * (1 - 0.05) / F0                  # the schedule's 5 % margin
    np.testing.assert_allclose(sc.feeds_after[b], analytic, rtol=0.01, atol=1.0)
    # and the physics is that line: the verified force is the limit less the margin
    np.testing.assert_allclose(sc.after.force_N[b], 50.0 * 0.95, rtol=0.01)


def test_a_tolerance_no_feed_reaches_is_refused_in_one_line_and_nothing_written(
        tmp_path, capsys):
    scn = _slice(tmp_path, "wall-radius", (376, 377))
    out = tmp_path / "never.nc"
    assert main(["schedule", str(scn), "-o", str(out), "--tolerance-um", "0.5",
                 "--force-limit-n", "1e4", "-q"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ")
    assert "nothing written" in err[0] and "lowest allowed feed" in err[0]
    assert not out.exists()
    assert "Nothing written" in out.with_suffix(".html").read_text()


def test_bad_limits_are_refused_before_any_prediction(tmp_path, capsys):
    scn = _slice(tmp_path, "wall-radius", (376, 377))
    for extra, what in ((["--max-feed", "100", "--min-feed", "200"], "--max-feed"),
                        (["--max-feed-step", "-5"], "--max-feed-step"),
                        (["--min-feed", "nan"], "--min-feed")):
        assert main(["schedule", str(scn), "-o", str(tmp_path / "x.nc"), "--tolerance-um",
                     "10", "--force-limit-n", "100", *extra]) == 2
        assert what in capsys.readouterr().err
    assert main(["schedule", str(scn), "-o", str(tmp_path / "x.nc"), "--tolerance-um",
                 "inf", "--force-limit-n", "100"]) == 2
    assert main(["schedule", str(scn), "-o", str(tmp_path / "x.nc"), "--tolerance-um",
                 "10", "--force-limit-n", "100", "--iterate"]) == 2
    assert "--iterate: only with --correct" in capsys.readouterr().err
    assert not (tmp_path / "x.nc").exists()


def test_a_mold_raster_slice_is_scheduled_within_its_limits(tmp_path, capsys):
    """A raster pass over the core's base (rapid in, plunge at F400, then F1600; up to
    11 um and 133 N at the programmed feeds)."""
    scn = _slice(tmp_path, "mold-ball", (19103, 19125))
    out = tmp_path / "mold.nc"
    assert main(["schedule", str(scn), "-o", str(out), "--tolerance-um", "12",
                 "--force-limit-n", "200", "--no-page"]) == 0
    said = capsys.readouterr().out
    orig = load(scn).read_program()
    prog, blocks, after = _dense(scn, out.read_text())
    assert after.over(blocks, 12.0, 200.0).size == 0
    assert not out.with_suffix(".html").exists()
    # the plunge (F400 before F1600) keeps its share of the cutting feed within the step
    assert orig.feed[blocks].min() == 400.0
    _factor_steps_within(orig, prog, blocks, 0.2)
    assert re.search(r"cycle time \(scheduled lines.*-\d", said)   # faster


def test_correct_then_schedule_keeps_the_corrected_error_within(tmp_path, capsys):
    """--correct: the program is corrected (verified as compensate does), then the
    corrected program's feeds are scheduled on its error against the original's path. On
    a steep wall (tests/errpred/adversarial.py) the original misses 9 um at its own feed
    (9.98 um); corrected and scheduled, it is within 9 um and faster."""
    from errpred.verification import error_field
    from nc.path import cutter_locations

    from . import adversarial as adv

    scn = adv.steep_wall(tmp_path / "wall", levels=3, length=30.0, stiffness_scale=0.3)
    out = tmp_path / "corrected-fast.nc"
    assert main(["schedule", str(scn), "-o", str(out), "--tolerance-um", "9",
                 "--force-limit-n", "1e4", "--correct", "--no-page"]) == 0
    said = capsys.readouterr().out
    assert "corrected first" in said
    s = load(scn)
    orig = s.read_program()
    prog = parse_program(out.read_text(), file="written.nc")
    res = s.resolution.dense()
    ref = cutter_locations(orig, s.resolve_machine(), chord_tol_mm=res.chord_tol_mm)
    before = error_field(build_predictor(s, orig, res, sensitivity=False).run(), ref,
                         orig.line, moved=False)
    after = error_field(build_predictor(s, prog, res, sensitivity=False).run(), ref,
                        orig.line)
    assert np.abs(before.E_um).max() > 9.0                 # the original: over
    assert len(after) >= len(before) and np.abs(after.E_um).max() <= 9.0
    feed = prog.motion != RAPID
    assert prog.feed[feed].max() > 1350.0 and prog.feed[feed].min() >= 337.5
    m = re.search(r"cycle time \(whole program.*?: ([\d.]+) s -> ([\d.]+) s", said)
    assert float(m.group(2)) < float(m.group(1))


# -- cycle time in each feed mode (nc.path.block_minutes) --------------------------------
CYCLE_TIMES = [
    # (program, feeds given to cycle_time or None, feed minutes by hand)
    # G95: 10 mm at 0.1 mm/rev x 1000 rev/min = 100 mm/min -> 0.1 min; then 5 mm at
    # 0.25 x 2000 = 500 mm/min -> 0.01 min
    ("G21 G90 G95\nS1000 M3\nG0 X0 Y0 Z0\nG1 X10 F0.1\nS2000\nG1 X15 F0.25\nM30\n",
     None, 0.1 + 0.01),
    # the same with scheduled feeds per revolution 0.2 and 0.5: half the time
    ("G21 G90 G95\nS1000 M3\nG0 X0 Y0 Z0\nG1 X10 F0.1\nS2000\nG1 X15 F0.25\nM30\n",
     [math.nan, 0.2, 0.5], 0.05 + 0.005),
    # rotary only: 90 deg at F900 deg/min -> 0.1 min (LinuxCNC's rule); then 3-4-5 mm
    # with A at F500 -> the 5 mm of X Y only, 0.01 min
    ("G21 G90 G94\nG0 X0 Y0 Z0 A0\nG1 A90 F900\nG1 X3 Y4 A100 F500\nM30\n", None,
     0.1 + 0.01),
]


@pytest.mark.parametrize("src,feeds,minutes", CYCLE_TIMES)
def test_cycle_time_per_revolution_and_rotary_only_by_hand(src, feeds, minutes):
    prog = parse_program(src)
    lengths = block_lengths(prog)
    f = None
    if feeds is not None:
        f = prog.feed.copy()
        f[prog.motion != RAPID] = feeds[1:]
    ct = cycle_time(prog, lengths, feeds=f)
    assert ct.feed_min == pytest.approx(minutes, rel=1e-12)
    assert math.isnan(ct.rapid_min) and ct.rapid_length_mm == pytest.approx(0.0)


def test_cycle_time_refuses_per_revolution_without_spindle_speed():
    prog = parse_program("G21 G90 G95\nS1000 M3\nG0 X0\nG1 X10 F0.1\nM30\n", file="r.nc")
    import dataclasses

    # a Program built without S (the readers refuse G95 without one)
    prog = dataclasses.replace(prog, modals=tuple(dataclasses.replace(m, spindle_rpm=0.0)
                                                   for m in prog.modals))
    with pytest.raises(InputError, match=r"^r\.nc: line 4: feed per revolution \(G95\) "
                                         r"with no spindle speed"):
        cycle_time(prog, block_lengths(prog))


def test_the_feed_limits_keep_the_force_models_feed_per_tooth():
    """The schedule's largest feed keeps a tooth within MAX_FEED_PER_TOOTH_RADII of the
    radius at the slowest spindle speed in scope (the Predictor refuses beyond it): the
    default (twice the programmed 4,000 mm/min) is cut to 5,000 mm/min for the D10
    two-flute ball at 1,000 rev/min; a --max-feed beyond it is refused, named."""
    from errpred.scenario import bundled_scenario, load_scenario
    from errpred.schedule_run import feed_limits
    from nc import parse_program
    from nc.errors import InputError

    s = load_scenario(bundled_scenario("mold-ball"))
    assert s.tool.diameter_mm == 10.0 and s.tool.flutes == 2
    prog = parse_program("G21 G90 S1000 M3\nG0 X0 Y0 Z5\nG1 Z0 F4000\nG1 X20\nM2\n")
    blocks = np.arange(len(prog))
    assert feed_limits(s, prog, blocks, None, None, None).max_mm_min == pytest.approx(5000.0)
    assert feed_limits(s, prog, blocks, None, 4500.0, None).max_mm_min == 4500.0
    with pytest.raises(InputError, match=r"^--max-feed: 6000 mm/min is 1\.2 times .* "
                       r"\(5000 mm/min, errpred\.constants\.MAX_FEED_PER_TOOTH_RADII\)"):
        feed_limits(s, prog, blocks, None, 6000.0, None)
