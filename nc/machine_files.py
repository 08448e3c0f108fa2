"""Machine files: a machine (:class:`nc.machines.Machine`) in TOML, read and written.

A file names one of the named machines (:mod:`nc.named_machines`) as ``kind``
and overrides its geometry, or describes a ``custom`` one axis by axis;
:func:`machine_to_toml` writes the custom form back.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from .errors import MachineFileError
from .machines import _UNLIMITED, Machine, RotaryAxis
from .named_machines import MACHINE_ALIASES, MACHINES
from .tables import TableReader

__all__ = ["load_machine", "machine_to_toml"]


_AXIS_KEYS = ("pivot_mm", "direction", "min_deg", "max_deg")
_CUSTOM_KEYS = ("name", "about", "carrier")
_TOP_KEYS = ("name", "tool_length_mm", "linear_limits_mm", "tilt", "rotary")


class _MachineReader(TableReader):
    """:class:`nc.tables.TableReader` raising :class:`MachineFileError`."""

    error = MachineFileError


def _axis_from(r: TableReader, t: dict, sec: str, base: RotaryAxis | None) -> RotaryAxis:
    """A rotary axis from section ``sec`` over the named default ``base`` (None: custom)."""
    if base is None:
        about = (r.string(t, "about", sec) if isinstance(t.get("about"), str)
                 else tuple(r.numbers(t, "about", sec, length=3)))
        base = _CustomDefault(r.string(t, "name", sec), about, r.string(t, "carrier", sec))
    pivot = tuple(r.numbers(t, "pivot_mm", sec, length=3, default=base.pivot_mm))
    direction = r.number(t, "direction", sec, default=float(base.direction))
    if direction not in (1.0, -1.0):
        raise r.fail(f"{sec}.direction", f"expected 1 or -1, got {direction!r}")
    lo = hi = None
    try:
        lo = math.radians(r.number(t, "min_deg", sec, allow_inf=True)) \
            if "min_deg" in t else base.min_rad
        hi = math.radians(r.number(t, "max_deg", sec, allow_inf=True)) \
            if "max_deg" in t else base.max_rad
        return RotaryAxis(base.name, base.about, base.carrier, pivot, int(direction), lo, hi)
    except ValueError as exc:
        if isinstance(exc, MachineFileError):
            raise
        field = str(exc).split(":")[0]
        raise r.fail(f"{sec}.{ {'min_rad, max_rad': 'min_deg'}.get(field, field)}",
                     str(exc)) from None


class _CustomDefault:
    """What a custom axis section falls back to: unlimited, +1, pivot at 0."""

    def __init__(self, name: str, about: Any, carrier: str) -> None:
        self.name, self.about, self.carrier = name, about, carrier
        self.pivot_mm, self.direction, (self.min_rad, self.max_rad) = (0.0,) * 3, 1, _UNLIMITED


def load_machine(path: str | Path) -> Machine:
    """Read a machine file (TOML; format in :mod:`nc.machines`).

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    Machine

    Raises
    ------
    MachineFileError
        Unreadable file, bad TOML, a missing or unknown key, a value of the
        wrong type, NaN, an unknown ``kind``; the message names file and key
        (:class:`nc.tables.TableReader`).
    """
    r = _MachineReader(path)
    doc = r.load("machine file")
    r.keys(doc, "", ("kind",), _TOP_KEYS)
    kind = MACHINE_ALIASES.get(k := r.string(doc, "kind", ""), k)
    if kind != "custom" and kind not in MACHINES:
        raise r.fail("kind", f"unknown kind {kind!r} (known: custom, {', '.join(MACHINES)})")
    lim = r.table(doc.get("linear_limits_mm", {}), "linear_limits_mm")
    r.keys(lim, "linear_limits_mm", (), ("x", "y", "z"))
    lin = tuple(tuple(r.numbers(lim, q, "linear_limits_mm", length=2, default=_UNLIMITED,
                                allow_inf=True)) for q in "xyz")
    bases: tuple[Any, ...] = MACHINES[kind]().axes if kind != "custom" else (None, None)
    axes = []
    for sec, base in zip(("tilt", "rotary"), bases):
        if base is None and sec not in doc:
            raise r.fail(sec, "missing")
        t = r.table(doc.get(sec, {}), sec)
        r.keys(t, sec, _CUSTOM_KEYS if base is None else (), _AXIS_KEYS)
        axes.append(_axis_from(r, t, sec, base))
    try:
        return Machine(r.string(doc, "name", "", default=kind), tuple(axes),  # type: ignore
                       r.number(doc, "tool_length_mm", "", default=0.0), lin)
    except ValueError as exc:  # e.g. "axes: tilt and rotary axes are parallel"
        if isinstance(exc, MachineFileError):
            raise
        raise r.fail(str(exc).split(":")[0], str(exc)) from None


def machine_to_toml(machine: Machine) -> str:
    """The machine as a machine file (``kind = "custom"``) for :func:`load_machine`.

    Parameters
    ----------
    machine : Machine

    Returns
    -------
    str
        TOML text. Limits are written in degrees: a round trip reproduces
        them to rounding (1e-16 relative).
    """
    def num(v: float) -> str:
        return repr(float(v)) if math.isfinite(v) else ("inf" if v > 0 else "-inf")

    def vec(v: Any) -> str:
        return "[" + ", ".join(num(c) for c in v) + "]"

    name = machine.name.replace("\\", "\\\\").replace('"', '\\"')
    out = ['kind = "custom"', f'name = "{name}"',
           f"tool_length_mm = {num(machine.tool_length_mm)}", "", "[linear_limits_mm]"]
    out += [f"{q} = {vec(lim)}" for q, lim in zip("xyz", machine.linear_limits_mm)]
    for sec, ax in zip(("tilt", "rotary"), machine.axes):
        about = f'"{ax.about}"' if isinstance(ax.about, str) else vec(ax.about)
        out += ["", f"[{sec}]", f'name = "{ax.name}"', f"about = {about}",
                f'carrier = "{ax.carrier}"', f"pivot_mm = {vec(ax.pivot_mm)}",
                f"direction = {ax.direction}", f"min_deg = {num(math.degrees(ax.min_rad))}",
                f"max_deg = {num(math.degrees(ax.max_rad))}"]
    return "\n".join(out) + "\n"
