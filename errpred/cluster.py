"""A Dask client for the command lines: an existing scheduler or a local cluster."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any

from nc.errors import InputError

__all__ = ["dask_client", "keep_freed_memory"]


@contextlib.contextmanager
def dask_client(scheduler: str | None = None, workers: int = 0) -> Iterator[Any]:
    """``dask.distributed.Client`` of ``scheduler`` (an address such as
    ``tcp://10.0.0.5:8786``), or of a local cluster of ``workers`` single-threaded
    worker processes bound to 127.0.0.1 (whose malloc keeps freed memory:
    :func:`keep_freed_memory`); None (no cluster) when neither is given.

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
        client.run(keep_freed_memory)       # speed only (a restarted worker goes without)
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
