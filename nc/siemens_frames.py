"""CYCLE800 (swivel plane) of the Sinumerik 840D as a frame: rotation and shifts.

``CYCLE800(_FR, _TC, _ST, _MODE, _X0, _Y0, _Z0, _A, _B, _C, _X1, _Y1, _Z1, _DIR,
_FR_I, _DMODE)``. What is read:

* ``_MODE`` bits 7-6 the swivel mode, bits 1-0, 3-2 and 5-4 the axes ``_A``,
  ``_B`` and ``_C`` belong to (``01`` X, ``10`` Y, ``11`` Z):

  - ``00`` axis by axis: ``_A _B _C`` turn about those axes in that order,
    each about the axes the previous rotations left (``AROT``): ``57`` = X then
    Y then Z, ``27`` = Z then Y then X;
  - ``01`` solid angle (``_MODE`` 64): ``_A`` about Z, then ``_B`` about the Y
    that turn left, ``Rz(_A) Ry(_B)``; a ``_C`` other than 0 is refused;
  - ``10`` projection angle (``_MODE`` 128 + the axis sequence, e.g. 185 = X Y
    Z, 182 = Y X Z): ``_A`` and ``_B`` are projection angles about their axes,
    defined as the 840D's solid angles of ``ROTS`` (:func:`projection_frame`),
    ``_C`` a turn about the new third axis;
  - ``11`` direct (``_MODE`` 192): ``_A`` and ``_B`` are the positions [deg]
    of the swivel data set's rotary axes 1 and 2 (Sinumerik's rule: axis 2 is
    carried by axis 1; with a head and a table axis, axis 1 is the head's:
    :meth:`nc.machines.Machine.swivel_axes`). The plane is the spindle's frame
    at those positions, its Z the tool axis
    (:meth:`nc.machines.Machine.tool_frame`), so it needs the machine: without
    one the mode is refused, naming the machine file it needs.
* ``_X0 _Y0 _Z0`` the point rotated about (a shift before the rotation) and
  ``_X1 _Y1 _Z1`` the zero point of the swivelled plane (a shift after it):
  a point ``p`` of the swivelled plane is ``X0 + R (X1 + p)`` in the frame
  before the cycle.
* ``_ST``: its units digit, 0 a new swivel frame (replacing the last one), 1
  additive (on top of it). ``_TC = "0"`` or no parameters at all: swivel off.
* ``_FR`` (retraction), ``_DIR`` (which of the two rotary solutions), ``_FR_I``
  and ``_DMODE`` do not change the frame; the retraction is a rapid move the
  reader does not model (the next move starts where the last one ended).
"""

from __future__ import annotations

import math

import numpy as np

from .errors import InputError

__all__ = ["FrameError", "Swivel", "cycle800", "rotation", "projection_frame", "plane_order",
           "MODE_NAMES"]

MODE_NAMES = {0: "axis by axis", 1: "solid angle", 2: "projection angle",
              3: "direct (rotary axis positions)"}
_AXIS_OF_CODE = {1: 0, 2: 1, 3: 2}
#: Names of the parameters, 1-based position - 1.
PARAMS = ("_FR", "_TC", "_ST", "_MODE", "_X0", "_Y0", "_Z0", "_A", "_B", "_C", "_X1", "_Y1",
          "_Z1", "_DIR", "_FR_I", "_DMODE")


class FrameError(InputError):
    """A CYCLE800 the reader cannot turn into a frame; ``param`` is its 0-based position."""

    def __init__(self, message: str, param: int | None = None) -> None:
        self.param = param
        super().__init__(message)


class Swivel:
    """A frame: a point ``p`` in it is ``shift + R @ p`` in the frame below."""

    __slots__ = ("R", "shift")

    def __init__(self, R: np.ndarray, shift: np.ndarray) -> None:
        self.R, self.shift = R, shift

    @property
    def identity(self) -> bool:
        return bool(np.all(self.R == np.eye(3)) and not np.any(self.shift))

    def then(self, inner: "Swivel") -> "Swivel":
        """This frame with ``inner`` applied inside it (additive swivel)."""
        return Swivel(self.R @ inner.R, self.shift + self.R @ inner.shift)


def rotation(axis: int, deg: float) -> np.ndarray:
    """Right-hand rotation by ``deg`` [deg] about X (0), Y (1) or Z (2)."""
    a = math.radians(deg)
    c, s = math.cos(a), math.sin(a)
    if axis == 0:
        return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])
    if axis == 1:
        return np.array([[c, 0, s], [0, 1.0, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def _solid_angle(mode: int, alpha: float, beta: float, gamma: float) -> np.ndarray:
    """Solid angle (``_MODE`` 64): ``alpha`` [deg] about Z, then ``beta`` [deg] about
    the Y that rotation left: ``Rz(alpha) Ry(beta)``."""
    if mode != 64:
        raise FrameError(f"CYCLE800 _MODE = {mode}: solid angle is _MODE 64 (bits 0-5 "
                         "zero)", 3)
    if gamma:
        raise FrameError(f"CYCLE800 _C = {gamma:g} with solid angle (_MODE 64) is not read; "
                         "expected _C = 0 (solid angle takes _A about Z and _B about Y)", 9)
    return rotation(2, alpha) @ rotation(1, beta)


def projection_frame(first: int, second: int, a_first: float, a_second: float) -> np.ndarray:
    """Rotation whose plane has the projection angles ``a_first``, ``a_second`` [deg].

    ``first``, ``second`` are the axes of the plane in G17/G18/G19 order (X Y, Z X
    or Y Z; 0 X, 1 Y, 2 Z), the third axis ``k`` the one left. As the 840D
    defines its solid angles (ROTS) and CYCLE800's projection angles: the first
    axis turned about the second by ``a_second`` is the line where the swivelled
    plane meets the first-third plane, and it is the swivelled first axis; the
    second axis turned about the first by ``a_first`` is the line where the plane
    meets the second-third plane. The new third axis is the plane's normal.

    Raises
    ------
    FrameError
        When both lines are the third axis (both angles +-90 deg): no plane.
    """
    e = np.eye(3)
    f_new = rotation(second, a_second) @ e[first]
    u = rotation(first, a_first) @ e[second]
    normal = np.cross(f_new, u)
    norm = float(np.linalg.norm(normal))
    if not norm > 1e-9:
        raise FrameError("CYCLE800 projection angles of +-90 deg about both axes leave the "
                         "plane undefined", 7)
    normal /= norm
    s_new = np.cross(normal, f_new)
    R = np.empty((3, 3))
    R[:, first], R[:, second], R[:, 3 - first - second] = f_new, s_new, normal
    return R


def plane_order(a: int, b: int) -> tuple[int, int]:
    """Axes ``a``, ``b`` (0 X, 1 Y, 2 Z; different) in G17/G18/G19 order: (X, Y),
    (Z, X) or (Y, Z)."""
    return _PLANE_ORDER[frozenset((a, b))]


_PLANE_ORDER = {frozenset((0, 1)): (0, 1), frozenset((2, 0)): (2, 0), frozenset((1, 2)): (1, 2)}


def _projection(axes: list[int], angles: list[float]) -> np.ndarray:
    """Projection angle (``_MODE`` 128 + axis sequence): ``_A`` and ``_B`` are the
    projection angles about the first two axes of the sequence, ``_C`` a turn about
    the swivelled third axis (the axis the two leave: Z after X Y or Y X)."""
    first, second = plane_order(axes[0], axes[1])
    by_axis = {axes[0]: angles[0], axes[1]: angles[1]}
    R = projection_frame(first, second, by_axis[first], by_axis[second])
    if angles[2]:
        R = R @ rotation(axes[2], angles[2])
    return R


def cycle800(values: list, current: Swivel, machine: object = None) -> Swivel:
    """The swivel frame after a CYCLE800 call.

    Parameters
    ----------
    values : list
        The call's parameters in order: None where empty, ``_TC`` a str, the
        others float [mm, deg or codes]; at most 16.
    current : Swivel
        The swivel frame before the call.
    machine : nc.machines.Machine, optional
        The machine, for the direct mode (192); without it that mode is refused.

    Returns
    -------
    Swivel
        Identity for a reset (no parameters, ``_TC = "0"``).

    Raises
    ------
    FrameError
        The direct swivel mode (192) without a machine, an axis sequence that is not a
        permutation of X Y Z, a solid angle with ``_C``, projection angles with
        no plane, a ``_ST`` or ``_MODE`` that is not a whole code.
    """
    ident = Swivel(np.eye(3), np.zeros(3))
    if not values or all(v is None for v in values):
        return ident
    if len(values) > len(PARAMS):
        raise FrameError(f"CYCLE800 with {len(values)} parameters; expected at most "
                         f"{len(PARAMS)} ({', '.join(PARAMS)})", len(PARAMS))
    v = list(values) + [None] * (len(PARAMS) - len(values))
    tc = v[1]
    if tc is not None and str(tc).strip() == "0":
        return ident
    nums = [0.0 if x is None else x for x in v]
    st, mode = nums[2], nums[3]
    for k, val in ((2, st), (3, mode)):
        if not (isinstance(val, float) and val == int(val) and val >= 0):
            raise FrameError(f"CYCLE800 {PARAMS[k]} = {val!r}: expected a whole code >= 0", k)
    st, mode = int(st), int(mode)
    if st % 10 not in (0, 1):
        raise FrameError(f"CYCLE800 _ST = {st}: its units digit must be 0 (new swivel "
                         "plane) or 1 (additive)", 2)
    kind = (mode >> 6) & 3
    if mode > 255 or (kind == 3 and (mode != 192 or machine is None)):
        why = ("needs the machine's kinematics: give a machine file or a named machine "
               "(nc parse --machine, a scenario's [program] machine)" if mode == 192 else
               "is not a swivel mode")
        raise FrameError(f"CYCLE800 swivel mode {mode} ({MODE_NAMES[kind]}"
                         + (", bits above 7" if mode > 255 else "")
                         + f") {why}; supported: axis by axis (_MODE 0..63, e.g. 57 = X Y Z, "
                         "27 = Z Y X), solid angle (64), projection angle (128 + axis "
                         "sequence, e.g. 185 = X Y Z), direct (192) with a machine", 3)
    for k in range(4, 13):
        if not isinstance(nums[k], float):
            raise FrameError(f"CYCLE800 {PARAMS[k]}: expected a number", k)
    if kind == 3:
        if nums[9] != 0.0:
            raise FrameError("CYCLE800 direct mode (192) with _C; expected the two rotary "
                             "axis positions in _A and _B only", 9)
        joints = [0.0] * 5
        for col, val in zip(machine.swivel_axes(), nums[7:9]):
            joints[col] = math.radians(val)
        R = machine.tool_frame(joints[3], joints[4])
    elif kind == 1:
        R = _solid_angle(mode, nums[7], nums[8], nums[9])
    else:
        codes = [mode & 3, (mode >> 2) & 3, (mode >> 4) & 3]
        if sorted(codes) != [1, 2, 3]:
            raise FrameError(f"CYCLE800 _MODE = {mode}: bits 0-5 must name X, Y and Z once "
                             "each (01 X, 10 Y, 11 Z), e.g. 57 = X Y Z, 27 = Z Y X", 3)
        axes = [_AXIS_OF_CODE[c] for c in codes]
        if kind == 2:
            R = _projection(axes, nums[7:10])
        else:
            R = np.eye(3)
            for ax, ang in zip(axes, nums[7:10]):
                if ang:
                    R = R @ rotation(ax, ang)
    x0, x1 = np.array(nums[4:7]), np.array(nums[10:13])
    new = Swivel(R, x0 + R @ x1)
    return current.then(new) if st % 10 == 1 else new
