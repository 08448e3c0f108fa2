"""Stability analysis of orient: ZOA and time-periodic (full discretization).

Benchmarks and their sources
----------------------------
1-DOF milling model of Insperger & Stepan (IJNME 61 (2004) 117-141, "Updated
semi-discretization method ...", section on the 1-DOF milling model), also the
benchmark of Ding, Zhu, Zhang, Ding (IJMTM 50 (2010) 502-509, "A
full-discretization method for prediction of milling stability"): modal mass
m = 0.03993 kg, natural frequency 922 Hz, damping ratio 0.011, Kt = 6e8 N/m^2,
Kn = 2e8 N/m^2, 2 teeth, down-milling, a/D = 1 and 0.05; the tool is flexible
in the feed direction x. (Values checked against the public implementation
of Ding et al.'s method in github.com/leekunhwee/Dynamics,
Cutting/Stability/TimeDomain/FullDis/FulldisOneDOFMilling.m, which uses
k = 1340049.648 N/m = m wn^2.) The papers show the lobes as charts only, so
the minima are checked against the closed form of the zero-order method
(Altintas & Budak, CIRP Annals 44(1) (1995) 357-362; Altintas, Manufacturing
Automation, 2nd ed., 2012, ch. 3.6): for one mode along x,
``a_lim = -2 pi / (N Kt alpha_xx Re G)`` at the extremum of ``Re G``, i.e.
``a_lim = 8 pi k zeta (1 + zeta) / (N Kt |alpha_xx|)`` when ``alpha_xx < 0``
(``min Re G = -1 / (4 k zeta (1 + zeta))``) and ``8 pi k zeta (1 - zeta) / (N Kt
alpha_xx)`` when ``alpha_xx > 0``, with Altintas' average directional factor
``alpha_xx = 1/2 [cos 2phi - 2 Kr phi + Kr sin 2phi]`` from phi_st to phi_ex.

2-DOF: the cutting data of Altintas & Budak's example (Kt = 796 N/mm^2,
Kr = 0.212, four flutes, half-immersion up-milling; Altintas, Manufacturing
Automation, 2nd ed., ch. 3) on the symmetric 2-DOF tool of Ding et al.
2010's 2-DOF example (x and y: 922 Hz, zeta 0.011, k = 1340049.648 N/m); the
reference is Altintas & Budak's closed-form quadratic eigenvalue solution
(``a0 Lambda^2 + a1 Lambda + 1 = 0``, ``a_lim = -2 pi Lambda_R (1 + kappa^2) / (N Kt)``)
evaluated here on its own fine frequency grid.

2-DOF with the book's own tool: the measured FRF of Manufacturing Automation,
2nd ed. (2012), p. 162, in residue form (x: 452.77 and 1448.53 Hz, zeta 0.123718
and 0.01651; y: 516.17 and 1407.64 Hz, zeta 0.0243 and 0.0324; complex
residues below, non-proportional damping), as transcribed in the public
implementation github.com/leekunhwee/Vibration-Signal-Processing (FRF
generation, residue form after Altintas), and its cutting data there: Kt =
1319.4 N/mm^2, Kr = 788.8 N/mm^2 (the radial force coefficient, Kr/Kt =
0.598), two flutes, half-immersion down-milling. The zero-order reference is
again the closed form, evaluated on the book's FRF itself.
"""

from __future__ import annotations

import csv
import math
import os
from pathlib import Path

import numpy as np
import pytest
from numba import njit
from scipy.optimize import minimize_scalar

from errpred.dynamics import Mode
from orient.dynamics import ModalSystem, minimal_rotation
from orient.plots_lobes import plot_lobes
from orient.stability import (
    StraightEndMill2D,
    default_steps,
    floquet_multipliers,
    sdm_margin,
    stability_lobes,
    zoa_critical,
    zoa_frequency_grid,
    zoa_lobes,
    zoa_margin,
    zoa_margin_batch,
)
from orient.stability.sdm import _active_states, _Fdm, _monodromy, _monodromy_numpy, _remap
from orient.stability.zoa import zoa_margin_detail

# --- benchmark data (sources in the module docstring) ----------------------
M_KG = 0.03993
FN_HZ = 922.0
ZETA = 0.011
K_N_M = 1340049.648            # = M_KG (2 pi FN_HZ)^2
KT_1DOF, KN_1DOF = 6e8, 2e8    # N/m^2
KT_AB, KR_AB = 796e6, 0.212    # N/m^2, -


def _mode() -> Mode:
    wn = 2 * math.pi * FN_HZ
    m = K_N_M / wn**2
    return Mode(K_N_M, m, 2 * ZETA * math.sqrt(K_N_M * m))


def _sys_1dof() -> ModalSystem:
    return ModalSystem.from_modes([(_mode(), (1.0, 0.0, 0.0))])


def _sys_2dof() -> ModalSystem:
    return ModalSystem.from_modes([(_mode(), (1.0, 0.0, 0.0)), (_mode(), (0.0, 1.0, 0.0))])


def _alpha(st: float, ex: float, kr: float) -> np.ndarray:
    """Altintas' average directional factors [[axx, axy], [ayx, ayy]] (his sign)."""
    def a(p):
        return np.array([[np.cos(2 * p) - 2 * kr * p + kr * np.sin(2 * p),
                          -np.sin(2 * p) - 2 * p + kr * np.cos(2 * p)],
                         [-np.sin(2 * p) + 2 * p + kr * np.cos(2 * p),
                          -np.cos(2 * p) - 2 * kr * p - kr * np.sin(2 * p)]]) / 2
    return a(ex) - a(st)


def _alim_1dof_closed_form(ad: float, milling: str, teeth: int) -> float:
    """Zero-order limiting depth [mm] of the 1-DOF benchmark (Altintas & Budak closed form)."""
    st, ex = StraightEndMill2D(KT_1DOF, KN_1DOF, teeth, ad, milling).angles
    axx = _alpha(st, ex, KN_1DOF / KT_1DOF)[0, 0]
    if axx < 0:
        return 8e3 * math.pi * K_N_M * ZETA * (1 + ZETA) / (teeth * KT_1DOF * -axx)
    return 8e3 * math.pi * K_N_M * ZETA * (1 - ZETA) / (teeth * KT_1DOF * axx)


# ---------------------------------------------------------------------- milling2d
def test_directional_matrix_matches_insperger_and_altintas():
    tool = StraightEndMill2D(KT_1DOF, KN_1DOF, 2, 1.0, "down", depth_mm=2.0)
    phi = np.linspace(0.05, 3.0, 7)
    h = tool.directional_matrix(phi)
    w = 2e-3
    # Insperger & Stepan's 1-DOF: H_xx = -w sum g sin(phi) (Kt cos phi + Kn sin phi)
    hxx = -w * np.sin(phi) * (KT_1DOF * np.cos(phi) + KN_1DOF * np.sin(phi))
    assert np.allclose(h[:, 0, 0], hxx, rtol=1e-12)
    # Altintas: F = a Kt / 2 A(t) with a_xy = -(1 + cos 2phi) - Kr sin 2phi etc.
    kr = KN_1DOF / KT_1DOF
    axy = -(1 + np.cos(2 * phi)) - kr * np.sin(2 * phi)
    ayx = (1 - np.cos(2 * phi)) - kr * np.sin(2 * phi)
    ayy = np.sin(2 * phi) - kr * (1 + np.cos(2 * phi))
    assert np.allclose(h[:, 0, 1], w * KT_1DOF / 2 * axy, rtol=1e-12)
    assert np.allclose(h[:, 1, 0], w * KT_1DOF / 2 * ayx, rtol=1e-12)
    assert np.allclose(h[:, 1, 1], w * KT_1DOF / 2 * ayy, rtol=1e-12)
    assert np.all(h[:, 2, :] == 0) and np.all(h[:, :, 2] == 0)


@pytest.mark.parametrize("ad,milling", [(1.0, "down"), (0.05, "down"), (0.5, "up"),
                                        (0.3, "up")])
def test_mean_directional_matrix_closed_form_and_samples(ad, milling):
    tool = StraightEndMill2D(KT_AB, KR_AB * KT_AB, 4, ad, milling, depth_mm=1.0)
    p = tool.mean_directional_matrix()
    st, ex = tool.angles
    # Altintas: P = depth N Kt / (4 pi) alpha
    ref = 1e-3 * 4 * KT_AB / (4 * math.pi) * _alpha(st, ex, KR_AB)
    assert np.allclose(p[:2, :2], ref, rtol=1e-12, atol=1e-9)
    # the step averages keep the mean exactly, and are the averages of the point values
    for k in (20, 40, 37):
        hk = tool.directional_samples(k)
        assert np.allclose(hk.mean(axis=0), p, rtol=0, atol=1e-12 * np.abs(p).max())
        sub = 4000                                  # midpoint rule on each step
        phi = 2 * math.pi / (4 * k) * (np.arange(k)[:, None] + (np.arange(sub) + 0.5) / sub)
        num = tool.directional_matrix(phi).mean(axis=1)
        assert np.allclose(hk, num, rtol=0, atol=2e-3 * np.abs(hk).max())


# ---------------------------------------------------------------------- ZOA
@pytest.mark.parametrize("ad,milling", [(1.0, "down"), (0.05, "down")])
def test_zoa_1dof_minimum_matches_closed_form(ad, milling):
    tool = StraightEndMill2D(KT_1DOF, KN_1DOF, 2, ad, milling, depth_mm=1.0)
    ref = _alim_1dof_closed_form(ad, milling, 2)
    crit = zoa_critical(tool.mean_directional_matrix(), _sys_1dof())
    assert crit.margin == pytest.approx(ref, rel=1e-5)           # depth 1 mm -> mm
    rpm = np.linspace(5000, 25000, 801)
    lobes = zoa_lobes(tool.mean_directional_matrix(), _sys_1dof(), 2, rpm)
    assert lobes.min() == pytest.approx(ref, rel=0.01)
    assert np.all(lobes >= ref * (1 - 1e-6))
    if ad == 1.0:   # slotting: Kt drops out of the x-x average, a_lim = 4 k zeta (1+zeta) / Kn
        assert ref == pytest.approx(4 * K_N_M * ZETA * (1 + ZETA) / KN_1DOF * 1e3, rel=1e-12)


def _altintas_budak_alim(ad: float, milling: str, teeth: int, omega: np.ndarray) -> np.ndarray:
    """Altintas & Budak's closed form over ``omega``: a_lim [m] per frequency (positive only)."""
    st, ex = StraightEndMill2D(KT_AB, KR_AB * KT_AB, teeth, ad, milling).angles
    mode = _mode()
    phi = 1.0 / (mode.k_N_m - mode.m_kg * omega**2 + 1j * mode.c_Ns_m * omega)
    return _ab_quadratic(_alpha(st, ex, KR_AB), phi, phi, teeth, KT_AB)


def _ab_quadratic(a: np.ndarray, phi_xx: np.ndarray, phi_yy: np.ndarray, teeth: int,
                  kt: float) -> np.ndarray:
    """Altintas & Budak: ``a0 Lambda^2 + a1 Lambda + 1 = 0`` per frequency, a_lim [m]
    (positive ones) for directional factors ``a`` and direct FRFs ``phi_xx``, ``phi_yy``."""
    a0 = phi_xx * phi_yy * (a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0])
    a1 = a[0, 0] * phi_xx + a[1, 1] * phi_yy
    out = []
    for sign in (1, -1):
        lam = -(a1 + sign * np.sqrt(a1 * a1 - 4 * a0)) / (2 * a0)
        kappa = lam.imag / lam.real
        out.append(-2 * math.pi * lam.real * (1 + kappa**2) / (teeth * kt))
    alim = np.concatenate(out)
    return alim[alim > 0]


def test_zoa_2dof_matches_altintas_budak_closed_form():
    tool = StraightEndMill2D(KT_AB, KR_AB * KT_AB, 4, 0.5, "up", depth_mm=1.0)
    omega = 2 * math.pi * np.linspace(800.0, 1200.0, 400001)
    ref_mm = _altintas_budak_alim(0.5, "up", 4, omega).min() * 1e3
    crit = zoa_critical(tool.mean_directional_matrix(), _sys_2dof())
    assert crit.margin == pytest.approx(ref_mm, rel=1e-4)
    rpm = np.linspace(5000, 40000, 1401)
    lobes = zoa_lobes(tool.mean_directional_matrix(), _sys_2dof(), 4, rpm)
    assert lobes.min() == pytest.approx(ref_mm, rel=0.01)


# --- the book's 2-DOF tool (sources in the module docstring) ---------------------
BOOK_X = ((452.77, 1448.53), (0.123718, 0.01651),
          (9.202966e-05 - 1.862195e-04j, -4.181562e-05 - 3.043618e-04j))
BOOK_Y = ((516.17, 1407.64), (0.0243, 0.0324),
          (-2.3929e-06 - 1.721539e-04j, 4.055052e-05 - 3.618808e-04j))
KT_BOOK, KR_BOOK = 1319.4e6, 788.8 / 1319.4          # N/m^2, -


def _sys_book() -> ModalSystem:
    return ModalSystem.from_residues(BOOK_X[0] + BOOK_Y[0], BOOK_X[1] + BOOK_Y[1],
                                     BOOK_X[2] + BOOK_Y[2],
                                     [(1, 0, 0), (1, 0, 0), (0, 1, 0), (0, 1, 0)])


def _book_frf(w: np.ndarray, modes) -> np.ndarray:
    """The residue form itself: ``sum R / (i w - p) + conj(R) / (i w - conj(p))``."""
    g = np.zeros_like(w, dtype=complex)
    for f, z, r in zip(*modes, strict=True):
        wn = 2 * math.pi * f
        p = complex(-z * wn, wn * math.sqrt(1 - z * z))
        g += r / (1j * w - p) + np.conj(r) / (1j * w - np.conj(p))
    return g


def _book_closed_form(kt: float, kr: float, teeth: int, ad: float, milling: str) -> float:
    """Altintas & Budak's zero-order minimum [mm] on the book's FRF (fine grid)."""
    st, ex = StraightEndMill2D(kt, kr * kt, teeth, ad, milling).angles
    w = 2 * math.pi * np.linspace(50.0, 4000.0, 400001)
    alim = _ab_quadratic(_alpha(st, ex, kr), _book_frf(w, BOOK_X), _book_frf(w, BOOK_Y),
                         teeth, kt)
    return float(alim.min() * 1e3)


def test_book_frf_from_residues():
    """The non-proportional modes reproduce the residue form to round-off."""
    sys = _sys_book()
    w = 2 * math.pi * np.linspace(10.0, 3000.0, 300)
    g = sys.frf(w)
    np.testing.assert_allclose(g[:, 0, 0], _book_frf(w, BOOK_X), rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(g[:, 1, 1], _book_frf(w, BOOK_Y), rtol=1e-12, atol=1e-18)
    assert np.all(g[:, 0, 1] == 0)
    assert np.any(sys.velocity_s != 0)


BOOK_CASES = [  # (Kt, Kr, teeth, a/D, milling, speeds of the lobe minimum [rev/min])
    (KT_BOOK, KR_BOOK, 2, 0.5, "down", (24000.0, 31000.0)),     # the book's data
    (KT_AB, KR_AB, 4, 0.5, "down", (7500.0, 9500.0)),
    (KT_AB, KR_AB, 4, 1.0, "down", (13000.0, 16000.0)),
    (KT_AB, KR_AB, 4, 0.5, "up", (13000.0, 16500.0)),
]


@pytest.mark.parametrize("kt, kr, teeth, ad, milling, _speeds", BOOK_CASES)
def test_zoa_book_2dof_equals_the_closed_form(kt, kr, teeth, ad, milling, _speeds):
    ref = _book_closed_form(kt, kr, teeth, ad, milling)
    tool = StraightEndMill2D(kt, kr * kt, teeth, ad, milling, depth_mm=1.0)
    crit = zoa_critical(tool.mean_directional_matrix(), _sys_book())
    assert crit.margin == pytest.approx(ref, rel=1e-4)
    lobes = zoa_lobes(tool.mean_directional_matrix(), _sys_book(), teeth,
                      np.linspace(2000.0, 30000.0, 1401))
    assert lobes.min() == pytest.approx(ref, rel=0.01)


def _fdm_book_min(kt, kr, teeth, ad, milling, speeds, n=15):
    tool = StraightEndMill2D(kt, kr * kt, teeth, ad, milling, depth_mm=1.0)
    h = tool.directional_samples(tool.recommended_samples())
    rpm = np.linspace(*speeds, n)
    res = [sdm_margin(h, _sys_book(), float(r), teeth) for r in rpm]
    i = int(np.argmin([r.margin for r in res]))
    # refine around the coarse minimum
    fine = np.linspace(rpm[max(i - 1, 0)], rpm[min(i + 1, n - 1)], 9)
    res2 = [sdm_margin(h, _sys_book(), float(r), teeth) for r in fine]
    j = int(np.argmin([r.margin for r in res2]))
    return res2[j].margin, res2[j].kind


@pytest.mark.parametrize("case", [1, 2])
def test_fdm_book_2dof_minimum_matches_where_the_average_holds(case):
    """Four flutes, down-milling at half immersion and slotting: the time-periodic
    minimum is within 5 % of the zero-order closed form."""
    kt, kr, teeth, ad, milling, speeds = BOOK_CASES[case]
    ref = _book_closed_form(kt, kr, teeth, ad, milling)
    m, _kind = _fdm_book_min(kt, kr, teeth, ad, milling, speeds)
    assert abs(m / ref - 1.0) < 0.05


def test_fdm_book_2dof_lower_lobes_the_average_misses():
    """Where the cut is intermittent the methods part (method.md §7): with the book's
    own data (two flutes, half immersion) the time-periodic minimum is a Hopf lobe
    about 20 % below the zero-order one (the time-domain simulation confirms it:
    tests/sim/test_cutting.py); with four flutes up-milling a flip lobe near half the
    tooth frequency lies about 30 % below."""
    kt, kr, teeth, ad, milling, speeds = BOOK_CASES[0]
    ref = _book_closed_form(kt, kr, teeth, ad, milling)
    m, kind = _fdm_book_min(kt, kr, teeth, ad, milling, speeds)
    assert m < 0.85 * ref and kind == "hopf"
    kt, kr, teeth, ad, milling, speeds = BOOK_CASES[3]
    ref = _book_closed_form(kt, kr, teeth, ad, milling)
    m, kind = _fdm_book_min(kt, kr, teeth, ad, milling, speeds)
    assert m < 0.8 * ref and kind == "flip"


def _sys_asym(n: int = 3) -> ModalSystem:
    """Three modes with skew directions (illustrative data for the invariance checks)."""
    rng = np.random.default_rng(3)
    d = rng.normal(size=(3, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    modes = [Mode.from_frequency(600, 0.035, 5.6e6), Mode.from_frequency(660, 0.03, 7.5e6),
             Mode.from_frequency(900, 0.02, 3e6)]
    return ModalSystem.from_modes(list(zip(modes[:n], d[:n], strict=True)))


def _p_asym() -> np.ndarray:
    p = StraightEndMill2D(KT_AB, KR_AB * KT_AB, 4, 0.5, "up").mean_directional_matrix()
    p[2, :2] = [0.3 * p[0, 0], -0.2 * p[1, 1]]                # some axial gain
    p[:2, 2] = [0.1 * p[0, 0], 0.05 * p[1, 1]]
    p[2, 2] = -0.4 * abs(p[0, 0])
    return p


@pytest.mark.parametrize("rpm", [3000.0, 7321.0, 15000.0])
def test_zoa_margin_solves_characteristic_equation_by_brute_force(rpm):
    """Brute force: scan real s and w for zeros of det(I - s (1 - e^{-i w tau}) P G(i w))
    (as the cubic 1 - c1 s + c2 s^2 - c3 s^3 in s per frequency), without eigenvalue
    branches or phase conditions; the first s with a zero must be the margin."""
    sys, p = _sys_asym(), _p_asym()
    teeth = 4
    tau = 60.0 / (rpm * teeth)
    res = zoa_margin_detail(p, sys, rpm, teeth)
    z = 1 - np.exp(-1j * res.omega_rad_s * tau)
    mat = np.eye(3) - res.margin * z * p @ sys.frf(res.omega_rad_s)
    sv = np.linalg.svd(mat, compute_uv=False)
    assert sv[-1] < 1e-7 * sv[0]
    w = np.linspace(0.6, 1.8, 40001) * 2 * math.pi * 600.0
    a = (1 - np.exp(-1j * w * tau))[:, None, None] * np.einsum("ij,wjk->wik", p, sys.frf(w))
    c1 = np.trace(a, axis1=1, axis2=2)
    c2 = 0.5 * (c1**2 - np.trace(a @ a, axis1=1, axis2=2))
    c3 = np.linalg.det(a)
    s_grid = np.linspace(0.5, 1.5, 1001) * res.margin
    dets = np.abs(1 - np.outer(s_grid, c1) + np.outer(s_grid**2, c2)
                  - np.outer(s_grid**3, c3)).min(axis=1)
    i = int(np.argmin(dets))
    assert s_grid[i] == pytest.approx(res.margin, rel=0.002)
    assert dets[s_grid < 0.99 * res.margin].min() > 5 * dets[i]


def test_zoa_invariant_under_rotation():
    sys, p = _sys_asym(), _p_asym()
    r = minimal_rotation(np.array([0.3, -0.5, 0.8]))
    rz = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    rot = rz @ r
    for rpm in (4000.0, 9000.0):
        a = zoa_margin(p, sys, rpm, 4)
        b = zoa_margin(rot @ p @ rot.T, sys.rotated(rot), rpm, 4)
        assert b == pytest.approx(a, rel=1e-9)
    assert zoa_critical(rot @ p @ rot.T, sys.rotated(rot)).margin == \
        pytest.approx(zoa_critical(p, sys).margin, rel=1e-9)


def test_zoa_restriction_to_one_direction_is_scalar_gain():
    sys, p = _sys_asym(), _p_asym()
    e = np.array([0.6, 0.0, 0.8])
    # restricted: only e^T P e along e, and only the compliance e^T G e matters
    restricted = zoa_critical(p, sys, restrict=e).margin
    w = np.linspace(0.3, 3.0, 400001) * 2 * math.pi * 600.0
    ge = np.einsum("i,wij,j->w", e, sys.frf(w), e)
    lam = (e @ p @ e) * ge
    assert restricted == pytest.approx(1 / (2 * lam.real.max()), rel=1e-4)


def test_zero_gain_and_bad_input():
    sys = _sys_1dof()
    assert zoa_margin(np.zeros((3, 3)), sys, 9000, 2) == math.inf
    assert zoa_critical(np.zeros((3, 3)), sys).margin == math.inf
    assert np.all(np.isinf(zoa_margin_batch(np.zeros((4, 3, 3)), sys, 9000, 2)))
    assert sdm_margin(np.zeros((20, 3, 3)), sys, 9000, 2).margin == math.inf
    p = np.full((3, 3), np.nan)
    with pytest.raises(ValueError, match="P"):
        zoa_margin(p, sys, 9000, 2)
    with pytest.raises(ValueError, match="spindle_rpm"):
        zoa_margin(np.zeros((3, 3)), sys, float("nan"), 2)
    with pytest.raises(ValueError, match="H_samples"):
        sdm_margin(np.full((10, 3, 3), np.nan), sys, 9000, 2)
    with pytest.raises(ValueError, match="P"):
        zoa_margin_batch(np.full((2, 3, 3), np.inf), sys, 9000, 2)
    with pytest.raises(ValueError, match="teeth"):
        zoa_margin(np.zeros((3, 3)), sys, 9000, 0)


def test_batch_matches_single_calls_and_tool_axes():
    base = ModalSystem.from_modes([(Mode.from_frequency(600, 0.035, 5.6e6), (1, 0, 0)),
                                   (Mode.from_frequency(660, 0.03, 7.5e6), (0, 1, 0))],
                                  source="tool")
    wp = ModalSystem.from_modes([(Mode.from_frequency(900, 0.02, 3e6), (0, 0.6, 0.8))])
    sys = ModalSystem.combine(base, wp)
    rng = np.random.default_rng(7)
    p0 = _p_asym()
    rots = [minimal_rotation(v / np.linalg.norm(v))
            for v in rng.normal([0, 0, 3], 1.0, size=(12, 3))]
    p = np.array([r @ p0 @ r.T for r in rots])
    rpm = rng.uniform(3000, 15000, size=12)
    out = zoa_margin_batch(p, sys, rpm, 4)
    single = np.array([zoa_margin(p[i], sys, rpm[i], 4) for i in range(12)])
    assert np.allclose(out, single, rtol=1e-12)
    axes = rng.normal([0, 0, 2], 0.5, size=(12, 3))
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    md = sys.directions_for_axes(axes)
    out2 = zoa_margin_batch(p, sys, rpm, 4, mode_directions=md)
    single2 = np.array([zoa_margin(p[i], sys.with_tool_axis(axes[i]), rpm[i], 4)
                        for i in range(12)])
    assert np.allclose(out2, single2, rtol=1e-9)
    assert not np.allclose(out2, out)


def test_default_grid_converged_with_close_and_far_modes():
    """The default ZOA grid (thinned where the bands of close modes overlap) gives the
    margins of a 4x denser grid: a tool pair and five wall-like modes along one
    normal, three of them within 5 % of each other (as at a thin-wall point)."""
    tool = ModalSystem.from_modes([(Mode.from_frequency(3600, 0.03, 1.6e7), (1, 0, 0)),
                                   (Mode.from_frequency(3700, 0.03, 1.7e7), (0, 1, 0))],
                                  source="tool")
    wall = ModalSystem.from_modes(
        [(Mode.from_frequency(f, 0.01, k), (0, 0.6, 0.8))
         for f, k in ((3540, 7.2e6), (5290, 6.5e6), (9870, 2.0e7), (18180, 1.1e8),
                      (20700, 2.6e8))])
    sys = ModalSystem.combine(tool, wall)
    grid = zoa_frequency_grid(sys)
    wn = sys.natural_frequency_rad_s
    assert grid.size < 41 * wn.size + 32          # thinned where bands overlap
    fine = np.unique(np.concatenate([grid] + [grid[:-1] + f * np.diff(grid)
                                            for f in (0.25, 0.5, 0.75)]))
    rng = np.random.default_rng(11)
    p0 = _p_asym()
    rots = [minimal_rotation(v / np.linalg.norm(v))
            for v in rng.normal([0, 0, 3], 1.0, size=(60, 3))]
    p = np.array([r @ p0 @ r.T for r in rots]) * rng.uniform(0.2, 5.0, size=(60, 1, 1))
    rpm = rng.uniform(4000, 16000, size=60)
    m = zoa_margin_batch(p, sys, rpm, 2)
    m_fine = zoa_margin_batch(p, sys, rpm, 2, omega_rad_s=fine)
    assert np.all(np.isfinite(m))
    np.testing.assert_allclose(m, m_fine, rtol=1e-6)


# ---------------------------------------------------------------------- time-periodic
def test_fdm_equals_zoa_for_a_constant_directional_matrix():
    """With H(t) = P constant the zero-order equation is exact for the delayed system:
    the time-periodic margin must tend to it, to second order in the step."""
    sys, p = _sys_asym(2), _p_asym()
    h = np.repeat(p[None], 40, axis=0)
    for rpm in (5000.0, 11000.0):
        exact = zoa_margin(p, sys, rpm, 4)
        e1 = abs(sdm_margin(h, sys, rpm, 4).margin / exact - 1)
        k = default_steps(sys, rpm, 4)
        e2 = abs(sdm_margin(h, sys, rpm, 4, steps=2 * k).margin / exact - 1)
        assert e1 < 0.01
        assert e2 < e1 / 3


def _fdm_min(tool, sys, lo, hi, steps=None):
    h = tool.directional_samples(steps or 40)
    res = minimize_scalar(lambda r: sdm_margin(h, sys, r, tool.teeth, steps=steps).margin,
                          bounds=(lo, hi), method="bounded", options={"xatol": 1.0})
    return res.x, res.fun


def test_fdm_converges_under_refinement():
    tool = StraightEndMill2D(KT_1DOF, KN_1DOF, 2, 1.0, "down", depth_mm=1.0)
    sys = _sys_1dof()
    for rpm in (15870.0, 19000.0):
        a = sdm_margin(tool.directional_samples(40), sys, rpm, 2).margin
        b = sdm_margin(tool.directional_samples(80), sys, rpm, 2, steps=80).margin
        assert abs(a - b) < 0.01 * b
    low = StraightEndMill2D(KT_1DOF, KN_1DOF, 2, 0.05, "down", depth_mm=1.0)
    k = low.recommended_samples()                      # 168: 24 samples in the cut
    a = sdm_margin(low.directional_samples(k), sys, 18200.0, 2)
    b = sdm_margin(low.directional_samples(2 * k), sys, 18200.0, 2)
    assert a.kind == b.kind == "flip"
    assert abs(a.margin - b.margin) < 0.01 * b.margin


# Converged limits of the 1-DOF benchmark on the grid 5,000-25,000 rev/min (every 500),
# a/D 0.05, 0.1, 0.5, 1, up and down milling: sdm_margin at L, 2L, 4L (8L, 16L) steps
# per tooth period with 16 exact sub-steps, Richardson-extrapolated (the method is
# second order); relative uncertainty below 2e-4. Regenerate with
# scripts/sdm_benchmark_table.py (its docstring gives the details).
TABLE_1DOF = Path(__file__).parent / "data" / "sdm_1dof_converged.csv"


def _table_1dof() -> list[dict]:
    with open(TABLE_1DOF) as f:
        return list(csv.DictReader(line for line in f if not line.startswith("#")))


@pytest.mark.parametrize("milling", ["up", "down"])
@pytest.mark.parametrize("ad", [0.05, 0.1, 0.5, 1.0])
def test_defaults_on_the_1dof_benchmark_grid(ad, milling):
    """The default time-periodic margin (recommended samples, default steps and error
    control) is within 1 % of the converged limit and at most 0.5 % above it
    (sdm_margin's docstring claim)."""
    rows = [r for r in _table_1dof()
            if r["milling"] == milling and float(r["radial_immersion"]) == ad]
    assert len(rows) == 41
    assert all(float(r["uncertainty_mm"]) < 2e-4 * float(r["limit_mm"]) for r in rows)
    tool = StraightEndMill2D(KT_1DOF, KN_1DOF, 2, ad, milling, depth_mm=1.0)
    h = tool.directional_samples(tool.recommended_samples())
    sys = _sys_1dof()
    err = np.array([sdm_margin(h, sys, float(r["rpm"]), 2).margin / float(r["limit_mm"]) - 1
                    for r in rows])
    assert err.max() <= 0.005, (err.max(), rows[int(err.argmax())]["rpm"])
    assert np.abs(err).max() <= 0.01, (err.min(), rows[int(err.argmin())]["rpm"])


def test_table_limits_converge_at_second_order():
    """Spot check of the table: two refinements of one row reproduce its limit, and the
    differences shrink four-fold (second order: the coefficient is integrated exactly)."""
    row = next(r for r in _table_1dof() if r["milling"] == "down"
               and float(r["radial_immersion"]) == 0.05 and float(r["rpm"]) == 18000.0)
    tool = StraightEndMill2D(KT_1DOF, KN_1DOF, 2, 0.05, "down", depth_mm=1.0)
    sys = _sys_1dof()
    s = [sdm_margin(tool.directional_samples(16 * k), sys, 18000.0, 2, steps=k,
                    rtol=1e-9).margin for k in (40, 80, 160)]
    assert s[0] > s[1] > s[2]                             # from above
    assert 3.6 < (s[0] - s[1]) / (s[1] - s[2]) < 4.4
    assert s[2] + (s[2] - s[1]) / 3 == pytest.approx(float(row["limit_mm"]), rel=2e-4)


@pytest.mark.parametrize("modes, steps", [(2, 12), (3, 41), (1, 1), (1, 2)])
@pytest.mark.parametrize("immersion", [0.3, 1.0])
def test_monodromy_kernel_matches_numpy_twin(modes, steps, immersion):
    """The kernel (each step on the columns the history has reached, the history's unit
    blocks subtracted, only the active delays, the columns put back in order) against
    the twin's product of whole one-step block matrices: the twin's principal submatrix
    on the active states, and the twin's other columns zero."""
    sys = _sys_asym(modes)
    tool = StraightEndMill2D(KT_AB, KR_AB * KT_AB, 4, immersion, "up", depth_mm=1.0)
    h = tool.directional_samples(24)
    f = _Fdm(h, sys, 60.0 / (9000.0 * 4), steps)
    out = np.full((f.active.size, f.active.size), np.nan)
    _monodromy(f.phi0, f.pa, f.pb, 0.7, f.cmat, f.active, out)
    twin = _monodromy_numpy(f.phi0, f.pa, f.pb, 0.7, f.cmat)
    sub = twin[np.ix_(f.active, f.active)]
    assert np.allclose(out, sub, rtol=1e-10, atol=1e-10 * np.abs(twin).max())
    assert np.count_nonzero(sub) > f.active.size          # not trivially zero
    others = np.setdiff1d(np.arange(f.n), f.active)
    assert not np.any(twin[:, others])
    # the active states are exactly the twin's non-zero columns (none kept needlessly)
    assert np.array_equal(np.flatnonzero(np.any(twin != 0.0, axis=0)), f.active)


@pytest.mark.parametrize("pattern", ["gaps", "gaps in a or b", "one step", "none", "whole",
                                     "one mode"])
def test_monodromy_kernel_on_any_pattern_of_steps_out_of_the_cut(pattern):
    """Random maps (seeded) whose steps out of the cut leave gaps anywhere in the period
    (the cut at its end, one step alone, none, every step, a mode that a step's weights
    leave out), at scalings 0 to 2.5: the kernel is the twin's principal submatrix on the
    active states, the twin's other columns are zero, and the spectral radii agree."""
    rng = np.random.default_rng(["gaps", "gaps in a or b", "one step", "none", "whole",
                                 "one mode"].index(pattern))
    for _ in range(40):
        m = int(rng.integers(1, 4))
        k = int(rng.integers(1, 12))
        n2 = 2 * m
        phi0 = rng.normal(size=(n2, n2)) * 0.5
        pa = rng.normal(size=(k, n2, m)) * 0.3
        pb = rng.normal(size=(k, n2, m)) * 0.3
        if pattern == "gaps":
            out_of_cut = rng.random(k) < 0.6
            pa[out_of_cut] = 0.0
            pb[out_of_cut] = 0.0
        elif pattern == "gaps in a or b":
            pa[rng.random(k) < 0.5] = 0.0
            pb[rng.random(k) < 0.5] = 0.0
        elif pattern == "one step":
            out_of_cut = np.ones(k, bool)
            out_of_cut[rng.integers(k)] = False
            pa[out_of_cut] = 0.0
            pb[out_of_cut] = 0.0
        elif pattern == "none":
            pa[:] = 0.0
            pb[:] = 0.0
        elif pattern == "one mode":
            pa[:, :, 0] = 0.0
            pb[rng.random(k) < 0.5] = 0.0
        r = rng.normal(size=m) * 0.1 if rng.random() < 0.5 else np.zeros(m)
        cmat = np.ascontiguousarray(np.hstack([np.eye(m), np.diag(r)]))
        active = _active_states(pa, pb)
        for s in (0.0, 0.3, 2.5):
            out = np.full((active.size, active.size), np.nan)
            _monodromy(phi0, pa, pb, s, cmat, active, out)
            twin = _monodromy_numpy(phi0, pa, pb, s, cmat)
            scale = max(1.0, np.abs(twin).max())
            assert np.allclose(out, twin[np.ix_(active, active)], rtol=0, atol=1e-10 * scale)
            assert not np.any(twin[:, np.setdiff1d(np.arange(twin.shape[0]), active)])
            rho = np.abs(np.linalg.eigvals(out)).max() if out.size else 0.0
            assert rho == pytest.approx(np.abs(np.linalg.eigvals(twin)).max(), rel=1e-8,
                                        abs=1e-12)
        if pattern == "none":
            assert active.size == n2                      # only y: nothing delayed enters
        if pattern == "whole":
            assert active.size == (k + 2) * m             # every delay enters


def test_multipliers_on_the_active_states_are_the_whole_matrix_s():
    """Out of the cut most of the period, most delayed states never enter: the
    multipliers from the active states (padded with zeros) are the whole monodromy
    matrix's (the twin's), and the spectral radius the same."""
    sys = _sys_asym(2)
    tool = StraightEndMill2D(KT_AB, KR_AB * KT_AB, 4, 0.05, "down", depth_mm=1.0)
    h = tool.directional_samples(40)
    f = _Fdm(h, sys, 60.0 / (9000.0 * 4), 40)
    assert f.active.size < f.n // 2                     # the restriction does something
    for s in (0.0, 0.3, 2.0):
        whole = np.linalg.eigvals(_monodromy_numpy(f.phi0, f.pa, f.pb, s, f.cmat))
        mu = f.multipliers(s)
        assert mu.shape == (f.n,)
        assert np.allclose(np.sort_complex(mu), np.sort_complex(whole), rtol=0,
                           atol=1e-9 * max(1.0, np.abs(whole).max()))
        assert f.rho(s) == pytest.approx(np.abs(whole).max(), rel=1e-9)


def test_remap_is_exact():
    sys = _sys_asym(2)
    tool = StraightEndMill2D(KT_AB, KR_AB * KT_AB, 4, 0.3, "up", depth_mm=1.0)
    h = tool.directional_samples(24)
    # the remap integrates the piecewise-constant samples exactly
    fine = _remap(h, 72)                                    # a multiple: repeated
    assert np.array_equal(fine[::3], h) and np.array_equal(fine[1::3], h)
    odd = _remap(h, 37)
    assert np.allclose(odd.mean(axis=0), h.mean(axis=0), rtol=0, atol=1e-12 * np.abs(h).max())
    # sample j covers [j/24, (j+1)/24); interval i of 37 covers [i/37, (i+1)/37)
    i = 5
    a, b = i / 37, (i + 1) / 37
    w = np.clip(np.minimum(b, (np.arange(24) + 1) / 24) - np.maximum(a, np.arange(24) / 24),
                0, None)
    assert np.allclose(odd[i], np.einsum("j,jkl->kl", w, h) / (b - a))


def test_default_steps_rule():
    sys = _sys_1dof()
    assert default_steps(sys, 25000.0, 2) == 40                # 32 x 1.1 mode periods -> 36
    assert default_steps(sys, 5000.0, 2) == math.ceil(32 * 0.006 * 922.0)    # 178
    assert default_steps(sys, 1000.0, 2) == 200                # capped
    with pytest.raises(ValueError, match="spindle_rpm"):
        default_steps(sys, -1.0, 2)


@njit(cache=True)
def _simulate_growth(s_depth_m, rpm, steps_per_tau, periods, phi_st, phi_ex):
    """RK4 of m x'' + c x' + k x = w H(t)/w (x - x(t - tau)) (1-DOF Insperger model);
    returns log(max|x| over the last 20 periods / max|x| over periods 40..60)."""
    wn = 2 * math.pi * 922.0
    m = 1340049.648 / wn**2
    c = 2 * 0.011 * math.sqrt(1340049.648 * m)
    k = 1340049.648
    tau = 60.0 / (rpm * 2)
    dt = tau / steps_per_tau
    n = steps_per_tau * periods
    x = np.zeros(n + steps_per_tau + 1)
    v = np.zeros(n + steps_per_tau + 1)
    for i in range(steps_per_tau + 1):           # initial history: a small wave
        x[i] = 1e-6 * math.sin(0.37 * i)
        v[i] = 1e-6 * 0.37 / dt * math.cos(0.37 * i)
    om = 2 * math.pi * rpm / 60

    def hxx(t):
        acc = 0.0
        for j in range(2):
            p = (om * t + j * math.pi) % (2 * math.pi)
            if phi_st <= p <= phi_ex:
                acc += -s_depth_m * math.sin(p) * (6e8 * math.cos(p) + 2e8 * math.sin(p))
        return acc

    def acc(t, xx, vv, xd):
        return (-c * vv - k * xx + hxx(t) * (xx - xd)) / m

    big_a, big_b = 0.0, 0.0
    for i in range(steps_per_tau, steps_per_tau + n):
        t = (i - steps_per_tau) * dt
        j = i - steps_per_tau
        xd0, xd1 = x[j], x[j + 1]
        xdm = 0.5 * (xd0 + xd1) + dt * (v[j] - v[j + 1]) / 8.0
        x0, v0 = x[i], v[i]
        k1x, k1v = v0, acc(t, x0, v0, xd0)
        k2x, k2v = v0 + 0.5 * dt * k1v, acc(t + 0.5 * dt, x0 + 0.5 * dt * k1x,
                                            v0 + 0.5 * dt * k1v, xdm)
        k3x, k3v = v0 + 0.5 * dt * k2v, acc(t + 0.5 * dt, x0 + 0.5 * dt * k2x,
                                            v0 + 0.5 * dt * k2v, xdm)
        k4x, k4v = v0 + dt * k3v, acc(t + dt, x0 + dt * k3x, v0 + dt * k3v, xd1)
        x[i + 1] = x0 + dt / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
        v[i + 1] = v0 + dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        per = j // steps_per_tau
        if 40 <= per < 60:
            big_a = max(big_a, abs(x[i + 1]))
        if per >= periods - 20:
            big_b = max(big_b, abs(x[i + 1]))
    return math.log(big_b / big_a)


def test_fdm_boundary_matches_time_domain_simulation():
    """Independent check of the time-periodic boundary: RK4 of the delayed 1-DOF model."""
    tool = StraightEndMill2D(KT_1DOF, KN_1DOF, 2, 1.0, "down", depth_mm=1.0)
    rpm = 15870.0
    margin = sdm_margin(tool.directional_samples(40), _sys_1dof(), rpm, 2).margin
    st, ex = tool.angles
    below = _simulate_growth(0.97 * margin * 1e-3, rpm, 200, 400, st, ex)
    above = _simulate_growth(1.03 * margin * 1e-3, rpm, 200, 400, st, ex)
    assert below < -0.5 and above > 0.5


def test_fdm_1dof_slotting_minimum_is_above_zoa_and_converged():
    """At 1-DOF slotting the converged time-periodic minimum (0.318 mm; its boundary is
    checked by the time-domain simulation above) lies 6.5 % above the zero-order closed
    form (0.298 mm): the 2-tooth slotting H(t) has a strong tooth-frequency harmonic that
    the average drops. The methods legitimately differ here (method.md §7)."""
    tool = StraightEndMill2D(KT_1DOF, KN_1DOF, 2, 1.0, "down", depth_mm=1.0)
    ref = _alim_1dof_closed_form(1.0, "down", 2)
    rpm40, fdm40 = _fdm_min(tool, _sys_1dof(), 15000.0, 16800.0)
    _, fdm80 = _fdm_min(tool, _sys_1dof(), rpm40 - 200.0, rpm40 + 200.0, steps=80)
    assert abs(fdm40 - fdm80) < 0.01 * fdm80
    # the zero-order limit is conservative here: no time-periodic point lies below it
    assert fdm80 > ref


def test_fdm_low_immersion_flip_lobe_the_zoa_misses():
    """a/D = 0.05 down-milling (Insperger et al.): a period-doubling lobe well below the
    zero-order limit at the same speed and below the zero-order critical depth."""
    tool = StraightEndMill2D(KT_1DOF, KN_1DOF, 2, 0.05, "down", depth_mm=1.0)
    sys = _sys_1dof()
    res = sdm_margin(tool.directional_samples(tool.recommended_samples()), sys, 18200.0, 2)
    zoa_here = zoa_margin(tool.mean_directional_matrix(), sys, 18200.0, 2)
    crit = _alim_1dof_closed_form(0.05, "down", 2)
    assert res.kind == "flip"
    assert abs(abs(res.multiplier) - 1) < 0.01 and res.multiplier.real < 0
    assert res.margin < 0.75 * zoa_here and res.margin < 0.75 * crit
    # and away from the flip lobes both methods agree on a Hopf boundary
    hopf = sdm_margin(tool.directional_samples(tool.recommended_samples()), sys, 21000.0, 2)
    assert hopf.kind == "hopf"
    assert hopf.margin == pytest.approx(zoa_margin(tool.mean_directional_matrix(), sys,
                                                   21000.0, 2), rel=0.05)


def test_fdm_2dof_minimum_matches_altintas_budak():
    """The Hopf lobes' bottom matches the closed form; a narrow flip lobe near 27,700
    rev/min (found by the 200-speed scan of benchmarks/bench_stability.py) dips about
    11 % below it, which the zero-order method cannot see."""
    tool = StraightEndMill2D(KT_AB, KR_AB * KT_AB, 4, 0.5, "up", depth_mm=1.0)
    omega = 2 * math.pi * np.linspace(800.0, 1200.0, 200001)
    ref_mm = _altintas_budak_alim(0.5, "up", 4, omega).min() * 1e3
    rpm, fdm = _fdm_min(tool, _sys_2dof(), 24000.0, 26500.0)
    assert fdm == pytest.approx(ref_mm, rel=0.05)
    assert sdm_margin(tool.directional_samples(40), _sys_2dof(), rpm, 4).kind == "hopf"
    flip = sdm_margin(tool.directional_samples(40), _sys_2dof(), 27738.7, 4)
    assert flip.kind == "flip"
    assert 0.8 * ref_mm < flip.margin < 0.95 * ref_mm


def test_fdm_invariant_under_rotation_and_multiplier_kinds():
    tool = StraightEndMill2D(KT_AB, KR_AB * KT_AB, 4, 0.5, "up", depth_mm=1.0)
    h = tool.directional_samples(40)
    sys = _sys_asym(2)
    rot = minimal_rotation(np.array([0.2, 0.4, 0.9]))
    a = sdm_margin(h, sys, 8000.0, 4)
    b = sdm_margin(np.einsum("ij,kjl,ml->kim", rot, h, rot), sys.rotated(rot), 8000.0, 4)
    assert b.margin == pytest.approx(a.margin, rel=2e-3)
    mu = floquet_multipliers(h, sys, 8000.0, 4, scale=a.margin * 0.99)
    assert np.abs(mu).max() < 1.0
    mu = floquet_multipliers(h, sys, 8000.0, 4, scale=a.margin * 1.01)
    assert np.abs(mu).max() > 1.0
    assert a.kind in ("hopf", "flip", "fold")


# ---------------------------------------------------------------------- lobes + plot
def test_stability_lobes_and_plot(tmp_path):
    tool = StraightEndMill2D(KT_1DOF, KN_1DOF, 2, 0.05, "down", depth_mm=1.0)
    h = tool.directional_samples(40)
    rpm = np.linspace(16000, 22000, 13)
    z = stability_lobes(h, _sys_1dof(), 2, rpm, method="zoa", depth_mm=1.0)
    s = stability_lobes(h, _sys_1dof(), 2, rpm, method="sdm", depth_mm=1.0)
    assert np.allclose(z.depth_limit_mm, z.margin)
    assert s.kind is not None and "flip" in s.kind
    assert np.allclose(z.margin, zoa_lobes(h.mean(axis=0), _sys_1dof(), 2, rpm))
    with pytest.raises(ValueError, match="method"):
        stability_lobes(h, _sys_1dof(), 2, rpm, method="sd")
    path = tmp_path / "lobes.png"
    plot_lobes([z, s], (18000.0, 1.2), path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(os.listdir(tmp_path)) == ["lobes.png"]


def test_capped_batch_equals_min_of_margin_and_cap():
    """The capped batch (eigenvalues only where their real parts can matter) gives
    exactly min(margin, cap) on tool plus close and far wall-like modes."""
    tool = ModalSystem.from_modes([(Mode.from_frequency(3600, 0.03, 1.6e7), (1, 0, 0)),
                                   (Mode.from_frequency(3700, 0.03, 1.7e7), (0, 1, 0))],
                                  source="tool")
    wall = ModalSystem.from_modes(
        [(Mode.from_frequency(f, 0.01, k), (0, 0.6, 0.8))
         for f, k in ((3540, 7.2e6), (5290, 6.5e6), (9870, 2.0e7), (18180, 1.1e8))])
    sys = ModalSystem.combine(tool, wall)
    rng = np.random.default_rng(12)
    p0 = _p_asym()
    rots = [minimal_rotation(v / np.linalg.norm(v))
            for v in rng.normal([0, 0, 3], 1.0, size=(200, 3))]
    p = np.array([r @ p0 @ r.T for r in rots]) * rng.uniform(0.05, 3.0, size=(200, 1, 1))
    rpm = rng.uniform(4000, 16000, size=200)
    exact = zoa_margin_batch(p, sys, rpm, 2)
    for cap in (0.5, 1.5, 4.0):
        capped = zoa_margin_batch(p, sys, rpm, 2, cap=cap)
        np.testing.assert_allclose(capped, np.minimum(exact, cap), rtol=1e-9)
        assert np.any(exact < cap) and np.any(exact > cap)
    with pytest.raises(ValueError, match="cap"):
        zoa_margin_batch(p, sys, rpm, 2, cap=0.0)


def test_zoa_batch_in_one_thread_equals_the_threaded_kernel():
    """The planner's calls (a few hundred postures) run in the calling thread: the same
    margins, bit for bit, as over numba's threads, capped or not, per-posture mode
    directions and speeds."""
    sys = ModalSystem.from_modes([(Mode.from_frequency(2150, 0.03, 6e6), (1, 0, 0)),
                                  (Mode.from_frequency(2240, 0.028, 6.5e6), (0, 1, 0))],
                                 source="tool")
    rng = np.random.default_rng(29)
    p0 = _p_asym()
    rots = [minimal_rotation(v / np.linalg.norm(v))
            for v in rng.normal([0, 0, 3], 1.0, size=(64, 3))]
    p = np.array([r @ p0 @ r.T for r in rots]) * rng.uniform(0.05, 3.0, size=(64, 1, 1))
    rpm = rng.uniform(4000, 16000, size=64)
    axes = rng.normal([0, 0, 2], 0.5, size=(64, 3))
    md = sys.directions_for_axes(axes / np.linalg.norm(axes, axis=1)[:, None])
    for cap in (None, 1.5):
        one = zoa_margin_batch(p, sys, rpm, 2, mode_directions=md, cap=cap, parallel=False)
        threads = zoa_margin_batch(p, sys, rpm, 2, mode_directions=md, cap=cap, parallel=True)
        np.testing.assert_array_equal(one, threads)
        assert np.all(np.isfinite(one)) and np.ptp(one) > 0.1


@pytest.mark.parametrize("n,p", [(1, 1), (4, 8), (12, 20)])
def test_step_solve_is_a_linear_solve(n, p):
    """The monodromy kernel's hand-written solve against np.linalg.solve, on matrices
    that need row exchanges (a zero leading entry) and near the identity (its use)."""
    from orient.stability.sdm import _solve_in_place

    rng = np.random.default_rng(n)
    for a in (rng.normal(size=(n, n)) + 3.0 * np.eye(n),
              np.eye(n) - 0.3 * rng.normal(size=(n, n))):
        if n > 1:
            a[0, 0] = 0.0           # pivoting needed
        b = rng.normal(size=(n, p))
        want = np.linalg.solve(a, b)
        got = b.copy()
        _solve_in_place(a.copy(), got)
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12)
    with pytest.raises(ValueError, match="singular"):
        _solve_in_place(np.zeros((n, n)), np.ones((n, p)))
