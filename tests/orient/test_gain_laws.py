"""The process gain with each force law (errpred.laws): the closed form takes the
slope as a polynomial in kappa (linear, Lee-Altintas), Kienzle's chip-dependent
slope goes through the sampled engagement."""

from __future__ import annotations

import math

import numpy as np
import pytest

from errpred.coefficients import CuttingCoefficients
from errpred.laws.kienzle import KienzleCoefficients
from errpred.laws.lee_altintas import LeeAltintasCoefficients
from errpred.tool import Tool
from orient.engagement import LocalCut, engagement
from orient.gain import (
    GainResolution,
    default_edges,
    directional_matrices,
    gain_from_engagement,
    process_gain,
    process_gain_batch,
)
from orient.geometry import posture_axis

LIN = CuttingCoefficients(Ktc_N_mm2=2000.0, Krc_N_mm2=700.0, Kac_N_mm2=300.0,
                          Kte0_N_mm=20.0, Kre0_N_mm=25.0, Kae0_N_mm=5.0)
LA_CONST = LeeAltintasCoefficients([2000.0], [700.0], [300.0], [20.0], [25.0], [5.0])
LA = LeeAltintasCoefficients([2600.0, -900.0, 300.0], [1100.0, -400.0], [150.0, 200.0],
                             [25.0], [30.0], [2.0])
KZ0 = KienzleCoefficients(2000.0, 700.0, 300.0, 0.0, 0.0, 0.0)      # = LIN's chip terms
KZ = KienzleCoefficients(2200.0, 900.0, 350.0, 0.25, 0.25, 0.25)
Z, X = np.eye(3)[2], np.eye(3)[0]
BALL = Tool("ball", 10.0, flutes=2, helix_deg=30.0, flute_length_mm=15.0)
U = posture_axis(Z, X, math.radians(15), math.radians(-10))
CUT = LocalCut(0.3, 0.5, 1, 0.06)


def _rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def test_constant_lee_altintas_is_the_linear_law_bit_for_bit():
    a = process_gain(BALL, LA_CONST, U, Z, X, CUT, n_angles=36)
    b = process_gain(BALL, LIN, U, Z, X, CUT, n_angles=36)
    np.testing.assert_array_equal(a.H, b.H)
    ba = process_gain_batch(BALL, LA_CONST, np.stack([U, Z]), Z, X, CUT)
    bb = process_gain_batch(BALL, LIN, np.stack([U, Z]), Z, X, CUT)
    np.testing.assert_array_equal(ba.P, bb.P)


def test_lee_altintas_closed_form_equals_the_sampled_gain_in_the_limit():
    """The kernel's polynomial in kappa against errpred.laws' numpy evaluation on
    sampled engagements of the same micro edges, converging as they refine."""
    edges = default_edges(BALL)
    exact = process_gain(BALL, LA, U, Z, X, CUT, edges=edges,
                         resolution=GainResolution(root_step_rad=math.radians(0.5)))
    lin = process_gain(BALL, LIN, U, Z, X, CUT, edges=edges)
    assert _rel(exact.P, lin.P) > 0.05          # the polynomial does change the gain
    errs = [_rel(gain_from_engagement(BALL, edges, LA,
                                      engagement(BALL, edges, U, Z, X, CUT, n)).P, exact.P)
            for n in (180, 1440)]
    assert errs[-1] < 2e-3 and errs[-1] < errs[0]


def test_kienzle_sampled_path_with_zero_exponent_matches_the_closed_form():
    """The per-edge numeric path (Kienzle) against the closed form (linear), same law."""
    edges = default_edges(BALL)
    a = process_gain(BALL, KZ0, U, Z, X, CUT, edges=edges, n_angles=36)
    b = process_gain(BALL, LIN, U, Z, X, CUT, edges=edges, n_angles=36)
    assert a.H.shape == b.H.shape
    assert _rel(a.P, b.P) < 0.02
    assert a.mean_chip_mm == pytest.approx(b.mean_chip_mm, rel=0.02)


def test_kienzle_gain_falls_with_the_feed_as_the_power_law_says(monkeypatch):
    """Slope (1-m) k h^-m with one m for all directions: doubling the feed scales every
    chip by 2 and the gain by 2^-m. The chip floor (KIENZLE_MIN_CHIP_MM, where the
    slope stops growing) is moved below every chip of the ball's tip here: with it
    |P| falls by 0.846 instead of 2^-0.25 = 0.841 (edges near the tip have chips
    under 1 um)."""
    import errpred.laws.kienzle as kz

    monkeypatch.setattr(kz, "KIENZLE_MIN_CHIP_MM", 1e-9)
    p1 = process_gain(BALL, KZ, U, Z, X, CUT).P
    p2 = process_gain(BALL, KZ, U, Z, X, LocalCut(0.3, 0.5, 1, 0.12)).P
    np.testing.assert_allclose(p2, 2.0 ** -0.25 * p1, atol=2e-3 * np.abs(p1).max())


def test_kienzle_batch_equals_single_postures_and_needs_the_chip():
    axes = np.stack([U, posture_axis(Z, X, math.radians(-20), math.radians(5))])
    b = process_gain_batch(BALL, KZ, axes, Z, X, CUT)
    for i in range(2):
        g = process_gain(BALL, KZ, axes[i], Z, X, CUT)
        np.testing.assert_array_equal(b.P[i], g.P)
        assert b.mean_chip_mm[i] == g.mean_chip_mm
    edges = default_edges(BALL)
    eng = engagement(BALL, edges, U, Z, X, CUT, 36)
    with pytest.raises(ValueError, match="kienzle law's slope depends on the chip"):
        directional_matrices(BALL, edges, KZ, eng.frame, eng.phi, eng.cutting)
