"""A Dask client for the command lines: an existing scheduler or a local cluster."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any

__all__ = ["dask_client"]


@contextlib.contextmanager
def dask_client(scheduler: str | None = None, workers: int = 0) -> Iterator[Any]:
    """``dask.distributed.Client`` of ``scheduler`` (an address such as
    ``tcp://10.0.0.5:8786``), or of a local cluster of ``workers`` single-threaded
    worker processes bound to 127.0.0.1 (with ``constants.WORKER_MALLOC_ENV``); None
    (no cluster) when neither is given.

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
        raise ValueError(f"--dask: expected >= 1 workers, got {workers}")
    import dask

    from .constants import WORKER_MALLOC_ENV

    env = {**dask.config.get("distributed.nanny.pre-spawn-environ", {}), **WORKER_MALLOC_ENV}
    with dask.config.set({"distributed.nanny.pre-spawn-environ": env}), \
            LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                         host="127.0.0.1", dashboard_address=None) as cluster, \
            Client(cluster) as client:
        yield client
