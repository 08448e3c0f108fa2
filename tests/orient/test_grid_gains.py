"""The planner's shared work (issue 20): the grid's gains shared between cutter
locations with the same local cut (orient.grid_gains) equal the direct computation in
each location's frame; the margins of locations sharing one modal system, computed in
one call (orient.plan_margins), equal one call per location bit for bit."""

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


class _Rigid:
    """A workpiece without modes: every point's system is the tool's, one object."""

    def system_at(self, tool, point):
        return tool


class _OwnSystem:
    """Every point its own system object (as a thin wall's): the same modes here."""

    def system_at(self, tool, point):
        return tool.with_tool_axis(tool.tool_axis)


def test_margins_of_locations_sharing_a_system_equal_one_call_per_location():
    from orient.dynamics import Mode, ModalSystem
    from orient.plan_margins import _margins_rows
    from orient.stability import zoa_margin_batch

    tool_sys = ModalSystem.from_modes([(Mode.from_frequency(2150, 0.03, 6e6), (1, 0, 0)),
                                       (Mode.from_frequency(2240, 0.028, 6.5e6), (0, 1, 0))],
                                      source="tool")
    rng = np.random.default_rng(3)
    t, s = 9, 7
    normal = rng.normal(size=(t, 3)) * [0.4, 0.4, 1.0] + [0, 0, 2.0]
    feed = rng.normal(size=(t, 3))
    lead = np.radians(rng.uniform(-30, 30, s))
    tilt = np.radians(rng.uniform(-30, 30, s))
    axes = posture_axis(normal[:, None, :], feed[:, None, :], lead[None], tilt[None])
    ok = rng.random((t, s)) < 0.7
    ok[4] = False                                  # a location without candidates
    P = np.zeros((t, s, 3, 3))
    obj = np.empty(t * s, dtype=object)
    obj[:] = [LocalCut(0.3, 0.5, 1, 0.08)] * (t * s)
    g = process_gain_batch(BALL, COEF, axes.reshape(-1, 3), np.repeat(normal, s, axis=0),
                           np.repeat(feed, s, axis=0), obj)
    P[:] = g.P.reshape(t, s, 3, 3) * 3.0            # margins on both sides of the cap
    points = rng.normal(size=(t, 3))
    for cap in (None, 1.5):
        expect = np.full((t, s), np.inf)
        for i in range(t):
            sel = np.flatnonzero(ok[i])
            if len(sel):
                expect[i, sel] = zoa_margin_batch(
                    P[i, sel], tool_sys, 10000.0, 2,
                    mode_directions=tool_sys.directions_for_axes(axes[i, sel]), cap=cap)
        for wp in (_Rigid(), _OwnSystem()):
            systems = [None] * t
            got = _margins_rows(BALL, wp, tool_sys, points, axes, ok, P, 10000.0, cap, systems)
            np.testing.assert_array_equal(got, expect)
            assert systems[4] is None and all(systems[i] is not None for i in range(t)
                                              if ok[i].any())
        assert np.isfinite(expect[ok]).all() and np.ptp(expect[ok]) > 0.1
        if cap is not None:
            assert np.any(expect[ok] == cap) and np.any(expect[ok] < cap)
