"""Identifying a force law's coefficients from measured mean forces.

The tests are straight cuts of a flat end mill (slotting, or side milling
up or down) at several feeds, each with its mean force over whole
revolutions. The forward model is the force law (:mod:`errpred.laws`) on the
flank's micro edges (``kappa = 90 deg``), summed into the tool frame by
:func:`errpred.force.to_tool_frame`, and averaged over the rotation::

    F_mean = N ap / (2 pi) * integral over the engaged arc of
             to_tool_frame(F(h(phi)), phi, 90 deg) dphi,    h = fz sin(phi)

(a flat end mill's helix does not change the mean: every disc of the flank
sees the same arc over a revolution). Tool frame: ``x`` along the feed, ``z``
up the tool axis, ``y = z x x`` (to the left of the feed seen from the
spindle); the force is the force **on the tool** (a dynamometer under the
workpiece reads minus this). Up milling: the material on ``+y``, the edge
enters at ``h = 0``; down milling: on ``-y``.

The fit is least squares on the three mean components of every test
(:func:`scipy.optimize.least_squares`), in N; standard errors from the
Jacobian at the solution. The linear law's model is linear in its six
coefficients (a few evaluations reach the linear least-squares solution);
Kienzle's is not (its exponents are bounded to ``0 <= m <= KIENZLE_MAX_MC``).
The Lee-Altintas law's kappa polynomials cannot be identified from flat end
mill tests (one kappa): refused.

No file is read or written here (:mod:`errpred.fit_files`).

References
----------
.. [1] Y. Altintas, *Manufacturing Automation*, 2nd ed., Cambridge University
   Press, 2012, §2.3.2 (identification of the linear edge-force coefficients
   from mean slotting forces at several feeds).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from types import ModuleType

import numpy as np
import scipy.optimize

from . import laws
from .coefficients import LawCoefficients
from .constants import FIT_QUADRATURE_NODES, KIENZLE_MAX_MC
from .force import to_tool_frame

__all__ = ["FitResult", "MeanForceTest", "fit_law", "mean_force", "slot_force_linear"]

MODES = ("slot", "up", "down")


@dataclass(frozen=True)
class MeanForceTest:
    """One cutting test: a straight cut of a flat end mill and its mean force.

    Attributes
    ----------
    fz_mm : float [mm]
        Feed per tooth, > 0.
    ap_mm : float [mm]
        Axial depth of cut, > 0.
    ae_mm : float [mm]
        Radial width of cut, 0 < ae <= D (ignored for a slot: ae = D).
    mode : str
        "slot", "up" (conventional) or "down" (climb).
    diameter_mm : float [mm]
    teeth : int
    force_N : tuple of 3 float [N]
        Mean force on the tool, tool frame (module docstring).
    rpm : float [rev/min]
        Spindle speed (recorded; the mean force model does not use it).
    label : str
        Where the test comes from (e.g. "tests.csv line 4"), for messages.
    """

    fz_mm: float
    ap_mm: float
    ae_mm: float
    mode: str
    diameter_mm: float
    teeth: int
    force_N: tuple
    rpm: float = math.nan
    label: str = ""

    def __post_init__(self) -> None:
        where = f"{self.label}: " if self.label else ""
        for name in ("fz_mm", "ap_mm", "ae_mm", "diameter_mm"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{where}{name}: expected a finite value > 0, got {v!r}")
        if self.mode not in MODES:
            raise ValueError(f"{where}mode: expected one of {', '.join(MODES)}, got "
                             f"{self.mode!r}")
        if self.mode != "slot" and self.ae_mm > self.diameter_mm:
            raise ValueError(f"{where}ae_mm: {self.ae_mm:g} is wider than the tool "
                             f"({self.diameter_mm:g} mm); a full-width cut is a slot")
        if isinstance(self.teeth, bool) or not isinstance(self.teeth, int) or self.teeth < 1:
            raise ValueError(f"{where}teeth: expected a whole number >= 1, got {self.teeth!r}")
        f = tuple(float(x) for x in self.force_N)
        if len(f) != 3 or not all(math.isfinite(x) for x in f):
            raise ValueError(f"{where}force: expected three finite components, got "
                             f"{self.force_N!r}")
        object.__setattr__(self, "force_N", f)

    def arc(self) -> tuple[float, float]:
        """Engaged arc ``(phi_start, phi_exit)`` [rad] (module docstring)."""
        if self.mode == "slot":
            return 0.0, math.pi
        w = math.acos(max(-1.0, 1.0 - 2.0 * self.ae_mm / self.diameter_mm))
        return (0.0, w) if self.mode == "up" else (math.pi - w, math.pi)


@dataclass(frozen=True)
class FitResult:
    """Result of :func:`fit_law`.

    Attributes
    ----------
    coefficients : LawCoefficients
        The fitted law (wear growth 0: new-tool tests).
    names : tuple of str
        The fitted coefficients, in order.
    std_error : dict of str to float
        Standard error of each, in its unit (``s^2 (J^T J)^-1``).
    model_N : ndarray, shape (n, 3) [N]
        The fitted model's mean force per test.
    residual_N : ndarray, shape (n, 3) [N]
        Measured minus model.
    rms_N : float [N]
        RMS of the residuals over all components.
    condition_number : float [-]
        Of the Jacobian at the solution, columns scaled to unit norm.
    """

    coefficients: object
    names: tuple
    std_error: dict
    model_N: np.ndarray
    residual_N: np.ndarray
    rms_N: float
    condition_number: float


@functools.lru_cache(maxsize=4)
def _legendre(n: int) -> tuple[np.ndarray, np.ndarray]:
    return np.polynomial.legendre.leggauss(n)


def _nodes(a: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    """Quadrature nodes and weights on [a, b], clustered at both ends."""
    x, w = _legendre(FIT_QUADRATURE_NODES)
    s = 0.5 * (x + 1.0)
    phi = a + (b - a) * 0.5 * (1.0 - np.cos(math.pi * s))
    # d phi = (b - a) (pi / 2) sin(pi s) ds and ds = dx / 2
    return phi, w * 0.5 * (b - a) * 0.5 * math.pi * np.sin(math.pi * s)


def mean_force(coeffs: LawCoefficients, test: MeanForceTest) -> np.ndarray:
    """The law's mean force on the tool over a revolution, tool frame [N], shape (3,).

    The arc is split where the chip passes a law's kink (``KINKS_MM``, e.g.
    Kienzle's floor), so that each piece's integrand is smooth.

    Parameters
    ----------
    coeffs : LawCoefficients
    test : MeanForceTest
        Its forces are not used.
    """
    a, b = test.arc()
    cuts = [a, b]
    for hk in getattr(laws.law_of(coeffs), "KINKS_MM", ()):
        if hk < test.fz_mm:
            p = math.asin(hk / test.fz_mm)
            cuts += [x for x in (p, math.pi - p) if a < x < b]
    cuts.sort()
    total = np.zeros(3)
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        phi, w = _nodes(lo, hi)
        h = test.fz_mm * np.sin(phi)
        kappa = np.full(phi.shape, 0.5 * math.pi)
        ft, fr, fa = laws.force(coeffs, h, kappa, 0.0)
        total += w @ to_tool_frame(ft, fr, fa, phi, kappa)          # [N/mm]
    return test.teeth * test.ap_mm / (2.0 * math.pi) * total


def slot_force_linear(c, fz_mm: float, ap_mm: float, teeth: int) -> np.ndarray:
    """Closed-form mean slot force of the linear law on the tool, tool frame [N].

    ``Fx = -N a (Kre/pi + Krc fz/4)``, ``Fy = N a (Kte/pi + Ktc fz/4)``,
    ``Fz = -N a (Kae/2 + Kac fz/pi)`` (Altintas 2012, §2.3.2, in this
    project's frame and sign of the axial force).

    Parameters
    ----------
    c : CuttingCoefficients
    fz_mm, ap_mm : float [mm]
    teeth : int
    """
    na = teeth * ap_mm
    return np.array([-na * (c.Kre0_N_mm / math.pi + c.Krc_N_mm2 * fz_mm / 4.0),
                     na * (c.Kte0_N_mm / math.pi + c.Ktc_N_mm2 * fz_mm / 4.0),
                     -na * (c.Kae0_N_mm / 2.0 + c.Kac_N_mm2 * fz_mm / math.pi)])


def _law(name: str) -> ModuleType:
    if name not in laws.LAWS:
        raise ValueError(f"law: unknown {name!r}; expected one of {', '.join(laws.LAWS)}")
    law = laws.LAWS[name]
    if not hasattr(law, "FIT_NAMES"):
        raise ValueError(f"law {name!r}: its coefficients vary with kappa, which flat end mill "
                         f"tests do not vary (all at 90 deg); fit the linear law and give its "
                         f"values as constant polynomials")
    return law


def fit_law(name: str, tests: Sequence[MeanForceTest], *, source: str = "") -> FitResult:
    """Fit law ``name``'s coefficients to the tests' mean forces (least squares, N).

    Parameters
    ----------
    name : str
        "linear" or "kienzle" (:data:`errpred.laws.LAWS`).
    tests : sequence of MeanForceTest
        At least two feeds (the chip and edge terms, or Kienzle's factor and
        exponent, separate only across feeds).
    source : str
        Recorded in the coefficients' ``source``.

    Returns
    -------
    FitResult

    Raises
    ------
    ValueError
        Unknown or unfittable law, too few tests or feeds, a rank-deficient fit.
    """
    law = _law(name)
    tests = list(tests)
    names = tuple(law.FIT_NAMES)
    if 3 * len(tests) < len(names):
        raise ValueError(f"tests: {len(tests)} test(s) give {3 * len(tests)} equations for "
                         f"{len(names)} coefficients of the {name} law")
    if len({t.fz_mm for t in tests}) < 2:
        raise ValueError("tests: all at one feed per tooth; at least two feeds are needed to "
                         "separate the chip term from the edge term (or the exponent)")
    meas = np.array([t.force_N for t in tests])
    start = law.fit_start()
    x0 = np.array([start[n] for n in names])
    lo = np.array([0.0 if n.startswith("mc_") else -np.inf for n in names])
    hi = np.array([KIENZLE_MAX_MC if n.startswith("mc_") else np.inf for n in names])

    def model(x: np.ndarray) -> np.ndarray:
        c = law.from_values(dict(zip(names, map(float, x))))
        return np.array([mean_force(c, t) for t in tests])

    def resid(x: np.ndarray) -> np.ndarray:
        return (model(x) - meas).ravel()

    sol = scipy.optimize.least_squares(resid, x0, bounds=(lo, hi), x_scale="jac",
                                       xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=2000)
    J = sol.jac
    scale = np.linalg.norm(J, axis=0)
    dead = [names[i] for i in range(len(names)) if not scale[i] > 0]
    if dead:
        raise ValueError(f"tests: the mean forces do not depend on {', '.join(dead)} at the "
                         f"solution; it cannot be identified from these tests")
    Js = J / scale
    sv = np.linalg.svd(Js, compute_uv=False)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf
    n_eq, p = J.shape
    if not cond < 1.0 / (np.finfo(float).eps * max(n_eq, p)):
        raise ValueError(f"tests: the fit is rank deficient (condition number {cond:.3g}); add "
                         f"tests at other feeds or widths")
    r = sol.fun
    dof = n_eq - p
    s2 = float(r @ r) / dof if dof > 0 else math.nan
    se = np.sqrt(np.maximum(np.diag(np.linalg.inv(Js.T @ Js)) * s2, 0.0)) / scale
    coeffs = law.from_values(dict(zip(names, map(float, sol.x))), source=source)
    mod = model(sol.x)
    return FitResult(coefficients=coeffs, names=names, std_error=dict(zip(names, map(float, se))),
                     model_N=mod, residual_N=meas - mod,
                     rms_N=float(np.sqrt(np.mean((meas - mod) ** 2))), condition_number=cond)
