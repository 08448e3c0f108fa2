"""Orthographic views (``docs/method.md`` §3).

A :class:`View` is a pixel grid on a plane plus a viewing direction:

* ``basis`` rows are the image ``u`` axis, the image ``v`` axis and the
  depth (view) direction ``d``, unit and orthogonal. The constructors make a
  right-handed basis from a right-handed tool frame; a mirrored tool frame
  (counter-clockwise spindle, ``errpred/frames.py``) gives a mirrored
  (left-handed) basis, so that image coordinates stay tool-frame
  coordinates. :attr:`View.handedness` (``det(basis)``, +1 or -1) is what the
  rasterizer uses to tell front from back faces, so both work.
* Pixel ``(i, j)`` (row ``i`` along ``v``, column ``j`` along ``u``) covers
  ``u in [j p, (j+1) p)``, ``v in [i p, (i+1) p)`` with ``p = pixel_mm``;
  its centre is at ``origin + (j + 0.5) p u + (i + 0.5) p v``.
* Depth is measured along ``d`` from the plane through ``origin`` (depth 0,
  "the camera"); a pixel's ray starts at the pixel centre on that plane and
  runs toward +depth.

View coordinates of a world point ``x``: ``(u, v, depth) = basis @ (x - origin)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["View"]


def _as_point(x, name: str) -> np.ndarray:
    a = np.array(x, dtype=float).reshape(-1)
    if a.shape != (3,) or not np.isfinite(a).all():
        raise ValueError(f"{name}: expected 3 finite numbers, got {x!r}")
    return a


_EYE = np.eye(3)
_CUBE = np.array([[u, v, d] for u in (0.0, 1.0) for v in (0.0, 1.0) for d in (0.0, 1.0)])


def _orthonormal(f: np.ndarray, tol: float) -> bool:
    return bool(np.abs(f @ f.T - _EYE).max() <= tol)


def _as_frame(frame, name: str = "frame") -> np.ndarray:
    f = np.asarray(frame, dtype=float)
    if f.shape != (3, 3) or not np.isfinite(f).all():
        raise ValueError(f"{name}: expected a finite (3, 3) matrix, got shape {f.shape}")
    if not _orthonormal(f, 1e-8):
        raise ValueError(f"{name}: rows are not orthonormal (unit axis vectors expected)")
    return f


def _n_pixels(extent_mm: float, pixel_mm: float, name: str) -> int:
    if not (math.isfinite(extent_mm) and extent_mm > 0):
        raise ValueError(f"{name}: expected a finite value > 0, got {extent_mm!r}")
    return max(1, int(math.ceil(extent_mm / pixel_mm - 1e-9)))


@dataclass(frozen=True, eq=False)
class View:
    """An orthographic pixel grid looking along ``basis[2]``.

    Attributes
    ----------
    origin : ndarray, shape (3,) [mm]
        World point at the grid's corner (``u = v = 0``) on the depth-0 plane.
    basis : ndarray, shape (3, 3)
        Rows: image ``u`` axis, image ``v`` axis, depth direction (world).
    pixel_mm : float [mm]
        Side of a square pixel.
    nx, ny : int
        Columns (along ``u``) and rows (along ``v``); buffers are ``(ny, nx)``.
    """

    origin: np.ndarray
    basis: np.ndarray
    pixel_mm: float
    nx: int
    ny: int

    def __post_init__(self) -> None:
        origin = _as_point(self.origin, "view.origin")
        basis = np.array(self.basis, dtype=float)
        if basis.shape != (3, 3) or not np.isfinite(basis).all():
            raise ValueError(f"view.basis: expected a finite (3, 3) matrix, got {basis.shape}")
        if not _orthonormal(basis, 1e-8):
            raise ValueError("view.basis: rows must be unit and orthogonal")
        p = float(self.pixel_mm)
        if not (math.isfinite(p) and p > 0):
            raise ValueError(f"view.pixel_mm: expected a finite value > 0, got {self.pixel_mm!r}")
        for name in ("nx", "ny"):
            n = getattr(self, name)
            if int(n) != n or n < 1:
                raise ValueError(f"view.{name}: expected a whole number >= 1, got {n!r}")
            object.__setattr__(self, name, int(n))
        origin.flags.writeable = False
        basis = np.ascontiguousarray(basis)
        basis.flags.writeable = False
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "basis", basis)
        object.__setattr__(self, "pixel_mm", p)
        (a0, a1, a2), (b0, b1, b2), (c0, c1, c2) = basis.tolist()
        # det(basis) (+-1 within 1e-8: the rows are orthonormal), in scalars
        hand = (a1 * b2 - a2 * b1) * c0 + (a2 * b0 - a0 * b2) * c1 + (a0 * b1 - a1 * b0) * c2
        object.__setattr__(self, "_handedness", 1 if hand > 0 else -1)

    # --- axes -------------------------------------------------------------
    @property
    def u_axis(self) -> np.ndarray:
        return self.basis[0]

    @property
    def v_axis(self) -> np.ndarray:
        return self.basis[1]

    @property
    def direction(self) -> np.ndarray:
        """Depth (viewing) direction, world, unit."""
        return self.basis[2]

    @property
    def handedness(self) -> int:
        """``det(basis)``: +1 right-handed, -1 mirrored."""
        return self._handedness

    @property
    def shape(self) -> tuple[int, int]:
        """Buffer shape ``(ny, nx)``."""
        return (self.ny, self.nx)

    @property
    def width_mm(self) -> float:
        return self.nx * self.pixel_mm

    @property
    def height_mm(self) -> float:
        return self.ny * self.pixel_mm

    # --- coordinates ------------------------------------------------------
    def to_view(self, points) -> np.ndarray:
        """World points (n, 3) -> view coordinates (n, 3): ``(u, v, depth)``."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        return (p - self.origin) @ self.basis.T

    def to_world(self, uvd) -> np.ndarray:
        """View coordinates (n, 3) -> world points (n, 3)."""
        q = np.asarray(uvd, dtype=float).reshape(-1, 3)
        return self.origin + q @ self.basis

    def pixel_of(self, points) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pixel of each world point: ``(i, j, inside)``.

        ``i`` (row, along ``v``) and ``j`` (column, along ``u``) are clipped
        into the grid so they can always index a buffer; ``inside`` is False
        where the point projects outside the window.
        """
        q = self.to_view(points)
        inv = 1.0 / self.pixel_mm
        jf = np.floor(q[:, 0] * inv)
        if_ = np.floor(q[:, 1] * inv)
        inside = (jf >= 0) & (jf < self.nx) & (if_ >= 0) & (if_ < self.ny)
        j = np.clip(jf, 0, self.nx - 1).astype(np.int64)
        i = np.clip(if_, 0, self.ny - 1).astype(np.int64)
        return i, j, inside

    def pixel_centres(self) -> np.ndarray:
        """Pixel centres in image coordinates, shape (ny, nx, 2): ``(u, v)``."""
        p = self.pixel_mm
        u = (np.arange(self.nx) + 0.5) * p
        v = (np.arange(self.ny) + 0.5) * p
        uu, vv = np.meshgrid(u, v)
        return np.stack([uu, vv], axis=-1)

    def pixel_centres_world(self, depth: float = 0.0) -> np.ndarray:
        """Pixel centres at ``depth`` in world coordinates, shape (ny, nx, 3)."""
        c = self.pixel_centres()
        return (self.origin + c[..., 0:1] * self.basis[0] + c[..., 1:2] * self.basis[1]
                + float(depth) * self.basis[2])

    def ray_origins_world(self) -> np.ndarray:
        """Start points of the pixel rays (centres on the depth-0 plane), (ny, nx, 3)."""
        return self.pixel_centres_world(0.0)

    def corners_world(self, dmin: float, dmax: float) -> np.ndarray:
        """The 8 corners of the window prism between depths dmin and dmax, (8, 3)."""
        uvd = _CUBE * (self.width_mm, self.height_mm, 1.0)
        uvd[:, 2] = np.where(_CUBE[:, 2] == 0.0, float(dmin), float(dmax))
        return self.origin + uvd @ self.basis

    def aabb(self, dmin: float, dmax: float) -> np.ndarray:
        """World bounding box (2, 3) of the window prism between depths dmin and dmax."""
        c = self.corners_world(dmin, dmax)
        return np.stack([c.min(axis=0), c.max(axis=0)])

    # --- constructors -----------------------------------------------------
    @classmethod
    def centred(cls, centre, basis, width_mm: float, height_mm: float, pixel_mm: float,
                depth_offset_mm: float = 0.0) -> "View":
        """A window of ``width_mm`` x ``height_mm`` centred on ``centre``'s projection.

        The depth-0 plane lies ``depth_offset_mm`` before ``centre`` (``centre``
        is at depth ``depth_offset_mm``). ``nx = ceil(width / pixel)``, ``ny =
        ceil(height / pixel)``; the window grows to whole pixels, staying centred.
        """
        c = _as_point(centre, "centre")
        b = _as_frame(basis, "basis")
        p = float(pixel_mm)
        if not (math.isfinite(p) and p > 0):
            raise ValueError(f"pixel_mm: expected a finite value > 0, got {pixel_mm!r}")
        nx = _n_pixels(float(width_mm), p, "width_mm")
        ny = _n_pixels(float(height_mm), p, "height_mm")
        origin = c - 0.5 * nx * p * b[0] - 0.5 * ny * p * b[1] - float(depth_offset_mm) * b[2]
        return cls(origin, b, p, nx, ny)

    @classmethod
    def along_axis(cls, tip, frame, window_mm: float, pixel_mm: float,
                   depth_offset_mm: float) -> "View":
        """The bottom view: up the tool axis (+z') from below the tip.

        Image axes ``x'`` (u) and ``y'`` (v), square window of side
        ``window_mm`` (the tool diameter) centred on the tool axis, depth 0 at
        ``z' = -depth_offset_mm`` (so a point's depth is ``z' +
        depth_offset_mm``). ``frame`` rows are ``x', y', z'`` (a mirrored
        frame gives a mirrored view).
        """
        f = _as_frame(frame)
        return cls.centred(tip, f, window_mm, window_mm, pixel_mm, depth_offset_mm)

    @staticmethod
    def side_basis_tool(azimuth_rad: float) -> np.ndarray:
        """Basis of :meth:`side` in tool-frame coordinates (rows u, v, d).

        The camera sits at azimuth ``a`` (measured like the flute angle,
        from +y' toward +x': direction ``(sin a, cos a, 0)``) and looks toward
        the axis: ``d = -(sin a, cos a, 0)``, ``v = +z'``, ``u = v x d =
        (cos a, -sin a, 0)`` (right-handed in the tool frame).
        """
        s, c = math.sin(azimuth_rad), math.cos(azimuth_rad)
        return np.array([[c, -s, 0.0], [0.0, 0.0, 1.0], [-s, -c, 0.0]])

    @classmethod
    def side(cls, tip, frame, azimuth_rad: float, width_mm: float, height_mm: float,
             pixel_mm: float, depth_offset_mm: float | None = None) -> "View":
        """A horizontal view (in the tool frame) toward the tool axis.

        The camera sits at azimuth ``azimuth_rad`` (see
        :meth:`side_basis_tool`); image ``v`` is ``+z'``. The window is
        centred on the axis laterally (``u`` in ``[-W/2, W/2]`` about the
        axis) and runs from ``z' = 0`` up to ``height_mm`` (rounded up to whole
        pixels). The depth-0 plane lies ``depth_offset_mm`` from the axis on
        the camera side (default ``width_mm / 2``: tangent to a tool of
        diameter ``width_mm``), so the axis is at depth ``depth_offset_mm``.
        """
        f = _as_frame(frame)
        t = _as_point(tip, "tip")
        p = float(pixel_mm)
        if not (math.isfinite(p) and p > 0):
            raise ValueError(f"pixel_mm: expected a finite value > 0, got {pixel_mm!r}")
        nx = _n_pixels(float(width_mm), p, "width_mm")
        ny = _n_pixels(float(height_mm), p, "height_mm")
        off = 0.5 * float(width_mm) if depth_offset_mm is None else float(depth_offset_mm)
        bt = cls.side_basis_tool(float(azimuth_rad))
        origin_tool = -0.5 * nx * p * bt[0] - off * bt[2]
        return cls(t + origin_tool @ f, bt @ f, p, nx, ny)

    def zoomed(self, centre, width_mm: float, pixel_mm: float,
               height_mm: float | None = None) -> "View":
        """Same direction and depth-0 plane, a new window centred on ``centre``'s projection."""
        c = _as_point(centre, "centre")
        depth = float((c - self.origin) @ self.basis[2])
        h = width_mm if height_mm is None else height_mm
        return View.centred(c, self.basis, width_mm, h, pixel_mm, depth_offset_mm=depth)
