"""A Dask client for the command lines: an existing scheduler or a local cluster."""

from __future__ import annotations

import contextlib
import logging
import threading
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from nc.errors import InputError

_log = logging.getLogger(__name__)

__all__ = ["balanced", "dask_client", "keep_freed_memory", "restart_compiled_workers"]


@contextlib.contextmanager
def dask_client(scheduler: str | None = None, workers: int = 0) -> Iterator[Any]:
    """``dask.distributed.Client`` of ``scheduler`` (an address such as
    ``tcp://10.0.0.5:8786``), or of a local cluster of ``workers`` single-threaded
    worker processes bound to 127.0.0.1 (whose malloc keeps freed memory:
    :func:`keep_freed_memory`, and which count the kernels numba compiles in them:
    :func:`restart_compiled_workers`); None (no cluster) when neither is given.

    Parameters
    ----------
    scheduler : str, optional
        Address of an existing Dask scheduler.
    workers : int
        Worker processes of a local cluster (0: none).
    """
    if not scheduler and not workers:
        yield None
        return
    from distributed import Client, LocalCluster

    if scheduler:
        with Client(scheduler, timeout="20s") as client:
            yield client
        return
    if workers < 1:
        raise InputError(f"--dask: expected >= 1 workers, got {workers}")
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                      host="127.0.0.1", dashboard_address=None) as cluster, \
            Client(cluster) as client:
        from ._dask_worker import WorkerSetup

        client.register_plugin(WorkerSetup(keep_freed_memory))       # restarted workers too
        yield client


def keep_freed_memory() -> bool:
    """Let glibc's malloc in this process keep freed memory for reuse
    (``constants.WORKER_MALLOC_TRIM_BYTES``, ``WORKER_MALLOC_MMAP_BYTES``); False where
    there is no glibc ``mallopt`` (nothing changed)."""
    import ctypes
    import ctypes.util

    from .constants import WORKER_MALLOC_MMAP_BYTES, WORKER_MALLOC_TRIM_BYTES

    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name) if name else None
    except OSError:
        libc = None
    if libc is None or not hasattr(libc, "mallopt"):
        return False
    m_trim_threshold, m_mmap_threshold = -1, -3            # glibc's malloc.h
    return (libc.mallopt(m_trim_threshold, WORKER_MALLOC_TRIM_BYTES) == 1
            and libc.mallopt(m_mmap_threshold, WORKER_MALLOC_MMAP_BYTES) == 1)


def restart_compiled_workers(client) -> list[str]:
    """Start again the workers of this process's local cluster (:func:`dask_client`) in
    which numba compiled a kernel, where they are idle and hold no data; returns the
    addresses of those restarted. Numba's compiler keeps the memory it took (150-290 MB
    for the main job's kernels: its compiled code is in numba's cache on disk, which
    the new worker loads): without it a worker that compiled a stage's kernels (the
    planner's gains when the job's warm-up child had not yet cached them) peaked at
    1.15 GB verifying. Nothing is restarted on a cluster this process did not start (an
    address: ``client.cluster`` is None), on a worker without a nanny, nor where no
    worker compiled (kernels cached). Call it with no task submitted and no result held
    that a worker still runs or keeps (the scheduler may not have seen a task just
    submitted). A worker that does not come back within ``WORKER_RESTART_TIMEOUT_S`` is
    logged, and the work goes on without it.
    """
    if client is None or getattr(client, "cluster", None) is None:
        return []
    from ._dask_worker import compiles
    from .constants import WORKER_RESTART_TIMEOUT_S

    counts = client.run(compiles, on_error="return")
    busy = client.processing()
    held = client.has_what()
    nannies = {a: w.get("nanny") for a, w in client.scheduler_info()["workers"].items()}
    todo = [addr for addr, n in counts.items()
            if isinstance(n, int) and n > 0 and nannies.get(addr)
            and not busy.get(addr) and not held.get(addr)]
    if not todo:
        return []
    quiet = _PlannedRestarts()
    nanny_log = logging.getLogger("distributed.nanny")
    nanny_log.addFilter(quiet)
    try:
        status = client.restart_workers(todo, timeout=WORKER_RESTART_TIMEOUT_S,
                                        raise_for_error=False)
    finally:
        nanny_log.removeFilter(quiet)
    for addr, what in status.items():
        if what != "OK":
            _log.warning("worker %s, started again after numba compiled there: %s",
                         addr, what)
    return [addr for addr in todo if status.get(addr) == "OK"]


def balanced(client, calls: Sequence[tuple[Callable, tuple, dict]]) -> Iterator[Any]:
    """The results of ``calls`` (function, positional and keyword arguments) run on the
    cluster's workers, in the order given; the calls start in that order, one a worker
    thread at a time, each on the worker that frees up next (started from the finished
    call's callback, whether or not the caller is waiting for a result). The first ones
    start here, before the first result is asked for.

    Dask places a task where its arguments' data lies: the stretches of one program,
    which share its part (a future), all went to the worker that made it, so the main
    job's verification ran the corrected program's on one worker and the planned
    program's on the other, 18 s apart at the end on the bundled thin wall. Here a call
    goes to a worker with a free thread (its data moved there if needed), so with the
    longest calls first the workers end close together. The worker is a preference
    (``allow_other_workers``): a call whose worker has left runs on another. The workers
    are those listed when this is called (none listed: every call submitted at once,
    placed by Dask). A call that fails raises where its result is taken (the results
    before it are given first); no call starts after a failure, and the calls still
    running are cancelled when the results are left.

    Parameters
    ----------
    client : distributed.Client
    calls : sequence of (callable, tuple, dict)
        In the order they should start (longest first for the shortest end).
    """
    todo = list(calls)
    n = len(todo)
    info = client.scheduler_info().get("workers", {})
    free = [addr for addr, w in info.items() for _ in range(max(int(w.get("nthreads", 1)), 1))]
    if not free:
        free = [None] * n         # no worker listed: let the scheduler place them all
    futures: list[Any] = [None] * n
    cond = threading.Condition()
    state: dict[str, Any] = {"next": 0, "failed": False, "error": None}

    def start(addr) -> None:
        """The next call, on ``addr`` (``cond`` held)."""
        i = state["next"]
        state["next"] += 1
        fn, args, kwargs = todo[i]
        where = {} if addr is None else {"workers": [addr], "allow_other_workers": True}
        f = client.submit(fn, *args, pure=False, **where, **kwargs)
        futures[i] = f
        cond.notify_all()
        f.add_done_callback(lambda done: freed(addr, done))

    def freed(addr, done) -> None:
        with cond:
            # an error stops the starts; "cancelled" is also a call whose result was taken
            # and released before this callback ran (Dask cancels a released key's state)
            if done.status == "error":
                state["failed"] = True
            if not state["failed"] and state["next"] < n:
                try:
                    start(addr)
                except Exception as exc:           # noqa: BLE001 -- raised to the caller
                    state["failed"], state["error"] = True, exc
                    cond.notify_all()

    with cond:
        while free and state["next"] < n:
            start(free.pop(0))

    def results() -> Iterator[Any]:
        try:
            for i in range(n):
                with cond:
                    while futures[i] is None:      # started once a call before it ends
                        if state["error"] is not None:
                            raise state["error"]   # it could not be started
                        cond.wait()
                    f = futures[i]
                out = f.result()                   # raises the call's error
                with cond:
                    futures[i] = False             # taken: let Dask forget it
                f.release()
                del f
                yield out
        finally:
            with cond:
                state["failed"] = True             # nothing more starts
                left = [f for f in futures if f]
                futures[:] = [False] * n
                todo.clear()
            if left:
                client.cancel(left)

    return results()


class _PlannedRestarts(logging.Filter):
    """Drops the nanny's warning that it restarts a worker (planned here)."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not record.getMessage().startswith("Restarting worker")
