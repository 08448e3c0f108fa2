"""Compiled (numba) kernel of :func:`errpred.force.tool_forces`.

Optional: numba is not a declared dependency of the package. When it cannot
be imported, :data:`forces_kernel` is None and ``errpred.force`` uses its
numpy path (same result to round-off; ``tests/errpred/test_force.py``
compares them, and ``tests/errpred/test_laws.py`` for every force law).
Measured for (n_ang, n_fl, m) = (180, 2, 120), ball end mill, when the kernel
still held the linear law: 19 % of the entries cutting, numba 0.16 ms, numpy
0.9 ms per call; 50 % cutting, 0.37 ms and 2.3 ms. The law is now evaluated
on the whole block before the kernel (``errpred.laws``): ``tool_forces`` as a
whole, 30 % cutting, linear law, went from 1.03-1.05 ms to 1.2-1.5 ms per call
(2 shared cores under load). First call compiles (~0.6 s, then cached on disk).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["forces_kernel"]

try:  # pragma: no cover - exercised where numba is installed
    import numba
except ImportError:  # pragma: no cover
    numba = None


def _forces(phi: np.ndarray, cutting: np.ndarray, db: np.ndarray, sk: np.ndarray,
            ck: np.ndarray, ft: np.ndarray, fr: np.ndarray, fa: np.ndarray,
            weight: np.ndarray) -> np.ndarray:
    """Sum of the micro-edge forces per angle sample, shape (n_ang, 3) [N].

    The force law is not here: ``ft, fr, fa`` are each entry's force per unit
    chip width, evaluated by the law (``errpred.laws``).

    Parameters
    ----------
    phi : ndarray, shape (n_ang, n_fl, m) [rad]
    cutting : ndarray of bool, shape (n_ang, n_fl, m)
    db, sk, ck : ndarray, shape (m,) [mm], [-], [-]
        Chip width, sin and cos of the immersion angle.
    ft, fr, fa : ndarray, shape (n_ang, n_fl, m) [N/mm]
        Tangential, radial, axial force per unit chip width (read where cutting).
    weight : ndarray, shape (n_ang, n_fl, m)
        Fraction of each sample's rotation step spent cutting (1 inside the
        engagement, between 0 and 1 at its boundary).
    """
    n_ang, n_fl, m = phi.shape
    out = np.zeros((n_ang, 3))
    for i in range(n_ang):
        fx = 0.0
        fy = 0.0
        fz = 0.0
        for k in range(n_fl):
            for j in range(m):
                if cutting[i, k, j]:
                    w = db[j] * weight[i, k, j]
                    dft = ft[i, k, j] * w
                    dfr = fr[i, k, j] * w
                    dfa = fa[i, k, j] * w
                    sp = math.sin(phi[i, k, j])
                    cp = math.cos(phi[i, k, j])
                    a = dfr * sk[j] + dfa * ck[j]
                    fx -= dft * cp + a * sp
                    fy += dft * sp - a * cp
                    fz += dfr * ck[j] - dfa * sk[j]
        out[i, 0] = fx
        out[i, 1] = fy
        out[i, 2] = fz
    return out


forces_kernel = None if numba is None else numba.njit(cache=True, nogil=True)(_forces)
