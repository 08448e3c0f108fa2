"""The packed per-revolution arrays (errpred.geometry_pack) come back bit for bit."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from errpred.geometry import PointGeometry
from errpred.geometry_pack import (SUB_SAMPLES, pack_engagement, pack_sparse,
                                   unpack_engagement, unpack_sparse)
from errpred.pipeline import blocks_in_scope, build_predictor, load
from errpred.scenario import bundled_scenario


def same(a, b) -> bool:
    """Bit for bit: type, dtype, shape and bytes of arrays; tuples and dataclasses
    field by field; anything else by ==."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return (type(a) is type(b) and a.dtype == b.dtype and a.shape == b.shape
                and a.tobytes() == b.tobytes())
    if isinstance(a, tuple):
        return (isinstance(b, tuple) and len(a) == len(b)
                and all(same(x, y) for x, y in zip(a, b, strict=True)))
    if dataclasses.is_dataclass(a):
        return type(a) is type(b) and all(same(getattr(a, f.name), getattr(b, f.name))
                                          for f in dataclasses.fields(a))
    return type(a) is type(b) and a == b


def boundary(n=40, m=12, seed=0):
    """An engagement as the engager returns one: a band of rows cutting, weights
    1 inside and counts/32 on the band's edges, offsets only there."""
    rng = np.random.default_rng(seed)
    w = np.zeros((n, m), np.float32)
    s = np.zeros((n, m), np.float32)
    w[10:20, 2:9] = 1.0
    for i, j in [(10, c) for c in range(2, 9)] + [(r, 8) for r in range(10, 20)]:
        k = int(rng.integers(1, SUB_SAMPLES))
        w[i, j] = k / SUB_SAMPLES
        s[i, j] = np.float32(rng.uniform(-0.01, 0.01))
    w[21, 3] = 3 / SUB_SAMPLES      # a lone partial cell, its offset 0 (centred)
    return w > 0, w, s


def _variant(f):
    c, w, s = boundary()
    return f(c.copy(), w.copy(), s.copy())


def _set(a, idx, v):
    a[idx] = v
    return a


Z = np.zeros((30, 7), np.float32)
CASES = {
    "boundary": boundary(),
    "all zero": (Z > 0, Z.copy(), Z.copy()),
    "dense": (np.ones((9, 5), bool), np.ones((9, 5), np.float32),
              np.linspace(0.1, 0.9, 45, dtype=np.float32).reshape(9, 5)),
    "not multiples of 1/32": _variant(lambda c, w, s: (c, _set(w, (12, 3), 0.3), s)),
    "weight above 1": _variant(lambda c, w, s: (_set(c, (0, 0), True), _set(w, (0, 0), 2.0), s)),
    "negative zero weight": _variant(lambda c, w, s: (c, _set(w, (0, 0), -0.0), s)),
    "NaN weight": _variant(lambda c, w, s: (_set(c, (0, 1), True), _set(w, (0, 1), np.nan), s)),
    "cutting != weight > 0": _variant(lambda c, w, s: (_set(c, (12, 4), False), w, s)),
    "cutting bytes not 0/1": _variant(
        lambda c, w, s: ((c.view(np.uint8) * np.uint8(2)).view(bool), w, s)),
    "shift off the weights": _variant(lambda c, w, s: (c, w, _set(s, (35, 0), 0.5))),
    "negative zero shift": _variant(lambda c, w, s: (c, w, _set(s, (35, 0), -0.0))),
    "NaN shift on a weight": _variant(lambda c, w, s: (c, w, _set(s, (15, 4), np.nan))),
    "float64 weight": _variant(lambda c, w, s: (c, w.astype(np.float64), s)),
    "big-endian weight": _variant(lambda c, w, s: (c, w.astype(">f4"), s)),
    "big-endian shift": _variant(lambda c, w, s: (c, w, s.astype(">f4"))),
    "shift shape differs": _variant(lambda c, w, s: (c, w, s[:, :5].copy())),
    "Fortran order": _variant(lambda c, w, s: (np.asfortranarray(c), np.asfortranarray(w),
                                               np.asfortranarray(s))),
    "transposed views": _variant(lambda c, w, s: (c.T, w.T, s.T)),
    "all None": (None, None, None),
    "cutting None": _variant(lambda c, w, s: (None, w, s)),
    "weight None": _variant(lambda c, w, s: (c, None, s)),
    "1-d": (np.array([0, 1, 1, 0], bool), np.array([0, 0.5, 1, 0], np.float32),
            np.array([0, 0.1, 0, 0], np.float32)),
    "empty": (np.zeros((0, 4), bool), np.zeros((0, 4), np.float32), np.zeros((0, 4), np.float32)),
    "0-d": (np.array(True), np.array(0.25, np.float32), np.array(0.0, np.float32)),
}


@pytest.mark.parametrize("name", list(CASES))
def test_engagement_round_trip_is_exact(name):
    arrays = CASES[name]
    packed = pickle.loads(pickle.dumps(pack_engagement(*arrays), protocol=5))
    back = unpack_engagement(packed)
    for a, b in zip(arrays, back, strict=True):
        if a is None:
            assert b is None
        else:   # bytes in C order: layout (Fortran, views) is not kept, values are
            assert (b.dtype == a.dtype and b.shape == a.shape
                    and np.ascontiguousarray(a).tobytes() == b.tobytes()), name


def test_engagement_as_the_engager_returns_it_is_counts_and_far_smaller():
    c, w, s = boundary(n=360, m=182)
    cp, wp, sp = pack_engagement(c, w, s)
    assert cp == "weight>0" and wp[0] == "counts" and sp[0] == "on-weight"
    raw = len(pickle.dumps((c, w, s), protocol=5))
    assert len(pickle.dumps((cp, wp, sp), protocol=5)) < raw / 50


@pytest.mark.parametrize("name", ["not multiples of 1/32", "negative zero weight",
                                  "NaN weight", "weight above 1"])
def test_weights_that_are_not_counts_take_the_exact_fallback(name):
    cp, wp, sp = pack_engagement(*CASES[name])
    assert wp[0] == "sparse"


def test_shift_off_the_weights_and_unequal_cutting_take_the_fallback():
    assert pack_engagement(*CASES["shift off the weights"])[2][0] == "sparse"
    assert pack_engagement(*CASES["cutting != weight > 0"])[0][0] == "sparse"
    assert pack_engagement(*CASES["cutting bytes not 0/1"])[0][0] == "sparse"


SPARSE = {
    "None": None,
    "1-d float64": np.array([0.0, 0.0, 3.5, 0.0, -0.0, 0.0, 0.0, 0.0, 0.0, 1e-300]),
    "int16 2-d": np.array([[0, 0, 0, 7], [0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0]], np.int16),
    "complex": np.array([0, 0, 0, 0, 0, 0, 1j, 0, 0, 0]),
    "structured": np.zeros(20, dtype=[("a", "<i4"), ("b", "<f8")]),
    "dense stays": np.arange(1, 50, dtype=np.float32),
    "objects stay": np.array([None, 1, "x"], dtype=object),
    "a tuple stays": (1, 2),
}


@pytest.mark.parametrize("name", list(SPARSE))
def test_sparse_round_trip_is_exact(name):
    a = SPARSE[name]
    p = pickle.loads(pickle.dumps(pack_sparse(a), protocol=5))
    b = unpack_sparse(p)
    if isinstance(a, np.ndarray) and a.dtype.hasobject:
        assert b.dtype == a.dtype and list(b) == list(a)
    else:
        assert same(a, b), name


def test_sparse_packs_only_when_smaller():
    assert pack_sparse(SPARSE["1-d float64"])[0] == "sparse"
    assert pack_sparse(SPARSE["dense stays"]) is SPARSE["dense stays"]


@st.composite
def sparse_engagements(draw):
    n, m = draw(st.integers(0, 24)), draw(st.integers(1, 24))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    nz = rng.random((n, m)) < draw(st.sampled_from([0.0, 0.02, 0.2, 0.9]))
    kind = draw(st.sampled_from(["counts", "floats", "specials"]))
    w = np.zeros((n, m), np.float32)
    if kind == "counts":
        w[nz] = rng.integers(1, SUB_SAMPLES + 1, nz.sum()) / SUB_SAMPLES
    else:
        w[nz] = rng.normal(size=nz.sum()).astype(np.float32)
    if kind == "specials" and w.size:
        flat = w.reshape(-1)
        pick = rng.integers(0, w.size, 3)
        flat[pick] = np.array([-0.0, np.nan, np.inf], np.float32)
    s = np.zeros((n, m), np.float32)
    on = nz & (rng.random((n, m)) < 0.5)
    if draw(st.booleans()):
        on |= rng.random((n, m)) < 0.05      # some offsets off the weights' cells
    s[on] = rng.normal(size=on.sum()).astype(np.float32)
    c = w > 0
    if draw(st.booleans()) and c.size:
        c.reshape(-1)[rng.integers(0, c.size)] ^= True
    return c, w, s


@settings(max_examples=150, deadline=None)
@given(sparse_engagements())
def test_random_sparse_engagements_round_trip_exactly(arrays):
    back = unpack_engagement(pickle.loads(pickle.dumps(pack_engagement(*arrays))))
    for a, b in zip(arrays, back, strict=True):
        assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    for a in arrays:
        b = unpack_sparse(pack_sparse(a))
        assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


@pytest.fixture(scope="module")
def wall_points() -> list[PointGeometry]:
    scn = dataclasses.replace(load(bundled_scenario("wall-radius")), lines=(38, 53))
    pred = build_predictor(scn)
    return [g for b in blocks_in_scope(scn, pred.program) for g in pred.model.geometry(b)]


def test_real_points_pickle_back_field_by_field(wall_points):
    """A bundled scenario's points (sensitivity pass on) come back equal in every field
    (arrays bit for bit), and their engagements take the compact path."""
    predicted = [g for g in wall_points if g.status == "predicted"]
    assert len(predicted) >= 5 and all(g.sensitivity is not None for g in predicted)
    for g in wall_points:
        back = pickle.loads(pickle.dumps(g, protocol=5))
        assert same(g, back), g.block
    for g in predicted:
        state = g.__getstate__()
        assert state["engagement"][0] == "weight>0" and state["engagement"][1][0] == "counts"
        assert state["sensitivity_packed"][1][1][0] == "counts"
        raw = sum(a.nbytes for a in (g.cutting0, g.weight0, g.shift0, *g.sensitivity[1:]))
        assert len(pickle.dumps(g)) < raw / 10


def test_a_point_that_came_packed_goes_on_packed_as_it_came(wall_points):
    """A point read back from a pickle (a worker's result) pickles again to the same
    bytes without packing again (the results' store), equal field by field after a
    second trip; its arrays are read only (so the packing it keeps still holds), and a
    point made from it by replacing a field packs afresh."""
    import errpred.geometry as geometry

    for g in wall_points:
        once = pickle.dumps(g, protocol=5)
        back = pickle.loads(once)
        calls = []
        real = geometry.pack_engagement
        geometry.pack_engagement = lambda *a: calls.append(1) or real(*a)
        try:
            twice = pickle.dumps(back, protocol=5)
        finally:
            geometry.pack_engagement = real
        assert not calls and twice == once, g.block
        assert same(g, pickle.loads(twice)), g.block
        for a in (back.cutting0, back.weight0, back.shift0, back.cl_per_rev):
            if isinstance(a, np.ndarray):
                assert not a.flags.writeable
        if back.cutting0 is not None:
            with pytest.raises(ValueError):
                back.cutting0[...] = False
            fresh = dataclasses.replace(back, cutting0=~back.cutting0)
            assert not same(g, pickle.loads(pickle.dumps(fresh, protocol=5)))
