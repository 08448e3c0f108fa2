"""The named machines: four parameter sets of the one mechanism (:class:`nc.machines.Machine`).

``xyzac-trt``, ``xyzbc-trt`` (table-table, LinuxCNC's trt kinematics),
``xyzbc-head-table`` and ``xyzbc-head-head``; the aliases ``head-table-bc`` and
``head-head-bc``. Machine files (:mod:`nc.machine_files`) start from them, and
:mod:`nc.kinematics` re-exports them.
"""

from __future__ import annotations

import math
from functools import partial
from typing import Any, Callable

from .errors import InputError
from .machines import _UNLIMITED, Machine, RotaryAxis

__all__ = ["MACHINES", "MACHINE_ALIASES", "get_machine", "machine_kind",
           "linuxcnc_trt_machine"]


_DEG = math.pi / 180.0
_TILT_LIMITS_RAD = (-90.0 * _DEG, 90.0 * _DEG)

#: kind -> (tilt letter, tilt about, tilt carrier, rotary carrier)
_KINDS = {
    "xyzac-trt": ("A", "x", "table", "table"),
    "xyzbc-trt": ("B", "y", "table", "table"),
    "xyzbc-head-table": ("B", "y", "head", "table"),
    "xyzbc-head-head": ("B", "y", "head", "head"),
}
#: Other names of the named machines.
MACHINE_ALIASES = {"head-table-bc": "xyzbc-head-table", "head-head-bc": "xyzbc-head-head"}


def _named(kind: str, *, name: str | None = None, tool_length_mm: float = 0.0,
           tilt_pivot_mm: tuple[float, float, float] = (0.0, 0.0, 0.0),
           rotary_pivot_mm: tuple[float, float, float] = (0.0, 0.0, 0.0),
           tilt_direction: int = 1, rotary_direction: int = 1,
           tilt_limits_rad: tuple[float, float] = _TILT_LIMITS_RAD,
           rotary_limits_rad: tuple[float, float] = _UNLIMITED,
           linear_limits_mm: tuple[tuple[float, float], ...] = (_UNLIMITED,) * 3,
           ) -> Machine:
    """Named machine ``kind`` (a key of :data:`MACHINES`); keywords: :func:`get_machine`."""
    letter, about, tilt_carrier, rot_carrier = _KINDS[kind]
    tilt = RotaryAxis(letter, about, tilt_carrier, tuple(tilt_pivot_mm), tilt_direction,
                      *tilt_limits_rad)
    rot = RotaryAxis("C", "z", rot_carrier, tuple(rotary_pivot_mm), rotary_direction,
                     *rotary_limits_rad)
    return Machine(name or kind, (tilt, rot), tool_length_mm, tuple(linear_limits_mm))


#: Named machine factories; each takes the keywords of :func:`get_machine`.
MACHINES: dict[str, Callable[..., Machine]] = {k: partial(_named, k) for k in _KINDS}


def machine_kind(name: str) -> str | None:
    """The kind (a key of :data:`MACHINES`) a machine name or alias stands for, or None."""
    kind = MACHINE_ALIASES.get(name, name)
    return kind if kind in MACHINES else None


def get_machine(name: str, /, **overrides: Any) -> Machine:
    """A named machine, with geometry overrides.

    Parameters
    ----------
    name : str
        ``xyzac-trt``, ``xyzbc-trt``, ``xyzbc-head-table`` (alias
        ``head-table-bc``) or ``xyzbc-head-head`` (alias ``head-head-bc``).
    name : str, optional (keyword; the kind above is positional)
        Machine name; default the kind.
    tool_length_mm : float [mm]
        Tool gauge length (spindle nose to tip).
    tilt_pivot_mm, rotary_pivot_mm : tuple of 3 float [mm]
        Points on the tilt / rotary axis at zero posture (table axis:
        workpiece frame; head axis: from the spindle gauge point).
    tilt_direction, rotary_direction : int
        +1 or -1 (see "Signs" above).
    tilt_limits_rad, rotary_limits_rad : tuple of 2 float [rad]
        (min, max) travel; +-inf for unlimited.
    linear_limits_mm : tuple of 3 (min, max) [mm]
        X, Y, Z travel.

    Returns
    -------
    Machine
    """
    kind = MACHINE_ALIASES.get(name, name)
    if kind not in MACHINES:
        raise InputError(f"unknown machine {name!r}; known: {', '.join(MACHINES)}")
    return MACHINES[kind](**overrides)


def linuxcnc_trt_machine(kins: str, *, x_rot_point: float = 0.0, y_rot_point: float = 0.0,
                         z_rot_point: float = 0.0, x_offset: float = 0.0,
                         y_offset: float = 0.0, z_offset: float = 0.0,
                         **overrides: Any) -> Machine:
    """The machine of LinuxCNC's ``xyzac-trt-kins`` / ``xyzbc-trt-kins`` pins [mm].

    LinuxCNC (src/emc/kinematics/trtfuncs.c) turns C about the vertical line
    through (x-rot-point, y-rot-point) and A about the X-parallel line through
    (y-rot-point + y-offset, z-rot-point + z-offset) (B: the Y-parallel line
    through (x-rot-point + x-offset, z-rot-point + z-offset)), both
    right-handed for positive angles (direction +1). Its joints equal ours when
    the ``tool-offset`` pin is 0 (tool length applied by G43): its world
    position is then our tool tip in the workpiece frame.

    Parameters
    ----------
    kins : str
        ``"xyzac-trt"`` or ``"xyzbc-trt"`` (a ``-kins`` suffix is accepted).
    x_rot_point, y_rot_point, z_rot_point, x_offset, y_offset, z_offset : float [mm]
        The HAL pin values (``x_offset`` is used by xyzbc only, ``y_offset``
        by xyzac only).
    **overrides
        Further keywords of :func:`get_machine` (limits, directions, name).

    Returns
    -------
    Machine
    """
    kind = kins.removesuffix("-kins")
    rot = (x_rot_point, y_rot_point, z_rot_point)
    if kind == "xyzac-trt":
        tilt = (x_rot_point, y_rot_point + y_offset, z_rot_point + z_offset)
    elif kind == "xyzbc-trt":
        tilt = (x_rot_point + x_offset, y_rot_point, z_rot_point + z_offset)
    else:
        raise InputError(f"kins: expected 'xyzac-trt' or 'xyzbc-trt', got {kins!r}")
    return get_machine(kind, tilt_pivot_mm=tilt, rotary_pivot_mm=rot, **overrides)
