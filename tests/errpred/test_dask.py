"""Stage 1 of the error prediction on a Dask cluster: a LocalCluster of two worker
processes on loopback gives the same prediction as one process, bit for bit."""

from __future__ import annotations

import dataclasses
import json
import time

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from errpred.cli import main
from errpred.pipeline import blocks_in_scope, build_predictor, load

SCENARIO = "errpred/scenarios/mold-ball/scenario.toml"
LINES = (6131, 6250)       # about 120 blocks of the contour slice


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as c, \
            distributed.Client(c) as client:
        yield client


def _fields(pred):
    return [(p.geometry.block, p.status, p.E_um, p.line) for p in pred.points]


def test_local_cluster_prediction_equals_one_process(cluster):
    scn = dataclasses.replace(load(SCENARIO), lines=LINES)
    pred = build_predictor(scn)
    blocks = blocks_in_scope(scn, pred.program)
    assert len(blocks) > 60
    one = pred.run(blocks)
    dist = build_predictor(scn).run(blocks, client=cluster)
    assert len(cluster.scheduler_info()["workers"]) == 2
    a, b = _fields(one), _fields(dist)
    assert a == b                                         # exact, floats included
    np.testing.assert_array_equal(one.wear_mm, dist.wear_mm)
    assert sum(1 for p in one.points if p.status == "predicted") > 30


def test_cli_scheduler_option_gives_the_same_report(cluster, tmp_path):
    r1, r2 = tmp_path / "one.json", tmp_path / "dask.json"
    base = ["predict", SCENARIO, "--lines", str(LINES[0]), str(LINES[1]), "-q", "--no-design"]
    assert main(base + ["-o", str(r1)]) == 0
    assert main(base + ["-o", str(r2), "--scheduler", cluster.scheduler.address]) == 0
    one, dist = json.loads(r1.read_text()), json.loads(r2.read_text())
    one.pop("timing", None)
    dist.pop("timing", None)
    assert one["points"] == dist["points"]
    assert one["summary"] == dist["summary"]


def _faults_per_alloc(n: int = 200, nbytes: int = 1 << 20) -> float:
    """Minor page faults per allocation, fill and release of an ``nbytes`` array."""
    import resource

    import numpy as np

    np.ones(nbytes // 8).sum()
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(n):
        np.ones(nbytes // 8).sum()
    return (resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before) / n


def test_the_local_cluster_workers_keep_freed_memory_for_reuse():
    """Dask starts its workers with a 64 kB malloc trim threshold, under which every array
    above 128 kB is mapped and unmapped again: a 1 MB array faults in its 256 pages each
    time (the reference: a fresh interpreter with that setting). The command lines'
    local cluster sets the workers' malloc to keep freed memory
    (errpred.cluster.keep_freed_memory): the same array is reused without faults."""
    import inspect
    import os
    import subprocess
    import sys

    from errpred.cluster import dask_client

    env = {**os.environ, "MALLOC_TRIM_THRESHOLD_": "65536"}
    env.pop("MALLOC_MMAP_THRESHOLD_", None)
    code = inspect.getsource(_faults_per_alloc) + "\nprint(_faults_per_alloc())\n"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True)
    assert float(out.stdout) > 200
    with dask_client(workers=1) as client:
        faults = list(client.run(_faults_per_alloc).values())
    assert faults[0] < 5


def _compile_a_kernel() -> int:
    """Compile a new numba function in this process (no cache: always a compilation)."""
    import numba

    @numba.njit(cache=False)
    def plus_one(x):
        return x + 1

    return plus_one(1)


def _pid() -> int:
    import os

    return os.getpid()


def test_workers_that_compiled_are_started_again_and_only_those():
    """errpred.cluster.restart_compiled_workers: numba's compiler keeps the memory it
    took, so a worker of the local cluster that compiled a kernel is started again
    (another process, its setup applied again: its malloc keeps freed memory), one that
    did not is left, one holding data is left, and a client by address (a cluster this
    process did not start) restarts nothing."""
    from errpred._dask_worker import compiles
    from errpred.cluster import dask_client, restart_compiled_workers

    with dask_client(workers=2) as client:
        pids = client.run(_pid)
        a, b = sorted(pids)
        assert set(client.run(compiles).values()) == {0}
        assert restart_compiled_workers(client) == []        # nothing compiled
        assert client.submit(_compile_a_kernel, pure=False, workers=[a]).result() == 2
        assert client.run(compiles)[a] > 0 and client.run(compiles)[b] == 0
        with distributed.Client(client.scheduler.address) as by_address:
            assert restart_compiled_workers(by_address) == []
        held = client.scatter(np.arange(3), workers=[a])
        assert restart_compiled_workers(client) == []        # a holds data
        del held
        for _ in range(100):                                 # the release reaches it
            if not client.has_what()[a]:
                break
            time.sleep(0.05)
        assert restart_compiled_workers(client) == [a]
        client.wait_for_workers(2)
        after = client.run(_pid)
        assert len(after) == 2 and a not in after and after[b] == pids[b]
        (new,) = set(after) - {b}
        assert after[new] not in pids.values()
        assert client.run(compiles) == {new: 0, b: 0}
        assert client.run(_faults_per_alloc)[new] < 5
        assert restart_compiled_workers(client) == []


class _FakeFuture:
    def __init__(self, client, value):
        self.client, self.value, self.released = client, value, False

    def result(self):
        return self.value

    def release(self):
        self.released = True
        self.client.alive -= 1


class _FakeClient:
    """Runs tasks at submission; counts the futures not yet released."""

    def __init__(self, workers):
        self.workers, self.alive, self.peak, self.cancelled = workers, 0, 0, []

    def scheduler_info(self):
        return {"workers": {f"w{i}": {} for i in range(self.workers)}}

    def scatter(self, obj, broadcast=False):
        return obj

    def submit(self, fn, *args, pure=True):
        self.alive += 1
        self.peak = max(self.peak, self.alive)
        return _FakeFuture(self, fn(*args))

    def cancel(self, futures):
        self.cancelled.extend(futures)


class _Model:
    def geometry(self, block):
        return [("point", block)]


def test_cluster_chunks_in_flight_are_bounded_and_released():
    from errpred import constants as K
    from errpred.predict import _on_cluster

    client = _FakeClient(workers=2)
    blocks = list(range(1000))
    out = list(_on_cluster(client, _Model(), blocks, chunk=7))
    assert [g[0][1] for g in out] == blocks               # every block, in order
    assert client.peak == K.DASK_CHUNKS_IN_FLIGHT * 2     # bounded, and the bound is used
    assert client.alive == 0                               # every future released


def test_cluster_stopped_early_cancels_what_is_in_flight():
    from errpred.predict import _on_cluster

    client = _FakeClient(workers=1)
    gen = _on_cluster(client, _Model(), list(range(100)), chunk=5)
    next(gen)
    gen.close()
    assert client.cancelled and client.alive == len(client.cancelled)


def test_guided_chunks_cover_the_blocks_in_order_and_shrink_to_the_end():
    """Stage 1's tasks (worker pool and Dask): consecutive runs of the blocks given, in
    order, none over the largest, shrinking toward the end to the smallest (so no worker
    waits a whole chunk for the other at the end)."""
    from errpred import constants as K
    from errpred.predict import _chunks

    blocks = list(range(3, 303))
    chunks = _chunks(blocks, 2, 64)
    assert [b for c in chunks for b in c] == blocks
    sizes = [len(c) for c in chunks]
    assert sizes == sorted(sizes, reverse=True)                 # never growing
    assert sizes[0] == -(-300 // (K.WORKER_CHUNK_SHARE * 2))    # guided: left / (share x workers)
    assert sizes[-1] <= K.WORKER_CHUNK_MIN_BLOCKS
    assert max(sizes) <= 64 and max(len(c) for c in _chunks(list(range(5000)), 2, 64)) == 64
    assert _chunks([], 2) == [] and _chunks([7], 2) == [[7]]


def test_pool_results_in_order_bounded_and_the_collector_unfrozen():
    """The worker pool yields every block's points in order, with at most
    ``POOL_CHUNKS_IN_FLIGHT`` chunks a worker submitted ahead, and leaves Python's garbage
    collector as it found it (frozen only over the fork)."""
    import gc

    from errpred import constants as K
    from errpred import predict as P

    submitted, taken = [], []

    class _Taken:                       # a pool future that notes when it is taken
        def __init__(self, chunk, future):
            self.chunk, self.future = chunk, future

        def result(self):
            taken.append(self.chunk[0])
            return self.future.result()

        def cancel(self):
            return self.future.cancel()

    real = P._in_order

    def spy(submit, chunks, limit, **kw):
        def counted(c):
            assert len(submitted) - len(taken) < limit
            submitted.append(c[0])
            return _Taken(c, submit(c))
        assert limit == K.POOL_CHUNKS_IN_FLIGHT * 2
        return real(counted, chunks, limit, **kw)

    P._in_order = spy
    try:
        out = list(P._on_pool(_Model(), list(range(200)), 2, 64))
    finally:
        P._in_order = real
    assert [g[0][1] for g in out] == list(range(200))
    assert len(submitted) == len(taken) > 2
    assert gc.get_freeze_count() == 0


def _where(i, data, seconds):
    """A call of :func:`errpred.cluster.balanced`'s test: its index, the worker it ran on,
    when it ran."""
    from distributed import get_worker

    t0 = time.time()
    time.sleep(seconds)
    return i, get_worker().address, t0, time.time(), float(np.sum(data))


def _fails(i):
    raise ValueError(f"call {i} fails")


def _touch(path):
    """A call that leaves a trace: the file ``path``."""
    with open(path, "w") as fh:
        fh.write("ran")


def test_balanced_calls_run_where_a_thread_is_free_not_where_their_data_is(cluster):
    """``balanced`` gives the results in the order of the calls, starts them in that
    order, one a worker thread at a time, each on the worker that frees up next,
    although every call needs data held by one worker only. Dask alone places such
    calls by their data and each worker runs its own queue: the main job's verification
    ran every stretch of a program on the worker that made its part, and here Dask alone
    starts call 2 (moved to the idle worker) a whole call before call 1."""
    from errpred.cluster import balanced

    a, b = list(cluster.scheduler_info()["workers"])
    data = cluster.submit(np.ones, 1000, workers=[a], pure=False)
    data.result()
    assert cluster.who_has(data)[data.key] == (a,)
    seconds = [1.2, 0.9, 0.6, 0.3, 0.3, 0.3]                      # longest first
    out = list(balanced(cluster, [(_where, (i, data, s), {}) for i, s in enumerate(seconds)]))
    assert [o[0] for o in out] == list(range(len(seconds)))       # in the calls' order
    assert all(o[4] == 1000.0 for o in out)                       # each got the data
    ran = {w: sorted((o[2], o[3]) for o in out if o[1] == w) for w in (a, b)}
    assert ran[a] and ran[b]                                      # both workers used
    for spans in ran.values():                                    # one at a time on each
        assert all(s[1] <= t[0] + 1e-3 for s, t in zip(spans, spans[1:]))
    starts = [o[2] for o in out]
    # started in order: a later call never started before an earlier one (but for the
    # hand-over's latency, far below the calls' lengths)
    assert all(starts[k] >= max(starts[:k]) - 0.15 for k in range(2, len(starts)))
    assert list(balanced(cluster, [])) == []


def test_balanced_call_that_fails_raises_where_its_result_is_taken(cluster, tmp_path):
    """Call 1 fails while call 0 still runs: call 0's result comes first, then the error;
    nothing starts after the failure (call 2, which leaves a file, never runs)."""
    from errpred.cluster import balanced

    trace = tmp_path / "call-2-ran"
    res = balanced(cluster, [(_where, (0, np.ones(3), 1.0), {}), (_fails, (1,), {}),
                             (_touch, (str(trace),), {})])
    assert next(res)[0] == 0
    with pytest.raises(ValueError, match="call 1 fails"):
        next(res)
    with pytest.raises(StopIteration):
        next(res)
    time.sleep(0.5)             # a call started after the failure would have run by now
    assert not trace.exists()


def test_balanced_many_short_calls_all_come_back_in_order(cluster):
    """Many short calls, each result taken and released as soon as it is in, all come
    back, in order. (A result released before its call's callback runs reads as
    cancelled there, and must not stop the starts; this run does not force that race,
    which the callback's test of ``"error"`` alone covers.)"""
    from errpred.cluster import balanced

    calls = [(_where, (i, np.ones(2), 0.0), {}) for i in range(40)]
    assert [o[0] for o in balanced(cluster, calls)] == list(range(40))
