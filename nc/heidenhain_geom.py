"""Geometry of Klartext blocks: arcs about a centre, tangential arcs, frames.

Pure functions on plain floats; the reader turns :class:`GeomError` into an
:class:`~nc.errors.NCParseError` at the block. Arc conventions are
:mod:`nc.arcs`'s: in-plane axes ``(a1, a2)`` and axial ``ax`` from
:data:`nc.program.PLANE_AXES`, sweep positive counter-clockwise (``DR+``).
"""

from __future__ import annotations

import math

import numpy as np

from . import constants as K
from .arcs import arc_sweep
from .errors import InputError

__all__ = ["GeomError", "sweep_to", "check_radii", "tangent_centre", "spatial_rotation",
           "arc_points"]


class GeomError(InputError):
    """Geometry that cannot be: a radius mismatch, an arc of zero radius..."""


def sweep_to(c1: float, c2: float, s1: float, s2: float, e1: float, e2: float,
             sign: float) -> float:
    """Signed sweep [rad] from start to end about (c1, c2); a full turn if they meet."""
    sweep = arc_sweep(c1, c2, s1, s2, e1, e2, sign)
    # an end that meets the start within rounding is a full circle, not a sliver
    if abs(abs(sweep) - 2 * math.pi) < 1e-9:
        sweep = sign * 2 * math.pi
    return sweep


def check_radii(c1: float, c2: float, s1: float, s2: float, e1: float, e2: float
                ) -> tuple[float, float]:
    """Start and end radius [mm]; refuses zero radius and a mismatch beyond tolerance."""
    rs = math.hypot(s1 - c1, s2 - c2)
    re_ = math.hypot(e1 - c1, e2 - c2)
    if rs < 1e-9:
        raise GeomError("arc of zero radius: the centre (CC) is the start point")
    tol = min(K.ARC_RADIUS_TOL_MAX_MM, max(K.ARC_RADIUS_TOL_ABS_MM, K.ARC_RADIUS_TOL_REL * rs))
    if abs(rs - re_) > tol:
        raise GeomError(f"arc start radius {rs:.6g} mm and end radius {re_:.6g} mm differ by "
                        f"{abs(rs - re_):.3g} mm; expected them equal within {tol:.3g} mm "
                        "(is CC the centre?)")
    return rs, re_


def tangent_centre(s1: float, s2: float, e1: float, e2: float, t1: float, t2: float
                   ) -> tuple[float, float, float]:
    """Centre and direction sign of the arc leaving (s1, s2) along (t1, t2) to (e1, e2)."""
    tn = math.hypot(t1, t2)
    if tn < 1e-12:
        raise GeomError("CT: the previous contour element has no direction in this plane; "
                        "expected a line or arc before CT that moves in the arc's plane")
    t1, t2 = t1 / tn, t2 / tn
    d1, d2 = e1 - s1, e2 - s2
    cross = t1 * d2 - t2 * d1
    dd = d1 * d1 + d2 * d2
    if dd < 1e-18:
        raise GeomError("CT: end point equals start point; expected a different end point")
    if abs(cross) < 1e-9 * math.sqrt(dd):
        raise GeomError("CT: the end point lies on the tangent of the previous element; "
                        "a tangential arc to it would be a straight line (use L)")
    rho = dd / (2 * cross)  # signed radius, > 0: centre on the left, counter-clockwise
    return s1 - rho * t2, s2 + rho * t1, 1.0 if rho > 0 else -1.0


def spatial_rotation(a_deg: float, b_deg: float, c_deg: float) -> np.ndarray:
    """Rotation of the TNC's spatial angles: about fixed X by A, then Y by B, then Z by C.

    Returns ``Rz(C) @ Ry(B) @ Rx(A)``; its columns are the tilted X, Y, Z
    axes in the untilted frame, so a tilted point ``p`` is ``R @ p`` there.
    """
    a, b, c = (math.radians(v) for v in (a_deg, b_deg, c_deg))
    ca, sa, cb, sb, cc, sc = math.cos(a), math.sin(a), math.cos(b), math.sin(b), \
        math.cos(c), math.sin(c)
    rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    rz = np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]])
    return rz @ ry @ rx


def arc_points(axes: tuple[int, int, int], start: np.ndarray, end: np.ndarray,
               centre: tuple[float, float], radii: tuple[float, float], sweep: float,
               chord_tol_mm: float) -> np.ndarray:
    """Chord end points (k, 3) of an arc within the chord tolerance, the end exactly."""
    a1, a2, ax = axes
    r = max(radii)
    ratio = min(max(1.0 - chord_tol_mm / max(r, 1e-12), -1.0), 1.0)
    step = 2.0 * math.acos(ratio) if ratio < 1.0 else math.pi
    k = max(1, math.ceil(abs(sweep) / min(max(step, 1e-6), math.pi / 2)))
    t = np.arange(1, k + 1) / k
    ang0 = math.atan2(start[a2] - centre[1], start[a1] - centre[0])
    ang = ang0 + t * sweep
    rr = radii[0] + t * (radii[1] - radii[0])
    pts = np.empty((k, 3))
    pts[:, a1] = centre[0] + rr * np.cos(ang)
    pts[:, a2] = centre[1] + rr * np.sin(ang)
    pts[:, ax] = start[ax] + t * (end[ax] - start[ax])
    pts[-1] = end
    return pts
