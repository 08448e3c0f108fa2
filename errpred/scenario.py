"""Scenario files: everything one prediction run needs, in one TOML file.

A scenario names the stock, the tool, the NC program, the cutting
coefficients, the tool-tip dynamics, the tool's shape error and wear, and
optional resolution, correction and tool-change settings. Every path is
relative to the scenario file. Units are in the key names (``diameter_mm``,
``stiffness_N_m``); degrees only in keys ending ``_deg``. The format is
described key by key in ``docs/scenario-format.md``.

:func:`load_scenario` checks the whole file before anything is computed. Every
problem raises :class:`ScenarioError` (a ``ValueError``) whose message names
the file, the dotted key (``tool.diameter_mm``, ``dynamics.modes[1].frequency_hz``)
and what was expected: missing keys, unknown keys (typos and wrong units are
refused, with a suggestion), wrong types, NaN and infinity (TOML has ``nan``
and ``inf`` literals), zero or negative values where a positive one is
needed, unknown tool types, files that do not exist (with the resolved path),
and both or neither of ``stock.stl`` and ``stock.box_*``.

A used tool starts from its wear state: ``[tool] state = "tool-state.json"``
(a file written by ``--tool-state-out``, :mod:`errpred.tool_state`; read and
checked against the scenario's tool and micro edges here) or ``[tool]
used_cutting_distance_m = 12.5`` (every micro edge has cut that far).

The tool may come from a library: ``[tool] library = "tools.json"`` and
``number = 3`` (a Fusion 360 tool library, or a LinuxCNC ``.tbl`` with
``library_units``), the other ``[tool]`` keys overriding or completing it
(:mod:`errpred.toollib`). Measured FRFs: ``dynamics.frf_uff``, ``frf_csv`` or
``frf_cutpro`` (:mod:`errpred.frf_files`).

Two scenarios are bundled (:data:`BUNDLED`, :func:`bundled_scenario`); they
are made by ``scripts/make_errpred_scenarios.py``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from nc.errors import InputError
from nc.tables import value_kind

from . import constants as K
from .geometry import Resolution
from .tables import ScenarioError, TableReader, _limit, check_program_lines
from .tool import TOOL_KINDS, Holder, Tool
from .toollib import LIBRARY_KEYS, tool_table_from_library

__all__ = ["ScenarioError", "StockSpec", "ShapeError", "Resolution", "CorrectionOptions",
           "Scenario", "TableReader", "load_scenario", "check_program_lines", "BUNDLED",
           "bundled_scenario", "cutting_coefficients"]

_HERE = Path(__file__).resolve().parent / "scenarios"
#: Bundled scenarios: name -> path of their ``scenario.toml``.
BUNDLED: dict[str, Path] = {n: _HERE / n / "scenario.toml" for n in ("mold-ball", "wall-radius")}

_DIRECTIONS = ("x", "y", "z")


def bundled_scenario(name: str) -> Path:
    """Path of the bundled scenario ``name`` (a key of :data:`BUNDLED`)."""
    try:
        return BUNDLED[name]
    except KeyError:
        raise InputError(f"no bundled scenario {name!r}; expected one of "
                         f"{', '.join(BUNDLED)}") from None


# --------------------------------------------------------------------------- results
@dataclass(frozen=True)
class StockSpec:
    """Where the stock comes from.

    Attributes
    ----------
    kind : str
        ``'stl'`` or ``'box'``.
    path : Path or None
        The stock mesh (kind ``'stl'``).
    bounds : tuple of two 3-tuples or None
        ``(min_mm, max_mm)`` (kind ``'box'``) [mm].
    design_path : Path or None
        The design surface mesh, for over- and undercut against the design.
    """

    kind: str
    path: Path | None = None
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    design_path: Path | None = None

    def load(self):
        """The stock as an :class:`errpred.raster.meshes.Stock`."""
        from .raster.meshes import Stock

        if self.kind == "stl":
            return Stock.from_stl(self.path)
        return Stock.from_box(*self.bounds)

    def load_design(self):
        """The design mesh as a ``trimesh.Trimesh``, or None without one."""
        if self.design_path is None:
            return None
        from .meshio import load_mesh

        return load_mesh(self.design_path, what="design mesh")

    def mesh(self):
        """The stock as a closed ``trimesh.Trimesh``: the STL, or the box (what shank and
        holder must clear, and what the planner, the job and the simulated machine check
        postures against)."""
        if self.kind == "stl":
            from .meshio import load_mesh

            return load_mesh(self.path, what="stock mesh", closed=True)
        import trimesh

        lo, hi = np.asarray(self.bounds[0], float), np.asarray(self.bounds[1], float)
        return trimesh.creation.box(extents=hi - lo,
                                    transform=trimesh.transformations.translation_matrix(
                                        (lo + hi) / 2))


@dataclass(frozen=True, eq=False)
class ShapeError:
    """Tool shape error (measured on the spinning tool) and wear.

    The table gives the effective cutting radius minus nominal against the
    contact angle kappa (``axis == 'kappa'``, abscissa in rad) or against the
    height above the tip (``axis == 'z'``, in mm); ``axis == 'none'`` means no
    table (zero deviation). Between table points the deviation is linear;
    beyond the first and last point it is held at the end value.

    Sign: the machining error from the tool's shape is ``E_p = -deviation +
    wear loss`` [mm], positive = material left. A tool whose effective radius
    is smaller than nominal (negative deviation) or that has worn leaves
    material. The wear loss is ``wear_rate_mm_per_mm * cl``, ``cl`` the
    micro edge's actual cutting distance [mm].

    Attributes
    ----------
    axis : str
    abscissa : ndarray [rad or mm]
    deviation_mm : ndarray [mm]
    wear_rate_mm_per_mm : float
        Radius loss per mm of actual cutting distance [mm/mm] (the file's
        ``wear_rate_um_per_m`` times 1e-6).
    source : str
    """

    axis: str = "none"
    abscissa: np.ndarray = field(default_factory=lambda: np.zeros(1))
    deviation_mm: np.ndarray = field(default_factory=lambda: np.zeros(1))
    wear_rate_mm_per_mm: float = 0.0
    source: str = ""

    def radius_deviation_mm(self, kappa_rad: Any, z_mm: Any) -> np.ndarray:
        """Effective radius minus nominal at contact angle / height [mm].

        Both arguments are given (broadcast together); the table's axis
        decides which one is used.
        """
        k, z = np.broadcast_arrays(np.asarray(kappa_rad, float), np.asarray(z_mm, float))
        if self.axis == "none":
            return np.zeros(k.shape)
        return np.interp(k if self.axis == "kappa" else z, self.abscissa, self.deviation_mm)

    def wear_loss_mm(self, cl_mm: Any) -> np.ndarray:
        """Radius lost to wear after actual cutting distance ``cl_mm`` [mm]."""
        return self.wear_rate_mm_per_mm * np.asarray(cl_mm, float)

    def material_left_mm(self, kappa_rad: Any, z_mm: Any, cl_mm: Any = 0.0) -> np.ndarray:
        """``E_p = -deviation + wear loss`` [mm] (positive = undercut, material left)."""
        return self.wear_loss_mm(cl_mm) - self.radius_deviation_mm(kappa_rad, z_mm)


@dataclass(frozen=True)
class CorrectionOptions:
    """Path correction: one pass, or predict-correct iterations until the
    largest change of a point is below ``tolerance_um``; the corrected program is
    written only if its dense re-prediction is nowhere worse than the original's by
    more than ``verify_tolerance_um``."""

    iterate: bool = False
    tolerance_um: float = 1.0
    max_iterations: int = 5
    verify_tolerance_um: float = K.VERIFY_TOLERANCE_UM
    #: Share of the first pass's fit applied (0 < share <= 1; None: RELAXATION when
    #: iterating, the whole fit for one pass) [-] (``[correction] relaxation``).
    relaxation: float | None = None
    #: Compare the walls a flat or radius end mill's flank finishes beside its floors
    #: too (``[correction] verify_walls``; false where they are not the part's surfaces,
    #: e.g. the steps between a flat end mill's raster passes).
    verify_walls: bool = True


@dataclass(frozen=True, eq=False)
class Scenario:
    """A loaded, checked scenario (see :func:`load_scenario`)."""

    name: str
    path: Path
    stock: StockSpec
    tool: Tool
    program_path: Path
    allow: tuple[str, ...]
    lines: tuple[int, int] | None
    machine: str | Path | None
    coefficients: Any
    compliance: Any
    shape_error: ShapeError
    resolution: Resolution
    correction: CorrectionOptions
    tool_change_tolerance_um: float | None
    sources: dict[str, str]
    description: str = ""
    #: Tables of the sections named in ``load_scenario(extra_sections=...)``,
    #: unchecked: the package that asked for them reads them.
    extra: dict = field(default_factory=dict)
    #: The program's dialect: "auto" (detected from its first blocks), "gcode",
    #: "heidenhain" or "siemens" (``[program] dialect``).
    dialect: str = "auto"
    #: The tool's wear at the start [mm]: None (a fresh tool), one actual
    #: cutting distance for every micro edge (``tool.used_cutting_distance_m``),
    #: or one per micro edge (``tool.state``, checked against this tool and
    #: its micro edges at the scenario's resolution).
    initial_wear_mm: Any = None
    #: Where :attr:`initial_wear_mm` comes from, in words (for the report).
    tool_start: str = "new tool"

    def resolve_machine(self, override: Any = None) -> Any:
        """The machine the program runs on, the one resolution every package uses.

        Parameters
        ----------
        override : str, Path or nc.machines.Machine, optional
            A named machine, a machine file (``.toml``) or a machine; default: the
            scenario's ``program.machine``.

        Returns
        -------
        nc.machines.Machine or None
            A name or a file resolved (:func:`nc.kinematics.get_machine`,
            :func:`nc.kinematics.load_machine`) with the tool length set to the
            tool's overhang [mm] (spindle nose to tip, the gauge length: on a head
            machine it places the tip from the pivots, so a program read or written
            without it puts the tip elsewhere); a machine given as such is returned
            as given. None when neither is given.
        """
        m = override if override is not None else self.machine
        if m is None:
            return None
        if hasattr(m, "inverse"):
            return m
        from nc.kinematics import get_machine, load_machine

        machine = load_machine(m) if isinstance(m, Path) or str(m).endswith(".toml") \
            else get_machine(str(m))
        return machine.with_tool_length(self.tool.overhang_mm)

    def read_program(self):
        """The NC program (``nc.read_any``: the scenario's dialect, allow list and
        machine, which a Siemens CYCLE800 in direct mode needs)."""
        from nc import read_any

        return read_any(self.program_path, None if self.dialect == "auto" else self.dialect,
                        allow=self.allow, machine=self.resolve_machine())


# --------------------------------------------------------------------------- sections
def _stock(r: TableReader, d: dict) -> StockSpec:
    r.keys(d, "stock", (), ("stl", "box_min_mm", "box_max_mm", "design_stl"))
    design = _mesh(r, d, "design_stl", closed=False) if "design_stl" in d else None
    box = [k for k in ("box_min_mm", "box_max_mm") if k in d]
    if "stl" in d and box:
        raise r.fail("stock.stl", "give either stl or box_min_mm and box_max_mm, not both")
    if "stl" in d:
        return StockSpec("stl", path=_mesh(r, d, "stl", closed=True), design_path=design)
    if not box:
        raise r.fail("stock.stl", "missing; expected stl = \"file.stl\" or box_min_mm and "
                                  "box_max_mm")
    lo = r.numbers(d, "box_min_mm", "stock", length=3) if "box_min_mm" in d else None
    hi = r.numbers(d, "box_max_mm", "stock", length=3) if "box_max_mm" in d else None
    if lo is None or hi is None:
        raise r.fail("stock.box_min_mm" if lo is None else "stock.box_max_mm",
                     "missing; a box needs both box_min_mm and box_max_mm")
    if any(b <= a for a, b in zip(lo, hi)):
        raise r.fail("stock.box_max_mm", f"expected every coordinate above box_min_mm {lo}, "
                                         f"got {hi}")
    return StockSpec("box", bounds=(tuple(lo), tuple(hi)), design_path=design)


def _mesh(r: TableReader, d: dict, k: str, *, closed: bool) -> Path:
    """A mesh file's path, read once here (:func:`errpred.meshio.load_mesh`) so that an
    empty, corrupt or (``closed``: a stock) open mesh is refused before any work."""
    from .meshio import MeshFileError, load_mesh

    path = r.path(d, k, "stock")
    try:
        load_mesh(path, what="stock mesh" if closed else "design mesh", closed=closed)
    except MeshFileError as exc:
        raise r.fail(f"stock.{k}", str(exc)) from None
    return path


def _tool(r: TableReader, d: dict) -> Tool:
    p = "tool"
    origin = ""
    if any(k in d for k in LIBRARY_KEYS):   # library + number: errpred.toollib
        d, origin = tool_table_from_library(r, d)
    r.keys(d, p, ("type", "diameter_mm", "flutes", "helix_deg"),
           ("corner_radius_mm", "flute_length_mm", "overhang_mm", "rotation",
            "shank_diameter_mm", "holder", "state", "used_cutting_distance_m"))
    kind = r.string(d, "type", p)
    if kind not in TOOL_KINDS:
        raise r.fail("tool.type", f"unknown tool type {kind!r}; expected one of "
                                  f"{', '.join(TOOL_KINDS)}")
    dia = r.number(d, "diameter_mm", p, sign=">0", **_limit("MAX_TOOL_DIAMETER_MM"))
    corner = 0.0
    if kind == "radius":
        corner = r.number(d, "corner_radius_mm", p, sign=">0")
        if corner >= dia / 2:
            raise r.fail("tool.corner_radius_mm", f"expected less than diameter_mm / 2 = "
                                                  f"{dia / 2:g} for a radius end mill, got "
                                                  f"{corner:g}")
    elif "corner_radius_mm" in d:
        want = dia / 2 if kind == "ball" else 0.0
        got = r.number(d, "corner_radius_mm", p, sign=">=0")
        if abs(got - want) > 1e-9:
            raise r.fail("tool.corner_radius_mm", f"a {kind} end mill has corner radius "
                                                  f"{want:g} mm, got {got:g}")
    helix = r.number(d, "helix_deg", p)
    if abs(helix) > 60:
        raise r.fail("tool.helix_deg", f"expected -60 to 60 degrees, got {helix:g}")
    opt = {k: r.number(d, k, p, default=None, sign=">0", **_limit(
        "MAX_TOOL_DIAMETER_MM" if k == "shank_diameter_mm" else "MAX_TOOL_LENGTH_MM"))
           for k in ("flute_length_mm", "overhang_mm", "shank_diameter_mm")}
    holder = None
    if "holder" in d:
        h = r.table(d["holder"], "tool.holder")
        r.keys(h, "tool.holder", ("diameter_mm", "length_mm"))
        holder = Holder(*(r.number(h, k, "tool.holder", sign=">0",
                                   **_limit("MAX_TOOL_LENGTH_MM"))
                          for k in ("diameter_mm", "length_mm")))
    flutes = r.integer(d, "flutes", p, **_limit("MAX_FLUTES"))
    rotation = r.string(d, "rotation", p, default="cw", choices=("cw", "ccw"))
    try:
        return Tool(kind, dia, corner, flutes, helix, rotation=rotation, holder=holder, **opt)
    except ValueError as exc:
        raise r.fail("tool", str(exc) + (f" (with {origin})" if origin else "")) from None


def _tool_start(r: TableReader, d: dict, tool: Tool, res: Resolution) -> tuple[Any, str]:
    """``tool.state`` or ``tool.used_cutting_distance_m``: the wear at the start [mm]."""
    from .tool_state import check_compatible, read_tool_state

    given = [k for k in ("state", "used_cutting_distance_m") if k in d]
    if len(given) > 1:
        raise r.fail("tool.used_cutting_distance_m", "give state or used_cutting_distance_m, "
                                                     "not both")
    if "used_cutting_distance_m" in d:
        v = r.number(d, "used_cutting_distance_m", "tool", sign=">=0",
                     **_limit("MAX_CUTTING_DISTANCE_M"))
        return v * 1e3, f"used tool: every micro edge has cut {v:g} m"
    if "state" in d:
        path = r.path(d, "state", "tool")
        try:
            state = read_tool_state(path)
            check_compatible(state, tool, tool.micro_edges(res.micro_edges))
        except ValueError as exc:
            raise r.fail("tool.state", str(exc)) from None
        return state.cl_mm, f"used tool: state from {path}"
    return None, "new tool"


def _program(r: TableReader, d: dict) -> tuple:
    p = "program"
    r.keys(d, p, ("gcode",), ("allow", "lines", "machine", "dialect"))
    gcode = r.path(d, "gcode", p)
    dialect = r.string(d, "dialect", p, default="auto") if "dialect" in d else "auto"
    if dialect not in ("auto", "gcode", "heidenhain", "siemens"):
        raise r.fail("program.dialect", f"expected \"auto\", \"gcode\", \"heidenhain\" or "
                                        f"\"siemens\", got {dialect!r}")
    allow = d.get("allow", [])
    if not isinstance(allow, list) or not all(isinstance(a, str) for a in allow):
        raise r.fail("program.allow", f"expected an array of strings, got {value_kind(allow)}")
    try:
        from nc.dialect import normalise_allow

        normalise_allow(allow)
    except ValueError as exc:
        raise r.fail("program.allow", str(exc)) from None
    lines = None
    if "lines" in d:
        v = d["lines"]
        if not (isinstance(v, list) and len(v) == 2
                and all(isinstance(x, int) and not isinstance(x, bool) and x >= 1 for x in v)
                and v[0] <= v[1]):
            raise r.fail("program.lines", f"expected [first, last], whole numbers >= 1 with "
                                          f"first <= last, got {value_kind(v)}")
        lines = (v[0], v[1])
    machine: str | Path | None = None
    if "machine" in d:
        m = r.string(d, "machine", p)
        if m.endswith(".toml"):
            machine = r.path(d, "machine", p)
        else:
            from nc.kinematics import MACHINES, machine_kind

            if machine_kind(m) is None:
                raise r.fail("program.machine", f"unknown machine {m!r}; expected one of "
                                                f"{', '.join(sorted(MACHINES))} or a .toml file")
            machine = m
    return gcode, tuple(allow), lines, machine, dialect


def _cutting(r: TableReader, d: dict):
    """``[cutting]``: ``law`` (default "linear", :data:`errpred.laws.LAWS`) and that
    law's keys (its ``KEYS``), each checked here; the law's own checks (e.g. a
    polynomial's degree) are refused under the table."""
    from .constants import KIENZLE_MAX_MC
    from .laws import LAWS

    p = "cutting"
    name = r.string(d, "law", p, default="linear", choices=tuple(LAWS))
    law = LAWS[name]
    keys = law.KEYS
    r.keys(d, p, tuple(k for k, (_, req) in keys.items() if req),
           tuple(k for k, (_, req) in keys.items() if not req) + ("law", "source"))
    lim = _limit("MAX_CUTTING_COEFFICIENT")
    vals = {}
    for k, (kind, _req) in keys.items():
        if k not in d:
            continue
        if kind == "polynomial":
            v = d[k]
            vals[k] = r.numbers({k: v if isinstance(v, list) else [v]}, k, p, **lim)
        elif kind == "fraction":
            vals[k] = r.number(d, k, p, sign=">=0", maximum=KIENZLE_MAX_MC,
                               limit="errpred.constants.KIENZLE_MAX_MC")
        else:
            vals[k] = r.number(d, k, p, sign=">0" if kind == "positive" else "", **lim)
    src = r.string(d, "source", p, default="")
    try:
        return law.from_values(vals, source=src), src
    except ValueError as exc:
        raise r.fail(p, str(exc)) from None


def cutting_coefficients(table: Any, file: str | os.PathLike):
    """The coefficients of a ``[cutting]`` table (a dict parsed from ``file``), checked
    as a scenario's are (:class:`ScenarioError` naming the file and key).

    Returns
    -------
    LawCoefficients
    """
    r = TableReader(file)
    return _cutting(r, r.table(table, "cutting"))[0]


def _dynamics(r: TableReader, d: dict):
    from .dynamics import Compliance, Mode

    p = "dynamics"
    r.keys(d, p, (), ("model", "modes", "frf_uff", "frf_csv", "frf_cutpro",
                      "static_compliance_m_N", "source"))
    model = r.string(d, "model", p, default="dynamic", choices=("dynamic", "static"))
    src = r.string(d, "source", p, default="")
    given = [k for k in ("modes", "frf_uff", "frf_csv", "frf_cutpro") if k in d]
    if len(given) > 1:
        raise r.fail(f"dynamics.{given[1]}", f"give one of modes, frf_uff, frf_csv, "
                                             f"frf_cutpro; got {', '.join(given)}")
    static = None
    if "static_compliance_m_N" in d:
        t = r.table(d["static_compliance_m_N"], "dynamics.static_compliance_m_N")
        r.keys(t, "dynamics.static_compliance_m_N", (), _DIRECTIONS)
        static = {k: r.number(t, k, "dynamics.static_compliance_m_N", sign=">0",
                              **_limit("MAX_STATIC_COMPLIANCE_M_N")) for k in t}
    if not given and not (model == "static" and static):
        raise r.fail("dynamics.modes", "missing; expected [[dynamics.modes]], frf_uff, "
                                       "frf_csv or frf_cutpro (or model = \"static\" with "
                                       "static_compliance_m_N)")
    if given == ["modes"] and static:
        raise r.fail("dynamics.static_compliance_m_N", "not with modes (their static "
                                                       "compliance is sum 1/k)")
    try:
        if given == ["modes"]:
            modes = _modes(r, d["modes"], Mode)
            return Compliance.from_modes(modes, static_only=model == "static"), src
        if given:
            key = given[0]
            if key == "frf_uff":
                comp = Compliance.from_uff(r.path(d, key, p), static_m_N=static)
            else:   # frf_csv, frf_cutpro: one file per direction
                t = r.table(d[key], f"dynamics.{key}")
                r.keys(t, f"dynamics.{key}", ("x", "y"), ("z",))
                read = Compliance.from_csv if key == "frf_csv" else Compliance.from_cutpro
                comp = read({k: r.path(t, k, f"dynamics.{key}") for k in t}, static_m_N=static)
            _need_xy(r, comp.directions, f"dynamics.{key}")
            if model == "dynamic":
                return comp, src
            static = comp.static_compliance_m_N
        _need_xy(r, tuple(static), "dynamics.static_compliance_m_N")
        return Compliance.from_modes({k: Mode(1.0 / c, 1.0, 0.0) for k, c in static.items()},
                                     static_only=True), src
    except ScenarioError:
        raise
    except (ValueError, TypeError, OSError) as exc:
        raise r.fail(f"dynamics.{given[0] if given else 'static_compliance_m_N'}",
                     str(exc)) from None


def _need_xy(r: TableReader, dirs: tuple, key: str) -> None:
    if not {"x", "y"} <= set(dirs):
        raise r.fail(key, f"needs directions x and y (the tool's two bending directions), "
                          f"got {', '.join(dirs) or 'none'}")


def _modes(r: TableReader, v: Any, Mode) -> dict:
    if not isinstance(v, list) or not v:
        raise r.fail("dynamics.modes", f"expected [[dynamics.modes]] tables, got {value_kind(v)}")
    out: dict[str, list] = {}
    for i, m in enumerate(v):
        p = f"dynamics.modes[{i}]"
        m = r.table(m, p)
        by_freq = "frequency_hz" in m or "damping_ratio" in m
        if by_freq:
            r.keys(m, p, ("direction", "frequency_hz", "damping_ratio", "stiffness_N_m"))
        else:
            r.keys(m, p, ("direction", "mass_kg", "damping_Ns_m", "stiffness_N_m"))
        dr = r.string(m, "direction", p, choices=_DIRECTIONS)
        k = r.number(m, "stiffness_N_m", p, sign=">0", **_limit("MAX_STIFFNESS_N_M"))
        if by_freq:
            mode = Mode.from_frequency(
                r.number(m, "frequency_hz", p, sign=">0", **_limit("MAX_MODE_FREQUENCY_HZ")),
                r.number(m, "damping_ratio", p, sign=">=0", **_limit("MAX_DAMPING_RATIO")), k)
        else:
            mode = Mode(k, r.number(m, "mass_kg", p, sign=">0", **_limit("MAX_MODE_MASS_KG")),
                        r.number(m, "damping_Ns_m", p, sign=">=0",
                                 **_limit("MAX_MODE_DAMPING_NS_M")))
            f = math.sqrt(mode.k_N_m / mode.m_kg) / (2 * math.pi)
            if f > K.MAX_MODE_FREQUENCY_HZ:
                raise r.fail(f"{p}.mass_kg", f"stiffness_N_m and mass_kg give a natural "
                                             f"frequency of {f:.3g} Hz, above "
                                             f"{K.MAX_MODE_FREQUENCY_HZ:g} "
                                             f"(errpred.constants.MAX_MODE_FREQUENCY_HZ)")
        out.setdefault(dr, []).append(mode)
    _need_xy(r, tuple(out), "dynamics.modes")
    return out


def _shape_error(r: TableReader, d: dict) -> ShapeError:
    p = "shape_error"
    r.keys(d, p, (), ("kappa_deg", "z_mm", "radius_deviation_um", "wear_rate_um_per_m",
                      "source"))
    wear = r.number(d, "wear_rate_um_per_m", p, default=0.0, sign=">=0",
                    **_limit("MAX_WEAR_RATE_UM_PER_M")) * 1e-6
    src = r.string(d, "source", p, default="")
    axes = [k for k in ("kappa_deg", "z_mm") if k in d]
    if len(axes) > 1:
        raise r.fail("shape_error.z_mm", "give kappa_deg or z_mm, not both")
    if not axes and "radius_deviation_um" not in d:
        return ShapeError(wear_rate_mm_per_mm=wear, source=src)
    if not axes:
        raise r.fail("shape_error.kappa_deg", "missing; radius_deviation_um needs kappa_deg "
                                              "or z_mm")
    if "radius_deviation_um" not in d:
        raise r.fail("shape_error.radius_deviation_um", "missing")
    x = r.numbers(d, axes[0], p, sign=">=0")
    dev = r.numbers(d, "radius_deviation_um", p, length=len(x),
                    **_limit("MAX_RADIUS_DEVIATION_UM"))
    if any(b <= a for a, b in zip(x, x[1:])):
        raise r.fail(f"shape_error.{axes[0]}", "expected strictly increasing values")
    if axes[0] == "kappa_deg":
        if x[-1] > 90:
            raise r.fail("shape_error.kappa_deg", f"expected 0 to 90 degrees, got {x[-1]:g}")
        xs = np.radians(x)
    else:
        xs = np.asarray(x)
    return ShapeError("kappa" if axes[0] == "kappa_deg" else "z", np.asarray(xs, float),
                      np.asarray(dev) * 1e-3, wear, src)


def _resolution(r: TableReader, d: dict, tool: Tool) -> Resolution:
    from .limits import check_resolution_budget

    p = "resolution"
    r.keys(d, p, (), ("pixel_mm", "micro_edges", "angle_step_deg", "chord_tol_mm",
                      "point_spacing_mm"))
    res = Resolution(
        r.number(d, "pixel_mm", p, default=tool.diameter_mm * K.PIXEL_PER_DIAMETER, sign=">0",
                 maximum=tool.diameter_mm / K.MIN_PIXELS_PER_DIAMETER,
                 limit="tool.diameter_mm / errpred.constants.MIN_PIXELS_PER_DIAMETER"),
        r.integer(d, "micro_edges", p, default=K.MICRO_EDGES_ENVELOPE, minimum=2,
                  **_limit("MAX_MICRO_EDGES")),
        math.radians(r.number(d, "angle_step_deg", p, default=math.degrees(K.ANGLE_STEP_RAD),
                              sign=">0", **_limit("MAX_ANGLE_STEP_DEG"))),
        r.number(d, "chord_tol_mm", p, default=K.CHORD_TOL_MM, sign=">0",
                 **_limit("MAX_CHORD_TOL_MM")),
        r.number(d, "point_spacing_mm", p, default=K.POINT_SPACING_MM, sign=">0")
        if "point_spacing_mm" in d else K.POINT_SPACING_MM)
    for k, least in (("chord_tol_mm", K.MIN_CHORD_TOL_MM),
                     ("point_spacing_mm", K.MIN_POINT_SPACING_MM)):
        if getattr(res, k) < least:
            raise r.fail(f"resolution.{k}", f"expected at least {least:g} "
                                            f"(errpred.constants.MIN_{k.upper()}), got "
                                            f"{getattr(res, k):g}")
    check_resolution_budget(r, d, tool, res)
    return res


def _correction(r: TableReader, d: dict) -> CorrectionOptions:
    p = "correction"
    r.keys(d, p, (), ("iterate", "tolerance_um", "max_iterations", "verify_tolerance_um",
                      "relaxation", "verify_walls"))
    it, walls = d.get("iterate", False), d.get("verify_walls", True)
    for key, v in (("iterate", it), ("verify_walls", walls)):
        if not isinstance(v, bool):
            raise r.fail(f"correction.{key}", f"expected true or false, got {value_kind(v)}")
    relax = r.number(d, "relaxation", p, default=None, sign=">0", maximum=1.0)
    return CorrectionOptions(it, r.number(d, "tolerance_um", p, default=1.0, sign=">0"),
                             r.integer(d, "max_iterations", p, default=5,
                                       **_limit("MAX_CORRECTION_ITERATIONS")),
                             r.number(d, "verify_tolerance_um", p,
                                      default=K.VERIFY_TOLERANCE_UM, sign=">=0"),
                             relax, walls)


# --------------------------------------------------------------------------- entry point
_TOP_REQUIRED = ("name", "stock", "tool", "program", "cutting", "dynamics")
_TOP_OPTIONAL = ("description", "shape_error", "resolution", "correction", "tool_change")


def load_scenario(path: str | os.PathLike, *, extra_sections: tuple[str, ...] = ()
                  ) -> Scenario:
    """Read and check a scenario file.

    Parameters
    ----------
    path : path-like
        The scenario TOML; relative paths inside it are relative to its folder.
    extra_sections : tuple of str
        Further top-level tables allowed in the file (a format that extends
        this one); they are returned unchecked in :attr:`Scenario.extra`.

    Returns
    -------
    Scenario

    Raises
    ------
    ScenarioError
        The first problem found, naming the file and the dotted key.
    """
    r = TableReader(path)
    doc = r.load("scenario file")
    r.keys(doc, "", _TOP_REQUIRED, _TOP_OPTIONAL + tuple(extra_sections))
    extra = {k: r.table(doc[k], k) for k in extra_sections if k in doc}
    sec = {k: r.table(doc[k], k) for k in _TOP_REQUIRED[1:] + _TOP_OPTIONAL[1:] if k in doc}
    name = r.string(doc, "name", "")
    if not name.strip():
        raise r.fail("name", "expected a non-empty string")
    description = r.string(doc, "description", "", default="")
    stock = _stock(r, sec["stock"])
    tool = _tool(r, sec["tool"])
    gcode, allow, lines, machine, dialect = _program(r, sec["program"])
    check_program_lines(r.read_program(gcode, allow, dialect), lines, r.file)
    coeffs, cut_src = _cutting(r, sec["cutting"])
    compliance, dyn_src = _dynamics(r, sec["dynamics"])
    shape = _shape_error(r, sec["shape_error"]) if "shape_error" in sec else ShapeError()
    resolution = _resolution(r, sec.get("resolution", {}), tool)
    wear0, start = _tool_start(r, sec["tool"], tool, resolution)
    tol = None
    if "tool_change" in sec:
        r.keys(sec["tool_change"], "tool_change", ("tolerance_um",))
        tol = r.number(sec["tool_change"], "tolerance_um", "tool_change", sign=">0")
    sources = {k: v for k, v in (("cutting", cut_src), ("dynamics", dyn_src),
                                 ("shape_error", shape.source)) if v}
    return Scenario(
        name=name, path=Path(r.file).resolve(), stock=stock, tool=tool, program_path=gcode,
        allow=allow, lines=lines, machine=machine, dialect=dialect, coefficients=coeffs, compliance=compliance,
        shape_error=shape, resolution=resolution,
        correction=_correction(r, sec.get("correction", {})), tool_change_tolerance_um=tol,
        sources=sources, description=description, extra=extra, initial_wear_mm=wear0,
        tool_start=start)
