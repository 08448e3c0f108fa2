"""Workpiece flexibility of a thin wall from a finite-element model (``docs/method.md`` §7).

A thin wall standing on a rigid base vibrates along its own normal and can be
the cause of chatter. :class:`ThinWall` describes the wall in its in-process
shape (stock thickness where it is still to be machined, finished thickness
where it has been; machining goes top-down, :meth:`ThinWall.in_process`).
:func:`wall_modes` meshes it with triquadratic hexahedra (:mod:`orient.fem.q2hex`),
solves for its lowest modes, and :class:`WallModes` gives, at a cutting point,
the equivalent single-DOF modes (:class:`errpred.dynamics.Mode` plus a unit
direction, as orient's stability contract adds them to the tool's modes), the
point FRF and the flexible direction.

Physical assumptions (the limits of the model):

* small displacements, linear isotropic homogeneous elasticity, no prestress
  (residual stresses, clamping preload) and no temperature effects;
* the base (bottom face, ``h = 0``) is clamped (rigid floor and fixture: no
  fixture or floor compliance), optionally the two ends too; every other face
  is free;
* the wall has its in-process shape only: material of the stock still standing
  is included, the rest of the part is rigid; the tool's contact adds no mass
  or stiffness;
* one viscous modal damping ratio for every mode (measure it: 0.2 - 2 % is
  typical of thin aluminium walls);
* the FRF is a sum over the computed modes only (``n_modes``): it lacks the
  residual flexibility of the higher ones (a few % of the static compliance at
  the top of a cantilever wall with 6 modes; see the tests).

In-process behaviour: finishing from the top first *raises* the first
frequency (the top loses mass faster than the wall loses root stiffness) and
lowers it only once enough has been removed, while the static compliance at
the top grows all along (the tests check both against a stepped beam).

Units: geometry in mm in the workpiece frame at the interface; the solver works
in SI (m, Pa, kg): Young's modulus in GPa (``young_GPa``), density in kg/m^3;
frequencies in Hz, angular frequencies in rad/s; mass-normalized shapes in
m/sqrt(kg) (``phi^T M phi = 1`` with M in kg); stiffness N/m, mass kg, damping
N s/m, FRF m/N.

Wall frame: local coordinates ``(a, n, h)`` [mm] along the wall, along its
normal and up its height; the workpiece point is
``origin_mm + a * along + n * normal + h * up``. The wall occupies
``0 <= a <= length_mm``, ``0 <= h <= height_mm`` and ``n`` between its faces;
``n = 0`` is the mid-plane of the base section (thickness ``thickness_mm``).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from errpred.dynamics import Mode
from orient.fem import q2hex
from orient.fem.wall import (
    ALUMINIUM,
    DEFAULT_DAMPING_RATIO,
    DEFAULT_ELEMENTS_SHORT_SIDE,
    DEFAULT_MAX_ELEMENTS_PER_DIRECTION,
    FINISH_SIDES,
    STEEL,
    Material,
    ThinWall,
    _real,
    _vec3,
    wall_mesh,
)
from orient.constants import (
    DEFAULT_N_MODES,
    MAX_DOFS,
    NEGLIGIBLE_MODE_FRACTION,
    POINT_TOLERANCE_MM,
)

__all__ = [
    "ALUMINIUM",
    "DEFAULT_DAMPING_RATIO",
    "DEFAULT_ELEMENTS_SHORT_SIDE",
    "DEFAULT_MAX_ELEMENTS_PER_DIRECTION",
    "DEFAULT_N_MODES",
    "FINISH_SIDES",
    "MAX_DOFS",
    "NEGLIGIBLE_MODE_FRACTION",
    "POINT_TOLERANCE_MM",
    "STEEL",
    "Material",
    "ThinWall",
    "WallModes",
    "wall_modes",
]



# ---------------------------------------------------------------------- modes
def _nearest_box(p: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> tuple:
    """Of the boxes ``lower``, ``upper`` (n, 3), the one nearest the point ``p`` (the first
    of equals): its index, corners, the nearest point in it and the distance."""
    q = np.clip(p, lower, upper)
    dist = np.linalg.norm(q - p, axis=1)
    e = int(np.argmin(dist))
    return e, lower[e], upper[e], q[e], float(dist[e])


@dataclass(frozen=True, eq=False)
class WallModes:
    """Lowest modes of a :class:`ThinWall` (from :func:`wall_modes`).

    Attributes
    ----------
    wall : ThinWall
    frequencies_hz : ndarray, shape (k,) [Hz]
        Undamped natural frequencies, ascending.
    shapes : ndarray, shape (k, N, 3) [m/sqrt(kg)]
        Mass-normalized mode shapes at the nodes, workpiece-frame components.
    nodes_mm : ndarray, shape (N, 3) [mm]
        Node positions, workpiece frame.
    elements : ndarray, shape (E, 27) int
        Node numbers of each 27-node hexahedron (local order ``9a + 3b + c``).
    mesh : orient.fem.q2hex.Q2Mesh
        The mesh in local wall coordinates ``(a, n, h)`` [mm].
    n_dofs : int
        Free degrees of freedom of the solved model.
    """

    wall: ThinWall
    frequencies_hz: np.ndarray = field(repr=False)
    shapes: np.ndarray = field(repr=False)
    nodes_mm: np.ndarray = field(repr=False)
    elements: np.ndarray = field(repr=False)
    mesh: q2hex.Q2Mesh = field(repr=False)
    n_dofs: int = 0

    @property
    def omega_rad_s(self) -> np.ndarray:
        """Natural angular frequencies, shape (k,) [rad/s]."""
        return 2.0 * math.pi * self.frequencies_hz

    def shapes_at(self, point_mm: Any, *, tol_mm: float = POINT_TOLERANCE_MM) -> np.ndarray:
        """Mode shapes at a point, interpolated with the element's shape functions.

        Parameters
        ----------
        point_mm : array_like, shape (3,) [mm]
            Workpiece-frame point on or in the wall; a point outside (at most
            ``tol_mm`` away) is taken at the nearest point of the material.
        tol_mm : float [mm]

        Returns
        -------
        ndarray, shape (k, 3) [m/sqrt(kg)]
            Displacement of each mass-normalized mode, workpiece frame.
        """
        p = self.wall.to_local(_vec3("point_mm", point_mm))
        tol = _real("tol_mm", tol_mm, ">=0")
        # the elements within tol of the point along each axis hold every one within tol
        # of it, so the nearest (the first of equals, ascending as they are) is the one a
        # pass over all elements finds; where none is, that pass gives the error its
        # distance
        ids = self.mesh.elements_near(np.ravel(p), tol)
        if ids.size:
            e, lo, hi, q, gap = _nearest_box(p, *self.mesh.boxes(ids))
            e = int(ids[e])
        if ids.size == 0 or gap > tol:
            e, lo, hi, q, gap = _nearest_box(p, *self.mesh.boxes())
        if gap > tol:
            raise ValueError(f"point_mm: {np.asarray(point_mm).tolist()} is {gap:.3g} mm "
                             f"from the wall's material (tol_mm={tol:g})")
        n = q2hex.shape_functions((q - lo) / (hi - lo))
        return np.einsum("i,kij->kj", n, self.shapes[:, self.elements[e], :])

    def _oriented(self, d: np.ndarray) -> np.ndarray:
        """``d`` with the sign that makes it point along +normal (else +along, +up)."""
        for ref in (self.wall.normal, self.wall.along, self.wall.up):
            c = float(d @ np.asarray(ref))
            if abs(c) > 1e-9:
                return d if c > 0 else -d
        return d

    def modes_at(self, point_mm: Any, direction: Any = None, *,
                 tol_mm: float = POINT_TOLERANCE_MM) -> list[tuple[Mode, np.ndarray]]:
        """Equivalent single-DOF modes of the wall at a (cutting) point.

        For a mass-normalized shape with displacement ``u`` at the point,
        ``m = 1 / |u|^2``, ``k = w^2 m``, ``c = 2 zeta w m`` along ``d = u/|u|``,
        so that ``d d^T / (k - m W^2 + i c W) = u u^T / (w^2 - W^2 + 2 i zeta w W)``
        (the mode's exact contribution to the point FRF). With ``direction`` e
        given, ``u . e`` replaces ``|u|`` and e is returned (the FRF along e).

        Parameters
        ----------
        point_mm : array_like, shape (3,) [mm]
            Workpiece-frame point (see :meth:`shapes_at`).
        direction : array_like, shape (3,) [-], optional
            Workpiece-frame direction (normalized here).
        tol_mm : float [mm]

        Returns
        -------
        list of (Mode, ndarray shape (3,))
            One entry per mode whose static compliance at the point is above
            ``NEGLIGIBLE_MODE_FRACTION`` of the largest, ascending frequency;
            directions are unit vectors signed toward +normal.
        """
        u = self.shapes_at(point_mm, tol_mm=tol_mm)
        w = self.omega_rad_s
        if direction is None:
            amp = np.linalg.norm(u, axis=1)
            dirs = [self._oriented(ui / a) if a > 0 else ui for ui, a in zip(u, amp)]
        else:
            e = _vec3("direction", direction, unit=True)
            amp = np.abs(u @ e)
            dirs = [e.copy() for _ in u]
        zeta = self.wall.damping_ratio
        return [(Mode.from_frequency(float(self.frequencies_hz[k]), zeta,
                                     float(w[k] ** 2 / amp[k] ** 2)), dirs[k])
                for k in self._kept(amp)]

    def _kept(self, amp: np.ndarray) -> np.ndarray:
        """Indices of the modes whose static compliance at the point (``amp^2 / w^2``)
        is above ``NEGLIGIBLE_MODE_FRACTION`` of the largest."""
        contrib = amp ** 2 / self.omega_rad_s ** 2
        if not np.any(contrib > 0):
            return np.zeros(0, dtype=np.int64)
        return np.flatnonzero(contrib > NEGLIGIBLE_MODE_FRACTION * contrib.max())

    def shape_along(self, point_mm: Any, direction: Any, *,
                    tol_mm: float = POINT_TOLERANCE_MM) -> tuple[np.ndarray, np.ndarray]:
        """Which modes :meth:`modes_at` keeps at a point, and their signed displacement
        there along ``direction``.

        A time-domain run that moves from point to point keeps each mode's modal
        coordinate: the displacement at the point, ``a q``, changes by ``a_new /
        a_old`` (and flips sign across a node), which :meth:`modes_at`'s
        equivalent single-DOF modes (``|a|``) do not carry.

        Returns
        -------
        index : ndarray of int, shape (k,)
            Mode numbers (ascending frequency), as :meth:`modes_at` returns them.
        amp : ndarray, shape (k,) [m/sqrt(kg)]
            ``u . e`` of each.
        """
        e = _vec3("direction", direction, unit=True)
        a = self.shapes_at(point_mm, tol_mm=tol_mm) @ e
        k = self._kept(np.abs(a))
        return k, a[k]

    def frf_at(self, point_mm: Any, omega_rad_s: Any, *,
               tol_mm: float = POINT_TOLERANCE_MM) -> np.ndarray:
        """Point FRF (receptance) of the wall from its modal sum.

        ``G(W) = sum_k u_k u_k^T / (w_k^2 - W^2 + 2 i zeta w_k W)``, the sign
        convention of :mod:`errpred.dynamics` (force ``Re(F e^{iWt})``).

        Parameters
        ----------
        point_mm : array_like, shape (3,) [mm]
        omega_rad_s : array_like, shape (w,) [rad/s]
            Angular frequencies, finite.
        tol_mm : float [mm]

        Returns
        -------
        ndarray complex, shape (w, 3, 3) [m/N]
            Workpiece frame.
        """
        om = np.atleast_1d(np.asarray(omega_rad_s, dtype=float))
        if om.ndim != 1 or not np.all(np.isfinite(om)):
            raise ValueError("omega_rad_s: expected a 1-D array of finite values")
        u = self.shapes_at(point_mm, tol_mm=tol_mm)
        w, zeta = self.omega_rad_s, self.wall.damping_ratio
        den = w[None, :] ** 2 - om[:, None] ** 2 + 2j * zeta * w[None, :] * om[:, None]
        return np.einsum("wk,ki,kj->wij", 1.0 / den, u, u)

    def static_compliance_at(self, point_mm: Any, *,
                             tol_mm: float = POINT_TOLERANCE_MM) -> np.ndarray:
        """Static compliance of the modal model ``sum_k u_k u_k^T / w_k^2``, shape (3, 3) [m/N].

        Truncated to the computed modes (a true 3-D point load has unbounded
        local compliance; the modal sum is the wall's global flexibility)."""
        u = self.shapes_at(point_mm, tol_mm=tol_mm)
        return np.einsum("k,ki,kj->ij", 1.0 / self.omega_rad_s ** 2, u, u)

    def flexible_direction(self, point_mm: Any, *,
                           tol_mm: float = POINT_TOLERANCE_MM) -> np.ndarray:
        """Direction of largest static compliance at the point (principal axis of
        :meth:`static_compliance_at`), unit, signed toward +normal; shape (3,)."""
        vals, vecs = np.linalg.eigh(self.static_compliance_at(point_mm, tol_mm=tol_mm))
        return self._oriented(vecs[:, int(np.argmax(vals))])


def wall_modes(wall: ThinWall, n_modes: int = DEFAULT_N_MODES,
               elements: tuple[int, int, int] | float | None = None) -> WallModes:
    """Lowest natural modes of a thin wall by 3-D finite elements.

    Linear elasticity on triquadratic 27-node hexahedra (no bending locking),
    consistent mass, base ``h = 0`` clamped (and the ends if
    ``wall.clamp_ends``), shift-invert Lanczos for the lowest ``n_modes``.

    Parameters
    ----------
    wall : ThinWall
    n_modes : int
        Number of modes, >= 1.
    elements : None, float [mm] or tuple (n_along, n_thickness, n_height)
        Mesh: None for the default (element size ``min(length, height) /
        DEFAULT_ELEMENTS_SHORT_SIDE``, at most ``DEFAULT_MAX_ELEMENTS_PER_DIRECTION``
        along and up); a float is a target element size [mm] in all three
        directions; a tuple gives the elements along the wall, through each
        thickness layer (a layer lies between two face positions of the
        profile) and over the height (shared among the profile's segments in
        proportion to their height, at least one each).

    Returns
    -------
    WallModes
    """
    if not isinstance(wall, ThinWall):
        raise TypeError(f"wall: expected a ThinWall, got {wall!r}")
    if (isinstance(n_modes, (bool, np.bool_)) or not isinstance(n_modes, numbers.Integral)
            or n_modes < 1):
        raise ValueError(f"n_modes: expected an integer >= 1, got {n_modes!r}")
    mesh = wall_mesh(wall, elements)
    nodes = mesh.nodes
    fixed = nodes[:, 2] <= 0.0
    if wall.clamp_ends:
        fixed |= (nodes[:, 0] <= 0.0) | (nodes[:, 0] >= wall.length_mm)
    free = np.repeat(~fixed, 3)
    n_free = int(free.sum())
    if n_free > MAX_DOFS:
        raise ValueError(f"elements: the mesh has {n_free} free DOFs, more than MAX_DOFS="
                         f"{MAX_DOFS}; use a coarser mesh")
    if n_modes >= n_free:
        raise ValueError(f"n_modes: {n_modes} is not below the model's {n_free} free DOFs")
    si = q2hex.Q2Mesh(lines=tuple(x * 1e-3 for x in mesh.lines), cells=mesh.cells,
                      elements=mesh.elements, nodes=nodes * 1e-3)
    lam, mu = wall.material.lame_Pa()
    K, M = q2hex.assemble(si, lam, mu, wall.material.density_kg_m3)
    w2, X = q2hex.lowest_modes(K, M, free, int(n_modes), q2hex.nested_dissection(si))
    shapes = np.einsum("nck,rc->knr", X.reshape(len(nodes), 3, -1), wall.rotation)
    freq = np.sqrt(np.maximum(w2, 0.0)) / (2.0 * math.pi)
    arrays = [freq, shapes, wall.to_workpiece(nodes), mesh.elements]
    for a in arrays:
        a.flags.writeable = False
    return WallModes(wall, *arrays, mesh=mesh, n_dofs=n_free)
