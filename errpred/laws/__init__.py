"""Force laws, side by side: one module per law, one signature.

Each law module offers, for its coefficient class (a
:class:`errpred.coefficients.LawCoefficients`)::

    force(c, h, kappa, cl) -> (Ft, Fr, Fa)     per unit chip width [N/mm]
    slope(c, h, kappa)     -> (dFt/dh, ...)    [N/mm^2]
    slope_in_kappa(c)      -> (3, d) polynomial in kappa of the slope, or None
                              when it depends on the chip
    KEYS, values(c), from_values(d, source)    the scenario's [cutting] table

at micro edges of chip thickness ``h`` [mm], axial immersion angle ``kappa``
[rad] and actual cutting distance ``cl`` [mm]. errpred's forces
(:func:`errpred.force.tool_forces`), orient's process gain and sim's force
table all take these per-edge values; no kernel encodes a law. A new law is a
module here, an entry in :data:`LAWS`, and its tests.
"""

from __future__ import annotations

from types import ModuleType
from typing import Any

import numpy as np

from ..coefficients import LawCoefficients
from . import kienzle, lee_altintas, linear

__all__ = ["LAWS", "force", "law_of", "slope", "slope_in_kappa"]

#: Law name (``[cutting] law``) -> its module.
LAWS: dict[str, ModuleType] = {m.NAME: m for m in (linear, kienzle, lee_altintas)}


def law_of(c: Any) -> ModuleType:
    """The law module of coefficients ``c``; ValueError if ``c`` is not a law's."""
    if not isinstance(c, LawCoefficients) or c.law not in LAWS:
        raise ValueError(f"coeffs: expected the coefficients of a force law "
                         f"({', '.join(LAWS)}), got {type(c).__name__}")
    return LAWS[c.law]


def force(c: LawCoefficients, h: Any, kappa: Any, cl: Any
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``law_of(c).force``: force per unit chip width [N/mm] (t, r, a)."""
    return law_of(c).force(c, h, kappa, cl)


def slope(c: LawCoefficients, h: Any, kappa: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``law_of(c).slope``: ``dF/dh`` per unit chip width [N/mm^2] (t, r, a)."""
    return law_of(c).slope(c, h, kappa)


def slope_in_kappa(c: LawCoefficients) -> np.ndarray | None:
    """``law_of(c).slope_in_kappa``: (3, d) polynomial, or None (chip-dependent)."""
    return law_of(c).slope_in_kappa(c)
