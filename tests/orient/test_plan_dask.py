"""Planning on a Dask cluster: a two-worker LocalCluster on loopback plans the bundled
thin wall exactly as one process does."""

from __future__ import annotations

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from orient.plan import plan  # noqa: E402
from orient.scenario import load_plan_scenario  # noqa: E402

from tests.thin_wall import thin_wall_copy, wall_mode  # noqa: E402


def test_local_cluster_plan_equals_one_process(planned):
    scn, one = planned
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        dist = plan(scn, client=client)
        assert len(client.scheduler_info()["workers"]) == 2
    np.testing.assert_array_equal(one.cl.axis, dist.cl.axis)
    np.testing.assert_array_equal(one.cl.tip, dist.cl.tip)
    np.testing.assert_array_equal(one.margin, dist.margin)
    np.testing.assert_array_equal(one.cam_margin, dist.cam_margin)
    np.testing.assert_array_equal(one.grid_margin, dist.grid_margin)
    assert one.reason == dist.reason
    assert [c["sdm_margin"] for c in one.sdm_checks] == [c["sdm_margin"] for c in dist.sdm_checks]


_STARTED = __import__("threading").Event()
_RELEASE = __import__("threading").Event()


def _busy() -> bool:
    _STARTED.set()
    return _RELEASE.wait(30)


def _square_slowly(x: int) -> tuple[int, str]:
    """x squared, and where: here (this process's main thread) or on a worker."""
    import threading
    import time

    if x == 0:
        time.sleep(1.0)         # meanwhile an idle worker solves the others
    if x == 3:
        time.sleep(3.0)         # a worker is still on it when this process is done
    here = threading.current_thread() is threading.main_thread()
    return x * x, "here" if here else "worker"


@pytest.fixture
def one_worker():
    """A client of a one-worker, one-thread cluster in this process."""
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        yield client


def test_wall_levels_are_taken_from_idle_workers_and_withdrawn_from_busy_ones(one_worker):
    # the thin wall's levels but the first are offered to the workers: one a worker has
    # finished when this process gets to it is taken; one still waiting for a busy
    # worker is withdrawn and solved here (the answers are the same either way)
    from orient.workpiece import _solve_shared

    got = _solve_shared(one_worker, _square_slowly, [0, 1, 2])
    assert got == [(0, "here"), (1, "worker"), (4, "worker")]

    _STARTED.clear()
    _RELEASE.clear()
    busy = one_worker.submit(_busy, pure=False)
    assert _STARTED.wait(30)            # the worker is busy from here on
    try:
        got = _solve_shared(one_worker, _square_slowly, [0, 1, 2])
    finally:
        _RELEASE.set()
    assert busy.result()
    assert got == [(0, "here"), (1, "here"), (4, "here")]


def test_a_wall_level_a_worker_is_solving_is_waited_for_not_solved_again(one_worker):
    # level 1 takes a worker 3 s, this process's own 1 s: this process waits for it
    # instead of solving it a second time, and solves the level queued behind it
    from orient.workpiece import _solve_shared

    got = _solve_shared(one_worker, _square_slowly, [0, 3, 2])
    assert got == [(0, "here"), (9, "worker"), (4, "here")]


@pytest.fixture(scope="module")
def light_planned(tmp_path_factory):
    """The thin wall's first three passes with one wall mode instead of the finite
    elements, and its plan in one process (about 5 s instead of the whole wall's 35 s:
    117 cutter locations, still past the margin kernel's threshold of postures)."""
    scn = load_plan_scenario(thin_wall_copy(tmp_path_factory.mktemp("light") / "scn", None,
                                            wall_mode(2.0e7), cam_lines=124))
    return scn, plan(scn)


def test_dask_tasks_use_the_one_thread_margin_kernel(light_planned, one_worker, monkeypatch):
    """On a cluster the workers are the parallelism: no task calls the threaded margin
    kernel (the speed choice's rows passed its size threshold and used it, and the job's
    warm-up compiled it, 2 s more, for them alone). The plan is the one-process plan."""
    import orient.stability._kernels as kernels
    from orient.constants import ZOA_PARALLEL_MIN_POSTURES

    scn, one = light_planned
    serial = kernels.margin_batch_serial
    calls = {"serial": 0, "largest": 0}

    def threaded(*args):
        raise AssertionError("the threaded margin kernel was called in a Dask task")

    def counted(*args):
        calls["serial"] += 1
        calls["largest"] = max(calls["largest"], len(args[0]))
        return serial(*args)

    monkeypatch.setattr(kernels, "margin_batch", threaded)
    monkeypatch.setattr(kernels, "margin_batch_serial", counted)
    dist = plan(scn, client=one_worker)
    assert calls["serial"] > 0
    # a call the size threshold alone would have given to the threaded kernel
    assert calls["largest"] >= ZOA_PARALLEL_MIN_POSTURES
    np.testing.assert_array_equal(one.cl.axis, dist.cl.axis)
    np.testing.assert_array_equal(one.margin, dist.margin)
