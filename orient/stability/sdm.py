"""Time-periodic stability: first-order full discretization (Ding et al. 2010).

Same model as :mod:`orient.stability.zoa` (the contract), now with the
time-periodic directional matrix: ``F = s H(t) (q(t) - q(t - tau))``, and
the modal equations ``m_k eta_k'' + c_k eta_k' + k_k eta_k = d_k . F``
(:class:`orient.dynamics.ModalSystem`, ``q = D xi``, ``xi = eta + R eta'``;
``R = 0`` for real modes). With ``y = [eta; eta']`` and ``xi = C y``,
``C = [I, R]``:

    ``y' = A0 y + B U(t) (xi(t) - xi(t - tau))``,  ``U = s M^-1 D^T H(t) D``.

Method (Ding, Zhu, Zhang, Ding, "A full-discretization method for
prediction of milling stability", IJMTM 50 (2010) 502-509): the tooth period
is cut into ``k`` equal steps ``dt = tau / k`` (the delay is exactly ``k``
steps); on each step the response is integrated exactly for the constant
structure ``A0`` (Duhamel), and the delayed difference
``d(t) = xi(t) - xi(t - tau)`` is interpolated linearly between the nodes.
Unlike the paper, the periodic coefficient ``U(t)`` is **not** interpolated:
it is integrated exactly against the Duhamel kernel over each step,

    ``Pa_i = int_0^dt e^{A0 (dt - r)} B U(t_i + r) (1 - r / dt) dr``,
    ``Pb_i = int_0^dt e^{A0 (dt - r)} B U(t_i + r) r / dt dr``,

for the piecewise-constant ``U`` of the samples (below), which gives the
implicit one-step map

    ``(I - Pb_i C) y_{i+1} = Phi0 y_i + Pa_i (xi_i - xi_{i-k}) - Pb_i xi_{i+1-k}``

with ``Phi0 = e^{A0 dt}``. Each step is cut into ``n`` equal sub-steps on
which ``U`` is constant; the sub-step weights follow from one matrix
exponential of a block matrix per spindle speed (Van Loan). The entry and
exit jumps of ``H`` then enter with their exact timing and impulse (no
blurring by an interpolation of ``U``), and the only discretization error
left is the linear interpolation of the smooth ``d(t)``: second order in
``dt`` (tests), with an error that scales with ``(f dt)^2`` for the natural
frequencies ``f`` near which the chatter oscillates, mostly from above (the
margin converges downward on most of the 1-DOF benchmark grid; not
everywhere: slotting at 19,500 rev/min converges from below), and
magnified where lobes cross or the boundary is steep in speed (a small
phase error moves the lobe). Chaining ``k`` steps gives the monodromy matrix of
the state ``[y; xi_{i-1} .. xi_{i-k}]``; the cut is stable iff its spectral
radius is < 1.

``H_samples[i]`` is the **average** of ``H`` over the interval
``[i tau / K, (i + 1) tau / K]`` of ``K`` equal intervals of one tooth period
(the semi-discretization's step average; :func:`orient.gain.process_gain`
and :meth:`StraightEndMill2D.directional_samples` give them in closed
form), i.e. a piecewise-constant ``H`` whose period mean is ``P``. The
samples are carried to the ``k n`` sub-steps by integrating that piecewise
constant function exactly (a conservative remap; exact when ``K`` divides
``k n``), so the integration's step count does not depend on the sample
count. Point values ``H(t_i)`` are accepted too (their representation error
is then second order in ``tau / K``).

The *margin* is the smallest ``s`` at which the spectral radius reaches 1:
a geometric scan upward from a fraction of the ZOA critical margin brackets
it, a finer scan of the last coarse interval finds an earlier crossing (the
radius can cross 1 and come back), Brent's method on ``log rho(s)`` refines
it. With the default steps, :func:`sdm_margin` also estimates the
discretization error and returns a margin reduced by part of it (its
Notes). The critical multiplier's kind is ``'fold'`` (real, +1), ``'flip'``
(real, -1, period doubling) or ``'hopf'`` (complex pair).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg
from numba import njit
from scipy.optimize import brentq

from errpred.spindle import tooth_period
from orient.blas import blas_limited
from orient.dynamics import ModalSystem
from orient.stability.zoa import _positive, _teeth, zoa_critical
from orient.constants import (
    KIND_ANGLE_TOL,
    ROUND_SLACK,
    SDM_DEFAULT_STEPS,
    SDM_ERROR_WEIGHT,
    SDM_MAX_STEPS,
    SDM_MAX_SUBSTEPS,
    SDM_MIN_SAMPLES,
    SDM_MIN_SAMPLES_IN_CUT,
    SDM_REFINE_MAX_ROWS,
    SDM_REFINE_TOL,
    SDM_RTOL,
    SDM_SCAN_FACTOR,
    SDM_SCAN_FINE_FACTOR,
    SDM_SCAN_MAX,
    SDM_SCAN_MIN_ZETA,
    SDM_SCAN_START,
    SDM_STEPS_PER_MODE_PERIOD,
    SDM_SUBSTEPS,
)

__all__ = [
    "KIND_ANGLE_TOL",
    "SDM_DEFAULT_STEPS",
    "SDM_ERROR_WEIGHT",
    "SDM_MAX_STEPS",
    "SDM_MAX_SUBSTEPS",
    "SDM_MIN_SAMPLES",
    "SDM_MIN_SAMPLES_IN_CUT",
    "SDM_REFINE_MAX_ROWS",
    "SDM_REFINE_TOL",
    "SDM_RTOL",
    "SDM_SCAN_FACTOR",
    "SDM_SCAN_FINE_FACTOR",
    "SDM_SCAN_MAX",
    "SDM_SCAN_START",
    "SDM_STEPS_PER_MODE_PERIOD",
    "SDM_SUBSTEPS",
    "SdmResult",
    "default_steps",
    "floquet_multipliers",
    "recommended_samples",
    "sdm_lobes",
    "sdm_margin",
]



@dataclass(frozen=True)
class SdmResult:
    """Time-periodic margin at one spindle speed.

    Attributes
    ----------
    margin : float
        Smallest scaling ``s`` with spectral radius 1 [-] (inf if none found
        up to ``SDM_SCAN_MAX`` times the scan start).
    multiplier : complex
        The critical Floquet multiplier just above the boundary (nan if none).
    kind : str
        ``'hopf'``, ``'flip'``, ``'fold'`` or ``'none'``.
    """

    margin: float
    multiplier: complex
    kind: str


def recommended_samples(cut_fraction: float) -> int:
    """Samples of ``H`` (step averages) per tooth period for a cut engaged over
    ``cut_fraction`` of it.

    ``max(SDM_MIN_SAMPLES, ceil(SDM_MIN_SAMPLES_IN_CUT / cut_fraction))``; e.g.
    168 for 2 teeth at a/D = 0.05 (engaged 14 % of the tooth period). The
    samples are integrated exactly, so their count only bounds how well the
    shape of ``H`` is known: at 80 steps, 84 samples left +0.26 % on the
    a/D = 0.05 flip lobe, 160 samples 0.05 % (1-DOF benchmark, against 1280).

    Parameters
    ----------
    cut_fraction : float
        Fraction of the tooth period during which ``H`` is non-zero, in (0, 1].
    """
    if isinstance(cut_fraction, (bool, np.bool_)) or not isinstance(cut_fraction, numbers.Real) \
            or not (0.0 < float(cut_fraction) <= 1.0):
        raise ValueError(f"cut_fraction: expected a value in (0, 1], got {cut_fraction!r}")
    return max(SDM_MIN_SAMPLES, math.ceil(SDM_MIN_SAMPLES_IN_CUT / float(cut_fraction)))


# ---------------------------------------------------------------------- kernel
@njit(cache=True)
def _solve_in_place(a, b):
    """``b <- a^-1 b`` for ``a`` (n, n), ``b`` (n, p): Gaussian elimination with partial
    pivoting (``a`` is overwritten). A matrix with a zero pivot raises."""
    n, p = a.shape[0], b.shape[1]
    for col in range(n):
        piv_row, big = col, abs(a[col, col])
        for r in range(col + 1, n):
            if abs(a[r, col]) > big:
                piv_row, big = r, abs(a[r, col])
        if big == 0.0:
            raise ValueError("singular step matrix (I - b C) in the monodromy matrix")
        if piv_row != col:
            for c in range(n):
                a[col, c], a[piv_row, c] = a[piv_row, c], a[col, c]
            for c in range(p):
                b[col, c], b[piv_row, c] = b[piv_row, c], b[col, c]
        piv = a[col, col]
        for r in range(col + 1, n):
            f = a[r, col] / piv
            if f != 0.0:
                for c in range(col + 1, n):
                    a[r, c] -= f * a[col, c]
                for c in range(p):
                    b[r, c] -= f * b[col, c]
    for r in range(n - 1, -1, -1):
        for c in range(p):
            v = b[r, c]
            for q in range(r + 1, n):
                v -= a[r, q] * b[q, c]
            b[r, c] = v / a[r, r]


@njit(cache=True)
def _monodromy(phi0, pa, pb, s, cmat, active, out):
    """Monodromy matrix of the full-discretization map (see module docstring), on its
    active states.

    ``phi0`` (2m, 2m), ``pa``/``pb`` (k, 2m, m) the per-step weights of the
    delayed difference at the step's start and end (``U`` integrated in), ``s``
    the scaling, ``cmat`` (m, 2m) = [I, R]: the modal displacement
    ``xi = eta + R eta'`` whose delay drives the cut; ``active`` the states whose
    columns can be non-zero (:func:`_active_states`, ascending, in the order
    ``[y; xi_{-1} .. xi_{-k}]`` of the whole state, N = (k + 2) m); ``out`` (a, a), a =
    ``active.size``: the whole matrix's principal submatrix on them (every other column
    of the whole matrix is zero).

    One step is ``y_{i+1} = M_i y_i - N_i xi_{i-k} - P_i xi_{i+1-k}`` with ``L_i = I -
    b_i C``, ``M_i = L_i^-1 (Phi0 + a_i C)``, ``N_i = L_i^-1 a_i``, ``P_i = L_i^-1 b_i``
    (the numpy twin's step). Over one period the delayed terms are the initial history
    (unit blocks: a subtraction, not a product) but for ``xi_0 = C y_0`` at the last
    step. The map is carried on the columns of the initial state, kept as rows (the
    state transposed, so that a run of leading columns is one contiguous block): ``y_0``,
    then the active delays in the order the period reads them (``xi_{-k}`` first), so
    that after step ``i`` only the rows of ``y_0`` and of the delays read so far are
    non-zero: each step works on those, and the columns are put in ``out``'s order at the
    end.
    """
    k, n2, m = pa.shape[0], pa.shape[1], pa.shape[2]
    na = active.shape[0]
    # active: y's 2m states, then whole m-blocks of delays (as _active_states makes it)
    h = (na - n2) // m                            # active delays
    slot = np.full(k + 1, -1, dtype=np.int64)     # row block of delay xi_{-lag}, or -1
    lag_of = np.empty(na, dtype=np.int64)         # out's column c: its delay (0: y)
    for c in range(na):
        lag_of[c] = 0 if c < n2 else (active[c] - n2) // m + 1
    for j in range(h):                            # ascending lags; read descending
        slot[lag_of[n2 + j * m]] = h - 1 - j
    read = np.zeros(k, dtype=np.int64)            # delays read up to step i (rows in use)
    for i in range(k):
        lowest = max(k - i - 1, 1)
        count = 0
        for lag in range(lowest, k + 1):
            if slot[lag] >= 0:
                count += 1
        read[i] = count
    nn = n2 + h * m
    xt = np.zeros((nn, n2))                       # y_i, transposed
    for r in range(n2):
        xt[r, r] = 1.0
    cmatt = np.ascontiguousarray(cmat.T)
    xs = np.empty((k, nn, m))                     # xi_j = C y_j, transposed, j = 0..k-1
    width = np.empty(k, dtype=np.int64)           # ... non-zero in its first rows only
    # element loops, not slice assignments, and the solve by hand: numba compiles each
    # array-to-array assignment's broadcast with its error message, np.linalg.solve its
    # checks and copies (3-4 s of this kernel's 6-8 s on an empty cache)
    prod = xt[:n2] @ cmatt
    for r in range(n2):
        for a in range(m):
            xs[0, r, a] = prod[r, a]
    width[0] = n2
    eye = np.eye(n2)
    sol = np.empty((n2, n2 + 2 * m))
    for i in range(k):
        w = n2 + read[i] * m                      # the non-zero rows after this step
        ai = s * pa[i]
        bi = s * pb[i]
        top = phi0 + ai @ cmat
        for r in range(n2):
            for c in range(n2):
                sol[r, c] = top[r, c]
            for c in range(m):
                sol[r, n2 + c] = ai[r, c]
                sol[r, n2 + m + c] = bi[r, c]
        _solve_in_place(eye - bi @ cmat, sol)     # [M_i, N_i, P_i] (a new left side)
        prod = xt[:w] @ np.ascontiguousarray(sol[:, :n2].T)
        for r in range(w):
            for c in range(n2):
                xt[r, c] = prod[r, c]
        sa = slot[k - i]                                       # xi_{i-k} (N_i = 0 if not)
        if sa >= 0:
            c0 = n2 + sa * m
            for a in range(m):
                for r in range(n2):
                    xt[c0 + a, r] -= sol[r, n2 + a]
        if i + 1 < k:                                          # xi_{i+1-k}: the next one
            sb = slot[k - i - 1]
            if sb >= 0:
                c0 = n2 + sb * m
                for a in range(m):
                    for r in range(n2):
                        xt[c0 + a, r] -= sol[r, n2 + m + a]
            prod = xt[:w] @ cmatt
            for r in range(w):
                for a in range(m):
                    xs[i + 1, r, a] = prod[r, a]
            width[i + 1] = w
        else:                                                  # xi_0 = C y_0
            prod = np.ascontiguousarray(sol[:, n2 + m:]) @ cmat
            for r in range(n2):
                for c in range(n2):
                    xt[r, c] -= prod[c, r]
    src = np.empty(na, dtype=np.int64)            # out's column c is row src[c] here
    for c in range(na):
        src[c] = c if c < n2 else n2 + slot[lag_of[c]] * m + (c - n2) % m
    for r in range(n2):
        for c in range(na):
            out[r, c] = xt[src[c], r]
    for r in range(n2, na):                       # row of xi_{-lag} after the period: xi_{k-lag}
        q = k - lag_of[r]
        a = (r - n2) % m
        for c in range(na):
            out[r, c] = xs[q, src[c], a] if src[c] < width[q] else 0.0


def _monodromy_numpy(phi0, pa, pb, s, cmat):
    """Numpy twin of :func:`_monodromy` (tests): the whole monodromy matrix, the one-step
    maps chained as block matrices on the state ``[y; xi_{i-1} .. xi_{i-k}]`` (the
    kernel's is its principal submatrix on the active states)."""
    k, n2, m = pa.shape
    nn = n2 + k * m
    total = np.eye(nn)
    for i in range(k):
        a, b = s * pa[i], s * pb[i]
        step = np.zeros((nn, nn))
        linv = np.linalg.inv(np.eye(n2) - b @ cmat)
        # y_{i+1} = L^-1 (Phi0 y_i + a (C y_i - xi_{i-k}) - b xi_{i+1-k})
        step[:n2, :n2] = linv @ (phi0 + a @ cmat)
        step[:n2, n2 + (k - 1) * m:] -= linv @ a                 # xi_{i-k}: the oldest
        if k > 1:
            step[:n2, n2 + (k - 2) * m:n2 + (k - 1) * m] -= linv @ b  # xi_{i+1-k}
        else:
            step[:n2, :n2] -= linv @ b @ cmat                     # k = 1: xi_{i+1-k} = xi_i
        step[n2:n2 + m, :n2] = cmat                               # xi_i = C y_i
        for j in range(1, k):
            step[n2 + j * m:n2 + (j + 1) * m, n2 + (j - 1) * m:n2 + j * m] = np.eye(m)
        total = step @ total
    return total


# ---------------------------------------------------------------------- setup
def _check_samples(h: Any) -> np.ndarray:
    a = np.asarray(h, dtype=float)
    if a.ndim != 3 or a.shape[1:] != (3, 3) or a.shape[0] < 2:
        raise ValueError(f"H_samples: expected shape (k, 3, 3) with k >= 2, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError("H_samples: expected finite values")
    return a


def _remap(h: np.ndarray, n: int) -> np.ndarray:
    """Averages over ``n`` equal intervals of the piecewise-constant function with
    averages ``h`` over ``K`` equal intervals (exact integration; the mean is kept)."""
    k = h.shape[0]
    if n == k:
        return h
    if n % k == 0:
        return np.repeat(h, n // k, axis=0)
    flat = h.reshape(k, 9)
    cum = np.vstack([np.zeros((1, 9)), np.cumsum(flat, axis=0)])     # tau/K units
    i = np.arange(n + 1) * k / n                                     # fine edges, in samples
    j = np.minimum(np.floor(i).astype(int), k - 1)
    at = cum[j] + (i - j)[:, None] * flat[j]
    return (np.diff(at, axis=0) * (n / k)).reshape(n, 3, 3)


def _substeps(k: int, steps: int) -> int:
    """Sub-steps per step: the sample intervals' edges on sub-step edges when that
    takes at most ``SDM_MAX_SUBSTEPS`` (the samples' jumps kept exactly), else at
    least ``SDM_SUBSTEPS`` and as fine as the samples."""
    fine = k * steps // math.gcd(k, steps)                     # lcm
    if fine // steps <= SDM_MAX_SUBSTEPS:
        n = fine // steps
        return n * -(-SDM_SUBSTEPS // n)                       # a multiple, >= SDM_SUBSTEPS
    return max(SDM_SUBSTEPS, -(-k // steps))


def default_steps(system: ModalSystem, spindle_rpm: float, teeth: int) -> int:
    """Default steps per tooth period of the time-periodic analysis [-].

    ``min(SDM_MAX_STEPS, max(SDM_DEFAULT_STEPS, ceil(SDM_STEPS_PER_MODE_PERIOD
    tau f_max)))`` with ``tau = 60 / (spindle_rpm teeth)`` [s] and ``f_max`` the
    highest natural frequency [Hz]. The coefficient is integrated exactly on
    sub-steps (module docstring), so the step resolves only the delayed state
    difference, which oscillates near the natural frequencies.

    Parameters
    ----------
    system : ModalSystem
        Relative dynamics.
    spindle_rpm : float [rev/min]
        Spindle speed, > 0.
    teeth : int
        Number of teeth.
    """
    if not isinstance(system, ModalSystem):
        raise TypeError(f"system: expected an orient.dynamics.ModalSystem, got "
                        f"{type(system).__name__}")
    tau = tooth_period(_positive("spindle_rpm", spindle_rpm), _teeth(teeth))
    return _default_steps(system, tau)


def _default_steps(system: ModalSystem, tau: float) -> int:
    fmax = float(system.natural_frequency_rad_s.max()) / (2.0 * math.pi)
    need = math.ceil(SDM_STEPS_PER_MODE_PERIOD * tau * fmax - ROUND_SLACK)
    return min(SDM_MAX_STEPS, max(SDM_DEFAULT_STEPS, need))


def _steps(steps: Any, k: int, system: ModalSystem, tau: float) -> int:
    """Steps per tooth period: ``steps`` checked, or the default (``k`` unused:
    kept for callers that pass the sample count)."""
    if steps is None:
        return _default_steps(system, tau)
    if isinstance(steps, (bool, np.bool_)) or not isinstance(steps, numbers.Integral) \
            or steps < 2:
        raise ValueError(f"steps: expected an integer >= 2, got {steps!r}")
    return int(steps)


class _Fdm:
    """Precomputed full-discretization data of one (H, system, speed, steps)."""

    def __init__(self, h: np.ndarray, system: ModalSystem, tau: float, steps: int) -> None:
        m = system.n_modes
        nsub = _substeps(h.shape[0], steps)
        hf = _remap(h, steps * nsub)
        d = system.shape_matrix                                   # (3, m)
        w = np.einsum("ai,kab,bj->kij", d, hf, d)                 # D^T H D
        u = (w / system.m_kg[None, :, None]).reshape(steps, nsub, m, m)
        dt = tau / steps
        hh = dt / nsub
        a0 = system.state_matrix()
        big = np.zeros((4 * m, 4 * m))
        big[:2 * m, :2 * m] = a0
        big[m:2 * m, 2 * m:3 * m] = np.eye(m)                     # B = [0; I]
        big[2 * m:3 * m, 3 * m:] = np.eye(m)
        e = scipy.linalg.expm(big * hh)
        ph = e[:2 * m, :2 * m]                                    # e^{A0 h}
        g0 = e[:2 * m, 2 * m:3 * m]                               # int_0^h e^{A0 v} dv B
        g1 = hh * g0 - e[:2 * m, 3 * m:]                          # int_0^h e^{A0 v} v dv B
        wa = np.empty((nsub, 2 * m, m))
        wb = np.empty((nsub, 2 * m, m))
        carry = np.eye(2 * m)                                     # e^{A0 (dt - (j+1) h)}
        for j in range(nsub - 1, -1, -1):     # sub-step j: r in [j h, (j+1) h], v = (j+1) h - r
            wb[j] = carry @ (((j + 1) * hh * g0 - g1) / dt)
            wa[j] = carry @ g0 - wb[j]
            carry = carry @ ph
        self.phi0 = np.ascontiguousarray(carry)                   # e^{A0 dt}
        self.pa = np.ascontiguousarray(np.einsum("jab,ijbc->iac", wa, u))
        self.pb = np.ascontiguousarray(np.einsum("jab,ijbc->iac", wb, u))
        self.cmat = np.ascontiguousarray(np.hstack([np.eye(m), np.diag(system.velocity_s)]))
        self.steps = steps
        self.n = (steps + 2) * m
        self.active = _active_states(self.pa, self.pb)
        self._out = np.zeros((self.active.size, self.active.size))
        self.evaluations = 0

    def matrix(self, s: float) -> np.ndarray:
        """The monodromy matrix on :attr:`active` (the principal submatrix; the whole
        matrix's other columns are zero)."""
        _monodromy(self.phi0, self.pa, self.pb, float(s), self.cmat, self.active, self._out)
        self.evaluations += 1
        return self._out

    def _eigvals(self, s: float) -> np.ndarray:
        """The monodromy matrix's non-trivial eigenvalues: those on its active states
        (:func:`_active_states`; the others are exactly 0)."""
        return scipy.linalg.eigvals(self.matrix(s), check_finite=False)

    def multipliers(self, s: float) -> np.ndarray:
        mu = np.zeros(self.n, dtype=complex)
        mu[:self.active.size] = self._eigvals(s)
        return mu[np.argsort(-np.abs(mu), kind="stable")]

    def rho(self, s: float) -> float:
        return float(np.max(np.abs(self._eigvals(s)), initial=0.0))


def _active_states(pa: np.ndarray, pb: np.ndarray) -> np.ndarray:
    """The states of the monodromy matrix (:func:`_monodromy`'s ``out`` order) whose
    columns can be non-zero: ``y`` and the delayed ``xi_{-l}`` that a step of the period
    reads, ascending.

    ``xi_{-l}`` enters the period only at step ``k - l`` (through ``a``) and at step
    ``k - l - 1`` (through ``b``); where the cut's coefficient is zero over both (the
    tooth out of the cut) its column is zero for every scaling. A matrix whose columns
    ``Z`` are zero has the eigenvalues of its principal submatrix on the other states,
    and ``|Z|`` zeros (its characteristic polynomial is ``lambda^|Z|`` times the
    submatrix's): out of the cut most of the period, most of the matrix.

    Parameters
    ----------
    pa, pb : ndarray, shape (k, 2m, m)
        The per-step weights (:class:`_Fdm`).

    Returns
    -------
    ndarray of int
    """
    k, n2, m = pa.shape
    reads_a = np.any(pa != 0.0, axis=(1, 2))          # step i reads xi_{i-k}
    reads_b = np.any(pb != 0.0, axis=(1, 2))          # step i reads xi_{i+1-k}
    lag = np.arange(1, k + 1)
    # through b: lag k would be step -1 (none; the last step's b reads xi_0 = C y_0, in y)
    used = reads_a[k - lag] | np.concatenate([reads_b[k - lag[:-1] - 1], [False]])
    cols = n2 + (lag - 1)[:, None] * m + np.arange(m)[None, :]
    return np.concatenate([np.arange(n2), cols[used].ravel()]).astype(np.int64)


def _prepare(H_samples: Any, system: Any, spindle_rpm: Any, teeth: Any,
             steps: Any) -> tuple[_Fdm, np.ndarray]:
    h = _check_samples(H_samples)
    if not isinstance(system, ModalSystem):
        raise TypeError(f"system: expected an orient.dynamics.ModalSystem, got "
                        f"{type(system).__name__}")
    rpm = _positive("spindle_rpm", spindle_rpm)
    tau = tooth_period(rpm, _teeth(teeth))
    return _Fdm(h, system, tau, _steps(steps, h.shape[0], system, tau)), h


@blas_limited
def floquet_multipliers(H_samples: Any, system: ModalSystem, spindle_rpm: float, teeth: int,
                        scale: float = 1.0, steps: int | None = None) -> np.ndarray:
    """Floquet multipliers of the discretized cut, sorted by decreasing modulus.

    Parameters
    ----------
    H_samples : array_like, shape (k, 3, 3) [N/m]
        Directional matrix: its averages over ``k`` equal steps of one tooth
        period (see module doc).
    system : ModalSystem
        Relative dynamics.
    spindle_rpm : float [rev/min]
        Spindle speed, > 0.
    teeth : int
        Number of teeth (``tau = 60 / (spindle_rpm teeth)``).
    scale : float [-]
        The process scaling ``s`` (>= 0).
    steps : int, optional
        Steps per tooth period; default :func:`default_steps`. The samples
        are integrated exactly over its sub-steps (module docstring),
        whatever their count.

    Returns
    -------
    ndarray complex, shape ((steps + 2) m,)
        Multipliers; stable iff all have modulus < 1.
    """
    if isinstance(scale, (bool, np.bool_)) or not isinstance(scale, numbers.Real) \
            or not math.isfinite(float(scale)) or float(scale) < 0:
        raise ValueError(f"scale: expected a finite value >= 0, got {scale!r}")
    fdm, _ = _prepare(H_samples, system, spindle_rpm, teeth, steps)
    return fdm.multipliers(float(scale))


def _kind(mu: complex) -> str:
    ang = abs(math.atan2(mu.imag, mu.real))
    if ang < KIND_ANGLE_TOL:
        return "fold"
    if math.pi - ang < KIND_ANGLE_TOL:
        return "flip"
    return "hopf"


def _scan_start(h: np.ndarray, system: ModalSystem) -> float:
    """Start of the upward scan: a fraction of the ZOA critical margin of mean(H),
    or, when the mean gives none, of a stiffness-to-gain scale."""
    crit = zoa_critical(h.mean(axis=0), system).margin
    if math.isfinite(crit):
        return SDM_SCAN_START * crit
    gain = float(np.max(np.linalg.norm(h, ord=2, axis=(1, 2))))
    if gain == 0.0:
        return math.inf
    kz = float(np.min(system.k_N_m * np.maximum(system.damping_ratio, SDM_SCAN_MIN_ZETA)))
    return SDM_SCAN_START * kz / gain


def _margin(fdm: _Fdm, s0: float, rtol: float) -> SdmResult:
    """Smallest ``s >= 0`` with spectral radius 1: coarse scan (``SDM_SCAN_FACTOR``) to
    the first unstable point, fine scan (``SDM_SCAN_FINE_FACTOR``) over the last coarse
    interval for an earlier crossing, Brent in the first fine bracket."""
    if not math.isfinite(s0):
        return SdmResult(math.inf, complex(math.nan, math.nan), "none")
    lo, hi = 0.0, s0
    if fdm.rho(hi) >= 1.0:            # already unstable at the start: scan downward
        for _ in range(200):
            lo = hi / SDM_SCAN_FACTOR
            if fdm.rho(lo) < 1.0:
                break
            hi = lo
        else:
            mu = fdm.multipliers(hi)[0]
            return SdmResult(0.0, complex(mu), _kind(mu))
    else:
        while True:
            lo, hi = hi, hi * SDM_SCAN_FACTOR
            if hi > s0 * SDM_SCAN_MAX:
                return SdmResult(math.inf, complex(math.nan, math.nan), "none")
            if fdm.rho(hi) >= 1.0:
                break
    x = lo * SDM_SCAN_FINE_FACTOR
    while x < hi:                     # an unstable window inside (lo, hi)?
        if fdm.rho(x) >= 1.0:
            hi = x
            break
        lo, x = x, x * SDM_SCAN_FINE_FACTOR
    s = brentq(lambda x: math.log(fdm.rho(x)), lo, hi, rtol=rtol, xtol=1e-300)
    mu = fdm.multipliers(s * (1.0 + 2.0 * rtol))[0]
    # the root is known to within rtol: its lower end, on the safe side
    return SdmResult(float(s) * (1.0 - rtol), complex(mu), _kind(mu))


@blas_limited
def sdm_margin(H_samples: Any, system: ModalSystem, spindle_rpm: float, teeth: int, *,
               steps: int | None = None, s_start: float | None = None,
               rtol: float = SDM_RTOL) -> SdmResult:
    """Time-periodic stability margin at one spindle speed.

    Parameters
    ----------
    H_samples : array_like, shape (k, 3, 3) [N/m]
        Directional matrix: its averages over ``k`` equal steps of the tooth
        period (see module doc).
    system : ModalSystem
        Relative dynamics.
    spindle_rpm : float [rev/min]
        Spindle speed, > 0.
    teeth : int
        Number of teeth.
    steps : int, optional
        Steps per tooth period, and the margin of that discretization as
        it is. Default: :func:`default_steps` with the error control below.
    s_start : float, optional
        Where the upward scan in ``s`` starts [-]; default
        ``SDM_SCAN_START`` times the ZOA critical margin of ``mean(H)``.
        Unstable regions below it are not searched.
    rtol : float
        Relative tolerance of the root in ``s`` [-].

    Returns
    -------
    SdmResult
        ``margin`` (inf for a zero-gain process), the critical multiplier
        and its kind.

    Notes
    -----
    Default steps: the margins ``s_k`` at ``k = default_steps`` and ``s_{k/2}``
    give the error estimate ``D = |s_k - s_{k/2}|`` (``D / 3`` for a
    second-order method); where ``D`` exceeds ``SDM_REFINE_TOL s_k`` and the
    matrix stays within ``SDM_REFINE_MAX_ROWS`` rows, ``k`` is doubled once
    (``D = |s_2k - s_k|``). The margin returned is ``s - SDM_ERROR_WEIGHT D``
    for the finest ``s``: below the plain value, by more than the
    second-order estimate of its error. On the 1-DOF milling benchmark grid
    (Insperger & Stepan; 5,000-25,000 rev/min, a/D 0.05-1, up and down
    milling, samples :func:`recommended_samples`) it is within 1 % of the
    converged limit and at most 0.5 % above it
    (``tests/orient/test_stability.py::test_defaults_on_the_1dof_benchmark_grid``,
    table ``tests/orient/data/sdm_1dof_converged.csv``).
    """
    fdm, hs = _prepare(H_samples, system, spindle_rpm, teeth, steps)
    s0 = _scan_start(hs, system) if s_start is None else _positive("s_start", s_start)
    rtol = _positive("rtol", rtol)
    res = _margin(fdm, s0, rtol)
    if steps is not None or not (0.0 < res.margin < math.inf):
        return res
    k = fdm.steps
    tau = tooth_period(float(spindle_rpm), int(teeth))
    near = res.margin / SDM_SCAN_FACTOR           # the other levels scan from just below
    coarse = _margin(_Fdm(hs, system, tau, max(2, k // 2)), near, rtol).margin
    if not math.isfinite(coarse):
        return res
    err = abs(res.margin - coarse)
    if err > SDM_REFINE_TOL * res.margin and (2 * k + 2) * system.n_modes <= SDM_REFINE_MAX_ROWS:
        fine = _margin(_Fdm(hs, system, tau, 2 * k), near, rtol)
        if 0.0 < fine.margin < math.inf:
            err = abs(fine.margin - res.margin)
            res = fine
    return SdmResult(max(0.0, res.margin - SDM_ERROR_WEIGHT * err), res.multiplier, res.kind)


@blas_limited
def sdm_lobes(H_samples: Any, system: ModalSystem, teeth: int, rpm: Any, *,
              steps: int | None = None, rtol: float = SDM_RTOL) -> list[SdmResult]:
    """:func:`sdm_margin` at many spindle speeds ``rpm`` (r,) [rev/min]."""
    h = _check_samples(H_samples)
    r = np.asarray(rpm, dtype=float).reshape(-1)
    if r.size == 0 or not np.all(np.isfinite(r)) or np.any(r <= 0):
        raise ValueError("rpm: expected finite spindle speeds > 0 [rev/min]")
    s0 = _scan_start(h, system)
    return [sdm_margin(h, system, float(x), teeth, steps=steps, s_start=s0, rtol=rtol)
            for x in r]
