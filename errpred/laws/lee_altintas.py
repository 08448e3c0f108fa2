"""Ball-end coefficients that vary with the contact angle kappa (Lee & Altintas).

Along a ball end mill's edge the rake, helix and cutting speed change with the
axial immersion (contact) angle ``kappa``, and so do the cutting coefficients.
Per micro edge and unit chip width, direction ``x`` in (t, r, a)::

    F_x(h)  = Kxe(kappa) + Kxe1 cl + Kxc(kappa) h            [N/mm]
    dF_x/dh = Kxc(kappa)                                     [N/mm^2]
    Kxc(kappa) = sum_i Kxc[i] kappa^i,  Kxe(kappa) = sum_i Kxe[i] kappa^i

``kappa`` in radians (0 at the tip, pi/2 on the flank), so the polynomial's
i-th coefficient is in N/mm^2 per rad^i (chip) or N/mm per rad^i (edge). A
polynomial of degree 0 is the linear law. The wear growth ``Kxe1`` is the
linear law's (a constant). The slope does not depend on the chip: orient's
process gain stays in closed form (the kernels evaluate the polynomial at each
micro edge's kappa, :func:`slope_in_kappa`).

References
----------
.. [1] P. Lee, Y. Altintas, "Prediction of ball-end milling forces from
   orthogonal cutting data", *Int. J. Mach. Tools Manuf.* 36(9) (1996)
   1059-1072 (coefficients varying along the ball edge with kappa).
.. [2] J. Gradišek, M. Kalveram, K. Weinert, "Mechanistic identification of
   specific force coefficients for a general end mill", *Int. J. Mach. Tools
   Manuf.* 44(4) (2004) 401-414 (coefficients as functions of the position on
   the edge, identified from mean forces).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from ..coefficients import LawCoefficients, finite_coefficient
from ..constants import LEE_ALTINTAS_MAX_DEGREE

__all__ = ["NAME", "KEYS", "Coefficients", "LeeAltintasCoefficients", "force", "from_values",
           "slope", "slope_in_kappa", "values"]

NAME = "lee-altintas"
_CHIP = ("Ktc_N_mm2", "Krc_N_mm2", "Kac_N_mm2")
_EDGE = ("Kte0_N_mm", "Kre0_N_mm", "Kae0_N_mm")
_WEAR = ("Kte1_N_mm2", "Kre1_N_mm2", "Kae1_N_mm2")
KEYS = {**{k: ("polynomial", True) for k in _CHIP + _EDGE},
        **{k: ("number", False) for k in _WEAR}}


def _poly(name: str, v: Any) -> tuple[float, ...]:
    if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool):
        v = (v,)
    if isinstance(v, (str, bytes)) or not hasattr(v, "__len__") or len(v) == 0:
        raise ValueError(f"cutting coefficient {name}: expected a non-empty sequence of "
                         f"polynomial coefficients in kappa, got {v!r}")
    if len(v) > LEE_ALTINTAS_MAX_DEGREE + 1:
        raise ValueError(f"cutting coefficient {name}: degree {len(v) - 1} above "
                         f"LEE_ALTINTAS_MAX_DEGREE={LEE_ALTINTAS_MAX_DEGREE}")
    return tuple(finite_coefficient(f"{name}[{i}]", x) for i, x in enumerate(v))


@dataclass(frozen=True)
class LeeAltintasCoefficients(LawCoefficients):
    """Coefficient polynomials in kappa (module docstring).

    Attributes
    ----------
    Ktc_N_mm2, Krc_N_mm2, Kac_N_mm2 : tuple of float [N/mm^2 per rad^i]
        Chip coefficients' polynomial coefficients, constant term first.
    Kte0_N_mm, Kre0_N_mm, Kae0_N_mm : tuple of float [N/mm per rad^i]
        Edge coefficients' (new tool).
    Kte1_N_mm2, Kre1_N_mm2, Kae1_N_mm2 : float [N/mm^2]
        Wear growth of the edge force per mm of cutting distance (default 0).
    source : str
    """

    Ktc_N_mm2: tuple
    Krc_N_mm2: tuple
    Kac_N_mm2: tuple
    Kte0_N_mm: tuple
    Kre0_N_mm: tuple
    Kae0_N_mm: tuple
    Kte1_N_mm2: float = 0.0
    Kre1_N_mm2: float = 0.0
    Kae1_N_mm2: float = 0.0
    source: str = field(default="", compare=False)
    law: ClassVar[str] = NAME

    def __post_init__(self) -> None:
        for name in _CHIP + _EDGE:
            object.__setattr__(self, name, _poly(name, getattr(self, name)))
        for name in _WEAR:
            object.__setattr__(self, name, finite_coefficient(name, getattr(self, name)))

    def as_dict(self) -> dict[str, Any]:
        """The coefficients by field name (polynomials as lists; ``source`` left out)."""
        return {n: (list(getattr(self, n)) if n in _CHIP + _EDGE else getattr(self, n))
                for n in _CHIP + _EDGE + _WEAR}


Coefficients = LeeAltintasCoefficients


def _eval(p: tuple, kappa: np.ndarray) -> np.ndarray:
    """Horner; a constant polynomial gives exactly its coefficient."""
    out = np.full(kappa.shape, p[-1])
    for a in reversed(p[:-1]):
        out = out * kappa + a
    return out


def force(c: LeeAltintasCoefficients, h: Any, kappa: Any, cl: Any
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Force per unit chip width [N/mm], tangential, radial, axial.

    Parameters
    ----------
    c : LeeAltintasCoefficients
    h : array_like [mm]
        Uncut chip thickness (broadcasting with ``kappa`` and ``cl``).
    kappa : array_like [rad]
        Axial immersion angle of the micro edge.
    cl : array_like [mm]
        Actual cutting distance of the micro edge.

    Returns
    -------
    Ft, Fr, Fa : ndarray, broadcast shape [N/mm]
        ``Kxe(kappa) + Kxe1 cl + Kxc(kappa) h``.
    """
    h = np.asarray(h, dtype=float)
    k = np.asarray(kappa, dtype=float)
    grow = c.edge_growth(cl)
    return tuple(_eval(e, k) + g + _eval(q, k) * h
                 for e, g, q in zip((c.Kte0_N_mm, c.Kre0_N_mm, c.Kae0_N_mm), grow,
                                    (c.Ktc_N_mm2, c.Krc_N_mm2, c.Kac_N_mm2)))


def slope(c: LeeAltintasCoefficients, h: Any, kappa: Any
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``dF/dh = Kxc(kappa)`` [N/mm^2], broadcast with ``h``.

    Parameters
    ----------
    c : LeeAltintasCoefficients
    h : array_like [mm]
    kappa : array_like [rad]
    """
    _, k = np.broadcast_arrays(np.asarray(h, dtype=float), np.asarray(kappa, dtype=float))
    return tuple(_eval(q, k) for q in (c.Ktc_N_mm2, c.Krc_N_mm2, c.Kac_N_mm2))


def slope_in_kappa(c: LeeAltintasCoefficients) -> np.ndarray:
    """``dF/dh`` as polynomials in kappa, shape (3, d) [N/mm^2 per rad^i], zero-padded."""
    d = max(len(q) for q in (c.Ktc_N_mm2, c.Krc_N_mm2, c.Kac_N_mm2))
    out = np.zeros((3, d))
    for i, q in enumerate((c.Ktc_N_mm2, c.Krc_N_mm2, c.Kac_N_mm2)):
        out[i, :len(q)] = q
    return out


def values(c: LeeAltintasCoefficients) -> dict[str, Any]:
    """The coefficients by scenario key."""
    return c.as_dict()


def from_values(vals: dict[str, Any], source: str = "") -> LeeAltintasCoefficients:
    """Coefficients from scenario keys (checked)."""
    return LeeAltintasCoefficients(**vals, source=source)
