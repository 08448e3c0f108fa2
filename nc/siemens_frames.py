"""CYCLE800 (swivel plane) of the Sinumerik 840D as a frame: rotation and shifts.

``CYCLE800(_FR, _TC, _ST, _MODE, _X0, _Y0, _Z0, _A, _B, _C, _X1, _Y1, _Z1, _DIR,
_FR_I, _DMODE)``. What is read:

* ``_MODE`` bits 7-6 swivel mode: only ``00`` axis by axis; bits 1-0, 3-2 and
  5-4 the axes ``_A``, ``_B`` and ``_C`` turn about (``01`` X, ``10`` Y, ``11`` Z),
  in that order, each about the axes the previous rotations left (``AROT``):
  ``57`` = X then Y then Z, ``27`` = Z then Y then X. Solid angle (64),
  projection angle (128) and direct rotary-axis positions (192, which need the
  machine's swivel data) are refused by name.
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

__all__ = ["FrameError", "Swivel", "cycle800", "rotation", "MODE_NAMES"]

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


def cycle800(values: list, current: Swivel) -> Swivel:
    """The swivel frame after a CYCLE800 call.

    Parameters
    ----------
    values : list
        The call's parameters in order: None where empty, ``_TC`` a str, the
        others float [mm, deg or codes]; at most 16.
    current : Swivel
        The swivel frame before the call.

    Returns
    -------
    Swivel
        Identity for a reset (no parameters, ``_TC = "0"``).

    Raises
    ------
    FrameError
        Swivel modes other than axis by axis, an axis sequence that is not a
        permutation of X Y Z, a ``_ST`` or ``_MODE`` that is not a whole code.
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
    if mode > 255 or kind != 0:
        raise FrameError(f"CYCLE800 swivel mode {mode} ({MODE_NAMES[kind]}"
                         + (", bits above 7" if mode > 255 else "")
                         + ") is not read; supported: axis by axis (_MODE 0..63 with the "
                         "axis sequence in bits 0-5, e.g. 57 = X Y Z, 27 = Z Y X)", 3)
    codes = [mode & 3, (mode >> 2) & 3, (mode >> 4) & 3]
    if sorted(codes) != [1, 2, 3]:
        raise FrameError(f"CYCLE800 _MODE = {mode}: bits 0-5 must name X, Y and Z once "
                         "each (01 X, 10 Y, 11 Z), e.g. 57 = X Y Z, 27 = Z Y X", 3)
    for k in range(4, 13):
        if not isinstance(nums[k], float):
            raise FrameError(f"CYCLE800 {PARAMS[k]}: expected a number", k)
    R = np.eye(3)
    for code, ang in zip(codes, nums[7:10]):
        if ang:
            R = R @ rotation(_AXIS_OF_CODE[code], ang)
    x0, x1 = np.array(nums[4:7]), np.array(nums[10:13])
    new = Swivel(R, x0 + R @ x1)
    return current.then(new) if st % 10 == 1 else new
