"""Zero-order (average process gain) stability analysis (``docs/method.md`` §7).

Model (the contract of orient's stability code): relative displacement
``q`` (tool minus workpiece, workpiece frame, metres), regenerative force on
the tool ``F = s H(t) (q(t) - q(t - tau))`` with ``P = mean H`` [N/m],
``q = G(i w) F``. The zero-order characteristic equation is

    ``det(I - s (1 - exp(-i w tau)) P G(i w)) = 0``.

With ``lambda`` an eigenvalue of ``P G(i w)`` and ``Lambda = 1/lambda =
L_R + i L_I`` the boundary scaling is ``s = (L_R/2)(1 + (L_I/L_R)^2) =
1 / (2 Re lambda)`` (only positive ``s`` are physical) and the phase
condition is ``w tau = pi + 2 arg(lambda) + 2 pi k``, ``k = 0, 1, 2, ...``
(``1 - exp(-i w tau)`` has the phase of ``Lambda``).

``docs/method.md`` writes the scaling with a minus sign,
``-(Lambda_R/2)(1 + ...)``, because its texts (Altintas & Budak 1995) define
the directional matrix with the opposite sign (their ``Lambda`` is minus
ours). Here ``H`` and ``P`` are "negative" (a thicker chip pushes the tool
back), e.g. 1-DOF slotting ``P_xx = -depth Kn / 2``; the tests check the
result against the Altintas & Budak closed form.

The *margin* is the smallest positive ``s`` on the boundary: > 1 stable.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np

from errpred.spindle import tooth_period
from nc.checks import real_number, whole_number
from orient.dynamics import ModalSystem
from orient.stability import _kernels as _k
from orient.constants import (
    DIRECTION_TOL,
    GROUP_PARALLEL_TOL,
    ORTHONORMAL_TOL,
    ZOA_BAND_HALF_WIDTH,
    ZOA_BAND_POINTS,
    ZOA_GLOBAL_POINTS,
    ZOA_GLOBAL_RANGE,
    ZOA_MIN_ZETA,
    ZOA_NEAR_HALF_WIDTH,
    ZOA_NEAR_POINTS,
    ZOA_PARALLEL_MIN_POSTURES,
    ZOA_THIN_FRACTION,
)

__all__ = [
    "ZOA_BAND_HALF_WIDTH",
    "ZOA_BAND_POINTS",
    "ZOA_GLOBAL_POINTS",
    "ZOA_GLOBAL_RANGE",
    "ZOA_MIN_ZETA",
    "ZOA_NEAR_HALF_WIDTH",
    "ZOA_NEAR_POINTS",
    "ZoaCritical",
    "ZoaMargin",
    "zoa_critical",
    "zoa_frequency_grid",
    "zoa_lobes",
    "zoa_margin",
    "zoa_margin_batch",
    "zoa_margin_detail",
]


# ---------------------------------------------------------------------- validation
def _matrix3(name: str, value: Any) -> np.ndarray:
    a = np.asarray(value, dtype=float)
    if a.shape != (3, 3):
        raise ValueError(f"{name}: expected shape (3, 3), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: expected finite values, got {a.tolist()}")
    return a


def _positive(name: str, value: Any) -> float:
    return real_number(name, value, ">0")


def _teeth(value: Any) -> int:
    return whole_number("teeth", value, 1)


def _system(value: Any) -> ModalSystem:
    if not isinstance(value, ModalSystem):
        raise TypeError(f"system: expected an orient.dynamics.ModalSystem, got "
                        f"{type(value).__name__}")
    return value


def _restrict(p: np.ndarray, restrict: Any) -> np.ndarray:
    """``E E^T P E E^T`` for directions ``E`` (3, d) with orthonormal columns."""
    if restrict is None:
        return p
    e = np.asarray(restrict, dtype=float)
    if e.ndim == 1:
        e = e[:, None]
    if e.ndim != 2 or e.shape[0] != 3 or not 1 <= e.shape[1] <= 3 or not np.all(np.isfinite(e)):
        raise ValueError(f"restrict: expected finite directions of shape (3, d), d in 1..3, "
                         f"got shape {e.shape}")
    if not np.allclose(e.T @ e, np.eye(e.shape[1]), atol=ORTHONORMAL_TOL):
        raise ValueError("restrict: the columns must be orthonormal")
    pr = e @ e.T
    return pr @ p @ pr


def _omega_grid(system: ModalSystem, omega_rad_s: Any) -> np.ndarray:
    if omega_rad_s is None:
        return zoa_frequency_grid(system)
    w = np.asarray(omega_rad_s, dtype=float).reshape(-1)
    if w.size < 2 or not np.all(np.isfinite(w)) or np.any(w <= 0) or np.any(np.diff(w) <= 0):
        raise ValueError("omega_rad_s: expected >= 2 finite, positive, strictly increasing "
                         "chatter frequencies [rad/s]")
    return w


def _tau(spindle_rpm: float, teeth: int) -> float:
    return tooth_period(spindle_rpm, teeth)


# ---------------------------------------------------------------------- groups
def _groups(system: ModalSystem) -> tuple[np.ndarray, np.ndarray]:
    """Direction groups: (group index per mode (n,), first mode of each group (ng,)).

    Modes group when they share a direction and a source: tool modes turn with the
    tool axis and workpiece modes do not, so a tool and a workpiece mode that happen
    to be parallel in ``system`` stay apart (they part when the axis changes).
    """
    d = system.direction
    src = system.source
    group = np.full(d.shape[0], -1, dtype=np.int64)
    first: list[int] = []
    for i in range(d.shape[0]):
        for gi, f in enumerate(first):
            if src[i] == src[f] and abs(float(d[i] @ d[f])) > GROUP_PARALLEL_TOL:
                group[i] = gi
                break
        else:
            group[i] = len(first)
            first.append(i)
    return group, np.array(first, dtype=np.int64)


def _setup(system: ModalSystem, omega: np.ndarray):
    group, first = _groups(system)
    ng = first.size
    rec = system.modal_receptance(omega)                          # (nw, n)
    gw = np.zeros((omega.size, ng), dtype=complex)
    for i in range(group.size):
        gw[:, group[i]] += rec[:, i]
    return (group, first, np.ascontiguousarray(gw), np.ascontiguousarray(system.k_N_m),
            np.ascontiguousarray(system.m_kg), np.ascontiguousarray(system.c_Ns_m),
            np.ascontiguousarray(system.velocity_s))


def _required_step(w: np.ndarray, wn: np.ndarray, near: np.ndarray,
                   global_ratio: float) -> np.ndarray:
    """Finest grid step [rad/s] any band asks for at each frequency of ``w``."""
    h = w * (global_ratio - 1.0)
    for wm, hw in zip(wn, near, strict=True):
        rel = np.abs(w / wm - 1.0)
        h = np.where(rel <= ZOA_BAND_HALF_WIDTH,
                     np.minimum(h, wm * 2.0 * ZOA_BAND_HALF_WIDTH / (ZOA_BAND_POINTS - 1)), h)
        h = np.where(rel <= hw, np.minimum(h, wm * 2.0 * hw / (ZOA_NEAR_POINTS - 1)), h)
    return h


def zoa_frequency_grid(system: ModalSystem) -> np.ndarray:
    """Default chatter-frequency grid [rad/s], sorted, built from the modes.

    Per mode: ``ZOA_NEAR_POINTS`` points over ``wn (1 +- ZOA_NEAR_HALF_WIDTH zeta)``
    and ``ZOA_BAND_POINTS`` over ``wn (1 +- ZOA_BAND_HALF_WIDTH)``; plus
    ``ZOA_GLOBAL_POINTS`` log-spaced points over ``ZOA_GLOBAL_RANGE`` times the
    lowest and highest natural frequency. Where bands overlap, the union is
    thinned so that no step is below ``ZOA_THIN_FRACTION`` of the finest step
    a band asks for there (each band's own spacing is kept).
    """
    system = _system(system)
    return _grid(tuple(system.natural_frequency_rad_s.tolist()),
                 tuple(system.damping_ratio.tolist()))


@functools.lru_cache(maxsize=256)
def _grid(wn_t: tuple, zeta_t: tuple) -> np.ndarray:
    """:func:`zoa_frequency_grid` of given natural frequencies and damping ratios,
    cached (a planner asks for the same modes at many points); read-only."""
    wn = np.array(wn_t)
    zeta = np.maximum(np.array(zeta_t), ZOA_MIN_ZETA)
    lo, hi = ZOA_GLOBAL_RANGE[0] * wn.min(), ZOA_GLOBAL_RANGE[1] * wn.max()
    parts = [np.geomspace(lo, hi, ZOA_GLOBAL_POINTS)]
    near = np.minimum(ZOA_NEAR_HALF_WIDTH * zeta, 0.9)
    u_near = np.linspace(-1.0, 1.0, ZOA_NEAR_POINTS)
    u_band = np.linspace(-1.0, 1.0, ZOA_BAND_POINTS)
    for w, hw in zip(wn, near, strict=True):
        parts.append(w * (1.0 + hw * u_near))
        parts.append(w * (1.0 + ZOA_BAND_HALF_WIDTH * u_band))
    grid = np.unique(np.concatenate(parts))
    grid = grid[grid > 0]
    ratio = (hi / lo) ** (1.0 / (ZOA_GLOBAL_POINTS - 1))
    min_step = ZOA_THIN_FRACTION * _required_step(grid, wn, near, ratio)
    keep = np.zeros(grid.size, dtype=bool)
    last = -np.inf
    for i, w in enumerate(grid):                 # greedy, in order; ends always kept
        if w - last >= min_step[i] or i == grid.size - 1:
            keep[i] = True
            last = w
    grid = grid[keep]
    grid.flags.writeable = False
    return grid


# ---------------------------------------------------------------------- API
@dataclass(frozen=True)
class ZoaCritical:
    """Speed-independent ZOA result.

    Attributes
    ----------
    margin : float
        ``min over w of 1 / (2 max Re lambda(w))`` [-] (inf if no eigenvalue
        ever has a positive real part): the lowest point of the lobes.
    omega_rad_s : float
        Chatter frequency at that minimum [rad/s] (nan if margin is inf).
    omega_grid : ndarray, shape (w,)
        The frequency grid [rad/s].
    s_curve : ndarray, shape (w,)
        Boundary scaling per grid frequency [-] (inf where none is positive).
    """

    margin: float
    omega_rad_s: float
    omega_grid: np.ndarray
    s_curve: np.ndarray


@dataclass(frozen=True)
class ZoaMargin:
    """ZOA margin at one spindle speed: ``margin`` [-] and ``omega_rad_s`` the
    chatter frequency of the critical crossing [rad/s] (nan if none)."""

    margin: float
    omega_rad_s: float


def zoa_critical(P: Any, system: ModalSystem, omega_rad_s: Any = None, *,
                 restrict: Any = None) -> ZoaCritical:
    """Speed-independent (critical) ZOA margin.

    Parameters
    ----------
    P : array_like, shape (3, 3) [N/m]
        Average process gain matrix (workpiece frame, contract sign).
    system : ModalSystem
        Relative dynamics.
    omega_rad_s : array_like, shape (w,), optional
        Chatter-frequency grid [rad/s]; default :func:`zoa_frequency_grid`.
        The grid maximum of ``Re lambda`` is refined by golden-section search.
    restrict : array_like, shape (3, d), optional
        Orthonormal directions ``E``: analyse ``E E^T P E E^T`` (force and
        vibration restricted to span(E)).
    """
    p = _restrict(_matrix3("P", P), restrict)
    system = _system(system)
    w = _omega_grid(system, omega_rad_s)
    group, first, gw, mk, mm, mc, mr = _setup(system, w)
    d = system.direction[first]
    q = d @ p @ d.T
    curve = np.empty(w.size)
    s, wc = _k.critical_one(np.ascontiguousarray(q), w, gw, mk, mm, mc, mr, group, curve)
    return ZoaCritical(float(s), float(wc), w, curve)


def zoa_margin_detail(P: Any, system: ModalSystem, spindle_rpm: float, teeth: int,
                      omega_rad_s: Any = None, *, restrict: Any = None) -> ZoaMargin:
    """ZOA margin and chatter frequency at one spindle speed; see :func:`zoa_margin`."""
    p = _restrict(_matrix3("P", P), restrict)
    system = _system(system)
    rpm = _positive("spindle_rpm", spindle_rpm)
    tau = _tau(rpm, _teeth(teeth))
    w = _omega_grid(system, omega_rad_s)
    group, first, gw, mk, mm, mc, mr = _setup(system, w)
    d = system.direction[first]
    q = np.ascontiguousarray(d @ p @ d.T)
    lam = np.empty((w.size, first.size), dtype=complex)
    s, wc = _k.margin_one(q, w, gw, tau, mk, mm, mc, mr, group, lam, 0.0)  # rmin: one version
    return ZoaMargin(float(s), float(wc))


def zoa_margin(P: Any, system: ModalSystem, spindle_rpm: float, teeth: int,
               omega_rad_s: Any = None, *, restrict: Any = None) -> float:
    """ZOA stability margin at a spindle speed.

    For each eigenvalue branch of ``P G(i w)`` over the frequency grid, the
    crossings of the phase condition ``w tau = pi + 2 arg(lambda) + 2 pi k`` are
    located (linear interpolation between grid points, then refined by
    root finding on the exact eigenvalues); the margin is the smallest
    ``s = 1 / (2 Re lambda) > 0`` among them.

    Parameters
    ----------
    P : array_like, shape (3, 3) [N/m]
        Average process gain matrix (contract sign: "negative").
    system : ModalSystem
        Relative dynamics.
    spindle_rpm : float [rev/min]
        Spindle speed, > 0.
    teeth : int
        Number of teeth (tooth period ``tau = 60 / (spindle_rpm teeth)`` [s]).
    omega_rad_s : array_like, shape (w,), optional
        Chatter-frequency grid [rad/s]; default :func:`zoa_frequency_grid`.
    restrict : array_like, shape (3, d), optional
        Orthonormal directions ``E``; see :func:`zoa_critical`.

    Returns
    -------
    float
        Margin [-]: > 1 stable, < 1 chatters; ``inf`` if no crossing.
    """
    return zoa_margin_detail(P, system, spindle_rpm, teeth, omega_rad_s,
                             restrict=restrict).margin


def zoa_lobes(P: Any, system: ModalSystem, teeth: int, rpm: Any, omega_rad_s: Any = None, *,
              restrict: Any = None) -> np.ndarray:
    """ZOA margins at many spindle speeds.

    Parameters
    ----------
    P : array_like, shape (3, 3) [N/m]
        Average process gain matrix.
    system : ModalSystem
        Relative dynamics.
    teeth : int
        Number of teeth.
    rpm : array_like, shape (r,) [rev/min]
        Spindle speeds, finite, > 0.
    omega_rad_s, restrict
        As in :func:`zoa_margin`.

    Returns
    -------
    ndarray, shape (r,)
        Margin per speed [-]; multiply by the depth of cut for the lobes.
    """
    p = _restrict(_matrix3("P", P), restrict)
    system = _system(system)
    n = _teeth(teeth)
    r = np.asarray(rpm, dtype=float).reshape(-1)
    if r.size == 0 or not np.all(np.isfinite(r)) or np.any(r <= 0):
        raise ValueError("rpm: expected finite spindle speeds > 0 [rev/min]")
    w = _omega_grid(system, omega_rad_s)
    group, first, gw, mk, mm, mc, mr = _setup(system, w)
    d = np.ascontiguousarray(system.direction[first])
    return _k.margin_speeds(np.ascontiguousarray(p), d, w, gw, tooth_period(r, n), mk, mm, mc,
                            mr, group)


def zoa_margin_batch(P: Any, system: ModalSystem, spindle_rpm: Any, teeth: int, *,
                     mode_directions: Any = None, omega_rad_s: Any = None,
                     cap: float | None = None, parallel: bool | None = None) -> np.ndarray:
    """ZOA margins of many postures at once (numba, parallel over postures when many).

    Parameters
    ----------
    P : array_like, shape (n, 3, 3) [N/m]
        Average process gain matrices, one per posture.
    system : ModalSystem
        Relative dynamics (moduli, damping; directions unless overridden).
    spindle_rpm : float or array_like, shape (n,) [rev/min]
        Spindle speed(s), > 0.
    teeth : int
        Number of teeth.
    mode_directions : array_like, shape (n, m, 3) or (m, 3), optional
        Per-posture directions of the system's ``m`` modes (e.g. from
        :meth:`ModalSystem.directions_for_axes` when the tool axis changes
        with the posture). Modes sharing a direction in ``system`` must
        share it here too.
    omega_rad_s : array_like, shape (w,), optional
        Chatter-frequency grid [rad/s]; default :func:`zoa_frequency_grid`.
    cap : float, optional
        Margins at or above ``cap`` (> 0) are returned as ``cap``; below it they
        are exact. Much faster when only ``min(margin, cap)`` matters (a
        planner's score): eigenvalues are computed only at frequencies where
        ``||Q diag(g)||_F >= 1 / (2 cap)``, a bound on their real parts.
    parallel : bool, optional
        Over numba's threads; default: from ``ZOA_PARALLEL_MIN_POSTURES`` postures on
        (below, launching the threads costs more than the margins). The same margins
        either way (the same loop body per posture).

    Returns
    -------
    ndarray, shape (n,)
        Margins [-] (inf where no crossing; at most ``cap``).
    """
    system = _system(system)
    p = np.asarray(P, dtype=float)
    if p.ndim != 3 or p.shape[1:] != (3, 3):
        raise ValueError(f"P: expected shape (n, 3, 3), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("P: expected finite values")
    n = _teeth(teeth)
    rpm = np.asarray(spindle_rpm, dtype=float).reshape(-1)
    if rpm.size not in (1, p.shape[0]) or not np.all(np.isfinite(rpm)) or np.any(rpm <= 0):
        raise ValueError(f"spindle_rpm: expected a finite value > 0 or {p.shape[0]} of them")
    w = _omega_grid(system, omega_rad_s)
    group, first, gw, mk, mm, mc, mr = _setup(system, w)
    if mode_directions is None:
        d = system.direction[first][None]
    else:
        md = np.asarray(mode_directions, dtype=float)
        if md.ndim == 2:
            md = md[None]
        if md.ndim != 3 or md.shape[1:] != (system.n_modes, 3) \
                or md.shape[0] not in (1, p.shape[0]) or not np.all(np.isfinite(md)):
            raise ValueError(f"mode_directions: expected finite shape ({p.shape[0]}, "
                             f"{system.n_modes}, 3), got {md.shape}")
        norms = np.linalg.norm(md, axis=2)
        if np.any(np.abs(norms - 1.0) > DIRECTION_TOL):
            raise ValueError("mode_directions: expected unit vectors")
        lead = md[:, first[group], :]
        if np.any(np.abs(np.sum(md * lead, axis=2)) < GROUP_PARALLEL_TOL - 1e-6):
            raise ValueError("mode_directions: modes that share a direction in system must "
                             "share it in every posture")
        d = md[:, first, :]
    taus = tooth_period(rpm, n)
    c = np.inf if cap is None else _positive("cap", cap)
    if parallel is None:
        parallel = p.shape[0] >= ZOA_PARALLEL_MIN_POSTURES
    kernel = _k.margin_batch if parallel else _k.margin_batch_serial
    return kernel(np.ascontiguousarray(p), np.ascontiguousarray(d), w, gw, taus, mk, mm, mc,
                  mr, group, c)
