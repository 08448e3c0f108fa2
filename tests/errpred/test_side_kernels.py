"""The side view's numba kernels against their numpy twins (``errpred/_side_kernels.py``).

The kernels do the twins' arithmetic, but numpy forms its matrix products in BLAS and
its ``arctan2``/``arccos`` with its own routines, so coordinates and angles agree
within ``SIDE_HITS_TOL_MM`` / ``SIDE_HITS_TOL_RAD`` (not to the bit), and every
pixel's flags (hit, in stock, cutting, finished) must be the same.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from nc import parse_program
from nc.path import cutter_locations
from errpred import geometry as G
from errpred._side_kernels import interval_contains, interval_contains_numpy
from errpred.constants import MEMBERSHIP_EPS_MM, SIDE_HITS_TOL_MM, SIDE_HITS_TOL_RAD
from errpred.geometry import GeometryModel, Resolution
from errpred.raster.camera import View
from errpred.raster.meshes import Stock
from errpred.surface import envelope_hits, generation_point, regions, side_regions
from errpred.tool import Tool

TOOLS = (Tool("ball", 10.0, flute_length_mm=15.0),
         Tool("radius", 10.0, corner_radius_mm=1.5, flute_length_mm=12.0),
         Tool("flat", 6.0, flute_length_mm=8.0, rotation="ccw"))


def _random_frame(rng: np.random.Generator, mirrored: bool) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    if np.linalg.det(q) < 0:
        q[2] = -q[2]
    if mirrored:  # a counter-clockwise spindle's frame (errpred/frames.py)
        q[0] = -q[0]
    return q


def _assert_same_hits(a, b) -> None:
    """``a``: the kernel's hits (its in-stock pixels, ``a.index``); ``b``: the numpy twin's
    over the whole view."""
    assert a.shape == b.shape
    k = a.index
    np.testing.assert_allclose(a.tool_xyz, b.tool_xyz[k], rtol=0, atol=SIDE_HITS_TOL_MM)
    np.testing.assert_allclose(a.world, b.world[k], rtol=0, atol=SIDE_HITS_TOL_MM)
    dphi = np.abs(np.angle(np.exp(1j * (a.phi - b.phi[k]))))
    assert dphi.max(initial=0.0) <= SIDE_HITS_TOL_RAD
    # the contact angle through its cosine, (r - z) / r: well conditioned where arccos is
    # not (near kappa 0 a rounding of z moves kappa by sqrt(2 dz / r)); the tools' corner
    # radii are at least 1 mm, so the cosines agree within SIDE_HITS_TOL_MM / 1 mm
    np.testing.assert_allclose(np.cos(a.kappa), np.cos(b.kappa[k]), rtol=0,
                               atol=SIDE_HITS_TOL_MM)
    away = np.cos(a.kappa) < 1.0 - 1e-6      # off the pole: the angles themselves
    np.testing.assert_allclose(a.kappa[away], b.kappa[k][away], rtol=0, atol=SIDE_HITS_TOL_RAD)


class _Everywhere:
    """A stock probe whose box holds every hit (the kernel then keeps every pixel hit)."""

    _BIG = np.full(3, 1e9)

    def kernel_args(self):
        return True, -self._BIG, self._BIG, np.zeros((1, 1)), np.zeros((1, 1))


_NO_SWEEPS = (np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)),
              np.zeros((0, 3)))


@pytest.mark.parametrize("tool", TOOLS, ids=lambda t: t.kind)
def test_side_hits_match_the_numpy_twin_on_seeded_views(tool):
    """Seeded side views (frames at any attitude, mirrored ones too, tips far from the
    origin where coordinates round coarsely, windows past the flute length and below
    the tip), the stock everywhere: the kernel keeps exactly the pixels the numpy twin
    hits, with the same hits within the tolerances."""
    rng = np.random.default_rng(20261127)
    hit = 0
    for k in range(12):
        frame = _random_frame(rng, mirrored=bool(k % 2))
        tip = rng.uniform(-500.0, 500.0, 3)
        az = rng.uniform(-math.pi, math.pi)
        pixel = rng.uniform(0.03, 0.08)
        width = tool.diameter_mm + rng.uniform(0.0, 2.0)
        height = rng.uniform(0.2, 1.3) * tool.flute_length_mm
        view = View.side(tip, frame, az, width, height, pixel)
        if k % 3 == 0:  # the window starting below the tip
            view = View(view.origin - 0.7 * view.basis[1], view.basis, pixel, view.nx,
                        view.ny + 20)
        a = side_regions(tool, view, frame, tip, _Everywhere(), _NO_SWEEPS, _NO_SWEEPS).hits
        b = envelope_hits(tool, view, frame, tip)
        np.testing.assert_array_equal(a.index, np.flatnonzero(b.valid))
        _assert_same_hits(a, b)
        hit += a.index.size
        # hits lie on the envelope: radius R above the corner, on the ray
        z = a.tool_xyz[:, 2]
        rho = np.hypot(a.tool_xyz[:, 0], a.tool_xyz[:, 1])
        up = z >= tool.corner_radius_mm
        np.testing.assert_allclose(rho[up], tool.radius_mm, atol=1e-9)
        assert z.min(initial=0.0) >= 0.0 and z.max(initial=0.0) <= tool.flute_length_mm
    assert hit > 10_000


def test_interval_contains_matches_the_numpy_twin():
    """Points in and around a view's window against a seeded depth interval (some pixels
    empty: +inf): the same answers as the stock probe's numpy code."""
    rng = np.random.default_rng(7)
    frame = _random_frame(rng, mirrored=False)
    view = View.side(rng.uniform(-100, 100, 3), frame, 0.3, 12.0, 7.0, 0.05)
    bottom = rng.uniform(0.0, 6.0, view.shape)
    top = bottom + rng.uniform(0.0, 6.0, view.shape)
    empty = rng.random(view.shape) < 0.2
    bottom[empty] = top[empty] = np.inf
    uvd = np.column_stack([rng.uniform(-1.0, view.width_mm + 1.0, 50_000),
                           rng.uniform(-1.0, view.height_mm + 1.0, 50_000),
                           rng.uniform(-1.0, 13.0, 50_000)])
    pts = view.to_world(uvd)
    got = interval_contains(pts, view.origin, view.basis, view.pixel_mm, view.nx, view.ny,
                            bottom, top, MEMBERSHIP_EPS_MM)
    want = interval_contains_numpy(pts, view, bottom, top, MEMBERSHIP_EPS_MM)
    np.testing.assert_array_equal(got, want)
    assert 0.1 < want.mean() < 0.9


def _side_cuts(stock, tool):
    """Geometry of the middle block of a wall side-milled along +X (material on +Y), with
    every side view the point makes recorded: (view, frame, tip, probe, t1, t2)."""
    prog = parse_program("G21 G90 G94\nS6000 M3\nG0 X-30 Y0 Z0\nG1 X-2 F600\nG1 X2\n"
                         "G1 X30\nM30\n")
    res = Resolution(pixel_mm=tool.diameter_mm / 32, angle_step_rad=math.radians(4.0))
    model = GeometryModel(tool, stock, cutter_locations(prog), res, sensitivity=False)
    seen = []
    reg = G.side_regions

    def record(tool_, view, frame, tip, probe, t1, t2, **kw):
        seen.append((view, frame.copy(), tip.copy(), probe, t1, t2))
        return reg(tool_, view, frame, tip, probe, t1, t2, **kw)

    G.side_regions = record
    try:
        (g,) = model.geometry(2)
    finally:
        G.side_regions = reg
    return g, seen


@pytest.mark.parametrize("mesh", [False, True], ids=["box", "mesh"])
def test_real_side_views_flag_the_same_pixels_as_the_numpy_twins(mesh):
    """The side views of wall cuts (a flat end mill with a counter-clockwise spindle, a
    radius end mill; the stock a box and the same box as a mesh, whose probe is the
    interval kernel): hits within the tolerances, the same in-stock, cutting and
    finished pixels as the numpy twins, the generation point within the tolerances;
    and :func:`side_regions` (one kernel: the in-stock pixels only) the same pixels and
    generation point as the numpy twins over the whole view."""
    finished = 0
    for tool in (TOOLS[2], Tool("radius", 10.0, corner_radius_mm=1.5, flute_length_mm=6.0)):
        # 1 mm radial depth of cut, 2 mm high, above the corner
        z0 = tool.corner_radius_mm + 0.001
        lo, hi = [-20.0, tool.radius_mm - 1.0, z0], [20.0, 30.0, z0 + 2.0]
        stock = (Stock.from_mesh(trimesh.creation.box(bounds=[lo, hi])) if mesh
                 else Stock.from_box(lo, hi))
        g, seen = _side_cuts(stock, tool)
        assert g.status == "predicted" and g.view == "side"
        assert seen
        for view, frame, tip, probe, t1, t2 in seen:
            b = envelope_hits(tool, view, frame, tip)
            if mesh:
                assert not probe._box
                twin = (lambda p, v=view, pr=probe:  # noqa: E731
                        interval_contains_numpy(p, v, pr.bottom, pr.top, MEMBERSHIP_EPS_MM))
                np.testing.assert_array_equal(probe(b.world[b.valid]), twin(b.world[b.valid]))
            else:
                twin = probe
            rb = regions(tool, b, view.pixel_mm, twin, t1, t2)
            finished += int(rb.finished.sum())
            # the kernel's region: exactly the twin's in-stock pixels, in order
            rc = side_regions(tool, view, frame, tip, probe, t1, t2)
            in_stock = b.valid.copy()
            in_stock[in_stock] = twin(b.world[b.valid])
            np.testing.assert_array_equal(rc.hits.index, np.flatnonzero(in_stock))
            _assert_same_hits(rc.hits, b)
            for got, want in ((rc.cutting, rb.cutting), (rc.finished, rb.finished)):
                np.testing.assert_array_equal(got, want[rc.hits.index])
                assert got.sum() == want.sum()
            # finished pixels only, T2's nearest sweeps asked first: the same pixels
            rf = side_regions(tool, view, frame, tip, probe, t1, t2, cutting=False)
            assert rf.cutting is None
            np.testing.assert_array_equal(rf.hits.index, rc.hits.index)
            np.testing.assert_array_equal(rf.finished, rc.finished)
            gb = generation_point(tool, rb, frame, tip)
            for ga in (generation_point(tool, rc, frame, tip),
                       generation_point(tool, rf, frame, tip)):
                assert (ga is None) == (gb is None)
                if ga is not None:
                    assert ga.pixels == gb.pixels
                    np.testing.assert_allclose(ga.point_world, gb.point_world,
                                               atol=SIDE_HITS_TOL_MM)
                    np.testing.assert_allclose(ga.normal_world, gb.normal_world,
                                               atol=SIDE_HITS_TOL_RAD)
                    np.testing.assert_allclose(ga.samples_kappa, gb.samples_kappa,
                                               atol=SIDE_HITS_TOL_RAD)
                    assert abs(math.remainder(ga.theta_rad - gb.theta_rad, 2 * math.pi)) \
                        <= SIDE_HITS_TOL_RAD
    assert finished > 100
