"""Coordinate frames and reference points while a program is read.

The reader keeps positions in the *program frame*, as LinuxCNC's interpreter
reports them: machine = program + work offset (G54...G59, settable by G10
L2/L20) + axis offset (G92, G52). The codes here change those offsets or move
to a point given in machine coordinates (G53, G28/G30); the interpreter
(:mod:`nc.gcode`) converts its current position whenever the total offset
changes, so that the tool stays where it is on the machine.

Semantics follow LinuxCNC (checked against its ``rs274`` in the tests):

* ``G92 X..`` sets the axis offset so that the current position reads the
  given values; ``G92.1`` clears it and its saved copy, ``G92.2`` clears it
  and keeps the copy, ``G92.3`` restores the copy. ``G52 X..`` sets the axis
  offset of the named axes to the given values (LinuxCNC shares it with G92).
* ``G10 L2 Pn X..`` sets work offset n (0: the active one) to the given values;
  ``G10 L20 Pn X..`` sets it so that the current position reads the values.
  Both are absolute whatever G90/G91. ``G10 L1/L10/L11`` (tool table) changes
  no position the reader keeps.
* ``G53`` (with G0/G1, G90): the block's axis words are machine coordinates.
* ``G28``/``G30``: a rapid to the intermediate point given by the axis words
  (in the distance mode in effect), then a rapid of the named axes (all,
  when none is named) to the reference point. The reference point is in
  machine coordinates and comes from the machine's setup
  (``reference_points``); without it the end is *unknown* (NaN) on those axes
  until an absolute move (or G53, or G92) gives each axis a value again.
  ``G28.1``/``G30.1`` store the current machine position as the point.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence

import numpy as np

from .errors import InputError

__all__ = ["Frames", "reference_table", "work_offset_table", "convert_position"]

NAN = math.nan


def _pose6(table: str, key, value) -> np.ndarray:
    """``(x, y, z[, a, b, c])`` [mm, deg] -> 6 numbers [mm, rad]; a b c default 0."""
    v = np.asarray(value, dtype=float)
    if v.ndim != 1 or v.size not in (3, 6) or not np.all(np.isfinite(v)):
        raise InputError(f"{table}[{key!r}]: expected 3 or 6 finite numbers "
                         f"(x y z [mm], a b c [deg]), got {value!r}")
    pose = np.zeros(6)
    pose[:3] = v[:3]
    if v.size == 6:
        pose[3:] = np.radians(v[3:])
    return pose


def work_offset_table(work_offsets: Mapping[str, Sequence[float]] | None) -> np.ndarray:
    """G54...G59 offsets from ``{"G55": (x, y, z[, a, b, c])}`` [mm, deg]."""
    table = np.zeros((6, 6))
    for key, value in (work_offsets or {}).items():
        m = re.fullmatch(r"G5([4-9])", str(key).strip().upper())
        if not m:
            raise InputError(f"work_offsets: key {key!r} must be one of G54...G59")
        table[int(m.group(1)) - 4] = _pose6("work_offsets", key, value)
    return table


def reference_table(points: Mapping[str, Sequence[float]] | None) -> dict[int, list | None]:
    """``{"G28": (x, y, z[, a, b, c])}`` [mm, deg], machine coordinates -> by code key."""
    out: dict[int, list | None] = {280: None, 300: None}
    for key, value in (points or {}).items():
        m = re.fullmatch(r"G(28|30)", str(key).strip().upper())
        if not m:
            raise InputError(f"reference_points: key {key!r} must be G28 or G30")
        out[int(m.group(1)) * 10] = [float(x) for x in _pose6("reference_points", key, value)]
    return out


def convert_position(pos: list[float], old: list[float], new: list[float]) -> list[float]:
    """The same machine position in a frame whose offset changed from ``old`` to ``new``.

    Axes whose offset did not change keep their value exactly (also when it
    is NaN, not known); the others are NaN where either offset is.
    """
    return [p if o == n else p + o - n for p, o, n in zip(pos, old, new)]


class Frames:
    """Work offsets, the G92/G52 axis offset and the reference points [mm, rad].

    Parameters
    ----------
    table : ndarray, shape (6, 6) [mm, rad]
        G54...G59 offsets at the program's start.
    references : dict
        Code key (280, 300) -> reference point in machine coordinates, or
        None where the machine's is not known.
    """

    def __init__(self, table: np.ndarray, references: dict[int, list | None]) -> None:
        self.table = [[float(x) for x in row] for row in table]
        self.axis = [0.0] * 6
        self.saved = [0.0] * 6
        self.references = dict(references)

    def total(self, wcs: int) -> list[float]:
        """Offset from the program frame to machine coordinates under ``wcs`` (1...6)."""
        return [a + b for a, b in zip(self.table[wcs - 1], self.axis)]

    # -- offsets ---------------------------------------------------------------
    def g92(self, code: int, named: list[tuple[int, float]], pos: list[float]) -> str | None:
        """Apply G92/G92.1/G92.2/G92.3/G52; returns an error message or None."""
        if code in (920, 520):
            if not named:
                return "expected axis words with G92 / G52"
            for i, v in named:
                self.axis[i] = pos[i] + self.axis[i] - v if code == 920 else v
            self.saved = self.axis[:]
        elif named:
            return "axis words with G92.1/G92.2/G92.3; expected none"
        elif code == 921:
            self.axis, self.saved = [0.0] * 6, [0.0] * 6
        elif code == 922:
            self.axis = [0.0] * 6
        else:
            self.axis = self.saved[:]
        return None

    def g10(self, level: int, number: int, named: list[tuple[int, float]], pos: list[float],
            wcs: int) -> None:
        """Apply G10 L2 / L20 to work offset ``number`` (0: active)."""
        n = wcs if number == 0 else number
        row = self.table[n - 1]
        cur = self.table[wcs - 1]
        for i, v in named:
            row[i] = v if level == 2 else pos[i] + cur[i] - v

    # -- moves in machine coordinates -------------------------------------
    def machine_to_program(self, i: int, v: float, wcs: int) -> float:
        return v - self.table[wcs - 1][i] - self.axis[i]

    def store_reference(self, code: int, pos: list[float], wcs: int) -> None:
        """G28.1 / G30.1: the current machine position becomes the point."""
        self.references[code - 1] = [p + t for p, t in zip(pos, self.total(wcs))]

    def home(self, code: int, named: list[tuple[int, float]], inc: bool, pos: list[float],
             wcs: int, rotary_used: bool) -> tuple[list[float], list[float]]:
        """G28 / G30: the intermediate point and the end (NaN where unknown)."""
        mid = pos[:]
        for i, v in named:
            mid[i] = pos[i] + v if inc else v
        end = mid[:]
        axes = [i for i, _ in named] or ([0, 1, 2, 3, 4, 5] if rotary_used else [0, 1, 2])
        ref = self.references.get(code)
        total = self.total(wcs)
        for i in axes:
            end[i] = ref[i] - total[i] if ref is not None else NAN
        return mid, end
