"""BLAS threads of orient's linear-algebra hot paths (threadpoolctl).

The time-periodic stability's eigenvalues (:mod:`orient.stability.sdm`) and
the thin-wall FEM's sparse LU and Lanczos solves (:mod:`orient.fem.q2hex`)
run with numpy's and scipy's OpenBLAS limited to
:data:`orient.constants.BLAS_THREADS` threads, restored afterwards. With
OpenBLAS's default (one thread a core) on a machine whose cores other
processes keep busy, its spinning threads made ``eigvals`` of the monodromy
matrices 10 to 100 times slower; and its results change in the last bits
with the thread count. The job's main process limits them the same way
(``sim.constants.JOB_BLAS_THREADS``).

The limit is process-wide (the BLAS library's own setting): nested and
concurrent uses (threads solving side by side) share one limit, set by the
first to enter and restored by the last to leave. Enter it in the thread
that starts the solver threads (as :mod:`orient.workpiece` does): OpenBLAS
ignores a limit set in another thread once the main thread has set its own.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

from orient.constants import BLAS_THREADS

__all__ = ["blas_limited", "limited_blas"]

F = TypeVar("F", bound=Callable[..., Any])

_LOCK = threading.Lock()
_state: dict[str, Any] = {"depth": 0, "limiter": None, "controller": None}


def _controller() -> Any:
    # built on first use, after numpy and scipy have loaded their BLAS libraries
    if _state["controller"] is None:
        import scipy.linalg  # noqa: F401  (scipy's own OpenBLAS loaded before the scan)
        from threadpoolctl import ThreadpoolController

        _state["controller"] = ThreadpoolController()
    return _state["controller"]


@contextmanager
def limited_blas() -> Iterator[None]:
    """BLAS limited to ``BLAS_THREADS`` threads inside the block, restored after it."""
    with _LOCK:
        if _state["depth"] == 0:
            _state["limiter"] = _controller().limit(limits=BLAS_THREADS, user_api="blas")
        _state["depth"] += 1
    try:
        yield
    finally:
        with _LOCK:
            _state["depth"] -= 1
            if _state["depth"] == 0:
                _state["limiter"].restore_original_limits()
                _state["limiter"] = None


def blas_limited(func: F) -> F:
    """Decorator: ``func`` runs inside :func:`limited_blas`."""
    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with limited_blas():
            return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
