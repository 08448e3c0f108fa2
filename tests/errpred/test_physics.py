"""Stage 2's engagement as a list of cutting entries (``errpred.physics``) against the
whole (sample, flute, micro edge) block it stands for (``errpred.engagement.expand_flutes``,
``errpred.force.chip_thickness`` and ``tool_forces``)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from errpred.coefficients import CuttingCoefficients
from errpred.engagement import expand_flutes
from errpred.force import chip_thickness, tool_forces
from errpred.physics import (_deflection, _engagement, _flute_entries, _revolution,
                             _strip_error, _wear_influence, bending_basis)
from errpred.tool import Tool

from .cases import stiff_tool

COEF = CuttingCoefficients(Ktc_N_mm2=2000.0, Krc_N_mm2=700.0, Kac_N_mm2=300.0,
                           Kte0_N_mm=15.0, Kre0_N_mm=20.0, Kae0_N_mm=5.0,
                           Kte1_N_mm2=2e-3, Kre1_N_mm2=3e-3, Kae1_N_mm2=1e-3)


def _point(tool: Tool, m: int, n: int, seed: int, *, weight: bool, shift: bool):
    """A point's flute-0 engagement: a band of steps and micro edges cutting (few per
    cent of the block, as at a finishing point), sub-step weights and shifts on them."""
    rng = np.random.default_rng(seed)
    c0 = np.zeros((n, m), bool)
    c0[n // 5:n // 3, m // 2:m // 2 + 7] = True
    c0 &= rng.random(c0.shape) < 0.8
    w0 = np.where(c0, rng.integers(1, 9, c0.shape) / np.float32(8), 0).astype(np.float32)
    s0 = np.where(c0 & (rng.random(c0.shape) < 0.3),
                  rng.uniform(-0.01, 0.01, c0.shape), 0).astype(np.float32)
    axis = np.array([0.3, -0.2, 1.0]) / math.hypot(0.3, 0.2, 1.0)
    frame = np.linalg.qr(rng.normal(size=(3, 3)))[0].T
    return SimpleNamespace(cutting0=c0, weight0=w0 if weight else None,
                           shift0=s0 if shift else None, frame=frame,
                           feed_per_tooth_world=np.array([0.04, 0.01, -0.005]), axis=axis,
                           spindle_rpm=9000.0)


@pytest.mark.parametrize("flutes", [2, 3])
@pytest.mark.parametrize("weight, shift", [(True, True), (True, False), (False, False)])
def test_cutting_entries_are_the_blocks_non_zero_entries(flutes, weight, shift):
    tool = Tool("ball", 6.0, flutes=flutes, helix_deg=30.0, flute_length_mm=12.0)
    edges = tool.micro_edges(40)
    n = 60 * flutes
    g = _point(tool, len(edges), n, 7 + flutes, weight=weight, shift=shift)
    theta, cols, e, i, k, j, phi, w = _engagement(tool, edges, g)
    assert np.array_equal(cols, np.flatnonzero(g.cutting0.any(axis=0)))
    ph, cut = expand_flutes(theta, g.cutting0[:, cols], e, flutes)
    if shift:
        ph = ph + expand_flutes(theta, g.shift0[:, cols].astype(float), e, flutes)[1]
    ii, kk, jj = np.nonzero(cut)
    assert ii.size == flutes * np.count_nonzero(g.cutting0) > 0
    for a, b in ((i, ii), (k, kk), (j, jj)):
        assert np.array_equal(a, b)
    assert np.array_equal(phi, ph[ii, kk, jj])              # bit for bit
    if weight:
        wb = expand_flutes(theta, g.weight0[:, cols].astype(float), e, flutes)[1]
        assert np.array_equal(w, wb[ii, kk, jj])
    else:
        assert w is None


@pytest.mark.parametrize("flutes", [2, 4])
def test_revolution_from_the_entries_is_the_blocks_bit_for_bit(flutes):
    """The force from the entries equals the one from the whole block (chip thickness
    and tool forces on every sample, flute and micro edge), and the deflection follows."""
    tool = Tool("ball", 6.0, flutes=flutes, helix_deg=30.0, flute_length_mm=12.0)
    edges = tool.micro_edges(40)
    n = 45 * flutes
    g = _point(tool, len(edges), n, 3, weight=True, shift=True)
    cl = np.random.default_rng(2).uniform(0, 300, len(edges))
    theta, force, defl, _eng = _revolution(tool, edges, COEF, stiff_tool(), g, cl, [])
    cols = np.flatnonzero(g.cutting0.any(axis=0))
    e = edges.take(cols)
    ph, cut = expand_flutes(theta, g.cutting0[:, cols], e, flutes)
    ph = ph + expand_flutes(theta, g.shift0[:, cols].astype(float), e, flutes)[1]
    wb = expand_flutes(theta, g.weight0[:, cols].astype(float), e, flutes)[1]
    f_tool = g.frame @ g.feed_per_tooth_world
    h = np.where(cut, chip_thickness(e, ph, f_tool), 0.0)
    ref = tool_forces(e, COEF, ph, h, cut, cl[cols], weight=wb) @ g.frame
    assert np.abs(ref).max() > 1.0
    assert np.array_equal(force, ref)
    assert np.array_equal(defl, _deflection(stiff_tool(), g, ref, []))


def test_revolution_with_a_wear_per_flute_and_with_one_flute():
    """A per-flute cutting distance (n_fl, m) reaches each flute's entries, and a single
    flute is its own block: both against the whole block's force."""
    for flutes, per_flute in ((3, True), (1, False)):
        tool = Tool("ball", 6.0, flutes=flutes, helix_deg=30.0, flute_length_mm=12.0)
        edges = tool.micro_edges(40)
        n = 48 * flutes
        g = _point(tool, len(edges), n, 11, weight=True, shift=False)
        rng = np.random.default_rng(4)
        cl = rng.uniform(0, 300, (flutes, len(edges)) if per_flute else len(edges))
        theta, force, _defl, _eng = _revolution(tool, edges, COEF, stiff_tool(), g, cl, [])
        cols = np.flatnonzero(g.cutting0.any(axis=0))
        e = edges.take(cols)
        ph, cut = expand_flutes(theta, g.cutting0[:, cols], e, flutes)
        wb = expand_flutes(theta, g.weight0[:, cols].astype(float), e, flutes)[1]
        h = np.where(cut, chip_thickness(e, ph, g.frame @ g.feed_per_tooth_world), 0.0)
        ref = tool_forces(e, COEF, ph, h, cut, cl[..., cols], weight=wb) @ g.frame
        assert np.abs(ref).max() > 1.0
        np.testing.assert_allclose(force, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
        if per_flute:   # each flute's own wear counts: another flute's would differ
            other = _revolution(tool, edges, COEF, stiff_tool(), g, cl[::-1], [])[1]
            assert not np.allclose(other, force)


def test_a_point_that_cuts_nothing_and_steps_that_do_not_split_into_flutes():
    tool = Tool("ball", 6.0, flutes=2, helix_deg=30.0, flute_length_mm=12.0)
    edges = tool.micro_edges(40)
    g = _point(tool, len(edges), 90, 5, weight=True, shift=True)
    g.cutting0 = np.zeros_like(g.cutting0)
    g.weight0 = np.zeros_like(g.weight0)
    g.shift0 = np.zeros_like(g.shift0)
    theta, force, defl, eng = _revolution(tool, edges, COEF, stiff_tool(), g,
                                          np.zeros(len(edges)), [])
    assert eng[3].size == 0 and not force.any() and not defl.any()
    odd = _point(tool, len(edges), 91, 5, weight=False, shift=False)
    with pytest.raises(ValueError, match="not a multiple of 2 flutes"):
        _engagement(tool, edges, odd)


def test_wear_influence_is_the_error_s_derivative_in_each_edge_s_cutting_distance():
    """The linear law's edge force grows by Kxe1 cl db, so the error at the generation
    point is affine in each micro edge's cutting distance: the influence from the entries
    equals the difference of two revolutions with one edge's distance changed."""
    tool = Tool("ball", 6.0, flutes=2, helix_deg=30.0, flute_length_mm=12.0)
    edges = tool.micro_edges(40)
    g = _point(tool, len(edges), 120, 9, weight=True, shift=True)
    g.gen = SimpleNamespace(samples_theta=None, theta_rad=1.1,
                            normal_world=np.array([0.6, 0.0, 0.8]))
    cl = np.random.default_rng(3).uniform(0, 300, len(edges))
    comp = stiff_tool()
    cols, a = _wear_influence(tool, edges, COEF, comp, g, [])
    assert np.array_equal(cols, np.flatnonzero(g.cutting0.any(axis=0)))
    theta, _f, defl, _e = _revolution(tool, edges, COEF, comp, g, cl, [])
    base = _strip_error(g.gen, defl, theta)
    delta = 50.0
    checked = 0
    for q in (0, cols.size // 2, cols.size - 1):
        bumped = cl.copy()
        bumped[cols[q]] += delta
        th, _f, d2, _e = _revolution(tool, edges, COEF, comp, g, bumped, [])
        slope = (_strip_error(g.gen, d2, th) - base) / delta
        assert slope == pytest.approx(a[q], rel=1e-6, abs=1e-9 * np.abs(a).max())
        checked += abs(a[q]) > 0
    assert checked >= 2


def _lexsorted_entries(i0, j0, n, flutes):
    """Every flute's entries from flute 0's as stage 2 first listed them: all flutes'
    entries, then ``np.lexsort`` by (step, flute, edge) (the twin of ``_flute_entries``)."""
    shift = n // flutes
    k = np.repeat(np.arange(flutes), i0.size)
    i = (np.tile(i0, flutes) - shift * k) % n
    j = np.tile(j0, flutes)
    order = np.lexsort((j, k, i))
    return i[order], k[order], j[order], np.tile(np.arange(i0.size), flutes)[order]


def _check_flute_entries(c0: np.ndarray, flutes: int) -> None:
    i0, j0 = np.nonzero(c0)
    i, k, src = _flute_entries(i0, c0.shape[0], flutes)
    want = _lexsorted_entries(i0, j0, c0.shape[0], flutes)
    for got, ref in zip((i, k, j0[src], src), want):
        assert got.dtype == ref.dtype and np.array_equal(got, ref)
    assert i.size == flutes * i0.size


@pytest.mark.parametrize("seed", range(40))
def test_flute_entries_are_the_sorted_entries_of_every_flute(seed):
    """The entries without the sort: the same arrays as sorting all flutes' entries, for
    sparse and dense blocks, empty rows and blocks, one flute and several."""
    rng = np.random.default_rng(seed)
    flutes = int(rng.integers(1, 5))
    n = flutes * int(rng.integers(1, 40))
    m = int(rng.integers(1, 25))
    _check_flute_entries(rng.random((n, m)) < (0.0 if seed == 0 else rng.random() * 0.6),
                         flutes)


@pytest.mark.parametrize("flutes", [1, 2, 3, 4])
def test_flute_entries_of_one_step_a_flute_and_of_full_blocks(flutes):
    """As many steps as flutes (each flute's row is another flute's), and every sample
    cutting."""
    rng = np.random.default_rng(flutes)
    for n in (flutes, 3 * flutes):
        _check_flute_entries(np.ones((n, 5), bool), flutes)
        _check_flute_entries(rng.random((n, 7)) < 0.5, flutes)


def test_bending_basis_is_numpys_cross_and_norm_bit_for_bit():
    """Its three-component arithmetic against np.linalg.norm and np.cross, byte for byte
    (signed zeros too), for axes in every direction, along +X and -X and near them
    (where Y is taken as the first direction)."""
    rng = np.random.default_rng(5)
    axes = rng.normal(size=(2000, 3))
    axes[:100] = [1.0, 0.0, 0.0] + 1e-7 * rng.normal(size=(100, 3))
    axes[100:200] = [-1.0, 0.0, 0.0] + 1e-7 * rng.normal(size=(100, 3))
    axes[200:204] = [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    near_x = 0
    for u in axes:
        x = np.array([1.0, 0.0, 0.0]) - u[0] * u
        if np.linalg.norm(x) < 1e-6:
            near_x += 1
            x = np.array([0.0, 1.0, 0.0]) - u[1] * u
        x /= np.linalg.norm(x)
        b = bending_basis(u)
        for got, ref in ((b["x"], x), (b["y"], np.cross(u, x)), (b["z"], u)):
            assert got.dtype == ref.dtype and got.tobytes() == ref.tobytes()
    assert near_x > 200
