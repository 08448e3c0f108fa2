"""Cutting force coefficients of the linear edge-force law (the laws side by
side: :mod:`errpred.laws`; identification from measured forces:
:mod:`errpred.calibration` and :mod:`errpred.fit`).

The force model (``docs/method.md`` §4, ``errpred/force.py``) is, per micro
edge and rotation step, while the edge cuts::

    dFt = (Kte0 + Kte1 cl + Ktc h) db
    dFr = (Kre0 + Kre1 cl + Krc h) db
    dFa = (Kae0 + Kae1 cl + Kac h) db

Units of the coefficients:

* ``Ktc_N_mm2``, ``Krc_N_mm2``, ``Kac_N_mm2`` -- chip (shearing) coefficients,
  force per chip area [N/mm^2] (``h`` and ``db`` in mm);
* ``Kte0_N_mm``, ``Kre0_N_mm``, ``Kae0_N_mm`` -- edge (rubbing) coefficients of
  a new tool, force per unit chip width [N/mm];
* ``Kte1_N_mm2``, ``Kre1_N_mm2``, ``Kae1_N_mm2`` -- growth of the edge
  coefficients per mm of actual cutting distance ``cl`` of the micro edge:
  N/mm per mm = [N/mm^2].

Identification (:func:`errpred.calibration.fit_coefficients`) is linear least
squares (the model is linear in the nine coefficients).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np


__all__ = [
    "CHIP_AND_EDGE_NAMES",
    "WEAR_NAMES",
    "CuttingCoefficients",
    "LawCoefficients",
    "finite_coefficient",
]

#: The six coefficients fitted from new-tool measurements, in column order.
CHIP_AND_EDGE_NAMES = ("Ktc_N_mm2", "Krc_N_mm2", "Kac_N_mm2", "Kte0_N_mm", "Kre0_N_mm",
                       "Kae0_N_mm")
#: The three wear growth coefficients fitted from worn-tool measurements.
WEAR_NAMES = ("Kte1_N_mm2", "Kre1_N_mm2", "Kae1_N_mm2")


class LawCoefficients:
    """Base of every force law's coefficients (:mod:`errpred.laws`).

    A subclass names its law (:attr:`law`, the key of ``errpred.laws.LAWS``
    and of a scenario's ``[cutting] law``) and carries, whatever the law,
    the wear growth of the edge (rubbing) force per mm of actual cutting
    distance, ``Kte1_N_mm2, Kre1_N_mm2, Kae1_N_mm2`` [N/mm^2], which
    :func:`errpred.physics.wear_influence` uses.
    """

    law: ClassVar[str] = ""
    Kte1_N_mm2: float
    Kre1_N_mm2: float
    Kae1_N_mm2: float

    def edge_growth(self, cl_mm: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Wear growth of the edge force at cutting distance ``cl_mm`` [mm]: ``Kxe1 cl``
        [N/mm], tangential, radial, axial."""
        cl = np.asarray(cl_mm, dtype=float)
        return self.Kte1_N_mm2 * cl, self.Kre1_N_mm2 * cl, self.Kae1_N_mm2 * cl


def finite_coefficient(name: str, v: Any) -> float:
    """``v`` as a float, or ``ValueError`` naming ``name`` when it is not a finite number."""
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise ValueError(f"cutting coefficient {name}: expected a number, got {v!r}")
    if not math.isfinite(v):
        raise ValueError(f"cutting coefficient {name}: expected a finite value, got {v!r}")
    return float(v)


@dataclass(frozen=True)
class CuttingCoefficients(LawCoefficients):
    """Linear edge-force model coefficients with wear growth of the edge terms.

    Attributes
    ----------
    Ktc_N_mm2, Krc_N_mm2, Kac_N_mm2 : float [N/mm^2]
        Chip (shearing) coefficients: tangential, radial, axial.
    Kte0_N_mm, Kre0_N_mm, Kae0_N_mm : float [N/mm]
        Edge (rubbing) coefficients of a new tool.
    Kte1_N_mm2, Kre1_N_mm2, Kae1_N_mm2 : float [N/mm^2]
        Growth of the edge coefficients per mm of actual cutting distance.
    source : str
        Where the values come from (free text; not compared, not a field of
        :meth:`as_dict`).

    Every value must be finite (zero and negative values are allowed: a
    fitted coefficient may come out slightly negative); a non-finite value
    raises ``ValueError`` naming the field.
    """

    Ktc_N_mm2: float
    Krc_N_mm2: float
    Kac_N_mm2: float
    Kte0_N_mm: float
    Kre0_N_mm: float
    Kae0_N_mm: float
    Kte1_N_mm2: float = 0.0
    Kre1_N_mm2: float = 0.0
    Kae1_N_mm2: float = 0.0
    source: str = field(default="", compare=False)
    law: ClassVar[str] = "linear"

    def __post_init__(self) -> None:
        for name in CHIP_AND_EDGE_NAMES + WEAR_NAMES:
            object.__setattr__(self, name, finite_coefficient(name, getattr(self, name)))
        if not isinstance(self.source, str):
            raise ValueError(f"cutting coefficients source: expected a string, got "
                             f"{self.source!r}")

    # --- the model ------------------------------------------------------------
    def edge(self, cl_mm: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Edge coefficients at actual cutting distance ``cl_mm``.

        Parameters
        ----------
        cl_mm : array_like, any shape [mm]
            Actual cutting distance of the micro edges.

        Returns
        -------
        Kte, Kre, Kae : ndarray, shape of ``cl_mm`` [N/mm]
            ``Kxe0 + Kxe1 * cl``.
        """
        cl = np.asarray(cl_mm, dtype=float)
        return (self.Kte0_N_mm + self.Kte1_N_mm2 * cl,
                self.Kre0_N_mm + self.Kre1_N_mm2 * cl,
                self.Kae0_N_mm + self.Kae1_N_mm2 * cl)

    @property
    def chip(self) -> tuple[float, float, float]:
        """``(Ktc, Krc, Kac)`` [N/mm^2]."""
        return self.Ktc_N_mm2, self.Krc_N_mm2, self.Kac_N_mm2

    # --- I/O ------------------------------------------------------------------
    def as_dict(self) -> dict[str, float]:
        """The nine coefficients, keys = field names (``source`` left out)."""
        return {name: getattr(self, name) for name in CHIP_AND_EDGE_NAMES + WEAR_NAMES}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], source: str = "") -> CuttingCoefficients:
        """Coefficients from a mapping with the field names as keys.

        The six chip and new-tool edge coefficients are required, the three
        wear coefficients default to 0. An unknown key (a misspelt name, a
        unit missing from the name) is refused, naming it.

        Parameters
        ----------
        d : mapping of str to float
        source : str
            Recorded in :attr:`source` (e.g. the file the values came from).
        """
        if not isinstance(d, Mapping):
            raise ValueError(f"cutting coefficients{_where(source)}: expected a mapping, got "
                             f"{type(d).__name__}")
        known = set(CHIP_AND_EDGE_NAMES + WEAR_NAMES)
        unknown = [k for k in d if k not in known]
        if unknown:
            raise ValueError(f"cutting coefficients{_where(source)}: unknown key(s) "
                             f"{', '.join(map(repr, unknown))}; expected "
                             f"{', '.join(CHIP_AND_EDGE_NAMES + WEAR_NAMES)}")
        missing = [k for k in CHIP_AND_EDGE_NAMES if k not in d]
        if missing:
            raise ValueError(f"cutting coefficients{_where(source)}: missing key(s) "
                             f"{', '.join(missing)}")
        try:
            return cls(**{k: d[k] for k in d}, source=source)
        except ValueError as exc:
            raise ValueError(f"{exc}{_where(source)}") from None

    def replace(self, **changes: Any) -> CuttingCoefficients:
        """A copy with some fields changed."""
        vals = self.as_dict()
        vals.update(changes)
        src = vals.pop("source", self.source)
        return CuttingCoefficients(**vals, source=src)


def _where(source: str) -> str:
    return f" (from {source})" if source else ""
