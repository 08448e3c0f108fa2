"""The machine model (one posture, vectorized over points) and machine files.

:class:`RotaryAxis` and :class:`Machine` follow the frames and sign
conventions written down in :mod:`nc.kinematics`, which re-exports every
public name here and adds the named machines, the path solver and the
linearization. Use those names through :mod:`nc.kinematics`.

Machine file (TOML; angles in degrees in ``*_deg`` keys; missing limits mean
unlimited, ``inf``/``-inf`` allowed there, NaN never)::

    kind = "xyzbc-head-table"   # a named machine (nc.kinematics.MACHINES) or "custom"
    name = "my mill"            # optional, default: kind
    tool_length_mm = 120.0      # optional, default 0

    [linear_limits_mm]          # optional, each [min, max]
    x = [-300.0, 300.0]

    [tilt]                      # column 3; optional for a named kind
    pivot_mm = [0.0, 0.0, 150.0]
    direction = 1
    min_deg = -95.0
    max_deg = 95.0

    [rotary]                    # column 4 (the C axis)
    pivot_mm = [0.0, 0.0, 0.0]

With ``kind = "custom"`` both sections also need ``name`` ("A"/"B"/"C"),
``about`` ("x"/"y"/"z" or [ux, uy, uz]) and ``carrier`` ("head"/"table").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import constants as K
from .errors import KinematicsError

__all__ = ["RotaryAxis", "Machine"]

_BASIS = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
_Z = np.array([0.0, 0.0, 1.0])
_TWO_PI = 2.0 * math.pi
_UNLIMITED = (-math.inf, math.inf)


# --------------------------------------------------------------------------- helpers
def _rows(a: ArrayLike, width: int, name: str) -> tuple[NDArray[np.float64], bool]:
    """Float array (n, width) from (n, width) or (width,); refuse NaN/inf."""
    try:
        arr = np.asarray(a, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: not an array of numbers ({exc})") from None
    single = arr.ndim == 1
    if single:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != width:
        raise ValueError(f"{name}: expected shape (n, {width}) or ({width},), "
                         f"got {np.shape(a)}")
    fin = np.isfinite(arr).all(axis=1)
    if not fin.all():
        i = int(np.argmin(fin))
        raise ValueError(f"{name}: row {i} is not finite (NaN or inf): {arr[i]}")
    return arr, single


def _unit_rows(a: ArrayLike, name: str) -> tuple[NDArray[np.float64], bool]:
    """Unit vectors (n, 3), normalized; refuse lengths off 1 by UNIT_VECTOR_TOL."""
    arr, single = _rows(a, 3, name)
    norm = np.linalg.norm(arr, axis=1)
    off = np.abs(norm - 1.0) > K.UNIT_VECTOR_TOL
    if off.any():
        i = int(np.argmax(off))
        raise ValueError(f"{name}: row {i} has length {norm[i]:.9g}, not a unit "
                         f"vector (within {K.UNIT_VECTOR_TOL:g})")
    return arr / norm[:, None], single


def _rotate(v: NDArray, k: NDArray, c: NDArray, s: NDArray) -> NDArray:
    """Rotate rows of ``v`` (n, 3) right-handed about unit ``k`` (3,).

    ``c``, ``s`` (n,): cosine and sine of the angles.
    """
    out = np.empty(np.broadcast_shapes(v.shape, (len(c), 3)))
    hit = np.flatnonzero(k == 1.0)
    if hit.size == 1 and np.count_nonzero(k) == 1:  # about +X, +Y or +Z: 4 products
        i = int(hit[0])
        j, m = (i + 1) % 3, (i + 2) % 3
        vj, vm = v[:, j], v[:, m]
        out[:, i] = v[:, i]
        out[:, j] = c * vj - s * vm
        out[:, m] = s * vj + c * vm
        return out
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    dot = (x * k[0] + y * k[1] + z * k[2]) * (1.0 - c)
    out[:, 0] = x * c + (k[1] * z - k[2] * y) * s + k[0] * dot
    out[:, 1] = y * c + (k[2] * x - k[0] * z) * s + k[1] * dot
    out[:, 2] = z * c + (k[0] * y - k[1] * x) * s + k[2] * dot
    return out


def _angle_about(k: NDArray, x: NDArray, y: NDArray) -> NDArray:
    """Angle [rad] of the rotation about unit ``k`` that turns ``x`` toward ``y`` (rows)."""
    det = np.cross(x, y) @ k
    dot = np.einsum("ij,ij->i", x, y) - (x @ k) * (y @ k)
    return np.arctan2(det, dot)


def _wrap(a: NDArray) -> NDArray:
    """Angles wrapped into [-pi, pi) [rad]."""
    return (np.asarray(a) + math.pi) % _TWO_PI - math.pi


def _between(v: NDArray, lo: float, hi: float, tol: float) -> NDArray:
    return (v >= lo - tol) & (v <= hi + tol)


def _angle_between(u: NDArray, v: NDArray) -> NDArray:
    """Angle [rad] between unit row vectors, accurate near 0."""
    return np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), np.einsum("ij,ij->i", u, v))


# --------------------------------------------------------------------------- model
@dataclass(frozen=True)
class RotaryAxis:
    """One rotary axis of a machine.

    Parameters
    ----------
    name : str
        Axis letter, ``"A"``, ``"B"`` or ``"C"``.
    about : str or tuple of 3 float
        ``"x"``, ``"y"``, ``"z"`` (machine axis) or a unit vector: the axis
        direction at zero posture. Vectors off unit length by more than
        ``UNIT_VECTOR_TOL`` are refused, others normalized.
    carrier : str
        ``"table"`` (turns the workpiece) or ``"head"`` (turns the spindle).
    pivot_mm : tuple of 3 float [mm]
        A point on the axis at zero posture. Table axis: in the workpiece
        frame. Head axis: from the spindle gauge point (spindle nose).
    direction : int
        +1 or -1: machine angle = direction x right-hand rotation of the
        carried body about ``about``.
    min_rad, max_rad : float [rad]
        Travel of the machine angle; +-inf for continuous rotation.
    """

    name: str
    about: str | tuple[float, float, float]
    carrier: str
    pivot_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    direction: int = 1
    min_rad: float = -math.inf
    max_rad: float = math.inf

    def __post_init__(self) -> None:
        if self.name not in ("A", "B", "C"):
            raise ValueError(f"name: expected 'A', 'B' or 'C', got {self.name!r}")
        if self.carrier not in ("head", "table"):
            raise ValueError(f"carrier: expected 'head' or 'table', got {self.carrier!r}")
        about: Any = self.about
        if isinstance(about, str):
            if about.lower() not in _BASIS:
                raise ValueError(f"about: expected 'x', 'y', 'z' or a unit vector, got {about!r}")
            about = about.lower()
        else:
            vec, _ = _unit_rows(about, "about")
            if vec.shape[0] != 1:
                raise ValueError("about: expected 3 numbers")
            about = tuple(float(c) for c in vec[0])
            about = next((k for k, b in _BASIS.items() if b == about), about)
        object.__setattr__(self, "about", about)
        piv, _ = _rows(self.pivot_mm, 3, "pivot_mm")
        if piv.shape[0] != 1:
            raise ValueError("pivot_mm: expected 3 numbers")
        object.__setattr__(self, "pivot_mm", tuple(float(c) for c in piv[0]))
        if isinstance(self.direction, bool) or self.direction not in (1, -1):
            raise ValueError(f"direction: expected +1 or -1, got {self.direction!r}")
        object.__setattr__(self, "direction", int(self.direction))
        lo, hi = float(self.min_rad), float(self.max_rad)
        if math.isnan(lo) or math.isnan(hi) or not lo < hi:
            raise ValueError(f"min_rad, max_rad: need min < max, got {lo!r}, {hi!r}")
        object.__setattr__(self, "min_rad", lo)
        object.__setattr__(self, "max_rad", hi)

    @property
    def vector(self) -> NDArray[np.float64]:
        """Unit axis direction at zero posture, shape (3,)."""
        return np.array(_BASIS[self.about] if isinstance(self.about, str) else self.about)

    @property
    def limited(self) -> bool:
        """True unless the axis turns without limit both ways."""
        return math.isfinite(self.min_rad) or math.isfinite(self.max_rad)


@dataclass(frozen=True)
class Machine:
    """A 5-axis machine: X Y Z plus ``axes = (tilt, rotary)`` (conventions: :mod:`nc.kinematics`).

    Parameters
    ----------
    name : str
        Machine name (shown in messages).
    axes : tuple of 2 RotaryAxis
        The tilt axis (A or B, joint column 3) and the rotary axis (C, the
        free axis at the singularity, joint column 4). Allowed carriers
        (tilt, rotary): (table, table), (head, table), (head, head).
    tool_length_mm : float [mm]
        Gauge length of the tool (spindle nose to tip); moves head pivots.
    linear_limits_mm : tuple of 3 (min, max) [mm]
        Travel of machine X, Y, Z; +-inf for unlimited (default).
    """

    name: str
    axes: tuple[RotaryAxis, RotaryAxis]
    tool_length_mm: float = 0.0
    linear_limits_mm: tuple[tuple[float, float], ...] = (_UNLIMITED,) * 3

    def __post_init__(self) -> None:
        axes = tuple(self.axes)
        if len(axes) != 2 or not all(isinstance(a, RotaryAxis) for a in axes):
            raise ValueError("axes: expected (tilt, rotary), two RotaryAxis")
        object.__setattr__(self, "axes", axes)
        tilt, rot = axes
        if tilt.name == rot.name:
            raise ValueError(f"axes: both rotary axes are named {tilt.name}")
        if (tilt.carrier, rot.carrier) == ("table", "head"):
            raise ValueError("axes: a table tilt axis with a head rotary axis is not "
                             "supported (the rotary axis must sit nearer the workpiece)")
        at, ac = tilt.vector, rot.vector
        if np.linalg.norm(np.cross(at, ac)) < math.sin(K.MIN_AXIS_ANGLE_RAD):
            raise ValueError("axes: tilt and rotary axes are parallel")
        if np.linalg.norm(np.cross(at, _Z)) < math.sin(K.MIN_AXIS_ANGLE_RAD):
            raise ValueError("axes: the tilt axis is parallel to the tool axis (+Z)")
        tl = float(self.tool_length_mm)
        if not math.isfinite(tl):
            raise ValueError(f"tool_length_mm: not finite: {self.tool_length_mm!r}")
        object.__setattr__(self, "tool_length_mm", tl)
        try:
            lim = tuple((float(lo), float(hi)) for lo, hi in self.linear_limits_mm)
        except (TypeError, ValueError):
            lim = ()
        if len(lim) != 3 or any(math.isnan(lo) or math.isnan(hi) or not lo < hi
                                for lo, hi in lim):
            raise ValueError(f"linear_limits_mm: need three (min, max) with min < max, "
                             f"got {self.linear_limits_mm!r}")
        object.__setattr__(self, "linear_limits_mm", lim)

    @property
    def rotary_names(self) -> tuple[str, str]:
        """Letters of joint columns 3 and 4, e.g. ``("A", "C")``."""
        return self.axes[0].name, self.axes[1].name

    def with_tool_length(self, mm: float) -> "Machine":
        """The same machine with tool length ``mm`` [mm]."""
        return replace(self, tool_length_mm=mm)

    def forward(self, joints: ArrayLike) -> tuple[NDArray, NDArray]:
        """Tool tip and tool axis in the workpiece frame.

        Parameters
        ----------
        joints : ndarray, shape (n, 5) or (5,) [mm, mm, mm, rad, rad]
            Machine X, Y, Z, tilt, rotary.

        Returns
        -------
        tip : ndarray, shape (n, 3) or (3,) [mm]
        axis : ndarray, shape (n, 3) or (3,)
            Unit tool axis, tip toward spindle.
        """
        j, single = _rows(joints, 5, "joints")
        m, u = self._forward(j)
        return (m[0], u[0]) if single else (m, u)

    def tool_frame(self, tilt_rad: float, rot_rad: float) -> NDArray[np.float64]:
        """The spindle's X, Y and Z (columns) in the workpiece frame at these angles.

        The head axes turn the spindle's frame, the table axes turn the
        workpiece under it (so their turns are undone), as in :meth:`forward`;
        column 2 is :meth:`forward`'s tool axis. This is the frame a swivel
        cycle sets from rotary axis positions (Sinumerik CYCLE800 direct mode).

        Parameters
        ----------
        tilt_rad, rot_rad : float [rad]
            Machine angles of the tilt (column 3) and rotary (column 4) axes.

        Returns
        -------
        ndarray, shape (3, 3)
            Orthonormal, determinant +1.
        """
        a = np.array([float(tilt_rad), float(rot_rad)])
        if not np.all(np.isfinite(a)):
            raise ValueError(f"tool_frame: angles not finite: {tilt_rad!r}, {rot_rad!r}")
        cs = self._cos_sin(a[:1], a[1:])
        rows = np.eye(3)  # the frame's axes as rows while turning
        for ax, q in reversed(self._head_chain()):
            c, s = cs[q]
            rows = _rotate(rows, ax.vector, np.repeat(c, 3), np.repeat(s, 3))
        for ax, q in self._table_chain():
            c, s = cs[q]
            rows = _rotate(rows, ax.vector, np.repeat(c, 3), -np.repeat(s, 3))
        return rows.T.copy()

    def swivel_axes(self) -> tuple[int, int]:
        """Joint columns of a swivel data set's rotary axes 1 and 2 (Sinumerik's rule).

        Rotary axis 2 is carried by rotary axis 1; with a head and a table axis,
        axis 1 is the head's (the one that sets the tool orientation).
        Table-table: (tilt, rotary); head-head: (rotary, tilt); head-table:
        (tilt, rotary).
        """
        tilt, rot = self.axes
        if tilt.carrier == "head" and rot.carrier == "head":
            return 4, 3
        return 3, 4

    def inverse(self, tip: ArrayLike, axis: ArrayLike, *, free_rad: ArrayLike = 0.0,
                singular_cone_rad: float = K.SINGULAR_CONE_RAD) -> tuple[NDArray, NDArray]:
        """Both joint solutions for tool tips and axes in the workpiece frame.

        Parameters
        ----------
        tip : ndarray, shape (n, 3) or (3,) [mm]
        axis : ndarray, shape (n, 3) or (3,)
            Unit tool axes.
        free_rad : float or ndarray, shape (n,) [rad]
            Rotary-axis angle used inside the singular cone (the previous one).
        singular_cone_rad : float [rad]
            Half angle of the cone around the rotary axis inside which the
            rotary axis is held at ``free_rad`` and the tilt gives the best
            orientation (both solutions are then equal). 0: exactly on it only.

        Returns
        -------
        sol0, sol1 : ndarray, shape (n, 5) or (5,) [mm, mm, mm, rad, rad]
            Solution 0 has the larger tilt angle. Angles wrapped into
            [-pi, pi), then moved by 2 pi k into the limits where that fits.

        Raises
        ------
        KinematicsError
            A tool axis no rotary position gives (never for named machines).
        """
        w, single = _rows(tip, 3, "tip")
        u, _ = _unit_rows(axis, "axis")
        if len(u) != len(w):
            raise ValueError(f"tip and axis: {len(w)} and {len(u)} rows")
        free = np.broadcast_to(np.asarray(free_rad, dtype=float), (len(w),))
        if not np.isfinite(free).all():
            raise ValueError("free_rad: not finite")
        t0, c0, t1, c1 = self._solutions(u)
        sing = self._sin_free(u) <= math.sin(singular_cone_rad)
        if sing.any():
            t0[sing] = t1[sing] = self._held_tilt(u[sing], free[sing])
            c0[sing] = c1[sing] = free[sing]
        out = []
        for t, c in ((t0, c0), (t1, c1)):
            t, c = self._into_limits(t, 0), self._into_limits(c, 1)
            out.append(np.column_stack([self._xyz(w, t, c), t, c]))
        return (out[0][0], out[1][0]) if single else (out[0], out[1])

    def within_limits(self, joints: ArrayLike) -> NDArray[np.bool_]:
        """True where all five joints are inside their limits.

        Parameters
        ----------
        joints : ndarray, shape (n, 5) or (5,) [mm, mm, mm, rad, rad]

        Returns
        -------
        ndarray of bool, shape (n,) (a numpy bool for one row)
        """
        j, single = _rows(joints, 5, "joints")
        ok = self._linear_ok(j[:, :3])
        for q, ax in enumerate(self.axes):
            ok &= _between(j[:, 3 + q], ax.min_rad, ax.max_rad, K.LIMIT_TOL_RAD)
        return ok[0] if single else ok

    # ------------------------------------------------------------------ internals
    def _forward(self, j: NDArray, axis: bool = True) -> tuple[NDArray, NDArray | None]:
        """Tips [mm] and (if ``axis``) tool axes for checked joint rows (n, 5)."""
        cs = self._cos_sin(j[:, 3], j[:, 4])
        p, u = self._head(cs, len(j), axis)
        m = j[:, :3] + p
        for ax, q in self._table_chain():  # undo the table turns, base outward
            c, s = cs[q]
            piv = np.asarray(ax.pivot_mm)
            m = piv + _rotate(m - piv, ax.vector, c, -s)
            u = None if u is None else _rotate(u, ax.vector, c, -s)
        return m, u

    def _cos_sin(self, tilt: NDArray, rot: NDArray) -> list[tuple[NDArray, NDArray]]:
        """Cosine and sine of the body rotations (right-hand about the axis vectors)."""
        out = []
        for ax, a in zip(self.axes, (tilt, rot)):
            phi = a * ax.direction
            out.append((np.cos(phi), np.sin(phi)))
        return out

    def _table_chain(self) -> list[tuple[RotaryAxis, int]]:
        """Table axes from the machine base outward (tilt carries rotary), with column."""
        return [(a, q) for q, a in enumerate(self.axes) if a.carrier == "table"]

    def _head_chain(self) -> list[tuple[RotaryAxis, int]]:
        """Head axes from the carriage outward (rotary carries tilt), with column."""
        return [(a, q) for q, a in ((1, self.axes[1]), (0, self.axes[0]))
                if a.carrier == "head"]

    def _head(self, cs: list, n: int, axis: bool = True) -> tuple[NDArray, NDArray | None]:
        """Tip offset from the controlled point [mm] and tool axis, machine frame."""
        p = np.zeros((n, 3))
        u = np.broadcast_to(_Z, (n, 3)) if axis else None
        for ax, q in reversed(self._head_chain()):
            c, s = cs[q]
            piv = np.asarray(ax.pivot_mm) + self.tool_length_mm * _Z
            p = piv + _rotate(p - piv, ax.vector, c, s)
            u = None if u is None else _rotate(u, ax.vector, c, s)
        return p, u

    def _xyz(self, tip: NDArray, tilt: NDArray, rot: NDArray) -> NDArray:
        """Machine X Y Z [mm] putting the tip at ``tip`` (workpiece) at these angles."""
        cs = self._cos_sin(tilt, rot)
        m = tip
        for ax, q in reversed(self._table_chain()):
            piv = np.asarray(ax.pivot_mm)
            m = piv + _rotate(m - piv, ax.vector, *cs[q])
        if self._head_chain():
            m = m - self._head(cs, len(tip), axis=False)[0]
        return m

    def _sign(self, q: int) -> int:
        """Sign taking the machine angle to the angle in ``u = R(a_C, .) R(a_T, .) z``."""
        ax = self.axes[q]
        return ax.direction * (-1 if ax.carrier == "table" else 1)

    def _sin_free(self, u: NDArray) -> NDArray:
        """Sine of the angle between tool axes (workpiece frame) and the rotary axis."""
        return np.linalg.norm(np.cross(u, self.axes[1].vector), axis=1)

    def _solutions(self, u: NDArray) -> tuple[NDArray, NDArray, NDArray, NDArray]:
        """Exact (tilt, rotary) [rad] of both solutions, wrapped; solution 0 = larger tilt.

        ``R(a_T, b) z = v = R(a_C, -g) u``: ``v`` is on both cones
        ``a_T.v = a_T.z`` and ``a_C.v = a_C.u`` (Paden-Kahan subproblem 2).
        """
        at, ac = self.axes[0].vector, self.axes[1].vector
        k, p = float(at @ ac), float(at @ _Z)
        q = u @ ac
        den = 1.0 - k * k
        x, y = (p - k * q) / den, (q - k * p) / den
        w2 = (1.0 - x * x - y * y - 2.0 * x * y * k) / den
        bad = w2 < -K.REACH_TOL
        if bad.any():
            i = int(np.argmax(bad))
            raise KinematicsError(f"tool axis {u[i]} cannot be reached by machine "
                                  f"{self.name} at any rotary position", index=i)
        w = np.sqrt(np.clip(w2, 0.0, None))
        base = np.outer(x, at) + np.outer(y, ac)
        nrm = np.cross(at, ac)
        sols = []
        for sgn in (1.0, -1.0):
            v = base + np.outer(sgn * w, nrm)
            beta = _angle_about(at, np.broadcast_to(_Z, v.shape), v)
            gamma = _angle_about(ac, v, u)
            sols.append((_wrap(beta * self._sign(0)), _wrap(gamma * self._sign(1))))
        (t0, c0), (t1, c1) = sols
        swap = t1 > t0
        return (np.where(swap, t1, t0), np.where(swap, c1, c0),
                np.where(swap, t0, t1), np.where(swap, c0, c1))

    def _held_tilt(self, u: NDArray, rot: NDArray) -> NDArray:
        """Tilt [rad] of the orientation nearest ``u`` with the rotary axis at ``rot``."""
        g = rot * self._sign(1)
        v = _rotate(u, self.axes[1].vector, np.cos(g), -np.sin(g))
        beta = _angle_about(self.axes[0].vector, np.broadcast_to(_Z, v.shape), v)
        return _wrap(beta * self._sign(0))

    def _into_limits(self, a: NDArray, q: int) -> NDArray:
        """Shift angles by 2 pi k (k nearest 0) into the limits of axis ``q`` where one fits."""
        ax = self.axes[q]
        if not ax.limited:
            return a
        lo, hi = ax.min_rad - K.LIMIT_TOL_RAD, ax.max_rad + K.LIMIT_TOL_RAD
        klo = np.ceil((lo - a) / _TWO_PI) if math.isfinite(lo) else np.full_like(a, -np.inf)
        khi = np.floor((hi - a) / _TWO_PI) if math.isfinite(hi) else np.full_like(a, np.inf)
        k = np.where(klo <= khi, np.clip(0.0, klo, khi), 0.0)
        return a + _TWO_PI * k

    def _linear_ok(self, xyz: NDArray) -> NDArray:
        ok = np.ones(len(xyz), dtype=bool)
        for q, (lo, hi) in enumerate(self.linear_limits_mm):
            if math.isfinite(lo) or math.isfinite(hi):
                ok &= _between(xyz[:, q], lo, hi, K.LIMIT_TOL_MM)
        return ok
