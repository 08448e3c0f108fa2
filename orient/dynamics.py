"""Relative tool-workpiece dynamics with mode directions (``docs/method.md`` §5, §7).

A :class:`ModalSystem` is a set of modes, each acting along one unit
direction ``d_k`` of the workpiece frame. The relative compliance (tool
displacement minus workpiece displacement per unit force on the tool) is

    ``G(omega) = sum_k d_k d_k^T (1 + i omega r_k) / (k_k - m_k omega^2 + i c_k omega)``  [m/N]

with ``r_k = 0`` for real (proportionally damped) modes. A measured mode in
residue form ``(sigma + i nu) / (i omega - p) + conj``, ``p = -zeta wn + i wd``,
whose residue has a real part (non-proportional damping) has ``r_k != 0``
(:meth:`ModalSystem.from_residues`); in the time domain its contribution to
the displacement is ``eta + r eta'`` with ``m eta'' + c eta' + k eta = d . F``.

Tool modes and workpiece modes both add with a plus sign: the workpiece
receives ``-F`` and ``q`` subtracts its displacement.

Tool modes come from an :class:`errpred.dynamics.Compliance` measured with
the tool vertical (``'x'``, ``'y'``, ``'z'`` = machine X, Y, Z); for a tilted
tool axis ``u`` they are carried by the minimal rotation taking ``+Z`` to
``u`` (so bending stays perpendicular to the axis). The system remembers
that axis (:attr:`ModalSystem.tool_axis`) so that the tool modes can be
re-carried to other axes (:meth:`ModalSystem.with_tool_axis`,
:meth:`ModalSystem.directions_for_axes`).

Modal coordinates for the time-periodic analysis: ``q = D (eta + R eta')`` with
``D = direction.T`` (3, n), ``R = diag(r)`` and
``m_k eta_k'' + c_k eta_k' + k_k eta_k = d_k . F``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from errpred.dynamics import Compliance, Mode
from .constants import (
    ANTIPODAL_TOL,
    DIRECTION_TOL,
    FIT_MAX_MODES,
    FIT_MIN_ZETA,
    FIT_PEAK_FRACTION,
    ORTHONORMAL_TOL,
)

__all__ = [
    "DIRECTION_TOL",
    "SOURCES",
    "ModalSystem",
    "fit_modes",
    "minimal_rotation",
]

#: Allowed mode sources.
SOURCES = ("tool", "workpiece")
#: Unit vectors of the compliance directions of a vertical tool.
_AXIS_UNIT = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


def _finite_array(name: str, value: Any, shape_tail: tuple[int, ...] = ()) -> np.ndarray:
    a = np.array(value, dtype=float)
    if a.ndim != 1 + len(shape_tail) or a.shape[1:] != shape_tail:
        want = "(n" + "".join(f", {s}" for s in shape_tail) + ")"
        raise ValueError(f"{name}: expected shape {want}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: expected finite values, got {a!r}")
    return a


def _unit_vector(name: str, value: Any) -> np.ndarray:
    v = np.asarray(value, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name}: expected a finite 3-vector, got {value!r}")
    n = float(np.linalg.norm(v))
    if n == 0.0:
        raise ValueError(f"{name}: expected a non-zero vector, got {value!r}")
    return v / n


def minimal_rotation(axis: Any) -> np.ndarray:
    """Rotation matrix taking ``+Z`` to ``axis`` about ``Z x axis`` (the minimal one).

    Parameters
    ----------
    axis : array_like, shape (3,) or (p, 3)
        Tool axes (normalized here); must not point along ``-Z``.

    Returns
    -------
    ndarray, shape (3, 3) or (p, 3, 3)
        ``R`` with ``R @ (0, 0, 1) = axis``; ``R = I + [v]x + [v]x^2 / (1 + c)``
        with ``v = Z x axis``, ``c = axis_z``.
    """
    u = np.asarray(axis, dtype=float)
    single = u.ndim == 1
    u = u.reshape(-1, 3)
    if not np.all(np.isfinite(u)):
        raise ValueError("axis: expected finite values")
    n = np.linalg.norm(u, axis=1)
    if np.any(n == 0.0):
        raise ValueError("axis: expected non-zero vectors")
    u = u / n[:, None]
    c = u[:, 2]
    if np.any(c <= -1.0 + ANTIPODAL_TOL):
        raise ValueError("axis: a tool axis along -Z has no minimal rotation from +Z")
    vx, vy = -u[:, 1], u[:, 0]
    vx_ = np.zeros((u.shape[0], 3, 3))
    vx_[:, 0, 2], vx_[:, 1, 2] = vy, -vx
    vx_[:, 2, 0], vx_[:, 2, 1] = -vy, vx
    r = np.eye(3)[None] + vx_ + (vx_ @ vx_) / (1.0 + c)[:, None, None]
    return r[0] if single else r


@dataclass(frozen=True, eq=False)
class ModalSystem:
    """Modes of the relative tool-workpiece dynamics, with directions.

    Attributes
    ----------
    k_N_m : ndarray, shape (n,)
        Modal stiffness [N/m], > 0.
    m_kg : ndarray, shape (n,)
        Modal mass [kg], > 0.
    c_Ns_m : ndarray, shape (n,)
        Modal viscous damping [N s/m], >= 0.
    direction : ndarray, shape (n, 3)
        Unit mode directions in the workpiece frame [-].
    source : ndarray of str, shape (n,)
        ``'tool'`` or ``'workpiece'`` per mode.
    tool_axis : ndarray, shape (3,)
        The tool axis to which the tool modes are currently carried (unit,
        default ``+Z``); the tool modes at a vertical axis are
        ``minimal_rotation(tool_axis).T @ direction``.
    velocity_s : ndarray, shape (n,)
        ``r_k`` [s]: the velocity share of each mode's displacement (0 for real
        modes; default all 0).

    All arrays are read-only copies. Build with :meth:`from_modes`,
    :meth:`tool`, :meth:`combine`, or directly from arrays.
    """

    k_N_m: np.ndarray
    m_kg: np.ndarray
    c_Ns_m: np.ndarray
    direction: np.ndarray
    source: np.ndarray
    tool_axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    velocity_s: np.ndarray | None = None

    def __post_init__(self) -> None:
        k = _finite_array("ModalSystem.k_N_m", self.k_N_m)
        n = k.shape[0]
        m = _finite_array("ModalSystem.m_kg", self.m_kg)
        c = _finite_array("ModalSystem.c_Ns_m", self.c_Ns_m)
        d = _finite_array("ModalSystem.direction", self.direction, (3,))
        src = np.array(self.source, dtype=str).reshape(-1)
        for name, a in (("m_kg", m), ("c_Ns_m", c), ("direction", d), ("source", src)):
            if a.shape[0] != n:
                raise ValueError(f"ModalSystem.{name}: expected {n} entries (one per mode), "
                                 f"got {a.shape[0]}")
        if n == 0:
            raise ValueError("ModalSystem: expected at least one mode")
        if np.any(k <= 0) or np.any(m <= 0) or np.any(c < 0):
            raise ValueError("ModalSystem: need k_N_m > 0, m_kg > 0 and c_Ns_m >= 0 for every "
                             f"mode, got k={k}, m={m}, c={c}")
        norms = np.linalg.norm(d, axis=1)
        if np.any(np.abs(norms - 1.0) > DIRECTION_TOL):
            raise ValueError(f"ModalSystem.direction: expected unit vectors, got norms {norms}")
        bad = [s for s in src if s not in SOURCES]
        if bad:
            raise ValueError(f"ModalSystem.source: expected labels in {SOURCES}, got {bad}")
        axis = _unit_vector("ModalSystem.tool_axis", self.tool_axis)
        r = np.zeros(n) if self.velocity_s is None else \
            _finite_array("ModalSystem.velocity_s", self.velocity_s)
        if r.shape[0] != n:
            raise ValueError(f"ModalSystem.velocity_s: expected {n} entries (one per mode), "
                             f"got {r.shape[0]}")
        for name, a in (("k_N_m", k), ("m_kg", m), ("c_Ns_m", c),
                        ("direction", d / norms[:, None]), ("source", src), ("tool_axis", axis),
                        ("velocity_s", r)):
            a = np.array(a)
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    def __setstate__(self, state: dict) -> None:
        """Unpickled (on a Dask worker, or back from one): the arrays read-only again, as
        built, so that the numba kernels see the same array types (and reuse their
        compiled, cached code) in every process."""
        for name, a in state.items():
            if isinstance(a, np.ndarray):
                a.setflags(write=False)
            object.__setattr__(self, name, a)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_modes(cls, pairs: Iterable[tuple[Mode, Any]], *,
                   source: str = "workpiece") -> ModalSystem:
        """System from ``(Mode, direction)`` pairs.

        Parameters
        ----------
        pairs : iterable of (errpred.dynamics.Mode, array_like shape (3,))
            Modes and their directions in the workpiece frame (normalized here).
        source : str
            ``'tool'`` or ``'workpiece'`` for all of them. Tool modes given
            this way are taken as carried to ``tool_axis = +Z``.
        """
        pairs = list(pairs)
        if not pairs:
            raise ValueError("ModalSystem.from_modes: pairs: expected at least one (Mode, "
                             "direction) pair")
        rows = []
        for i, p in enumerate(pairs):
            if len(p) != 2 or not isinstance(p[0], Mode):
                raise ValueError(f"ModalSystem.from_modes: pairs[{i}]: expected (Mode, "
                                 f"direction), got {p!r}")
            rows.append((p[0], _unit_vector(f"ModalSystem.from_modes: pairs[{i}] direction",
                                            p[1])))
        return cls(np.array([m.k_N_m for m, _ in rows]), np.array([m.m_kg for m, _ in rows]),
                   np.array([m.c_Ns_m for m, _ in rows]), np.array([d for _, d in rows]),
                   np.array([source] * len(rows)))

    @classmethod
    def from_residues(cls, frequency_hz: Any, damping_ratio: Any, residue_m_N: Any,
                      direction: Any, *, source: str = "tool") -> ModalSystem:
        """Modes from a measured FRF's modal parameters in residue form.

        Each mode contributes ``R / (i w - p) + conj(R) / (i w - conj(p))``, with
        ``p = -zeta wn + i wd``, ``wd = wn sqrt(1 - zeta^2)``, ``R = sigma + i nu``
        [m/(N s)], along its direction. That is
        ``(alpha + i beta w) / (wn^2 - w^2 + 2 i zeta wn w)`` with
        ``alpha = 2 (zeta wn sigma - wd nu)`` and ``beta = 2 sigma``, i.e. a mode
        with ``m = 1/alpha``, ``k = wn^2 m``, ``c = 2 zeta wn m`` and
        ``r = beta / alpha``. ``alpha`` must be > 0.

        Parameters
        ----------
        frequency_hz, damping_ratio : array_like, shape (n,) [Hz, -]
        residue_m_N : array_like complex, shape (n,) [m/(N s)]
        direction : array_like, shape (n, 3) [-]
        source : str
        """
        f = _finite_array("from_residues: frequency_hz", frequency_hz)
        z = _finite_array("from_residues: damping_ratio", damping_ratio)
        res = np.asarray(residue_m_N, dtype=complex).reshape(-1)
        d = _finite_array("from_residues: direction", direction, (3,))
        if not (f.shape == z.shape == res.shape and d.shape[0] == f.shape[0]):
            raise ValueError("from_residues: expected one frequency, damping ratio, residue "
                             "and direction per mode")
        if np.any(f <= 0) or np.any(z < 0) or np.any(z >= 1) or not np.all(np.isfinite(res)):
            raise ValueError("from_residues: need frequency_hz > 0, 0 <= damping_ratio < 1 and "
                             "finite residues")
        wn = 2.0 * math.pi * f
        wd = wn * np.sqrt(1.0 - z * z)
        alpha = 2.0 * (z * wn * res.real - wd * res.imag)
        beta = 2.0 * res.real
        if np.any(alpha <= 0):
            raise ValueError(f"from_residues: modes {np.flatnonzero(alpha <= 0).tolist()} have "
                             f"no positive modal flexibility (alpha <= 0)")
        m = 1.0 / alpha
        return cls(wn * wn * m, m, 2.0 * z * wn * m,
                   d / np.linalg.norm(d, axis=1)[:, None], np.array([source] * f.size),
                   velocity_s=beta / alpha)

    @classmethod
    def tool(cls, compliance: Compliance, axis: Any = (0.0, 0.0, 1.0), *,
             fit: bool = False) -> ModalSystem:
        """Tool modes from a tool-tip compliance, carried to the tool axis ``axis``.

        Parameters
        ----------
        compliance : errpred.dynamics.Compliance
            Modal compliance measured with the tool vertical: direction
            ``'x'``/``'y'``/``'z'`` is machine X/Y/Z.
        axis : array_like, shape (3,)
            Tool axis ``u`` in the workpiece frame (unit, not along -Z).
            Each mode direction is ``minimal_rotation(u) @ e_dir``.
        fit : bool
            For a measured-FRF compliance: fit modes with :func:`fit_modes`
            (peak picking and least squares) instead of refusing it.

        Raises
        ------
        ValueError
            Static-only compliance (no dynamics), or a measured FRF without
            ``fit=True``.
        """
        if not isinstance(compliance, Compliance):
            raise TypeError(f"ModalSystem.tool: compliance: expected an errpred.dynamics."
                            f"Compliance, got {type(compliance).__name__}")
        if compliance.kind == "static":
            raise ValueError("ModalSystem.tool: compliance is static-only (no dynamics); "
                             "chatter analysis needs modes")
        if compliance.kind == "measured":
            if not fit:
                raise ValueError("ModalSystem.tool: compliance is a measured FRF; pass fit=True "
                                 "to fit modes to it (fit_modes) or build it from modes")
            modes = {}
            for d in compliance.directions:
                f = compliance._freq[d]   # its measured grid (no public accessor)
                g = compliance.response(2.0 * math.pi * f)[:, compliance.directions.index(d)]
                modes[d] = fit_modes(f, g)
        else:
            modes = compliance.modes
        u = _unit_vector("ModalSystem.tool: axis", axis)
        rot = minimal_rotation(u)
        pairs = [(mode, rot @ np.array(_AXIS_UNIT[d])) for d in compliance.directions
                 for mode in modes[d]]
        sys0 = cls.from_modes(pairs, source="tool")
        return cls(sys0.k_N_m, sys0.m_kg, sys0.c_Ns_m, sys0.direction, sys0.source, u)

    @classmethod
    def combine(cls, *systems: ModalSystem) -> ModalSystem:
        """All modes of ``systems`` in one system (tool and workpiece modes add).

        Systems holding tool modes must share their tool axis.
        """
        if not systems or not all(isinstance(s, ModalSystem) for s in systems):
            raise ValueError("ModalSystem.combine: expected one or more ModalSystem")
        with_tool = [s for s in systems if np.any(s.source == "tool")]
        axis = with_tool[0].tool_axis if with_tool else np.array([0.0, 0.0, 1.0])
        for s in with_tool[1:]:
            if not np.allclose(s.tool_axis, axis, atol=1e-12):
                raise ValueError(f"ModalSystem.combine: tool modes carried to different tool "
                                 f"axes {axis} and {s.tool_axis}")
        cat = [np.concatenate([getattr(s, a) for s in systems])
               for a in ("k_N_m", "m_kg", "c_Ns_m", "direction", "source", "velocity_s")]
        return cls(*cat[:5], tool_axis=axis, velocity_s=cat[5])

    # ------------------------------------------------------------------ properties
    @property
    def n_modes(self) -> int:
        """Number of modes."""
        return int(self.k_N_m.shape[0])

    @property
    def natural_frequency_rad_s(self) -> np.ndarray:
        """Undamped natural frequencies ``sqrt(k/m)`` [rad/s], shape (n,)."""
        return np.sqrt(self.k_N_m / self.m_kg)

    @property
    def damping_ratio(self) -> np.ndarray:
        """Damping ratios ``c / (2 sqrt(k m))`` [-], shape (n,)."""
        return self.c_Ns_m / (2.0 * np.sqrt(self.k_N_m * self.m_kg))

    @property
    def shape_matrix(self) -> np.ndarray:
        """``D = direction.T`` [-], shape (3, n): ``q = D eta``."""
        return self.direction.T.copy()

    # ------------------------------------------------------------------ re-carrying
    def directions_for_axes(self, axes: Any) -> np.ndarray:
        """Mode directions with the tool modes carried to each of ``axes``.

        Parameters
        ----------
        axes : array_like, shape (p, 3)
            Tool axes (unit, not along -Z), workpiece frame.

        Returns
        -------
        ndarray, shape (p, n, 3)
            Tool modes ``minimal_rotation(axis) @ minimal_rotation(tool_axis).T @ d``;
            workpiece modes unchanged.
        """
        a = np.asarray(axes, dtype=float).reshape(-1, 3)
        rot = minimal_rotation(a) @ minimal_rotation(self.tool_axis).T        # (p, 3, 3)
        out = np.broadcast_to(self.direction, (a.shape[0],) + self.direction.shape).copy()
        tool = self.source == "tool"
        out[:, tool, :] = np.einsum("pij,nj->pni", rot, self.direction[tool])
        return out

    def with_tool_axis(self, axis: Any) -> ModalSystem:
        """The same system with its tool modes carried to ``axis`` (shape (3,))."""
        u = _unit_vector("ModalSystem.with_tool_axis: axis", axis)
        return ModalSystem(self.k_N_m, self.m_kg, self.c_Ns_m,
                           self.directions_for_axes(u[None])[0], self.source, u,
                           self.velocity_s)

    def rotated(self, rotation: Any) -> ModalSystem:
        """All mode directions (and the tool axis) rotated by ``rotation`` (3, 3, proper)."""
        r = np.asarray(rotation, dtype=float)
        if r.shape != (3, 3) or not np.allclose(r @ r.T, np.eye(3), atol=ORTHONORMAL_TOL) \
                or np.linalg.det(r) <= 0:
            raise ValueError("ModalSystem.rotated: rotation: expected a proper 3x3 rotation")
        return ModalSystem(self.k_N_m, self.m_kg, self.c_Ns_m, self.direction @ r.T,
                           self.source, r @ self.tool_axis, self.velocity_s)

    # ------------------------------------------------------------------ responses
    def modal_receptance(self, omega_rad_s: Any) -> np.ndarray:
        """Per-mode receptance ``(1 + i w r) / (k - m w^2 + i c w)`` [m/N], shape
        ``omega.shape + (n,)``."""
        w = np.asarray(omega_rad_s, dtype=float)
        if not np.all(np.isfinite(w)):
            raise ValueError("omega_rad_s: expected finite values")
        ww = w[..., None]
        return (1.0 + 1j * ww * self.velocity_s) / (self.k_N_m - self.m_kg * ww * ww
                                                    + 1j * self.c_Ns_m * ww)

    def frf(self, omega_rad_s: Any) -> np.ndarray:
        """Relative compliance ``G(omega)`` [m/N], shape ``omega.shape + (3, 3)`` complex.

        Parameters
        ----------
        omega_rad_s : array_like
            Angular frequencies [rad/s], finite.
        """
        g = self.modal_receptance(omega_rad_s)
        return np.einsum("...k,ki,kj->...ij", g, self.direction, self.direction)

    def state_matrix(self) -> np.ndarray:
        """``A0`` of ``y' = A0 y`` for ``y = [eta; eta']`` [1/s], shape (2n, 2n)."""
        n = self.n_modes
        a = np.zeros((2 * n, 2 * n))
        a[:n, n:] = np.eye(n)
        a[n:, :n] = -np.diag(self.k_N_m / self.m_kg)
        a[n:, n:] = -np.diag(self.c_Ns_m / self.m_kg)
        return a

    def __repr__(self) -> str:
        f = self.natural_frequency_rad_s / (2 * math.pi)
        return (f"ModalSystem(n_modes={self.n_modes}, f_Hz={np.round(f, 1).tolist()}, "
                f"source={self.source.tolist()})")


# ---------------------------------------------------------------------- modal fit


def fit_modes(freq_hz: Any, frf_m_N: Any, n_modes: int | None = None) -> list[Mode]:
    """Fit real modes ``sum_k 1/(k_k - m_k w^2 + i c_k w)`` to a direct receptance.

    Peak picking on ``-Im G`` (initial natural frequencies, half-power
    damping, stiffness from the peak height), then a joint least-squares
    refinement (scipy) of ``(f_n, zeta, k)`` per mode on the complex FRF.

    Parameters
    ----------
    freq_hz : array_like, shape (w,)
        Frequencies [Hz], finite, >= 0, strictly increasing.
    frf_m_N : array_like complex, shape (w,)
        Direct receptance [m/N].
    n_modes : int, optional
        Number of modes to fit; default: every peak above
        ``FIT_PEAK_FRACTION`` of the largest (at most ``FIT_MAX_MODES``).

    Returns
    -------
    list of errpred.dynamics.Mode
        Sorted by natural frequency.
    """
    from scipy.optimize import least_squares
    from scipy.signal import find_peaks

    f = np.asarray(freq_hz, dtype=float)
    g = np.asarray(frf_m_N, dtype=complex)
    if f.ndim != 1 or g.shape != f.shape or f.size < 5:
        raise ValueError(f"fit_modes: need 1-D frequency and FRF arrays of equal length >= 5, "
                         f"got {f.shape} and {g.shape}")
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(g))):
        raise ValueError("fit_modes: freq_hz and frf_m_N must be finite")
    if f[0] < 0 or np.any(np.diff(f) <= 0):
        raise ValueError("fit_modes: freq_hz must be >= 0 and strictly increasing")
    y = -g.imag
    peaks, _ = find_peaks(y, height=FIT_PEAK_FRACTION * max(float(y.max()), 1e-300))
    if peaks.size == 0:
        raise ValueError("fit_modes: no resonance peak (-Im G > 0) found")
    peaks = peaks[np.argsort(y[peaks])[::-1]]
    count = FIT_MAX_MODES if n_modes is None else int(n_modes)
    if count < 1:
        raise ValueError(f"fit_modes: n_modes: expected an integer >= 1, got {n_modes!r}")
    peaks = np.sort(peaks[:count])
    x0 = []
    for p in peaks:
        half = y[p] / math.sqrt(2.0)
        lo, hi = p, p
        while lo > 0 and y[lo] > half:
            lo -= 1
        while hi < f.size - 1 and y[hi] > half:
            hi += 1
        zeta = max((f[hi] - f[lo]) / (2.0 * f[p]), FIT_MIN_ZETA)
        k = 1.0 / (2.0 * zeta * y[p])
        x0 += [math.log(f[p]), math.log(zeta), math.log(k)]
    w = 2.0 * math.pi * f
    scale = float(np.max(np.abs(g)))

    def model(x: np.ndarray) -> np.ndarray:
        out = np.zeros_like(g)
        for i in range(0, x.size, 3):
            fn, z, k = np.exp(x[i:i + 3])
            wn = 2.0 * math.pi * fn
            out += 1.0 / (k * (1.0 - (w / wn) ** 2 + 2j * z * w / wn))
        return out

    def resid(x: np.ndarray) -> np.ndarray:
        r = (model(x) - g) / scale
        return np.concatenate([r.real, r.imag])

    sol = least_squares(resid, np.array(x0), method="lm")
    modes = []
    for i in range(0, sol.x.size, 3):
        fn, z, k = np.exp(sol.x[i:i + 3])
        modes.append(Mode.from_frequency(float(fn), float(z), float(k)))
    return sorted(modes, key=lambda m: m.natural_frequency_hz)
