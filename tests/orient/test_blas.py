"""orient.blas: BLAS threads limited in the stability and FEM hot paths, restored after."""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

import orient.fem.q2hex as q2hex
import orient.stability.sdm as sdm
from errpred.dynamics import Mode
from orient.blas import blas_limited, limited_blas
from orient.constants import BLAS_THREADS
from orient.dynamics import ModalSystem
from orient.stability import StraightEndMill2D, sdm_margin
from orient.workpiece_fem import Material, ThinWall, wall_modes

OUTSIDE = 2                            # a limit set by the caller, to be restored


def _blas_threads() -> set[int]:
    return {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}


@pytest.fixture
def outside():
    """The caller's BLAS at OUTSIDE threads (skip where the library cannot have them)."""
    with threadpool_limits(limits=OUTSIDE, user_api="blas"):
        if _blas_threads() != {OUTSIDE} or OUTSIDE == BLAS_THREADS:
            pytest.skip(f"BLAS cannot be set to {OUTSIDE} threads here")
        yield


def _system() -> ModalSystem:
    k, wn = 1340049.648, 2 * math.pi * 922.0
    m = k / wn ** 2
    return ModalSystem.from_modes([(Mode(k, m, 2 * 0.011 * math.sqrt(k * m)), (1.0, 0.0, 0.0))])


def test_time_periodic_margin_runs_with_limited_blas_and_restores(outside, monkeypatch):
    seen = []
    eigvals = sdm.scipy.linalg.eigvals

    def spy(*args, **kwargs):
        seen.append(_blas_threads())
        return eigvals(*args, **kwargs)

    monkeypatch.setattr(sdm.scipy.linalg, "eigvals", spy)
    h = StraightEndMill2D(6e8, 2e8, 2, 0.5, "down").directional_samples(40)
    res = sdm_margin(h, _system(), 15000.0, 2)
    assert math.isfinite(res.margin) and len(seen) > 5
    assert all(s == {BLAS_THREADS} for s in seen)
    assert _blas_threads() == {OUTSIDE}


def test_fem_solve_runs_with_limited_blas_and_restores(outside, monkeypatch):
    seen = []
    eigsh = q2hex.eigsh

    def spy(*args, **kwargs):
        seen.append(_blas_threads())
        return eigsh(*args, **kwargs)

    monkeypatch.setattr(q2hex, "eigsh", spy)
    wall = ThinWall(60.0, 40.0, 3.0, Material(70.0, 2700.0, 0.33))
    assert wall_modes(wall, n_modes=1, elements=(4, 1, 4)).frequencies_hz[0] > 0
    assert seen == [{BLAS_THREADS}]
    assert _blas_threads() == {OUTSIDE}


def test_nested_and_concurrent_uses_share_one_limit(outside):
    """Threads solving side by side under one limit (as orient.workpiece sets it); the
    limit is restored by the last to leave, also when an exception ends the block."""
    @blas_limited
    def inner(barrier, out):
        barrier.wait()
        out.append(_blas_threads())
        barrier.wait()

    barrier, out = threading.Barrier(2), []
    with limited_blas():
        threads = [threading.Thread(target=inner, args=(barrier, out)) for _ in range(2)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert _blas_threads() == {BLAS_THREADS}
    assert out == [{BLAS_THREADS}] * 2
    assert _blas_threads() == {OUTSIDE}
    with pytest.raises(RuntimeError), limited_blas():
        with limited_blas():
            assert _blas_threads() == {BLAS_THREADS}
        assert _blas_threads() == {BLAS_THREADS}
        raise RuntimeError("boom")
    assert _blas_threads() == {OUTSIDE}
    np.linalg.eigvals(np.eye(3))                     # BLAS still usable
