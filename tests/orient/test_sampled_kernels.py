"""The sampled engagement's kernel (orient/_sampled_kernels.py) against its numpy twin,
and FluteEngagement.entries against its expanded arrays, bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from errpred.tool import Tool
from orient import _sampled_kernels as SK
from orient.engagement import LocalCut, engagement, flute_engagement
from orient.geometry import posture_axis

TOOLS = {
    "ball": Tool("ball", 10.0, flutes=2, helix_deg=30.0, flute_length_mm=15.0),
    "radius": Tool("radius", 10.0, corner_radius_mm=2.0, flutes=3, helix_deg=35.0,
                   flute_length_mm=12.0),
    "flat": Tool("flat", 8.0, flutes=4, helix_deg=30.0, flute_length_mm=12.0),
}


def _cases(seed: int, kind: str, count: int):
    """Random postures and cuts: every previous side, flat and curved tops."""
    rng = np.random.default_rng(seed)
    tool = TOOLS[kind]
    for t in range(count):
        n = rng.normal(size=3)
        n[2] = abs(n[2]) + 0.5
        n /= np.linalg.norm(n)
        feed = rng.normal(size=3)
        feed -= (feed @ n) * n
        lead, tilt = rng.uniform(-0.4, 0.5), rng.uniform(-0.5, 0.5)
        u = posture_axis(n, feed, lead, tilt)
        curved = t % 2 == 1
        cut = LocalCut(depth_mm=float(rng.uniform(0.02, 0.6)),
                       pick_mm=float(rng.uniform(0.05, 1.5)),
                       previous_side=int(t % 3) - 1, fz_mm=float(rng.uniform(0.02, 0.15)),
                       curvature_f_1_mm=float(rng.uniform(-0.05, 0.1)) if curved else 0.0,
                       curvature_b_1_mm=float(rng.uniform(-0.05, 0.1)) if curved else 0.0)
        yield tool, u, n, feed, cut


def _recorded_calls(monkeypatch) -> list:
    """The arguments of every call flute_engagement makes to the kernel, from now on."""
    calls = []
    kernel = SK.flute0_engagement

    def record(*args):
        calls.append(args)
        return kernel(*args)

    monkeypatch.setattr(SK, "flute0_engagement", record)
    return calls


@pytest.mark.parametrize("kind", ["ball", "radius", "flat"])
def test_kernel_equals_numpy_twin(kind, monkeypatch):
    """On the arguments flute_engagement hands the kernel (random postures and cuts, with
    and without the trailing edges): the same mask and chips, bit for bit."""
    calls = _recorded_calls(monkeypatch)
    cutting_seen = trailing_seen = removed_seen = 0
    for tool, u, n, feed, cut in _cases(11, kind, 12):
        edges = tool.micro_edges(60)
        for trailing in (False, True):
            fe = flute_engagement(tool, edges, u, n, feed, cut, 96, trailing=trailing)
            args = calls[-1]
            cutting, h, rows, cols = SK.flute0_engagement_numpy(*args[:-2])
            assert cutting.tobytes() == fe.cutting0.tobytes()
            assert h.tobytes() == fe.h0.tobytes()
            for a, b in ((rows, fe.rows), (cols, fe.cols)):
                assert a.dtype == b.dtype and a.tobytes() == b.tobytes()
            cutting_seen += int(fe.cutting0.sum())
            if cut.previous_side != 0:      # the previous pass took material away somewhere
                none = np.zeros((0, 3))
                alone = SK.flute0_engagement_numpy(*args[:12], none, none, *args[14:-2])[0]
                removed_seen += int((alone & ~cutting).sum())
            if trailing:
                trailing_seen += int((fe.cutting0 & (fe.h0 <= 0.0)).sum())
    assert cutting_seen > 0 and removed_seen > 0
    if kind == "ball":          # the ball's trailing sliver is there, so it was compared
        assert trailing_seen > 0


@pytest.mark.parametrize("kind", ["ball", "radius"])
def test_entries_are_the_expanded_nonzeros(kind):
    """entries() gives np.nonzero's order of the expanded mask and its phi and h."""
    for tool, u, n, feed, cut in _cases(5, kind, 6):
        edges = tool.micro_edges(40)
        fe = flute_engagement(tool, edges, u, n, feed, cut, 64, trailing=True)
        full = fe.expand(edges)
        i, k, j = np.nonzero(full.cutting)
        ei, ek, ej, phi, h = fe.entries()
        for a, b in ((i, ei), (k, ek), (j, ej), (full.phi[i, k, j], phi),
                     (full.h[i, k, j], h)):
            assert a.dtype == b.dtype and a.tobytes() == b.tobytes()


def test_engagement_is_the_expanded_flute():
    """engagement() is flute_engagement() expanded: flute k at step i is flute 0 a tooth
    of steps later, the angle grid the same as errpred's."""
    tool = TOOLS["ball"]
    edges = tool.micro_edges(50)
    (_, u, n, feed, cut), = _cases(3, "ball", 1)
    eng = engagement(tool, edges, u, n, feed, cut, 80, trailing=True)
    fe = flute_engagement(tool, edges, u, n, feed, cut, 80, trailing=True)
    shift = fe.theta.size // tool.flutes
    assert np.array_equal(eng.cutting[:, 1], np.roll(fe.cutting0, -shift, axis=0))
    assert np.array_equal(eng.h[:, 0], fe.h0)
    assert eng.theta[1] == pytest.approx(2 * math.pi / fe.theta.size)
    assert fe.cutting0.any()


@pytest.mark.parametrize("kind", ["ball", "radius", "flat"])
def test_edges_reaching_keeps_every_edge_below_the_top_and_drops_others(kind, monkeypatch):
    """The kernel tests the stock top only on the edges ``edges_reaching`` keeps: on a grid
    of 2,048 angles (twenty times the cases' own), every edge with a sample below the top
    (concave, flat and convex tops) is kept, and edges that stay above it are dropped."""
    calls = _recorded_calls(monkeypatch)
    kept = dropped = concave = 0
    phi = np.linspace(0.0, 2 * math.pi, 2048, endpoint=False)[:, None]
    for tool, u, n, feed, cut in _cases(23, kind, 16):
        edges = tool.micro_edges(60)
        flute_engagement(tool, edges, u, n, feed, cut, 96)
        args = calls[-1]
        rho, z, proj, depth, kf, kb = args[2], args[3], args[8], args[9], args[10], args[11]
        reach = SK.edges_reaching(proj, rho, z, depth, kf, kb)
        x, y = rho * np.sin(phi), rho * np.cos(phi)

        def along(r):
            return proj[r, 0] + x * proj[r, 1] + y * proj[r, 2] + z * proj[r, 3]

        below = (along(0) < depth - 0.5 * (kf * along(1) ** 2 + kb * along(2) ** 2)).any(0)
        assert np.all(reach[below])
        kept += int(below.sum())
        dropped += int((~reach).sum())
        concave += int(below.any() and min(kf, kb) < 0.0)
    assert kept > 0 and dropped > 0 and concave > 0
