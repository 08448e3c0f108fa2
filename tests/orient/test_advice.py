"""orient.advice: the suggested speed sits in a lobe pocket, the largest stable depth is
the zero-order closed form on a 1-DOF cut, zero-order and time-periodic limits agree at
full immersion where the average holds (1-DOF benchmark of test_stability)."""

from __future__ import annotations

import cmath
import math

import numpy as np
import pytest

from errpred.dynamics import Mode
from orient.advice import largest_stable, suggest_speed, window_minimum
from orient.dynamics import ModalSystem
from orient.stability import StraightEndMill2D, sdm_margin, zoa_lobes, zoa_margin

M_KG = 0.03993
FN_HZ = 922.0
ZETA = 0.011
K_N_M = 1340049.648            # = M_KG (2 pi FN_HZ)^2
KT, KN = 6e8, 2e8              # N/m^2 (Insperger & Stepan's 1-DOF benchmark)


def _sys() -> ModalSystem:
    wn = 2 * math.pi * FN_HZ
    m = K_N_M / wn**2
    return ModalSystem.from_modes([(Mode(K_N_M, m, 2 * ZETA * math.sqrt(K_N_M * m)),
                                    (1.0, 0.0, 0.0))])


def _g(w: float) -> complex:
    wn = 2 * math.pi * FN_HZ
    return 1.0 / (K_N_M * (1 - (w / wn) ** 2 + 2j * ZETA * w / wn))


def _zoa_depth(tool: StraightEndMill2D, rpm: float) -> float:
    """Largest stable depth [mm] at ``rpm`` by the advice's root finder on the ZOA margin
    of the cut at each trial depth."""
    sys_ = _sys()

    def margin(d: float) -> float:
        t = StraightEndMill2D(KT, KN, tool.teeth, tool.radial_immersion, tool.milling,
                              depth_mm=d)
        return zoa_margin(t.mean_directional_matrix(), sys_, rpm, tool.teeth)

    return largest_stable(margin, 1.0, 1e3, rtol=1e-6).value


@pytest.mark.parametrize("k", [1, 2])
def test_suggested_speed_is_a_lobe_pocket_near_fn_over_k(k):
    """Slotting, 2 flutes: the pockets (lobe peaks) are near tooth-passing frequency
    fn / k; over a range around the k-th one the suggestion lies at its peak."""
    tool = StraightEndMill2D(KT, KN, 2, 1.0, "down", depth_mm=1.0)
    peak = 60.0 * FN_HZ / (2 * k)                       # tooth passing = fn / k [rev/min]
    rpm = np.linspace(0.8 * peak, 1.15 * peak, 701)
    depth = zoa_lobes(tool.mean_directional_matrix(), _sys(), 2, rpm)      # [mm]
    r0, _ = suggest_speed(rpm, depth, margin=0.0)
    i = int(np.searchsorted(rpm, r0))
    assert depth[i] >= depth[i - 1] and depth[i] >= depth[i + 1]          # a local peak
    assert depth[i] >= depth.max() * (1 - 1e-12)
    assert abs(r0 / peak - 1) < 0.08                                       # near fn / k
    # with a margin the suggestion keeps its distance: its window's lowest depth is the
    # best of all windows', and above the lobes' floor
    r1, w1 = suggest_speed(rpm, depth, margin=0.02)
    win = window_minimum(rpm, depth, 0.02)
    assert w1 == pytest.approx(win.max()) and w1 > 1.2 * depth.min()
    assert abs(r1 / peak - 1) < 0.08


@pytest.mark.parametrize("k", [0, 1, 2])
def test_largest_stable_depth_is_the_zoa_closed_form_1dof(k):
    """a_lim = 1 / (2 Re(p G(iw))) [mm] with p = P_xx per mm of depth (the contract's
    sign: Altintas' -1 / (2 Kt N/(4 pi) alpha_xx Re G)), at the speed whose phase
    condition w tau = pi + 2 arg(p G) + 2 pi k the chatter frequency w meets; w at the
    lobes' minimum (Re G lowest), where lobe k is the lowest at its speed."""
    tool = StraightEndMill2D(KT, KN, 2, 1.0, "down", depth_mm=1.0)
    p = tool.mean_directional_matrix()[0, 0]                # N/m per mm of depth
    wn = 2 * math.pi * FN_HZ
    w = wn * math.sqrt(1 + 2 * ZETA)                        # min Re G of 1 DOF
    lam = p * _g(w)
    tau = (math.pi + 2 * cmath.phase(lam) + 2 * math.pi * k) / w
    rpm = 60.0 / (tau * 2)
    closed = 1.0 / (2 * lam.real)
    assert closed > 0
    assert _zoa_depth(tool, rpm) == pytest.approx(closed, rel=1e-4)


def test_largest_stable_nonlinear_capped_and_unstable():
    a = 0.37
    lim = largest_stable(lambda x: (a / x) ** 2, 0.05, 5.0, rtol=1e-6)
    assert lim.value == pytest.approx(a, rel=2e-6) and lim.value <= a and not lim.capped
    lim = largest_stable(lambda x: (a / x) ** 2, 2.0, 5.0, rtol=1e-6)    # from above
    assert lim.value == pytest.approx(a, rel=2e-6)
    cap = largest_stable(lambda x: 10.0, 0.1, 0.3)
    assert cap.capped and cap.value == 0.3
    # nothing cuts (inf) below 0.1: bisection there
    lim = largest_stable(lambda x: math.inf if x < 0.1 else 0.5, 0.05, 1.0, rtol=1e-6)
    assert lim.value == pytest.approx(0.1, rel=1e-5) and lim.value < 0.1
    with pytest.raises(ValueError):
        largest_stable(lambda x: 1.0, -1.0, 1.0)


def test_zoa_and_sdm_limits_agree_at_full_immersion():
    """Slotting with 4 flutes: H(t) hardly varies (4 engaged flutes at once), so the
    zero-order and time-periodic limits at the same speed agree; stated tolerance 3 %
    (the time-periodic default steps leave it within 1 % of its converged value, and
    the residual variation of H a few per cent of its mean)."""
    sys_ = _sys()
    rpm = 9000.0
    rel = []
    for m in ("zoa", "sdm"):
        def margin(d: float, m=m) -> float:
            t = StraightEndMill2D(KT, KN, 4, 1.0, "down", depth_mm=d)
            if m == "zoa":
                return zoa_margin(t.mean_directional_matrix(), sys_, rpm, 4)
            return sdm_margin(t.directional_samples(t.recommended_samples()), sys_, rpm,
                              4).margin
        rel.append(largest_stable(margin, 1.0, 1e3, rtol=1e-4).value)
    assert rel[1] == pytest.approx(rel[0], rel=0.03)


def test_plot_labels_and_suggested_speed(tmp_path):
    from orient.plots_lobes import plot_lobes
    from orient.stability import Lobes

    rpm = np.linspace(5000, 9000, 30)
    a = Lobes(rpm, 1 + 0.5 * np.sin(rpm / 300), "zoa", 0.2)
    b = Lobes(rpm[:5], np.full(5, 1.2), "sdm", 0.2)           # a spot check: markers
    png = tmp_path / "l.png"
    plot_lobes([a, b], (7000.0, 0.2), png, labels=["CAM posture, zero-order", "check"],
               suggested=(6000.0, 0.25))
    assert png.read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(ValueError, match="labels"):
        plot_lobes([a, b], None, png, labels=["one"])
    with pytest.raises(ValueError, match="suggested"):
        plot_lobes([a], None, png, suggested=(math.nan, 1.0))
