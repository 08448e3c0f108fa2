"""Coordinate rotation (G68/G69) and tilted working planes (G68.2, G53.1) of Fanuc-family controls.

LinuxCNC has none of these codes (its ``rs274`` refuses them); Fanuc, Haas,
Makino and Okuma's ISO mode have them. While one is in effect the program's
coordinates are in a rotated frame; the reader turns every end point (and
arc centre) into the program frame of the work offset, which is what
:class:`~nc.program.Program` keeps: ``world = t + M @ p``.

* ``G68 X.. Y.. R..`` (G17; G18: Z X, G19: Y Z): rotation by R [deg],
  counter-clockwise seen from the plane's normal, about the centre X Y
  (absolute; the current position when not given). Arcs stay arcs.
* ``G68 X.. Y.. Z.. I.. J.. K.. R..``: Fanuc's 3-D coordinate conversion,
  rotation by R about the direction I J K through X Y Z.
* ``G68.2 X.. Y.. Z.. I.. J.. K..``: tilted working plane, origin X Y Z,
  Euler angles I J K [deg] in Z-X-Z order (turn about Z by I, about the new
  X by J, about the new Z by K): ``M = Rz(I) Rx(J) Rz(K)``, its columns the
  plane's X Y Z axes. Arcs in a plane that the rotation tilts become chords
  (:data:`nc.constants.CHORD_TOL_MM`).
* ``G68.2 P2``: a plane through three points, in blocks of their own that
  follow one another: ``G68.2 P2 Q1 X Y Z`` the first point, which is the
  origin; ``Q2 X Y Z`` the second, the plane's +X from the first;
  ``Q3 X Y Z`` the third, on the plane's +Y side. An optional ``G68.2 P2 Q0
  X Y Z R`` before them gives the shift from the first point to the origin,
  in the plane's axes, and a turn R [deg] about the plane's Z (a post's
  wording of Fanuc's: "amount of shift from the first point to the origin of
  a feature coordinate system"). With ``x = (p2 - p1)/|p2 - p1|``,
  ``z = x × (p3 - p1)`` normalised and ``y = z × x``: ``M = [x y z] Rz(R)``,
  origin ``p1 + [x y z] s``. A shift and a turn together are refused (which
  comes first was not found), as are points on one line
  (:data:`nc.constants.TILT_POINTS_MIN_SIN`).
* ``G68.2 P3``: a plane from two directions: ``G68.2 P3 Q1 X Y Z I J K``
  the origin and the plane's X direction, then ``G68.2 P3 Q2 I J K`` its Z
  direction (the tool axis after G53.1). ``M = [x y z]`` with ``z`` the unit
  Q2 vector, ``x`` Q1's vector made perpendicular to it
  (:data:`nc.constants.TILT_VECTORS_ANGLE_TOL_DEG`), ``y = z × x``.
  Until the last block of a P2/P3 definition no plane is in effect, and any
  other block there is refused.
* ``G68.2 P1`` (roll-pitch-yaw, ``Q123``/``Q321``... the order of the three
  turns) is refused by name. Fanuc's own wording on whether the turns are
  about the workpiece's fixed axes or the axes already turned was not found.
  The public implementations disagree: LinuxCNC's tilted-work-plane remap
  (``remap_twp``) composes ``Rx(I) Ry(J) Rz(K)`` for ``Q123``, turns about
  the moving axes in the order I, J, K (the same as fixed axes in the order
  K, J, I), and a simulator's notes derived from it say the same; another
  implementation found earlier composes the Q order about the fixed axes,
  the reverse product. The two give different planes for the same words
  whenever two of I J K are non-zero, so the reader does not guess. A
  further search (Fanuc 30i/31i and 16i/18i manual pages, the tilted-plane
  and roll-pitch-yaw wording in documentation, issue, page and code
  corpora) found again no Fanuc text on it, only more disagreement: a
  LinuxCNC-derived suite's test takes ``G68.2 P1 Q123 I30 J20`` as
  ``Ry(20) Rx(30)`` (fixed axes) while its remap code composes
  ``Rx Ry Rz`` (moving axes), and post generators write P1 without Q.
* ``G53.1``: the tool is turned along the tilted plane's Z. The reader does
  not know the machine's angles, so it takes the turn as one about the tool
  tip (as under tool centre point control), and from there every row is a
  tool-vector row (:data:`~nc.program.TCP_VECTOR`) whose vector is the
  plane's Z, as the Heidenhain reader stores a tilted plane;
  :func:`nc.path.cutter_locations` gives tip and axis, and
  :mod:`nc.kinematics` the machine's angles. The tool stays turned after
  ``G69`` until rotary words move the axes again.
* ``G69`` cancels the rotation or the plane.

Refused with the word and what is expected: G68 or G68.2 while one is in
effect, a change of plane, work offset or frame (G92, G52, G10, G28, G53)
while one is in effect, rotary words or tool centre point control under
G68.2, G53.1 without G68.2, G68.2 P1 and LinuxCNC's P0 ``Q`` axis orders, an
incomplete or interrupted P2/P3 definition.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import constants as K
from .dialect import code_key, code_name
from .heidenhain_geom import arc_points
from .lexer import find_token
from .program import PLANE_AXES, TCP_OFF

__all__ = ["Rotation", "RotationBlocks", "RotationError", "euler_zxz", "rotation_about",
           "rotation_block", "plane_from_points", "plane_from_vectors"]

G68, G68_2, G69, G53_1 = 680, 682, 690, 531


class RotationError(Exception):
    """A rotation block that cannot be read; ``letter`` is the word to point at."""

    def __init__(self, message: str, letter: str | None = None) -> None:
        super().__init__(message)
        self.letter = letter


def rotation_about(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    """The 3x3 rotation by ``angle_rad`` about the unit vector ``axis`` (right hand)."""
    x, y, z = axis
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    C = 1.0 - c
    return np.array([[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
                     [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
                     [z * x * C - y * s, z * y * C + x * s, c + z * z * C]])


def euler_zxz(i_deg: float, j_deg: float, k_deg: float) -> np.ndarray:
    """Fanuc G68.2 Euler angles: ``Rz(I) @ Rx(J) @ Rz(K)``; columns are the plane's axes."""
    ez, ex = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    return (rotation_about(ez, math.radians(i_deg)) @ rotation_about(ex, math.radians(j_deg))
            @ rotation_about(ez, math.radians(k_deg)))


def plane_from_points(p1, p2, p3) -> np.ndarray:
    """G68.2 P2's frame: columns x (p1 -> p2), y, z = x × (p1 -> p3) (see the module).

    Raises
    ------
    RotationError
        Coincident points or points on one line.
    """
    p1, p2, p3 = (np.asarray(p, dtype=float) for p in (p1, p2, p3))
    u, v = p2 - p1, p3 - p1
    lu, lv = float(np.linalg.norm(u)), float(np.linalg.norm(v))
    if not (lu > 1e-9 and lv > 1e-9):
        raise RotationError("G68.2 P2 with two points at one place; expected three points "
                            "spanning the plane", "Q")
    x = u / lu
    n = np.cross(x, v / lv)
    sn = float(np.linalg.norm(n))
    if not sn > K.TILT_POINTS_MIN_SIN:
        raise RotationError("G68.2 P2 with three points on one line; expected the third "
                            "point off the line through the first two", "Q")
    z = n / sn
    return np.column_stack([x, np.cross(z, x), z])


def plane_from_vectors(xdir, zdir) -> np.ndarray:
    """G68.2 P3's frame: z along ``zdir``, x along ``xdir``'s part perpendicular to it.

    Raises
    ------
    RotationError
        A zero vector, or directions more than
        :data:`nc.constants.TILT_VECTORS_ANGLE_TOL_DEG` from perpendicular.
    """
    a, b = np.asarray(xdir, dtype=float), np.asarray(zdir, dtype=float)
    la, lb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    if not (la > 1e-12 and lb > 1e-12):
        raise RotationError("G68.2 P3 with a zero vector; expected I J K of the plane's X "
                            "(Q1) and Z (Q2) directions", "Q")
    z = b / lb
    off = math.degrees(math.asin(min(1.0, abs(float(a @ z)) / la)))
    if off > K.TILT_VECTORS_ANGLE_TOL_DEG:
        raise RotationError(f"G68.2 P3 X and Z directions {90 - off:.3f} deg apart; expected "
                            f"perpendicular within {K.TILT_VECTORS_ANGLE_TOL_DEG} deg", "Q")
    x = a - (a @ z) * z
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


#: G68.2 P2/P3: the blocks of one definition in order, and each block's words
_PARTS = {2: ((0, "XYZR", ""), (1, "XYZ", "XYZ"), (2, "XYZ", "XYZ"), (3, "XYZ", "XYZ")),
          3: ((1, "XYZIJK", "XYZIJK"), (2, "IJK", "IJK"))}


def _plane_part(vals: dict[str, float], form: int, scale: float, current: "Rotation | None",
                plane: int, held) -> "Rotation":
    """One block of a G68.2 P2/P3 definition: the pending state, or the plane when complete."""
    parts = current.pending[1] if current is not None and current.pending else {}
    order = _PARTS[form]
    if "Q" not in vals:
        raise RotationError(f"G68.2 P{form} without Q; expected Q" +
                            "/Q".join(str(q) for q, _, _ in order), "P")
    q = vals["Q"]
    done = [k for k, _, _ in order if k in parts]
    nxt = [k for k, _, _ in order if k not in parts and (not done or k > done[-1])]
    allowed = nxt[:2] if form == 2 and not done else nxt[:1]  # P2's Q0 may be left out
    if q not in allowed:
        want = " or ".join(f"Q{k}" for k in allowed)
        raise RotationError(f"G68.2 P{form} Q{q:g} here; expected {want} next (the blocks "
                            f"of one definition in order, one after another)", "Q")
    _, words, needed = next(o for o in order if o[0] == q)
    for c in vals:
        if c in "XYZIJKRABC" and c not in words:
            raise RotationError(f"{c} word with G68.2 P{form} Q{int(q)}; expected "
                                f"{' '.join(words)}", c)
    for c in needed:
        if c not in vals:
            raise RotationError(f"G68.2 P{form} Q{int(q)} without {c}; expected "
                                f"{' '.join(needed)}", "Q")
    parts = {**parts, int(q): {c: vals[c] * (scale if c in "XYZ" else 1.0)
                               for c in words if c in vals}}
    if len(parts) < len(order) - (1 if form == 2 and 0 not in parts else 0):
        return Rotation(np.eye(3), np.zeros(3), active=False, axis=held, pending=(form, parts))
    if form == 2:
        pts = [np.array([parts[k][c] for c in "XYZ"]) for k in (1, 2, 3)]
        frame = plane_from_points(*pts)
        q0 = parts.get(0, {})
        shift = np.array([q0.get(c, 0.0) for c in "XYZ"])
        r = q0.get("R", 0.0)
        if r != 0.0 and np.any(shift != 0.0):
            raise RotationError("G68.2 P2 Q0 with both a shift X Y Z and a turn R; expected "
                                "one of them (which applies first was not found in Fanuc's "
                                "text)", "R")
        M = frame @ rotation_about(np.array([0.0, 0.0, 1.0]), math.radians(r))
        return Rotation(M, pts[0] + frame @ shift, tilted=True, plane=plane, axis=held)
    frame = plane_from_vectors([parts[1][c] for c in "IJK"], [parts[2][c] for c in "IJK"])
    origin = np.array([parts[1][c] for c in "XYZ"])
    return Rotation(frame, origin, tilted=True, plane=plane, axis=held)


@dataclass
class Rotation:
    """The rotation in effect, or the tool axis G53.1 left after G69.

    Attributes
    ----------
    M : ndarray, shape (3, 3)
        Rotation; its columns are the rotated X Y Z in the program frame.
    t : ndarray, shape (3,) [mm]
        ``world = t + M @ p``.
    active : bool
        G68/G68.2 in effect (False: only the tool axis is held after G69).
    tilted : bool
        G68.2 (G53.1 may follow).
    plane : int
        The plane the rotation was given in (17, 18, 19).
    axis : tuple of 3 float or None
        Tool axis after G53.1, in the program frame; None before.
    pending : tuple or None
        A G68.2 P2/P3 definition read in part: (P, {Q: words [mm]}); no
        plane is in effect until it is complete.
    """

    M: np.ndarray
    t: np.ndarray
    active: bool = True
    tilted: bool = False
    plane: int = 17
    axis: tuple[float, float, float] | None = None
    pending: tuple[int, dict] | None = None

    def __post_init__(self) -> None:
        # plain floats: one block's conversion is faster without numpy
        self._m = tuple(tuple(float(v) for v in row) for row in self.M)
        self._t = tuple(float(v) for v in self.t)

    def to_program(self, pos: list[float]) -> list[float]:
        """Program-frame position -> the rotated frame's coordinates (rotary kept)."""
        if not self.active:
            return pos
        (a, b, c), (d, e, f), (g, h, i) = self._m
        x, y, z = pos[0] - self._t[0], pos[1] - self._t[1], pos[2] - self._t[2]
        return [a * x + d * y + g * z, b * x + e * y + h * z, c * x + f * y + i * z,
                *pos[3:]]

    def to_world(self, p: list[float] | np.ndarray) -> list[float]:
        """The rotated frame's coordinates -> program frame (rotary kept)."""
        if not self.active:
            return list(p)
        (a, b, c), (d, e, f), (g, h, i) = self._m
        x, y, z = float(p[0]), float(p[1]), float(p[2])
        return [self._t[0] + a * x + b * y + c * z, self._t[1] + d * x + e * y + f * z,
                self._t[2] + g * x + h * y + i * z, *(float(v) for v in p[3:])]

    def keeps_normal(self, plane: int) -> bool:
        """Whether arcs of ``plane`` stay arcs of the same plane (the normal is fixed)."""
        if not self.active:
            return True
        n = PLANE_AXES[plane][2]
        return abs(self.M[n, n] - 1.0) < 1e-12

    def rows(self, motion: int, start: list[float], end: list[float], arc, plane: int,
             budget: int = K.MAX_TILTED_ARC_CHORDS
             ) -> list[tuple[int, list[float], tuple | None]]:
        """The rows of one move given in the rotated frame: (motion, end, arc).

        ``arc`` is ``(centre3, radii, sweep)`` from :func:`nc.arcs.arc_from_words`,
        or None; in the result, ``(centre3, radii, sweep, plane)`` in the program
        frame, or chords (motion 1, no arc) where the rotation tilts the plane,
        at most ``budget`` of them (else :class:`RotationError`).
        """
        if arc is None:
            return [(motion, self.to_world(end), None)]
        centre, radii, sweep = arc
        if self.keeps_normal(plane):
            return [(motion, self.to_world(end), (self.to_world(list(centre))[:3], radii,
                                                  sweep, plane))]
        a1, a2, ax = PLANE_AXES[plane]
        r = max(radii)
        ratio = min(max(1.0 - K.CHORD_TOL_MM / max(r, 1e-12), -1.0), 1.0)
        step = 2.0 * math.acos(ratio) if ratio < 1.0 else math.pi
        if abs(sweep) / min(max(step, 1e-6), math.pi / 2) > budget:
            raise RotationError(f"arc in the tilted plane would make more than {budget} "
                                f"chords (all tilted arcs of the program together at most "
                                f"{K.MAX_TILTED_ARC_CHORDS}); expected fewer turns or a "
                                "smaller radius")
        pts = arc_points((a1, a2, ax), np.asarray(start[:3]), np.asarray(end[:3]),
                         (centre[a1], centre[a2]), tuple(radii), sweep, K.CHORD_TOL_MM)
        rot = list(end[3:])
        return [(1, self.to_world(list(p) + rot), None) for p in pts]


def rotation_block(code: int, vals: dict[str, float], pos: list[float], plane: int,
                   scale: float, current: Rotation | None, tcp: int) -> Rotation | None:
    """G68, G68.2, G69 or G53.1 with its words; returns the rotation in effect after it.

    Parameters
    ----------
    code : int
        680 (G68), 682 (G68.2), 690 (G69), 531 (G53.1).
    vals : dict
        The block's words in program units and degrees.
    pos : list of 6 float [mm, rad]
        Position, program frame.
    plane : int
    scale : float [mm per program unit]
    current : Rotation or None
    tcp : int
        Tool centre point mode in effect.

    Raises
    ------
    RotationError
    """
    active = current is not None and current.active
    form = vals.get("P", 0.0) if code == G68_2 else None
    if current is not None and current.pending is not None and form != current.pending[0]:
        f = current.pending[0]
        raise RotationError(f"G68.2 P{f} definition not complete; expected its next "
                            f"G68.2 P{f} Q block first")
    if "Q" in vals and form not in (2.0, 3.0):
        raise RotationError("Q word with G68.x (LinuxCNC's G68.2 Q orientation forms, Fanuc's "
                            "P1 roll-pitch-yaw order) is not supported; expected Fanuc's "
                            "G68.2 X Y Z I J K (Euler angles), P2 or P3 with Q", "Q")
    if "L" in vals:
        raise RotationError("L word with G68.x/G69/G53.1; expected none", "L")
    if code == G69:
        for c in vals:
            if c in "XYZIJKRP":
                raise RotationError(f"{c} word with G69; expected G69 alone", c)
        if current is not None and current.axis is not None:
            return Rotation(np.eye(3), np.zeros(3), active=False, axis=current.axis)
        return None
    if code == G53_1:
        if not (active and current.tilted):
            raise RotationError("G53.1 without a tilted working plane; expected G68.2 first")
        for c in vals:
            if c in "XYZIJKRP":
                raise RotationError(f"{c} word with G53.1; expected G53.1 alone (P, the "
                                    "choice of solution, is the machine's here)", c)
        z = current.M[:, 2]
        current.axis = (float(z[0]), float(z[1]), float(z[2]))
        return current
    if active:
        name = "G68" if not current.tilted else "G68.2"
        raise RotationError(f"G68/G68.2 while {name} is in effect; expected G69 first")
    held = None if current is None else current.axis  # the tool stays where G53.1 put it
    if tcp != 0:
        raise RotationError("G68/G68.2 under tool centre point control (G43.4/G43.5); "
                            "expected G49 or G43 first")
    for c in "ABC":
        if c in vals:
            raise RotationError(f"{c} word with G68/G68.2; expected the centre X Y Z, "
                                "I J K and R only", c)
    if code == G68_2:
        if form in (2.0, 3.0):
            return _plane_part(vals, int(form), scale, current, plane, held)
        if form == 1.0:
            raise RotationError("G68.2 P1 (roll-pitch-yaw) is not supported: whether its "
                                "turns are about the fixed or the turned axes was not found "
                                "in Fanuc's text (nc.rotation); expected P0 Euler angles I J "
                                "K, P2 three points or P3 two vectors", "P")
        if form != 0.0:
            raise RotationError(f"G68.2 P{form:g}; expected P0 (Euler angles), P2 (three "
                                "points) or P3 (two vectors)", "P")
        if "R" in vals:
            raise RotationError("R word with G68.2; expected X Y Z (origin) and I J K "
                                "(Euler angles)", "R")
        origin = np.array([vals.get(c, 0.0) * scale for c in "XYZ"])
        M = euler_zxz(vals.get("I", 0.0), vals.get("J", 0.0), vals.get("K", 0.0))
        return Rotation(M, origin, tilted=True, plane=plane, axis=held)
    if "P" in vals:
        raise RotationError("P word with G68; expected X Y (Z) centre, R angle (I J K axis)",
                            "P")
    if "R" not in vals:
        raise RotationError("G68 without R; expected the angle R [deg] (the control's "
                            "default angle is not known here)")
    angle = math.radians(vals["R"])
    centre = np.array([vals[c] * scale if c in vals else pos[k]
                       for k, c in enumerate("XYZ")])
    if not np.all(np.isfinite(centre)):
        raise RotationError("G68 at a position not known with no centre; expected the "
                            "centre X Y")
    if any(c in vals for c in "IJK"):  # Fanuc's 3-D coordinate conversion
        d = np.array([vals.get(c, 0.0) for c in "IJK"])
        n = float(np.linalg.norm(d))
        if not n > 1e-12:
            raise RotationError("G68 I J K of zero length; expected the axis of rotation",
                                next(c for c in "IJK" if c in vals))
        M = rotation_about(d / n, angle)
    else:
        a1, a2, ax = PLANE_AXES[plane]
        for c in "XYZ"[ax]:
            if c in vals:
                raise RotationError(f"{c} word with G68 in G{plane}; expected the centre in "
                                    "the plane's two axes", c)
        normal = np.zeros(3)
        normal[ax] = 1.0
        M = rotation_about(normal, angle)
    return Rotation(M, centre - M @ centre, plane=plane, axis=held)



class RotationBlocks:
    """The reader's part for these codes (a base of :class:`nc.gcode_interp.Interpreter`,
    beside :class:`nc.blockreader.BlockReader`, whose ``_error`` it uses)."""

    def _rotation(self, lineno: int, toks: list, gs: list[str] | None, gcodes: dict,
                  vals: dict[str, float], axes: list | None, pos: list[float], plane: int,
                  scale: float, rot, tcp: int, fc: int | None):
        """G68/G68.2/G69/G53.1, and what may not change under them.

        Returns the rotation after the block and whether the block is done
        (G68, G68.2 and G53.1 own their words; nothing moves).
        """
        code = gcodes.get("rotation") if gcodes else None
        orient = gcodes.get("orient") if gcodes else None
        if rot is not None and rot.active and code != 690:
            what = "G68.2" if rot.tilted else "G68"
            if plane != rot.plane:
                raise self._error(lineno, f"change of plane under {what}; expected G69 first",
                                  token=find_token(toks, "G", gs[0]) if gs else None)
            if tcp != TCP_OFF:
                raise self._error(lineno, f"tool centre point control (G43.4/G43.5) under "
                                  f"{what}; expected G69 first",
                                  token=find_token(toks, "G", gs[0]) if gs else None)
            if fc is not None or (gcodes and "wcs" in gcodes):
                raise self._error(lineno, f"change of frame or machine coordinates under "
                                  f"{what}; expected G69 first",
                                  token=find_token(toks, "G", gs[0]) if gs else None)
            if rot.tilted and any(i >= 3 for i, _ in axes or ()):
                c = next(c for c in "ABC" if c in vals)
                raise self._word_error(lineno, toks, c, f"rotary word {c} under G68.2; "
                                       "expected G53.1 to turn the tool (G69 first to move "
                                       "rotary axes)")
        if rot is not None and rot.pending is not None and code is None:
            f = rot.pending[0]
            raise self._error(lineno, f"G68.2 P{f} definition not complete; expected its next "
                              f"G68.2 P{f} Q block here (the blocks follow one another)")
        if code is None and orient is None:
            if rot is not None and not rot.active and any(i >= 3 for i, _ in axes or ()):
                return None, False  # rotary words: the axes leave G53.1's posture
            return rot, False
        if code is not None and orient is not None:
            raise self._error(lineno, "G53.1 with G68/G68.2/G69 in one block; expected "
                              "G53.1 in a block of its own after G68.2",
                              token=find_token(toks, "G", gs[0]))
        key = code if code is not None else orient
        name = code_name("G", key)
        if key != 690 and gcodes.get("motion") is not None:
            raise self._error(lineno, f"{name} with a motion code; expected {name} in a block "
                              "without motion", token=find_token(toks, "G", gs[0]))
        try:
            rot = rotation_block(key, vals, pos, plane, scale, rot, tcp)
        except RotationError as exc:
            tok = find_token(toks, "G", next(g for g in gs if code_key("G", g) == key))
            if exc.letter is None:
                raise self._error(lineno, f"{exc}", token=tok) from None
            raise self._word_error(lineno, toks, exc.letter, str(exc)) from None
        if key == 690:  # the block may go on: a move, a frame code
            return rot, not (axes or fc is not None or gcodes.get("motion") is not None)
        return rot, True
