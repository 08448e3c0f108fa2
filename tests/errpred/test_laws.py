"""Force laws side by side (errpred.laws) and their use by errpred, orient and sim.

References: Altintas, Manufacturing Automation (2nd ed., 2012) §2.3.2 (the
linear law's mean slot forces); the Kienzle power law's mean over a slot by
the Wallis integral ``int_0^pi sin^p = sqrt(pi) Gamma((p+1)/2) / Gamma(p/2+1)``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.integrate
from scipy.special import gamma

from errpred import force, laws
from errpred.coefficients import CuttingCoefficients, LawCoefficients
from errpred.constants import KIENZLE_MIN_CHIP_MM
from errpred.fit import MeanForceTest, mean_force, slot_force_linear
from errpred.laws.kienzle import KienzleCoefficients
from errpred.laws.lee_altintas import LeeAltintasCoefficients
from errpred.tool import Tool

LIN = CuttingCoefficients(Ktc_N_mm2=2000.0, Krc_N_mm2=700.0, Kac_N_mm2=300.0,
                          Kte0_N_mm=20.0, Kre0_N_mm=25.0, Kae0_N_mm=5.0,
                          Kte1_N_mm2=1e-3, Kre1_N_mm2=2e-3, Kae1_N_mm2=5e-4)
KZ = KienzleCoefficients(kc11_t_N_mm2=2200.0, kc11_r_N_mm2=900.0, kc11_a_N_mm2=350.0,
                         mc_t=0.24, mc_r=0.3, mc_a=0.2)
LA_CONST = LeeAltintasCoefficients(Ktc_N_mm2=[2000.0], Krc_N_mm2=[700.0], Kac_N_mm2=[300.0],
                                   Kte0_N_mm=[20.0], Kre0_N_mm=[25.0], Kae0_N_mm=[5.0],
                                   Kte1_N_mm2=1e-3, Kre1_N_mm2=2e-3, Kae1_N_mm2=5e-4)
LA = LeeAltintasCoefficients(Ktc_N_mm2=[2600.0, -900.0, 300.0], Krc_N_mm2=[1100.0, -400.0],
                             Kac_N_mm2=[150.0, 200.0], Kte0_N_mm=[25.0, -5.0],
                             Kre0_N_mm=[30.0], Kae0_N_mm=[2.0, 3.0])
FLAT = Tool("flat", 10.0, flutes=3, helix_deg=0.0, flute_length_mm=6.0)
BALL = Tool("ball", 10.0, flutes=2, helix_deg=30.0, flute_length_mm=15.0)


def test_registry_holds_the_three_laws_with_one_signature():
    assert set(laws.LAWS) == {"linear", "kienzle", "lee-altintas"}
    h = np.array([0.0, 0.01, 0.05])
    for c in (LIN, KZ, LA):
        assert isinstance(c, LawCoefficients) and laws.law_of(c).NAME == c.law
        f, g = laws.force(c, h, 0.7, 3.0), laws.slope(c, h, 0.7)
        assert len(f) == len(g) == 3 and all(x.shape == h.shape for x in f + g)
    with pytest.raises(ValueError, match="force law"):
        laws.law_of(object())


# --- the linear law through the new table -----------------------------------------

def _slot(tool, n_ang, ap):
    """Slot of a flat end mill's flank (straight flutes), midpoint samples."""
    e = tool.micro_edges(20, flank_height_mm=ap)
    e = e.take(np.flatnonzero(e.segment == 2))
    theta = (np.arange(n_ang) + 0.5) * 2 * math.pi / n_ang
    phi = (theta[:, None, None] + 2 * math.pi * np.arange(tool.flutes)[None, :, None]
           / tool.flutes + 0 * e.kappa[None, None, :]) % (2 * math.pi)
    cutting = phi < math.pi
    return e, phi, cutting


@pytest.mark.parametrize("path", ["numba", "numpy"])
def test_linear_law_through_the_table_equals_the_closed_form_slot_force(path):
    """tool_forces' mean over a revolution against Altintas' mean slot force."""
    fz, n_ang = 0.08, 3600
    e, phi, cutting = _slot(FLAT, n_ang, 2.0)
    assert e.db.sum() == pytest.approx(2.0)
    h = np.where(cutting, force.chip_thickness(e, phi, (fz, 0.0, 0.0)), 0.0)
    cl = np.zeros((FLAT.flutes, len(e)))
    if path == "numba" and force.entry_forces_kernel is None:
        pytest.skip("numba not installed")
    mean = force._block_forces(e, LIN, phi, h, cutting, cl, np.ones(phi.shape),
                               compiled=path == "numba").mean(axis=0)
    ref = slot_force_linear(LIN, fz, 2.0, FLAT.flutes)
    np.testing.assert_allclose(mean, ref, rtol=1e-6)        # midpoint rule, 3600 steps
    # and the fit's forward model (quadrature) to round-off
    t = MeanForceTest(fz, 2.0, 10.0, "slot", 10.0, FLAT.flutes, (0, 0, 0))
    np.testing.assert_allclose(mean_force(LIN, t), ref, rtol=1e-12)


def _random_block(seed):
    rng = np.random.default_rng(seed)
    e = BALL.micro_edges(30)
    phi = rng.uniform(-4, 4, (25, BALL.flutes, len(e)))
    h = rng.uniform(0, 0.1, phi.shape)
    h[rng.random(phi.shape) < 0.05] = 0.0
    cutting = rng.random(phi.shape) < 0.4
    cl = rng.uniform(0, 500, (BALL.flutes, len(e)))
    w = rng.uniform(0.2, 1.0, phi.shape)
    return e, phi, h, cutting, cl, w


@pytest.mark.parametrize("c", [LIN, KZ, LA], ids=["linear", "kienzle", "lee-altintas"])
def test_force_kernel_and_its_numpy_twin_agree_for_every_law(c):
    if force.entry_forces_kernel is None:
        pytest.skip("numba not installed")
    e, phi, h, cutting, cl, w = _random_block(3)
    a = force._block_forces(e, c, phi, h, cutting, cl, w, compiled=True)
    b = force._block_forces(e, c, phi, h, cutting, cl, w, compiled=False)
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max())
    assert np.abs(b).max() > 1.0


@pytest.mark.parametrize("c", [LIN, KZ, LA], ids=["linear", "kienzle", "lee-altintas"])
def test_entry_forces_are_tool_forces_from_the_cutting_entries(c):
    """The entries listed as ``np.nonzero`` lists the block's give tool_forces' numbers
    bit for bit (the same law per entry, the same sums in the same order); listed in
    another order, the same to round-off; the numpy twin the same to round-off."""
    e, phi, h, cutting, cl, w = _random_block(4)
    ref = force.tool_forces(e, c, phi, h, cutting, cl, weight=w)
    i, k, j = np.nonzero(cutting)
    got = force.entry_forces(e, c, phi.shape[0], i, k, j, phi[i, k, j], h[i, k, j], cl,
                             weight=w[i, k, j])
    assert np.array_equal(got, ref)
    assert np.abs(ref).max() > 1.0
    perm = np.random.default_rng(1).permutation(i.size)
    shuffled = force.entry_forces(e, c, phi.shape[0], i[perm], k[perm], j[perm],
                                  phi[i, k, j][perm], h[i, k, j][perm], cl,
                                  weight=w[i, k, j][perm])
    np.testing.assert_allclose(shuffled, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
    twin = force._entry_forces(e, c, phi.shape[0], i, j, phi[i, k, j], h[i, k, j], cl[k, j],
                               w[i, k, j], compiled=False)
    np.testing.assert_allclose(twin, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
    # one wear for every flute: cl (m,), (1, m) or a number, as tool_forces takes it
    for one in (cl[0], cl[:1], 120.0):
        ref1 = force.tool_forces(e, c, phi, h, cutting, one, weight=w)
        got1 = force.entry_forces(e, c, phi.shape[0], i, k, j, phi[i, k, j], h[i, k, j],
                                  one, weight=w[i, k, j])
        assert np.array_equal(got1, ref1)


def test_entry_forces_refuses_entries_that_do_not_fit():
    e, phi, h, cutting, cl, w = _random_block(4)
    i, k, j = np.nonzero(cutting)
    args = (phi[i, k, j], h[i, k, j], cl)
    with pytest.raises(ValueError, match="one value per entry"):
        force.entry_forces(e, LIN, phi.shape[0], i[:-1], k, j, *args)
    with pytest.raises(ValueError, match="samples in"):
        force.entry_forces(e, LIN, 3, i, k, j, *args)
    with pytest.raises(ValueError, match="cl_mm"):
        force.entry_forces(e, LIN, phi.shape[0], i, k, j, phi[i, k, j], h[i, k, j], cl[:, :3])
    with pytest.raises(ValueError, match="weight"):
        force.entry_forces(e, LIN, phi.shape[0], i, k, j, *args, weight=w[0, 0, :3])
    with pytest.raises(ValueError, match="flutes >= 0 and < 2"):
        force.entry_forces(e, LIN, phi.shape[0], i, k + 1, j, *args)
    with pytest.raises(ValueError, match="flutes >= 0"):
        force.entry_forces(e, LIN, phi.shape[0], i, k - 1, j, *args)
    for bad in (25.9, None, -1, True):
        with pytest.raises(ValueError, match="n_ang"):
            force.entry_forces(e, LIN, bad, i, k, j, *args)
    with pytest.raises(ValueError, match="i: expected integer indices"):
        force.entry_forces(e, LIN, phi.shape[0], i + 0.5, k, j, *args)
    empty = force.entry_forces(e, LIN, 7, [], [], [], [], [], cl)
    assert empty.shape == (7, 3) and not empty.any()


# --- Kienzle ----------------------------------------------------------------------

def test_kienzle_with_zero_exponent_is_the_linear_law():
    lin = CuttingCoefficients(2200.0, 900.0, 350.0, 12.0, 15.0, 3.0, 1e-3, 2e-3, 0.0)
    kz = KienzleCoefficients(2200.0, 900.0, 350.0, 0.0, 0.0, 0.0, 12.0, 15.0, 3.0, 1e-3, 2e-3,
                             0.0)
    h = np.array([0.0, 0.2 * KIENZLE_MIN_CHIP_MM, KIENZLE_MIN_CHIP_MM, 0.01, 0.3])
    for a, b in zip(laws.force(kz, h, 1.0, 250.0), laws.force(lin, h, 1.0, 250.0)):
        np.testing.assert_allclose(a, b, rtol=1e-14)
    for a, b in zip(laws.slope(kz, h, 1.0), laws.slope(lin, h, 1.0)):
        np.testing.assert_allclose(a, b, rtol=1e-14)


def test_kienzle_slope_is_the_derivative_and_finite_at_zero_chip():
    h = np.array([0.002, 0.01, 0.05, 0.2])
    d = 1e-7
    fp, fm = laws.force(KZ, h + d, 0.0, 0.0), laws.force(KZ, h - d, 0.0, 0.0)
    for g, a, b in zip(laws.slope(KZ, h, 0.0), fp, fm):
        np.testing.assert_allclose(g, (a - b) / (2 * d), rtol=1e-6)
    # below the floor: the chord, continuous at the floor and finite at 0
    h0 = KIENZLE_MIN_CHIP_MM
    g0 = laws.slope(KZ, np.array([0.0]), 0.0)[0][0]
    f_floor = laws.force(KZ, np.array([h0 * (1 - 1e-12), h0]), 0.0, 0.0)[0]
    assert math.isfinite(g0) and g0 == pytest.approx(KZ.kc11_t_N_mm2 * h0 ** -KZ.mc_t)
    assert f_floor[0] == pytest.approx(f_floor[1], rel=1e-9)
    assert laws.force(KZ, np.array([0.0]), 0.0, 0.0)[0][0] == 0.0


def _wallis(p):
    return math.sqrt(math.pi) * gamma((p + 1) / 2) / gamma(p / 2 + 1)


def test_kienzle_mean_slot_force_in_closed_form():
    """The power law's mean slot force (Wallis integrals) to within the effect of the
    chip floor, bounded in closed form: at each end where fz sin(phi) < h0 the chord
    replaces k h^(1-m), which changes the integral by at most k h0^(2-m) / fz
    (1/(2-m) - 1/2) per end."""
    fz, ap, n = 0.1, 2.0, 3
    t = MeanForceTest(fz, ap, 10.0, "slot", 10.0, n, (0, 0, 0))
    got = mean_force(KZ, t)
    na = n * ap / (2 * math.pi)
    (kt, kr, ka), (mt, mr, ma) = KZ.k11, KZ.exponents
    ref = np.array([-na * kr * fz ** (1 - mr) * _wallis(2 - mr),
                    na * kt * fz ** (1 - mt) * _wallis(2 - mt),
                    -na * ka * fz ** (1 - ma) * _wallis(1 - ma)])
    h0 = KIENZLE_MIN_CHIP_MM
    bound = np.array([2 * na * k * h0 ** (2 - m) / fz * (1 / (2 - m) - 0.5)
                      for k, m in ((kr, mr), (kt, mt), (ka, ma))])
    assert np.all(np.abs(got - ref) <= bound * 1.001 + 1e-9 * np.abs(ref))
    assert np.all(bound < 1e-4 * np.abs(ref))       # and the floor matters little


def test_kienzle_mean_force_equals_adaptive_quadrature_of_the_same_law():
    """The fit's quadrature against scipy's adaptive one (told where the floor kinks the
    integrand), side milling up and down and a slot."""
    for mode in ("up", "down", "slot"):
        t = MeanForceTest(0.06, 1.5, 2.5, mode, 8.0, 2, (0, 0, 0))
        a, b = t.arc()
        k = math.asin(KIENZLE_MIN_CHIP_MM / 0.06)      # the floor's kinks
        kinks = [x for x in (k, math.pi - k) if a < x < b]

        def comp(phi, i):
            f = laws.force(KZ, np.array([0.06 * math.sin(phi)]), math.pi / 2, 0.0)
            return force.to_tool_frame(*f, phi, math.pi / 2)[0, i]

        ref = [scipy.integrate.quad(comp, a, b, args=(i,), epsabs=1e-12, epsrel=1e-12,
                                    points=kinks,
                                    limit=200)[0] * 2 * 1.5 / (2 * math.pi) for i in range(3)]
        np.testing.assert_allclose(mean_force(KZ, t), ref, rtol=1e-9)


# --- Lee-Altintas -----------------------------------------------------------------

def test_lee_altintas_constant_polynomials_are_the_linear_law():
    e, phi, h, cutting, cl, w = _random_block(5)
    k = e.kappa
    for a, b in zip(laws.force(LA_CONST, h, k, cl), laws.force(LIN, h, k, cl)):
        np.testing.assert_array_equal(a, b)
    a = force.tool_forces(e, LA_CONST, phi, h, cutting, cl, weight=w)
    b = force.tool_forces(e, LIN, phi, h, cutting, cl, weight=w)
    np.testing.assert_array_equal(a, b)


def test_lee_altintas_polynomials_in_kappa():
    k = np.linspace(0, math.pi / 2, 7)
    g = laws.slope(LA, np.zeros(7), k)
    np.testing.assert_allclose(g[0], 2600.0 - 900.0 * k + 300.0 * k ** 2, rtol=1e-14)
    f = laws.force(LA, 0.05, k, 0.0)
    np.testing.assert_allclose(f[2], 2.0 + 3.0 * k + (150.0 + 200.0 * k) * 0.05, rtol=1e-14)
    assert laws.slope_in_kappa(LA).shape == (3, 3) and laws.slope_in_kappa(KZ) is None
    with pytest.raises(ValueError, match=r"Ktc_N_mm2\[1\]"):
        LeeAltintasCoefficients([1.0, math.nan], [1.0], [1.0], [1.0], [1.0], [1.0])
    with pytest.raises(ValueError, match="LEE_ALTINTAS_MAX_DEGREE"):
        LeeAltintasCoefficients([1.0] * 20, [1.0], [1.0], [1.0], [1.0], [1.0])
    with pytest.raises(ValueError, match="mc_r"):
        KienzleCoefficients(1.0, 1.0, 1.0, 0.2, 1.5, 0.2)


# --- the scenario's [cutting] law ---------------------------------------------------

_LIN_KEYS = """Ktc_N_mm2 = 2000.0
Krc_N_mm2 = 800.0
Kac_N_mm2 = 300.0
Kte0_N_mm = 30.0
Kre0_N_mm = 35.0
Kae0_N_mm = 10.0
"""
_KZ = """law = "kienzle"
kc11_t_N_mm2 = 2200.0
kc11_r_N_mm2 = 900.0
kc11_a_N_mm2 = 350.0
mc_t = 0.24
mc_r = 0.3
mc_a = 0.2
Kte1_N_mm2 = 1e-4
"""
_LA = """law = "lee-altintas"
Ktc_N_mm2 = [2600.0, -900.0, 300.0]
Krc_N_mm2 = [1100.0, -400.0]
Kac_N_mm2 = 150.0
Kte0_N_mm = [25.0]
Kre0_N_mm = [30.0]
Kae0_N_mm = [2.0, 3.0]
"""


def _scenario(tmp_path, cutting):
    from tests.errpred.test_scenario import VALID, _write

    assert _LIN_KEYS in VALID
    return _write(tmp_path, VALID.replace(_LIN_KEYS, cutting))


def test_scenario_chooses_the_law(tmp_path):
    from errpred.scenario import load_scenario

    s = load_scenario(_scenario(tmp_path, _KZ))
    assert s.coefficients == KienzleCoefficients(2200.0, 900.0, 350.0, 0.24, 0.3, 0.2,
                                                 Kte1_N_mm2=1e-4)
    s = load_scenario(_scenario(tmp_path, _LA))
    assert s.coefficients.Ktc_N_mm2 == (2600.0, -900.0, 300.0)
    assert s.coefficients.Kac_N_mm2 == (150.0,)
    s = load_scenario(_scenario(tmp_path, 'law = "linear"\n' + _LIN_KEYS))
    assert s.coefficients == CuttingCoefficients(2000.0, 800.0, 300.0, 30.0, 35.0, 10.0)


@pytest.mark.parametrize("cutting, key, message", [
    ('law = "taylor"\n' + _LIN_KEYS, "cutting.law", "expected one of 'linear'"),
    (_KZ.replace("mc_r = 0.3", "mc_r = 1.2"), "cutting.mc_r", "KIENZLE_MAX_MC"),
    (_KZ.replace("mc_a = 0.2", "mc_a = -0.1"), "cutting.mc_a", ">= 0"),
    (_KZ.replace("mc_a = 0.2\n", ""), "cutting.mc_a", "missing"),
    (_KZ + "Ktc_N_mm2 = 2000.0\n", "cutting.Ktc_N_mm2", "unknown key"),
    (_KZ.replace("kc11_t_N_mm2 = 2200.0", "kc11_t_N_mm2 = nan"), "cutting.kc11_t_N_mm2",
     "finite"),
    (_LA.replace("[2600.0, -900.0, 300.0]", '[2600.0, "x"]'), "cutting.Ktc_N_mm2[1]",
     "expected a number"),
    (_LA.replace("[25.0]", "[1e300]"), "cutting.Kte0_N_mm[0]", "MAX_CUTTING_COEFFICIENT"),
    (_LA.replace("[25.0]", "[" + ", ".join(["1.0"] * 9) + "]"), "cutting",
     "LEE_ALTINTAS_MAX_DEGREE"),
])
def test_scenario_refuses_bad_law_keys_naming_file_and_key(tmp_path, cutting, key, message):
    from errpred.scenario import ScenarioError, load_scenario

    with pytest.raises(ScenarioError) as exc:
        load_scenario(_scenario(tmp_path, cutting))
    msg = str(exc.value)
    assert "scenario.toml" in msg and f"{key}:" in msg and message in msg, msg
    assert "\n" not in msg
