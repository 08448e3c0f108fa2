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

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import constants as K
from .errors import KinematicsError
from .linearize import Linearized, linearize
from .machines import (
    _TWO_PI,
    Machine,
    RotaryAxis,
    _angle_between,
    _between,
    _rows,
    _unit_rows,
    _wrap,
)
from .machine_files import load_machine, machine_to_toml
from .named_machines import MACHINES, get_machine, linuxcnc_trt_machine, machine_kind

__all__ = ["RotaryAxis", "Machine", "PathSolution", "Linearized", "solve_path", "linearize",
           "MACHINES", "get_machine", "machine_kind", "load_machine", "machine_to_toml",
           "linuxcnc_trt_machine"]


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
