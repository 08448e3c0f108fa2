"""Kienzle's exponential law, per direction (tangential, radial, axial).

Per micro edge and unit chip width, direction ``x`` in (t, r, a)::

    F_x(h)  = Kxe0 + Kxe1 cl + k_x1.1 h^(1 - m_x)            [N/mm]
    dF_x/dh = (1 - m_x) k_x1.1 h^(-m_x)                      [N/mm^2]

``k_x1.1`` is the specific force at a chip of 1 mm thickness and 1 mm width
[N/mm^2] (``kc11_t_N_mm2``: the shops' k_c1.1; radial and axial the
feed/passive force's k_f1.1, k_p1.1 as tabulated), ``m_x`` [-] its exponent
(0 <= m < 1; ``m = 0`` is the linear law without edge force). The optional
edge terms ``Kxe0`` (default 0: Kienzle's law has none, the exponent carries the
size effect) and the wear growth ``Kxe1`` are those of the linear law.

The slope is infinite at ``h -> 0``: below ``KIENZLE_MIN_CHIP_MM`` the chip
term is the chord from 0 to its value there (finite slope, continuous force);
see :data:`errpred.constants.KIENZLE_MIN_CHIP_MM`. The slope depends on the
chip, so orient integrates the process gain over the sampled engagement
(:func:`slope_in_kappa` returns None).

References
----------
.. [1] O. Kienzle, "Die Bestimmung von Kräften und Leistungen an spanenden
   Werkzeugen und Werkzeugmaschinen", *VDI-Z* 94(11/12) (1952) 299-305.
.. [2] W. König, F. Klocke, *Fertigungsverfahren 1: Drehen, Fräsen, Bohren*,
   8th ed., Springer, 2008, §7 (the k_c1.1, m_c tables and their use in milling).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from ..coefficients import LawCoefficients, finite_coefficient
from ..constants import KIENZLE_MAX_MC, KIENZLE_MIN_CHIP_MM

__all__ = ["NAME", "KEYS", "Coefficients", "KienzleCoefficients", "fit_start", "force",
           "from_values", "slope", "slope_in_kappa", "values"]

NAME = "kienzle"
_CHIP = ("kc11_t_N_mm2", "kc11_r_N_mm2", "kc11_a_N_mm2")
_EXP = ("mc_t", "mc_r", "mc_a")
_EDGE = ("Kte0_N_mm", "Kre0_N_mm", "Kae0_N_mm")
_WEAR = ("Kte1_N_mm2", "Kre1_N_mm2", "Kae1_N_mm2")
KEYS = {**{k: ("number", True) for k in _CHIP}, **{k: ("fraction", True) for k in _EXP},
        **{k: ("number", False) for k in _EDGE + _WEAR}}
FIT_NAMES = _CHIP + _EXP
#: Chips where F(h) is not smooth [mm] (the floor): quadratures split there.
KINKS_MM = (KIENZLE_MIN_CHIP_MM,)


@dataclass(frozen=True)
class KienzleCoefficients(LawCoefficients):
    """Coefficients of Kienzle's law (module docstring).

    Attributes
    ----------
    kc11_t_N_mm2, kc11_r_N_mm2, kc11_a_N_mm2 : float [N/mm^2]
        Specific force at h = 1 mm, b = 1 mm: tangential, radial, axial.
    mc_t, mc_r, mc_a : float [-]
        Exponents, 0 <= m <= ``KIENZLE_MAX_MC``.
    Kte0_N_mm, Kre0_N_mm, Kae0_N_mm : float [N/mm]
        Edge force of a new tool (default 0).
    Kte1_N_mm2, Kre1_N_mm2, Kae1_N_mm2 : float [N/mm^2]
        Wear growth of the edge force per mm of cutting distance (default 0).
    source : str
    """

    kc11_t_N_mm2: float
    kc11_r_N_mm2: float
    kc11_a_N_mm2: float
    mc_t: float
    mc_r: float
    mc_a: float
    Kte0_N_mm: float = 0.0
    Kre0_N_mm: float = 0.0
    Kae0_N_mm: float = 0.0
    Kte1_N_mm2: float = 0.0
    Kre1_N_mm2: float = 0.0
    Kae1_N_mm2: float = 0.0
    source: str = field(default="", compare=False)
    law: ClassVar[str] = NAME

    def __post_init__(self) -> None:
        for name in _CHIP + _EXP + _EDGE + _WEAR:
            object.__setattr__(self, name, finite_coefficient(name, getattr(self, name)))
        for name in _EXP:
            v = getattr(self, name)
            if not 0.0 <= v <= KIENZLE_MAX_MC:
                raise ValueError(f"cutting coefficient {name}: expected 0 <= m <= "
                                 f"{KIENZLE_MAX_MC:g} (KIENZLE_MAX_MC), got {v:g}")

    @property
    def k11(self) -> tuple[float, float, float]:
        """``(k_t1.1, k_r1.1, k_a1.1)`` [N/mm^2]."""
        return self.kc11_t_N_mm2, self.kc11_r_N_mm2, self.kc11_a_N_mm2

    @property
    def exponents(self) -> tuple[float, float, float]:
        """``(m_t, m_r, m_a)`` [-]."""
        return self.mc_t, self.mc_r, self.mc_a

    def as_dict(self) -> dict[str, float]:
        """The coefficients by field name (``source`` left out)."""
        return {n: getattr(self, n) for n in _CHIP + _EXP + _EDGE + _WEAR}


Coefficients = KienzleCoefficients


def _chip_term(k: float, m: float, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``k h^(1-m)`` and its slope; the chord from 0 below ``KIENZLE_MIN_CHIP_MM``."""
    h0 = KIENZLE_MIN_CHIP_MM
    f0 = k * h0 ** (1.0 - m)
    big = h >= h0
    hb = np.where(big, h, h0)
    with np.errstate(invalid="ignore"):
        f = np.where(big, k * hb ** (1.0 - m), f0 * h / h0)
        g = np.where(big, (1.0 - m) * k * hb ** (-m), f0 / h0)
    return f, g


def force(c: KienzleCoefficients, h: Any, kappa: Any, cl: Any
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Force per unit chip width [N/mm], tangential, radial, axial.

    Parameters
    ----------
    c : KienzleCoefficients
    h : array_like [mm]
        Uncut chip thickness (>= 0 where it cuts; broadcasting with ``kappa``, ``cl``).
    kappa : array_like [rad]
        Axial immersion angle (unused by this law).
    cl : array_like [mm]
        Actual cutting distance of the micro edge.

    Returns
    -------
    Ft, Fr, Fa : ndarray, broadcast shape [N/mm]
        ``Kxe0 + Kxe1 cl + k_x1.1 h^(1-m_x)``.
    """
    h = np.asarray(h, dtype=float)
    cl = np.asarray(cl, dtype=float)
    out = []
    for e0, e1, k, m in zip((c.Kte0_N_mm, c.Kre0_N_mm, c.Kae0_N_mm),
                            (c.Kte1_N_mm2, c.Kre1_N_mm2, c.Kae1_N_mm2), c.k11, c.exponents):
        out.append((e0 + e1 * cl) + _chip_term(k, m, h)[0])
    return out[0], out[1], out[2]


def slope(c: KienzleCoefficients, h: Any, kappa: Any
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``dF/dh`` per unit chip width [N/mm^2]: ``(1-m) k h^(-m)`` (chord below the floor).

    Parameters
    ----------
    c : KienzleCoefficients
    h : array_like [mm]
    kappa : array_like [rad]
        Broadcast with ``h`` (unused by this law).
    """
    h, _ = np.broadcast_arrays(np.asarray(h, dtype=float), np.asarray(kappa, dtype=float))
    g = [_chip_term(k, m, h)[1] for k, m in zip(c.k11, c.exponents)]
    return g[0], g[1], g[2]


def slope_in_kappa(c: KienzleCoefficients) -> None:
    """None: the slope depends on the chip (no closed-form process gain)."""
    return None


def values(c: KienzleCoefficients) -> dict[str, float]:
    """The coefficients by scenario key."""
    return c.as_dict()


def from_values(vals: dict[str, Any], source: str = "") -> KienzleCoefficients:
    """Coefficients from scenario keys (checked)."""
    return KienzleCoefficients(**vals, source=source)


def fit_start() -> dict[str, float]:
    """Starting point of the nonlinear fit: a mid-range steel [N/mm^2], m = 0.25."""
    return {"kc11_t_N_mm2": 1800.0, "kc11_r_N_mm2": 600.0, "kc11_a_N_mm2": 300.0,
            "mc_t": 0.25, "mc_r": 0.25, "mc_a": 0.25}
