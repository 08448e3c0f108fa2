"""Time-domain milling (sim.cutting) against orient's stability analysis and closed forms.

Benchmarks, all with a straight-fluted flat end mill and errpred's micro-edge
force model; the reference is orient's full discretization (Floquet) of the
same linearized model, whose own benchmarks are in
tests/orient/test_stability.py:

* the 1-DOF slotting case of Insperger & Stepan (IJNME 61 (2004) 117-141) and
  Ding et al. (IJMTM 50 (2010) 502-509): m = 0.03993 kg, 922 Hz, zeta 0.011
  (k = 1340049.648 N/m) along x, Kt = 6e8 N/m^2, Kn = 2e8 N/m^2, 2 teeth,
  a/D = 1, no edge forces;
* half-immersion down-milling on Ding et al.'s symmetric 2-DOF tool (the same
  mode in x and y), with a steel-like force model with edge forces.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from errpred.dynamics import Mode
from errpred.coefficients import CuttingCoefficients
from errpred.tool import Tool
from orient.dynamics import ModalSystem
from orient.engagement import LocalCut
from orient.gain import process_gain
from orient.stability import sdm_margin
from sim.cutting import growth_rate, prepare_cut, simulate, stability_boundary

COEF = CuttingCoefficients(Ktc_N_mm2=2000.0, Krc_N_mm2=700.0, Kac_N_mm2=300.0,
                           Kte0_N_mm=20.0, Kre0_N_mm=25.0, Kae0_N_mm=5.0)
Z, X, Y = np.eye(3)[2], np.eye(3)[0], np.eye(3)[1]
DEPTH = 1.0
FLAT = Tool("flat", 10.0, flutes=2, helix_deg=0.0, flute_length_mm=6.0)
EDGES = FLAT.micro_edges(40, flank_height_mm=DEPTH)
HALF_DOWN = LocalCut(DEPTH, 5.0, 1, 0.05)       # ae = 5 mm of D = 10, down-milling


def _tool_2dof() -> ModalSystem:
    m = Mode.from_frequency(922.0, 0.011, 1.34e6)
    return ModalSystem.from_modes([(m, (1, 0, 0)), (m, (0, 1, 0))], source="tool")


def _insperger_case():
    k, fn, zeta = 1340049.648, 922.0, 0.011
    m = k / (2 * math.pi * fn) ** 2
    mode = Mode(k, m, 2 * zeta * math.sqrt(k * m))
    system = ModalSystem.from_modes([(mode, (1, 0, 0))], source="tool")
    coef = CuttingCoefficients(Ktc_N_mm2=600.0, Krc_N_mm2=200.0, Kac_N_mm2=0.0,
                               Kte0_N_mm=0.0, Kre0_N_mm=0.0, Kae0_N_mm=0.0)
    return system, coef, LocalCut(DEPTH, 10.0, 1, 0.1)         # slot: ae = D


@pytest.mark.parametrize("rpm", [5000.0, 10000.0])
def test_1dof_slotting_boundary_agrees_with_time_periodic_analysis(rpm):
    system, coef, slot = _insperger_case()
    g = process_gain(FLAT, coef, Z, Z, X, slot, spindle_rpm=rpm, edges=EDGES, n_angles=720)
    ref = sdm_margin(g.H, system, rpm, 2).margin
    model = prepare_cut(FLAT, coef, Z, Z, X, slot, system, rpm, edges=EDGES)
    b = stability_boundary(model, 0.5 * ref, 2.0 * ref)
    assert abs(b / ref - 1.0) < 0.10


def test_a_tables_entries_at_a_sample_ascend_by_position_and_edge():
    """The kernel walks two tables' entries at a sample side by side (sim._kernels._leave):
    prepare_cut orders them by surface position, then edge. A 4-flute slot engages two
    flutes at every sample; where the later flute's position has wrapped past the last
    one, flute order and position order differ."""
    system, coef, slot = _insperger_case()
    four = Tool("flat", 10.0, flutes=4, helix_deg=0.0, flute_length_mm=6.0)
    model = prepare_cut(four, coef, Z, Z, X, slot, system, 5000.0, edges=EDGES)
    ptr, pos, edge = model.table[:3]
    spr, spt = model.steps_per_rev, model.steps_per_tooth
    key = pos * model.n_edges + edge
    swapped = 0
    for i in range(spr):
        e = slice(ptr[i], ptr[i + 1])
        assert np.all(np.diff(key[e]) > 0), f"sample {i}"
        flute = (pos[e] - i) % spr // spt
        swapped += bool(np.any(np.diff(flute) < 0))
    assert swapped > spr // 8


def _fdm_margin(rpm: float, steps: int | None = None) -> float:
    g = process_gain(FLAT, COEF, Z, Z, X, HALF_DOWN, spindle_rpm=rpm, edges=EDGES,
                     n_angles=360)
    return sdm_margin(g.H, _tool_2dof(), rpm, 2, steps=steps).margin


@pytest.mark.parametrize("rpm", [9000.0, 12000.0])
def test_boundary_agrees_with_time_periodic_analysis(rpm):
    """The simulated boundary (nonlinear model, default step) lies within 10 % of the
    full-discretization margin at two speeds (one near a lobe bottom)."""
    ref = _fdm_margin(rpm)
    model = prepare_cut(FLAT, COEF, Z, Z, X, HALF_DOWN, _tool_2dof(), rpm, edges=EDGES)
    b = stability_boundary(model, 0.5 * ref, 2.0 * ref)
    assert abs(b / ref - 1.0) < 0.10


def test_boundary_converges_to_the_analysis_under_refinement():
    """Halving the step twice moves the boundary toward the analysis (first order). The
    linearized model: the discretization is what converges; the nonlinear model's edges
    leaving the cut and rubbing (``EDGE_RUB_MM``), which the analysis has not, move its
    boundary by a few tenths of a percent (its agreement is the test above)."""
    rpm = 9000.0
    ref = _fdm_margin(rpm, steps=80)
    err = []
    for spr in (360, 1440):
        model = prepare_cut(FLAT, COEF, Z, Z, X, HALF_DOWN, _tool_2dof(), rpm, edges=EDGES,
                            steps_per_rev=spr)
        err.append(abs(stability_boundary(model, 0.5 * ref, 2.0 * ref, revolutions=80,
                                          linear=True) / ref - 1.0))
    assert err[1] < 0.5 * err[0]
    assert err[1] < 0.03


def test_stable_cut_settles_to_the_static_force_and_deflection():
    """Well below the boundary the force becomes tooth-periodic, its mean equals
    the static micro-edge force (sum of F0 + h0 F1 over the engaged edges), and
    the mean deflection is G(0) times the mean force (compliance 1/k per axis)."""
    rpm = 9000.0
    model = prepare_cut(FLAT, COEF, Z, Z, X, HALF_DOWN, _tool_2dof(), rpm, edges=EDGES)
    run = simulate(model, 80, scale=0.3 * _fdm_margin(rpm))
    spt, spr = model.steps_per_tooth, model.steps_per_rev
    last = slice(-spr, None)
    ptr, _pos, _e, h0, _n, f0, f1 = model.table
    static = np.zeros((spr, 3))
    for i in range(spr):
        static[i] = (f0[ptr[i]:ptr[i + 1]] + h0[ptr[i]:ptr[i + 1], None]
                     * f1[ptr[i]:ptr[i + 1]]).sum(axis=0)
    mean_static = 0.3 * _fdm_margin(rpm) * static.mean(axis=0)
    np.testing.assert_allclose(run.force_N[last].mean(axis=0), mean_static,
                               atol=2e-3 * np.abs(mean_static).max())
    np.testing.assert_allclose(run.force_N[-spt:], run.force_N[-2 * spt:-spt],
                               atol=1e-3 * np.abs(run.force_N[-spt:]).max())
    defl = run.displacement_m[last].mean(axis=0)
    np.testing.assert_allclose(defl[:2], mean_static[:2] / 1.34e6, rtol=0.02)
    assert growth_rate(run, model) < 0


def test_chatter_grows_then_the_tool_leaves_the_cut():
    """Above the boundary the linear model keeps growing; the nonlinear one saturates
    once the chip vanishes somewhere (contact loss): over 300 revolutions its
    vibration stays within a few times what it reached after 60, while the
    linear model's grows more than tenfold every 20 revolutions."""
    rpm = 9000.0
    ref = _fdm_margin(rpm)
    model = prepare_cut(FLAT, COEF, Z, Z, X, HALF_DOWN, _tool_2dof(), rpm, edges=EDGES)
    spr = model.steps_per_rev

    def per_rev(run):                      # peak-to-peak per revolution [m]
        a = run.displacement_m[:, :2].reshape(-1, spr, 2)
        return np.ptp(a, axis=1).max(axis=1)

    def spread(run, revs):                 # once-per-tooth samples: 0 for a forced motion
        p = run.displacement_m[::model.steps_per_tooth, :2][-revs * model.flutes:]
        return np.ptp(p, axis=0).max()

    lin = per_rev(simulate(model, 80, scale=2.0 * ref, linear=True))
    non_run = simulate(model, 300, scale=2.0 * ref)
    non = per_rev(non_run)
    assert lin[-1] > 10 * lin[-21]
    assert non[60:].max() < 3 * non[20:60].max()
    stable = simulate(model, 300, scale=0.5 * ref)
    assert spread(non_run, 100) > 1000 * spread(stable, 100)      # it does chatter
    assert non_run.contact_loss[-spr:].sum() > 0


def test_exact_step_map_matches_free_vibration():
    """With no cut (zero scale) an initial modal state rings down as the closed-form
    damped oscillation: the step map is the exact solution."""
    rpm = 9000.0
    model = prepare_cut(FLAT, COEF, Z, Z, X, HALF_DOWN, _tool_2dof(), rpm, edges=EDGES)
    phi, _gam = model.step_map
    wn, zeta = 2 * math.pi * 922.0, 0.011
    wd = wn * math.sqrt(1 - zeta**2)
    n = 500
    x = np.array([1e-6, 0.0])
    for _ in range(n):
        x = phi[0] @ x
    t = n * model.dt_s
    exact = 1e-6 * math.exp(-zeta * wn * t) * (math.cos(wd * t)
                                                + zeta * wn / wd * math.sin(wd * t))
    assert x[0] == pytest.approx(exact, rel=1e-9, abs=1e-18)


def test_bad_input_is_refused_by_name():
    model = prepare_cut(FLAT, COEF, Z, Z, X, HALF_DOWN, _tool_2dof(), 9000.0, edges=EDGES)
    with pytest.raises(ValueError, match="scale"):
        simulate(model, 10, scale=float("nan"))
    with pytest.raises(ValueError, match="revolutions"):
        simulate(model, 0)
    with pytest.raises(ValueError, match="spindle_rpm"):
        prepare_cut(FLAT, COEF, Z, Z, X, HALF_DOWN, _tool_2dof(), -1.0)
    with pytest.raises(ValueError, match="steps_per_rev"):
        prepare_cut(FLAT, COEF, Z, Z, X, HALF_DOWN, _tool_2dof(), 9000.0, steps_per_rev=3)
    with pytest.raises(ValueError, match="MAX_STEPS_PER_REV"):
        stiff = ModalSystem.from_modes([(Mode.from_frequency(5e5, 0.01, 1e9), (1, 0, 0))])
        prepare_cut(FLAT, COEF, Z, Z, X, HALF_DOWN, stiff, 9000.0)
    with pytest.raises(ValueError, match="hi"):
        stability_boundary(model, 0.01, 0.02)


def test_ball_end_mill_on_the_thin_wall_matches_the_analysis_when_linear():
    """The bundled thin-wall point (D10 ball, CAM posture, two tool modes and the
    wall's modes at the contact): the linearized simulation's boundary lies within
    10 % of the full discretization; the full model's lies above it, because edges
    with a thin chip (near the previous pass and the tip) leave the cut at small
    amplitudes, which limits the growth (the analysis is linear)."""
    from orient.pointwise import point_setup
    from orient.scenario import bundled_scenario, load_plan_scenario

    scn = load_plan_scenario(bundled_scenario("thin-wall"))
    s = point_setup(scn)
    tool, coef = scn.base.tool, scn.base.coefficients
    i = s.index
    u, n, f = s.axis, s.contacts.normal[i], s.contacts.feed[i]
    g = process_gain(tool, coef, u, n, f, s.cut, spindle_rpm=s.spindle_rpm, n_angles=360)
    ref = sdm_margin(g.H, s.system.with_tool_axis(u), s.spindle_rpm, tool.flutes).margin
    model = prepare_cut(tool, coef, u, n, f, s.cut, s.system, s.spindle_rpm)
    lin = stability_boundary(model, 0.5 * ref, 2.0 * ref, linear=True)
    assert abs(lin / ref - 1.0) < 0.10
    full = stability_boundary(model, 0.5 * ref, 3.0 * ref)
    assert full > lin


def test_cutter_in_chunks_equals_one_run():
    """The NC's stateful cutter (servo ticks, swapped models) reproduces one run exactly."""
    from sim.cutter import Cutter

    m = prepare_cut(FLAT, COEF, Z, Z, X, HALF_DOWN, _tool_2dof(), 9000.0, edges=EDGES)
    run = simulate(m, 20, scale=0.1, ramp_revolutions=0)
    c = Cutter(m.steps_per_rev, m.n_edges)
    sizes = (100, 333, 1000, 20 * m.steps_per_rev - 1433)
    parts = [c.advance(m, k, 0.1) for k in sizes]
    np.testing.assert_array_equal(np.concatenate([p.force_N for p in parts]), run.force_N)
    np.testing.assert_array_equal(np.concatenate([p.displacement_m for p in parts]),
                                  run.displacement_m)
    # off the cut the modes ring down freely: the energy only decreases
    free = c.idle(m.dt_s, 2000, m.system)
    e = np.linalg.norm(free.displacement_m, axis=1)
    spt = m.steps_per_tooth
    assert e[-spt:].max() < e[:spt].max()
    with pytest.raises(ValueError, match="steps per revolution"):
        Cutter(m.steps_per_rev + 2, m.n_edges).advance(m, 10)


def test_radius_end_mill_at_a_tilted_posture_agrees_with_the_analysis():
    """A helical three-flute radius end mill (D10, r1), lead 10 deg and tilt 5 deg, on
    the 2-DOF tool: the simulated boundary within 10 % of the full discretization."""
    from orient.geometry import posture_axis

    tool = Tool("radius", 10.0, flutes=3, helix_deg=30.0, flute_length_mm=15.0,
                corner_radius_mm=1.0)
    u = posture_axis(Z, X, math.radians(10.0), math.radians(5.0))
    cut = LocalCut(0.5, 3.0, 1, 0.05)
    system = _tool_2dof()
    rpm = 9000.0
    g = process_gain(tool, COEF, u, Z, X, cut, spindle_rpm=rpm, n_angles=720)
    ref = sdm_margin(g.H, system.with_tool_axis(u), rpm, 3).margin
    model = prepare_cut(tool, COEF, u, Z, X, cut, system, rpm)
    b = stability_boundary(model, 0.5 * ref, 2.0 * ref)
    assert abs(b / ref - 1.0) < 0.10


def test_book_2dof_time_domain_confirms_the_time_periodic_minimum():
    """Altintas's Manufacturing Automation (2012) p. 162 tool, non-proportionally damped
    (residue form), two-flute half-immersion down-milling, Kt = 1319.4 and Kr = 788.8
    N/mm^2 (sources: tests/orient/test_stability.py). At the lobe minimum the zero-order
    method allows about 1.01 mm; the full discretization and the time-domain model,
    which knows nothing of averages, both put the boundary near 0.80 mm."""
    from orient.stability import zoa_margin
    from tests.orient.test_stability import BOOK_X, BOOK_Y

    system = ModalSystem.from_residues(BOOK_X[0] + BOOK_Y[0], BOOK_X[1] + BOOK_Y[1],
                                       BOOK_X[2] + BOOK_Y[2],
                                       [(1, 0, 0), (1, 0, 0), (0, 1, 0), (0, 1, 0)],
                                       source="tool")
    coef = CuttingCoefficients(Ktc_N_mm2=1319.4, Krc_N_mm2=788.8, Kac_N_mm2=0.0,
                               Kte0_N_mm=0.0, Kre0_N_mm=0.0, Kae0_N_mm=0.0)
    tool = Tool("flat", 31.75, flutes=2, helix_deg=0.0, flute_length_mm=10.0)
    edges = tool.micro_edges(40, flank_height_mm=DEPTH)
    cut = LocalCut(DEPTH, 31.75 / 2, 1, 0.05)
    rpm = 27400.0
    g = process_gain(tool, coef, Z, Z, X, cut, spindle_rpm=rpm, edges=edges, n_angles=720)
    fdm = sdm_margin(g.H, system, rpm, 2).margin
    zoa = zoa_margin(g.P, system, rpm, 2)
    model = prepare_cut(tool, coef, Z, Z, X, cut, system, rpm, edges=edges)
    b = stability_boundary(model, 0.5 * fdm, 2.0 * fdm)
    assert abs(b / fdm - 1.0) < 0.05
    assert b < 0.85 * zoa


FZ_MM, PICK_MM = 0.1, 0.5


def _ball_cut(lead_deg: float, tilt_deg: float, spr: int | None = None):
    """A D10 ball finishing a wall (normal +Y, feed +X) at a lead/tilt, 9000 min^-1:
    the model and the tool axis."""
    from orient.geometry import posture_axis

    ball = Tool("ball", 10.0, flutes=2, helix_deg=30.0, flute_length_mm=15.0)
    u = posture_axis(Y, X, math.radians(lead_deg), math.radians(tilt_deg))
    cut = LocalCut(0.2, PICK_MM, -1, FZ_MM)
    return prepare_cut(ball, COEF, u, Y, X, cut, _tool_2dof(), 9000.0, steps_per_rev=spr), u


@pytest.mark.parametrize(("lead_deg", "tilt_deg"), [(0.0, 45.0), (30.0, 10.0), (-20.0, 30.0)])
def test_surface_is_generated_where_an_edge_faces_the_surface(lead_deg, tilt_deg):
    """A tilted ball finishing a wall (normal +Y): the rotation samples that generate the
    surface include the one where an engaged edge's outward normal points into the
    surface (-n), and the record is the relative displacement along n averaged over them."""
    model, _ = _ball_cut(lead_deg, tilt_deg)
    w = model.generating
    assert w.sum() == pytest.approx(1.0)
    ptr, _, _, _, nrm, _, _ = model.table
    spt = model.steps_per_tooth
    facing = np.array([float(np.min(nrm[ptr[s]:ptr[s + 1]] @ Y)) / 1e3
                       if ptr[s + 1] > ptr[s] else 1.0 for s in range(model.steps_per_rev)])
    squarest = int(np.argmin(facing)) % spt
    assert facing.min() < -0.999
    assert w[squarest] > 0
    run = simulate(model, 10)
    d = (run.displacement_m @ Y * 1e3).reshape(-1, spt)
    np.testing.assert_allclose(run.surface_offset_mm, d @ w, rtol=1e-12)


def _weights_over_every_entry(table, spr, flutes, n, f, cut, r, edge_step):
    """The generating weights as the docstring states them, each patch point against every
    engaged entry (the function picks among the entries near -n first); the patch's points
    as the function makes them."""
    from sim.constants import STRIP_REACH
    from sim.generation import _patch_normals

    ptr, nrm = table[0], table[4]
    spt = spr // flutes
    unit = nrm / 1e3
    sample = np.repeat(np.arange(spr), np.diff(ptr)) % spt
    w = np.zeros(spt)
    target = _patch_normals(n, f, cut, r)
    dots = target @ unit.T
    best = np.argmax(dots, axis=1)
    ok = dots[np.arange(best.size), best] >= math.cos(
        STRIP_REACH * max(2 * math.pi / spr, edge_step))
    if not ok.any():
        w[sample[int(np.argmin(unit @ n))]] = 1.0
        return w
    np.add.at(w, sample[best[ok]], 1.0)
    return w / w.sum()


@pytest.mark.parametrize("pick_mm", [0.05, PICK_MM, 3.0])
@pytest.mark.parametrize(("lead_deg", "tilt_deg"), [(0.0, 45.0), (30.0, 10.0), (-20.0, 30.0)])
def test_generating_weights_equal_every_entrys_test(lead_deg, tilt_deg, pick_mm):
    """Only the entries near -n are tested against the patch's points: the same weights,
    bit for bit, as testing every engaged entry, from a narrow patch to one wider than the
    engagement (some points reached by no edge)."""
    from orient.geometry import posture_axis
    from sim.generation import edge_spacing_rad, generating_weights

    ball = Tool("ball", 10.0, flutes=2, helix_deg=30.0, flute_length_mm=15.0)
    u = posture_axis(Y, X, math.radians(lead_deg), math.radians(tilt_deg))
    cut = LocalCut(0.2, pick_mm, -1, FZ_MM)
    edges = ball.micro_edges(60)
    model = prepare_cut(ball, COEF, u, Y, X, cut, _tool_2dof(), 9000.0, edges=edges)
    args = (model.table, model.steps_per_rev, 2, Y, X, cut, 5.0, edge_spacing_rad(edges))
    got = generating_weights(*args)
    ref = _weights_over_every_entry(*args)
    assert got.sum() == pytest.approx(1.0)
    np.testing.assert_array_equal(got, ref)
    if pick_mm <= PICK_MM:      # a patch narrower than the engagement: entries left out
        from sim.constants import STRIP_REACH

        facing = -(model.table[4] / 1e3) @ Y
        cone = math.hypot(FZ_MM, pick_mm) / 2 / 5.0 + STRIP_REACH * max(
            2 * math.pi / model.steps_per_rev, edge_spacing_rad(edges)) + 1e-3
        assert np.any(facing < math.cos(cone))


@pytest.mark.parametrize(("lead_deg", "tilt_deg"), [(30.0, 10.0), (30.0, 0.0)])
def test_generating_strip_spans_the_finished_patch(lead_deg, tilt_deg):
    """Where the whole patch (fz along the feed, pick across) lies inside the engagement,
    the rotation it is generated over is the patch's extent along the direction the edge
    normal turns, over the sine of the normal's angle to the axis: a closed form."""
    fz, pick = FZ_MM, PICK_MM
    model, u = _ball_cut(lead_deg, tilt_deg)
    on = np.flatnonzero(model.generating)
    step_deg = 360.0 / model.steps_per_rev
    t = np.cross(u, -Y)
    sin_k = np.linalg.norm(t)
    t /= sin_k
    b = np.cross(Y, X)
    half = (fz / 2 / 5.0 * abs(t @ X) + pick / 2 / 5.0 * abs(t @ b)) / sin_k
    assert (on.max() - on.min() + 1) * step_deg == pytest.approx(2 * math.degrees(half),
                                                                 abs=2 * step_deg)


def test_trailing_edges_rub_with_the_edge_force_where_the_surface_is_generated():
    """The cut keeps the trailing edges (chip 0, material the tooth before left: errpred's
    sliver, orient.engagement(trailing=True)): they rub with the law's zero-chip force and
    no chip term, and the surface is generated among them. On the bundled thin wall
    without them the simulated surface kept 1-2 um less than errpred predicted on every
    tilted pass (the check of the main job's surface ratio failed on that)."""
    from errpred import laws
    from orient.engagement import engagement
    from sim.constants import MICRO_EDGES_ENVELOPE

    model, u = _ball_cut(0.0, 45.0)
    ptr, _pos, edge, h0, _nrm, f0, f1 = model.table
    rub = np.all(f1 == 0.0, axis=1)
    ball = Tool("ball", 10.0, flutes=2, helix_deg=30.0, flute_length_mm=15.0)
    edges = ball.micro_edges(MICRO_EDGES_ENVELOPE)
    cut = LocalCut(0.2, PICK_MM, -1, FZ_MM)
    a = engagement(ball, edges, u, Y, X, cut, n_angles=model.steps_per_rev, trailing=True)
    p = engagement(ball, edges, u, Y, X, cut, n_angles=model.steps_per_rev)
    assert rub.sum() == (a.cutting & ~p.cutting).sum() > 0
    assert np.all(np.any(f0[rub] != 0.0, axis=1))
    # their static chip is what the tooth before left: second order, fz^2 / 2R at most
    assert np.all(h0[rub] >= 0.0) and h0[rub].max() <= FZ_MM ** 2 / 10.0 * (1 + 1e-9)
    assert h0[rub].max() > 0.5 * FZ_MM ** 2 / 10.0
    # their force is the edge force (the law at zero chip): per entry |f0| = |F(0)| db
    ft, fr, fa = laws.force(COEF, np.zeros(int(rub.sum())), edges.kappa[edge[rub]], 0.0)
    np.testing.assert_allclose(np.linalg.norm(f0[rub], axis=1),
                               np.sqrt(ft ** 2 + fr ** 2 + fa ** 2) * edges.db[edge[rub]],
                               rtol=1e-9)
    # the generating samples hold trailing edges: the surface is generated where they rub
    sample = np.repeat(np.arange(model.steps_per_rev), np.diff(ptr)) % model.steps_per_tooth
    assert np.any(model.generating[np.unique(sample[rub])] > 0)


def test_forced_response_is_where_a_stable_cut_settles():
    """The closed-form periodic response to the static chips is the state a long
    time-domain run (with regeneration and the tool free to leave the cut) settles to,
    tooth after tooth (a stable cut: regeneration leaves a tooth-periodic vibration).
    From rest the trailing edges (chip of a fraction of a micrometre, rubbing) start out of
    contact by the static deflection (14 um here) and come back as the passes they miss
    leave their material to the next: 400 revolutions (at 200 one was still out)."""
    from sim.cutting import forced_response

    model, _ = _ball_cut(30.0, 10.0)
    x = forced_response(model)
    run = simulate(model, 400, ramp_revolutions=20)
    for k in (-1, -2):                      # the Poincare section: the start of a tooth
        for col in (0, 1):                  # displacement [m] and velocity [m/s]
            np.testing.assert_allclose(run.modal_state[k][:, col], x[0][:, col], rtol=1e-3,
                                       atol=1e-3 * np.abs(x[0][:, col]).max())
    assert np.abs(x[0]).max() > 0


def test_a_change_of_cut_taken_as_a_machine_moves_does_not_ring():
    """Cut A to steady state, then B (3 deg more tilt): taken through Cutter.switch the
    acceleration is tooth-periodic at once; switched bare, the step of force rings the
    modes for many revolutions."""
    from sim.cutter import Cutter

    a, _ = _ball_cut(30.0, 10.0)
    b, _ = _ball_cut(30.0, 13.0, a.steps_per_rev)
    spr, spt = a.steps_per_rev, a.steps_per_tooth
    ringing = {}
    for smooth in (False, True):
        c = Cutter(spr, a.n_edges)
        c.switch(a)
        c.advance(a, 40 * spr)
        if smooth:
            c.switch(b)
        acc = c.advance(b, 3 * spr).tool_acceleration_m_s2
        d = acc[spt:] - acc[:-spt]               # what is not tooth-periodic
        ringing[smooth] = float(np.sqrt(np.mean(d[:spr] ** 2)))
        forced = float(np.sqrt(np.mean(acc ** 2)))
    assert ringing[False] > 0.05 * forced
    assert ringing[True] < 1e-3 * ringing[False]


def test_blending_a_table_with_itself_or_at_its_ends_is_the_plain_run():
    """Cutter.advance's blend of two engagement tables (a posture changing along a
    segment): a table blended with itself is the table; at weight 0 the run is the
    previous table's, at weight 1 the model's."""
    import dataclasses

    from sim.cutter import Cut, Cutter

    a, _ = _ball_cut(30.0, 10.0)
    b0, _ = _ball_cut(30.0, 13.0, a.steps_per_rev)
    b = dataclasses.replace(a, table=b0.table, generating=b0.generating)   # a's dynamics
    spr = a.steps_per_rev

    def run(model, previous=None, weight=(1.0, 1.0)):
        c = Cutter(spr, a.n_edges)
        c.switch(Cut(model, previous, weight[0]))       # settled on the cut it starts with
        return c.advance(model, 3 * spr, previous=previous, weight=weight).force_N

    same = dataclasses.replace(a)
    np.testing.assert_allclose(run(a, previous=same, weight=(0.2, 0.7)), run(a), rtol=1e-12,
                               atol=1e-12)
    np.testing.assert_allclose(run(a, previous=b, weight=(0.0, 0.0)), run(b), rtol=1e-12,
                               atol=1e-12)
    np.testing.assert_allclose(run(a, previous=b, weight=(1.0, 1.0)), run(a), rtol=1e-12,
                               atol=1e-12)
    mid = run(a, previous=b, weight=(0.5, 0.5))
    assert np.abs(mid - run(a)).max() > 1e-3 * np.abs(mid).max()
    with pytest.raises(ValueError, match="same system"):
        Cutter(spr, a.n_edges).advance(a, 10, previous=b0)


def test_an_unstable_cut_grows_from_the_material_scatter():
    """With the work material's chip-to-chip scatter (``MATERIAL_SCATTER`` per tooth
    pass), a cut at twice the boundary started on its periodic motion (Cutter.switch;
    the linear model) leaves it within 30 revolutions: the once-per-tooth samples
    spread by more than a tenth of the vibration. At half the boundary the same
    scatter leaves a spread of the order of the scatter itself."""
    import dataclasses

    from sim.constants import MATERIAL_SCATTER
    from sim.cutter import Cutter

    rpm = 9000.0
    ref = _fdm_margin(rpm)

    def spread(scale: float, scatter: bool) -> float:
        k = {f.name: scale * ref * getattr(COEF, f.name) for f in dataclasses.fields(COEF)
             if f.name.endswith(("_N_mm2", "_N_mm"))}
        model = prepare_cut(FLAT, dataclasses.replace(COEF, **k), Z, Z, X, HALF_DOWN,
                            _tool_2dof(), rpm, edges=EDGES)
        spt, spr = model.steps_per_tooth, model.steps_per_rev
        c = Cutter(spr, model.n_edges)
        c.switch(model)
        rng = np.random.default_rng(7)
        disp = []
        for _ in range(30):
            v = None
            if scatter:
                v = np.repeat(1.0 + MATERIAL_SCATTER * rng.standard_normal(model.flutes), spt)
            disp.append(c.advance(model, spr, linear=True, variation=v).displacement_m[:, :2])
        d = np.concatenate(disp)
        p = d[::spt][-10 * model.flutes:]          # once per tooth: 0 for a forced motion
        return float(np.ptp(p, axis=0).max() / np.ptp(d[-spr:], axis=0).max())

    assert spread(2.0, scatter=True) > 0.1
    assert spread(0.5, scatter=True) < 10 * MATERIAL_SCATTER


@pytest.mark.parametrize("zeta", [0.002, 0.03, 0.3, 0.95, 0.995, 1.0, 2.5])
def test_the_step_map_is_the_exact_discretization(zeta):
    """The closed-form step map of each mode equals the matrix exponential of its state
    equation (Van Loan's block form), lightly damped to overdamped."""
    import scipy.linalg

    from sim.cutting import _step_map

    rng = np.random.default_rng(5)
    f_hz = rng.uniform(200.0, 20_000.0, 4)
    k = rng.uniform(1e6, 1e9, 4)
    system = ModalSystem.from_modes([(Mode.from_frequency(f, zeta, kk), (1, 0, 0))
                                     for f, kk in zip(f_hz, k)], source="tool")
    dt = 1.0 / (24 * f_hz.max())
    phi, gam = _step_map(system, dt)
    for j in range(4):
        m, c, kk = system.m_kg[j], system.c_Ns_m[j], system.k_N_m[j]
        big = np.zeros((3, 3))
        big[:2, :2] = [[0.0, 1.0], [-kk / m, -c / m]]
        big[1, 2] = 1.0 / m
        ex = scipy.linalg.expm(big * dt)
        np.testing.assert_allclose(phi[j], ex[:2, :2], rtol=1e-9, atol=1e-12 * np.abs(ex[:2, :2]).max())
        np.testing.assert_allclose(gam[j], ex[:2, 2], rtol=1e-9, atol=1e-12 * np.abs(ex[:2, 2]).max())


def test_cutter_switch_takes_the_places_the_cuts_engage():
    """Cutter.switch's places of the surface memory (flat indices from the tables) are
    those of :func:`sim.forced.engaged_cells`' masks, and the surface it leaves is the
    one the masks give (bit for bit), for a change of cut and a blend. The places of
    the last cuts are kept (a switch asks for its old cut's, the one before's new):
    asked again in another order, and for a blend whose other part has no share, they
    are still the masks'."""
    from sim.cutter import Cut, Cutter
    from sim.forced import engaged_cells, forced_response, mid_step_displacement

    a, _ = _ball_cut(30.0, 10.0)
    b, _ = _ball_cut(30.0, 13.0, a.steps_per_rev)
    spr, m = a.steps_per_rev, a.n_edges
    c = Cutter(spr, m)
    for cut in (Cut(a), Cut(b, a, 0.4), Cut(b), Cut(b, a, 0.4), Cut(a), Cut(b, a, 1.0),
                Cut(b, a, 0.0), Cut(a, b, 0.7)):
        mask = np.zeros((spr, m), bool)
        for mod, _w in cut.parts():
            mask |= engaged_cells(mod, m)
        assert np.array_equal(c._engaged(cut), np.flatnonzero(mask))
    c.switch(a)
    c.advance(a, 5 * spr + 7)
    before, p = c.surface.copy(), c.step % spr
    q_a = mid_step_displacement(a, forced_response(a))
    q_b = mid_step_displacement(b, forced_response(b))
    c.switch(b)
    on_a, on_b = engaged_cells(a, m), engaged_cells(b, m)
    both = on_a & on_b
    ref = before.copy()
    rows, cols = both.nonzero()
    ref[rows, cols] += (q_b - q_a)[rows]
    rows, cols = (on_b & ~both).nonzero()
    ref[rows, cols] = q_b[rows]
    assert both.any() and (on_b & ~both).any() and p > 0
    np.testing.assert_array_equal(c.surface, ref)


def _tooth_surface_twin(disp_m, model, first_step, generating=None):
    """numpy twin of :func:`sim.generation.tooth_surface` (its former code: each tooth's
    sums by ``np.bincount``)."""
    w_tooth = model.generating if generating is None else generating
    n = disp_m.shape[0]
    if n == 0 or not w_tooth.any():
        return np.zeros(0)
    spt = model.steps_per_tooth
    steps = first_step + np.arange(n)
    w = w_tooth[steps % spt]
    tooth = steps // spt - first_step // spt
    num = np.bincount(tooth, w * (disp_m @ model.normal))
    den = np.bincount(tooth, w)
    keep = den > 0.5
    return num[keep] / den[keep] * 1e3


def test_advance_pieces_is_advance_piece_by_piece_bit_for_bit():
    """The cutter's pieces in one kernel call (a stretch of servo ticks between two cutter
    locations) give what advance gives piece by piece: the blend going from piece to
    piece, the material's scatter, the generated surface per piece, the clock, the
    modal state and the surface memory; and the idle pieces as idle does."""
    import dataclasses

    from sim.cutter import Cut, Cutter
    from sim.generation import tooth_surfaces

    a, _ = _ball_cut(30.0, 10.0)
    b0, _ = _ball_cut(30.0, 13.0, a.steps_per_rev)
    b = dataclasses.replace(a, table=b0.table, generating=b0.generating)
    spr = a.steps_per_rev
    counts = [7, 613, 1, 1500, 2 * spr + 3, 240]
    w = np.array([0.0, 0.004, 0.4, 0.4004, 0.66, 0.99, 1.0])
    rng = np.random.default_rng(5)
    v = 1.0 + 0.01 * rng.standard_normal(sum(counts))
    one, many = Cutter(spr, a.n_edges), Cutter(spr, a.n_edges)
    for c in (one, many):
        c.switch(Cut(a, b, 0.0))
        c.advance(a, 333, previous=b, weight=(0.0, 0.0))
    runs, k = [], 0
    for p, n in enumerate(counts):
        runs.append(one.advance(a, n, previous=b, weight=(w[p], w[p + 1]),
                                variation=v[k:k + n]))
        k += n
    run, teeth = many.advance_pieces(a, counts, previous=b, weights=(w[:-1], w[1:]),
                                     variation=v)
    for key in ("time_s", "force_N", "displacement_m", "tool_acceleration_m_s2",
                "chip_mean_mm", "contact_loss", "surface_offset_mm"):
        np.testing.assert_array_equal(getattr(run, key),
                                      np.concatenate([getattr(r, key) for r in runs]))
    np.testing.assert_array_equal(teeth, [r.surface_offset_mm.size for r in runs])
    assert teeth.sum() > 5
    for x, y in ((one.state, many.state), (one.surface, many.surface)):
        np.testing.assert_array_equal(x, y)
    assert (one.step, one.time_s) == (many.step, many.time_s)
    assert many.cut.same_as(one.cut)
    idle = [one.idle(a.dt_s, n, a.system) for n in counts[:3]]
    free = many.idle_pieces(a.dt_s, counts[:3], a.system)
    np.testing.assert_array_equal(free.tool_acceleration_m_s2,
                                  np.concatenate([r.tool_acceleration_m_s2 for r in idle]))
    np.testing.assert_array_equal(free.time_s, np.concatenate([r.time_s for r in idle]))
    np.testing.assert_array_equal(one.state, many.state)
    assert many.cut is None and one.time_s == many.time_s
    # the surface of pieces at once, with and without their own generating weights
    d = rng.normal(0.0, 1e-6, (sum(counts), 3))
    starts = 11 + np.cumsum(counts) - counts
    g = rng.random((len(counts), a.steps_per_tooth)) * (rng.random(a.steps_per_tooth) < 0.1)
    for gen in (None, g):
        got, per = tooth_surfaces(d, a, starts, counts, gen)
        want = [_tooth_surface_twin(d[s - 11:s - 11 + n], a, s,
                                    None if gen is None else gen[p])
                for p, (s, n) in enumerate(zip(starts, counts))]
        np.testing.assert_array_equal(got, np.concatenate(want))
        np.testing.assert_array_equal(per, [x.size for x in want])
    with pytest.raises(ValueError, match="weights"):
        many.advance_pieces(a, counts, previous=b, weights=(w[:-1], w[1:] + 0.5))


def test_tooth_surfaces_of_pieces_with_an_empty_one_are_each_pieces_bit_for_bit():
    """Pieces at once (sim._kernels.tooth_sums) against each piece's numpy twin (bincount),
    and each piece's own tooth_surface, with an empty piece, a piece within one tooth and
    pieces across several, with and without their own generating weights."""
    from sim.generation import tooth_surface, tooth_surfaces

    a, _ = _ball_cut(30.0, 10.0)
    spt = a.steps_per_tooth
    counts = np.array([5, 0, spt - 3, 3 * spt + 11, 0, 2])
    starts = 1_000_003 + np.cumsum(counts) - counts
    rng = np.random.default_rng(11)
    d = rng.normal(0.0, 1e-6, (int(counts.sum()), 3))
    g = rng.random((counts.size, spt)) * (rng.random(spt) < 0.2)
    for gen in (None, g):
        got, per = tooth_surfaces(d, a, starts, counts, gen)
        rows = np.cumsum(counts) - counts
        want = [_tooth_surface_twin(d[r:r + n], a, s, None if gen is None else gen[p])
                for p, (r, s, n) in enumerate(zip(rows, starts, counts))]
        for p, (r, s, n) in enumerate(zip(rows, starts, counts)):
            one = tooth_surface(d[r:r + n], a, s, None if gen is None else gen[p])
            np.testing.assert_array_equal(one, want[p])
        assert sum(x.size for x in want) > 3
        np.testing.assert_array_equal(got, np.concatenate(want))
        np.testing.assert_array_equal(per, [x.size for x in want])
    # the kernel reads by the counts and the weights' shape: both checked first
    with pytest.raises(ValueError, match="counts"):
        tooth_surfaces(d[:-1], a, starts, counts)
    with pytest.raises(ValueError, match="generating"):
        tooth_surfaces(d, a, starts, counts, g[:-1])


def _forced_eigen(model):
    """The forced response computed another way: in each mode's step-map eigenvectors,
    where every component is a first-order filter (``w_p = lam^p w_0 + z t_p``), scipy's
    lfilter per mode and eigenvalue and the periodic start ``w_0 = z t_spr / (1 -
    lam^spr)`` (how sim.forced computed it before its real-arithmetic kernel)."""
    import scipy.signal

    ptr, _pos, _e, h0, _nrm, f0, f1 = model.table
    spr, nm = model.steps_per_rev, model.system.n_modes
    sample = np.repeat(np.arange(spr), np.diff(ptr))
    fe = 1.0 * (f0 + h0[:, None] * f1)
    force = np.stack([np.bincount(sample, fe[:, a], minlength=spr) for a in range(3)], axis=1)
    u = force @ model.system.direction.T
    phi, gam = model.step_map
    lam, vec = np.linalg.eig(phi)
    z = np.linalg.solve(vec, gam[..., None].astype(complex))[..., 0]
    tail = np.empty((spr + 1, nm, 2), complex)
    uc = np.zeros((nm, spr + 1), complex)
    uc[:, :spr] = u.T
    for m in range(nm):
        for i in range(2):
            tail[:, m, i] = scipy.signal.lfilter(np.array([0.0, 1.0]),
                                                 np.array([1.0, -lam[m, i]]), uc[m])
    w0 = z * tail[spr] / (1.0 - lam ** spr)
    w = np.cumprod(np.concatenate([np.ones((1, nm, 2), complex),
                                   np.broadcast_to(lam, (spr - 1, nm, 2))]), axis=0)
    w = w * w0[None] + z[None] * tail[:-1]
    return np.einsum("mij,pmj->pmi", vec, w).real


def test_forced_response_is_the_eigenvector_filters_answer():
    """The forced response (real 2 x 2 steps, sim._kernels.periodic_forced) equals the
    same periodic solution computed in the step maps' eigenvectors with scipy's lfilter,
    to rounding (1e-10 of its largest value), for two tables on the same dynamics and
    for other dynamics (three tool modes); and it is periodic: one more step from its
    last row gives its first."""
    import dataclasses

    from errpred.dynamics import Mode
    from sim.cutting import with_system
    from sim.forced import forced_response

    a, u = _ball_cut(30.0, 10.0)
    b0, _ = _ball_cut(30.0, 13.0, a.steps_per_rev)
    b = dataclasses.replace(a, table=b0.table, generating=b0.generating)
    modes = [(Mode.from_frequency(f, 0.02, 2e6), d) for f, d in
             ((700.0, (1, 0, 0)), (1300.0, (0, 1, 0)), (2900.0, (0.6, 0.8, 0)))]
    c = with_system(b, ModalSystem.from_modes(modes, source="tool"), u)
    for m in (a, b, c):
        ref = _forced_eigen(m)
        got = forced_response(m)
        assert np.abs(ref).max() > 0
        for col in (0, 1):          # displacement [m] and velocity [m/s]: own scales
            np.testing.assert_allclose(got[..., col], ref[..., col], rtol=0,
                                       atol=1e-10 * np.abs(ref[..., col]).max())
        # x[spr] = phi x[spr - 1] + gam u[spr - 1] is x[0]
        ptr, _pos, _e, h0, _nrm, f0, f1 = m.table
        last = np.arange(ptr[-2], ptr[-1])
        u_last = (f0[last] + h0[last, None] * f1[last]).sum(axis=0) @ m.system.direction.T
        phi, gam = m.step_map
        nxt = np.einsum("mij,mj->mi", phi, got[-1]) + gam * u_last[:, None]
        np.testing.assert_allclose(nxt, got[0], rtol=1e-9, atol=1e-12 * np.abs(got).max())
    np.testing.assert_array_equal(forced_response(a, scale=0.0), 0.0)
    # an undamped mode whose step map returns to itself over a revolution has no periodic
    # response to a force: refused, not a state of inf or NaN
    phi, gam = a.step_map
    still = dataclasses.replace(a, step_map=(np.broadcast_to(np.eye(2), phi.shape).copy(), gam))
    with pytest.raises(ValueError, match="undamped"):
        forced_response(still)
    one, scaled = forced_response(a), forced_response(a, scale=2.5)
    for col in (0, 1):              # linear in the force, to rounding
        np.testing.assert_allclose(scaled[..., col], 2.5 * one[..., col], rtol=0,
                                   atol=1e-10 * np.abs(one[..., col]).max())


def test_a_model_refuses_a_table_out_of_the_kernels_order():
    """A table whose entries at a sample do not ascend by (position, edge) would have the
    kernel write a place of the surface twice: the model refuses it, naming the sample."""
    import dataclasses

    system, coef, slot = _insperger_case()
    four = Tool("flat", 10.0, flutes=4, helix_deg=0.0, flute_length_mm=6.0)
    model = prepare_cut(four, coef, Z, Z, X, slot, system, 5000.0, edges=EDGES)
    ptr, pos, edge = model.table[:3]
    i = int(np.flatnonzero(np.diff(ptr) >= 2)[0])
    a, b = ptr[i], ptr[i + 1]
    swapped = tuple(np.concatenate([x[:a], x[a:b][::-1], x[b:]]) for x in model.table[1:])
    with pytest.raises(ValueError, match=f"rotation sample {i} "):
        dataclasses.replace(model, table=(ptr, *swapped))
