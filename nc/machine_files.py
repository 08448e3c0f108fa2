"""Machine files: a machine (:class:`nc.machines.Machine`) in TOML, read and written.

A file names one of the named machines (:mod:`nc.named_machines`) as ``kind``
and overrides its geometry, or describes a ``custom`` one axis by axis;
:func:`machine_to_toml` writes the custom form back.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

from .errors import MachineFileError
from .machines import _UNLIMITED, Machine, RotaryAxis
from .named_machines import MACHINE_ALIASES, MACHINES

__all__ = ["load_machine", "machine_to_toml"]


_AXIS_KEYS = {"pivot_mm", "direction", "min_deg", "max_deg"}
_CUSTOM_KEYS = {"name", "about", "carrier"}
_TOP_KEYS = {"kind", "name", "tool_length_mm", "linear_limits_mm", "tilt", "rotary"}


class _Doc:
    """Typed reads from a parsed TOML table; errors name the file and the key."""

    def __init__(self, file: str) -> None:
        self.file = file

    def fail(self, key: str, problem: str) -> MachineFileError:
        return MachineFileError(f"{self.file}: key {key!r}: {problem}")

    def get(self, t: dict, key: str, path: str, kind: str, default: Any = None,
            allow_inf: bool = False) -> Any:
        """``kind``: "str", "num", "vec3", "vec2" (lists of numbers) or "table"."""
        if key not in t:
            if default is None:
                raise self.fail(path, "missing")
            return default
        v = t[key]
        if kind == "str":
            if not isinstance(v, str):
                raise self.fail(path, f"expected a string, got {v!r}")
            return v
        if kind == "table":
            if not isinstance(v, dict):
                raise self.fail(path, f"expected a table, got {v!r}")
            return v
        if kind in ("vec3", "vec2"):
            width = int(kind[-1])
            if not isinstance(v, list) or len(v) != width:
                raise self.fail(path, f"expected a list of {width} numbers, got {v!r}")
            return tuple(self.get({key: c}, key, path, "num", allow_inf=allow_inf) for c in v)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.fail(path, f"expected a number, got {v!r}")
        if math.isnan(v) or (math.isinf(v) and not allow_inf):
            raise self.fail(path, f"expected a finite number, got {v!r}")
        return float(v)

    def known(self, t: dict, allowed: set[str], prefix: str = "") -> None:
        extra = sorted(set(t) - allowed)
        if extra:
            raise self.fail(prefix + extra[0], f"unknown key (known: {', '.join(sorted(allowed))})")


def _axis_from(d: _Doc, t: dict, sec: str, base: RotaryAxis | None) -> RotaryAxis:
    """A rotary axis from section ``sec`` over the named default ``base`` (None: custom)."""
    if base is None:
        about = t.get("about")
        base = _CustomDefault(d.get(t, "name", f"{sec}.name", "str"),
                              d.get(t, "about", f"{sec}.about",
                                    "str" if isinstance(about, str) else "vec3"),
                              d.get(t, "carrier", f"{sec}.carrier", "str"))
    pivot = d.get(t, "pivot_mm", f"{sec}.pivot_mm", "vec3", base.pivot_mm)
    direction = d.get(t, "direction", f"{sec}.direction", "num", float(base.direction))
    if direction not in (1.0, -1.0):
        raise d.fail(f"{sec}.direction", f"expected 1 or -1, got {direction!r}")
    lo = hi = None
    try:
        lo = math.radians(d.get(t, "min_deg", f"{sec}.min_deg", "num", math.degrees(
            base.min_rad), allow_inf=True)) if "min_deg" in t else base.min_rad
        hi = math.radians(d.get(t, "max_deg", f"{sec}.max_deg", "num", math.degrees(
            base.max_rad), allow_inf=True)) if "max_deg" in t else base.max_rad
        return RotaryAxis(base.name, base.about, base.carrier, pivot, int(direction), lo, hi)
    except ValueError as exc:
        if isinstance(exc, MachineFileError):
            raise
        field = str(exc).split(":")[0]
        raise d.fail(f"{sec}.{ {'min_rad, max_rad': 'min_deg'}.get(field, field)}",
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
        wrong type, NaN, an unknown ``kind``; the message names file and key.
    """
    d = _Doc(str(path))
    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except OSError as exc:
        raise MachineFileError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise MachineFileError(f"{path}: not valid TOML: {exc}") from None

    d.known(doc, _TOP_KEYS)
    kind = MACHINE_ALIASES.get(k := d.get(doc, "kind", "kind", "str"), k)
    if kind != "custom" and kind not in MACHINES:
        raise d.fail("kind", f"unknown kind {kind!r} (known: custom, {', '.join(MACHINES)})")
    lim = d.get(doc, "linear_limits_mm", "linear_limits_mm", "table", {})
    d.known(lim, {"x", "y", "z"}, "linear_limits_mm.")
    lin = tuple(d.get(lim, q, f"linear_limits_mm.{q}", "vec2", _UNLIMITED, allow_inf=True)
                for q in "xyz")
    bases: tuple[Any, ...] = MACHINES[kind]().axes if kind != "custom" else (None, None)
    axes = []
    for sec, base in zip(("tilt", "rotary"), bases):
        t = d.get(doc, sec, sec, "table", {} if base is not None else None)
        d.known(t, _AXIS_KEYS | (_CUSTOM_KEYS if base is None else set()), sec + ".")
        axes.append(_axis_from(d, t, sec, base))
    try:
        return Machine(d.get(doc, "name", "name", "str", kind), tuple(axes),  # type: ignore
                       d.get(doc, "tool_length_mm", "tool_length_mm", "num", 0.0), lin)
    except ValueError as exc:  # e.g. "axes: tilt and rotary axes are parallel"
        if isinstance(exc, MachineFileError):
            raise
        raise d.fail(str(exc).split(":")[0], str(exc)) from None


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
