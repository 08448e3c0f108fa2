"""Numba kernels: a stable argsort and the gathers that go with it.

numba compiles ``np.argsort`` and ``np.sort`` (a quicksort or a merge sort per
kind and key type), boolean masks and index arrays with their broadcast checks and
error messages into every kernel that uses them: on an empty cache each cost
0.8-1.6 s to compile. These small loops do the same for the prediction's kernels
at a fraction of that. Their numpy twins are ``np.argsort(keys, kind="stable")``,
``a[order]``, ``a[mask]`` and a slice copy into a larger array
(``tests/errpred/test_sort_kernels.py``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["argsort_stable", "compress", "grown", "take"]

#: Run length sorted by insertion before the merges (a common choice: short runs
#: sort faster by insertion than by merging).
_RUN = 16


@njit(cache=True)
def argsort_stable(keys):
    """Indices that sort ``keys`` (n,) ascending, equal keys in their order: as
    ``np.argsort(keys, kind="stable")`` for keys without NaN. Bottom-up merge sort
    over runs sorted by insertion; int64 (n,)."""
    n = keys.shape[0]
    a = np.empty(n, dtype=np.int64)
    b = np.empty(n, dtype=np.int64)
    for t in range(n):
        a[t] = t
    for s in range(0, n, _RUN):
        e = min(s + _RUN, n)
        for t in range(s + 1, e):
            idx = a[t]
            key = keys[idx]
            u = t
            while u > s and keys[a[u - 1]] > key:
                a[u] = a[u - 1]
                u -= 1
            a[u] = idx
    width = _RUN
    while width < n:
        for s in range(0, n, 2 * width):
            m = min(s + width, n)
            e = min(s + 2 * width, n)
            i, j, o = s, m, s
            while i < m and j < e:
                if keys[a[j]] < keys[a[i]]:     # the left one on a tie: stable
                    b[o] = a[j]
                    j += 1
                else:
                    b[o] = a[i]
                    i += 1
                o += 1
            while i < m:
                b[o] = a[i]
                i += 1
                o += 1
            while j < e:
                b[o] = a[j]
                j += 1
                o += 1
        a, b = b, a
        width *= 2
    return a


@njit(cache=True)
def take(values, order):
    """``values[order]`` of a 1-D int64 array (a new array)."""
    out = np.empty(order.shape[0], dtype=values.dtype)
    for t in range(order.shape[0]):
        out[t] = values[order[t]]
    return out


@njit(cache=True)
def compress(values, mask):
    """``values[mask]`` of a 1-D int64 array (a new array)."""
    n = 0
    for t in range(mask.shape[0]):
        if mask[t]:
            n += 1
    out = np.empty(n, dtype=values.dtype)
    n = 0
    for t in range(mask.shape[0]):
        if mask[t]:
            out[n] = values[t]
            n += 1
    return out


@njit(cache=True)
def grown(buf, used, size):
    """A new array of ``size`` (>= ``used``) with ``buf[:used]`` first: a growing buffer's
    next one, copied by a loop (a slice assignment compiles a broadcast and its error
    message)."""
    out = np.empty(size, dtype=buf.dtype)
    for t in range(used):
        out[t] = buf[t]
    return out
