"""Compiled (numba) kernel of :func:`errpred.force.entry_forces` (and so of
:func:`errpred.force.tool_forces`): the cutting entries' forces summed per angle sample.

Optional: numba is not a declared dependency of the package. When it cannot
be imported, :data:`entry_forces_kernel` is None and ``errpred.force`` uses its
numpy path (same result to round-off; ``tests/errpred/test_force.py``
compares them, and ``tests/errpred/test_laws.py`` for every force law).
It loops over the cutting entries only (stage 2 lists them from flute 0's
engagement arrays, ``errpred.physics``); the loop over the whole (n_ang, n_fl, m) block it
replaced gave the same sums in the same order. First call compiles (~0.6 s, then
cached on disk).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["entry_forces_kernel"]

try:  # pragma: no cover - exercised where numba is installed
    import numba
except ImportError:  # pragma: no cover
    numba = None


def _entry_forces(n_ang: int, i: np.ndarray, j: np.ndarray, phi: np.ndarray, db: np.ndarray,
                  sk: np.ndarray, ck: np.ndarray, ft: np.ndarray, fr: np.ndarray,
                  fa: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Sum of the micro-edge forces per angle sample over the cutting entries, shape
    (n_ang, 3) [N]. The force law is not here: ``ft, fr, fa`` are each entry's force per
    unit chip width, evaluated by the law (``errpred.laws``).

    Entry ``e`` is micro edge ``j[e]`` at angle sample ``i[e]`` (any flute), at angular
    position ``phi[e]`` [rad], with its force per unit chip width ``ft, fr, fa`` [N/mm]
    and its share of the step ``weight[e]``; ``db, sk, ck`` are per micro edge. The
    entries in the order of the samples, flutes and micro edges (``np.nonzero`` of the
    whole block's mask) sum in the order a loop over the block would (samples, then
    flutes, then micro edges).
    """
    out = np.zeros((n_ang, 3))
    for e in range(i.shape[0]):
        s = i[e]
        c = j[e]
        w = db[c] * weight[e]
        dft = ft[e] * w
        dfr = fr[e] * w
        dfa = fa[e] * w
        sp = math.sin(phi[e])
        cp = math.cos(phi[e])
        a = dfr * sk[c] + dfa * ck[c]
        out[s, 0] -= dft * cp + a * sp
        out[s, 1] += dft * sp - a * cp
        out[s, 2] += dfr * ck[c] - dfa * sk[c]
    return out


entry_forces_kernel = None if numba is None else numba.njit(cache=True, nogil=True)(
    _entry_forces)
