"""Stability lobes: margin (and limiting depth) over spindle speed, by either method.

Both methods use the contract's model (see :mod:`orient.stability.zoa`):
``'zoa'`` takes ``P = mean(H_samples)`` (:func:`~orient.stability.zoa.zoa_lobes`),
``'sdm'`` the time-periodic full discretization
(:func:`~orient.stability.sdm.sdm_lobes`).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import Any

import numpy as np

from orient.dynamics import ModalSystem
from orient.stability.sdm import _check_samples, sdm_lobes
from orient.stability.zoa import zoa_lobes

__all__ = ["METHODS", "Lobes", "stability_lobes"]

#: Method names.
METHODS = ("zoa", "sdm")


@dataclass(frozen=True)
class Lobes:
    """Stability margin over spindle speed.

    Attributes
    ----------
    rpm : ndarray, shape (r,) [rev/min]
        Spindle speeds.
    margin : ndarray, shape (r,) [-]
        Stability margin at each speed (inf where no boundary was found).
    method : str
        ``'zoa'`` or ``'sdm'``.
    depth_mm : float or None [mm]
        The depth of cut at which ``H_samples`` were computed, if given.
    kind : tuple of str or None
        Per speed, the critical multiplier's kind (``'hopf'``, ``'flip'``,
        ``'fold'``, ``'none'``) for ``'sdm'``; None for ``'zoa'``.
    """

    rpm: np.ndarray
    margin: np.ndarray
    method: str
    depth_mm: float | None = None
    kind: tuple[str, ...] | None = None

    @property
    def depth_limit_mm(self) -> np.ndarray | None:
        """Limiting depth of cut ``depth_mm * margin`` [mm], shape (r,); None without depth."""
        return None if self.depth_mm is None else self.depth_mm * self.margin

    @property
    def minimum(self) -> tuple[float, float]:
        """``(rpm, margin)`` at the lowest margin on the speed grid."""
        i = int(np.argmin(self.margin))
        return float(self.rpm[i]), float(self.margin[i])


def stability_lobes(H_samples: Any, system: ModalSystem, teeth: int, rpm: Any,
                    method: str = "zoa", depth_mm: float | None = None, *,
                    steps: int | None = None, omega_rad_s: Any = None) -> Lobes:
    """Stability lobes of one cut.

    Parameters
    ----------
    H_samples : array_like, shape (k, 3, 3) [N/m]
        Directional matrix: its averages over ``k`` equal steps of one tooth period,
        for the cut at depth ``depth_mm``.
    system : ModalSystem
        Relative dynamics.
    teeth : int
        Number of teeth.
    rpm : array_like, shape (r,) [rev/min]
        Spindle speeds, finite, > 0.
    method : str
        ``'zoa'`` (average gain) or ``'sdm'`` (time-periodic).
    depth_mm : float, optional [mm]
        Depth of cut of ``H_samples``; gives :attr:`Lobes.depth_limit_mm`.
    steps : int, optional
        Steps per tooth period (``'sdm'``).
    omega_rad_s : array_like, optional
        Chatter-frequency grid [rad/s] (``'zoa'``).
    """
    if method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    h = _check_samples(H_samples)
    r = np.asarray(rpm, dtype=float).reshape(-1)
    if r.size == 0 or not np.all(np.isfinite(r)) or np.any(r <= 0):
        raise ValueError("rpm: expected finite spindle speeds > 0 [rev/min]")
    if depth_mm is not None:
        if isinstance(depth_mm, (bool, np.bool_)) or not isinstance(depth_mm, numbers.Real) \
                or not math.isfinite(float(depth_mm)) or float(depth_mm) <= 0:
            raise ValueError(f"depth_mm: expected a finite value > 0, got {depth_mm!r}")
        depth_mm = float(depth_mm)
    if method == "zoa":
        m = zoa_lobes(h.mean(axis=0), system, teeth, r, omega_rad_s)
        return Lobes(r, m, "zoa", depth_mm)
    res = sdm_lobes(h, system, teeth, r, steps=steps)
    return Lobes(r, np.array([x.margin for x in res]), "sdm", depth_mm,
                 tuple(x.kind for x in res))
