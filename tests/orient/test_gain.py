"""Directional matrices and the average process gain (orient.gain).

References: Altintas & Budak (1995), "Analytical prediction of stability lobes
in milling", CIRP Annals 44(1) 357-362, eqs. for the directional factors
a_xx(phi) .. a_yy(phi) and their averages alpha_xx .. alpha_yy; Altintas,
Manufacturing Automation (2nd ed., 2012), section 3.4.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from errpred.coefficients import CuttingCoefficients
from errpred.tool import Tool
from orient.engagement import LocalCut, engagement, place
from orient.gain import (
    GainResolution,
    default_edges,
    directional_gain,
    directional_matrices,
    gain_from_engagement,
    process_gain,
    process_gain_batch,
    restricted,
)
from orient.geometry import posture_axis

COEF = CuttingCoefficients(Ktc_N_mm2=2000.0, Krc_N_mm2=700.0, Kac_N_mm2=300.0,
                           Kte0_N_mm=20.0, Kre0_N_mm=25.0, Kae0_N_mm=5.0)
Z, X, Y = np.eye(3)[2], np.eye(3)[0], np.eye(3)[1]
BALL = Tool("ball", 10.0, flutes=2, helix_deg=30.0, flute_length_mm=15.0)


def _random_cases(n, seed, concave=True):
    rng = np.random.default_rng(seed)
    cases = []
    for _ in range(n):
        nrm = rng.normal(size=3) * [0.4, 0.4, 1.0]
        feed = rng.normal(size=3)
        lead, tilt = np.radians(rng.uniform(-30, 30, 2))
        kmin = -0.04 if concave else 0.0
        cut = LocalCut(rng.uniform(0.05, 0.5), rng.uniform(0.1, 1.0), int(rng.integers(-1, 2)),
                       rng.uniform(0.02, 0.15),
                       rng.uniform(kmin, 0.04) * (rng.random() < 0.5),
                       rng.uniform(kmin, 0.04) * (rng.random() < 0.5))
        cases.append((posture_axis(nrm, feed, lead, tilt), nrm, feed, cut))
    return cases


# --- (a) flat end mill, straight flutes, side cut: Altintas & Budak ------------------

def _alpha(phi_st, phi_ex, kr):
    """Average directional factors alpha (2 x 2) of Altintas & Budak (1995)."""
    def prim(p):
        return 0.5 * np.array([
            [math.cos(2 * p) - 2 * kr * p + kr * math.sin(2 * p),
             -math.sin(2 * p) - 2 * p + kr * math.cos(2 * p)],
            [-math.sin(2 * p) + 2 * p + kr * math.cos(2 * p),
             -math.cos(2 * p) - 2 * kr * p - kr * math.sin(2 * p)]])
    return prim(phi_ex) - prim(phi_st)


def _a_factors_integral(lo, hi, kr):
    """Integral over [lo, hi] of the time-varying factors a_ij(phi) of A&B (1995)."""
    def prim(p):
        return np.array([
            [0.5 * math.cos(2 * p) - kr * (p - 0.5 * math.sin(2 * p)),
             -(p + 0.5 * math.sin(2 * p)) + 0.5 * kr * math.cos(2 * p)],
            [(p - 0.5 * math.sin(2 * p)) + 0.5 * kr * math.cos(2 * p),
             -0.5 * math.cos(2 * p) - kr * (p + 0.5 * math.sin(2 * p))]])
    return prim(hi) - prim(lo)


@pytest.mark.parametrize("ae_over_d", [0.1, 0.25, 0.5, 0.8])
@pytest.mark.parametrize("flutes", [2, 4])
def test_flat_end_mill_side_cut_equals_altintas_budak(ae_over_d, flutes):
    """Vertical axis, feed +X, previous pass at +pick b (b = +Y): the material
    is y < pick - R, a down-milling cut of radial width ae = pick, entering at
    phi_st = acos(2 ae / D - 1) and leaving at phi_ex = pi (errpred's phi is
    A&B's: from +y toward +x, feed +x). A&B: F = (1/2) a Kt [A] Delta with
    average (N / 2 pi) [alpha], so P = a Kt N / (4 pi) [alpha] (x 1000 N/m);
    the z row (errpred's axial convention, Fz' = -Fa on the flank) is
    P_zx = a Kac N / (2 pi) (cos phi_ex - cos phi_st),
    P_zy = -a Kac N / (2 pi) (sin phi_ex - sin phi_st)."""
    D, a = 10.0, 2.0
    tool = Tool("flat", D, flutes=flutes, helix_deg=0.0, flute_length_mm=6.0)
    ae = ae_over_d * D
    g = process_gain(tool, COEF, Z, Z, X, LocalCut(a, ae, 1, 0.05), n_angles=72 * flutes)
    phi_st, phi_ex = math.acos(2 * ae_over_d - 1), math.pi
    kr = COEF.Krc_N_mm2 / COEF.Ktc_N_mm2
    expected = np.zeros((3, 3))
    expected[:2, :2] = a * COEF.Ktc_N_mm2 * flutes / (4 * math.pi) * _alpha(phi_st, phi_ex, kr)
    expected[2, 0] = a * COEF.Kac_N_mm2 * flutes / (2 * math.pi) * (math.cos(phi_ex)
                                                                     - math.cos(phi_st))
    expected[2, 1] = -a * COEF.Kac_N_mm2 * flutes / (2 * math.pi) * (math.sin(phi_ex)
                                                                      - math.sin(phi_st))
    expected *= 1000.0
    scale = np.abs(expected).max()
    # default (adaptive) resolution: the depth's edge is located by bisection
    np.testing.assert_allclose(g.P, expected, atol=0.01 * scale)
    # micro edges that tile the flank up to the depth exactly: exact to the roots
    edges = tool.micro_edges(40, flank_height_mm=a)
    assert edges.db[edges.segment == 2].sum() == pytest.approx(a, abs=1e-12)
    exact = process_gain(tool, COEF, Z, Z, X, LocalCut(a, ae, 1, 0.05), edges=edges)
    np.testing.assert_allclose(exact.P, expected, atol=1e-6 * scale)
    assert g.engaged_fraction == pytest.approx(min(1.0, (phi_ex - phi_st) * flutes
                                                    / (2 * math.pi)), abs=1e-6)
    assert g.cut_sense == 0.0                                           # v normal to n


def test_flat_end_mill_time_varying_h_is_the_textbook_form():
    """H(t) over the tooth period: step averages of (a Kt / 2) sum_j g_j a(phi_j)
    (A&B 1995), integrated in closed form per step; and the point-sampled H of
    directional_matrices with the textbook mask equals the textbook pointwise."""
    D, a, flutes, ae = 10.0, 1.5, 3, 3.0
    tool = Tool("flat", D, flutes=flutes, helix_deg=0.0, flute_length_mm=6.0)
    n_ang = 36 * flutes
    edges = tool.micro_edges(40, flank_height_mm=a)    # tiles the flank up to a exactly
    g = process_gain(tool, COEF, Z, Z, X, LocalCut(a, ae, 1, 0.05), n_angles=n_ang, edges=edges)
    k = n_ang // flutes
    phi_st, kr = math.acos(2 * ae / D - 1), COEF.Krc_N_mm2 / COEF.Ktc_N_mm2
    step = 2 * math.pi / n_ang
    expected = np.zeros((k, 2, 2))
    for i in range(k):
        for p in range(flutes):          # flute p sits 2 pi p / N ahead (errpred)
            lo = i * step + 2 * math.pi * p / flutes
            for shift in (-2 * math.pi, 0.0, 2 * math.pi):
                a0, b0 = max(lo + shift, phi_st), min(lo + step + shift, math.pi)
                if b0 > a0:
                    expected[i] += _a_factors_integral(a0, b0, kr)
    expected *= 0.5 * a * COEF.Ktc_N_mm2 / step * 1000.0
    # the entry angle is a root refined to GAIN_ROOT_TOL_RAD = 1e-6 rad: in a step
    # of 0.058 rad that is 2e-5 of the step's value
    np.testing.assert_allclose(g.H[:, :2, :2], expected, atol=1e-4 * np.abs(expected).max())
    np.testing.assert_allclose(g.H.mean(axis=0), g.P, atol=1e-9 * np.abs(g.P).max())
    # point samples with the textbook mask (phi_st < phi < pi on the flank below a)
    theta = np.arange(n_ang) * step + 0.5 * step
    phi = (theta[:, None, None] + 2 * math.pi / flutes * np.arange(flutes)[None, :, None]
           + 0 * edges.z[None, None, :])
    wrapped = np.mod(phi, 2 * math.pi)
    mask = (wrapped > phi_st) & (wrapped < math.pi) & (edges.segment == 2)[None, None, :]
    frame = place(tool, Z, Z, X).frame
    Hs = directional_matrices(tool, edges, COEF, frame, phi, mask)
    depth = edges.db[edges.segment == 2].sum()
    pointwise = np.zeros((k, 2, 2))
    for i in range(k):
        for p in range(flutes):
            ph = wrapped[i, p, 0]
            if phi_st < ph < math.pi:
                s2, c2 = math.sin(2 * ph), math.cos(2 * ph)
                pointwise[i] += np.array([[-s2 - kr * (1 - c2), -(1 + c2) - kr * s2],
                                          [(1 - c2) - kr * s2, s2 - kr * (1 + c2)]])
    pointwise *= 0.5 * depth * COEF.Ktc_N_mm2 * 1000.0
    np.testing.assert_allclose(Hs[:, :2, :2], pointwise, atol=1e-9 * np.abs(pointwise).max())


# --- (b) symmetry ------------------------------------------------------------------

def test_vertical_ball_slot_gain_has_the_half_revolution_symmetry():
    """Lead 0, tilt 0, no previous pass, flat: every micro edge cuts phi in
    [0, pi], so the in-plane block is a rotation-symmetric (P_xx = P_yy,
    P_xy = -P_yx) and P_zy = 0; velocity normal to n: cut_sense 0."""
    g = process_gain(BALL, COEF, Z, Z, X, LocalCut(0.4, 0.0, 0, 0.05))
    s = np.abs(g.P).max()
    assert g.P[0, 0] == pytest.approx(g.P[1, 1], abs=1e-9 * s)
    assert g.P[0, 1] == pytest.approx(-g.P[1, 0], abs=1e-9 * s)
    assert abs(g.P[2, 1]) < 1e-9 * s and abs(g.P[0, 1]) > 0.01 * s
    assert g.cut_sense == 0.0
    assert g.engaged_fraction == pytest.approx(1.0)


@pytest.mark.parametrize("lead,tilt,side", [(15.0, 0.0, 0), (-10.0, 20.0, 0), (10.0, 12.0, 1),
                                            (25.0, -8.0, -1)])
def test_counter_clockwise_tool_is_the_mirror_image(lead, tilt, side):
    """Mirroring the cut in the plane of f and n (b -> -b) turns a clockwise tool
    into a counter-clockwise one, the tilt and the previous pass's side into
    their opposites: P_ccw(tilt, side) = M P_cw(-tilt, -side) M, M = diag(1,-1,1)
    in (f, b, n); the up/down-cut degree is a scalar of the mirror."""
    ccw = Tool("ball", 10.0, flutes=2, helix_deg=30.0, flute_length_mm=15.0, rotation="ccw")
    M = np.diag([1.0, -1.0, 1.0])
    cut_cw = LocalCut(0.3, 0.6, -side, 0.05)
    cut_ccw = LocalCut(0.3, 0.6, side, 0.05)
    u_cw = posture_axis(Z, X, math.radians(lead), -math.radians(tilt))
    u_ccw = posture_axis(Z, X, math.radians(lead), math.radians(tilt))
    # the same micro edges: exact mirror images (to the roots' tolerance)
    edges = BALL.micro_edges(60)
    g_cw = process_gain(BALL, COEF, u_cw, Z, X, cut_cw, edges=edges)
    g_ccw = process_gain(ccw, COEF, u_ccw, Z, X, cut_ccw, edges=edges)
    s = np.abs(g_cw.P).max()
    np.testing.assert_allclose(g_ccw.P, M @ g_cw.P @ M, atol=1e-5 * s)
    assert g_ccw.cut_sense == pytest.approx(g_cw.cut_sense, abs=1e-6)
    assert g_ccw.engaged_fraction == pytest.approx(g_cw.engaged_fraction, abs=1e-6)
    # the adaptive default samples the mirrored circles from their other ends:
    # equal within its discretization
    d_cw = process_gain(BALL, COEF, u_cw, Z, X, cut_cw)
    d_ccw = process_gain(ccw, COEF, u_ccw, Z, X, cut_ccw)
    np.testing.assert_allclose(d_ccw.P, M @ d_cw.P @ M, atol=2e-3 * s)


# --- (c) up-cut and down-cut -------------------------------------------------------

@pytest.mark.parametrize("side", [-1, 0, 1])
def test_tilt_sign_and_cut_sense(side):
    """Clockwise spindle, zero lead on a flat surface: every engaged edge moves
    with v.n = -sin(phi) sin(tilt) and sin(phi) > 0 where it cuts, so positive
    tilt (axis toward -b) is a pure down-cut (-1), negative tilt a pure up-cut."""
    cut = LocalCut(0.3, 0.6, side, 0.05)
    for tilt, expected in ((15.0, -1.0), (-15.0, 1.0)):
        g = process_gain(BALL, COEF, posture_axis(Z, X, 0.0, math.radians(tilt)), Z, X, cut)
        assert g.cut_sense == pytest.approx(expected, abs=1e-12)
        ccw = Tool("ball", 10.0, flutes=2, helix_deg=30.0, flute_length_mm=15.0,
                   rotation="ccw")
        g2 = process_gain(ccw, COEF, posture_axis(Z, X, 0.0, math.radians(tilt)), Z, X, cut)
        assert g2.cut_sense == pytest.approx(-expected, abs=1e-12)


@pytest.mark.parametrize("lead,tilt", [(20.0, 10.0), (-15.0, 25.0), (10.0, -5.0)])
def test_mirrored_tilt_and_side_mirror_the_cut_sense(lead, tilt):
    """With the previous pass on one side the cut is asymmetric; mirroring tilt
    and side (b -> -b, same clockwise spindle) reverses every edge velocity's
    normal component: cut_sense(tilt, side) = -cut_sense(-tilt, -side)."""
    u1 = posture_axis(Z, X, math.radians(lead), math.radians(tilt))
    u2 = posture_axis(Z, X, math.radians(lead), -math.radians(tilt))
    g1 = process_gain(BALL, COEF, u1, Z, X, LocalCut(0.3, 0.6, 1, 0.05))
    g2 = process_gain(BALL, COEF, u2, Z, X, LocalCut(0.3, 0.6, -1, 0.05))
    assert abs(g1.cut_sense) > 0.05
    assert g1.cut_sense == pytest.approx(-g2.cut_sense, abs=1e-9)
    # and the sampled engagement (errpred's chip thickness and sample grid) agrees
    edges = default_edges(BALL)
    gs = gain_from_engagement(BALL, edges, COEF, engagement(BALL, edges, u1, Z, X,
                                                            LocalCut(0.3, 0.6, 1, 0.05), 720))
    assert gs.cut_sense == pytest.approx(g1.cut_sense, abs=0.02)


# --- (d) linear scaling --------------------------------------------------------------

def test_gain_scales_with_chip_width_and_not_with_feed():
    tool = Tool("flat", 10.0, flutes=3, helix_deg=0.0, flute_length_mm=8.0)
    edges_a = tool.micro_edges(40, flank_height_mm=1.0)      # the flank up to 1 mm ...
    edges_2a = tool.micro_edges(40, flank_height_mm=2.0)     # ... and up to 2 mm, exactly
    g1 = process_gain(tool, COEF, Z, Z, X, LocalCut(1.0, 3.0, 1, 0.05), edges=edges_a)
    g2 = process_gain(tool, COEF, Z, Z, X, LocalCut(2.0, 3.0, 1, 0.05), edges=edges_2a)
    np.testing.assert_allclose(g2.P, 2 * g1.P, atol=1e-9 * np.abs(g1.P).max())
    assert g2.engaged_fraction == pytest.approx(g1.engaged_fraction)
    d1 = process_gain(tool, COEF, Z, Z, X, LocalCut(1.0, 3.0, 1, 0.05))
    d2 = process_gain(tool, COEF, Z, Z, X, LocalCut(2.0, 3.0, 1, 0.05))
    np.testing.assert_allclose(d2.P, 2 * d1.P, atol=0.01 * np.abs(d1.P).max())
    u = posture_axis(Z, X, 0.2, -0.3)
    edges = BALL.micro_edges(40)
    wide = type(edges)(edges.rho, edges.z, edges.kappa, edges.psi, 2.5 * edges.db, edges.ds,
                       edges.segment, edges.s)
    cut = LocalCut(0.3, 0.5, 1, 0.05)
    p1 = process_gain(BALL, COEF, u, Z, X, cut, edges=edges)
    p2 = process_gain(BALL, COEF, u, Z, X, cut, edges=wide)
    np.testing.assert_allclose(p2.P, 2.5 * p1.P, atol=1e-12 * np.abs(p1.P).max())
    p3 = process_gain(BALL, COEF, u, Z, X, LocalCut(0.3, 0.5, 1, 0.1), edges=edges)
    np.testing.assert_allclose(p3.P, p1.P, atol=1e-12 * np.abs(p1.P).max())
    assert p3.mean_chip_mm == pytest.approx(2 * p1.mean_chip_mm)


# --- the exact integration against sampled engagements ---------------------------------

@pytest.mark.parametrize("case", range(3))
def test_exact_gain_equals_the_sampled_gain_in_the_limit(case):
    """Same micro edges: the closed-form time integral (orient._kernels, its own
    unit vectors) against H sampled with errpred.force.to_tool_frame's unit
    vectors and errpred's chip thickness; converging as the samples refine."""
    u, n, feed, cut = _random_cases(3, 11 + case, concave=False)[case]
    edges = default_edges(BALL)
    # a fine root search: islands of material narrower than the default 10 deg
    # sampling step along a circle can be stepped over (case 0 has one)
    exact = process_gain(BALL, COEF, u, n, feed, cut, edges=edges,
                         resolution=GainResolution(root_step_rad=math.radians(0.5)))
    errs = []
    for n_ang in (180, 720, 2880):
        s = gain_from_engagement(BALL, edges, COEF, engagement(BALL, edges, u, n, feed, cut,
                                                               n_ang))
        errs.append(np.linalg.norm(s.P - exact.P) / np.linalg.norm(exact.P))
    assert errs[-1] < 2e-3 and errs[-1] < errs[0]
    assert s.mean_chip_mm == pytest.approx(exact.mean_chip_mm, rel=5e-3)
    assert s.engaged_fraction == pytest.approx(exact.engaged_fraction, abs=0.01)


def test_step_averages_of_h_match_finely_sampled_h():
    u = posture_axis(Z, X, math.radians(12), math.radians(-8))
    cut = LocalCut(0.3, 0.6, 1, 0.05)
    edges = default_edges(BALL)
    k_rev = 60
    exact = process_gain(BALL, COEF, u, Z, X, cut, edges=edges, n_angles=k_rev)
    sub = 48
    fine = gain_from_engagement(BALL, edges, COEF,
                                engagement(BALL, edges, u, Z, X, cut, k_rev * sub))
    # fine samples sit at the starts of sub-steps: shift by half a sub-step is
    # second order; average the sub-steps of each step
    Hf = fine.H.reshape(k_rev // BALL.flutes, sub, 3, 3).mean(axis=1)
    s = np.abs(exact.H).max()
    assert np.abs(Hf - exact.H).max() < 0.03 * s
    assert np.abs(exact.H.mean(axis=0) - exact.P).max() < 1e-12 * s


# --- batch, convergence, edge cases ---------------------------------------------------

def test_batch_equals_single_postures():
    cases = _random_cases(12, 21)
    U = np.array([c[0] for c in cases])
    N = np.array([c[1] for c in cases])
    F = np.array([c[2] for c in cases])
    cuts = [c[3] for c in cases]
    batch = process_gain_batch(BALL, COEF, U, N, F, cuts)
    par = process_gain_batch(BALL, COEF, U, N, F, cuts, parallel=True, threads=3)
    nonzero = 0
    for i, (u, n, f, cut) in enumerate(cases):
        g = process_gain(BALL, COEF, u, n, f, cut, n_angles=2 * BALL.flutes)
        s = max(np.abs(g.P).max(), 1e-300)
        np.testing.assert_allclose(batch.P[i], g.P, rtol=0, atol=1e-9 * s)
        np.testing.assert_array_equal(par.P[i], batch.P[i])
        assert batch.cut_sense[i] == pytest.approx(g.cut_sense, abs=1e-9)
        assert batch.engaged_fraction[i] == pytest.approx(g.engaged_fraction, abs=1e-9)
        assert batch.mean_chip_mm[i] == pytest.approx(g.mean_chip_mm, rel=1e-9)
        nonzero += bool(np.abs(g.P).max() > 0)
    assert nonzero >= 10
    # grid broadcasting: K postures at each of L points
    lead = np.radians(np.linspace(-20, 20, 5))
    axes = posture_axis(N[:3, None, :], F[:3, None, :], lead, 0.1)
    grid = process_gain_batch(BALL, COEF, axes, N[:3, None, :], F[:3, None, :],
                              np.array(cuts[:3], dtype=object)[:, None])
    assert grid.P.shape == (3, 5, 3, 3)
    g = process_gain(BALL, COEF, axes[2, 4], N[2], F[2], cuts[2])
    np.testing.assert_allclose(grid.P[2, 4], g.P, atol=1e-9 * max(np.abs(g.P).max(), 1e-300))


def test_default_resolution_converges():
    """P at the default resolution within 2 % (Frobenius) of P at 4x finer, over
    random finishing cuts (ball end mill; flat, convex and concave surfaces,
    with and without a previous pass)."""
    cases = _random_cases(40, 7)
    U, N, F = (np.array([c[i] for c in cases]) for i in range(3))
    cuts = [c[3] for c in cases]
    coarse = process_gain_batch(BALL, COEF, U, N, F, cuts)
    fine = process_gain_batch(BALL, COEF, U, N, F, cuts, resolution=GainResolution().finer(4))
    norm = np.linalg.norm(fine.P, axis=(1, 2))
    ok = norm > 0
    assert ok.sum() >= 35
    err = np.linalg.norm(coarse.P - fine.P, axis=(1, 2))[ok] / norm[ok]
    assert err.max() < 0.02
    assert np.median(err) < 0.005


def test_zero_depth_and_missed_material_give_zero_gain():
    u = posture_axis(Z, X, 0.3, -0.2)
    for cut in (LocalCut(0.0, 0.5, 1, 0.05), LocalCut(0.3, 0.0, -1, 0.05)):
        g = process_gain(BALL, COEF, u, Z, X, cut, spindle_rpm=10000.0)
        assert np.all(g.P == 0) and np.all(g.H == 0)
        assert g.engaged_fraction == 0 and g.cut_sense == 0 and g.mean_chip_mm == 0
        assert g.tooth_period_s == pytest.approx(60 / (10000 * 2))
        b = process_gain_batch(BALL, COEF, u, Z, X, cut)
        assert np.all(b.P == 0) and b.engaged_fraction == 0


def test_directional_and_restricted_gain():
    g = process_gain(BALL, COEF, posture_axis(Z, X, 0.2, 0.1), Z, X, LocalCut(0.3, 0.5, 1, 0.05))
    P = g.P
    assert directional_gain(P, X) == pytest.approx(P[0, 0])
    e = np.array([1.0, 2.0, -0.5])
    assert directional_gain(P, 3 * e) == pytest.approx(e @ P @ e / (e @ e))
    E = np.linalg.qr(np.random.default_rng(2).normal(size=(3, 2)))[0]
    np.testing.assert_allclose(restricted(P, E), E.T @ P @ E)
    np.testing.assert_allclose(restricted(P, np.eye(3)[:, :2]), P[:2, :2])
    with pytest.raises(ValueError, match="E"):
        restricted(P, np.ones((3, 2)))
    with pytest.raises(ValueError, match="direction"):
        directional_gain(P, np.zeros(3))


def test_refuses_bad_input():
    cut = LocalCut(0.3, 0.5, 1, 0.05)
    with pytest.raises(ValueError, match="spindle_rpm"):
        process_gain(BALL, COEF, Z, Z, X, cut, spindle_rpm=math.nan)
    with pytest.raises(ValueError, match="posture_axis"):
        process_gain_batch(BALL, COEF, [[0.0, 0.0, -1.0]], Z, X, cut)
    with pytest.raises(ValueError, match="feed_dir"):
        process_gain_batch(BALL, COEF, Z, Z, Z, cut)
    with pytest.raises(ValueError, match="cut"):
        process_gain_batch(BALL, COEF, np.tile(Z, (3, 1)), Z, X, [cut, cut])
    with pytest.raises(ValueError, match="resolution.piece_edges"):
        GainResolution(piece_edges=0)
    with pytest.raises(ValueError, match="phi"):
        directional_matrices(BALL, default_edges(BALL), COEF, np.eye(3), np.zeros((5, 2, 3)),
                             np.zeros((5, 2, 3), dtype=bool))


@pytest.mark.parametrize("tilt_deg", [20.0, 30.0, 45.0])
@pytest.mark.parametrize("kf, kb", [(-0.081, 0.0), (0.0, -0.081), (-0.081, -0.03)])
def test_a_concave_top_under_a_tilted_ball_keeps_its_engagement(tilt_deg, kf, kb):
    """The concave curvature (-0.081 1/mm) a mold core's raster gave, under a ball tilted
    20-45 deg: the adaptive exact gain against the gain of the sampled engagement.
    The concave stock-top bound once let the flank far above the contact pass for
    material, the band of the profile that can cut grew to the whole flank, its probes
    missed the true band and the gain was 0 from 30 deg on. The two sides place micro
    edges differently (adaptive against default_edges): on the flat top at the same
    postures they differ by 0.4-1.2 %, the concave ones by 0.1-2.3 %; a lost band is
    a difference of 100 %, so 5 % tells the two apart.
    The mold core's tool: 20 mm of flute (with 15 mm the flank stayed out of the bound)."""
    tool = Tool("ball", 10.0, flutes=2, helix_deg=30.0, flute_length_mm=20.0)
    u = posture_axis(Z, X, 0.0, math.radians(tilt_deg))
    cut = LocalCut(0.15, 0.35, 1, 0.08, kf, kb)
    exact = process_gain(tool, COEF, u, Z, X, cut)
    edges = default_edges(tool)
    s = gain_from_engagement(tool, edges, COEF, engagement(tool, edges, u, Z, X, cut, 720))
    assert exact.engaged_fraction > 0.05
    assert np.linalg.norm(s.P - exact.P) / np.linalg.norm(s.P) < 0.05
    assert exact.engaged_fraction == pytest.approx(s.engaged_fraction, abs=0.01)


@pytest.mark.parametrize("n", [1, 2, 5, 13, 40, 300])
def test_union_order_sorts_by_start(n):
    """The engaged-time union's order (a Shell sort) sorts the rows' starts, each row once,
    ties in any order: the union merged from it is the one np.argsort's order gives."""
    from orient._kernels import _order

    rng = np.random.default_rng(n)
    union = np.zeros((n + 7, 2))
    union[:n, 0] = rng.integers(0, max(n // 3, 1), n) * 0.25   # ties
    union[:n, 1] = union[:n, 0] + rng.random(n)
    got = _order(union, n)
    assert sorted(got.tolist()) == list(range(n))
    np.testing.assert_array_equal(union[got, 0], np.sort(union[:n, 0]))
