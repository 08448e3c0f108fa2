"""Cutter contact points of a ball end mill on the design surface.

A ball end mill touches the surface it finishes at the point nearest its
centre (``tip + R u``), and the surface normal there points from that point
to the centre: the contact and the normal follow from the design mesh alone
(trimesh's closest-point query), whatever orientation the CAM chose. Changing
the orientation about the ball centre keeps the contact point and the
finished surface (method.md §7); the tip moves to ``centre - R u_new``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nc.path import CutterLocations
from .constants import CONTACT_TOL_MM

__all__ = ["CONTACT_TOL_MM", "Contacts", "ball_contacts", "feed_directions"]



@dataclass(frozen=True, eq=False)
class Contacts:
    """Contact of the ball with the design at each cutter location.

    Attributes
    ----------
    centre : ndarray, shape (n, 3) [mm]
        Ball centres.
    point : ndarray, shape (n, 3) [mm]
        Nearest design point to the centre.
    normal : ndarray, shape (n, 3)
        Unit outward surface normal at the contact (centre minus point).
    gap_mm : ndarray, shape (n,) [mm]
        Distance of the centre from the design minus R (0 in contact,
        negative: the CAM path gouges).
    touching : ndarray of bool, shape (n,)
        ``|gap| <= CONTACT_TOL_MM`` on a feed move.
    feed : ndarray, shape (n, 3)
        Unit direction of the ball centre's motion at the point: the direction in
        which the contact moves over the part. (The tip's motion is not: where the
        posture changes between two points, the tip also swings with the axis.)
    """

    centre: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    gap_mm: np.ndarray
    touching: np.ndarray
    feed: np.ndarray


def feed_directions(tip: np.ndarray, rapid: np.ndarray) -> np.ndarray:
    """Unit direction of motion of the points ``tip`` (n, 3) [mm], shape (n, 3).

    The move ending at the point; at the first point of a pass (after a
    rapid, or the very first point) the move leaving it. Points that do not
    move get the previous direction (+X if none).
    """
    tip = np.asarray(tip, dtype=float)
    n = len(tip)
    d = np.zeros((n, 3))
    if n > 1:
        d[1:] = np.diff(tip, axis=0)
    start = np.zeros(n, bool)
    start[0] = True
    start[1:] = np.asarray(rapid, bool)[1:] | np.asarray(rapid, bool)[:-1]
    nxt = np.zeros((n, 3))
    nxt[:-1] = d[1:]
    d = np.where(start[:, None], nxt, d)
    norm = np.linalg.norm(d, axis=1)
    out = np.zeros((n, 3))
    last = np.array([1.0, 0.0, 0.0])
    for i in range(n):          # carry the last direction over standstills (rare, short)
        if norm[i] > 1e-12:
            last = d[i] / norm[i]
        out[i] = last
    return out


def ball_contacts(cl: CutterLocations, radius_mm: float, design, *,
                  tol_mm: float = CONTACT_TOL_MM) -> Contacts:
    """Contacts of a ball end mill of radius ``radius_mm`` along ``cl`` with ``design``.

    Parameters
    ----------
    cl : CutterLocations
    radius_mm : float [mm]
        Ball radius.
    design : trimesh.Trimesh
        The design surface (closed or open mesh).
    tol_mm : float [mm]
        A feed move's ball touches where its gap to the design is within this.

    Returns
    -------
    Contacts
    """
    import trimesh

    if not (np.isfinite(radius_mm) and radius_mm > 0):
        raise ValueError(f"radius_mm: expected a finite value > 0, got {radius_mm!r}")
    centre = cl.tip + radius_mm * cl.axis
    point, dist, _ = trimesh.proximity.closest_point(design, centre)
    point = np.asarray(point, dtype=float)
    dist = np.asarray(dist, dtype=float)
    vec = centre - point
    with np.errstate(invalid="ignore", divide="ignore"):
        normal = vec / dist[:, None]
    # a centre on the surface (gouging CAM data): fall back to the tool axis
    bad = ~np.isfinite(normal).all(axis=1)
    normal[bad] = cl.axis[bad]
    inside = design.contains(centre) if design.is_watertight else np.zeros(len(cl), bool)
    gap = np.where(inside, -dist, dist) - radius_mm
    normal[inside] = -normal[inside]
    touching = (np.abs(gap) <= tol_mm) & ~cl.rapid
    return Contacts(centre, point, normal, gap, touching, feed_directions(centre, cl.rapid))
