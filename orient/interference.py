"""Shank, holder and flank interference of a tilted end mill with a workpiece mesh.

The tool assembly is a stack of coaxial cylinders along the tool axis ``u``
(unit, from the tip toward the spindle), each given by its radius and its
axial range ``[z0, z1]`` measured from the tip (``docs/method.md`` §1, §2):

* ``'flank'``: the fluted part above the cutting zone, radius ``R`` from the
  top of the corner arc (``z = r``: the ball centre for a ball end mill) to
  the flute length. The cutting zone below it (the ball, or the corner arc
  and bottom face) is **excluded**: it touches the surface at the contact by
  design, and whether it cuts too deep is the cutter-location's business,
  not an interference question.
* ``'shank'``: radius ``shank_diameter / 2`` from the flute length to the
  overhang (gauge length).
* ``'holder'``: radius ``holder.diameter / 2`` from the overhang to
  ``overhang + holder.length`` (only when the tool has a holder).

Parts of zero length are left out. Cylinders, not capsules: the ends of the
shank and holder are flat faces, so a vertical tool above a floor is
``gap + flute_length`` away with its shank, not less.

Two kinds of test, with different meanings:

* **Collision** (shank, holder): the part enlarged by the clearance ``c``
  (radius ``r + c`` over ``[z0 - c, z1 + c]``, the usual CAM holder
  clearance with square corners, never reaching below the cutting zone)
  intersects the mesh. A part closer than ``c`` always collides; at the rims
  a part up to ``c sqrt(2)`` away can collide (the conservative side).
* **Gouge** (flank): the flank penetrates the surface by more than
  ``gouge_tol_mm`` (the flank shrunk radially by the tolerance, and lifted
  by it at its lower end, intersects the mesh). The flank may *touch*: on a
  steep wall the ball cuts near its equator and the flank above it is
  tangent to the wall, which is legitimate; demanding a positive gap would
  reject exactly the postures used on steep walls. The tolerance also
  absorbs the faceting of the mesh (facets of a concave region lie up to the
  chord tolerance outside the true surface): keep it above that.

The mesh is a *surface* (FCL BVH of its triangles). A part wholly inside the
material without crossing the surface is not seen by FCL itself; it cannot
occur while the ball centre is outside the material (any valid cutter
location), because the axis would then cross the surface inside the flank,
shank or holder, which then intersects the mesh.

Speed: FCL's collision test of a cylinder against a 20k-triangle BVH costs
~10-40 us, but its *distance* query 0.1-10 ms (it has to visit every
triangle nearly tied for the minimum, and python-fcl exposes no error
tolerance), so decisions use collision tests and exact distances are
opt-in (``check(..., distances=True)``) and computed only for parts near
the surface. A conservative pre-filter (a lower bound of the distance to
the mesh on a grid, from a distance transform of surface samples, built
once) skips the FCL calls for parts that are surely clear and bounds the
distance of the others. ``benchmarks/bench_interference.py``: on a
20k-triangle mold, ~17,000 postures/s for decisions, ~600/s with distances.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import fcl
import numpy as np
import trimesh
from scipy.ndimage import distance_transform_edt

from errpred.tool import Tool

from . import constants as K

__all__ = [
    "DEFAULT_CLEARANCE_MM",
    "DISTANCE_ACCURACY_MM",
    "DISTANCE_HORIZON_MM",
    "GOUGE_TOL_MM",
    "PART_NAMES",
    "PREFILTER_CELL_MM",
    "InterferenceChecker",
    "InterferenceResult",
    "Part",
    "ToolAssembly",
]

# --- defaults and tolerances ---------------------------------------------------
#: Clearance kept between shank/holder and the workpiece [mm]
#: (:data:`orient.constants.CLEARANCE_MM`, the one source of the value).
DEFAULT_CLEARANCE_MM = K.CLEARANCE_MM
#: Penetration of the flank into the design surface tolerated as a touch [mm]
#: (:data:`orient.constants.GOUGE_TOL_MM`: above the design mesh's deviation).
GOUGE_TOL_MM = K.GOUGE_TOL_MM
#: Exact (FCL) distances are computed for parts whose distance lower bound is
#: at most this; farther parts report the lower bound [mm].
DISTANCE_HORIZON_MM = 2.0
#: Cell of the pre-filter's distance grid and the sampling step along parts
#: [mm]; the bound is loose by about three times this.
PREFILTER_CELL_MM = 1.0
#: Most grid nodes / surface samples of the pre-filter (the cell grows to fit).
PREFILTER_MAX_NODES = 2_000_000
PREFILTER_MAX_SAMPLES = 2_000_000
#: Accuracy of the exact distances [mm]: FCL's GJK (independent solver) was
#: off by at most 1.5e-4 mm over 2,000 random rim-on-plane contacts.
DISTANCE_ACCURACY_MM = 1e-3
#: Axes shorter than this are refused (they are normalized otherwise) [-].
AXIS_MIN_NORM = 1e-9
#: Postures handled per vectorized pre-filter chunk (bounds memory).
CHUNK = 8192
#: Part names, in order from the tip.
PART_NAMES = ("flank", "shank", "holder")
_SOLVER = fcl.GJKSolverType.GST_INDEP
#: Margin for the float32 storage of the pre-filter grid [mm].
_ROUND_MM = 1e-4


@dataclass(frozen=True)
class Part:
    """One cylinder of the tool assembly.

    Attributes
    ----------
    name : str
        ``'flank'``, ``'shank'`` or ``'holder'``.
    radius_mm : float [mm]
    z0_mm, z1_mm : float [mm]
        Axial range from the tip, ``z0 < z1``.
    """

    name: str
    radius_mm: float
    z0_mm: float
    z1_mm: float

    @property
    def length_mm(self) -> float:
        return self.z1_mm - self.z0_mm

    @property
    def gouge(self) -> bool:
        """True for the flank (gouge test), False for shank/holder (collision)."""
        return self.name == "flank"


@dataclass(frozen=True)
class ToolAssembly:
    """The non-cutting parts of a tool, as coaxial cylinders from the tip.

    Attributes
    ----------
    parts : tuple of Part
        In order from the tip (flank, shank, holder; absent ones left out).
    cutting_top_mm : float [mm]
        Top of the excluded cutting zone (the corner radius ``r``; the ball
        centre height ``R`` for a ball end mill).
    clearance_mm : float [mm]
        Clearance of shank and holder (default of :class:`InterferenceChecker`).
    """

    parts: tuple[Part, ...]
    cutting_top_mm: float
    clearance_mm: float = DEFAULT_CLEARANCE_MM

    def __post_init__(self) -> None:
        _check_nonneg("clearance_mm", self.clearance_mm)
        _check_nonneg("cutting_top_mm", self.cutting_top_mm)
        if not self.parts:
            raise ValueError("parts: the assembly needs at least one part")
        for p in self.parts:
            if p.name not in PART_NAMES:
                raise ValueError(f"parts: unknown part name {p.name!r}; expected {PART_NAMES}")
            if not (math.isfinite(p.radius_mm) and p.radius_mm > 0):
                raise ValueError(f"parts[{p.name}].radius_mm: expected a finite value > 0, "
                                 f"got {p.radius_mm!r}")
            if not (math.isfinite(p.z0_mm) and math.isfinite(p.z1_mm) and p.z1_mm > p.z0_mm):
                raise ValueError(f"parts[{p.name}]: expected finite z0_mm < z1_mm, got "
                                 f"{p.z0_mm!r}, {p.z1_mm!r}")

    @classmethod
    def from_tool(cls, tool: Tool, clearance_mm: float = DEFAULT_CLEARANCE_MM,
                  min_length_mm: float = 1e-6) -> ToolAssembly:
        """Flank, shank and holder of ``tool`` (see the module docstring).

        Parameters
        ----------
        tool : errpred.tool.Tool
        clearance_mm : float [mm]
            Clearance of shank and holder.
        min_length_mm : float [mm]
            Parts shorter than this are left out (e.g. no flank when the
            flute length equals the corner radius).
        """
        if not isinstance(tool, Tool):
            raise TypeError(f"tool: expected errpred.tool.Tool, got {type(tool).__name__}")
        R, r = tool.radius_mm, tool.corner_radius_mm
        fl, oh = float(tool.flute_length_mm), float(tool.overhang_mm)
        parts = []
        if fl - r > min_length_mm:
            parts.append(Part("flank", R, r, fl))
        if oh - fl > min_length_mm:
            parts.append(Part("shank", float(tool.shank_diameter_mm) / 2.0, fl, oh))
        if tool.holder is not None:
            h = tool.holder
            parts.append(Part("holder", h.diameter_mm / 2.0, oh, oh + h.length_mm))
        return cls(tuple(parts), float(r), float(clearance_mm))

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parts)


@dataclass(frozen=True, eq=False)
class InterferenceResult:
    """Interference of a batch of postures.

    Attributes
    ----------
    part_names : tuple of str
        Column names of the per-part arrays (order from the tip).
    min_distance_mm : ndarray, shape (n, p) [mm]
        Distance of each nominal part to the mesh (the flank's to the design
        mesh when one is given): exact where ``exact``, otherwise a
        guaranteed lower bound. 0 = touching or intersecting (FCL gives no
        penetration depth).
    exact : ndarray, shape (n, p), bool
    part_violates : ndarray, shape (n, p), bool
        Shank/holder within the clearance, or flank gouging.
    collides : ndarray, shape (n,), bool
        Shank or holder within the clearance of the mesh.
    gouges : ndarray, shape (n,), bool
        The flank penetrates the surface by more than the gouge tolerance.
    part : ndarray, shape (n,), int
        Index into ``part_names`` of the offending part nearest the tip
        (the first one met going up the tool), -1 if none.
    """

    part_names: tuple[str, ...]
    min_distance_mm: np.ndarray
    exact: np.ndarray
    part_violates: np.ndarray
    collides: np.ndarray
    gouges: np.ndarray
    part: np.ndarray

    @property
    def feasible(self) -> np.ndarray:
        """No collision and no gouge, shape (n,)."""
        return ~(self.collides | self.gouges)

    @property
    def part_label(self) -> np.ndarray:
        """Name of the offending part per posture ('' if none), shape (n,)."""
        names = np.array(self.part_names + ("",), dtype=object)
        return names[self.part]

    def distance(self, name: str) -> np.ndarray:
        """``min_distance_mm`` of part ``name``, shape (n,) [mm]."""
        if name not in self.part_names:
            raise KeyError(f"name: no part {name!r} in this assembly {self.part_names}")
        return self.min_distance_mm[:, self.part_names.index(name)]


# --- the checker ----------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class _Prefilter:
    """Lower bound of the distance to the mesh on a grid (1-Lipschitz)."""

    origin: np.ndarray   # (3,) first node
    cell: float
    values: np.ndarray   # (nx, ny, nz) lower bounds at the nodes [mm]
    lo: np.ndarray       # mesh bounds
    hi: np.ndarray

    def lower_bound(self, p: np.ndarray) -> np.ndarray:
        """Lower bound of the distance from points ``p`` (..., 3) to the mesh [mm]."""
        aabb = np.linalg.norm(np.maximum(0.0, np.maximum(self.lo - p, p - self.hi)), axis=-1)
        idx = np.rint((p - self.origin) / self.cell).astype(np.int64)
        shape = np.array(self.values.shape)
        inside = np.all((idx >= 0) & (idx < shape), axis=-1)
        idx = np.where(inside[..., None], idx, 0)
        grid = self.values[idx[..., 0], idx[..., 1], idx[..., 2]] - self.cell * math.sqrt(3) / 2
        return np.where(inside, np.maximum(grid, aabb), aabb)


def _surface_samples(V: np.ndarray, F: np.ndarray, cell: float):
    """Centroids of a barycentric subdivision of each triangle into k^2 pieces
    (k = ceil(longest edge / cell)) and the largest centroid-to-vertex distance
    of any piece: every surface point lies within that radius of a sample."""
    A, B, C = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    edge = np.max(np.stack([np.linalg.norm(B - A, axis=1), np.linalg.norm(C - B, axis=1),
                            np.linalg.norm(A - C, axis=1)]), axis=0)
    cen = (A + B + C) / 3.0
    rad = np.max(np.stack([np.linalg.norm(X - cen, axis=1) for X in (A, B, C)]), axis=0)
    k = np.maximum(1, np.ceil(edge / cell)).astype(np.int64)
    pts, rho = [], 0.0
    for kk in np.unique(k):
        sel = k == kk
        i, j = np.meshgrid(np.arange(kk), np.arange(kk), indexing="ij")
        up = (i + j) <= kk - 1
        dn = (i + j) <= kk - 2
        bu = np.concatenate([(i[up] + 1 / 3) / kk, (i[dn] + 2 / 3) / kk])
        bv = np.concatenate([(j[up] + 1 / 3) / kk, (j[dn] + 2 / 3) / kk])
        a, e1, e2 = A[sel], B[sel] - A[sel], C[sel] - A[sel]
        pts.append((a[:, None, :] + bu[None, :, None] * e1[:, None, :]
                    + bv[None, :, None] * e2[:, None, :]).reshape(-1, 3))
        rho = max(rho, float(rad[sel].max()) / kk)
    return np.concatenate(pts), rho


def _build_prefilter(V: np.ndarray, F: np.ndarray, cell: float, reach: float) -> _Prefilter:
    """The grid of lower bounds of the distance to the mesh.

    The grid covers the mesh's bounding box, and above it (+Z, where tools
    come from) as far as the tool reaches: above the mesh's footprint the
    bounding-box bound would be poor. Elsewhere the box bound is used.

    Surface samples (every surface point within ``rho`` of one) mark their
    nearest grid node; the Euclidean distance transform gives each node its
    distance to the nearest marked node, and a sample is within
    ``cell sqrt(3) / 2`` of its node, so ``edt - cell sqrt(3)/2 - rho`` is a
    lower bound of the node's distance to the surface.
    """
    lo, hi = V.min(axis=0), V.max(axis=0)
    top = hi + np.array([0.0, 0.0, reach])
    A, B, C = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    edge = np.max(np.stack([np.linalg.norm(B - A, axis=1), np.linalg.norm(C - B, axis=1),
                            np.linalg.norm(A - C, axis=1)]), axis=0)
    while True:   # grow the cell until the grid and the samples fit their budgets
        dims = np.ceil((top - lo) / cell).astype(np.int64) + 3
        n_samples = int(np.sum(np.maximum(1, np.ceil(edge / cell)) ** 2))
        if np.prod(dims) <= PREFILTER_MAX_NODES and n_samples <= PREFILTER_MAX_SAMPLES:
            break
        cell *= 1.25
    origin = lo - cell
    samples, rho = _surface_samples(V, F, cell)
    occupied = np.zeros(tuple(dims), dtype=bool)
    idx = np.rint((samples - origin) / cell).astype(np.int64)
    occupied[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    edt = distance_transform_edt(~occupied) * cell
    values = (edt - cell * math.sqrt(3) / 2 - rho - _ROUND_MM).astype(np.float32)
    return _Prefilter(origin, cell, values, lo, hi)


def _frames(axes: np.ndarray) -> np.ndarray:
    """Rotations (n, 3, 3) whose third column is the axis (unit)."""
    helper = np.where(np.abs(axes[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    x = helper - np.sum(helper * axes, axis=1, keepdims=True) * axes
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(axes, x)
    return np.ascontiguousarray(np.stack([x, y, axes], axis=2))


@dataclass(eq=False)
class InterferenceChecker:
    """FCL interference checks of one tool assembly against one workpiece mesh.

    The mesh's BVH, the FCL objects of the parts and the pre-filter grid are
    built once; queries only move the parts (``setRotation``/``setTranslation``).

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Workpiece (in-process or design), workpiece frame [mm], for the shank
        and holder. Treated as a surface (see the module docstring).
    assembly : ToolAssembly
    clearance_mm : float, optional [mm]
        Clearance of shank and holder; default ``assembly.clearance_mm``.
    design_mesh : trimesh.Trimesh, optional
        Design surface for the flank's gouge test (default: ``mesh``). Give
        it when ``mesh`` is the in-process stock: the flank entering uncut
        stock is cutting, not gouging.
    gouge_tol_mm : float [mm]
        Flank penetration tolerated (must be below the flank radius).
    prefilter : bool
        Use the distance-bound pre-filter (results are the same either way,
        except that distances beyond the horizon become lower bounds).
    prefilter_cell_mm : float [mm]
    distance_horizon_mm : float [mm]
        With the pre-filter, exact distances only for parts whose lower bound
        is at most this.
    """

    mesh: trimesh.Trimesh
    assembly: ToolAssembly
    clearance_mm: float | None = None
    design_mesh: trimesh.Trimesh | None = None
    gouge_tol_mm: float = GOUGE_TOL_MM
    prefilter: bool = True
    prefilter_cell_mm: float = PREFILTER_CELL_MM
    distance_horizon_mm: float = DISTANCE_HORIZON_MM
    _pf: _Prefilter | None = field(init=False, repr=False, default=None)

    def __post_init__(self) -> None:
        if not isinstance(self.assembly, ToolAssembly):
            raise TypeError(f"assembly: expected ToolAssembly, got "
                            f"{type(self.assembly).__name__}")
        V, F = _mesh_arrays("mesh", self.mesh)
        if self.clearance_mm is None:
            self.clearance_mm = self.assembly.clearance_mm
        _check_nonneg("clearance_mm", self.clearance_mm)
        _check_nonneg("gouge_tol_mm", self.gouge_tol_mm)
        _check_nonneg("distance_horizon_mm", self.distance_horizon_mm)
        if not (math.isfinite(self.prefilter_cell_mm) and self.prefilter_cell_mm > 0):
            raise ValueError(f"prefilter_cell_mm: expected a finite value > 0, got "
                             f"{self.prefilter_cell_mm!r}")
        for p in self.assembly.parts:
            if p.gouge and self.gouge_tol_mm >= min(p.radius_mm, p.length_mm):
                raise ValueError(f"gouge_tol_mm: {self.gouge_tol_mm:g} mm is not below the "
                                 f"flank's radius and length")
        self._mesh_obj = _bvh_object(V, F)
        self._creq = fcl.CollisionRequest(gjk_solver_type=_SOLVER)
        self._dreq = fcl.DistanceRequest(gjk_solver_type=_SOLVER)
        self._dres = fcl.DistanceResult()
        self._dres.min_distance = -np.inf   # never updated: no conversion of nearest points
        # per part: nominal geometry (distance) and test geometry (collide)
        c, tol, bottom = float(self.clearance_mm), float(self.gouge_tol_mm), \
            self.assembly.cutting_top_mm
        self._nom, self._test = [], []
        for p in self.assembly.parts:
            if p.gouge:
                t = (p.radius_mm - tol, p.z0_mm + tol, p.z1_mm)
            else:
                t = (p.radius_mm + c, max(p.z0_mm - c, bottom), p.z1_mm + c)
            self._nom.append((p.radius_mm, p.z0_mm, p.z1_mm))
            self._test.append(t)
        self._nom_obj = [fcl.CollisionObject(fcl.Cylinder(r, z1 - z0), fcl.Transform())
                         for r, z0, z1 in self._nom]
        self._test_obj = [fcl.CollisionObject(fcl.Cylinder(r, z1 - z0), fcl.Transform())
                          for r, z0, z1 in self._test]
        reach = max(t[2] for t in self._test)
        if self.prefilter:
            self._pf = _build_prefilter(V, F, float(self.prefilter_cell_mm), reach)
        # the target of each part: (FCL object, pre-filter)
        targets = {False: (self._mesh_obj, self._pf)}
        targets[True] = targets[False]
        if self.design_mesh is not None:
            Vd, Fd = _mesh_arrays("design_mesh", self.design_mesh)
            pf = (_build_prefilter(Vd, Fd, float(self.prefilter_cell_mm), reach)
                  if self.prefilter else None)
            targets[True] = (_bvh_object(Vd, Fd), pf)
        self._target = [targets[p.gouge] for p in self.assembly.parts]

    @property
    def part_names(self) -> tuple[str, ...]:
        return self.assembly.names

    # --- public queries ---------------------------------------------------------
    def check(self, tips: np.ndarray, axes: np.ndarray, *,
              distances: bool = False) -> InterferenceResult:
        """Interference of the postures ``(tips[i], axes[i])``.

        Parameters
        ----------
        tips : ndarray, shape (n, 3) [mm]
            Tool tips (lowest point on the axis), workpiece frame.
        axes : ndarray, shape (n, 3) [-]
            Tool axes from the tip toward the spindle (normalized here).
        distances : bool
            False (default): decisions only; ``min_distance_mm`` holds lower
            bounds (exact only where a part surely intersects: 0). True: exact
            FCL distances for the parts whose distance lower bound is within
            the horizon (all parts without the pre-filter). FCL's mesh distance
            query costs 0.1-10 ms per part on a 20k-triangle mesh (it must
            visit every triangle nearly tied for the minimum), against
            10-25 us for a collision test: ask for distances only when needed.

        Returns
        -------
        InterferenceResult
        """
        tips, axes = self._validate(tips, axes)
        n, m = tips.shape[0], len(self.assembly.parts)
        Rm = _frames(axes)
        c = float(self.clearance_mm)
        gouge = np.array([p.gouge for p in self.assembly.parts])
        # lower bounds of the test and the nominal geometry (0 without pre-filter)
        lb_test, lb_nom = self._bounds(tips, axes)
        viol = np.zeros((n, m), dtype=bool)
        for i, j in zip(*np.nonzero(lb_test <= 0.0)):
            obj = self._test_obj[j]
            self._place(obj, self._test[j], tips[i], axes[i], Rm[i])
            viol[i, j] = fcl.collide(obj, self._target[j][0], self._creq) > 0
        # nominal distance: lower bound from the test, exact where computed. A
        # part whose enlarged cylinder is clear is farther than its margin
        known = np.array([0.0 if p.gouge else min(c, nom[1] - t[1]) for p, nom, t
                          in zip(self.assembly.parts, self._nom, self._test)])[None, :]
        dist = np.maximum(lb_nom, np.where(viol, 0.0, known))
        exact = np.zeros((n, m), dtype=bool)
        # a gouging flank (or a colliding part with c = 0) intersects: exactly 0
        sure0 = viol & (gouge[None, :] | (c == 0.0))
        dist[sure0], exact[sure0] = 0.0, True
        if distances:
            want = ~sure0 & ((lb_nom <= self.distance_horizon_mm) if self._pf is not None
                             else np.ones((n, m), dtype=bool))
            for i, j in zip(*np.nonzero(want)):
                obj = self._nom_obj[j]
                self._place(obj, self._nom[j], tips[i], axes[i], Rm[i])
                d = fcl.distance(obj, self._target[j][0], self._dreq, self._dres)
                dist[i, j], exact[i, j] = max(d, 0.0), True
        first = np.where(viol.any(axis=1), np.argmax(viol, axis=1), -1)
        return InterferenceResult(self.part_names, dist, exact, viol,
                                  (viol & ~gouge[None, :]).any(axis=1),
                                  (viol & gouge[None, :]).any(axis=1), first)

    def feasible(self, tips: np.ndarray, axes: np.ndarray) -> np.ndarray:
        """True where neither shank/holder collides nor the flank gouges.

        Parameters
        ----------
        tips : ndarray, shape (n, 3) [mm]
        axes : ndarray, shape (n, 3) [-]

        Returns
        -------
        ndarray, shape (n,), bool
        """
        return self.check(tips, axes, distances=False).feasible

    # --- internals --------------------------------------------------------------
    def _validate(self, tips, axes) -> tuple[np.ndarray, np.ndarray]:
        tips = np.asarray(tips, dtype=np.float64)
        axes = np.asarray(axes, dtype=np.float64)
        for name, a in (("tips", tips), ("axes", axes)):
            if a.ndim != 2 or a.shape[1] != 3:
                raise ValueError(f"{name}: expected shape (n, 3), got {a.shape}")
        if tips.shape[0] != axes.shape[0]:
            raise ValueError(f"tips, axes: different numbers of postures "
                             f"({tips.shape[0]} vs {axes.shape[0]})")
        for name, a in (("tips", tips), ("axes", axes)):
            bad = ~np.all(np.isfinite(a), axis=1)
            if bad.any():
                k = int(np.argmax(bad))
                raise ValueError(f"{name}: expected finite values, got {a[k].tolist()} "
                                 f"at row {k}")
        norm = np.linalg.norm(axes, axis=1)
        if np.any(norm < AXIS_MIN_NORM):
            k = int(np.argmax(norm < AXIS_MIN_NORM))
            raise ValueError(f"axes: expected non-zero vectors, got {axes[k].tolist()} at row {k}")
        return np.ascontiguousarray(tips), np.ascontiguousarray(axes / norm[:, None])

    @staticmethod
    def _place(obj, geom, tip, axis, R) -> None:
        _, z0, z1 = geom
        obj.setRotation(R)
        obj.setTranslation(tip + (0.5 * (z0 + z1)) * axis)

    def _bounds(self, tips: np.ndarray, axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lower bounds (n, p) of the distance of the test and nominal parts [mm]."""
        n, m = tips.shape[0], len(self._test)
        if self._pf is None:
            return np.zeros((n, m)), np.zeros((n, m))
        lb_test, lb_nom = np.empty((n, m)), np.empty((n, m))
        for j, ((rt, a, b), (rn, na, nb)) in enumerate(zip(self._test, self._nom)):
            pf = self._target[j][1]
            cell = pf.cell
            # samples along the union of both axial ranges: every axis point of
            # either part is within half a step of one
            lo_z, hi_z = min(a, na), max(b, nb)
            k = max(1, math.ceil((hi_z - lo_z) / cell))
            half = (hi_z - lo_z) / (2 * k)
            zs = lo_z + (np.arange(k) + 0.5) * (2 * half)
            for s in range(0, n, CHUNK):
                sl = slice(s, s + CHUNK)
                pts = tips[sl, None, :] + zs[None, :, None] * axes[sl, None, :]
                d = pf.lower_bound(pts).min(axis=1) - half
                lb_test[sl, j] = d - rt
                lb_nom[sl, j] = d - rn
        return lb_test, np.maximum(lb_nom, 0.0)


def _mesh_arrays(name: str, mesh) -> tuple[np.ndarray, np.ndarray]:
    if not isinstance(mesh, trimesh.Trimesh):
        raise TypeError(f"{name}: expected trimesh.Trimesh, got {type(mesh).__name__}")
    V = np.asarray(mesh.vertices, dtype=np.float64)
    F = np.asarray(mesh.faces, dtype=np.int64)
    if F.ndim != 2 or F.shape[0] == 0:
        raise ValueError(f"{name}: expected at least one triangle")
    if not np.all(np.isfinite(V)):
        raise ValueError(f"{name}: vertices must be finite")
    return V, F


def _bvh_object(V: np.ndarray, F: np.ndarray):
    """FCL collision object of a triangle mesh (OBBRSS BVH, identity pose)."""
    bvh = fcl.BVHModel()
    bvh.beginModel(len(V), len(F))
    bvh.addSubModel(V, F.astype(np.int32))
    bvh.endModel()
    return fcl.CollisionObject(bvh, fcl.Transform())


def _check_nonneg(name: str, v) -> None:
    if not (isinstance(v, (int, float, np.floating, np.integer)) and math.isfinite(v) and v >= 0):
        raise ValueError(f"{name}: expected a finite value >= 0, got {v!r}")
