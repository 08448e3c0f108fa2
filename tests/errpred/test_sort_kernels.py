"""errpred._sort_kernels against their numpy twins (np.argsort stable, a[order], a[mask])."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from errpred._sort_kernels import argsort_stable, compress, grown, take


@pytest.mark.parametrize("n", [0, 1, 2, 15, 16, 17, 31, 33, 100, 1000, 4099])
@pytest.mark.parametrize("kind", ["ties", "float", "sorted", "reversed"])
def test_argsort_stable_is_numpys_stable_argsort(n, kind):
    rng = np.random.default_rng(n)
    keys = {"ties": rng.integers(0, max(n // 8, 1), n),
            "float": rng.normal(size=n),
            "sorted": np.arange(n, dtype=np.int64),
            "reversed": np.arange(n, 0, -1).astype(float)}[kind]
    got = argsort_stable(keys)
    assert got.dtype == np.int64
    np.testing.assert_array_equal(got, np.argsort(keys, kind="stable"))


@settings(max_examples=200, deadline=None)
@given(arrays(np.int64, st.integers(0, 300), elements=st.integers(-5, 5)))
def test_argsort_stable_property(keys):
    """Equal keys keep their order (many ties), the result is a permutation."""
    np.testing.assert_array_equal(argsort_stable(keys), np.argsort(keys, kind="stable"))


def test_take_and_compress_are_numpys_indexing():
    rng = np.random.default_rng(3)
    values = rng.integers(-100, 100, 57)
    order = rng.permutation(57)[:40]
    mask = rng.random(57) < 0.4
    np.testing.assert_array_equal(take(values, order), values[order])
    np.testing.assert_array_equal(compress(values, mask), values[mask])
    assert compress(values, np.zeros(57, dtype=np.bool_)).shape == (0,)
    assert take(values, np.zeros(0, dtype=np.int64)).shape == (0,)


def test_grown_keeps_the_used_part():
    buf = np.arange(10, dtype=np.int64) * 3
    out = grown(buf, 7, 25)
    assert out.shape == (25,) and out.dtype == np.int64
    np.testing.assert_array_equal(out[:7], buf[:7])
    assert grown(buf, 0, 4).shape == (4,)
