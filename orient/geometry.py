"""Tool posture (lead and tilt) at a cutter contact point (``docs/method.md`` §1).

Local frame at a cutter contact point: ``n`` the unit outward normal of the
workpiece surface, ``f`` the feed direction projected onto the plane normal
to ``n`` (unit), ``b = n x f`` the cross-feed. ``(f, b, n)`` is right-handed
(``f x b = n``, ``b x n = f``, ``n x f = b``).

Posture: the tool axis ``u`` (unit, tip toward spindle) is the normal rotated
first about ``b`` by ``lead`` and then about ``f`` by ``tilt``::

    u = sin(lead) f - cos(lead) sin(tilt) b + cos(lead) cos(tilt) n

Sign conventions:

* positive lead leans the axis forward, toward ``+f`` (``u . f = sin(lead)``);
* positive tilt leans the axis toward ``-b`` (``u . b = -cos(lead) sin(tilt)``),
  the right-hand rotation about ``+f``. For a clockwise (M3) spindle on a
  flat surface with zero lead this makes every engaged edge point move into
  the surface: positive tilt = down-cut, negative tilt = up-cut
  (:mod:`orient.engagement`, ``tests/orient/test_gain.py``).

Inverse: ``lead = asin(u . f)`` in ``[-pi/2, pi/2]`` and
``tilt = atan2(-u . b, u . n)`` in ``(-pi, pi]``, a round trip for
``|lead| < pi/2``. Angles are in radians; :class:`Posture` converts from
degrees at the user interface.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .constants import DIRECTION_MIN_NORM

__all__ = ["Posture", "inclination", "lead_tilt_of", "local_frame", "posture_axis"]


def _vectors(name: str, v: Any) -> np.ndarray:
    """Float array with a last axis of 3, finite, refusing anything else."""
    a = np.asarray(v, dtype=float)
    if a.ndim == 0 or a.shape[-1] != 3:
        raise ValueError(f"{name}: expected vectors of 3 components (last axis), got shape "
                         f"{a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: expected finite values, got nan or inf")
    return a


def _unit(name: str, v: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    if np.any(norm < DIRECTION_MIN_NORM):
        raise ValueError(f"{name}: expected non-zero vectors, got a vector of length "
                         f"{float(norm.min()):.3g}")
    return v / norm


def local_frame(normal: Any, feed: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local frame ``(f, b, n)`` at cutter contact points.

    Parameters
    ----------
    normal : array_like, shape (..., 3) [-]
        Outward surface normals (any length > 0; normalized here).
    feed : array_like, shape (..., 3) [-]
        Feed directions (any length); projected onto the plane normal to
        ``normal``. Must not be parallel to the normal.

    Returns
    -------
    f, b, n : ndarray, shape (broadcast, 3) [-]
        Unit feed, cross-feed ``n x f`` and normal; right-handed.
    """
    n = _unit("normal", _vectors("normal", normal))
    fd = _vectors("feed", feed)
    n, fd = np.broadcast_arrays(n, fd)
    f = fd - np.sum(fd * n, axis=-1, keepdims=True) * n
    fn = np.linalg.norm(f, axis=-1, keepdims=True)
    scale = np.maximum(np.linalg.norm(fd, axis=-1, keepdims=True), 1e-300)
    if np.any(fn < DIRECTION_MIN_NORM * scale) or np.any(fn == 0):
        raise ValueError("feed: the feed direction is parallel to the surface normal (or zero); "
                         "no local frame")
    f = f / fn
    b = np.cross(n, f)
    return f, b, np.array(n)


def posture_axis(normal: Any, feed: Any, lead_rad: Any, tilt_rad: Any) -> np.ndarray:
    """Tool axes of postures (lead, tilt) at contact points.

    ``u = sin(lead) f - cos(lead) sin(tilt) b + cos(lead) cos(tilt) n``.

    Parameters
    ----------
    normal, feed : array_like, shape (..., 3) [-]
        As in :func:`local_frame`.
    lead_rad, tilt_rad : array_like [rad]
        Broadcast together and with ``normal.shape[:-1]``: e.g. a (15, 15)
        grid with one normal of shape (3,), or ``normal`` of shape (L, 1, 3)
        with angles of shape (K,) for K postures at each of L points.

    Returns
    -------
    ndarray, shape (broadcast, 3) [-]
        Unit tool axes.
    """
    f, b, n = local_frame(normal, feed)
    lead = np.asarray(lead_rad, dtype=float)
    tilt = np.asarray(tilt_rad, dtype=float)
    for name, a in (("lead_rad", lead), ("tilt_rad", tilt)):
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name}: expected finite values, got nan or inf")
    sl, cl = np.sin(lead)[..., None], np.cos(lead)[..., None]
    st, ct = np.sin(tilt)[..., None], np.cos(tilt)[..., None]
    return sl * f - (cl * st) * b + (cl * ct) * n


def lead_tilt_of(axis: Any, normal: Any, feed: Any) -> tuple[np.ndarray, np.ndarray]:
    """Lead and tilt of tool axes (inverse of :func:`posture_axis`).

    Parameters
    ----------
    axis : array_like, shape (..., 3) [-]
        Tool axes (normalized here).
    normal, feed : array_like, shape (..., 3) [-]
        As in :func:`local_frame`; broadcast with ``axis``.

    Returns
    -------
    lead, tilt : ndarray, shape (broadcast,) [rad]
        ``lead`` in ``[-pi/2, pi/2]``, ``tilt`` in ``(-pi, pi]`` (0 where the
        axis is along ``+-f``).
    """
    u = _unit("axis", _vectors("axis", axis))
    f, b, n = local_frame(normal, feed)
    uf = np.clip(np.sum(u * f, axis=-1), -1.0, 1.0)
    ub = np.sum(u * b, axis=-1)
    un = np.sum(u * n, axis=-1)
    return np.arcsin(uf), np.arctan2(-ub, un)


def inclination(axis: Any, normal: Any) -> np.ndarray:
    """Angle between tool axes and surface normals, ``acos(u . n)`` [rad].

    Parameters
    ----------
    axis, normal : array_like, shape (..., 3) [-]
        Normalized here; broadcast together.

    Returns
    -------
    ndarray, shape (broadcast,) [rad]
        In ``[0, pi]``.
    """
    u = _unit("axis", _vectors("axis", axis))
    n = _unit("normal", _vectors("normal", normal))
    return np.arccos(np.clip(np.sum(u * n, axis=-1), -1.0, 1.0))


@dataclass(frozen=True)
class Posture:
    """Lead and tilt of the tool axis in the local frame (module docstring).

    Attributes
    ----------
    lead_rad : float [rad]
        Rotation about ``b``; positive leans the axis toward ``+f``.
    tilt_rad : float [rad]
        Rotation about ``f``; positive leans the axis toward ``-b``.
    """

    lead_rad: float
    tilt_rad: float

    def __post_init__(self) -> None:
        for name in ("lead_rad", "tilt_rad"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise ValueError(f"posture.{name}: expected a number, got {v!r}")
            if not math.isfinite(v):
                raise ValueError(f"posture.{name}: expected a finite value, got {v!r}")
            object.__setattr__(self, name, float(v))
        if not abs(self.lead_rad) < math.pi / 2:
            raise ValueError(f"posture.lead_rad: expected |lead| < pi/2, got {self.lead_rad!r}")

    @classmethod
    def from_deg(cls, lead_deg: float, tilt_deg: float) -> Posture:
        """Posture from angles in degrees.

        Parameters
        ----------
        lead_deg, tilt_deg : float [deg]
        """
        for name, v in (("lead_deg", lead_deg), ("tilt_deg", tilt_deg)):
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise ValueError(f"{name}: expected a number, got {v!r}")
            if not math.isfinite(v):
                raise ValueError(f"{name}: expected a finite value, got {v!r}")
        return cls(math.radians(lead_deg), math.radians(tilt_deg))

    @property
    def lead_deg(self) -> float:
        """Lead angle [deg]."""
        return math.degrees(self.lead_rad)

    @property
    def tilt_deg(self) -> float:
        """Tilt angle [deg]."""
        return math.degrees(self.tilt_rad)

    def axis(self, normal: Any, feed: Any) -> np.ndarray:
        """Tool axis of this posture, shape (..., 3) [-] (:func:`posture_axis`).

        Parameters
        ----------
        normal, feed : array_like, shape (..., 3) [-]
        """
        return posture_axis(normal, feed, self.lead_rad, self.tilt_rad)
