"""Tool libraries: a scenario's tool from a LinuxCNC tool table or a Fusion 360 library.

A scenario may name a library file and a tool number instead of describing
the tool key by key (``[tool] library = "tools.json"``, ``number = 3``); keys
given beside them in ``[tool]`` override or complete the library's values.
:func:`library_tool` reads one tool of a library into those ``[tool]`` keys
(millimetres; inches are converted here, at the edge), and
:func:`tool_table_from_library` is the hook :mod:`errpred.scenario` calls.

Two formats:

* **LinuxCNC tool table** (``.tbl``), as LinuxCNC's own reader
  (``src/emc/tooldata/tooldata_common.cc``, ``tooldata_read_entry``) takes it:
  one tool a line, words of a letter and a number separated by spaces,
  ``T`` tool number, ``P`` pocket, ``D`` diameter, ``X Y Z A B C U V W``
  offsets, ``I J`` front and back angle and ``Q`` orientation (lathe tools),
  letters in either case; everything after the first ``;`` is the comment,
  lines starting with ``;`` and blank lines are skipped. Stricter than
  LinuxCNC, which skips a line it cannot read: any such line is an error
  here (a missing ``T``, an unknown letter, a malformed number, a letter
  given twice), since the tool asked for might be the one skipped. The
  table holds only the diameter; its values are in the machine's units,
  which the file does not name, so the scenario names them
  (``library_units``), and the type, flute count, helix angle, flute length
  (and a bull-nose's corner radius) must be given in ``[tool]``. ``Z`` is
  the tool length offset from the spindle's gauge line, not the overhang
  from the holder face; it is not used. A tool with ``Q``, ``I`` or ``J``
  is a lathe tool and is refused.
* **Fusion 360 tool library** (JSON export, ``.json``): ``{"data": [tool,
  ...]}``; of each tool ``type`` (``"ball end mill"``, ``"bull nose end
  mill"``, ``"flat end mill"``; ``"holder"`` entries are passed over),
  ``unit`` (``"millimeters"`` or ``"inches"``), ``post-process.number`` (the
  tool number), ``geometry``: ``DC`` cutting diameter, ``RE`` corner radius,
  ``NOF`` flutes, ``LCF`` flute length, ``LB`` body length below the holder
  (the overhang), ``SFDM`` shank diameter (``OAL`` and the others are not
  used), and ``holder.segments`` (``height``, ``lower-diameter``,
  ``upper-diameter``, in the holder's own ``unit``, which may differ from the
  tool's). The numeric fields are read; Fusion's ``expressions`` (from which
  Fusion re-derives them on loading) are not evaluated. The library has no
  helix angle: ``helix_deg`` is given in ``[tool]``.

The holder: :class:`errpred.tool.Holder` is one cylinder (``orient``'s
interference checks test it as one). A Fusion holder's segments (truncated
cones) become the cylinder that encloses them all: the largest diameter of
any segment over the sum of their heights (segments above the gauge line
included). Conservative: a slim shrink-fit nose is checked as if it were as
wide as the holder's widest part.

Every problem raises :class:`ToolLibraryError` (an :class:`nc.errors.InputError`)
naming the library file and the line (``.tbl``) or the tool (``data[i]``,
tool number). Syntax is checked on every line or entry; values (finite,
positive, consistent) on the tool asked for, since shop libraries hold
drills, probes and placeholders (``D0``) beside the end mills.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from nc.errors import InputError

from . import constants as K

__all__ = ["FUSION_TYPES", "LIBRARY_KEYS", "TBL_UNITS", "LibraryTool", "ToolLibraryError",
           "library_tool", "tool_table_from_library"]

#: Fusion 360 tool types read, and the project's kind each one is.
FUSION_TYPES = {"ball end mill": "ball", "bull nose end mill": "radius", "flat end mill": "flat"}
#: Units of a LinuxCNC tool table (``[tool] library_units``), as factors to mm.
TBL_UNITS = {"mm": 1.0, "inch": K.INCH_MM}
#: Fusion 360 ``unit`` values, as factors to mm.
_FUSION_UNITS = {"millimeters": 1.0, "inches": K.INCH_MM}
#: The ``[tool]`` keys that name a library (removed before the tool is read).
LIBRARY_KEYS = ("library", "number", "library_units")
#: ``[tool]`` keys every tool needs (besides a radius end mill's corner radius).
_REQUIRED = ("type", "diameter_mm", "flutes", "helix_deg")

_UNITS_MISSING = ("a LinuxCNC tool table carries no units (they are the machine's, the "
                  "INI's [TRAJ] LINEAR_UNITS); give library_units = \"mm\" or \"inch\"")
_UNITS_NOT_HERE = ("library_units is for a LinuxCNC tool table (.tbl) only; a Fusion 360 "
                   "library names its unit per tool")
_TBL_INT, _TBL_REAL = "TPQ", "DXYZABCUVWIJ"
_REAL = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


class ToolLibraryError(InputError):
    """A tool library that cannot be used: names the file and where in it.

    Attributes
    ----------
    file : str
    where : str or None
        ``line 4``, ``data[2] (tool 3)``, or None for the file as a whole.
    """

    def __init__(self, file: str | os.PathLike, where: str | None, message: str) -> None:
        self.file, self.where = os.fspath(file), where
        super().__init__(f"{self.file}: {where}: {message}" if where else
                         f"{self.file}: {message}")


@dataclass(frozen=True, eq=False)
class LibraryTool:
    """One tool of a library, as ``[tool]`` keys.

    Attributes
    ----------
    number : int
        The tool number.
    file : str
        The library file.
    where : str
        Where in it (``line 4``, ``data[2]``).
    format : str
        ``"LinuxCNC tool table"`` or ``"Fusion 360 tool library"``.
    values : dict
        ``[tool]`` keys the library gives, lengths in mm (``holder`` a table
        of ``diameter_mm`` and ``length_mm``).
    gaps : dict
        ``[tool]`` key -> why the library does not give it (for the message
        asking for it).
    required : tuple of str
        Keys this format requires beyond every tool's (a ``.tbl``'s flute
        length, which a ``[tool]`` table may leave to its default).
    description : str
        The library's description or comment of the tool.
    extra : dict
        Values read but not used (a ``.tbl``'s offsets, a Fusion ``OAL``), mm
        (a ``.tbl``'s A, B, C offsets in degrees).
    """

    number: int
    file: str
    where: str
    format: str
    values: dict
    gaps: dict
    required: tuple[str, ...] = ()
    description: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def label(self) -> str:
        """``tools.tbl tool 3 (line 4)``: the tool in words, for messages."""
        return f"{self.file} tool {self.number} ({self.where})"

    def complete(self, given: dict) -> tuple[dict, list[tuple[str, str]]]:
        """The library's values overridden by ``given``, and what is still missing.

        Parameters
        ----------
        given : dict
            The other ``[tool]`` keys (their values unchecked).

        Returns
        -------
        merged : dict
        missing : list of (key, reason)
            Required keys neither gives, in ``[tool]`` order.
        """
        merged = {**self.values, **given}
        need = list(_REQUIRED) + list(self.required)
        if merged.get("type") == "radius":
            need.append("corner_radius_mm")
        missing = [(k, self.gaps.get(k, f"{self.label} does not give it")) for k in need
                   if k not in merged]
        return merged, missing


def _real(file: Any, where: str, name: str, v: Any, *, sign: str = ">0") -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ToolLibraryError(file, where, f"{name}: expected a number, got {v!r}")
    v = float(v)
    if not math.isfinite(v) or (sign == ">0" and v <= 0) or (sign == ">=0" and v < 0):
        raise ToolLibraryError(file, where, f"{name}: expected a finite number {sign[:-1]} 0, "
                                            f"got {v!r}")
    return v


def _whole(file: Any, where: str, name: str, v: Any, minimum: int) -> int:
    ok = (isinstance(v, int) and not isinstance(v, bool)) or (
        isinstance(v, float) and math.isfinite(v) and v == int(v))
    if not ok or int(v) < minimum:
        raise ToolLibraryError(file, where, f"{name}: expected a whole number >= {minimum}, "
                                            f"got {v!r}")
    return int(v)


def _corner(file: Any, where: str, kind: str, dia: float, re_mm: float | None) -> float | None:
    """The corner radius a library gives for ``kind``, checked [mm] (None: not given)."""
    if kind == "radius":
        if re_mm is None:
            return None
        if not 0 < re_mm < dia / 2:
            raise ToolLibraryError(file, where, f"corner radius {re_mm:g} mm: a bull-nose end "
                                                f"mill needs 0 < r < D/2 = {dia / 2:g} mm")
        return re_mm
    if re_mm is None:
        return None
    if kind == "flat" and re_mm > K.LIBRARY_SHARP_CORNER_MM:
        raise ToolLibraryError(file, where, f"a flat end mill with corner radius {re_mm:g} mm "
                                            f"is a bull-nose end mill; fix the library, or give "
                                            f"type = \"radius\" and corner_radius_mm in [tool]")
    if kind == "ball" and abs(re_mm - dia / 2) > K.LIBRARY_BALL_RADIUS_TOL_MM:
        raise ToolLibraryError(file, where, f"a ball end mill has corner radius D/2 = "
                                            f"{dia / 2:g} mm, the library gives {re_mm:g} mm")
    return None


# --------------------------------------------------------------------------- LinuxCNC
def _tbl_lines(path: Path) -> list[tuple[int, dict, str]]:
    """Every tool line of a ``.tbl``: (line number, {letter: value}, comment)."""
    try:
        text = path.read_text(encoding="utf-8", errors="strict")
    except UnicodeDecodeError as exc:
        raise ToolLibraryError(path, None, f"not a text file ({exc})") from None
    except OSError as exc:
        raise ToolLibraryError(path, None, f"cannot read ({exc})") from None
    out = []
    for ln, raw in enumerate(text.splitlines(), start=1):
        data, _, comment = raw.partition(";")
        if not data.strip():
            continue
        words: dict[str, float | int] = {}
        where = f"line {ln}"
        if data.split()[0].upper() == "TOOLNO":
            raise ToolLibraryError(path, where, "a tool table in the old column format (TOOLNO "
                                                "POCKET LENGTH DIAMETER), which LinuxCNC no "
                                                "longer reads; write it as T, P, Z, D words")
        for tok in data.split():
            letter, num = tok[0].upper(), tok[1:]
            if letter not in _TBL_INT + _TBL_REAL or not num:
                raise ToolLibraryError(path, where, f"{tok!r} is not a word of a LinuxCNC tool "
                                                    f"table (T, P, D, X Y Z A B C U V W, I, J, "
                                                    f"Q with a number; comments after ';')")
            if letter in words:
                raise ToolLibraryError(path, where, f"{letter} given twice")
            value = float(num) if _REAL.fullmatch(num) else math.nan
            if not math.isfinite(value) or (letter in _TBL_INT and value != int(value)):
                kind = "a whole number" if letter in _TBL_INT else "a number"
                raise ToolLibraryError(path, where, f"{tok!r}: {letter} needs {kind}")
            words[letter] = int(value) if letter in _TBL_INT else value
        if "T" not in words:
            raise ToolLibraryError(path, f"line {ln}", "missing tool number (T)")
        out.append((ln, words, comment.strip()))
    return out


def _tbl_tool(path: Path, number: int, units: str | None) -> LibraryTool:
    if units not in TBL_UNITS:
        raise ToolLibraryError(path, None, _UNITS_MISSING)
    lines = _tbl_lines(path)
    rows = [r for r in lines if r[1]["T"] == number]
    if not rows:
        have = ", ".join(f"T{n}" for n in sorted({r[1]["T"] for r in lines})) or "none"
        raise ToolLibraryError(path, None, f"no tool T{number} (tools: {have})")
    if len(rows) > 1:
        raise ToolLibraryError(path, f"line {rows[1][0]}", f"T{number} is also on line "
                                                           f"{rows[0][0]}; which one is meant?")
    ln, words, comment = rows[0]
    where = f"line {ln} (T{number})"
    lathe = [k for k in "QIJ" if words.get(k)]
    if lathe:
        raise ToolLibraryError(path, where, f"a lathe tool ({', '.join(lathe)} given); "
                                            f"expected an end mill")
    if "D" not in words:
        raise ToolLibraryError(path, where, "no diameter (D)")
    fac = TBL_UNITS[units]
    dia = _real(path, where, "D (diameter)", words["D"]) * fac
    why = f"{path.name} is a LinuxCNC tool table, which holds only the diameter and offsets"
    gaps = {"type": f"{why}, no tool type", "flutes": f"{why}, no flute count",
            "helix_deg": f"{why}, no helix angle",
            "corner_radius_mm": f"{why}, no corner radius",
            "flute_length_mm": f"{why}, no flute length"}
    extra = {k: v * (fac if k in "XYZUVW" else 1.0) for k, v in words.items()
             if k in "XYZABCUVW"}                     # A, B, C in degrees
    return LibraryTool(number, os.fspath(path), f"line {ln}", "LinuxCNC tool table",
                       {"diameter_mm": dia}, gaps, ("flute_length_mm",), comment, extra)


# --------------------------------------------------------------------------- Fusion 360
def _fusion_tool(path: Path, number: int) -> LibraryTool:
    try:
        with open(path, encoding="utf-8-sig") as fh:
            doc = json.load(fh)
    except json.JSONDecodeError as exc:
        raise ToolLibraryError(path, f"line {exc.lineno}", f"not valid JSON ({exc.msg})") \
            from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ToolLibraryError(path, None, f"cannot read ({exc})") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("data"), list):
        raise ToolLibraryError(path, None, "expected a Fusion 360 tool library: an object "
                                           "with a \"data\" list of tools")
    found, numbers = [], []
    for i, t in enumerate(doc["data"]):
        where = f"data[{i}]"
        if not isinstance(t, dict):
            raise ToolLibraryError(path, where, f"expected a tool (an object), got {t!r}")
        if t.get("type") == "holder":
            continue
        pp = t.get("post-process")
        if not isinstance(pp, dict) or "number" not in pp:
            raise ToolLibraryError(path, where, f"missing post-process.number (the tool "
                                                f"number) of {t.get('type', 'a tool')!r} "
                                                f"{t.get('description', '')!r}")
        n = _whole(path, where, "post-process.number", pp["number"], 0)
        numbers.append(n)
        if n == number:
            found.append(i)
    if not found:
        have = ", ".join(map(str, sorted(set(numbers)))) or "none"
        raise ToolLibraryError(path, None, f"no tool number {number} (tool numbers: {have})")
    if len(found) > 1:
        raise ToolLibraryError(path, f"data[{found[1]}]", f"tool number {number} is also "
                                                          f"data[{found[0]}]; which is meant?")
    i = found[0]
    t, where = doc["data"][i], f"data[{i}] (tool {number})"
    kind = FUSION_TYPES.get(t.get("type"))
    if kind is None:
        raise ToolLibraryError(path, where, f"type {t.get('type')!r} is not an end mill this "
                                            f"project models; expected one of "
                                            f"{', '.join(map(repr, FUSION_TYPES))}")
    fac = _FUSION_UNITS.get(t.get("unit"))
    if fac is None:
        raise ToolLibraryError(path, where, f"unit {t.get('unit')!r}; expected one of "
                                            f"{', '.join(map(repr, _FUSION_UNITS))}")
    g = t.get("geometry")
    if not isinstance(g, dict):
        raise ToolLibraryError(path, where, "missing geometry")
    if "DC" not in g:
        raise ToolLibraryError(path, where, "missing geometry.DC (the cutting diameter)")

    def length(key: str) -> float | None:
        return _real(path, where, f"geometry.{key}", g[key]) * fac if key in g else None

    dia = length("DC")
    corner = _corner(path, where, kind, dia, None if "RE" not in g else
                     _real(path, where, "geometry.RE", g["RE"], sign=">=0") * fac)
    values: dict[str, Any] = {"type": kind, "diameter_mm": dia}
    if corner is not None:
        values["corner_radius_mm"] = corner
    if "NOF" in g:
        values["flutes"] = _whole(path, where, "geometry.NOF", g["NOF"], 1)
    for key, name in (("LCF", "flute_length_mm"), ("LB", "overhang_mm"),
                      ("SFDM", "shank_diameter_mm")):
        if key in g:
            values[name] = length(key)
    holder = _fusion_holder(path, where, t.get("holder"), t.get("unit"))
    if holder is not None:
        values["holder"] = holder
    why = f"{path.name} is a Fusion 360 tool library"
    gaps = {"helix_deg": f"{why}, which has no helix angle",
            "flutes": f"{where} of {path.name} has no geometry.NOF (flutes)",
            "corner_radius_mm": f"{where} of {path.name} has no geometry.RE (corner radius)"}
    extra = {"OAL": length("OAL")} if "OAL" in g else {}
    desc = t.get("description", "")
    return LibraryTool(number, os.fspath(path), f"data[{i}]", "Fusion 360 tool library",
                       values, gaps, (), desc if isinstance(desc, str) else "", extra)


def _fusion_holder(path: Path, where: str, h: Any, tool_unit: str) -> dict | None:
    """A Fusion holder as ``[tool.holder]`` keys: the cylinder enclosing its segments."""
    if h is None:
        return None
    if not isinstance(h, dict):
        raise ToolLibraryError(path, where, f"holder: expected an object, got {h!r}")
    segs = h.get("segments", [])
    if not isinstance(segs, list):
        raise ToolLibraryError(path, where, "holder.segments: expected a list")
    if not segs:
        return None
    unit = h.get("unit", tool_unit)
    fac = _FUSION_UNITS.get(unit)
    if fac is None:
        raise ToolLibraryError(path, where, f"holder.unit {unit!r}; expected one of "
                                            f"{', '.join(map(repr, _FUSION_UNITS))}")
    height, dia = 0.0, 0.0
    for j, s in enumerate(segs):
        name = f"holder.segments[{j}]"
        if not isinstance(s, dict) or any(k not in s for k in
                                          ("height", "lower-diameter", "upper-diameter")):
            raise ToolLibraryError(path, where, f"{name}: expected height, lower-diameter and "
                                                f"upper-diameter")
        height += _real(path, where, f"{name}.height", s["height"])
        dia = max(dia, _real(path, where, f"{name}.lower-diameter", s["lower-diameter"]),
                  _real(path, where, f"{name}.upper-diameter", s["upper-diameter"]))
    return {"diameter_mm": dia * fac, "length_mm": height * fac}


# --------------------------------------------------------------------------- entry points
def library_tool(path: str | os.PathLike, number: int, *, units: str | None = None
                 ) -> LibraryTool:
    """Read tool ``number`` of a tool library.

    Parameters
    ----------
    path : path-like
        A LinuxCNC tool table (``.tbl``) or a Fusion 360 tool library (``.json``).
    number : int
        The tool number (``T`` of the ``.tbl``, ``post-process.number`` in Fusion).
    units : str, optional
        ``"mm"`` or ``"inch"``: the units of a ``.tbl`` (required for one;
        refused for a Fusion library, which names its unit per tool).

    Returns
    -------
    LibraryTool

    Raises
    ------
    ToolLibraryError
        Naming the file and the line or tool.
    """
    p = Path(path)
    if not p.is_file():
        raise ToolLibraryError(p, None, "no such file")
    suffix = p.suffix.lower()
    if suffix == ".tbl":
        return _tbl_tool(p, number, units)
    if suffix == ".json":
        if units is not None:
            raise ToolLibraryError(p, None, _UNITS_NOT_HERE)
        return _fusion_tool(p, number)
    raise ToolLibraryError(p, None, f"unknown tool library format {suffix!r}; expected a "
                                    f"LinuxCNC tool table (.tbl) or a Fusion 360 tool library "
                                    f"(.json)")


def tool_table_from_library(r: Any, d: dict) -> tuple[dict, str]:
    """The hook of :mod:`errpred.scenario`'s ``[tool]``: a library tool as a ``[tool]`` table.

    Parameters
    ----------
    r : errpred.scenario.TableReader
        The scenario's reader (paths relative to the scenario, errors naming
        the scenario file and key).
    d : dict
        The ``[tool]`` table, with ``library`` and ``number`` (and a
        ``.tbl``'s ``library_units``).

    Returns
    -------
    table : dict
        The library's values, overridden and completed by the other keys of
        ``d`` (which the scenario then checks as any ``[tool]`` table).
    origin : str
        The tool in words (``tools.tbl tool 3 (line 4)``).

    Raises
    ------
    errpred.scenario.ScenarioError
        A missing ``library`` or ``number``, a library that cannot be read
        (key ``tool.library``, the message naming the library's file and line
        or tool), or a key the library does not give and ``d`` does not
        either (naming what is missing and where to put it).
    """
    if "library" not in d:
        given = ", ".join(k for k in LIBRARY_KEYS if k in d)
        raise r.fail("tool.library", f"missing; {given} needs library = \"tools.tbl\" (a "
                                     f"LinuxCNC tool table) or \"tools.json\" (Fusion 360)")
    path = r.path(d, "library", "tool")
    number = r.integer(d, "number", "tool", minimum=0)
    units = r.string(d, "library_units", "tool", default=None, choices=tuple(TBL_UNITS))
    is_tbl = path.suffix.lower() == ".tbl"
    if is_tbl and units is None:
        raise r.fail("tool.library_units", f"missing; {_UNITS_MISSING}")
    if units is not None and not is_tbl:
        raise r.fail("tool.library_units", _UNITS_NOT_HERE)
    try:
        entry = library_tool(path, number, units=units)
    except ToolLibraryError as exc:
        raise r.fail("tool.library", str(exc)) from None
    merged, missing = entry.complete({k: v for k, v in d.items() if k not in LIBRARY_KEYS})
    if missing:
        key, why = missing[0]
        raise r.fail(f"tool.{key}", f"missing; {why}: give {key} in [tool] beside library")
    return merged, entry.label
