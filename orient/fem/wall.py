"""Thin-wall workpiece geometry and its hexahedral mesh (used by :mod:`orient.workpiece_fem`).

:class:`ThinWall` is a wall on a clamped base in its in-process shape: a
piecewise-constant thickness over the height (stock where it is still to be
machined, finished where it has been; :meth:`ThinWall.in_process` finishes
top-down). :func:`wall_mesh` cuts it into the boxes of a tensor grid whose
lines include every face position and every thickness step, so steps are
represented exactly.

Wall frame: local coordinates ``(a, n, h)`` [mm] along the wall, along its
normal and up its height; the workpiece point is
``origin_mm + a * along + n * normal + h * up``. The wall occupies
``0 <= a <= length_mm``, ``0 <= h <= height_mm`` and ``n`` between its faces;
``n = 0`` is the mid-plane of the base section (thickness ``thickness_mm``).
Material constants: Young's modulus in GPa, density in kg/m^3.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from nc.checks import real_number as _real
from orient.fem import q2hex
from orient.constants import (
    DEFAULT_DAMPING_RATIO,
    DEFAULT_ELEMENTS_SHORT_SIDE,
    DEFAULT_MAX_ELEMENTS_PER_DIRECTION,
    MERGE_MM,
    ORTHO_TOL,
    ROUND_SLACK,
)

__all__ = [
    "ALUMINIUM",
    "DEFAULT_DAMPING_RATIO",
    "DEFAULT_ELEMENTS_SHORT_SIDE",
    "DEFAULT_MAX_ELEMENTS_PER_DIRECTION",
    "FINISH_SIDES",
    "STEEL",
    "Material",
    "ThinWall",
    "wall_mesh",
]

#: Which faces the finishing removes material from.
FINISH_SIDES = ("both", "front", "back")


def _vec3(name: str, value: Any, unit: bool = False) -> np.ndarray:
    """``value`` as a finite 3-vector (normalized if ``unit``; zero refused)."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"{name}: expected 3 real numbers, got {value!r}") from None
    if v.shape != (3,):
        raise ValueError(f"{name}: expected 3 components, got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{name}: expected finite components, got {value!r}")
    if unit:
        n = float(np.linalg.norm(v))
        if n == 0.0:
            raise ValueError(f"{name}: expected a non-zero direction, got {value!r}")
        v = v / n
    return v


@dataclass(frozen=True)
class Material:
    """Isotropic linear-elastic material.

    Attributes
    ----------
    young_GPa : float [GPa]
        Young's modulus, > 0.
    density_kg_m3 : float [kg/m^3]
        Density, > 0.
    poisson : float [-]
        Poisson's ratio, in (-1, 0.5).
    """

    young_GPa: float
    density_kg_m3: float
    poisson: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "young_GPa", _real("Material.young_GPa", self.young_GPa, ">0"))
        object.__setattr__(self, "density_kg_m3",
                           _real("Material.density_kg_m3", self.density_kg_m3, ">0"))
        nu = _real("Material.poisson", self.poisson)
        if not -1.0 < nu < 0.5:
            raise ValueError(f"Material.poisson: expected a value in (-1, 0.5), got {nu!r}")
        object.__setattr__(self, "poisson", nu)

    def lame_Pa(self) -> tuple[float, float]:
        """Lame parameters ``(lambda, mu)`` [Pa]."""
        e, nu = self.young_GPa * 1e9, self.poisson
        return e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), e / (2.0 * (1.0 + nu))


#: Wrought aluminium alloy (6061 / 7075 class).
ALUMINIUM = Material(young_GPa=70.0, density_kg_m3=2700.0, poisson=0.33)
#: Carbon / low-alloy steel.
STEEL = Material(young_GPa=210.0, density_kg_m3=7850.0, poisson=0.29)


@dataclass(frozen=True)
class ThinWall:
    """A thin wall on a clamped base, in its in-process shape.

    Attributes
    ----------
    length_mm : float [mm]
        Extent along the wall (``along``), > 0.
    height_mm : float [mm]
        Extent from the clamped base up (``up``), > 0.
    thickness_mm : float [mm]
        Thickness of the base section (from ``h = 0`` to the first ``profile``
        level), > 0; its mid-plane is ``n = 0``.
    material : Material
    damping_ratio : float [-]
        Modal damping ratio of every mode, >= 0.
    profile : tuple of (z_mm, thickness_mm) pairs [mm]
        Piecewise-constant thickness: from height ``z_mm`` up to the next level
        the thickness is ``thickness_mm``. Levels strictly increasing in
        ``[0, height_mm)``; empty for a uniform wall.
    finish_side : {'both', 'front', 'back'}
        Where thickness other than ``thickness_mm`` is taken from: 'both' keeps
        the mid-plane (faces at ``+-t/2``), 'front' keeps the back face
        (``n = -thickness_mm/2``) and moves the front (+normal) face, 'back' the
        reverse.
    clamp_ends : bool
        Also clamp the end faces ``a = 0`` and ``a = length_mm``.
    origin_mm : tuple of 3 float [mm]
        Workpiece-frame position of ``a = n = h = 0``.
    along, normal, up : tuple of 3 float [-]
        Workpiece-frame directions of ``a``, ``n`` (the flexible direction of a
        thin wall) and ``h``; normalized on construction, mutually orthogonal.
        ``up`` defaults to ``along x normal``, its sign flipped if its Z
        component is negative (a wall standing on a floor, Z up).
    """

    length_mm: float
    height_mm: float
    thickness_mm: float
    material: Material
    damping_ratio: float = DEFAULT_DAMPING_RATIO
    profile: tuple[tuple[float, float], ...] = ()
    finish_side: str = "both"
    clamp_ends: bool = False
    origin_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    along: tuple[float, float, float] = (1.0, 0.0, 0.0)
    normal: tuple[float, float, float] = (0.0, 1.0, 0.0)
    up: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        for name in ("length_mm", "height_mm", "thickness_mm"):
            put(name, _real(f"ThinWall.{name}", getattr(self, name), ">0"))
        put("damping_ratio", _real("ThinWall.damping_ratio", self.damping_ratio, ">=0"))
        if not isinstance(self.material, Material):
            raise TypeError(f"ThinWall.material: expected a Material, got {self.material!r}")
        if self.finish_side not in FINISH_SIDES:
            raise ValueError(f"ThinWall.finish_side: expected one of {FINISH_SIDES}, "
                             f"got {self.finish_side!r}")
        if not isinstance(self.clamp_ends, (bool, np.bool_)):
            raise TypeError(f"ThinWall.clamp_ends: expected a bool, got {self.clamp_ends!r}")
        put("clamp_ends", bool(self.clamp_ends))
        prof = []
        for i, pair in enumerate(self.profile):
            if len(pair) != 2:
                raise ValueError(f"ThinWall.profile[{i}]: expected (z_mm, thickness_mm), "
                                 f"got {pair!r}")
            z = _real(f"ThinWall.profile[{i}] z_mm", pair[0], ">=0")
            t = _real(f"ThinWall.profile[{i}] thickness_mm", pair[1], ">0")
            if z >= self.height_mm or (prof and z <= prof[-1][0]):
                raise ValueError(f"ThinWall.profile[{i}]: levels must increase strictly "
                                 f"within [0, height_mm={self.height_mm:g}), got z_mm={z:g}")
            prof.append((z, t))
        put("profile", tuple(prof))
        put("origin_mm", tuple(_vec3("ThinWall.origin_mm", self.origin_mm)))
        vecs = {n: _vec3(f"ThinWall.{n}", getattr(self, n), unit=True)
                for n in ("along", "normal")}
        vecs["up"] = None if self.up is None else _vec3("ThinWall.up", self.up, unit=True)
        for a, b in (("along", "normal"), ("along", "up"), ("normal", "up")):
            if vecs[b] is None:  # derived below, orthogonal by construction
                continue
            c = float(vecs[a] @ vecs[b])
            if abs(c) > ORTHO_TOL:
                raise ValueError(f"ThinWall.{a}, ThinWall.{b}: expected orthogonal directions, "
                                 f"cosine {c:.3g}")
        if vecs["up"] is None:
            up = np.cross(vecs["along"], vecs["normal"])
            up = up / np.linalg.norm(up)
            vecs["up"] = -up if up[2] < 0 else up
        for n, v in vecs.items():
            put(n, tuple(float(x) for x in v))

    # ------------------------------------------------------------------ geometry
    @property
    def rotation(self) -> np.ndarray:
        """Columns ``along, normal, up``: workpiece = origin + R @ local; shape (3, 3)."""
        return np.column_stack([self.along, self.normal, self.up])

    def to_workpiece(self, local_mm: Any) -> np.ndarray:
        """Local ``(a, n, h)`` [mm], shape (..., 3) -> workpiece frame [mm], shape (..., 3)."""
        return np.asarray(self.origin_mm) + np.asarray(local_mm, dtype=float) @ self.rotation.T

    def to_local(self, point_mm: Any) -> np.ndarray:
        """Workpiece frame [mm], shape (..., 3) -> local ``(a, n, h)`` [mm], shape (..., 3)."""
        return (np.asarray(point_mm, dtype=float) - np.asarray(self.origin_mm)) @ self.rotation

    def thickness_at(self, z_mm: float) -> float:
        """Wall thickness at height ``z_mm`` [mm] (the level's own value at a step) [mm]."""
        z = _real("z_mm", z_mm)
        t = self.thickness_mm
        for level, tl in self.profile:
            if z >= level:
                t = tl
        return t

    def faces_at(self, z_mm: float) -> tuple[float, float]:
        """``(n_back, n_front)`` [mm]: local normal coordinates of the faces at ``z_mm``."""
        t, t0 = self.thickness_at(z_mm), self.thickness_mm
        if self.finish_side == "front":
            return -0.5 * t0, -0.5 * t0 + t
        if self.finish_side == "back":
            return 0.5 * t0 - t, 0.5 * t0
        return -0.5 * t, 0.5 * t

    def in_process(self, cut_to_z_mm: float, finished_thickness_mm: float) -> ThinWall:
        """The wall after finishing top-down to height ``cut_to_z_mm``.

        Parameters
        ----------
        cut_to_z_mm : float [mm]
            Height down to which the wall is finished: above it the thickness is
            ``finished_thickness_mm``, below it the current (stock) shape stays.
            ``<= 0``: finished everywhere; ``>= height_mm``: nothing removed.
        finished_thickness_mm : float [mm]
            Finished thickness, > 0 and not more than the current thickness
            anywhere above ``cut_to_z_mm`` (finishing removes material).
        """
        z = _real("cut_to_z_mm", cut_to_z_mm)
        tf = _real("finished_thickness_mm", finished_thickness_mm, ">0")
        if z >= self.height_mm:
            return self
        z = max(z, 0.0)
        above = [self.thickness_at(z)] + [t for lv, t in self.profile if lv > z]
        if tf > min(above) + MERGE_MM:
            raise ValueError(f"finished_thickness_mm: {tf:g} mm exceeds the stock thickness "
                             f"{min(above):g} mm above cut_to_z_mm={z:g}")
        kept = tuple((lv, t) for lv, t in self.profile if lv < z)
        return replace(self, profile=kept + ((z, tf),))


# ---------------------------------------------------------------------- meshing
def _merge(values: Sequence[float]) -> np.ndarray:
    v = np.sort(np.asarray(values, dtype=float))
    return v[np.concatenate([[True], np.diff(v) > MERGE_MM])]


def _subdivide(breaks: np.ndarray, counts: Sequence[int]) -> np.ndarray:
    parts = [np.linspace(breaks[i], breaks[i + 1], c + 1)[:-1] for i, c in enumerate(counts)]
    return np.concatenate(parts + [breaks[-1:]])


def _counts(name: str, elements: Any, wall: ThinWall) -> tuple[int, Any, Any]:
    """Along count and per-segment rules for height and thickness layers."""
    if elements is None:
        size = min(wall.length_mm, wall.height_mm) / DEFAULT_ELEMENTS_SHORT_SIDE
        cap = DEFAULT_MAX_ELEMENTS_PER_DIRECTION
        nx = min(math.ceil(wall.length_mm / size - ROUND_SLACK), cap)
        nz = min(math.ceil(wall.height_mm / size - ROUND_SLACK), cap)
        return (nx, lambda seg: max(1, round(nz * seg / wall.height_mm)),
                lambda lay: max(1, math.ceil(lay / size - ROUND_SLACK)))
    if isinstance(elements, numbers.Real) and not isinstance(elements, (bool, np.bool_)):
        size = _real(f"{name} (element size)", elements, ">0")
        return (max(1, math.ceil(wall.length_mm / size - ROUND_SLACK)),
                lambda seg: max(1, math.ceil(seg / size - ROUND_SLACK)),
                lambda lay: max(1, math.ceil(lay / size - ROUND_SLACK)))
    try:
        nx, ny, nz = elements
    except (TypeError, ValueError):
        raise TypeError(f"{name}: expected None, an element size [mm] or (n_along, "
                        f"n_thickness, n_height), got {elements!r}") from None
    for label, v in (("n_along", nx), ("n_thickness", ny), ("n_height", nz)):
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Integral) or v < 1:
            raise ValueError(f"{name}: {label} must be an integer >= 1, got {v!r}")
    return (int(nx), lambda seg: max(1, round(int(nz) * seg / wall.height_mm)),
            lambda lay: int(ny))


def wall_mesh(wall: ThinWall, elements: Any) -> q2hex.Q2Mesh:
    """Q2 mesh of the wall in local coordinates ``(a, n, h)`` [mm].

    The grid lines include every face position and every profile level, so each
    box is wholly inside or outside the material; the boxes inside are kept.

    Parameters
    ----------
    wall : ThinWall
    elements : None, float [mm] or tuple of 3 int
        As in :func:`orient.workpiece_fem.wall_modes`.

    Returns
    -------
    orient.fem.q2hex.Q2Mesh
        Lengths in mm.
    """
    nx, height_rule, layer_rule = _counts("elements", elements, wall)
    hb = _merge([0.0, wall.height_mm] + [lv for lv, _ in wall.profile])
    levels = [0.0] + [lv for lv, _ in wall.profile]
    nb = _merge([f for lv in levels for f in wall.faces_at(lv)])
    lines = (np.linspace(0.0, wall.length_mm, nx + 1),
             _subdivide(nb, [layer_rule(s) for s in np.diff(nb)]),
             _subdivide(hb, [height_rule(s) for s in np.diff(hb)]))
    nc = 0.5 * (lines[1][:-1] + lines[1][1:])
    hc = 0.5 * (lines[2][:-1] + lines[2][1:])
    faces = np.array([wall.faces_at(h) for h in hc])  # (nh, 2)
    inside = (nc[:, None] > faces[None, :, 0]) & (nc[:, None] < faces[None, :, 1])  # (nn, nh)
    active = np.broadcast_to(inside[None], (nx, len(nc), len(hc)))
    return q2hex.build_mesh(lines, active)
