"""Directional matrix of a straight-flute cylindrical end mill in the X-Y plane.

The textbook regenerative milling model (Altintas & Budak 1995; Insperger &
Stepan 2002/2004), written in orient's contract convention: ``F = s H(t)
(q(t) - q(t - tau))`` with ``H`` in N/m, workpiece frame, embedded in 3x3 with
a zero Z row and column. It is the reference for the stability benchmarks
and for checking orient's micro-edge process gain.

Angles and frames (the contract's tool frame with a vertical tool): feed
along ``+X`` (= ``x'``), ``Y`` = ``y'``, clockwise spindle seen from the
spindle; the flute angle ``phi`` is measured from ``+Y`` toward ``+X`` and a
flute sits at ``(R sin phi, R cos phi)``. This is the angle of Altintas and
of Insperger & Stepan (``phi_j(t) = 2 pi n t / 60 + j 2 pi / N``), so their
formulas apply unchanged. With feed ``f_z`` the chip is ``h = f_z sin phi``,
i.e. the chip-thickness direction is ``n = (sin phi, cos phi)``.

Forces on the tool per flute and unit axial depth: tangential ``Kt h``
along ``t = (-cos phi, sin phi)`` (opposing the edge velocity
``(cos phi, -sin phi)``), radial ``Kn h`` along ``-n`` (toward the axis). The
dynamic chip ``h = (q(t) - q(t - tau)) . n`` gives

    ``H(t) = depth sum_j g(phi_j) (Kt t_j - Kn n_j) n_j^T``

so ``H_xx = -depth sum_j g sin phi_j (Kt cos phi_j + Kn sin phi_j)`` (Insperger's
1-DOF ``-w h(t)``); ``H = depth Kt / 2 A(t)`` with Altintas' ``A(t)``.

Immersion: up-milling engages ``phi`` in ``[0, acos(1 - 2 a/D)]``,
down-milling ``[acos(2 a/D - 1), pi]`` (``a/D`` the radial immersion). The
screen function ``g(phi)`` is 1 inside, 0 outside.

Units: cutting coefficients in N/m^2 (as in the papers), axial depth in mm
(converted to m inside: ``H`` [N/m] = coefficient [N/m^2] x depth [m]).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

__all__ = ["StraightEndMill2D", "immersion_angles", "screen"]

_MILLING = ("up", "down")


def immersion_angles(radial_immersion: float, milling: str) -> tuple[float, float]:
    """Entry and exit angles ``(phi_st, phi_ex)`` [rad].

    Parameters
    ----------
    radial_immersion : float
        ``a / D`` in (0, 1].
    milling : str
        ``'up'`` or ``'down'``.
    """
    if isinstance(radial_immersion, (bool, np.bool_)) \
            or not isinstance(radial_immersion, numbers.Real) \
            or not (0.0 < float(radial_immersion) <= 1.0):
        raise ValueError(f"radial_immersion: expected a value in (0, 1], got "
                         f"{radial_immersion!r}")
    if milling not in _MILLING:
        raise ValueError(f"milling: expected 'up' or 'down', got {milling!r}")
    ad = float(radial_immersion)
    if milling == "up":
        return 0.0, math.acos(1.0 - 2.0 * ad)
    return math.acos(2.0 * ad - 1.0), math.pi


def screen(phi: np.ndarray, phi_st: float, phi_ex: float) -> np.ndarray:
    """Screen function ``g(phi)``: 1 where ``phi mod 2 pi`` is in ``[phi_st, phi_ex]``."""
    p = np.mod(phi, 2.0 * math.pi)
    return ((p >= phi_st) & (p <= phi_ex)).astype(float)


@dataclass(frozen=True)
class StraightEndMill2D:
    """Straight-flute cylindrical end mill, 2-D regenerative model.

    Attributes
    ----------
    kt_N_m2 : float [N/m^2]
        Tangential cutting coefficient.
    kn_N_m2 : float [N/m^2]
        Normal (radial) cutting coefficient (``Kr Kt`` in Altintas' notation).
    teeth : int
        Number of equally spaced flutes.
    radial_immersion : float
        ``a / D`` in (0, 1].
    milling : str
        ``'up'`` or ``'down'``.
    depth_mm : float [mm]
        Axial depth of cut (the scaling ``s`` multiplies it).
    """

    kt_N_m2: float
    kn_N_m2: float
    teeth: int
    radial_immersion: float
    milling: str
    depth_mm: float = 1.0

    def __post_init__(self) -> None:
        for name in ("kt_N_m2", "kn_N_m2", "depth_mm"):
            v = getattr(self, name)
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real) \
                    or not math.isfinite(float(v)) or float(v) < 0:
                raise ValueError(f"StraightEndMill2D.{name}: expected a finite value >= 0, "
                                 f"got {v!r}")
            object.__setattr__(self, name, float(v))
        t = self.teeth
        if isinstance(t, (bool, np.bool_)) or not isinstance(t, numbers.Integral) or t < 1:
            raise ValueError(f"StraightEndMill2D.teeth: expected an integer >= 1, got {t!r}")
        object.__setattr__(self, "teeth", int(t))
        immersion_angles(self.radial_immersion, self.milling)
        object.__setattr__(self, "radial_immersion", float(self.radial_immersion))

    @property
    def angles(self) -> tuple[float, float]:
        """``(phi_st, phi_ex)`` [rad]."""
        return immersion_angles(self.radial_immersion, self.milling)

    @property
    def cut_fraction(self) -> float:
        """Fraction of the tooth period during which some flute cuts [-] (at most 1)."""
        st, ex = self.angles
        return min(1.0, (ex - st) * self.teeth / (2.0 * math.pi))

    def recommended_samples(self) -> int:
        """Samples per tooth period for the time-periodic analysis
        (:func:`orient.stability.sdm.recommended_samples` of :attr:`cut_fraction`)."""
        from orient.stability.sdm import recommended_samples

        return recommended_samples(self.cut_fraction)

    def directional_matrix(self, phi0: np.ndarray) -> np.ndarray:
        """``H`` [N/m] at rotation angles ``phi0`` of flute 0 [rad], shape ``phi0.shape + (3, 3)``."""
        phi0 = np.asarray(phi0, dtype=float)
        st, ex = self.angles
        depth_m = self.depth_mm * 1e-3
        out = np.zeros(phi0.shape + (3, 3))
        for j in range(self.teeth):
            phi = phi0 + j * 2.0 * math.pi / self.teeth
            g = screen(phi, st, ex) * depth_m
            s, c = np.sin(phi), np.cos(phi)
            fx = -self.kt_N_m2 * c - self.kn_N_m2 * s         # (Kt t - Kn n)_x
            fy = self.kt_N_m2 * s - self.kn_N_m2 * c          # (Kt t - Kn n)_y
            out[..., 0, 0] += g * fx * s
            out[..., 0, 1] += g * fx * c
            out[..., 1, 0] += g * fy * s
            out[..., 1, 1] += g * fy * c
        return out

    def directional_samples(self, samples: int, *, average: bool = True) -> np.ndarray:
        """``H`` over one tooth period at ``samples`` equal steps [N/m], shape (k, 3, 3).

        With ``average`` (default) sample ``i`` is the exact average of ``H``
        over the step ``[t_i, t_{i+1}]``, ``t_i = i tau / k`` (flute 0 at
        ``phi = 2 pi i / (N k)``), in closed form: the semi-discretization's
        step average that :func:`orient.stability.sdm_margin` expects (the
        entry and exit jumps fall inside steps with their exact weight; the
        period mean is :meth:`mean_directional_matrix`). Without it, the point
        values ``H(t_i)``.
        """
        if isinstance(samples, (bool, np.bool_)) or not isinstance(samples, numbers.Integral) \
                or samples < 2:
            raise ValueError(f"samples: expected an integer >= 2, got {samples!r}")
        k = int(samples)
        dphi = 2.0 * math.pi / (self.teeth * k)
        nodes = dphi * np.arange(k)
        if not average:
            return self.directional_matrix(nodes)
        st, ex = self.angles
        acc = np.zeros((k, 2, 2))
        for j in range(self.teeth):
            for wrap in (-2.0 * math.pi, 0.0):          # flute angles in [0, 4 pi)
                off = j * 2.0 * math.pi / self.teeth + wrap
                a = np.clip(nodes + off, st, ex)
                b = np.clip(nodes + dphi + off, st, ex)
                acc += self._primitive(b) - self._primitive(a)
        out = np.zeros((k, 3, 3))
        out[:, :2, :2] = acc * (self.depth_mm * 1e-3 / dphi)
        return out

    def _primitive(self, p: np.ndarray) -> np.ndarray:
        """``int^p (Kt t - Kn n) n^T dphi`` [N/m^2 rad], shape ``p.shape + (2, 2)``."""
        kt, kn = self.kt_N_m2, self.kn_N_m2
        # int sin^2 = p/2 - sin2p/4, int cos^2 = p/2 + sin2p/4, int sin cos = -cos2p/4
        ss = p / 2 - np.sin(2 * p) / 4
        cc = p / 2 + np.sin(2 * p) / 4
        sc = -np.cos(2 * p) / 4
        return np.stack([np.stack([-kt * sc - kn * ss, -kt * cc - kn * sc], axis=-1),
                         np.stack([kt * ss - kn * sc, kt * sc - kn * cc], axis=-1)], axis=-2)

    def mean_directional_matrix(self) -> np.ndarray:
        """Exact period mean ``P`` of ``H`` [N/m], shape (3, 3) (closed form).

        ``P = depth N / (2 pi) int_{phi_st}^{phi_ex} (Kt t - Kn n) n^T dphi``.
        """
        st, ex = self.angles
        prim = self._primitive
        out = np.zeros((3, 3))
        scale = self.depth_mm * 1e-3 * self.teeth / (2 * math.pi)
        out[:2, :2] = (prim(np.float64(ex)) - prim(np.float64(st))) * scale
        return out
