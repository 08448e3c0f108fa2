"""Arc geometry from the words of a G2/G3 block: centre, radii, sweep.

Pure geometry, no I/O: :func:`arc_from_words` raises :class:`ArcWordError`
naming the offending word, and the reader turns it into an
:class:`~nc.errors.NCParseError` with the word's column.

Conventions: in-plane axes ``(a1, a2)`` and axial ``ax`` from
:data:`nc.program.PLANE_AXES` (LinuxCNC's order); sweep positive
counter-clockwise about the plane's axis (G3), negative for G2; a G2/G3
whose end is its start is a full circle; LinuxCNC's ``P`` adds turns; an R
arc with R > 0 is the short one (<= 180 deg), R < 0 the long one. Start and
end radius may differ within LinuxCNC's tolerance (``nc.constants``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from . import constants as K
from .errors import InputError
from .program import PLANE_AXES

__all__ = ["ArcWordError", "arc_from_words", "arc_sweep"]


class ArcWordError(InputError):
    """An arc's words do not make an arc; ``letter`` names the word, if one."""

    def __init__(self, letter: str | None, message: str) -> None:
        self.letter = letter
        super().__init__(message)



def arc_sweep(c1: float, c2: float, s1: float, s2: float, e1: float, e2: float,
              sign: float) -> float:
    """Signed sweep [rad] about (c1, c2) from start (s1, s2) to end (e1, e2): in
    ``(0, 2 pi]`` counter-clockwise (``sign`` > 0), ``[-2 pi, 0)`` clockwise; an end
    on the start is a full turn [mm in, rad out]."""
    ang_s = math.atan2(s2 - c2, s1 - c1)
    ang_e = math.atan2(e2 - c2, e1 - c1)
    sweep = ang_e - ang_s
    if sign > 0:
        while sweep <= 1e-12:
            sweep += 2 * math.pi
    else:
        while sweep >= -1e-12:
            sweep -= 2 * math.pi
    return sweep

def arc_from_words(vals: Mapping[str, float], motion_mode: int, plane: int, scale: float,
                   arc_distance: int, start: Sequence[float], end: Sequence[float]):
    """Centre, radii and sweep of an arc move.

    Parameters
    ----------
    vals : mapping of str to float
        The block's words as programmed (I J K R in program units, P turns).
    motion_mode : int
        2 (G2, clockwise) or 3 (G3).
    plane : int
        17, 18 or 19.
    scale : float [mm per program unit]
        1 for G21, 25.4 for G20.
    arc_distance : int
        911 (IJK incremental from the start, G91.1) or 901 (absolute).
    start, end : sequence of 6 float [mm, rad]
        Start and end of the move, program frame.

    Returns
    -------
    centre : list of 3 float [mm]
        In-plane centre at the start's axial coordinate.
    radii : tuple of 2 float [mm]
        Start and end radius.
    sweep : float [rad]
        Signed sweep, turns included.
    """
    a1, a2, ax = PLANE_AXES[plane]
    letters = "IJK"
    l1, l2, lax = letters[a1], letters[a2], letters[ax]
    if lax in vals:
        raise ArcWordError(lax, f"{lax} word in a G{plane} arc; "
                               f"expected only {l1} and {l2} (or R)")
    s1, s2, e1, e2 = start[a1], start[a2], end[a1], end[a2]
    sign = 1.0 if motion_mode == 3 else -1.0
    turns = 1
    if "P" in vals:
        p = vals["P"]
        if not 1 <= p <= K.MAX_ARC_TURNS or p != int(p):
            raise ArcWordError("P", "expected P (arc turns) to be a whole number from 1 "
                                    f"to {K.MAX_ARC_TURNS} (nc.constants.MAX_ARC_TURNS)")
        turns = int(p)
    if "R" in vals:
        if l1 in vals or l2 in vals:
            raise ArcWordError("R", "both R and a centre word in one "
                                   f"arc; expected either R or {l1} {l2}")
        r = vals["R"] * scale
        d1, d2 = e1 - s1, e2 - s2
        chord = math.hypot(d1, d2)
        if chord < 1e-12:
            raise ArcWordError("R", "R arc whose end point is its "
                                   "start point; expected I J K for a full circle")
        half = chord / 2
        if half > abs(r) + K.ARC_R_CHORD_TOL_MM or r == 0:
            raise ArcWordError("R",
                                   f"impossible arc: the chord ({chord:.6g} mm) is longer "
                                   f"than the diameter 2|R| ({2 * abs(r):.6g} mm)")
        h = math.sqrt(max(r * r - half * half, 0.0))
        # centre right of the chord for a short G2, left for a short G3
        side = -sign if r > 0 else sign
        u1, u2 = d1 / chord, d2 / chord
        c1 = (s1 + e1) / 2 + side * h * u2
        c2 = (s2 + e2) / 2 - side * h * u1
    else:
        if l1 not in vals and l2 not in vals:
            raise ArcWordError(None, f"arc without a centre; expected {l1} and/or {l2}, "
                              "or R")
        if arc_distance == 911:
            c1 = s1 + vals.get(l1, 0.0) * scale
            c2 = s2 + vals.get(l2, 0.0) * scale
        else:
            c1 = vals.get(l1, 0.0) * scale
            c2 = vals.get(l2, 0.0) * scale
    rs = math.hypot(s1 - c1, s2 - c2)
    re_ = math.hypot(e1 - c1, e2 - c2)
    if rs < 1e-9:
        raise ArcWordError(None, "arc of zero radius: the centre is the start point")
    tol = min(K.ARC_RADIUS_TOL_MAX_MM,
              max(K.ARC_RADIUS_TOL_ABS_MM, K.ARC_RADIUS_TOL_REL * rs))
    if abs(rs - re_) > tol:
        raise ArcWordError(None, f"arc start radius {rs:.6g} mm and end radius "
                          f"{re_:.6g} mm differ by {abs(rs - re_):.3g} mm; expected "
                          f"them equal within {tol:.3g} mm")
    sweep = arc_sweep(c1, c2, s1, s2, e1, e2, sign)
    sweep += sign * 2 * math.pi * (turns - 1)
    centre = [0.0, 0.0, 0.0]
    centre[a1], centre[a2], centre[ax] = c1, c2, start[ax]
    return centre, (rs, re_), sweep
