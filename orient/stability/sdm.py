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
structure ``A0`` (Duhamel), and the periodic, delayed term
``g(t) = U(t) (eta(t) - eta(t - tau))`` is interpolated linearly between the
nodes, which gives the implicit one-step map

    ``(I - Gb U_{i+1} C) y_{i+1} = Phi0 y_i + Ga U_i (xi_i - xi_{i-k}) - Gb U_{i+1} xi_{i+1-k}``

with ``Phi0 = e^{A0 dt}``, ``Ga = (Gamma0 - Gamma1/dt) B``, ``Gb = Gamma1/dt B``,
``Gamma0 = int_0^dt e^{A0 r} dr``, ``Gamma1 = int_0^dt e^{A0 r} (dt - r) dr``
(one matrix exponential of a block matrix per spindle speed, Van Loan).
This interpolates the product ``U eta`` rather than ``U`` and ``eta``
separately as the paper does; both are second-order accurate for smooth
data. Chaining ``k`` steps gives the monodromy matrix of the state
``[y; xi_{i-1} .. xi_{i-k}]``; the cut is stable iff its spectral radius is < 1.

``H_samples[i]`` is ``H`` at the **node** ``t_i = i tau / k`` (interval
starts, not midpoints); for discontinuous ``H`` pass hat-weighted node
averages (:meth:`StraightEndMill2D.directional_samples` does), which keep
the period mean exact.

The *margin* is the smallest ``s`` at which the spectral radius reaches 1:
a geometric scan upward from a fraction of the ZOA critical margin brackets
it, Brent's method on ``log rho(s)`` refines it. The critical multiplier's
kind is ``'fold'`` (real, +1), ``'flip'`` (real, -1, period doubling) or
``'hopf'`` (complex pair).
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

from orient.dynamics import ModalSystem
from orient.stability.zoa import _positive, _teeth, zoa_critical

__all__ = [
    "KIND_ANGLE_TOL",
    "SDM_DEFAULT_STEPS",
    "SDM_MAX_STEPS",
    "SDM_MIN_SAMPLES_IN_CUT",
    "SDM_RTOL",
    "SDM_SCAN_FACTOR",
    "SDM_SCAN_MAX",
    "SDM_SCAN_START",
    "SDM_STEPS_PER_MODE_PERIOD",
    "SdmResult",
    "floquet_multipliers",
    "recommended_samples",
    "sdm_lobes",
    "sdm_margin",
]

#: Default minimum number of steps per tooth period [-] ...
SDM_DEFAULT_STEPS = 40
#: ... raised to resolve the highest natural frequency with this many steps
#: per period (long tooth periods at low speeds) [-] ...
SDM_STEPS_PER_MODE_PERIOD = 24
#: ... but not beyond this [-]. With these defaults the boundary moves by
#: < 1 % when the steps are doubled on the benchmarks (tests), provided the
#: samples resolve the cut (next constant).
SDM_MAX_STEPS = 160
#: Intermittent cuts: sample ``H`` so that the engaged part of the tooth
#: period spans at least this many samples (resampling cannot add what the
#: samples miss); see :func:`recommended_samples` [-].
SDM_MIN_SAMPLES_IN_CUT = 12
#: The scan in ``s`` starts at this fraction of the ZOA critical margin [-] ...
SDM_SCAN_START = 0.25
#: ... and multiplies ``s`` by this per step [-] ...
SDM_SCAN_FACTOR = 1.3
#: ... up to this many times the start (then the margin is taken as inf) [-].
SDM_SCAN_MAX = 1e4
#: Relative tolerance of the margin [-].
SDM_RTOL = 1e-3
#: A critical multiplier within this angle [rad] of the real axis is a fold (+1)
#: or a flip (-1); otherwise a Hopf pair.
KIND_ANGLE_TOL = 1e-6


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
    """Samples of ``H`` per tooth period for a cut engaged over ``cut_fraction`` of it.

    ``max(SDM_DEFAULT_STEPS, ceil(SDM_MIN_SAMPLES_IN_CUT / cut_fraction))``; e.g.
    2 teeth at a/D = 0.05 (engaged 14 % of the tooth period) need 84. With
    fewer, the boundary of a low-immersion (flip) lobe is off by a few
    percent (tests: 2 % at 40 samples where 84 give 0.3 %).

    Parameters
    ----------
    cut_fraction : float
        Fraction of the tooth period during which ``H`` is non-zero, in (0, 1].
    """
    if isinstance(cut_fraction, (bool, np.bool_)) or not isinstance(cut_fraction, numbers.Real) \
            or not (0.0 < float(cut_fraction) <= 1.0):
        raise ValueError(f"cut_fraction: expected a value in (0, 1], got {cut_fraction!r}")
    return max(SDM_DEFAULT_STEPS, math.ceil(SDM_MIN_SAMPLES_IN_CUT / float(cut_fraction)))


# ---------------------------------------------------------------------- kernel
@njit(cache=True)
def _monodromy(phi0, ga, gb, u, s, cmat, out):
    """Monodromy matrix of the full-discretization map (see module docstring).

    ``phi0`` (2m, 2m), ``ga``/``gb`` (2m, m), ``u`` (k, m, m) = M^-1 D^T H_i D,
    ``s`` the scaling, ``cmat`` (m, 2m) = [I, R]: the modal displacement
    ``xi = eta + R eta'`` whose delay drives the cut; ``out`` (N, N), N = (k + 2) m.
    """
    k, m = u.shape[0], u.shape[1]
    n2 = 2 * m
    nn = n2 + k * m
    x = np.zeros((n2, nn))
    for i in range(n2):
        x[i, i] = 1.0
    hist = np.zeros((2 * k, m, nn))               # xi_j at index j + k, j = -k .. k-1
    for lag in range(1, k + 1):                   # xi_{-lag} = unit block
        for a in range(m):
            hist[k - lag, a, n2 + (lag - 1) * m + a] = 1.0
    hist[k] = cmat @ x
    eye = np.eye(n2)
    for i in range(k):
        ui = s * u[i]
        ui1 = s * u[(i + 1) % k]
        d = cmat @ x - hist[i]
        rhs = phi0 @ x + ga @ (ui @ d) - gb @ (ui1 @ hist[i + 1])
        lmat = eye - gb @ ui1 @ cmat
        x = np.ascontiguousarray(np.linalg.solve(lmat, rhs))
        if i + 1 < k:
            hist[i + 1 + k] = cmat @ x
    out[:n2] = x
    for j in range(k):                            # rows: xi_{k-1}, ..., xi_0
        out[n2 + j * m:n2 + (j + 1) * m] = hist[2 * k - 1 - j]


# ---------------------------------------------------------------------- setup
def _check_samples(h: Any) -> np.ndarray:
    a = np.asarray(h, dtype=float)
    if a.ndim != 3 or a.shape[1:] != (3, 3) or a.shape[0] < 2:
        raise ValueError(f"H_samples: expected shape (k, 3, 3) with k >= 2, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError("H_samples: expected finite values")
    return a


def _resample(h: np.ndarray, steps: int) -> np.ndarray:
    """Periodic piecewise-linear resampling of node values to ``steps`` nodes."""
    k = h.shape[0]
    if steps == k:
        return h
    t = np.arange(steps) * k / steps
    i0 = np.floor(t).astype(int)
    f = (t - i0)[:, None, None]
    return (1.0 - f) * h[i0 % k] + f * h[(i0 + 1) % k]


def _steps(steps: Any, k: int, system: ModalSystem, tau: float) -> int:
    if steps is None:
        fmax = float(system.natural_frequency_rad_s.max()) / (2.0 * math.pi)
        need = math.ceil(SDM_STEPS_PER_MODE_PERIOD * tau * fmax)
        return max(k, SDM_DEFAULT_STEPS, min(need, SDM_MAX_STEPS))
    if isinstance(steps, (bool, np.bool_)) or not isinstance(steps, numbers.Integral) \
            or steps < 2:
        raise ValueError(f"steps: expected an integer >= 2, got {steps!r}")
    return int(steps)




class _Fdm:
    """Precomputed full-discretization data of one (H, system, speed)."""

    def __init__(self, h: np.ndarray, system: ModalSystem, tau: float) -> None:
        m = system.n_modes
        k = h.shape[0]
        d = system.shape_matrix                                   # (3, m)
        w = np.einsum("ai,kab,bj->kij", d, h, d)                  # D^T H D
        self.u = np.ascontiguousarray(w / system.m_kg[None, :, None])
        dt = tau / k
        a0 = system.state_matrix()
        big = np.zeros((4 * m, 4 * m))
        big[:2 * m, :2 * m] = a0
        big[m:2 * m, 2 * m:3 * m] = np.eye(m)                     # B = [0; I]
        big[2 * m:3 * m, 3 * m:] = np.eye(m)
        e = scipy.linalg.expm(big * dt)
        self.phi0 = np.ascontiguousarray(e[:2 * m, :2 * m])
        g0b = e[:2 * m, 2 * m:3 * m]                              # Gamma0 B
        g1b = e[:2 * m, 3 * m:] / dt                              # Gamma1 B / dt
        self.ga = np.ascontiguousarray(g0b - g1b)
        self.gb = np.ascontiguousarray(g1b)
        self.cmat = np.ascontiguousarray(np.hstack([np.eye(m), np.diag(system.velocity_s)]))
        self.n = (k + 2) * m
        self._out = np.zeros((self.n, self.n))
        self.evaluations = 0

    def multipliers(self, s: float) -> np.ndarray:
        _monodromy(self.phi0, self.ga, self.gb, self.u, float(s), self.cmat, self._out)
        self.evaluations += 1
        mu = scipy.linalg.eigvals(self._out, check_finite=False, overwrite_a=False)
        return mu[np.argsort(-np.abs(mu))]

    def rho(self, s: float) -> float:
        _monodromy(self.phi0, self.ga, self.gb, self.u, float(s), self.cmat, self._out)
        self.evaluations += 1
        return float(np.max(np.abs(scipy.linalg.eigvals(self._out, check_finite=False))))


def _prepare(H_samples: Any, system: Any, spindle_rpm: Any, teeth: Any,
             steps: Any) -> tuple[_Fdm, np.ndarray]:
    h = _check_samples(H_samples)
    if not isinstance(system, ModalSystem):
        raise TypeError(f"system: expected an orient.dynamics.ModalSystem, got "
                        f"{type(system).__name__}")
    rpm = _positive("spindle_rpm", spindle_rpm)
    tau = 60.0 / (rpm * _teeth(teeth))
    hs = _resample(h, _steps(steps, h.shape[0], system, tau))
    return _Fdm(hs, system, tau), hs


def floquet_multipliers(H_samples: Any, system: ModalSystem, spindle_rpm: float, teeth: int,
                        scale: float = 1.0, steps: int | None = None) -> np.ndarray:
    """Floquet multipliers of the discretized cut, sorted by decreasing modulus.

    Parameters
    ----------
    H_samples : array_like, shape (k, 3, 3) [N/m]
        Directional matrix at the nodes ``t_i = i tau / k`` of one tooth period.
    system : ModalSystem
        Relative dynamics.
    spindle_rpm : float [rev/min]
        Spindle speed, > 0.
    teeth : int
        Number of teeth (``tau = 60 / (spindle_rpm teeth)``).
    scale : float [-]
        The process scaling ``s`` (>= 0).
    steps : int, optional
        Steps per tooth period; default ``max(k, SDM_DEFAULT_STEPS,
        min(SDM_STEPS_PER_MODE_PERIOD tau f_max, SDM_MAX_STEPS))`` with
        ``f_max`` the highest natural frequency [Hz]. Samples are resampled
        (periodic, piecewise linear between nodes) when it differs from k.

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
    kz = float(np.min(system.k_N_m * np.maximum(system.damping_ratio, 1e-3)))
    return SDM_SCAN_START * kz / gain


def _margin(fdm: _Fdm, s0: float, rtol: float) -> SdmResult:
    if not math.isfinite(s0):
        return SdmResult(math.inf, complex(math.nan, math.nan), "none")
    lo, hi = 0.0, s0
    r = fdm.rho(hi)
    if r >= 1.0:                      # already unstable at the start: scan downward
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
    if lo > 0.0:
        s = brentq(lambda x: math.log(fdm.rho(x)), lo, hi, rtol=rtol, xtol=1e-300)
    else:
        s = brentq(lambda x: fdm.rho(x) - 1.0, lo, hi, rtol=rtol, xtol=1e-300)
    mu = fdm.multipliers(s * (1.0 + 2.0 * rtol))[0]
    return SdmResult(float(s), complex(mu), _kind(mu))


def sdm_margin(H_samples: Any, system: ModalSystem, spindle_rpm: float, teeth: int, *,
               steps: int | None = None, s_start: float | None = None,
               rtol: float = SDM_RTOL) -> SdmResult:
    """Time-periodic stability margin at one spindle speed.

    Parameters
    ----------
    H_samples : array_like, shape (k, 3, 3) [N/m]
        Directional matrix at the nodes ``t_i = i tau / k`` (see module doc).
    system : ModalSystem
        Relative dynamics.
    spindle_rpm : float [rev/min]
        Spindle speed, > 0.
    teeth : int
        Number of teeth.
    steps : int, optional
        Steps per tooth period; default as in :func:`floquet_multipliers`.
    s_start : float, optional
        Where the upward scan in ``s`` starts [-]; default
        ``SDM_SCAN_START`` times the ZOA critical margin of ``mean(H)``.
        Unstable regions below it are not searched.
    rtol : float
        Relative tolerance of the margin [-].

    Returns
    -------
    SdmResult
        ``margin`` (inf for a zero-gain process), the critical multiplier
        and its kind.
    """
    fdm, hs = _prepare(H_samples, system, spindle_rpm, teeth, steps)
    s0 = _scan_start(hs, system) if s_start is None else _positive("s_start", s_start)
    return _margin(fdm, s0, _positive("rtol", rtol))


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
