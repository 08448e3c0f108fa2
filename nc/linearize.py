"""Linearization: points inserted where interpolated machine axes leave the line.

Between two points of a machine-axis program the control moves every axis
linearly. With rotary axes turning, the tool tip then follows a curve in the
workpiece frame, not the programmed straight line. :func:`linearize` inserts
points (tip on the line, axis by slerp, joints continuous with the
neighbours) until the deviation is below a tolerance. Re-exported by
:mod:`nc.kinematics`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import constants as K
from .errors import KinematicsError
from .machines import _TWO_PI, Machine, _rows, _unit_rows

__all__ = ["Linearized", "linearize"]


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
              singular_cone_rad: float = K.SINGULAR_CONE_RAD,
              max_points: int | None = None,
              joint_segments: ArrayLike | None = None) -> Linearized:
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
    max_points : int, optional
        Refuse to grow the path beyond this many points (default
        ``LINEARIZE_MAX_POINTS_PER_POINT`` per input point plus
        ``LINEARIZE_MAX_POINTS_EXTRA``). A path that needs more usually
        grazes the singularity with a noisy tool axis, so that the rotary
        axis swings between neighbours; a larger ``singular_cone_rad`` is the
        cure, not millions of points.
    joint_segments : ndarray of bool, shape (n - 1,), optional
        Segments (from point k to k + 1) whose inserted points take the rotary axes
        halfway between their neighbours' (the machine's own interpolation) instead of
        the axis by slerp: the tip still on the line. For rapid moves that turn the
        tool: a slerp passing near the free axis's pole swings the free axis through up
        to 180 deg within a sliver of the move, which no bisection depth straightens
        (the mold core's links turning from one flank's tilt to the other's), while
        interpolated angles turn it evenly over the whole move.

    Returns
    -------
    Linearized

    Raises
    ------
    KinematicsError
        When more than ``max_points`` points would be needed, naming the
        first input segment that asks for them.
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
    if max_points is None:
        max_points = K.LINEARIZE_MAX_POINTS_PER_POINT * n + K.LINEARIZE_MAX_POINTS_EXTRA
    src = np.arange(n, dtype=float)
    if n < 2:
        return Linearized(w, u, j, src, 0.0)
    jseg = (np.zeros(n - 1, bool) if joint_segments is None
            else np.asarray(joint_segments, bool).reshape(-1))
    if len(jseg) != n - 1:
        raise ValueError(f"joint_segments: expected {n - 1} entries, got {len(jseg)}")
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
        total = len(pts[0]) + sum(len(m[0]) for m in added) + int(bad.sum())
        if total > max_points:
            first = int(np.floor(a[3][bad].min()))
            raise KinematicsError(
                f"linearizing within {tol_mm:g} mm needs more than {max_points:,} points "
                f"(bisection depth {depth + 1}); the rotary axes swing between neighbouring "
                "points, typically near the singularity with a noisy tool axis: raise "
                "singular_cone_rad or smooth the tool axes", index=first)
        a = tuple(x[bad] for x in a)
        b = tuple(x[bad] for x in b)
        mid = _midpoint(machine, a, b, singular_cone_rad,
                        jseg[np.clip(np.floor(a[3]).astype(int), 0, n - 2)])
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
              cone: float, joint: NDArray | None = None) -> tuple[NDArray, ...]:
    """Point halfway along each segment: tip, axis (slerp; where ``joint``, the rotary
    axes halfway instead), joints, source, sort key."""
    tip = 0.5 * (a[0] + b[0])
    if joint is not None and joint.any():
        out = _midpoint(machine, tuple(x[~joint] for x in a), tuple(x[~joint] for x in b),
                        cone) if (~joint).any() else None
        rot = 0.5 * (a[2][joint, 3:] + b[2][joint, 3:])
        jm = np.column_stack([machine._xyz(tip[joint], rot[:, 0], rot[:, 1]), rot])
        ax = machine._forward(jm)[1]
        res = [np.zeros((len(tip), 3)), np.zeros((len(tip), 3)), np.zeros((len(tip), 5)),
               0.5 * (a[3] + b[3]), 0.5 * (a[4] + b[4])]
        res[0] = tip
        res[1][joint], res[2][joint] = ax, jm
        if out is not None:
            res[1][~joint], res[2][~joint] = out[1], out[2]
        return tuple(res)
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
