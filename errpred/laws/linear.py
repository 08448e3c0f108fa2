"""The linear edge-force law (the project's default; ``docs/method.md`` §4).

Per micro edge and unit chip width, direction ``x`` in (t, r, a)::

    F_x(h) = Kxe0 + Kxe1 cl + Kxc h          [N/mm]
    dF_x/dh = Kxc                            [N/mm^2]

The coefficients are :class:`errpred.coefficients.CuttingCoefficients`. The
slope does not depend on the chip, so orient's process gain is integrated in
closed form (:func:`slope_in_kappa` gives it as a constant polynomial).

References
----------
.. [1] Y. Altintas, *Manufacturing Automation*, 2nd ed., Cambridge University
   Press, 2012, §2.3 (the linear edge-force model of milling).
.. [2] E. Budak, Y. Altintas, E. J. A. Armarego, "Prediction of milling force
   coefficients from orthogonal cutting data", *J. Manuf. Sci. Eng.* 118(2)
   (1996) 216-224.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..coefficients import CHIP_AND_EDGE_NAMES, WEAR_NAMES, CuttingCoefficients

__all__ = ["NAME", "KEYS", "Coefficients", "fit_start", "force", "from_values", "slope",
           "slope_in_kappa", "values"]

#: The law's name (``[cutting] law``).
NAME = "linear"
#: The coefficient class.
Coefficients = CuttingCoefficients
#: Scenario keys: name -> (kind, required). Kinds: "number", "positive" (> 0),
#: "fraction" (0 <= v <= KIENZLE_MAX_MC), "polynomial" (array of numbers).
KEYS = {**{k: ("positive" if k == "Ktc_N_mm2" else "number", True)
           for k in CHIP_AND_EDGE_NAMES},
        **{k: ("number", False) for k in WEAR_NAMES}}
#: The coefficients a fit from new-tool mean forces identifies, in order.
FIT_NAMES = CHIP_AND_EDGE_NAMES


def force(c: CuttingCoefficients, h: Any, kappa: Any, cl: Any
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Force per unit chip width, tangential, radial, axial.

    Parameters
    ----------
    c : CuttingCoefficients
    h : array_like [mm]
        Uncut chip thickness (broadcasting with ``kappa`` and ``cl``).
    kappa : array_like [rad]
        Axial immersion angle of the micro edge (unused by this law).
    cl : array_like [mm]
        Actual cutting distance of the micro edge.

    Returns
    -------
    Ft, Fr, Fa : ndarray, broadcast shape [N/mm]
        ``Kxe0 + Kxe1 cl + Kxc h``.
    """
    h = np.asarray(h, dtype=float)
    kte, kre, kae = c.edge(cl)
    return kte + c.Ktc_N_mm2 * h, kre + c.Krc_N_mm2 * h, kae + c.Kac_N_mm2 * h


def slope(c: CuttingCoefficients, h: Any, kappa: Any
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``dF/dh`` per unit chip width [N/mm^2]: ``Kxc``, broadcast to ``h`` and ``kappa``.

    Parameters
    ----------
    c : CuttingCoefficients
    h : array_like [mm]
    kappa : array_like [rad]
    """
    shape = np.broadcast(np.asarray(h, dtype=float), np.asarray(kappa, dtype=float)).shape
    return tuple(np.full(shape, k) for k in c.chip)


def slope_in_kappa(c: CuttingCoefficients) -> np.ndarray:
    """``dF/dh`` as polynomials in kappa, shape (3, 1) [N/mm^2]: the constant ``Kxc``."""
    return np.array(c.chip, dtype=float).reshape(3, 1)


def values(c: CuttingCoefficients) -> dict[str, float]:
    """The coefficients by scenario key (``[cutting]`` table, law key left out)."""
    return c.as_dict()


def from_values(vals: dict[str, Any], source: str = "") -> CuttingCoefficients:
    """Coefficients from scenario keys (checked: finite numbers)."""
    return CuttingCoefficients.from_dict(vals, source=source)


def fit_start() -> dict[str, float]:
    """A starting point of a nonlinear fit (the linear fit is linear: unused there)."""
    return dict.fromkeys(FIT_NAMES, 1.0)
