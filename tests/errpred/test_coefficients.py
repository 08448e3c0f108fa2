"""Cutting coefficients: validation, I/O, and least-squares identification."""

from __future__ import annotations

import math

import numpy as np
import pytest

from errpred.calibration import ForceMeasurement, fit_coefficients
from errpred.coefficients import CHIP_AND_EDGE_NAMES, WEAR_NAMES, CuttingCoefficients
from errpred.force import chip_thickness, tool_forces
from errpred.tool import Tool

TRUE = CuttingCoefficients(Ktc_N_mm2=1850.0, Krc_N_mm2=720.0, Kac_N_mm2=310.0,
                           Kte0_N_mm=24.0, Kre0_N_mm=31.0, Kae0_N_mm=6.0,
                           Kte1_N_mm2=6.0e-4, Kre1_N_mm2=9.0e-4, Kae1_N_mm2=2.0e-4)
NOISE = 0.01        # Gaussian noise, fraction of the RMS force of the measurement
N_ANG = 180         # 2 deg, the package's default angle step
TOOL = Tool("ball", 10.0, flutes=2, helix_deg=30.0, flute_length_mm=20.0)
EDGES = TOOL.micro_edges(40, flank_height_mm=8.0)

# (axial depth a_p [mm], feed per tooth [mm], engaged window of phi [rad])
ENGAGEMENTS = [
    (3.0, 0.10, (0.0, math.pi)),                          # slot
    (6.0, 0.05, (0.0, math.acos(1 - 2 * 0.3))),            # up-milling, ae = 0.3 D
    (2.0, 0.15, (math.pi - math.acos(1 - 2 * 0.5), math.pi)),  # down-milling, ae = 0.5 D
]


def engagement(a_p, fz, window):
    """Synthetic engagement: edges below a_p, flute angle in the window."""
    n_fl = TOOL.flutes
    theta = np.arange(N_ANG) * (2 * math.pi / N_ANG)
    phi = theta[:, None, None] + 2 * math.pi * np.arange(n_fl)[None, :, None] / n_fl \
        - EDGES.psi[None, None, :]
    h = chip_thickness(EDGES, phi, [fz, 0.0, 0.0])
    p = np.mod(phi, 2 * math.pi)
    cutting = (p >= window[0]) & (p <= window[1]) & (h > 0) & (EDGES.z <= a_p)
    return phi, h, cutting


def worn_cl(k: int) -> np.ndarray:
    """Known cutting distances: the lower edge wears most; per flute for k odd."""
    base = 2.0e4 * (1.5 - EDGES.z / EDGES.z.max()) * (1 + 0.5 * k)   # 10-30 m
    return np.stack([base, 0.8 * base]) if k % 2 else base


def measure(coef, cl_of, rng):
    out, sigmas = [], []
    for k, (a_p, fz, window) in enumerate(ENGAGEMENTS):
        phi, h, cutting = engagement(a_p, fz, window)
        cl = cl_of(k)
        f = tool_forces(EDGES, coef, phi, h, cutting, cl)
        sigma = NOISE * np.sqrt(np.mean(f ** 2))
        out.append(ForceMeasurement(EDGES, phi, h, cutting, cl,
                                    f + rng.normal(0.0, sigma, f.shape)))
        sigmas.append(sigma)
    return out, sigmas


def design(meas, names):
    cols = []
    for name in names:
        unit = CuttingCoefficients(**{**dict.fromkeys(CHIP_AND_EDGE_NAMES + WEAR_NAMES, 0.0),
                                      name: 1.0})
        cols.append(np.concatenate([tool_forces(m.edges, unit, m.phi, m.h, m.cutting,
                                                m.cl_mm).ravel() for m in meas]))
    return np.stack(cols, axis=1)


def test_fit_recovers_coefficients_and_wear():
    rng = np.random.default_rng(20240611)
    new, s_new = measure(TRUE.replace(Kte1_N_mm2=0, Kre1_N_mm2=0, Kae1_N_mm2=0),
                         lambda k: np.zeros(len(EDGES)), rng)
    worn, s_worn = measure(TRUE, worn_cl, rng)

    # Expected scatter of the estimates (the tolerance's derivation).
    # Step 1, ordinary least squares x6 = P b, P = (A^T A)^-1 A^T, noise
    # covariance S = diag(sigma_i^2): Cov6 = P S P^T.
    A = design(new, CHIP_AND_EDGE_NAMES)
    P = np.linalg.pinv(A)
    s2 = np.concatenate([np.full(m.force_N.size, s ** 2) for m, s in zip(new, s_new)])
    cov6 = (P * s2) @ P.T
    rel6 = np.sqrt(np.diag(cov6)) / np.array([getattr(TRUE, n) for n in CHIP_AND_EDGE_NAMES])
    # Step 2: x3 = Q (b_w - B x6_hat): the noise of the worn measurements plus
    # the error of the six held coefficients propagated through B.
    W = design(worn, WEAR_NAMES)
    B = design(worn, CHIP_AND_EDGE_NAMES)
    Q = np.linalg.pinv(W)
    s2w = np.concatenate([np.full(m.force_N.size, s ** 2) for m, s in zip(worn, s_worn)])
    QB = Q @ B
    cov3 = (Q * s2w) @ Q.T + QB @ cov6 @ QB.T
    rel3 = np.sqrt(np.diag(cov3)) / np.array([getattr(TRUE, n) for n in WEAR_NAMES])
    # 1 % noise on 3 x 180 x 3 samples: sigma of the six is 0.08 % (Ktc) to
    # 0.9 % (Kae0, the smallest share of the force), of the wear terms 0.14 %
    # (Kre1) to 0.6 % (Kae1). Tolerance: 5 sigma of each coefficient (a false
    # failure once in ~10^6 per coefficient), and the design must make that
    # at most 5 % for every coefficient.
    tol6, tol3 = 5 * rel6, 5 * rel3
    assert tol6.max() <= 0.05 and tol3.max() <= 0.05, (rel6, rel3)

    rep = fit_coefficients(new, worn, source="synthetic")
    got = rep.coefficients
    assert got.source == "synthetic"
    err6 = np.array([getattr(got, n) / getattr(TRUE, n) - 1 for n in CHIP_AND_EDGE_NAMES])
    err3 = np.array([getattr(got, n) / getattr(TRUE, n) - 1 for n in WEAR_NAMES])
    assert np.all(np.abs(err6) < tol6), (err6, tol6)
    assert np.all(np.abs(err3) < tol3), (err3, tol3)
    # the report: residual about the noise level, its standard errors about
    # the derived scatter, sizes as given
    rms_sigma = math.sqrt(np.mean(s2))
    assert 0.9 < rep.residual_rms_N / rms_sigma < 1.1
    assert 0.9 < rep.wear_residual_rms_N / math.sqrt(np.mean(s2w)) < 1.1
    se6 = np.array([rep.std_error[n] for n in CHIP_AND_EDGE_NAMES])
    assert np.allclose(se6, np.sqrt(np.diag(cov6)), rtol=0.3)
    assert rep.n_samples == 3 * 3 * N_ANG and rep.n_wear_samples == 3 * 3 * N_ANG
    assert 1 < rep.condition_number < 1e4 and 1 <= rep.wear_condition_number < 1e4


def test_fit_exact_without_noise_and_new_only():
    rng = np.random.default_rng(1)
    base = TRUE.replace(Kte1_N_mm2=0, Kre1_N_mm2=0, Kae1_N_mm2=0)
    new, _ = measure(base, lambda k: np.zeros(len(EDGES)), rng)
    clean = [ForceMeasurement(m.edges, m.phi, m.h, m.cutting, m.cl_mm,
                              tool_forces(m.edges, base, m.phi, m.h, m.cutting, m.cl_mm))
             for m in new]
    rep = fit_coefficients(clean)
    for n in CHIP_AND_EDGE_NAMES:
        assert math.isclose(getattr(rep.coefficients, n), getattr(base, n), rel_tol=1e-9)
    assert all(getattr(rep.coefficients, n) == 0.0 for n in WEAR_NAMES)
    assert rep.wear_residual_rms_N is None and rep.n_wear_samples == 0
    assert rep.residual_rms_N < 1e-9


def _one(force=None, **over):
    phi, h, cutting = engagement(*ENGAGEMENTS[0])
    f = tool_forces(EDGES, TRUE, phi, h, cutting, np.zeros(len(EDGES))) if force is None else force
    args = dict(edges=EDGES, phi=phi, h=h, cutting=cutting, cl_mm=np.zeros(len(EDGES)),
                force_N=f)
    args.update(over)
    return ForceMeasurement(**args)


def test_fit_refuses_bad_measurements():
    good = _one()
    nan_f = good.force_N.copy()
    nan_f[7, 1] = np.nan
    with pytest.raises(ValueError, match=r"new\[1\].*force_N.*non-finite.*\(7, 1\)"):
        fit_coefficients([good, _one(force=nan_f)])
    with pytest.raises(ValueError, match=r"new\[0\].*force_N: expected shape \(180, 3\)"):
        fit_coefficients([_one(force=good.force_N[:, :2]), good])
    with pytest.raises(ValueError, match=r"worn\[0\].*h: shape"):
        fit_coefficients([good], [_one(h=good.h[:, :1])])
    with pytest.raises(ValueError, match=r"worn\[1\].*cl_mm: expected shape"):
        fit_coefficients([good], [good, _one(cl_mm=np.zeros(3))])
    with pytest.raises(ValueError, match=r"new\[0\].*micro edges"):
        fit_coefficients([_one(phi=good.phi[..., :-1], h=good.h[..., :-1],
                               cutting=good.cutting[..., :-1])])
    bad_h = np.where(good.cutting, good.h, 0.0)
    bad_h[tuple(np.argwhere(good.cutting)[0])] = np.inf
    with pytest.raises(ValueError, match=r"new\[0\].*h: .*non-finite"):
        fit_coefficients([_one(h=bad_h)])
    with pytest.raises(ValueError, match=r"new\[0\].*no micro edge cuts"):
        fit_coefficients([_one(cutting=np.zeros_like(good.cutting))])
    one_sample = _one(phi=good.phi[:1], h=good.h[:1], cutting=good.cutting[:1],
                      force_N=good.force_N[:1])
    with pytest.raises(ValueError, match="too few samples"):
        fit_coefficients([one_sample])
    with pytest.raises(ValueError, match="at least one"):
        fit_coefficients([])
    # zero chip thickness everywhere: the chip coefficients leave no trace in
    # the force, so they cannot be identified -- refused, not a silent answer
    zero_h = _one(h=np.zeros_like(good.h))
    with pytest.raises(ValueError, match="Ktc_N_mm2"):
        fit_coefficients([zero_h])


# --- CuttingCoefficients --------------------------------------------------------------

ALL = CHIP_AND_EDGE_NAMES + WEAR_NAMES


@pytest.mark.parametrize("name", ALL)
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_refused_naming_field(name, bad):
    d = TRUE.as_dict()
    d[name] = bad
    with pytest.raises(ValueError, match=name):
        CuttingCoefficients(**d)
    with pytest.raises(ValueError, match=f"{name}.*cutting.toml"):
        CuttingCoefficients.from_dict(d, source="cutting.toml")


def test_zero_and_non_numbers():
    z = CuttingCoefficients(**dict.fromkeys(CHIP_AND_EDGE_NAMES, 0))
    assert z.as_dict() == dict.fromkeys(ALL, 0.0)
    with pytest.raises(ValueError, match="Krc_N_mm2"):
        CuttingCoefficients(**{**TRUE.as_dict(), "Krc_N_mm2": "700"})
    with pytest.raises(ValueError, match="Kae1_N_mm2"):
        CuttingCoefficients(**{**TRUE.as_dict(), "Kae1_N_mm2": None})


def test_dict_round_trip_and_unknown_keys():
    d = TRUE.as_dict()
    assert list(d) == list(ALL)
    back = CuttingCoefficients.from_dict(d, source="x.toml")
    assert back == TRUE and back.source == "x.toml" and back.as_dict() == d
    # wear terms default to 0
    short = {k: d[k] for k in CHIP_AND_EDGE_NAMES}
    assert CuttingCoefficients.from_dict(short).Kte1_N_mm2 == 0.0
    with pytest.raises(ValueError, match="'Ktc'"):
        CuttingCoefficients.from_dict({**short, "Ktc": 1.0})
    with pytest.raises(ValueError, match="'source'"):
        CuttingCoefficients.from_dict({**d, "source": "y"})
    with pytest.raises(ValueError, match="missing.*Kae0_N_mm"):
        CuttingCoefficients.from_dict({k: v for k, v in short.items() if k != "Kae0_N_mm"})


def test_edge_coefficients_grow_with_cl():
    cl = np.array([[0.0, 1e4], [2e4, 5e4]])
    kte, kre, kae = TRUE.edge(cl)
    assert kte.shape == cl.shape
    assert np.allclose(kte, 24.0 + 6.0e-4 * cl) and np.allclose(kre, 31.0 + 9.0e-4 * cl)
    assert np.allclose(kae, 6.0 + 2.0e-4 * cl)
    assert TRUE.edge(0.0)[0] == 24.0
