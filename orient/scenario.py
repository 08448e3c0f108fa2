"""Planning scenarios: errpred's scenario format plus ``[orient]`` and ``[workpiece]``.

A planning scenario is an errpred scenario file (stock, design, tool, the CAM
program, cutting coefficients, tool dynamics; ``docs/scenario-format.md``)
with two more tables:

``[orient]`` -- the search: lead and tilt ranges and grid, inclination
limits, the smoothness limit, the margin aimed at, interference
clearances, whether points without a feasible posture may keep the CAM
posture (``allow_fallback``, default false: the plan is refused), the machine
dialect of the written program; ``[orient.cut]`` optionally the
local cut of the finishing passes for the whole program (depth, pick feed, on which
side the previous pass lies), overriding the cut taken from the part at each cutter
location (:mod:`orient.part_cuts`); ``[orient.spindle]`` optionally a spindle speed chosen
from the lobes.

``[workpiece]`` -- the workpiece's flexibility: rigid when absent; modes with
their directions (``[[workpiece.modes]]``); or a thin wall whose modes a
finite-element model of its in-process shape gives (``[workpiece.thin_wall]``).

Every problem raises :class:`errpred.scenario.ScenarioError` naming the file
and the dotted key, as errpred's own sections do.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from errpred import constants as EK
from errpred.scenario import Scenario, ScenarioError, TableReader, load_scenario

from nc.errors import InputError

from . import constants as K

__all__ = [
    "BUNDLED",
    "CutSpec",
    "OrientOptions",
    "PlanScenario",
    "ScenarioError",
    "SpindleChoice",
    "WorkpieceSpec",
    "bundled_scenario",
    "load_plan_scenario",
]

_HERE = Path(__file__).resolve().parent / "scenarios"
#: Bundled planning scenarios: name -> path of their ``scenario.toml``.
BUNDLED: dict[str, Path] = {n: _HERE / n / "scenario.toml" for n in ("thin-wall", "mold-core")}
#: The scenario ``python -m orient plan`` runs when given none.
DEFAULT_SCENARIO = "thin-wall"


def bundled_scenario(name: str = DEFAULT_SCENARIO) -> Path:
    """Path of the bundled planning scenario ``name``."""
    try:
        return BUNDLED[name]
    except KeyError:
        raise InputError(f"no bundled planning scenario {name!r}; expected one of "
                         f"{', '.join(BUNDLED)}") from None


@dataclass(frozen=True)
class CutSpec:
    """The local cut of the finishing passes (the fast engagement's input).

    Attributes
    ----------
    depth_mm : float [mm]
        Stock above the finished surface, along its normal.
    pick_mm : float [mm]
        Pick feed (step-over) between adjacent passes.
    machined_side : ndarray, shape (3,)
        Workpiece-frame direction from a pass toward the previous one (the
        side already finished); zero for single grooves.
    """

    depth_mm: float
    pick_mm: float
    machined_side: np.ndarray


@dataclass(frozen=True)
class SpindleChoice:
    """Choose the spindle speed from the lobes within ``range_rpm`` (``steps`` speeds)."""

    range_rpm: tuple[float, float]
    steps: int = K.SPINDLE_STEPS


@dataclass(frozen=True)
class OrientOptions:
    """The planner's search (``[orient]``); angles in radians."""

    lead_range_rad: tuple[float, float] = (math.radians(-K.LEAD_TILT_RANGE_DEG),
                                           math.radians(K.LEAD_TILT_RANGE_DEG))
    tilt_range_rad: tuple[float, float] = (math.radians(-K.LEAD_TILT_RANGE_DEG),
                                           math.radians(K.LEAD_TILT_RANGE_DEG))
    grid: tuple[int, int] = (K.GRID_STEPS, K.GRID_STEPS)
    min_inclination_rad: float = math.radians(K.MIN_INCLINATION_DEG)
    max_inclination_rad: float = math.radians(K.MAX_INCLINATION_DEG)
    max_rate_rad_per_mm: float = math.radians(K.MAX_RATE_DEG_PER_MM)
    #: smallest angle between the tool axis and the machine's rotary axis (the pole)
    pole_floor_rad: float = math.radians(K.POLE_FLOOR_DEG)
    margin_target: float = K.MARGIN_TARGET
    verify_sdm: bool = True
    #: keep the CAM posture where no posture is feasible (flagged) instead of refusing
    allow_fallback: bool = False
    clearance_mm: float = K.CLEARANCE_MM
    gouge_tol_mm: float = K.GOUGE_TOL_MM
    safety_factor: float = 1.0
    dialect: str = "linuxcnc"
    cut: CutSpec | None = None
    spindle: SpindleChoice | None = None


@dataclass(frozen=True)
class WorkpieceSpec:
    """The workpiece's flexibility: ``kind`` is ``'rigid'``, ``'modes'`` or ``'thin_wall'``.

    ``modes``: list of (errpred Mode, unit direction (3,)); ``thin_wall``: the
    keyword arguments of :class:`orient.workpiece_fem.ThinWall` plus the
    finished thickness and the mesh settings.
    """

    kind: str = "rigid"
    modes: tuple = ()
    thin_wall: dict = field(default_factory=dict)
    source: str = ""


@dataclass(frozen=True, eq=False)
class PlanScenario:
    """An errpred scenario with the planner's options and the workpiece model."""

    base: Scenario
    options: OrientOptions
    workpiece: WorkpieceSpec

    @property
    def name(self) -> str:
        return self.base.name

    @property
    def path(self) -> Path:
        return self.base.path

    def machine(self, override: Any = None) -> Any:
        """The machine the program runs on (``override``, else ``program.machine``):
        :meth:`errpred.scenario.Scenario.resolve_machine`, a name or a machine file
        with the tool's overhang as its tool length.

        Raises
        ------
        ScenarioError
            Neither given.
        """
        m = self.base.resolve_machine(override)
        if m is None:
            raise ScenarioError(str(self.path), "program.machine", "missing; the planner "
                                "needs the machine (axis limits, kinematics)")
        return m

    def stock_mesh(self) -> Any:
        """The stock as a closed ``trimesh.Trimesh`` (:meth:`errpred.scenario.StockSpec.mesh`):
        what shank and holder must clear."""
        return self.base.stock.mesh()

    def interference_checker(self, design: Any = None) -> Any:
        """The interference check of this scenario's tool against its stock and design:
        shank and holder kept ``[orient] clearance_mm`` from the stock, the flank into the
        design by at most ``[orient] gouge_tol_mm`` (the one check the planner, the job and
        the simulated machine make).

        Parameters
        ----------
        design : trimesh.Trimesh, optional
            The design mesh when already loaded (default: loaded here; none without
            ``stock.design_stl``, and then no gouge check).

        Returns
        -------
        orient.interference.InterferenceChecker
        """
        from .interference import InterferenceChecker, ToolAssembly

        if design is None:
            design = self.base.stock.load_design()
        opt = self.options
        return InterferenceChecker(
            self.stock_mesh(),
            ToolAssembly.from_tool(self.base.tool, clearance_mm=opt.clearance_mm),
            design_mesh=design, gouge_tol_mm=opt.gouge_tol_mm)


# --------------------------------------------------------------------------- reading
def _range(r: TableReader, d: dict, k: str, p: str, default: float) -> tuple[float, float]:
    if k not in d:
        return (math.radians(-default), math.radians(default))
    lo, hi = r.numbers(d, k, p, length=2)
    if not (-90 < lo < hi < 90):
        raise r.fail(f"{p}.{k}", f"expected [low, high] with -90 < low < high < 90 degrees, "
                                 f"got [{lo:g}, {hi:g}]")
    return (math.radians(lo), math.radians(hi))


def _vector(r: TableReader, d: dict, k: str, p: str, *, unit: bool, allow_zero: bool = False
            ) -> np.ndarray:
    v = np.array(r.numbers(d, k, p, length=3))
    n = float(np.linalg.norm(v))
    if n == 0 and allow_zero:
        return v
    if n == 0:
        raise r.fail(f"{p}.{k}", "expected a non-zero vector")
    return v / n if unit else v


def _limit(name: str) -> dict:
    """``maximum`` and ``limit`` for the reader: the constant ``name`` of
    :mod:`orient.constants`."""
    return {"maximum": getattr(K, name), "limit": f"orient.constants.{name}"}


def _cut(r: TableReader, d: dict, radius_mm: float) -> CutSpec:
    p = "orient.cut"
    r.keys(d, p, ("depth_mm", "pick_mm"), ("machined_side",))
    side = (_vector(r, d, "machined_side", p, unit=True, allow_zero=True)
            if "machined_side" in d else np.zeros(3))
    # a finishing cut of a ball end mill: shallower than its radius, passes closer than
    # its diameter (the engagement's model of the cut assumes both)
    return CutSpec(r.number(d, "depth_mm", p, sign=">0", maximum=radius_mm,
                            limit="the tool's radius"),
                   r.number(d, "pick_mm", p, sign=">0", maximum=2 * radius_mm,
                            limit="the tool's diameter"), side)


def _spindle(r: TableReader, d: dict) -> SpindleChoice:
    p = "orient.spindle"
    r.keys(d, p, ("range_rpm",), ("steps",))
    lo, hi = r.numbers(d, "range_rpm", p, length=2, sign=">0")
    if not lo < hi <= K.MAX_SPINDLE_RPM:
        raise r.fail(f"{p}.range_rpm", f"expected [low, high] with low < high <= "
                                       f"{K.MAX_SPINDLE_RPM:g} (orient.constants."
                                       f"MAX_SPINDLE_RPM), got [{lo:g}, {hi:g}]")
    return SpindleChoice((lo, hi), r.integer(d, "steps", p, default=K.SPINDLE_STEPS, minimum=2,
                                             **_limit("MAX_SPINDLE_STEPS")))


def _options(r: TableReader, d: dict, radius_mm: float) -> OrientOptions:
    p = "orient"
    r.keys(d, p, (), ("lead_deg", "tilt_deg", "grid", "min_inclination_deg",
                      "max_inclination_deg", "max_rate_deg_per_mm", "pole_floor_deg",
                      "margin_target", "verify_sdm", "allow_fallback", "clearance_mm",
                      "gouge_tol_mm",
                      "safety_factor", "dialect", "cut", "spindle"))
    grid = (K.GRID_STEPS, K.GRID_STEPS)
    if "grid" in d:
        g = d["grid"]
        if not (isinstance(g, list) and len(g) == 2 and all(
                isinstance(x, int) and not isinstance(x, bool) and 1 <= x <= 101 for x in g)):
            raise r.fail("orient.grid", f"expected [lead steps, tilt steps], whole numbers "
                                        f"1..101, got {g!r}")
        grid = (g[0], g[1])
    lo_i = r.number(d, "min_inclination_deg", p, default=K.MIN_INCLINATION_DEG, sign=">=0")
    hi_i = r.number(d, "max_inclination_deg", p, default=K.MAX_INCLINATION_DEG, sign=">0")
    if not lo_i < hi_i <= 90:
        raise r.fail("orient.max_inclination_deg", f"expected min_inclination_deg < "
                                                   f"max_inclination_deg <= 90, got "
                                                   f"{lo_i:g} and {hi_i:g}")
    pole = r.number(d, "pole_floor_deg", p, default=K.POLE_FLOOR_DEG, sign=">=0")
    if not pole < 90:
        raise r.fail("orient.pole_floor_deg", f"expected an angle from 0 to below 90 [deg], "
                                              f"got {pole:g}")
    verify = d.get("verify_sdm", True)
    if not isinstance(verify, bool):
        raise r.fail("orient.verify_sdm", f"expected true or false, got {verify!r}")
    fallback = d.get("allow_fallback", False)
    if not isinstance(fallback, bool):
        raise r.fail("orient.allow_fallback", f"expected true or false, got {fallback!r}")
    from nc.writer import DIALECTS

    safety = r.number(d, "safety_factor", p, default=1.0, sign=">0")
    # a posture stable for the heavier cut keeps a margin against uneven allowance
    if safety < 1:
        raise r.fail("orient.safety_factor", f"expected a factor >= 1 (the planner plans for "
                                             f"depth and pick feed times it), got {safety:g}")
    return OrientOptions(
        lead_range_rad=_range(r, d, "lead_deg", p, K.LEAD_TILT_RANGE_DEG),
        tilt_range_rad=_range(r, d, "tilt_deg", p, K.LEAD_TILT_RANGE_DEG),
        grid=grid,
        min_inclination_rad=math.radians(lo_i), max_inclination_rad=math.radians(hi_i),
        max_rate_rad_per_mm=math.radians(r.number(d, "max_rate_deg_per_mm", p,
                                                  default=K.MAX_RATE_DEG_PER_MM, sign=">0",
                                                  **_limit("MAX_RATE_LIMIT_DEG_PER_MM"))),
        pole_floor_rad=math.radians(pole),
        margin_target=r.number(d, "margin_target", p, default=K.MARGIN_TARGET, sign=">0",
                               **_limit("MAX_MARGIN_TARGET")),
        verify_sdm=verify, allow_fallback=fallback,
        clearance_mm=r.number(d, "clearance_mm", p, default=K.CLEARANCE_MM, sign=">=0",
                              **_limit("MAX_CLEARANCE_MM")),
        gouge_tol_mm=r.number(d, "gouge_tol_mm", p, default=K.GOUGE_TOL_MM, sign=">=0",
                              **_limit("MAX_GOUGE_TOL_MM")),
        safety_factor=safety,
        dialect=r.string(d, "dialect", p, default="linuxcnc", choices=DIALECTS),
        cut=_cut(r, r.table(d["cut"], "orient.cut"), radius_mm) if "cut" in d else None,
        spindle=_spindle(r, r.table(d["spindle"], "orient.spindle")) if "spindle" in d
        else None)


_WALL_KEYS = ("origin_mm", "along", "normal", "length_mm", "height_mm", "thickness_mm",
              "stock_thickness_mm", "young_GPa", "poisson", "density_kg_m3", "damping_ratio",
              "modes", "element_mm")


def _workpiece(r: TableReader, d: dict) -> WorkpieceSpec:
    from errpred.dynamics import Mode

    p = "workpiece"
    r.keys(d, p, (), ("modes", "thin_wall", "source"))
    src = r.string(d, "source", p, default="")
    if ("modes" in d) == ("thin_wall" in d):
        raise r.fail("workpiece.modes", "give [[workpiece.modes]] or [workpiece.thin_wall] "
                                        "(one of them), or leave [workpiece] out for a rigid "
                                        "workpiece")
    if "modes" in d:
        v = d["modes"]
        if not isinstance(v, list) or not v or len(v) > K.MAX_WORKPIECE_MODES:
            raise r.fail("workpiece.modes", f"expected 1 to {K.MAX_WORKPIECE_MODES} "
                                            f"[[workpiece.modes]] tables (orient.constants."
                                            f"MAX_WORKPIECE_MODES), got {_count(v)}")
        modes = []
        for i, m in enumerate(v):
            q = f"workpiece.modes[{i}]"
            m = r.table(m, q)
            r.keys(m, q, ("direction", "frequency_hz", "damping_ratio", "stiffness_N_m"))
            mode = Mode.from_frequency(*(r.number(m, k, q, sign=s, maximum=getattr(EK, lim),
                                                  limit=f"errpred.constants.{lim}")
                                         for k, s, lim in (
                                             ("frequency_hz", ">0", "MAX_MODE_FREQUENCY_HZ"),
                                             ("damping_ratio", ">=0", "MAX_DAMPING_RATIO"),
                                             ("stiffness_N_m", ">0", "MAX_STIFFNESS_N_M"))))
            modes.append((mode, _vector(r, m, "direction", q, unit=True)))
        return WorkpieceSpec("modes", tuple(modes), source=src)
    q = "workpiece.thin_wall"
    t = r.table(d["thin_wall"], q)
    r.keys(t, q, ("origin_mm", "along", "normal", "length_mm", "height_mm", "thickness_mm",
                  "young_GPa", "density_kg_m3"), tuple(k for k in _WALL_KEYS if k not in (
                      "origin_mm", "along", "normal", "length_mm", "height_mm",
                      "thickness_mm", "young_GPa", "density_kg_m3")))
    wall: dict[str, Any] = {
        "origin_mm": _vector(r, t, "origin_mm", q, unit=False, allow_zero=True),
        "along": _vector(r, t, "along", q, unit=True),
        "normal": _vector(r, t, "normal", q, unit=True),
    }
    if abs(float(wall["along"] @ wall["normal"])) > 1e-6:
        raise r.fail(f"{q}.normal", "expected a direction perpendicular to 'along'")
    for k, lim in (("length_mm", "MAX_WALL_MM"), ("height_mm", "MAX_WALL_MM"),
                   ("thickness_mm", "MAX_WALL_MM"), ("young_GPa", "MAX_YOUNG_GPA"),
                   ("density_kg_m3", "MAX_DENSITY_KG_M3")):
        wall[k] = r.number(t, k, q, sign=">0", **_limit(lim))
    wall["stock_thickness_mm"] = r.number(t, "stock_thickness_mm", q,
                                          default=wall["thickness_mm"], sign=">0",
                                          **_limit("MAX_WALL_MM"))
    if wall["stock_thickness_mm"] < wall["thickness_mm"]:
        raise r.fail(f"{q}.stock_thickness_mm", f"expected >= thickness_mm "
                                                f"({wall['thickness_mm']:g} mm), got "
                                                f"{wall['stock_thickness_mm']:g}")
    wall["poisson"] = r.number(t, "poisson", q, default=0.3, sign=">=0")
    if not wall["poisson"] < 0.5:
        raise r.fail(f"{q}.poisson", f"expected 0 <= poisson < 0.5, got {wall['poisson']:g}")
    wall["damping_ratio"] = r.number(t, "damping_ratio", q, default=K.WALL_DAMPING_RATIO,
                                     sign=">=0", maximum=EK.MAX_DAMPING_RATIO,
                                     limit="errpred.constants.MAX_DAMPING_RATIO")
    wall["modes"] = r.integer(t, "modes", q, default=K.WALL_MODES, minimum=1,
                              **_limit("MAX_WALL_MODES"))
    wall["element_mm"] = r.number(t, "element_mm", q, default=0.0, sign=">=0") or None
    _wall_dofs_within_limit(r, wall)
    return WorkpieceSpec("thin_wall", thin_wall=wall, source=src)


def _count(v: Any) -> str:
    return f"{len(v)}" if isinstance(v, list) else type(v).__name__


def _wall_dofs_within_limit(r: TableReader, wall: dict) -> None:
    """Refuse a thin wall whose finite-element model would exceed
    :data:`orient.workpiece_fem.MAX_DOFS` (estimated as :func:`orient.fem.wall.wall_mesh`
    counts its elements: 27-node hexahedra, 3 DOFs a node), before it is built."""
    from .fem.wall import DEFAULT_ELEMENTS_SHORT_SIDE, DEFAULT_MAX_ELEMENTS_PER_DIRECTION
    from .workpiece_fem import MAX_DOFS

    L, H, T = wall["length_mm"], wall["height_mm"], wall["stock_thickness_mm"]
    size = wall["element_mm"]
    if size is None:
        size = min(L, H) / DEFAULT_ELEMENTS_SHORT_SIDE
        nx = min(L / size, DEFAULT_MAX_ELEMENTS_PER_DIRECTION)
        nz = min(H / size, DEFAULT_MAX_ELEMENTS_PER_DIRECTION)
    else:
        nx, nz = max(1.0, L / size), max(1.0, H / size)
    ny = max(1.0, T / size)
    dofs = 3.0 * (2 * nx + 1) * (2 * ny + 1) * (2 * nz + 1)
    if dofs > MAX_DOFS:
        key = "element_mm" if wall["element_mm"] is not None else "thickness_mm"
        raise r.fail(f"workpiece.thin_wall.{key}", f"the wall's finite-element model would "
                                                   f"have about {dofs:.3g} degrees of freedom, "
                                                   f"more than {MAX_DOFS} (orient."
                                                   f"workpiece_fem.MAX_DOFS); expected a "
                                                   f"coarser element_mm or a smaller wall")


def load_plan_scenario(path: str | os.PathLike) -> PlanScenario:
    """Read and check a planning scenario (errpred's sections, then ``[orient]``, ``[workpiece]``).

    Raises
    ------
    ScenarioError
        The first problem, naming the file and the dotted key.
    """
    base = load_scenario(path, extra_sections=("orient", "workpiece"))
    r = TableReader(base.path)
    if base.tool.kind != "ball":
        raise r.fail("tool.type", f"orient plans ball end mills; got {base.tool.kind!r}")
    options = _options(r, r.table(base.extra.get("orient", {}), "orient"), base.tool.radius_mm)
    if base.stock.design_path is None:
        raise r.fail("stock.design_stl", "missing; the planner needs the design surface (its "
                                         "normals at the contact points, the interference "
                                         "check)")
    wp = (_workpiece(r, r.table(base.extra["workpiece"], "workpiece")) if "workpiece" in base.extra
          else WorkpieceSpec())
    return PlanScenario(base, options, wp)

