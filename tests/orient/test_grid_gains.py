"""The grid's gains shared between cutter locations with the same local cut
(orient.grid_gains): each location's equal the direct computation at its own frame."""

from __future__ import annotations

import numpy as np

from errpred.coefficients import CuttingCoefficients
from errpred.tool import Tool
from orient.engagement import LocalCut
from orient.gain import process_gain_batch
from orient.geometry import posture_axis
from orient.grid_gains import share_grid_gains

COEF = CuttingCoefficients(Ktc_N_mm2=2000.0, Krc_N_mm2=700.0, Kac_N_mm2=300.0,
                           Kte0_N_mm=20.0, Kre0_N_mm=25.0, Kae0_N_mm=5.0)
BALL = Tool("ball", 10.0, flutes=2, helix_deg=30.0, flute_length_mm=15.0)


def test_shared_grid_gains_equal_the_direct_ones_in_every_frame():
    rng = np.random.default_rng(20)
    t = 12
    normal = rng.normal(size=(t, 3)) * [0.5, 0.5, 1.0] + [0, 0, 1.5]
    feed = rng.normal(size=(t, 3))
    # three cuts shared by several locations (as a raster's [orient.cut]), two alone,
    # one curved
    cuts_k = [LocalCut(0.15, 0.35, -1, 0.08), LocalCut(0.15, 0.35, 0, 0.08),
              LocalCut(0.3, 0.5, 1, 0.05, 0.02, -0.01), LocalCut(0.1, 0.2, 1, 0.1),
              LocalCut(0.2, 0.4, -1, 0.06, -0.03, 0.0)]
    pick = [0, 0, 0, 1, 1, 2, 2, 2, 0, 3, 4, 1]
    cuts = [cuts_k[k] for k in pick]
    lead, tilt = np.meshgrid(np.radians(np.linspace(-40, 40, 5)),
                             np.radians(np.linspace(-40, 40, 4)), indexing="ij")
    lead, tilt = lead.ravel(), tilt.ravel()
    grid_axes = posture_axis(normal[:, None, :], feed[:, None, :], lead[None], tilt[None])
    cam = normal / np.linalg.norm(normal, axis=1)[:, None]
    axes = np.concatenate([grid_axes, cam[:, None, :]], axis=1)
    ok = rng.random(axes.shape[:2]) < 0.8
    P = np.zeros(axes.shape[:2] + (3, 3))
    sense = np.zeros(axes.shape[:2])
    done = share_grid_gains(BALL, COEF, normal, feed, ok, cuts, (lead, tilt), P, sense,
                            parallel=False)
    # every grid posture where ok, nothing else (the CAM column, the infeasible ones)
    np.testing.assert_array_equal(done[:, :-1], ok[:, :-1])
    assert not done[:, -1].any()
    assert np.all(P[~done] == 0.0) and np.all(sense[~done] == 0.0)
    r, c = np.nonzero(done)
    obj = np.empty(len(r), dtype=object)
    obj[:] = [cuts[i] for i in r]
    direct = process_gain_batch(BALL, COEF, axes[r, c], normal[r], feed[r], obj)
    scale = np.abs(direct.P).max(axis=(1, 2))
    assert np.all(scale > 1e4)                     # real cuts, N/m
    err = np.abs(P[r, c] - direct.P).max(axis=(1, 2)) / scale
    assert err.max() < 1e-9, err.max()
    np.testing.assert_allclose(sense[r, c], direct.cut_sense, rtol=0, atol=1e-9)
    # the frames differ: the same canonical gains turned, not copied
    assert not np.allclose(P[0, 0], P[1, 0])
