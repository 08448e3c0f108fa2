"""5-axis machine kinematics: machines, forward/inverse, path solving, linearization.

The machine model (:class:`RotaryAxis`, :class:`Machine`) and machine files
(:func:`load_machine`, :func:`machine_to_toml`) are written in
:mod:`nc.machines` and re-exported here; use them from here.

Named machines (:data:`MACHINES`, :func:`get_machine`)::

    name                tilt axis (column 3)          rotary axis (column 4)
    xyzac-trt           A about X, table (trunnion)   C about Z, table, carried by A
    xyzbc-trt           B about Y, table (trunnion)   C about Z, table, carried by B
    xyzbc-head-table    B about Y, head               C about Z, table
    xyzbc-head-head     B about Y, head, carried by C C about Z, head

(aliases ``head-table-bc``, ``head-head-bc``). Defaults: table pivots at the
origin, head pivots at the spindle gauge point, tool length 0, tilt
+-90 deg, C and linear axes unlimited, directions +1. Give the real values.

Conventions
-----------
Units: mm and radians. Joint rows are ``(x, y, z, tilt, rotary)``
[mm, mm, mm, rad, rad]; :attr:`Machine.rotary_names` gives the letters of the
last two columns (``("A", "C")`` or ``("B", "C")``).

*Mechanism.* One general mechanism covers every machine: three linear axes
and ``axes = (tilt, rotary)``, two rotary axes, each carried by the
``"table"`` (it turns the workpiece) or the ``"head"`` (it turns the spindle).
Along the chain from the workpiece to the tool the rotary axis always comes
before the tilt axis::

    table-table  workpiece - rotary - tilt - machine base - tool   (trunnion carries the C table)
    head-table   workpiece - rotary - machine base - tilt - tool
    head-head    workpiece - machine base - rotary - tilt - tool   (C turns the tilting head)

Seen from the workpiece the tool axis is ``u = R(a_C, γ) R(a_T, β) z``
(``β``, ``γ`` the body rotations, negated for table axes), so the machine
is singular where ``u`` is parallel to the rotary axis: the rotary axis (C)
is then the *free* axis. For all named machines that is tilt = 0 (tool along
+Z in the workpiece frame at C = anything).

*Frames.* The workpiece frame is the machine frame with both rotary axes at
0. Table pivots [mm] are points on the table axes in that frame. Head pivots
[mm] are measured from the spindle gauge point (the spindle nose, from which
tool lengths are measured) at zero posture; the pivot relative to the tool
tip is ``pivot_mm + (0, 0, tool_length_mm)``, so a tool change is the one
field :attr:`Machine.tool_length_mm`. Machine XYZ is the controlled point: the
tool tip in the machine frame with the head at zero rotation (tool-length
compensated, as LinuxCNC with G43). The tool axis ``u`` is the unit vector
from the tip toward the spindle; at zero posture ``u = +Z``. Table-table
machines keep the tool along machine +Z.

*Signs.* Machine angle = ``direction`` x (right-hand rotation angle of the
carried body -- the workpiece for a table axis, the spindle for a head axis --
about the axis vector, +X/+Y/+Z for the named machines). ``direction = +1``
is LinuxCNC's xyzac-trt / xyzbc-trt formula (the table turns right-handed
for a positive angle) and is the default of every named machine. ISO 841
names the motion of the tool relative to the workpiece: ``direction = -1``
for a table axis.

*Solutions.* Away from the singularity :meth:`Machine.inverse` returns two
solutions, solution 0 with the larger tilt angle (for the named machines
``(t, c)`` and ``(-t, c + pi)``, ``t > 0``). Angles are wrapped into
``[-pi, pi)`` and shifted by ``2 pi k`` into the axis limits when a multiple
fits (the one nearest 0). Inside the singular cone (tool axis within
``singular_cone_rad`` of the rotary axis line, either sense) both solutions hold the rotary axis
at the given value and take the tilt of the best orientation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial
from typing import Any, Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import constants as K
from .errors import KinematicsError
from .machines import (_TWO_PI, _UNLIMITED, Machine, RotaryAxis, _angle_between, _between,
                       _rows, _unit_rows, _wrap, load_machine, machine_to_toml)

__all__ = ["RotaryAxis", "Machine", "PathSolution", "Linearized", "solve_path", "linearize",
           "MACHINES", "get_machine", "load_machine", "machine_to_toml",
           "linuxcnc_trt_machine"]


# --------------------------------------------------------------------------- named machines
_DEG = math.pi / 180.0
_TILT_LIMITS_RAD = (-90.0 * _DEG, 90.0 * _DEG)

#: kind -> (tilt letter, tilt about, tilt carrier, rotary carrier)
_KINDS = {
    "xyzac-trt": ("A", "x", "table", "table"),
    "xyzbc-trt": ("B", "y", "table", "table"),
    "xyzbc-head-table": ("B", "y", "head", "table"),
    "xyzbc-head-head": ("B", "y", "head", "head"),
}
_ALIASES = {"head-table-bc": "xyzbc-head-table", "head-head-bc": "xyzbc-head-head"}


def _named(kind: str, *, name: str | None = None, tool_length_mm: float = 0.0,
           tilt_pivot_mm: tuple[float, float, float] = (0.0, 0.0, 0.0),
           rotary_pivot_mm: tuple[float, float, float] = (0.0, 0.0, 0.0),
           tilt_direction: int = 1, rotary_direction: int = 1,
           tilt_limits_rad: tuple[float, float] = _TILT_LIMITS_RAD,
           rotary_limits_rad: tuple[float, float] = _UNLIMITED,
           linear_limits_mm: tuple[tuple[float, float], ...] = (_UNLIMITED,) * 3,
           ) -> Machine:
    """Named machine ``kind`` (a key of :data:`MACHINES`); keywords: :func:`get_machine`."""
    letter, about, tilt_carrier, rot_carrier = _KINDS[kind]
    tilt = RotaryAxis(letter, about, tilt_carrier, tuple(tilt_pivot_mm), tilt_direction,
                      *tilt_limits_rad)
    rot = RotaryAxis("C", "z", rot_carrier, tuple(rotary_pivot_mm), rotary_direction,
                     *rotary_limits_rad)
    return Machine(name or kind, (tilt, rot), tool_length_mm, tuple(linear_limits_mm))


#: Named machine factories; each takes the keywords of :func:`get_machine`.
MACHINES: dict[str, Callable[..., Machine]] = {k: partial(_named, k) for k in _KINDS}


def get_machine(name: str, /, **overrides: Any) -> Machine:
    """A named machine, with geometry overrides.

    Parameters
    ----------
    name : str
        ``xyzac-trt``, ``xyzbc-trt``, ``xyzbc-head-table`` (alias
        ``head-table-bc``) or ``xyzbc-head-head`` (alias ``head-head-bc``).
    name : str, optional (keyword; the kind above is positional)
        Machine name; default the kind.
    tool_length_mm : float [mm]
        Tool gauge length (spindle nose to tip).
    tilt_pivot_mm, rotary_pivot_mm : tuple of 3 float [mm]
        Points on the tilt / rotary axis at zero posture (table axis:
        workpiece frame; head axis: from the spindle gauge point).
    tilt_direction, rotary_direction : int
        +1 or -1 (see "Signs" above).
    tilt_limits_rad, rotary_limits_rad : tuple of 2 float [rad]
        (min, max) travel; +-inf for unlimited.
    linear_limits_mm : tuple of 3 (min, max) [mm]
        X, Y, Z travel.

    Returns
    -------
    Machine
    """
    kind = _ALIASES.get(name, name)
    if kind not in MACHINES:
        raise ValueError(f"unknown machine {name!r}; known: {', '.join(MACHINES)}")
    return MACHINES[kind](**overrides)


def linuxcnc_trt_machine(kins: str, *, x_rot_point: float = 0.0, y_rot_point: float = 0.0,
                         z_rot_point: float = 0.0, x_offset: float = 0.0,
                         y_offset: float = 0.0, z_offset: float = 0.0,
                         **overrides: Any) -> Machine:
    """The machine of LinuxCNC's ``xyzac-trt-kins`` / ``xyzbc-trt-kins`` pins [mm].

    LinuxCNC (src/emc/kinematics/trtfuncs.c) turns C about the vertical line
    through (x-rot-point, y-rot-point) and A about the X-parallel line through
    (y-rot-point + y-offset, z-rot-point + z-offset) (B: the Y-parallel line
    through (x-rot-point + x-offset, z-rot-point + z-offset)), both
    right-handed for positive angles (direction +1). Its joints equal ours when
    the ``tool-offset`` pin is 0 (tool length applied by G43): its world
    position is then our tool tip in the workpiece frame.

    Parameters
    ----------
    kins : str
        ``"xyzac-trt"`` or ``"xyzbc-trt"`` (a ``-kins`` suffix is accepted).
    x_rot_point, y_rot_point, z_rot_point, x_offset, y_offset, z_offset : float [mm]
        The HAL pin values (``x_offset`` is used by xyzbc only, ``y_offset``
        by xyzac only).
    **overrides
        Further keywords of :func:`get_machine` (limits, directions, name).

    Returns
    -------
    Machine
    """
    kind = kins.removesuffix("-kins")
    rot = (x_rot_point, y_rot_point, z_rot_point)
    if kind == "xyzac-trt":
        tilt = (x_rot_point, y_rot_point + y_offset, z_rot_point + z_offset)
    elif kind == "xyzbc-trt":
        tilt = (x_rot_point + x_offset, y_rot_point, z_rot_point + z_offset)
    else:
        raise ValueError(f"kins: expected 'xyzac-trt' or 'xyzbc-trt', got {kins!r}")
    return get_machine(kind, tilt_pivot_mm=tilt, rotary_pivot_mm=rot, **overrides)


# --------------------------------------------------------------------------- path solver
@dataclass(frozen=True, eq=False)
class PathSolution:
    """Machine joints along a path.

    Parameters
    ----------
    joints : ndarray, shape (n, 5) [mm, mm, mm, rad, rad]
        Rotary angles unwrapped (continuous, may pass +-360 deg).
    singular : ndarray of bool, shape (n,)
        Inside the singular cone: the rotary (free) axis was held.
    orientation_error_rad : ndarray, shape (n,) [rad]
        Angle between the reached and the programmed tool axis; 0 outside
        the singular cone.
    jump : ndarray of bool, shape (n,)
        The rotary axes change discontinuously from point i-1 to i: a branch
        flip (or rewind) inside the singular cone, which keeps the
        orientation and which :func:`linearize` spreads over inserted
        points, or, only with ``allow_jumps``, a jump anywhere.
    """

    joints: NDArray
    singular: NDArray
    orientation_error_rad: NDArray
    jump: NDArray


def solve_path(machine: Machine, tip: ArrayLike, axis: ArrayLike, *,
               start: ArrayLike | None = None,
               singular_cone_rad: float = K.SINGULAR_CONE_RAD,
               allow_jumps: bool = False) -> PathSolution:
    """Continuous machine joints for a tool path, inside the axis limits.

    Both inverse solutions of every point are paired with those of the next
    point by least rotary motion, giving two continuous tracks; rotary angles
    are unwrapped along them (no 359 -> 0 deg jumps) and shifted by ``2 pi k``
    where the limits allow. The path follows one track, chosen continuous with
    ``start`` (else the one staying inside the limits longest, then nearest
    0). Inside the singular cone the rotary axis is held at its previous
    value (never spun) and the tilt gives the best orientation. When the
    followed track leaves the limits, the path flips to another track (or
    2 pi multiple) inside the last singular cone before, where that costs no
    orientation; otherwise it fails (or, with ``allow_jumps``, jumps).

    Parameters
    ----------
    machine : Machine
    tip : ndarray, shape (n, 3) [mm]
        Tool tips, workpiece frame.
    axis : ndarray, shape (n, 3)
        Unit tool axes, workpiece frame.
    start : ndarray, shape (5,) [mm, mm, mm, rad, rad], optional
        Joints before the first point (continuity and the held free axis).
    singular_cone_rad : float [rad]
        Half angle of the cone around the rotary axis where it is held.
    allow_jumps : bool
        Accept a discontinuous jump to the other solution outside the
        singular cone (e.g. across a rapid move) instead of failing.

    Returns
    -------
    PathSolution

    Raises
    ------
    KinematicsError
        ``index`` = the first point not reachable within the limits by a
        continuous motion; the message says which limit and why.
    """
    w, _ = _rows(tip, 3, "tip")
    u, _ = _unit_rows(axis, "axis")
    n = len(w)
    if len(u) != n:
        raise ValueError(f"tip and axis: {n} and {len(u)} rows")
    s0 = None if start is None else _rows(start, 5, "start")[0]
    if s0 is not None and s0.shape[0] != 1:
        raise ValueError("start: expected shape (5,)")
    s0 = None if s0 is None else s0[0]
    if n == 0:
        z = np.zeros(0)
        return PathSolution(np.zeros((0, 5)), z.astype(bool), z, z.astype(bool))
    sinf = machine._sin_free(u)
    sing = sinf <= math.sin(singular_cone_rad)
    t0, c0, t1, c1 = machine._solutions(u)
    if sing.any():
        _hold_singular(machine, u, sing, s0, t0, c0, t1, c1)
    tr = _tracks(np.stack([t0, c0], 1), np.stack([t1, c1], 1), sing)
    xyz = np.stack([machine._xyz(w, tr[b, :, 0], tr[b, :, 1]) for b in (0, 1)])
    walk = _Walk(machine, tr, xyz, sing, sinf)
    segs, jump = walk.run(s0, allow_jumps)
    joints = np.empty((n, 5))
    for a, b, (tb, kt, kc) in segs:
        joints[a:b, :3] = xyz[tb, a:b]
        joints[a:b, 3:] = tr[tb, a:b] + _TWO_PI * np.array([kt, kc])
    err = np.zeros(n)
    if sing.any():
        err[sing] = _angle_between(machine.forward(joints[sing])[1], u[sing])
    return PathSolution(joints, sing, err, jump)


def _hold_singular(machine: Machine, u: NDArray, sing: NDArray, s0: NDArray | None,
                   t0: NDArray, c0: NDArray, t1: NDArray, c1: NDArray) -> None:
    """Overwrite both solutions at singular points: rotary held, best tilt (in place)."""
    n = len(u)
    ns = ~sing
    pre = np.maximum.accumulate(np.where(ns, np.arange(n), -1))
    h0, h1 = c0[np.maximum(pre, 0)], c1[np.maximum(pre, 0)]
    lead = pre < 0
    if lead.any():  # singular before any regular point: start, else the first regular one
        if s0 is not None:
            h0[lead], h1[lead] = s0[4], s0[4] + math.pi
        elif ns.any():
            f = int(np.argmax(ns))
            h0[lead], h1[lead] = c0[f], c1[f]
        else:
            h0[lead], h1[lead] = 0.0, math.pi
    t0[sing] = machine._held_tilt(u[sing], h0[sing])
    t1[sing] = machine._held_tilt(u[sing], h1[sing])
    c0[sing], c1[sing] = h0[sing], h1[sing]


def _tracks(a: NDArray, b: NDArray, sing: NDArray) -> NDArray:
    """Two continuous tracks (2, n, 2) of (tilt, rotary), unwrapped [rad]."""
    def d(p: NDArray, q: NDArray) -> NDArray:
        return np.abs(_wrap(p - q)).sum(axis=1)
    stay = d(a[1:], a[:-1]) + d(b[1:], b[:-1])
    swap = d(a[1:], b[:-1]) + d(b[1:], a[:-1])
    sw = (swap < stay) & ~sing[1:]  # a singular point continues its own held track
    lab = np.concatenate([[False], np.cumsum(sw) % 2 == 1])[:, None]
    tr = np.stack([np.where(lab, b, a), np.where(lab, a, b)])
    return np.unwrap(tr, axis=1)


class _Walk:
    """Follow one track (with 2 pi offsets) and switch where it leaves the limits."""

    def __init__(self, machine: Machine, tr: NDArray, xyz: NDArray, sing: NDArray,
                 sinf: NDArray) -> None:
        self.m, self.tr, self.xyz, self.sinf = machine, tr, xyz, sinf
        self.n = tr.shape[1]
        self.sing_idx = np.flatnonzero(sing)
        self.lin_ok = [machine._linear_ok(xyz[b]) for b in (0, 1)]
        self._bad: dict[tuple[int, int, int], NDArray] = {}

    def angles(self, c: tuple[int, int, int], i: int) -> NDArray:
        return self.tr[c[0], i] + _TWO_PI * np.array(c[1:], dtype=float)

    def joints(self, c: tuple[int, int, int], i: int) -> NDArray:
        return np.concatenate([self.xyz[c[0], i], self.angles(c, i)])

    def badcum(self, c: tuple[int, int, int]) -> NDArray:
        """Cumulative count of out-of-limit points of candidate ``c`` (n + 1,)."""
        if c not in self._bad:
            ang = self.tr[c[0]] + _TWO_PI * np.array(c[1:], dtype=float)
            ok = self.lin_ok[c[0]].copy()
            for q, ax in enumerate(self.m.axes):
                if ax.limited:
                    ok &= _between(ang[:, q], ax.min_rad, ax.max_rad, K.LIMIT_TOL_RAD)
            self._bad[c] = np.concatenate([[0], np.cumsum(~ok)])
        return self._bad[c]

    def ok_on(self, c: tuple[int, int, int], a: int, b: int) -> bool:
        """Candidate ``c`` inside the limits on points [a, b) (point a checked first)."""
        if c not in self._bad:  # cheap test of one point before a whole-path mask
            ang = self.angles(c, a)
            if not self.lin_ok[c[0]][a] or not all(
                    _between(ang[q], ax.min_rad, ax.max_rad, K.LIMIT_TOL_RAD)
                    for q, ax in enumerate(self.m.axes)):
                return False
            if b == a + 1:
                return True
        bc = self.badcum(c)
        return bool(bc[b] == bc[a])

    def first_bad(self, c: tuple[int, int, int], a: int) -> int:
        bc = self.badcum(c)
        return int(np.searchsorted(bc, bc[a] + 1, side="left")) - 1  # n when none

    def near(self, i: int, ref: NDArray) -> list[tuple[int, int, int]]:
        """Candidates (track, k_tilt, k_rot) at point i around the angles ``ref``."""
        out = []
        for b in (0, 1):
            k0 = np.round((ref - self.tr[b, i]) / _TWO_PI).astype(int)
            ks = [[int(k0[q]) + d for d in ((-1, 0, 1) if ax.limited else (0,))]
                  for q, ax in enumerate(self.m.axes)]
            out += [(b, kt, kc) for kt in ks[0] for kc in ks[1]]
        return out

    def dist(self, c: tuple[int, int, int], i: int, ref: NDArray) -> float:
        return float(np.abs(self.angles(c, i) - ref).sum())

    def run(self, s0: NDArray | None, allow_jumps: bool) -> tuple[list, NDArray]:
        n = self.n
        ref = np.zeros(2) if s0 is None else s0[3:]
        cands = [c for c in self.near(0, ref) if self.ok_on(c, 0, 1)]
        if not cands:
            raise KinematicsError(self._fail(0, None), index=0)
        if s0 is None:
            cur = min(cands, key=lambda c: (-self.first_bad(c, 0), self.dist(c, 0, ref), c))
        else:
            cur = min(cands, key=lambda c: (self.dist(c, 0, ref), -self.first_bad(c, 0), c))
        segs: list = []
        jump = np.zeros(n, dtype=bool)
        i = 0
        while True:
            j = self.first_bad(cur, i)
            if j >= n:
                segs.append((i, n, cur))
                return segs, jump
            new = self._flip(cur, i, j)
            if new is None and allow_jumps:
                ref = self.angles(cur, j - 1)
                opts = [c for c in self.near(j, ref) if self.ok_on(c, j, j + 1)]
                if opts:
                    new = (j, min(opts, key=lambda c: (self.dist(c, j, ref),
                                                       -self.first_bad(c, j))))
            if new is None:
                raise KinematicsError(self._fail(j, cur), index=j)
            s, nxt = new
            segs.append((i, s, cur))
            jump[s] = True
            i, cur = s, nxt

    def _flip(self, cur: tuple[int, int, int], i: int, j: int) -> tuple | None:
        """Switch candidate inside a singular cone in (i, j] covering j, or None."""
        si = self.sing_idx
        si = si[(si > i) & (si <= j)]
        if si.size == 0:
            return None
        order = np.lexsort((-si, self.sinf[si]))  # closest to the axis first, then latest
        for s in si[order][:K.SINGULAR_FLIP_TRIES]:
            ref = self.angles(cur, s - 1)
            opts = [c for c in self.near(s, ref) if c != cur and self.ok_on(c, s, j + 1)]
            if opts:
                return s, min(opts, key=lambda c: (-self.first_bad(c, s), self.dist(c, s, ref)))
        return None

    def _fail(self, j: int, cur: tuple[int, int, int] | None) -> str:
        m = self.m
        if cur is None:
            parts = [_violations(m, self.joints(c, j)) for c in
                     (min((c for c in self.near(j, np.zeros(2)) if c[0] == b),
                          key=lambda c: self.dist(c, j, np.zeros(2))) for b in (0, 1))]
            return (f"no solution within the limits of machine {m.name}: solution 1: "
                    f"{parts[0]}; solution 2: {parts[1]}")
        ref = self.angles(cur, j - 1)
        msg = (f"the solution continuous with point {j - 1} leaves the limits of machine "
               f"{m.name}: {_violations(m, self.joints(cur, j))}")
        opts = [c for c in self.near(j, ref) if self.ok_on(c, j, j + 1)]
        if opts:
            c = min(opts, key=lambda c: self.dist(c, j, ref))
            deg = np.degrees(self.angles(c, j))
            msg += (f"; another solution ({m.axes[0].name} = {deg[0]:.4f} deg, "
                    f"{m.axes[1].name} = {deg[1]:.4f} deg) is within the limits but needs "
                    f"a jump of {math.degrees(self.dist(c, j, ref)):.2f} deg of rotary "
                    "motion and no singular point before allows a flip (allow_jumps=True "
                    "accepts the jump, e.g. across a retract)")
        else:
            other = min((c for c in self.near(j, ref) if c[0] != cur[0]),
                        key=lambda c: self.dist(c, j, ref))
            msg += f"; the other solution too: {_violations(m, self.joints(other, j))}"
        return msg


def _violations(machine: Machine, joints: NDArray) -> str:
    """The limits one joint row (5,) [mm, rad] violates, in words."""
    out = []
    for q, (lo, hi) in enumerate(machine.linear_limits_mm):
        if not lo - K.LIMIT_TOL_MM <= joints[q] <= hi + K.LIMIT_TOL_MM:
            out.append(f"{'XYZ'[q]} = {joints[q]:.4f} mm outside [{lo:g}, {hi:g}] mm")
    for q, ax in enumerate(machine.axes):
        if not ax.min_rad - K.LIMIT_TOL_RAD <= joints[3 + q] <= ax.max_rad + K.LIMIT_TOL_RAD:
            out.append(f"{ax.name} = {math.degrees(joints[3 + q]):.4f} deg outside "
                       f"[{math.degrees(ax.min_rad):g}, {math.degrees(ax.max_rad):g}] deg")
    return ", ".join(out) or "within limits"


# --------------------------------------------------------------------------- linearization
@dataclass(frozen=True, eq=False)
class Linearized:
    """A path with points inserted so that linear axis motion stays on the line.

    Parameters
    ----------
    tip : ndarray, shape (m, 3) [mm]
    axis : ndarray, shape (m, 3)
    joints : ndarray, shape (m, 5) [mm, mm, mm, rad, rad]
    source : ndarray, shape (m,)
        Fractional index into the input path of each point (input point k
        has ``k``; a point inserted halfway between k and k+1 has k + 0.5).
        Nondecreasing; repeated where the rotary axis turns at a fixed
        singular point (a flip, see :attr:`PathSolution.jump`).
    max_deviation_mm : float [mm]
        Largest deviation left (above ``tol_mm`` only if ``max_depth`` was hit).
    """

    tip: NDArray
    axis: NDArray
    joints: NDArray
    source: NDArray
    max_deviation_mm: float


def linearize(machine: Machine, tip: ArrayLike, axis: ArrayLike, joints: ArrayLike, *,
              tol_mm: float = K.LINEARIZE_TOL_MM, max_depth: int = K.LINEARIZE_MAX_DEPTH,
              singular_cone_rad: float = K.SINGULAR_CONE_RAD) -> Linearized:
    """Insert points where linear joint motion takes the tip off the programmed line.

    Between consecutive points the control moves all five joints linearly.
    The tip deviation from the programmed segment is estimated from
    ``LINEARIZE_CHECKS`` interior fractions of every segment
    (``LINEARIZE_CHECKS_BISECTED`` of each half made by bisection), vectorized
    over all segments; segments over ``tol_mm`` (less ``LINEARIZE_MARGIN``
    for the sampling) are bisected -- tip at the middle, axis by slerp, joints
    from the inverse nearest the mean of the neighbours, the free axis at
    their mean inside the singular cone -- up to ``max_depth`` times. A flip
    onto a singular point first gets a segment of its own (the point repeated
    with the rotary axis held), which bisection then spreads. Cost: about
    1.5 us per input point and 2 us per inserted point.

    Parameters
    ----------
    machine : Machine
    tip : ndarray, shape (n, 3) [mm]
    axis : ndarray, shape (n, 3)
        Unit tool axes.
    joints : ndarray, shape (n, 5) [mm, mm, mm, rad, rad]
        Continuous joints of the points, e.g. :func:`solve_path` output.
    tol_mm : float [mm]
        Largest allowed deviation.
    max_depth : int
        Largest number of bisections of one input segment.
    singular_cone_rad : float [rad]
        As in :func:`solve_path`, for the inserted points.

    Returns
    -------
    Linearized
    """
    w, _ = _rows(tip, 3, "tip")
    u, _ = _unit_rows(axis, "axis")
    j, _ = _rows(joints, 5, "joints")
    n = len(w)
    if len(u) != n or len(j) != n:
        raise ValueError(f"tip, axis, joints: {n}, {len(u)}, {len(j)} rows")
    if not (math.isfinite(tol_mm) and tol_mm > 0):
        raise ValueError(f"tol_mm: expected a positive number, got {tol_mm!r}")
    if int(max_depth) != max_depth or max_depth < 0:
        raise ValueError(f"max_depth: expected an integer >= 0, got {max_depth!r}")
    src = np.arange(n, dtype=float)
    if n < 2:
        return Linearized(w, u, j, src, 0.0)
    pts = _split_flips(machine, w, u, j, src, singular_cone_rad)
    pts = (*pts, np.arange(len(pts[0]), dtype=float))  # + sort key
    a = tuple(x[:-1] for x in pts)
    b = tuple(x[1:] for x in pts)
    added: list[tuple[NDArray, ...]] = []
    worst = 0.0
    for depth in range(int(max_depth) + 1):
        checks = K.LINEARIZE_CHECKS if depth == 0 else K.LINEARIZE_CHECKS_BISECTED
        fr = np.arange(1, checks + 1) / (checks + 1)
        dev = _deviation(machine, a[0], b[0], a[2], b[2], fr)
        bad = dev > tol_mm * (1.0 - K.LINEARIZE_MARGIN)
        if depth == max_depth or not bad.any():
            worst = max(worst, float(dev.max(initial=0.0)))
            break
        worst = max(worst, float(dev[~bad].max(initial=0.0)))
        a = tuple(x[bad] for x in a)
        b = tuple(x[bad] for x in b)
        mid = _midpoint(machine, a, b, singular_cone_rad)
        added.append(mid)
        a, b = (tuple(np.concatenate([x, y]) for x, y in zip(a, mid)),
                tuple(np.concatenate([x, y]) for x, y in zip(mid, b)))
    cat = [np.concatenate([p[q] for p in [pts, *added]]) for q in range(5)]
    order = np.argsort(cat[4], kind="stable")
    return Linearized(*(c[order] for c in cat[:4]), max_deviation_mm=worst)


def _split_flips(machine: Machine, w: NDArray, u: NDArray, j: NDArray, src: NDArray,
                 cone: float) -> tuple[NDArray, ...]:
    """Give the rotary jump (flip) onto a singular point a segment of its own.

    Next to a singular point reached from a regular neighbour by a rotary jump,
    insert the same point with the rotary axis held at the neighbour's value:
    the jump then turns the rotary axis at a fixed tip and orientation between
    two singular points, where bisection spreads it.
    """
    n = len(w)
    sing = machine._sin_free(u) <= math.sin(cone)
    pos, new = [], []
    for e, nb, after in ((np.arange(1, n), np.arange(n - 1), 0),
                         (np.arange(n - 1), np.arange(1, n), 1)):
        sel = sing[e] & ~sing[nb]  # e singular, nb its regular neighbour
        if not sel.any():
            continue
        e, nb = e[sel], nb[sel]
        hold = j[nb, 4]
        tilt = machine._held_tilt(u[e], hold)
        tilt += _TWO_PI * np.round((j[nb, 3] - tilt) / _TWO_PI)
        alt = np.column_stack([machine._xyz(w[e], tilt, hold), tilt, hold])
        gain = (np.abs(j[e, 3:] - j[nb, 3:]).sum(axis=1)
                - np.abs(alt[:, 3:] - j[nb, 3:]).sum(axis=1))
        keep = (gain > K.FLIP_TOL_RAD) & machine.within_limits(alt)
        pos.append(e[keep] + after)
        new.append((w[e[keep]], u[e[keep]], alt[keep], src[e[keep]]))
    if not pos or not np.concatenate(pos).size:
        return w, u, j, src
    at = np.concatenate(pos)
    return tuple(np.insert(x, at, np.concatenate([p[q] for p in new]), axis=0)
                 for q, x in enumerate((w, u, j, src)))


def _deviation(machine: Machine, wa: NDArray, wb: NDArray, ja: NDArray, jb: NDArray,
               fr: NDArray) -> NDArray:
    """Largest distance [mm] of the tip from segment wa-wb under linear joint motion.

    Sampled at the fractions ``fr`` (evenly spaced), refined by the vertex of
    the parabola through the largest sample and its neighbours.
    """
    m = len(wa)
    jf = ja[None] + fr[:, None, None] * (jb - ja)[None]
    p = machine._forward(jf.reshape(-1, 5), axis=False)[0].reshape(len(fr), m, 3)
    d = wb - wa
    l2 = np.einsum("ij,ij->i", d, d)
    t = np.einsum("fij,ij->fi", p - wa, d) / np.where(l2 > 0, l2, 1.0)
    t = np.clip(t, 0.0, 1.0)
    y = np.zeros((len(fr) + 2, m))  # deviation at 0, fr..., 1 (the ends are exact)
    y[1:-1] = np.linalg.norm(p - (wa + t[..., None] * d), axis=2)
    i = np.clip(np.argmax(y, axis=0), 1, len(fr))[None]
    y0, y1, y2 = (np.take_along_axis(y, i + k, axis=0)[0] for k in (-1, 0, 1))
    curv = y0 - 2.0 * y1 + y2  # peak of the parabola through the largest sample
    peak = y1 - (y2 - y0) ** 2 / (8.0 * np.where(curv < 0.0, curv, -1.0))
    return np.where(curv < 0.0, np.maximum(peak, y1), y1)


def _midpoint(machine: Machine, a: Sequence[NDArray], b: Sequence[NDArray],
              cone: float) -> tuple[NDArray, ...]:
    """Point halfway along each segment: tip, axis (slerp), joints, source, sort key."""
    tip = 0.5 * (a[0] + b[0])
    s = a[1] + b[1]  # slerp at 1/2 = normalized sum
    ns = np.linalg.norm(s, axis=1)
    if (ns < K.UNIT_VECTOR_TOL).any():
        i = int(np.argmax(ns < K.UNIT_VECTOR_TOL))
        raise ValueError(f"axis: opposite tool axes at source {a[3][i]:g} and {b[3][i]:g}; "
                         "no rotation between them is defined")
    ax = s / ns[:, None]
    ref = 0.5 * (a[2] + b[2])
    sols = machine.inverse(tip, ax, free_rad=ref[:, 4], singular_cone_rad=cone)
    best, best_d = None, None
    for sol in sols:
        sol = sol.copy()
        sol[:, 3:] += _TWO_PI * np.round((ref[:, 3:] - sol[:, 3:]) / _TWO_PI)
        dist = np.abs(sol[:, 3:] - ref[:, 3:]).sum(axis=1)
        if best is None:
            best, best_d = sol, dist
        else:
            best = np.where((dist < best_d)[:, None], sol, best)
    return tip, ax, best, 0.5 * (a[3] + b[3]), 0.5 * (a[4] + b[4])
