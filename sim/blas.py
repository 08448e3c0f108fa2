"""How many threads the BLAS libraries of this process use (the main job's main process).

The main job runs a local Dask cluster of one worker process per core; Dask starts
its workers with one BLAS thread each (``OPENBLAS_NUM_THREADS=1``), but the main
process keeps OpenBLAS's default of one thread per core, and it does BLAS work of
its own while the workers compute (the planner's time-periodic margins: LAPACK's
eigenvalues of a 1,134 x 1,134 monodromy matrix, and numba's ``np.linalg.solve``
in building it). OpenBLAS's threads spin while they wait for work, so with every
core taken they wait for each other: measured on the bundled thin wall's monodromy
matrix on the 2 cores with the workers busy, an eigenvalue computation took 6.1 s
with two threads against 0.07 s with one, its matrix 2.0 s against 0.1 s.

numpy and scipy each bring an OpenBLAS of their own (``scipy_openblas64_`` and
``scipy_openblas``); :func:`blas_threads` sets both, through the
``*_set_num_threads`` entry each exports, found among the libraries the process has
loaded (``/proc/self/maps``; elsewhere nothing is changed).
"""

from __future__ import annotations

import contextlib
import ctypes
from collections.abc import Iterator
from pathlib import Path

__all__ = ["blas_threads"]

#: OpenBLAS's entries that set and read its thread count, by symbol suffix
#: (``scipy_openblas`` builds add a prefix and, for 64-bit integers, ``64_``).
_SETTERS = (("openblas_set_num_threads", "openblas_get_num_threads"),
            ("openblas_set_num_threads64_", "openblas_get_num_threads64_"),
            ("scipy_openblas_set_num_threads", "scipy_openblas_get_num_threads"),
            ("scipy_openblas_set_num_threads64_", "scipy_openblas_get_num_threads64_"))


def _openblas_libraries() -> list[ctypes.CDLL]:
    """The OpenBLAS libraries loaded in this process (none where /proc is not there)."""
    try:
        maps = Path("/proc/self/maps").read_text()
    except OSError:
        return []
    paths = sorted({line.split()[-1] for line in maps.splitlines()
                    if "openblas" in line.rsplit("/", 1)[-1].lower() and ".so" in line})
    libs = []
    for p in paths:
        try:
            libs.append(ctypes.CDLL(p))
        except OSError:
            continue
    return libs


@contextlib.contextmanager
def blas_threads(threads: int) -> Iterator[int]:
    """Run the block with every loaded OpenBLAS at ``threads`` threads, then restore.

    Parameters
    ----------
    threads : int [-]
        Threads per BLAS library, >= 1.

    Yields
    ------
    int
        How many libraries were set (0: none found; nothing changed).
    """
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise ValueError(f"threads: expected an integer >= 1, got {threads!r}")
    restore = []
    for lib in _openblas_libraries():
        for set_name, get_name in _SETTERS:
            setter, getter = getattr(lib, set_name, None), getattr(lib, get_name, None)
            if setter is None or getter is None:
                continue
            setter.argtypes, getter.restype = [ctypes.c_int], ctypes.c_int
            restore.append((setter, int(getter())))
            setter(threads)
            break
    try:
        yield len(restore)
    finally:
        for setter, before in restore:
            setter(before)
