"""sim's force table with each force law (errpred.laws): the tangent of F(h) at the
static chip; the linear law's table unchanged."""

from __future__ import annotations

import numpy as np

from errpred import laws
from errpred.coefficients import CuttingCoefficients
from errpred.force import to_tool_frame
from errpred.laws.kienzle import KienzleCoefficients
from errpred.laws.lee_altintas import LeeAltintasCoefficients
from errpred.tool import Tool
from orient.dynamics import ModalSystem, Mode
from orient.engagement import LocalCut, engagement
from sim.cutting import prepare_cut

LIN = CuttingCoefficients(Ktc_N_mm2=2000.0, Krc_N_mm2=700.0, Kac_N_mm2=300.0,
                          Kte0_N_mm=20.0, Kre0_N_mm=25.0, Kae0_N_mm=5.0)
KZ = KienzleCoefficients(2200.0, 900.0, 350.0, 0.24, 0.3, 0.2, 5.0, 4.0, 1.0)
Z, X = np.eye(3)[2], np.eye(3)[0]
FLAT = Tool("flat", 10.0, flutes=2, helix_deg=30.0, flute_length_mm=6.0)
EDGES = FLAT.micro_edges(40, flank_height_mm=1.0)
CUT = LocalCut(1.0, 5.0, 1, 0.05)


def _system():
    m = Mode.from_frequency(922.0, 0.011, 1.34e6)
    return ModalSystem.from_modes([(m, (1, 0, 0)), (m, (0, 1, 0))], source="tool")


def test_kienzle_table_is_the_tangent_at_the_static_chip():
    model = prepare_cut(FLAT, KZ, Z, Z, X, CUT, _system(), 9000.0, edges=EDGES)
    ptr, pos, j, h0, nrm, f0, f1 = model.table
    # the table's engagement keeps the trailing edges (first-order chip 0): they rub with
    # the law's zero-chip force and no chip term (their static chip is the second-order
    # thickness the tooth before left, not the law's argument)
    eng = engagement(FLAT, EDGES, Z, Z, X, CUT, n_angles=model.steps_per_rev, trailing=True)
    i, f, jj = np.nonzero(eng.cutting)
    np.testing.assert_array_equal(jj, j)
    h = eng.h[i, f, j]
    assert np.all(f1[h == 0.0] == 0.0) and np.array_equal(h0[h > 0.0], h[h > 0.0])
    kappa, db = EDGES.kappa[j], EDGES.db[j]
    F = to_tool_frame(*(x * db for x in laws.force(KZ, h, kappa, 0.0)), eng.phi[i, f, j],
                      kappa) @ eng.frame
    np.testing.assert_allclose(f0 + h[:, None] * f1, F, atol=1e-12 * np.abs(F).max())
    # the slope: a finite difference of the law about h0 (h0 above the chip floor)
    d = 1e-6
    ok = h0 > 0.01
    Fp = to_tool_frame(*(x * db for x in laws.force(KZ, h0 + d, kappa, 0.0)),
                       eng.phi[i, f, j], kappa) @ eng.frame
    np.testing.assert_allclose(((Fp - F) / d)[ok], f1[ok], rtol=1e-4,
                               atol=1e-4 * np.abs(f1).max())


def test_constant_lee_altintas_gives_the_linear_table():
    la = LeeAltintasCoefficients([2000.0], [700.0], [300.0], [20.0], [25.0], [5.0])
    a = prepare_cut(FLAT, la, Z, Z, X, CUT, _system(), 9000.0, edges=EDGES).table
    b = prepare_cut(FLAT, LIN, Z, Z, X, CUT, _system(), 9000.0, edges=EDGES).table
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
