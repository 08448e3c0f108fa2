"""End mills as surfaces of revolution, and their cutting edges as micro edges.

One generalized end mill covers the three kinds (``docs/method.md`` §2):
diameter ``D = 2R`` and corner radius ``r``; a ball end mill has ``r = R``,
a flat end mill ``r = 0``, a radius (bull-nose) end mill ``0 < r < R``. The
cutting profile in the tool frame (tip at the origin, ``z'`` up the tool
axis) has three segments, in order of arc length from the axis outward:

1. bottom face: ``rho`` in ``[0, R - r]``, ``z = 0``, ``kappa = 0``;
2. corner arc: ``rho = (R - r) + r sin(kappa)``, ``z = r (1 - cos(kappa))``,
   ``kappa`` in ``[0, pi/2]``;
3. flank: ``rho = R``, ``z`` in ``[r, flute length]``, ``kappa = pi/2``.

``kappa`` is the axial immersion (contact) angle: the angle between the
tool axis and the outward normal of the envelope, measured from the
downward axis (0 at a ball's tip, 90 deg on the flank). The outward normal
at rotation angle ``phi`` is ``(sin k sin phi, sin k cos phi, -cos k)``;
the centre of curvature of the envelope is the core circle
``((R - r) sin phi, (R - r) cos phi, r)`` on the corner arc (the ball
centre for a ball end mill).

The tool solid (cutting envelope and the region above it, the shank taken as
an endless cylinder of radius ``R``) is the set of points within ``r`` of the
*core* ``C = {rho <= R - r, z >= r}``; :func:`core_distance` is that
distance, which is how sweeps and membership tests use the geometry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from nc.checks import real_number

from . import constants as K

__all__ = ["Tool", "Holder", "MicroEdges", "TOOL_KINDS", "core_distance"]

TOOL_KINDS = ("ball", "radius", "flat")


@dataclass(frozen=True)
class Holder:
    """Tool holder, for interference checks (a cylinder above the shank).

    Attributes
    ----------
    diameter_mm : float [mm]
    length_mm : float [mm]
        Axial length of the holder body, starting where the overhang ends.
    """

    diameter_mm: float
    length_mm: float

    def __post_init__(self) -> None:
        for name in ("diameter_mm", "length_mm"):
            object.__setattr__(self, name, real_number(f"holder.{name}", getattr(self, name),
                                                       ">0"))


@dataclass(frozen=True, eq=False)
class MicroEdges:
    """The cutting edge of one flute cut into micro edges (at rotation 0).

    Attributes
    ----------
    rho : ndarray, shape (m,) [mm]
        Radius of the micro edge's midpoint from the tool axis.
    z : ndarray, shape (m,) [mm]
        Height above the tip.
    kappa : ndarray, shape (m,) [rad]
        Axial immersion angle (0 at the tip, pi/2 on the flank).
    psi : ndarray, shape (m,) [rad]
        Helix lag: the micro edge of a flute at rotation ``theta`` sits at
        angle ``theta - psi`` (``psi = z tan(helix) / R``).
    db : ndarray, shape (m,) [mm]
        Chip width: the micro edge's length along the profile
        (``dz / sin(kappa)`` on the corner, ``drho`` on the bottom face).
    ds : ndarray, shape (m,) [mm]
        Length of the helical edge itself (chip width and helix lag).
    segment : ndarray, shape (m,), int
        0 bottom face, 1 corner arc, 2 flank.
    s : ndarray, shape (m,) [mm]
        Arc length of the micro edge's midpoint along the profile
        (:meth:`Tool.profile_at`).
    """

    rho: np.ndarray
    z: np.ndarray
    kappa: np.ndarray
    psi: np.ndarray
    db: np.ndarray
    ds: np.ndarray
    segment: np.ndarray
    s: np.ndarray

    def __len__(self) -> int:
        return int(self.rho.shape[0])

    def take(self, index) -> "MicroEdges":
        """The micro edges selected by ``index`` (mask or integer array)."""
        return MicroEdges(self.rho[index], self.z[index], self.kappa[index], self.psi[index],
                          self.db[index], self.ds[index], self.segment[index], self.s[index])

    def normals(self, phi: np.ndarray) -> np.ndarray:
        """Outward envelope normals at angles ``phi``, shape phi.shape + (m, 3).

        Parameters
        ----------
        phi : ndarray [rad]
            Angular positions (already including the helix lag), broadcast
            against the micro edges on the last axis.
        """
        sk, ck = np.sin(self.kappa), np.cos(self.kappa)
        sp, cp = np.sin(phi), np.cos(phi)
        return np.stack(np.broadcast_arrays(sk * sp, sk * cp, -ck), axis=-1)


#: The lengths a tool may leave out (``None``: derived from the diameter).
_OPTIONAL = ("flute_length_mm", "overhang_mm", "shank_diameter_mm")


@dataclass(frozen=True)
class Tool:
    """A generalized end mill.

    Parameters
    ----------
    kind : str
        ``"ball"``, ``"radius"`` or ``"flat"``.
    diameter_mm : float [mm]
    corner_radius_mm : float [mm]
        Ignored (set to ``R``) for a ball end mill and (set to 0) for a flat
        end mill; for a radius end mill ``0 < r < R``.
    flutes : int
    helix_deg : float [deg]
        Helix angle (0 for straight edges and inserts).
    flute_length_mm : float [mm]
        Axial length of the cutting edges from the tip.
    overhang_mm : float [mm]
        Gauge length from the holder face to the tip.
    rotation : str
        ``"cw"`` (M3, clockwise seen from the spindle) or ``"ccw"`` (M4).
    shank_diameter_mm : float, optional [mm]
        Default: the cutting diameter.
    holder : Holder, optional

    Lengths and angles are held as float, whatever real number type they are given in.

    Raises
    ------
    TypeError
        A length or angle that is not a real number (a boolean included).
    ValueError
        A value out of its range; the message names the key.
    """

    kind: str
    diameter_mm: float
    corner_radius_mm: float = 0.0
    flutes: int = 2
    helix_deg: float = 30.0
    flute_length_mm: float | None = None
    overhang_mm: float | None = None
    rotation: str = "cw"
    shank_diameter_mm: float | None = None
    holder: Holder | None = field(default=None)

    def __post_init__(self) -> None:
        if self.kind not in TOOL_KINDS:
            raise ValueError(f"tool.type: {self.kind!r}; expected one of {', '.join(TOOL_KINDS)}")
        # lengths and angles held as float: an int (``flute_length_mm=15``) had every numba
        # kernel that takes them compiled a second time, for int64; every length finite
        # and > 0 (the angle and the corner radius: their ranges below)
        for name in ("diameter_mm", "corner_radius_mm", "helix_deg", "flute_length_mm",
                     "overhang_mm", "shank_diameter_mm"):
            v = getattr(self, name)
            if v is None and name in _OPTIONAL or (name == "corner_radius_mm"
                                                     and self.kind != "radius"):
                continue            # derived below (a ball's or flat end mill's: ignored)
            bound = "" if name in ("corner_radius_mm", "helix_deg") else ">0"
            object.__setattr__(self, name, real_number(f"tool.{name}", v, bound))
        d = self.diameter_mm
        R = d / 2
        if self.kind == "ball":
            object.__setattr__(self, "corner_radius_mm", R)
        elif self.kind == "flat":
            object.__setattr__(self, "corner_radius_mm", 0.0)
        else:
            r = self.corner_radius_mm
            if not 0 < r < R:
                raise ValueError(f"tool.corner_radius_mm: {r!r}; a radius end mill needs "
                                 f"0 < r < D/2 = {R:g} mm")
        if not (isinstance(self.flutes, int) and self.flutes >= 1):
            raise ValueError(f"tool.flutes: expected a whole number >= 1, got {self.flutes!r}")
        if not -60 <= self.helix_deg <= 60:
            raise ValueError(f"tool.helix_deg: expected -60..60, got {self.helix_deg!r}")
        if self.rotation not in ("cw", "ccw"):
            raise ValueError(f"tool.rotation: {self.rotation!r}; expected 'cw' or 'ccw'")
        if self.flute_length_mm is None:
            object.__setattr__(self, "flute_length_mm", max(2.0 * d, self.corner_radius_mm))
        if self.overhang_mm is None:
            object.__setattr__(self, "overhang_mm", 3.0 * d + self.flute_length_mm)
        if self.shank_diameter_mm is None:
            object.__setattr__(self, "shank_diameter_mm", d)
        if self.flute_length_mm < self.corner_radius_mm:
            raise ValueError(f"tool.flute_length_mm: {self.flute_length_mm:g} mm is shorter "
                             f"than the corner radius {self.corner_radius_mm:g} mm")
        if self.overhang_mm < self.flute_length_mm:
            raise ValueError(f"tool.overhang_mm: {self.overhang_mm:g} mm is shorter than the "
                             f"flute length {self.flute_length_mm:g} mm")

    # --- dimensions -------------------------------------------------------
    @property
    def radius_mm(self) -> float:
        """Cutting radius ``R = D/2`` [mm]."""
        return self.diameter_mm / 2.0

    @property
    def core_radius_mm(self) -> float:
        """Radius of the core circle, ``R - r`` [mm] (0 for a ball)."""
        return self.radius_mm - self.corner_radius_mm

    @property
    def rotation_sign(self) -> int:
        """+1 for a clockwise (M3) spindle, -1 for counter-clockwise."""
        return 1 if self.rotation == "cw" else -1

    @property
    def tan_helix(self) -> float:
        return math.tan(math.radians(self.helix_deg))

    # --- the lower envelope ------------------------------------------------
    def envelope_z(self, rho: np.ndarray) -> np.ndarray:
        """Height of the lower envelope above the tip at radius ``rho`` [mm].

        NaN outside the tool (``rho > R``).
        """
        rho = np.asarray(rho, dtype=float)
        c, r = self.core_radius_mm, self.corner_radius_mm
        d = np.clip(rho - c, 0.0, r)
        z = r - np.sqrt(np.maximum(r * r - d * d, 0.0))
        return np.where(rho <= self.radius_mm * (1 + 1e-12), z, np.nan)

    def kappa_at_rho(self, rho: np.ndarray) -> np.ndarray:
        """Contact angle of the lower envelope at radius ``rho`` [rad]."""
        rho = np.asarray(rho, dtype=float)
        c, r = self.core_radius_mm, self.corner_radius_mm
        if r == 0:
            return np.where(rho <= self.radius_mm, 0.0, np.nan)
        s = np.clip((rho - c) / r, 0.0, 1.0)
        return np.where(rho <= self.radius_mm * (1 + 1e-12), np.arcsin(s), np.nan)

    def profile_point(self, kappa: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(rho, z)`` of the corner arc at contact angle ``kappa`` [mm]."""
        kappa = np.asarray(kappa, dtype=float)
        r = self.corner_radius_mm
        return self.core_radius_mm + r * np.sin(kappa), r * (1.0 - np.cos(kappa))

    def profile_at(self, s_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(rho, z, kappa)`` at arc length ``s_mm`` along the cutting profile.

        Arc length runs from the axis along the bottom face (``R - r``), the
        corner arc (``r pi / 2``) and up the flank.
        """
        s = np.asarray(s_mm, dtype=float)
        c, r = self.core_radius_mm, self.corner_radius_mm
        corner = r * math.pi / 2
        rho = np.where(s <= c, np.maximum(s, 0.0), self.radius_mm)
        z = np.where(s <= c + corner, 0.0, r + (s - c - corner))
        kappa = np.where(s <= c, 0.0, math.pi / 2)
        on = (s > c) & (s <= c + corner)
        if r > 0 and np.any(on):
            k = (s[on] - c) / r if s.ndim else (float(s) - c) / r
            rr, zz = self.profile_point(k)
            if s.ndim:
                rho[on], z[on], kappa[on] = rr, zz, k
            else:
                rho, z, kappa = rr, zz, np.asarray(k)
        return rho, z, kappa

    def helix_lag(self, z: np.ndarray) -> np.ndarray:
        """Helix lag ``psi = z tan(helix) / R`` at height ``z`` [rad]."""
        return np.asarray(z, dtype=float) * self.tan_helix / self.radius_mm

    # --- micro edges --------------------------------------------------------
    def micro_edges(self, n_envelope: int = K.MICRO_EDGES_ENVELOPE,
                    flank_height_mm: float | None = None) -> MicroEdges:
        """Cut one flute's edge into micro edges of about equal profile length.

        Parameters
        ----------
        n_envelope : int
            Micro edges on the lower envelope (bottom face and corner arc),
            shared between them by length (at least one on each segment that
            has length).
        flank_height_mm : float, optional [mm]
            Top of the flank part to include (default: the flute length).
            Flank micro edges get the envelope's spacing.

        Returns
        -------
        MicroEdges
        """
        if not (isinstance(n_envelope, (int, np.integer)) and n_envelope >= 2):
            raise ValueError(f"n_envelope: expected an integer >= 2, got {n_envelope!r}")
        R, r, c = self.radius_mm, self.corner_radius_mm, self.core_radius_mm
        top = self.flute_length_mm if flank_height_mm is None else float(flank_height_mm)
        if not (math.isfinite(top) and top >= 0):
            raise ValueError(f"flank_height_mm: expected a finite value >= 0, got {top!r}")
        top = min(top, self.flute_length_mm)
        len_bottom, len_corner = c, r * math.pi / 2
        total = len_bottom + len_corner
        n_b = 0 if len_bottom == 0 else max(1, round(n_envelope * len_bottom / total))
        n_c = 0 if len_corner == 0 else max(1, n_envelope - n_b)
        if len_corner == 0:
            n_b = n_envelope
        rho, z, kap, db, seg = [], [], [], [], []
        if n_b:
            edges = np.linspace(0.0, c, n_b + 1)
            rho.append(0.5 * (edges[1:] + edges[:-1]))
            z.append(np.zeros(n_b))
            kap.append(np.zeros(n_b))
            db.append(np.diff(edges))
            seg.append(np.zeros(n_b, dtype=int))
        if n_c:
            ke = np.linspace(0.0, math.pi / 2, n_c + 1)
            km = 0.5 * (ke[1:] + ke[:-1])
            rr, zz = self.profile_point(km)
            rho.append(rr)
            z.append(zz)
            kap.append(km)
            db.append(np.full(n_c, r * (math.pi / 2) / n_c))
            seg.append(np.ones(n_c, dtype=int))
        spacing = total / n_envelope
        flank_len = max(top - r, 0.0)
        n_f = int(math.ceil(flank_len / spacing - 1e-9)) if flank_len > 0 else 0
        if n_f:
            ze = np.linspace(r, r + flank_len, n_f + 1)
            rho.append(np.full(n_f, R))
            z.append(0.5 * (ze[1:] + ze[:-1]))
            kap.append(np.full(n_f, math.pi / 2))
            db.append(np.diff(ze))
            seg.append(np.full(n_f, 2, dtype=int))
        rho_a, z_a = np.concatenate(rho), np.concatenate(z)
        psi = self.helix_lag(z_a)
        db_a = np.concatenate(db)
        # helical edge length: profile length and the lag's arc, combined
        dpsi = np.gradient(psi) if psi.size > 1 else np.zeros_like(psi)
        ds = np.sqrt(db_a ** 2 + (rho_a * dpsi) ** 2)
        s_mid = np.cumsum(db_a) - 0.5 * db_a
        return MicroEdges(rho=rho_a, z=z_a, kappa=np.concatenate(kap), psi=psi, db=db_a,
                          ds=ds, segment=np.concatenate(seg), s=s_mid)


def core_distance(rho: np.ndarray, z: np.ndarray, core_radius: float,
                  corner_radius: float) -> np.ndarray:
    """Distance from points (tool frame, radius ``rho``, height ``z``) to the core.

    The core is ``{rho <= R - r, z >= r}``; a point is inside the tool solid
    when this distance is at most ``r``.

    Parameters
    ----------
    rho, z : ndarray [mm]
    core_radius : float [mm]
        ``R - r``.
    corner_radius : float [mm]
        ``r``.

    Returns
    -------
    ndarray [mm]
    """
    dr = np.maximum(np.asarray(rho, dtype=float) - core_radius, 0.0)
    dz = np.maximum(corner_radius - np.asarray(z, dtype=float), 0.0)
    return np.hypot(dr, dz)
