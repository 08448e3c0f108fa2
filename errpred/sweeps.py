"""The volumes swept by the tool along a program, and a spatial index over them.

``docs/method.md`` §3: whether material is present at a point is known from
the stock and the sweeps of the motion before (T1) or after (T2) a cutter
location; no global model of the workpiece is kept. A :class:`Sweeps` holds
one entry per straight move with a constant tool axis (5-axis moves are
split where the axis turns by more than ``SWEEP_AXIS_STEP_RAD``, each piece
following the real motion at the centre of the tool's corner; a turning
move whose turn does not go on into the next move, as before a rapid, also
gets the tool standing at its end, with the end's exact axis), the
cumulative tool-tip path length at its start and end (so T1/T2 are path
intervals), its axis-aligned bounds, and a uniform grid over the bounds so
that a query near a point costs the same whether the program has 10^3 or
10^6 blocks.

Rapid moves (G0) are not sweeps: a rapid through material is a crash, not a
cut, and is not modelled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from nc.path import CutterLocations

from . import constants as K
from ._cluster_kernels import read_only
from ._kernels import inside_any_sweep, sweep_distance, sweeps_within
from ._sort_kernels import argsort_stable, compress, grown, take
from .tool import Tool

#: ``inside_any_sweep`` and ``sweep_distance`` (numba, usable inside other
#: numba kernels) are the swept tool solid's membership and distance, public
#: here for the packages above errpred.
__all__ = ["BlockLookup", "Sweeps", "build_sweeps", "inside_any_sweep", "read_only", "slerp",
           "sweep_distance"]


def _cylinder_bounds(p: np.ndarray, w: np.ndarray, height: float, radius: float):
    """AABB of cylinders from p to p + height w with the given radius, (n,3) each."""
    q = p + height * w
    ext = radius * np.sqrt(np.clip(1.0 - w * w, 0.0, None))
    return np.minimum(p, q) - ext, np.maximum(p, q) + ext


@njit(cache=True)
def _grid_query(cell_start, cell_items, shape, origin, cell, lo, hi, mark):
    i0 = max(int(math.floor((lo[0] - origin[0]) / cell)), 0)
    j0 = max(int(math.floor((lo[1] - origin[1]) / cell)), 0)
    k0 = max(int(math.floor((lo[2] - origin[2]) / cell)), 0)
    i1 = min(int(math.floor((hi[0] - origin[0]) / cell)), shape[0] - 1)
    j1 = min(int(math.floor((hi[1] - origin[1]) / cell)), shape[1] - 1)
    k1 = min(int(math.floor((hi[2] - origin[2]) / cell)), shape[2] - 1)
    count = 0
    out = np.empty(64, dtype=np.int64)
    for i in range(i0, i1 + 1):
        for j in range(j0, j1 + 1):
            for k in range(k0, k1 + 1):
                c = (i * shape[1] + j) * shape[2] + k
                for t in range(cell_start[c], cell_start[c + 1]):
                    item = cell_items[t]
                    if mark[item]:
                        continue
                    mark[item] = True
                    if count == out.shape[0]:
                        out = grown(out, count, 2 * count)
                    out[count] = item
                    count += 1
    res = out[:count].copy()
    for t in range(count):
        mark[res[t]] = False
    return res


@njit(cache=True)
def _query_unsorted(cell_start, cell_items, shape, origin, cell, lo_all, hi_all, lo, hi):
    """Ids of the sweeps whose bounds overlap the box [lo, hi], in the grid's order."""
    mark = np.zeros(lo_all.shape[0], dtype=np.bool_)
    return _overlapping(_grid_query(cell_start, cell_items, shape, origin, cell, lo, hi, mark),
                        lo_all, hi_all, lo, hi)


@njit(cache=True)
def _query(cell_start, cell_items, shape, origin, cell, lo_all, hi_all, lo, hi):
    """Ids (sorted) of the sweeps whose bounds overlap the box [lo, hi]."""
    ids = _query_unsorted(cell_start, cell_items, shape, origin, cell, lo_all, hi_all, lo, hi)
    return take(ids, argsort_stable(ids))


@njit(cache=True)
def _clip(ids, p0_all, d_all, w_all, lo_all, hi_all, path_start, path_end, path_lo, path_hi,
          radius, height):
    """The parts of sweeps ``ids`` between two path lengths (:meth:`Sweeps.clipped`),
    and the ids of the parts kept."""
    k = ids.shape[0]
    kept = np.empty(k, dtype=np.int64)
    p0 = np.empty((k, 3))
    d = np.empty((k, 3))
    w = np.empty((k, 3))
    lo = np.empty((k, 3))
    hi = np.empty((k, 3))
    n = 0
    for t in range(k):
        j = ids[t]
        ps, pe = path_start[j], path_end[j]
        length = pe - ps
        if length > 0:
            a = (path_lo - ps) / length
            b = (path_hi - ps) / length
        else:
            a = 0.0 if ps >= path_lo else 1.0
            b = 1.0 if pe <= path_hi else 0.0
        a = min(max(a, 0.0), 1.0)
        b = min(max(b, 0.0), 1.0)
        if not (b > a or (length == 0 and ps >= path_lo and pe <= path_hi)):
            continue
        for c in range(3):
            p0[n, c] = p0_all[j, c] + a * d_all[j, c]
            d[n, c] = (b - a) * d_all[j, c]
            w[n, c] = w_all[j, c]
            lo[n, c] = lo_all[j, c]
            hi[n, c] = hi_all[j, c]
        if a > 0 or b < 1:
            for c in range(3):
                ext = radius * math.sqrt(max(1.0 - w[n, c] * w[n, c], 0.0))
                s0 = p0[n, c]
                q0 = s0 + height * w[n, c]
                s1 = p0[n, c] + d[n, c]
                q1 = s1 + height * w[n, c]
                lo[n, c] = min(min(s0, q0) - ext, min(s1, q1) - ext)
                hi[n, c] = max(max(s0, q0) + ext, max(s1, q1) + ext)
        kept[n] = j
        n += 1
    return p0[:n], d[:n], w[:n], lo[:n], hi[:n], kept[:n]


@njit(cache=True)
def _overlapping(within, lo_all, hi_all, lo, hi):
    """Those of sweeps ``within`` (in their order) whose bounds overlap the box [lo, hi]."""
    keep = np.empty(within.shape[0], dtype=np.bool_)
    for t in range(within.shape[0]):
        j = within[t]
        keep[t] = (lo_all[j, 0] <= hi[0] and lo_all[j, 1] <= hi[1] and lo_all[j, 2] <= hi[2]
                   and hi_all[j, 0] >= lo[0] and hi_all[j, 1] >= lo[1]
                   and hi_all[j, 2] >= lo[2])
    return compress(within, keep)


@njit(cache=True)
def _near_candidates(cell_start, cell_items, shape, origin, cell, p0_all, d_all, w_all, lo_all,
                     hi_all, c, r, top, lo, hi, centre, reach, order_from, within, use_within,
                     test_reach):
    """:meth:`Sweeps.near`'s sweeps before ordering, and each one's key (the squared
    distance of its middle from ``order_from``)."""
    if use_within:
        ids = _overlapping(within, lo_all, hi_all, lo, hi)
    else:   # in the grid's order (they are ordered below)
        ids = _query_unsorted(cell_start, cell_items, shape, origin, cell, lo_all, hi_all,
                              lo, hi)
    if test_reach:
        keep = sweeps_within(ids, centre[0], centre[1], centre[2], reach, p0_all, d_all,
                             w_all, lo_all, hi_all, c, r, top)
        ids = compress(ids, keep)
    dist = np.empty(ids.shape[0])
    for t in range(ids.shape[0]):
        j = ids[t]
        v = 0.0
        for a in range(3):
            e = p0_all[j, a] + 0.5 * d_all[j, a] - order_from[a]
            v += e * e
        dist[t] = v
    return ids, dist


@njit(cache=True)
def _near_clipped(ids, key, order, p0_all, d_all, w_all, lo_all, hi_all, path_start, path_end,
                  c, r, top, t1_end, t2_start):
    """:meth:`Sweeps.near`'s sweeps ``ids`` in the ``order`` that sorts their ``key``
    (equal keys in any order: put in the order of their ids here), clipped to T1 and
    T2."""
    ids = take(ids, order)
    for t in range(1, ids.shape[0]):    # equal keys (rare): by id, as a stable sort of ids
        u = t
        while u > 0 and key[order[u - 1]] == key[order[t]] and ids[u - 1] > ids[u]:
            ids[u - 1], ids[u] = ids[u], ids[u - 1]
            u -= 1
    radius = c + r
    height = top + r
    p0, d, w, lo1, hi1, ids1 = _clip(ids, p0_all, d_all, w_all, lo_all, hi_all, path_start,
                                     path_end, -np.inf, t1_end, radius, height)
    q0, e, v, lo2, hi2, _ = _clip(ids, p0_all, d_all, w_all, lo_all, hi_all, path_start,
                                  path_end, t2_start, np.inf, radius, height)
    return (p0, d, w, lo1, hi1), (q0, e, v, lo2, hi2), ids1


_NO_IDS = np.zeros(0, dtype=np.int64)


@dataclass(frozen=True, eq=False)
class Sweeps:
    """Straight, constant-axis tool moves of a program, indexed in space.

    Attributes
    ----------
    p0, d, w : ndarray, shape (n, 3)
        Tip at the start [mm], tip displacement [mm], unit tool axis.
    lo, hi : ndarray, shape (n, 3) [mm]
        Axis-aligned bounds of each swept tool solid.
    path_start, path_end : ndarray, shape (n,) [mm]
        Cumulative tip path length (from the first cutter location) at the
        start and end of each sweep.
    cl_index : ndarray, shape (n,), int
        Index of the cutter location the move ends at.
    core_radius_mm, corner_radius_mm, top_mm : float [mm]
        The tool's ``R - r``, ``r`` and flute length.
    """

    p0: np.ndarray
    d: np.ndarray
    w: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    path_start: np.ndarray
    path_end: np.ndarray
    cl_index: np.ndarray
    core_radius_mm: float
    corner_radius_mm: float
    top_mm: float
    cell_mm: float
    grid_origin: np.ndarray
    grid_shape: np.ndarray
    cell_start: np.ndarray
    cell_items: np.ndarray

    def __len__(self) -> int:
        return int(self.p0.shape[0])

    @property
    def nbytes(self) -> int:
        """Memory held by the arrays and the index [bytes]."""
        return sum(getattr(self, n).nbytes for n in (
            "p0", "d", "w", "lo", "hi", "path_start", "path_end", "cl_index",
            "cell_start", "cell_items"))

    def _index(self):
        return (self.cell_start, self.cell_items, self.grid_shape, self.grid_origin,
                self.cell_mm)

    def query(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Ids of the sweeps whose bounds may overlap the box ``[lo, hi]`` [mm].

        A superset: the grid cells overlapping the box give candidates, and
        their bounds are then tested exactly.
        """
        if len(self) == 0:
            return np.zeros(0, dtype=np.int64)
        return _query(*self._index(), self.lo, self.hi, np.asarray(lo, float),
                      np.asarray(hi, float))

    def overlapping(self, ids: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Those of sweeps ``ids`` (in their order) whose bounds overlap the box
        ``[lo, hi]`` [mm]: :meth:`query`'s test without the grid, for a few ids."""
        return _overlapping(np.asarray(ids, dtype=np.int64), self.lo, self.hi,
                            np.asarray(lo, float), np.asarray(hi, float))

    def near(self, lo, hi, centre, reach: float, order_from, t1_end: float,
             t2_start: float, within: np.ndarray | None = None):
        """T1 and T2 near a prediction point, in one call.

        The sweeps whose bounds overlap the box ``[lo, hi]`` and that may come
        within ``reach`` of ``centre`` (``errpred._kernels.sweeps_within``),
        nearest first (their middles' distance from ``order_from``; equal distances
        by id), clipped to the path before ``t1_end`` and after ``t2_start``
        (:meth:`clipped`).

        Parameters
        ----------
        lo, hi, centre, order_from : array_like, shape (3,) [mm]
        reach : float [mm]
            ``inf``: no reach test (the box alone; the membership and margin kernels
            prune per call what cannot reach their points).
        t1_end, t2_start : float [mm]
            Path lengths.
        within : ndarray of int, optional
            Sorted sweep ids that hold every sweep whose bounds overlap the box
            (:meth:`query` of a box holding it: one look-up shared by the
            positions of a block); the grid is not read. Same answer.

        Returns
        -------
        t1, t2 : tuple of ndarray
            ``(p0, d, w, lo, hi)`` each, as :meth:`clipped` returns.
        t1_ids : ndarray of int
            The sweep each part of T1 comes from.
        """
        if len(self) == 0:
            empty = tuple(np.zeros((0, 3)) for _ in range(5))
            return empty, empty, np.zeros(0, dtype=np.int64)
        ids, key = _near_candidates(
            *self._index(), self.p0, self.d, self.w, self.lo, self.hi, self.core_radius_mm,
            self.corner_radius_mm, self.top_mm, np.asarray(lo, float), np.asarray(hi, float),
            np.asarray(centre, float), float(reach), np.asarray(order_from, float),
            _NO_IDS if within is None else within, within is not None, reach != math.inf)
        # numpy's sort: 53 us for 3,700 keys, numba's merge sort 494 us (bench slices)
        return _near_clipped(ids, key, np.argsort(key), self.p0, self.d, self.w, self.lo,
                             self.hi, self.path_start, self.path_end, self.core_radius_mm,
                             self.corner_radius_mm, self.top_mm, float(t1_end),
                             float(t2_start))

    def in_frame(self, frame: np.ndarray) -> "Sweeps":
        """The same sweeps (ids, path lengths, tool) in another frame: a point ``p``
        becomes ``frame @ p`` (``frame``'s rows, orthonormal, are the new axes in this
        one's); their bounds and index made there."""
        rot = np.asarray(frame, dtype=float)
        p0, d, w = (np.ascontiguousarray(a @ rot.T) for a in (self.p0, self.d, self.w))
        return _indexed(p0, d, w, self.core_radius_mm + self.corner_radius_mm,
                        self.top_mm + self.corner_radius_mm, self.cell_mm,
                        path_start=self.path_start, path_end=self.path_end,
                        cl_index=self.cl_index, core_radius_mm=self.core_radius_mm,
                        corner_radius_mm=self.corner_radius_mm, top_mm=self.top_mm)

    def clipped(self, ids: np.ndarray, path_lo: float, path_hi: float):
        """The parts of sweeps ``ids`` between two path lengths.

        Parameters
        ----------
        ids : ndarray of int
        path_lo, path_hi : float [mm]
            Keep the motion whose cumulative path length lies in this interval
            (``-inf``/``inf`` for open ends).

        Returns
        -------
        p0, d, w, lo, hi : ndarray, shape (k, 3)
            The kept pieces, in the order of ``ids`` (empty pieces dropped).
        """
        R = self.core_radius_mm + self.corner_radius_mm
        h = self.top_mm + self.corner_radius_mm
        return _clip(np.asarray(ids, dtype=np.int64), self.p0, self.d, self.w, self.lo, self.hi,
                     self.path_start, self.path_end, float(path_lo), float(path_hi), R, h)[:5]


class BlockLookup:
    """One grid look-up shared by the tool positions of a block, and of the blocks
    after it that lie inside its box.

    A box holding the look-up box of every tool position between the given
    cutter locations (at each, the tool from its tip to ``height`` along its
    axis, ``radius`` plus ``margin`` around it, padded by
    ``SHARED_LOOKUP_PAD_MM``), grown by ``grow`` on every side, and the sweeps whose
    bounds overlap it (:meth:`Sweeps.query`, made on first use): :meth:`ids_for` a
    position's box inside it gives :meth:`Sweeps.near` those instead of another grid
    look-up (the same sweeps, in the same order). A position outside the box (the
    axis turning between cutter locations) gets None: its own look-up. A later
    block whose own box (:attr:`own_lo`, :attr:`own_hi`) lies inside this one's
    (:meth:`holds`) shares it too: on a finishing contour or raster, whose blocks
    are short, one look-up serves the next few blocks.

    Parameters
    ----------
    sweeps : Sweeps
    tips, axes : ndarray, shape (k, 3)
        The block's cutter locations (and the one before it) [mm], unit axes.
    radius, height, margin : float [mm]
        The tool's radius, the largest height a position's box takes, and the
        margin around the tool.
    max_span : float [mm]
        No shared look-up where the cutter locations span more (its box would
        hold too many sweeps).
    grow : float [mm]
        How far the box reaches beyond the block's, for the blocks after it.
    """

    def __init__(self, sweeps: Sweeps, tips: np.ndarray, axes: np.ndarray, radius: float,
                 height: float, margin: float, max_span: float, grow: float = 0.0) -> None:
        self._sweeps = sweeps
        self._ids = None
        self.lo = self.hi = self.own_lo = self.own_hi = None
        if tips.shape[0] and float(np.linalg.norm(tips.max(axis=0) - tips.min(axis=0))) \
                <= max_span:
            top = tips + height * axes
            ext = radius * np.sqrt(np.clip(1 - axes * axes, 0, None)) + margin \
                + K.SHARED_LOOKUP_PAD_MM
            self.own_lo = (np.minimum(tips, top) - ext).min(axis=0)
            self.own_hi = (np.maximum(tips, top) + ext).max(axis=0)
            self.lo, self.hi = self.own_lo - grow, self.own_hi + grow

    def _inside(self, lo, hi) -> bool:
        """Is the box ``[lo, hi]`` inside this look-up's (False: it has none)?"""
        return self.lo is not None and bool(np.all(lo >= self.lo) and np.all(hi <= self.hi))

    def holds(self, other: "BlockLookup") -> bool:
        """Does this look-up's box hold ``other``'s own box (the block's, not grown)?"""
        return other.own_lo is not None and self._inside(other.own_lo, other.own_hi)

    def ids_for(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray | None:
        """Sorted sweep ids holding every sweep whose bounds overlap ``[lo, hi]`` [mm],
        or None where that box is not inside the shared one."""
        if not self._inside(lo, hi):
            return None
        if self._ids is None:
            self._ids = self._sweeps.query(self.lo, self.hi)
        return self._ids


def slerp(ua: np.ndarray, ub: np.ndarray, om: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Unit axes a fraction ``t`` of the way from ``ua`` to ``ub`` (rows), turning at a
    constant rate through the angle ``om`` between them [rad] (straight interpolation
    where they are parallel)."""
    om = np.asarray(om, dtype=float)
    t = np.asarray(t, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        so = np.sin(om)
        wa = np.where(so > K.PARALLEL_AXES_SIN, np.sin((1 - t) * om) / so, 1 - t)
        wb = np.where(so > K.PARALLEL_AXES_SIN, np.sin(t * om) / so, t)
    u = wa[..., None] * ua + wb[..., None] * ub
    return u / np.linalg.norm(u, axis=-1, keepdims=True)


def build_sweeps(cl: CutterLocations, tool: Tool, *,
                 axis_step_rad: float = K.SWEEP_AXIS_STEP_RAD,
                 cell_mm: float | None = None, anchor_mm: float | None = None) -> Sweeps:
    """Sweeps of every cutting move of ``cl``.

    Parameters
    ----------
    cl : CutterLocations
        The path (arcs already expanded). The move ending at point i is a
        sweep unless it is a rapid.
    tool : Tool
    axis_step_rad : float [rad]
        5-axis moves whose axis turns by more are split into pieces with the
        axis of each piece's middle (slerp), so a piece's axis is within half
        this of the true one. A turning piece is anchored at the anchor point
        (``anchor_mm`` up the axis from the tip): that point is where the real
        tool's is at both of the piece's ends, and the piece misses the real tool
        there by up to |h - anchor| x sin(half the piece's turn) at height h above
        the tip (a 0.81 deg turn: 0.14 mm at 25 mm up a 5 mm ball). For a ball end
        mill the anchor is the ball's centre, so the ball part of every piece is
        the real ball at both ends (between them its centre runs on the chord of
        the real centre's arc, R (1 - cos(turn / 2)) off it: 0.2 um for 1 deg
        at R 5 mm). Anchored at the tip, the ball's centre was off by
        R sin(half the turn) at a piece's ends (22 um for 0.5 deg at R 5 mm),
        mostly along the feed, and jumped by twice that at each joint: far more
        than the strip of about one feed per tooth a point finishes, which the
        pieces after a point (T2) then took away ("no-finished-surface" at points of
        5-axis finishing passes the real tool finishes). Where the turn does not go
        on into the next move (a
        rapid leaves from the end, the path ends, the next move turns back or not
        at all), the move also gets a zero-length sweep with the end's own axis:
        the tool standing at the move's end, which the real move removed, so a
        rapid's start never meets a sliver the pieces left.
    cell_mm : float, optional [mm]
        Grid cell size (default: ``SWEEP_GRID_CELL_PER_RADIUS`` tool radii).
    anchor_mm : float, optional [mm]
        Height above the tip at which turning pieces follow the real motion
        (default: the tool's corner radius: a ball's centre, a torus end mill's
        corner centre; 0 for a flat end mill, the tip). Moves that do not turn
        are the same for any anchor.
    """
    anchor = tool.corner_radius_mm if anchor_mm is None else float(anchor_mm)
    if not math.isfinite(anchor):
        raise ValueError(f"anchor_mm: expected a finite height [mm], got {anchor_mm!r}")
    n = len(cl)
    tip, axis = cl.tip, cl.axis
    seg_len = np.zeros(n)
    if n > 1:
        seg_len[1:] = np.linalg.norm(np.diff(tip, axis=0), axis=1)
    cum = np.cumsum(seg_len)
    ends = np.flatnonzero(~cl.rapid)
    ends = ends[ends >= 1]
    if ends.size:
        u0, u1 = axis[ends - 1], axis[ends]
        ang = np.arccos(np.clip(np.sum(u0 * u1, axis=1), -1.0, 1.0))
        pieces = np.maximum(1, np.ceil(ang / axis_step_rad - 1e-12)).astype(np.int64)
        # a turning move whose turn does not go on into the next move (a rapid
        # leaves from its end, the path ends there, the next move turns back or
        # not at all) also gets its end cap: the tool standing at the end, with
        # the end's own axis. Where the turn goes on, the pieces either side of
        # the end are off to opposite sides by about +-e and cover the tool there
        # to second order, e^2 / (2 R): nothing at the anchor (a ball's centre,
        # e = 0), 3 um 25 mm up a 5 mm ball's flutes (e = 0.17 mm for 1 deg).
        nxt = ends + 1
        goes_on = np.zeros(ends.size, dtype=bool)
        inside = nxt < n
        k_in = ends[inside]
        nx = nxt[inside]
        turn = np.cross(axis[k_in - 1], axis[k_in])
        turn_next = np.cross(axis[nx - 1], axis[nx])
        goes_on[inside] = ~cl.rapid[nx] & (np.sum(turn * turn_next, axis=1) > 0.0)
        cap = (ang > 0.0) & ~goes_on
    else:
        ang = np.zeros(0)
        pieces = np.zeros(0, dtype=np.int64)
        cap = np.zeros(0, dtype=bool)
    rows = pieces + cap
    seg = np.repeat(ends, rows)
    first = np.cumsum(rows) - rows
    k = np.arange(seg.size) - np.repeat(first, rows)
    m = np.repeat(pieces, rows)
    is_cap = k >= m
    t0, t1 = np.minimum(k / m, 1.0), np.minimum((k + 1) / m, 1.0)
    a, b = tip[seg - 1], tip[seg]
    p0 = a + t0[:, None] * (b - a)
    d = (t1 - t0)[:, None] * (b - a)
    # axis of each piece: slerp at the piece's middle (a cap: the end's axis)
    ua, ub = axis[seg - 1], axis[seg]
    om = np.repeat(ang, rows)
    tm = np.where(is_cap, 1.0, 0.5 * (t0 + t1))
    w = slerp(ua, ub, om, tm)
    w[is_cap] = ub[is_cap] / np.linalg.norm(ub[is_cap], axis=1, keepdims=True)
    # a turning piece is anchored at the centre of the tool's corner (a ball's centre):
    # the point ``anchor`` up the axis follows the real motion at both of the piece's
    # ends, not the tip (the tip-anchored piece's ball centre is off by anchor x sin
    # of half the piece's turn, mostly along the feed, and jumps by that at every joint)
    turning = (om > 0.0) & ~is_cap
    if anchor != 0.0 and turning.any():
        u0 = slerp(ua[turning], ub[turning], om[turning], t0[turning])
        u1 = slerp(ua[turning], ub[turning], om[turning], t1[turning])
        wt = w[turning]
        p0[turning] += anchor * (u0 - wt)
        d[turning] += anchor * (u1 - u0)
    ps = cum[seg - 1] + t0 * seg_len[seg]
    pe = cum[seg - 1] + t1 * seg_len[seg]
    R = tool.radius_mm
    cell = float(cell_mm) if cell_mm is not None else K.SWEEP_GRID_CELL_PER_RADIUS * R
    if not (math.isfinite(cell) and cell > 0):
        raise ValueError(f"cell_mm: expected a finite value > 0, got {cell_mm!r}")
    return _indexed(p0, d, w, R, tool.flute_length_mm + tool.corner_radius_mm, cell,
                    path_start=ps, path_end=pe, cl_index=seg,
                    core_radius_mm=tool.core_radius_mm,
                    corner_radius_mm=tool.corner_radius_mm, top_mm=tool.flute_length_mm)


def _indexed(p0, d, w, radius: float, height: float, cell: float, **rest) -> Sweeps:
    """Sweeps of tips ``p0`` to ``p0 + d`` with axes ``w``, each bounded by the tool's
    cylinder (``radius``, ``height`` up the axis) at both ends, with the grid of ``cell``
    over the bounds; ``rest``: the other fields."""
    l0, h0 = _cylinder_bounds(p0, w, height, radius)
    l1, h1 = _cylinder_bounds(p0 + d, w, height, radius)
    lo, hi = np.minimum(l0, l1), np.maximum(h0, h1)
    return Sweeps(p0=p0, d=d, w=w, lo=lo, hi=hi, cell_mm=cell, **rest,
                  **_build_grid(lo, hi, cell))


def _build_grid(lo: np.ndarray, hi: np.ndarray, cell: float) -> dict:
    """CSR uniform grid: the cells each AABB overlaps."""
    if lo.shape[0] == 0:
        return dict(grid_origin=np.zeros(3), grid_shape=np.ones(3, dtype=np.int64),
                    cell_start=np.zeros(2, dtype=np.int64),
                    cell_items=np.zeros(0, dtype=np.int64))
    origin = lo.min(axis=0)
    shape = np.maximum(np.floor((hi.max(axis=0) - origin) / cell).astype(np.int64) + 1, 1)
    i0 = np.floor((lo - origin) / cell).astype(np.int64)
    i1 = np.minimum(np.floor((hi - origin) / cell).astype(np.int64), shape - 1)
    span = i1 - i0 + 1
    counts = span.prod(axis=1)
    item = np.repeat(np.arange(lo.shape[0]), counts)
    local = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    sy, sz = span[item, 1], span[item, 2]
    ci = i0[item, 0] + local // (sy * sz)
    cj = i0[item, 1] + (local // sz) % sy
    ck = i0[item, 2] + local % sz
    flat = (ci * shape[1] + cj) * shape[2] + ck
    order = np.argsort(flat, kind="stable")
    ncell = int(shape.prod())
    cell_start = np.zeros(ncell + 1, dtype=np.int64)
    np.add.at(cell_start, flat + 1, 1)
    return dict(grid_origin=origin, grid_shape=shape, cell_start=np.cumsum(cell_start),
                cell_items=item[order].astype(np.int64))
