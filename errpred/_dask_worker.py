"""What the command lines' local Dask cluster sets up in each of its worker processes,
the first ones and any the nanny starts again (a worker plugin): malloc that keeps
freed memory, and a count of the kernels numba compiles there.

Imported only where a cluster is made (it imports ``distributed``).
"""

from __future__ import annotations

from collections.abc import Callable

from distributed import WorkerPlugin
from numba.core import event

__all__ = ["WorkerSetup", "compiles"]

#: numba compilations in this process since the plugin set it up (cache loads excluded:
#: numba only signals ``numba:compile`` when its on-disk cache had no such kernel).
_COMPILES = 0


class _CompileCounter(event.Listener):
    def on_start(self, ev) -> None:
        global _COMPILES
        _COMPILES += 1

    def on_end(self, ev) -> None:
        pass


def compiles() -> int:
    """How many kernels numba compiled in this worker since it started (its compiler
    keeps the memory it took: about 150-290 MB for the job's kernels)."""
    return _COMPILES


class WorkerSetup(WorkerPlugin):
    """Run in every worker when it starts (``Client.register_plugin``): ``malloc_setup``
    (a function of no arguments: ``errpred.cluster.keep_freed_memory``), then the count of
    numba's compilations."""

    name = "errpred-worker-setup"

    def __init__(self, malloc_setup: Callable[[], object]) -> None:
        self.malloc_setup = malloc_setup

    def setup(self, worker) -> None:
        self.malloc_setup()
        self._counter = _CompileCounter()
        event.register("numba:compile", self._counter)

    def teardown(self, worker) -> None:      # a plugin registered again: one listener
        event.unregister("numba:compile", self._counter)
