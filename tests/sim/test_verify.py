"""Verification in the simulated machine: what it was asked to cut, what it cut, and why not.

Issue 16: on the flexible wall (``tests/sim/flexible_wall.py``) the job's corrected
program went up to 455 um into the wall and its simulated run cut a fraction of the
cutter locations, unexplained. The simulated machine took a feed move for a cut only
where the ball was within 0.1 mm of the design on either side (orient's contacts,
``|gap| <= tol``): a gouge deeper than that was air to it, left out of the surface
figures. A correction-shaped bump of up to 455 um on the flexible wall's three top
passes (93 cutting cutter locations) left 18 of them cut; now all 93 are, and a run
that cannot cover its stretch says so.
"""

from __future__ import annotations

import numpy as np
import pytest

from nc.path import CutterLocations
from nc.writer import PostOptions, write_program
from orient.scenario import load_plan_scenario
from sim.constants import CUTTING_GAP_MM, TICK_S
from sim.program import PartProgram
from sim.verify import Verification, scenario_with_program, verify_program
from tests.thin_wall import wall_mode

from .flexible_wall import HEIGHT_MM, MACHINE, THICKNESS_MM, flexible_rib, flexible_wall

#: Depth of the gouge made on purpose [mm] (three times the cutting gap's tolerance).
GOUGE_MM = 0.3
#: Contact x of the gouged cutter locations [mm].
GOUGED_X = (26.0, 28.0, 30.0)
#: Contact x where the short runs start [mm].
START_X = 20.0
#: A stiff tool and wall: the simulated surface is the programmed one to a few um.
STIFF = {"stiffness_N_m = 9.0e5": "stiffness_N_m = 1.0e8",
         "stiffness_N_m = 9.5e5": "stiffness_N_m = 1.0e8"}


def _point(tip: np.ndarray, cl: CutterLocations, x: float) -> int:
    """Index in ``cl`` (read through the machine) of the feed point at the tip of the
    CAM's point whose contact is at ``x``."""
    d = np.linalg.norm(cl.tip - tip, axis=1) + np.where(cl.rapid, np.inf, 0.0)
    i = int(np.argmin(d))
    assert d[i] < 1e-3, x
    return i


@pytest.fixture(scope="module")
def gouged(tmp_path_factory):
    """The flexible wall's top pass, stiff, with three cutter locations ``GOUGE_MM`` into
    the wall and, after the retract, a rapid move whose ball ends inside the wall and a
    feed move back out. Returns (scenario, part program, gouged rows, rapid row, first)."""
    folder = tmp_path_factory.mktemp("gouged") / "flexible-wall"
    toml = flexible_wall(folder, passes=1, edits=STIFF, workpiece=wall_mode(1.0e9))
    gen, rib = flexible_rib(passes=1)
    tip, axis, rapid = gen.cam_cutter_locations(rib)
    cx = tip[:, 0]                                  # contact x: the tips' x (feed along +X)
    normal = np.array([0.0, 1.0, 0.0])
    gouge = ~rapid & np.isin(np.round(cx, 6), GOUGED_X)
    tip = tip - GOUGE_MM * gouge[:, None] * normal
    # after the retract: a rapid to a ball centre 1 mm inside the wall, then back out
    u = axis[0]
    centre_in = np.array([40.0, rib.wall_y0 + rib.wall_t - 1.0, rib.z_top])
    tip = np.vstack([tip, centre_in - rib.r_ball * u, tip[-1]])
    axis = np.vstack([axis, u, u])
    rapid = np.r_[rapid, True, False]
    cl = CutterLocations.from_arrays(tip, axis, np.where(rapid, np.nan, rib.feed_mm_min),
                                     rib.spindle_rpm, rapid=rapid)
    path = folder / "gouged.nc"
    scn = load_plan_scenario(toml)
    write_program(path, cl, scn.machine(), PostOptions(dialect="linuxcnc",
                                                       source="gouged on purpose"))
    scn = scenario_with_program(scn, path)
    part = PartProgram(scn)
    rows = np.array([_point(tip[k], part.cam, cx[k]) for k in np.flatnonzero(gouge)])
    d = np.linalg.norm(part.cam.tip - tip[-2], axis=1) + np.where(part.cam.rapid, 0.0, np.inf)
    into = int(np.argmin(d))
    start = np.flatnonzero(~rapid[:cx.size] & np.isclose(cx, START_X))[0]
    first = _point(tip[start], part.cam, START_X)
    return scn, part, rows, into, first


def test_the_flexible_wall_is_the_reported_scenario(tmp_path):
    scn = load_plan_scenario(flexible_wall(tmp_path / "flexible-wall", passes=2))
    tool = scn.base.tool
    assert (tool.kind, tool.diameter_mm) == ("ball", 6.0)
    assert tool.overhang_mm - tool.flute_length_mm >= 0.5 * HEIGHT_MM
    assert scn.machine().name == MACHINE == "xyzbc-head-table"
    assert scn.machine().tool_length_mm == tool.overhang_mm     # places the head's pivots
    wall = scn.workpiece.thin_wall
    assert (wall["height_mm"], wall["thickness_mm"]) == (HEIGHT_MM, THICKNESS_MM) == (40, 2.5)
    part = PartProgram(scn)
    c = part.contacts
    # two one-way passes along +X, top down 0.5 mm apart, every contact on the +Y face
    z = np.unique(np.round(c.point[part.touch, 2], 6))
    np.testing.assert_allclose(z, [HEIGHT_MM - 1.0, HEIGHT_MM - 0.5])
    np.testing.assert_allclose(c.normal[part.touch], np.tile([0.0, 1.0, 0.0],
                                                             (part.touch.size, 1)), atol=1e-9)
    assert part.touch.size == 2 * 31                # contacts x = 0 .. 60, 2 mm apart
    np.testing.assert_allclose(c.gap_mm[part.touch], 0.0, atol=1e-4)   # 4 decimals


def test_a_gouge_deeper_than_the_cutting_gap_is_cut(gouged):
    _, part, rows, into, _ = gouged
    gap = part.contacts.gap_mm
    np.testing.assert_allclose(gap[rows], -GOUGE_MM, atol=1e-4)
    assert -GOUGE_MM < -CUTTING_GAP_MM                  # orient's |gap| <= tol left these out
    assert np.all(part.contacts.touching[rows]) and set(rows) <= set(part.cuts)
    assert part.rapid_in_material[into] and not part.contacts.touching[into]
    assert np.count_nonzero(part.rapid_in_material) == 1


@pytest.fixture(scope="module")
def run(gouged):
    scn, part, _, _, first = gouged
    return verify_program(scn, points=(first, len(part.cam) - 1))


def test_the_gouge_is_in_the_surface_figures(gouged, run):
    _, _, rows, _, _ = gouged
    assert set(rows) <= set(run.points.tolist())
    s = dict(zip(run.points.tolist(), run.surface_um))
    gouge = np.array([s[int(i)] for i in rows])
    rest = np.array([v for i, v in s.items() if i not in set(rows.tolist())])
    # the programmed 300 um into the wall, give or take the stiff system's deflection
    np.testing.assert_allclose(gouge, -GOUGE_MM * 1e3, atol=20.0)
    assert np.max(np.abs(rest)) < 20.0 and rest.size >= 15


def test_a_rapid_move_into_the_material_makes_the_run_incomplete(gouged, run):
    _, part, rows, into, first = gouged
    assert isinstance(run, Verification)
    assert run.stretch == (first, len(part.cam) - 1)
    assert into in run.asked and into not in run.covered
    assert set(rows) <= set(run.covered.tolist())
    np.testing.assert_array_equal(run.missed, [into])
    assert not run.complete
    line = int(part.cam_line[into])
    assert part.cam_line[into - 1] < line < part.cam_line[into + 1]
    assert part.scn.base.program_path.read_text().splitlines()[line - 1].startswith("G0 ")
    assert run.stopped_reason is not None
    assert "1 rapid move(s) into the material" in run.stopped_reason
    assert f"cutter locations {into}," in run.stopped_reason
    assert f"program lines {line}" in run.stopped_reason
    assert run.coverage.startswith(f"{run.asked.size - 1} of {run.asked.size} cutter "
                                   "locations in the material cut")
    assert run.reached == len(part.cam) - 1


def test_a_run_that_covers_its_stretch_is_complete(gouged):
    scn, _, rows, _, first = gouged
    last = int(rows[-1]) + 2
    v = verify_program(scn, points=(first, last))
    np.testing.assert_array_equal(v.asked, np.arange(first + 1, last + 1))
    np.testing.assert_array_equal(v.covered, v.asked)
    assert v.complete and v.stopped_reason is None and v.missed.size == 0
    assert v.reached == last


def test_the_time_budget_stops_the_run_and_says_where(gouged):
    scn, _, rows, _, first = gouged
    last = int(rows[-1]) + 2
    budget = 0.15                    # 3.6 mm at 1440 mm/min: into the second feed move
    v = verify_program(scn, points=(first, last), max_machining_s=budget)
    assert not v.complete
    assert budget <= v.machining_s < budget + 0.01
    assert v.reached == first + 2
    np.testing.assert_array_equal(v.covered, [first + 1])
    assert v.missed.size == v.asked.size - 1
    assert v.stopped_reason.startswith(f"{v.asked.size - 1} of {v.asked.size} cutter "
                                       "locations in the material not cut: the run's time "
                                       f"budget (0.15 s simulated) ran out on the move into "
                                       f"cutter location {first + 2}")
    with pytest.raises(ValueError, match="max_machining_s"):
        verify_program(scn, points=(first, last), max_machining_s=0.0)


def test_stretches_judged_as_one_say_what_one_run_says(gouged, run):
    """``judge`` on stretches of the gouged run: the rapid move into the material, in the
    first stretch's last move, is reported with the joined run's counts and the NC's last location;
    a stretch stopped by its time budget ends the joined run there (the stretches after
    it are not counted, as one run would not have reached them)."""
    from sim.verify import judge, simulate_stretch

    scn, part, rows, into, first = gouged
    last, mid = len(part.cam) - 1, into
    runs = [simulate_stretch(scn, points=(first, mid)),
            simulate_stretch(scn, points=(mid, last), seed=1)]
    v = judge(runs)
    np.testing.assert_array_equal(v.asked, run.asked)
    np.testing.assert_array_equal(v.covered, run.covered)
    assert v.reached == run.reached == last
    assert v.stopped_reason == run.stopped_reason
    assert v.coverage == run.coverage

    stop = rows[-1] + 2
    short = [simulate_stretch(scn, points=(first, stop), max_machining_s=0.15),
             simulate_stretch(scn, points=(stop, last), seed=1)]
    alone = verify_program(scn, points=(first, stop), max_machining_s=0.15)
    w = judge(short)
    assert w.reached == alone.reached == first + 2
    np.testing.assert_array_equal(w.covered, alone.covered)
    np.testing.assert_array_equal(w.asked, alone.asked)
    assert w.stopped_reason == alone.stopped_reason
    assert w.machining_s == alone.machining_s


def test_a_one_pass_program_is_not_split():
    """``split_at_air`` splits only in an air gap with cutting on both sides: the
    approach and the retract of a one-pass program are no such place."""
    from sim.verify import split_at_air

    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as d:
        scn = load_plan_scenario(flexible_wall(Path(d) / "wall", passes=1))
        n = len(PartProgram(scn, cuts=False).cam)
        assert split_at_air(scn, 2) == [(0, n - 1)]


@pytest.mark.parametrize("length", [7, 8, 9001, 8192 * 3 + 17, 8192 * 40 + 4095])
def test_welch_spectrum_in_chunks_is_scipys_welch_bit_for_bit(length):
    """The run's averaged spectrum, its segments' spectra computed a few at a time
    (less memory), is scipy.signal.welch's to the last bit, whatever the chunk."""
    from scipy import signal

    from sim.verify import welch_spectrum

    x = np.random.default_rng(length).normal(size=(length, 2)) * 3.7
    n = min(8192, length)
    for chunk in (1, 3, 64):
        f, a = welch_spectrum(x, 25600.0, chunk=chunk)
        if n < 8:
            assert f.size == 0 and a.size == 0
            continue
        f0, p = signal.welch(x, fs=25600.0, window="hann", nperseg=n, axis=0,
                             scaling="spectrum")
        assert np.array_equal(f, f0) and np.array_equal(a, np.sqrt(2.0 * p.sum(axis=1)))


def test_the_simulated_cut_is_the_programs_not_the_planners_table(tmp_path):
    """The simulated machine cuts what the program it runs cuts, from the part: a
    scenario whose ``[orient.cut]`` table says 0.05 mm still gets the wall's 0.2 mm
    (the planner's own cut is the table's). A corrected program cuts deeper than the
    table's depth; its verification must see that force. On the table, as before, the
    simulated cut was 0.05 mm."""
    from orient.cuts import local_cuts

    from tests.thin_wall import thin_wall_copy

    path = thin_wall_copy(tmp_path / "wall", edits={"depth_mm = 0.2": "depth_mm = 0.05"},
                          cam_lines=60)
    scn = load_plan_scenario(path)
    part = PartProgram(scn)
    depth = np.array([c.depth_mm for c in part.cuts.values()])
    assert depth.size >= 20
    np.testing.assert_allclose(depth, 0.2, atol=1e-3)
    planned = local_cuts(scn, part.contacts, part.touch, part.cam, part.rpm)
    assert all(c.depth_mm == 0.05 for c in planned)


def test_a_run_split_at_air_moves_and_judged_as_one_is_the_whole_run(tmp_path):
    """The main job runs each whole program in stretches split at air moves
    (``split_at_air``), apart, and judges them as one run (``judge``). On the flexible
    wall's two passes (stiffened; it still chatters): the split is in the air move
    between them; what was asked and cut and the cutter locations are the whole run's,
    the simulated time to one servo tick; the first stretch's surface is the whole
    run's bit for bit (the same start and noise seed); the second stretch's differs from
    the whole run's as much as the whole run with another noise seed does (the work
    material's scatter and the sensors' noise: another draw), and so do the chatter
    figures."""
    from sim.verify import judge, simulate_stretch, split_at_air

    scn = load_plan_scenario(flexible_wall(tmp_path / "wall", passes=2, edits=STIFF))
    part = PartProgram(scn, cuts=False)
    n = len(part.cam)
    material = part.contacts.touching | part.rapid_in_material
    assert split_at_air(scn, 1) == [(0, n - 1)]
    stretches = split_at_air(scn, 2)
    assert len(stretches) == 2
    (a, c), (c2, b) = stretches
    assert (a, c2, b) == (0, c, n - 1)
    assert not material[c - 1] and not material[c]            # in the air between passes
    assert material[:c].any() and material[c:].any()
    with pytest.raises(ValueError, match="parts"):
        split_at_air(scn, 0)

    whole = verify_program(scn)
    runs = [simulate_stretch(scn, points=p, seed=k) for k, p in enumerate(stretches)]
    v = judge(runs)
    with pytest.raises(ValueError, match="does not follow"):
        judge(runs[::-1])
    assert v.complete and whole.complete
    for name in ("asked", "covered", "points"):
        np.testing.assert_array_equal(getattr(v, name), getattr(whole, name))
    assert v.stretch == whole.stretch and v.reached == whole.reached
    # each stretch ends with its own servo tick: at most one tick more a split
    assert 0.0 <= v.machining_s - whole.machining_s <= TICK_S * (len(runs) - 1) + 1e-9
    one = v.points <= c
    np.testing.assert_array_equal(v.surface_um[one], whole.surface_um[one])
    np.testing.assert_array_equal(v.marks_um[one], whole.marks_um[one])
    other = verify_program(scn, seed=1)

    def rms(x: np.ndarray) -> float:
        return float(np.sqrt(np.mean(x ** 2)))

    split = rms(v.surface_um[~one] - whole.surface_um[~one])
    seed = rms(other.surface_um[~one] - whole.surface_um[~one])
    assert 0.0 < split < 1.5 * seed, (split, seed)
    assert v.sustained_chatter == whole.sustained_chatter
    assert abs(v.chatter_windows - whole.chatter_windows) <= max(
        2, 2 * abs(other.chatter_windows - whole.chatter_windows))


def test_a_stretch_run_with_its_programs_part_given_is_the_run_that_derives_it(tmp_path):
    """The job derives a program's part and local cuts once (``PartProgram``) and gives it
    to each of its stretches: a stretch run with it is the run that derives them itself,
    bit for bit; a part of another program, or one without local cuts, is refused, naming
    the program."""
    import dataclasses

    from sim.verify import simulate_stretch

    scn = load_plan_scenario(flexible_wall(tmp_path / "wall", passes=1, edits=STIFF))
    part = PartProgram(scn)
    touch = part.touch
    points = (int(touch[len(touch) // 2]) - 12, int(touch[len(touch) // 2]) + 12)
    alone = simulate_stretch(scn, points=points, seed=3)
    given = simulate_stretch(scn, points=points, seed=3, part=part)
    assert alone.stretch == given.stretch == points
    assert alone.surface["point"].size > 0
    for name in ("time_s", "acceleration_m_s2", "cutting", "asked", "covered"):
        np.testing.assert_array_equal(getattr(given, name), getattr(alone, name))
    for key, value in alone.surface.items():
        np.testing.assert_array_equal(given.surface[key], value)
    # a second stretch on the same part after the first: nothing of the first is left
    later = (points[1], min(points[1] + 24, len(part.cam) - 1))
    shared = simulate_stretch(scn, points=later, seed=4, part=part).surface["offset_mm"]
    assert shared.size > 0
    np.testing.assert_array_equal(
        shared, simulate_stretch(scn, points=later, seed=4).surface["offset_mm"])
    assert part.stretch(points).first == points[0] and part.first == 0   # part unchanged
    other = dataclasses.replace(scn, base=dataclasses.replace(scn.base,
                                                              program_path=tmp_path / "x.nc"))
    with pytest.raises(ValueError, match="x.nc"):
        simulate_stretch(other, points=points, part=part)
    with pytest.raises(ValueError, match="without local cuts"):
        simulate_stretch(scn, points=points, part=PartProgram(scn, cuts=False))
