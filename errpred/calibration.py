"""Identification of the cutting force coefficients from measured forces.

The model (:mod:`errpred.coefficients`) is linear in the nine coefficients, so
the design matrix is built by evaluating :func:`errpred.force.tool_forces` with
unit coefficients (one 1, the rest 0), and the fit is linear least squares. As
in the seed (JP5804367 ¶0060, ``docs/method.md`` §4), the six ``Kxc``/``Kxe0``
come from new-tool measurements (wear terms held at 0), then the three ``Kxe1``
from worn-tool measurements with known ``cl``, the six held.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from .coefficients import CHIP_AND_EDGE_NAMES, WEAR_NAMES, CuttingCoefficients
from .force import tool_forces
from .tool import MicroEdges

__all__ = ["FitReport", "ForceMeasurement", "fit_coefficients"]


@dataclass(frozen=True, eq=False)
class ForceMeasurement:
    """One measured revolution of cutting force with its engagement.

    Attributes
    ----------
    edges : MicroEdges
        The tool's micro edges (``m`` of them).
    phi : ndarray, shape (n_ang, n_fl, m) [rad]
        Angular position of every micro edge of every flute at each sample.
    h : ndarray, shape (n_ang, n_fl, m) [mm]
        Uncut chip thickness.
    cutting : ndarray of bool, shape (n_ang, n_fl, m)
        Whether the micro edge cuts at that sample.
    cl_mm : ndarray, shape (m,) or (n_fl, m) [mm]
        Actual cutting distance of the micro edges (about 0 for a new tool).
    force_N : ndarray, shape (n_ang, 3) [N]
        Measured force on the tool, tool frame, at the same samples as
        ``phi`` (one revolution, compared sample by sample).

    The arrays are converted, not checked, here: :func:`fit_coefficients`
    checks them (:meth:`problems`) and names the measurement at fault.
    """

    edges: MicroEdges
    phi: np.ndarray
    h: np.ndarray
    cutting: np.ndarray
    cl_mm: np.ndarray
    force_N: np.ndarray

    def __post_init__(self) -> None:
        for name in ("phi", "h", "cl_mm", "force_N"):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=float))
        object.__setattr__(self, "cutting", np.asarray(self.cutting, dtype=bool))

    def problems(self) -> list[str]:
        """What is wrong with the measurement (empty when usable)."""
        out: list[str] = []
        if not isinstance(self.edges, MicroEdges):
            return [f"edges: expected MicroEdges, got {type(self.edges).__name__}"]
        m = len(self.edges)
        if self.phi.ndim != 3:
            return [f"phi: expected shape (n_ang, n_fl, m), got {self.phi.shape}"]
        n_ang, n_fl, mm = self.phi.shape
        if mm != m:
            out.append(f"phi: last axis has {mm} micro edges, the edges have {m}")
        for name in ("h", "cutting"):
            if getattr(self, name).shape != self.phi.shape:
                out.append(f"{name}: shape {getattr(self, name).shape} differs from phi's "
                           f"{self.phi.shape}")
        if self.cl_mm.shape not in ((m,), (n_fl, m)):
            out.append(f"cl_mm: expected shape ({m},) or ({n_fl}, {m}), got {self.cl_mm.shape}")
        if self.force_N.shape != (n_ang, 3):
            out.append(f"force_N: expected shape ({n_ang}, 3) (one row per angle sample), "
                       f"got {self.force_N.shape}")
        if out:
            return out
        for name, arr in (("force_N", self.force_N), ("cl_mm", self.cl_mm),
                          ("phi", np.where(self.cutting, self.phi, 0.0)),
                          ("h", np.where(self.cutting, self.h, 0.0))):
            bad = ~np.isfinite(arr)
            if bad.any():
                first = tuple(int(i) for i in np.argwhere(bad)[0])
                out.append(f"{name}: {int(bad.sum())} non-finite value(s) (NaN/inf), first at "
                           f"index {first}")
        if np.any(self.cl_mm < 0):
            out.append("cl_mm: negative cutting distance")
        if np.any(np.where(self.cutting, self.h, 0.0) < 0):
            out.append("h: negative chip thickness on a cutting sample")
        return out


@dataclass(frozen=True)
class FitReport:
    """Result of :func:`fit_coefficients`.

    Attributes
    ----------
    coefficients : CuttingCoefficients
        The nine coefficients (wear terms 0 when no worn measurement was given).
    residual_rms_N : float [N]
        RMS of the force residual of the new-tool fit, over all samples and
        the three components.
    condition_number : float [-]
        2-norm condition number of the new-tool design matrix with its
        columns scaled to unit norm (the scaling the solve uses).
    n_samples : int
        Equations of the new-tool fit (angle samples x 3 components).
    std_error : dict of str to float
        Standard error of each fitted coefficient, from the residual variance
        and the design matrix (``s^2 (A^T A)^-1``), in the coefficient's unit.
        For the wear terms it is conditional on the six held values (their
        own error, propagated, comes on top).
    wear_residual_rms_N : float or None [N]
        RMS residual of the wear fit (None without worn measurements).
    wear_condition_number : float or None [-]
    n_wear_samples : int
        Equations of the wear fit (0 without worn measurements).
    """

    coefficients: CuttingCoefficients
    residual_rms_N: float
    condition_number: float
    n_samples: int
    std_error: dict[str, float]
    wear_residual_rms_N: float | None = None
    wear_condition_number: float | None = None
    n_wear_samples: int = 0


def _check(meas: Sequence[ForceMeasurement], label: str) -> list[ForceMeasurement]:
    out = []
    for i, m in enumerate(meas):
        if not isinstance(m, ForceMeasurement):
            raise ValueError(f"{label} measurement {i}: expected ForceMeasurement, got "
                             f"{type(m).__name__}")
        probs = m.problems()
        if probs:
            raise ValueError(f"{label} measurement {i} ({label}[{i}]): " + "; ".join(probs))
        if not m.cutting.any():
            raise ValueError(f"{label} measurement {i} ({label}[{i}]): no micro edge cuts at "
                             f"any sample; it carries no information on the coefficients")
        out.append(m)
    return out


def _unit(name: str) -> CuttingCoefficients:
    vals = dict.fromkeys(CHIP_AND_EDGE_NAMES + WEAR_NAMES, 0.0)
    vals[name] = 1.0
    return CuttingCoefficients(**vals)


def _design(meas: list[ForceMeasurement], names: Sequence[str]) -> np.ndarray:
    """Design matrix: one column per coefficient, rows = (sample, component)."""

    cols = []
    for name in names:
        k = _unit(name)
        cols.append(np.concatenate([
            tool_forces(m.edges, k, m.phi, m.h, m.cutting, m.cl_mm).ravel() for m in meas]))
    return np.stack(cols, axis=1)


def _solve(A: np.ndarray, b: np.ndarray, names: Sequence[str], label: str
           ) -> tuple[np.ndarray, float, float, np.ndarray]:
    """Column-scaled least squares; returns x, rms residual, cond, std errors."""
    n, p = A.shape
    scale = np.linalg.norm(A, axis=0)
    dead = [names[j] for j in range(p) if not scale[j] > 0]
    if dead:
        raise ValueError(f"{label} measurements: the engagement gives no force sensitivity to "
                         f"{', '.join(dead)}; it cannot be identified from these measurements")
    As = A / scale
    sv = np.linalg.svd(As, compute_uv=False)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf
    if not cond < 1.0 / (np.finfo(float).eps * max(n, p)):
        raise ValueError(f"{label} measurements: the design matrix is rank deficient "
                         f"(condition number {cond:.3g}); the engagements do not separate "
                         f"{', '.join(names)} (add engagements with other feeds/immersions)")
    xs, _, _, _ = scipy.linalg.lstsq(As, b)
    x = xs / scale
    r = b - A @ x
    rms = float(np.sqrt(np.mean(r * r)))
    dof = n - p
    s2 = float(r @ r) / dof if dof > 0 else math.nan
    cov_s = np.linalg.inv(As.T @ As) * s2
    se = np.sqrt(np.maximum(np.diag(cov_s), 0.0)) / scale
    return x, rms, cond, se


def fit_coefficients(new: Sequence[ForceMeasurement], worn: Sequence[ForceMeasurement] = (),
                     *, source: str = "") -> FitReport:
    """Identify the cutting coefficients by least squares on measured forces.

    Step 1: the six chip and new-tool edge coefficients (``Ktc, Krc, Kac,
    Kte0, Kre0, Kae0``) from the new-tool measurements, the wear terms held
    at 0 (so the given ``cl_mm``, about 0, has no effect). Step 2, when
    ``worn`` is given: the three wear growth coefficients (``Kte1, Kre1,
    Kae1``) from the worn-tool measurements with their known ``cl_mm``, the
    six held (``docs/method.md`` §4; JP5804367 ¶0060). Forces are compared
    sample by sample over the revolution (time series), all three components.

    Parameters
    ----------
    new : sequence of ForceMeasurement
        New-tool measurements; together at least 6 equations (3 per sample).
    worn : sequence of ForceMeasurement, optional
        Worn-tool measurements with known ``cl_mm``; at least 3 equations.
    source : str
        Recorded in the coefficients' ``source``.

    Returns
    -------
    FitReport

    Raises
    ------
    ValueError
        A measurement with NaN/inf, mismatched shapes, or no cutting sample
        (the message names it, e.g. ``new[1]``); too few equations; a design
        matrix that does not determine the coefficients.
    """
    new_l = _check(list(new), "new")
    worn_l = _check(list(worn), "worn")
    if not new_l:
        raise ValueError("new: at least one new-tool measurement is needed")
    n_new = 3 * sum(m.force_N.shape[0] for m in new_l)
    if n_new < len(CHIP_AND_EDGE_NAMES):
        raise ValueError(f"new: {n_new} equations (3 per sample) for "
                         f"{len(CHIP_AND_EDGE_NAMES)} coefficients; too few samples")
    A = _design(new_l, CHIP_AND_EDGE_NAMES)
    b = np.concatenate([m.force_N.ravel() for m in new_l])
    x, rms, cond, se = _solve(A, b, CHIP_AND_EDGE_NAMES, "new")
    vals = dict(zip(CHIP_AND_EDGE_NAMES, map(float, x)))
    std = dict(zip(CHIP_AND_EDGE_NAMES, map(float, se)))
    wear_rms = wear_cond = None
    n_worn = 0
    if worn_l:
        n_worn = 3 * sum(m.force_N.shape[0] for m in worn_l)
        if n_worn < len(WEAR_NAMES):
            raise ValueError(f"worn: {n_worn} equations (3 per sample) for "
                             f"{len(WEAR_NAMES)} coefficients; too few samples")

        held = CuttingCoefficients(**vals)
        b_w = np.concatenate([
            (m.force_N - tool_forces(m.edges, held, m.phi, m.h, m.cutting, m.cl_mm)).ravel()
            for m in worn_l])
        A_w = _design(worn_l, WEAR_NAMES)
        x_w, wear_rms, wear_cond, se_w = _solve(A_w, b_w, WEAR_NAMES, "worn")
        vals.update(zip(WEAR_NAMES, map(float, x_w)))
        std.update(zip(WEAR_NAMES, map(float, se_w)))
    return FitReport(coefficients=CuttingCoefficients(**vals, source=source),
                     residual_rms_N=rms, condition_number=cond, n_samples=n_new,
                     std_error=std, wear_residual_rms_N=wear_rms,
                     wear_condition_number=wear_cond, n_wear_samples=n_worn)
