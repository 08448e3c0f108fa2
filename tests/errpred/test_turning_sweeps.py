"""A ball end mill whose axis turns along a move while its centre goes straight (a 5-axis
finishing pass whose lead changes): every point of the pass leaves a finished strip.

The sweeps of a turning move are pieces with a constant axis. Anchored at the tool's
tip, a piece's ball centre was off the real one by R sin(half the piece's turn) along the
feed and jumped back by twice that at every joint; the sweeps after a point (T2) then
started behind its own tool and took the strip of about one feed per tooth it leaves:
"no-finished-surface" at points where the real pass finishes the surface, at any pixel
size. Anchored at the corner's centre (a ball's centre), the ball part of each piece is
the real ball at both of its ends.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from errpred.geometry import GeometryModel, Resolution
from errpred.raster.meshes import Stock
from errpred.sweeps import build_sweeps, slerp
from errpred.tool import Tool
from nc.path import CutterLocations

D, R = 10.0, 5.0
DEPTH = 0.15            # the ball's depth under the stock's top [mm]
STEP = 0.3              # the ball centre's advance per block [mm]
LEAD0, DLEAD = 20.0, 0.3   # lead at the pass's start and its change per block [deg]
TILT0, DTILT = 40.0, 0.5   # tilt (about the feed) at the start, its change per block [deg]
BLOCKS = 30
X0 = -1.0            # the ball centre's x at the pass's start [mm]


def _axis(lead_deg: float, tilt_deg: float = 0.0) -> np.ndarray:
    """The tool axis leaning ``lead_deg`` toward the feed (+X), then ``tilt_deg`` about it."""
    a, b = math.radians(lead_deg), math.radians(tilt_deg)
    return np.array([math.sin(a), -math.cos(a) * math.sin(b), math.cos(a) * math.cos(b)])


def _pass() -> CutterLocations:
    """A rapid to the start, then feed moves along +X with the ball's centre on a straight
    line ``DEPTH`` into the stock's top, the lead and the tilt changing by ``DLEAD`` and
    ``DTILT`` a block (a 0.57 deg turn: one sweep piece each, as a planner's 5-axis
    raster has); 600 mm/min at 6000 min^-1 on two flutes: 0.05 mm a tooth at the tip."""
    x = X0 + STEP * np.arange(BLOCKS + 1)
    centre = np.column_stack([x, np.zeros_like(x), np.full_like(x, R - DEPTH)])
    axis = np.array([_axis(LEAD0 + DLEAD * k, TILT0 + DTILT * k) for k in range(BLOCKS + 1)])
    tip = centre - R * axis
    tip = np.vstack([tip[:1] + [0.0, 0.0, 30.0], tip])
    axis = np.vstack([axis[:1], axis])
    rapid = np.zeros(len(tip), dtype=bool)
    rapid[0] = rapid[1] = True
    return CutterLocations.from_arrays(tip, axis, 600.0, 6000.0, rapid=rapid)


def test_turning_pieces_hold_the_real_ball_centre_at_their_ends():
    """Each piece of a turning move has its ball centre where the real tool's is at the
    piece's two ends (the tool's tip plus R times the axis turned that far), to 1e-12 mm;
    anchored at the tip it was off by R sin(half the turn) = 25 um here."""
    tool = Tool("ball", D, flute_length_mm=20.0)
    cl = _pass()
    sw = build_sweeps(cl, tool)
    feed = ~np.isclose(np.linalg.norm(sw.d, axis=1), 0.0)
    assert feed.sum() == BLOCKS
    k = sw.cl_index[feed]
    om = np.arccos(np.clip(np.sum(cl.axis[k - 1] * cl.axis[k], axis=1), -1, 1))
    assert np.all((np.degrees(om) > 0.5) & (np.degrees(om) < 0.6))
    start = cl.tip[k - 1] + R * cl.axis[k - 1]
    end = cl.tip[k] + R * cl.axis[k]
    got0 = sw.p0[feed] + R * sw.w[feed]
    got1 = sw.p0[feed] + sw.d[feed] + R * sw.w[feed]
    assert np.abs(got0 - start).max() < 1e-12
    assert np.abs(got1 - end).max() < 1e-12
    # the tip-anchored pieces (anchor 0) are the old ones: off by R sin(turn / 2)
    old = build_sweeps(cl, tool, anchor_mm=0.0)
    off = np.linalg.norm(old.p0[feed] + R * old.w[feed] - start, axis=1)
    assert np.allclose(off, 2 * R * np.sin(om / 4), rtol=1e-6)


def test_a_non_finite_anchor_is_refused():
    with pytest.raises(ValueError, match="anchor_mm"):
        build_sweeps(_pass(), Tool("ball", D, flute_length_mm=20.0), anchor_mm=math.nan)


def test_slerp_turns_at_a_constant_rate():
    ua, ub = _axis(30.0), _axis(10.0)
    om = math.radians(20.0)
    t = np.array([0.0, 0.25, 0.5, 1.0])
    got = slerp(np.tile(ua, (4, 1)), np.tile(ub, (4, 1)), np.full(4, om), t)
    want = np.array([_axis(30.0 - 20.0 * s) for s in t])
    assert np.abs(got - want).max() < 1e-12


def test_every_point_of_a_turning_ball_pass_leaves_a_finished_strip():
    """Dense points (both ends of every block) along the pass, where the ball is wholly past
    the stock's edge: all predicted, the generation point on the ring of the ball across
    the feed, under the stock's top. With the tip-anchored pieces none of them was
    (no-finished-surface at every point, at any pixel size)."""
    tool = Tool("ball", D, flute_length_mm=20.0)
    stock = Stock.from_box([0.0, -20.0, -10.0], [40.0, 20.0, 0.0])
    cl = _pass()
    res = Resolution(pixel_mm=D / 64).dense()
    model = GeometryModel(tool, stock, cl, res, sensitivity=False)
    # blocks whose ball is wholly past the stock's edge at x = 0 at both ends (block k,
    # k >= 2 the feed moves, runs from centre x = X0 + STEP (k - 2)); not the last (the
    # pass's end leaves all it cuts)
    blocks = [k for k in range(2, BLOCKS + 1) if X0 + STEP * (k - 2) > R + 0.5]
    assert len(blocks) >= 5
    # the strip lies on the ring of the ball across the feed under the stock's top: the
    # ball's points n(psi) = (0, sin psi, -cos psi) from its centre, |psi| <= psi_max
    psi_max = math.asin(math.sqrt(R * R - (R - DEPTH) ** 2) / R)
    psi = np.linspace(-psi_max, psi_max, 201)
    ring = np.column_stack([np.zeros_like(psi), np.sin(psi), -np.cos(psi)])
    for b in blocks:
        for g in model.geometry(b):
            assert g.status == "predicted", (b, g.status)
            assert g.finished_pixels > 0
            kappa = np.arccos(np.clip(-ring @ g.axis, -1.0, 1.0))
            assert kappa.min() - 1e-3 < g.gen.kappa_rad < kappa.max() + 1e-3
            assert abs(float(g.gen.point_world[1])) < R * math.sin(psi_max)
            assert -DEPTH - 1e-3 < float(g.gen.point_world[2]) < 1e-3


def _bend(bend_deg: float) -> CutterLocations:
    """A 3-axis ball pass along +X, its centre ``DEPTH`` into a flat stock's top, that at
    x = 6 turns down (toward the stock) by ``bend_deg`` for 3 mm; 0.05 mm a tooth."""
    b = math.radians(bend_deg)
    z = -DEPTH
    tip = np.array([[-8.0, 0.0, 30.0], [-8.0, 0.0, z], [6.0, 0.0, z],
                    [6.0 + 3.0 * math.cos(b), 0.0, z - 3.0 * math.sin(b)]])
    rapid = np.array([True, True, False, False])
    return CutterLocations.from_arrays(tip, [0.0, 0.0, 1.0], 600.0, 6000.0, rapid=rapid)


def test_a_vertex_turning_toward_the_stock_by_more_than_fz_over_r_finishes_nothing():
    """Not a discretization artefact, and not 5-axis: at a vertex where the path turns
    toward the surface by delta, the next move's ball a little way on (a < 2 R delta) is
    deeper under the vertex's contact than the vertex's own ball, by up to R delta^2 / 8
    (0.76 um for 2 deg at R 5 mm), so the strip of one feed per tooth the vertex's
    revolution leaves is overcut wherever delta > fz / R (0.57 deg here). The dense
    point at the vertex finishes nothing at 2 deg, at the default pixel and at half of
    it; at 0.3 deg it finishes a strip."""
    tool = Tool("ball", D, flute_length_mm=20.0)
    stock = Stock.from_box([-20.0, -20.0, -10.0], [40.0, 20.0, 0.0])
    res = Resolution(pixel_mm=D / 64).dense()
    for bend, want in ((2.0, "no-finished-surface"), (0.3, "predicted")):
        for r in (res, res.finer(2)):
            model = GeometryModel(tool, stock, _bend(bend), r, sensitivity=False)
            vertex = [g for g in model.geometry(2) if abs(g.tip[0] - 6.0) < 1e-9]
            assert len(vertex) == 1
            assert vertex[0].status == want, (bend, r.pixel_mm)
