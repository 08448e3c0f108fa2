"""The correction as a smooth offset of a path along the surface normal (``method.md`` §6).

Pure arrays, no I/O: :mod:`errpred.correct` builds the problem from a program's
blocks, :mod:`errpred.correct_path` from a 5-axis path's cutter locations.

The path is a set of vertices joined by segments. Every vertex moves by a vector
``m_v`` (3 unknowns); a point at fraction ``t`` of a segment moves by

* a **line**: ``(1 - t) m_0 + t m_1``;
* an **arc** with the sweep kept: the arc through the moved ends with the same
  sweep is the image of the old one under the plane similarity that maps the old
  ends onto the new ones, so in the arc's plane (complex numbers) the point moves
  by ``(1 - w) m_0 + w m_1`` with ``w = (p(t) - p_0) / (p_1 - p_0)`` (for a line
  ``w = t``), and along the arc's axis linearly;
* a **full circle** (start = end, no similarity): by its own centre shift ``dc``
  and radius change ``dr``: ``dc + dr r(theta)`` in the plane; its start and end
  vertex is held on the new circle (stiff rows), so a lead-in and lead-out follow.

Each prediction point asks for a move ``target`` along its normal ``n``
(``n . D = target``). The least-squares fit adds

* rows holding each vertex's move along its surface normal (the mean normal of
  the points next to it): a component across the normal changes no error and is
  not wanted (``OFFSET_NORMAL``);
* a smoothness term on the **second difference** of the moves along each chain
  of vertices (per unit path length, made dimensionless by the local spacing)
  where the vertex and both its segments carry points: straight and uniform
  offsets cost nothing, so a uniform error moves every vertex by the same
  amount; noise from one point to the next is not chased. Across a segment
  without points (air inside a chain, the stretch of a split block past its last
  point) the term is on the first difference: moves there are interpolated
  between the points on either side, or held constant past the last one, never
  extrapolated;
* a small ridge (nothing that no equation asks for).

A chain is trimmed by the caller to the vertices between its first and last
cutting segment, so lead-ins and lead-outs are not fitted and pull nothing.

**Bound (no zigzag).** Along a chain whose points ask for moves ``w`` at its
vertices, the fitted moves are no rougher than the wanted ones:
``max |second difference of m| <= max |second difference of w| + 0.05 um``, and a
move alternating from one point to the next is followed to ``1 / (1 + 16 s)`` of its
amplitude per pass (``s = OFFSET_SMOOTH``: 11 %). Both are tested
(``tests/errpred/test_offset.py``), on noise, a zigzag and a smooth error with noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .constants import (
    FALLBACK_FREE_VERTICES,
    OFFSET_EDGE_ITERATIONS,
    OFFSET_EDGE_UM,
    OFFSET_HOLD,
    OFFSET_NORMAL,
    OFFSET_PIN,
    OFFSET_RIDGE,
    OFFSET_SMOOTH,
    OFFSET_STIFF,
    SPLIT_TOL_MM,
)

#: Pieces of a split segment shorter than this are merged with their neighbour [mm].
_MIN_PIECE_MM = 0.05

__all__ = ["LINE", "ARC", "CIRCLE", "OffsetProblem", "OffsetSolution", "solve_offsets",
           "arc_weights", "second_difference", "Units", "OffsetEdit", "feed_chains", "fit_units",
           "split_fractions"]

#: Segment kinds.
LINE, ARC, CIRCLE = 0, 1, 2


@dataclass(frozen=True)
class OffsetProblem:
    """The fit's data.

    Attributes
    ----------
    vertices : ndarray, shape (V, 3) [mm]
    movable : ndarray, shape (V,), bool
        Vertices that may move (the others stay where they are).
    seg_v0, seg_v1 : ndarray, shape (S,), int
        Vertex indices of each segment's start and end.
    seg_kind : ndarray, shape (S,), int
        ``LINE``, ``ARC`` or ``CIRCLE``.
    seg_plane : ndarray, shape (S, 3), int
        In-plane axes ``a1, a2`` and the plane's axis of arcs and circles.
    seg_centre : ndarray, shape (S, 3) [mm]
        Centre of arcs and circles.
    chains : list of ndarray of int
        Ordered vertex indices along each chain (for the smoothness term).
    pt_seg : ndarray, shape (Q,), int
    pt_t : ndarray, shape (Q,)
        Fraction along the segment (0 start, 1 end).
    pt_w : ndarray, shape (Q, 2)
        Arc weight ``w`` (real, imaginary); ``(t, 0)`` on lines.
    pt_theta : ndarray, shape (Q,) [rad]
        Angle of the point on a full circle (about its centre, in its plane).
    pt_normal : ndarray, shape (Q, 3)
    pt_target : ndarray, shape (Q,) [mm]
        Wanted move along the normal.
    pt_weight : ndarray, shape (Q,)
        Weight of each equation (the path length it stands for, relative).
    fixed_moves : ndarray, shape (V, 3), optional [mm]
        What the vertices that may not move (``movable`` False) move by, given (zero
        when None): the rows that read them take them as known.
    """

    vertices: np.ndarray
    movable: np.ndarray
    seg_v0: np.ndarray
    seg_v1: np.ndarray
    seg_kind: np.ndarray
    seg_plane: np.ndarray
    seg_centre: np.ndarray
    chains: list
    pt_seg: np.ndarray
    pt_t: np.ndarray
    pt_w: np.ndarray
    pt_theta: np.ndarray
    pt_normal: np.ndarray
    pt_target: np.ndarray
    pt_weight: np.ndarray
    fixed_moves: np.ndarray | None = None


@dataclass(frozen=True)
class OffsetSolution:
    """Moves of the vertices and of the full circles.

    Attributes
    ----------
    moves : ndarray, shape (V, 3) [mm]
    circle : dict of int -> (ndarray (3,), float)
        Segment index -> (centre shift [mm], radius change [mm]) of each full circle.
    residual_mm : ndarray, shape (Q,) [mm]
        ``n . D - target`` per point after the fit.
    """

    moves: np.ndarray
    circle: dict
    residual_mm: np.ndarray


def arc_weights(p0: np.ndarray, p1: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``w = (p - p0) / (p1 - p0)`` as complex numbers, in-plane 2-d points, (k, 2)."""
    z0 = p0[0] + 1j * p0[1]
    z1 = p1[0] + 1j * p1[1]
    z = p[:, 0] + 1j * p[:, 1]
    w = (z - z0) / (z1 - z0)
    return np.column_stack([w.real, w.imag])


def second_difference(moves: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Dimensionless second difference of moves along a chain, (k - 2, 3) [mm].

    ``(m[i+1] - m[i]) h_- / h - (m[i] - m[i-1]) h_+ / h`` with ``h = (h_- + h_+) / 2``
    and ``h_-``, ``h_+`` the lengths before and after vertex ``i``: for equal spacing
    the plain ``m[i-1] - 2 m[i] + m[i+1]``; zero for moves linear in path length.
    """
    m = np.asarray(moves, float)
    if len(m) < 3:
        return np.zeros((0, 3))
    h = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    h = np.maximum(h, 1e-9)
    hm, hp = h[:-1], h[1:]
    mid = 0.5 * (hm + hp)
    return ((m[2:] - m[1:-1]) * (hm / mid)[:, None] - (m[1:-1] - m[:-2]) * (hp / mid)[:, None])


def solve_offsets(pb: OffsetProblem, *, smooth: float = OFFSET_SMOOTH,
                  ridge: float = OFFSET_RIDGE) -> OffsetSolution:
    """Least-squares vertex moves (and full-circle changes) for the wanted normal moves.

    Parameters
    ----------
    pb : OffsetProblem
    smooth : float
        Weight of the second-difference rows, relative to a point's equation [-].
    ridge : float
        Weight of the ridge rows [-].
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.linalg import spsolve

    V = pb.vertices.shape[0]
    unknown = np.full(V, -1, dtype=np.int64)
    mov = np.flatnonzero(pb.movable)
    unknown[mov] = np.arange(mov.size)
    circles = np.flatnonzero(pb.seg_kind == CIRCLE)
    circ_col = {int(s): 3 * mov.size + 3 * k for k, s in enumerate(circles)}
    N = 3 * mov.size + 3 * circles.size
    rows: list[np.ndarray] = []
    cols: list[np.ndarray] = []
    vals: list[np.ndarray] = []
    rhs: list[float] = []
    r = 0
    # a vertex that may not move has columns -2 - (3 v + axis): known, its given move
    # (pb.fixed_moves) goes to the right-hand side
    known = (np.zeros(3 * V) if pb.fixed_moves is None
             else np.asarray(pb.fixed_moves, float).reshape(-1))

    def add(cs, vs, b):
        nonlocal r
        cs = np.asarray(cs, np.int64)
        vs = np.asarray(vs, float)
        keep = cs >= 0
        given = cs <= -2
        if given.any():
            b = b - float(vs[given] @ known[-2 - cs[given]])
        rows.append(np.full(int(keep.sum()), r, np.int64))
        cols.append(cs[keep])
        vals.append(vs[keep])
        rhs.append(b)
        r += 1

    def vcols(v: int) -> np.ndarray:
        u = unknown[v]
        return (np.array([3 * u, 3 * u + 1, 3 * u + 2]) if u >= 0
                else -2 - (3 * v + np.arange(3)))

    # --- the points' equations --------------------------------------------------------
    Q = pb.pt_seg.size
    eq_rows = np.zeros(Q, np.int64)
    for q in range(Q):
        s = int(pb.pt_seg[q])
        sw = math.sqrt(max(float(pb.pt_weight[q]), 0.0))
        n = pb.pt_normal[q]
        t = float(pb.pt_t[q])
        c0, c1 = vcols(int(pb.seg_v0[s])), vcols(int(pb.seg_v1[s]))
        kind = int(pb.seg_kind[s])
        eq_rows[q] = r
        if kind == LINE:
            add(np.r_[c0, c1], sw * np.r_[(1 - t) * n, t * n], sw * float(pb.pt_target[q]))
        elif kind == ARC:
            a1, a2, ax = (int(x) for x in pb.seg_plane[s])
            wr, wi = (float(x) for x in pb.pt_w[q])
            # in-plane: (1 - w) m0 + w m1, complex; n . D with n = (n1, n2) in plane
            n1, n2, n3 = n[a1], n[a2], n[ax]
            coef0 = np.zeros(3)
            coef1 = np.zeros(3)
            coef0[a1] = n1 * (1 - wr) + n2 * (-wi)
            coef0[a2] = n1 * wi + n2 * (1 - wr)
            coef1[a1] = n1 * wr + n2 * wi
            coef1[a2] = n1 * (-wi) + n2 * wr
            coef0[ax] = (1 - t) * n3
            coef1[ax] = t * n3
            add(np.r_[c0, c1], sw * np.r_[coef0, coef1], sw * float(pb.pt_target[q]))
        else:
            a1, a2, ax = (int(x) for x in pb.seg_plane[s])
            th = float(pb.pt_theta[q])
            g = circ_col[s]
            cax = np.full(3, -1)
            vax = np.zeros(3)
            cax[:2] = (c0[ax], c1[ax])
            vax[:2] = ((1 - t) * n[ax], t * n[ax])
            add(np.r_[g, g + 1, g + 2, cax[:2]],
                sw * np.r_[n[a1], n[a2], n[a1] * math.cos(th) + n[a2] * math.sin(th), vax[:2]],
                sw * float(pb.pt_target[q]))
    # --- full circles: their start and end vertex stay on the new circle --------------
    for s in circles:
        s = int(s)
        a1, a2, _ = (int(x) for x in pb.seg_plane[s])
        g = circ_col[s]
        c = pb.seg_centre[s]
        for v in (int(pb.seg_v0[s]), int(pb.seg_v1[s])):
            p = pb.vertices[v]
            th = math.atan2(p[a2] - c[a2], p[a1] - c[a1])
            cv = vcols(v)
            st = OFFSET_STIFF
            add([cv[a1], g, g + 2], st * np.array([1.0, -1.0, -math.cos(th)]), 0.0)
            add([cv[a2], g + 1, g + 2], st * np.array([1.0, -1.0, -math.sin(th)]), 0.0)
    # --- each vertex moves along its surface normal -------------------------------------
    d, has_data = _vertex_normals(pb)
    ln = math.sqrt(OFFSET_NORMAL)
    for v in mov:
        P = ln * (np.eye(3) - np.outer(d[v], d[v]))
        cv = vcols(int(v))
        for a in range(3):
            add(cv, P[a], 0.0)
    # --- smoothness along the chains ----------------------------------------------------
    # second differences where the vertex and both its segments carry points; first
    # differences across segments without points (air inside a chain, the stretch past
    # the last point of a split block): those are interpolated, or held constant past
    # the last point, never extrapolated
    ls = math.sqrt(smooth)
    d2_rows: list[int] = []                  # first of the three rows of each vertex
    seg_has = np.zeros(pb.seg_v0.size, bool)
    seg_has[pb.pt_seg] = True
    pair_has = {}
    for k in range(pb.seg_v0.size):
        pair_has[(int(pb.seg_v0[k]), int(pb.seg_v1[k]))] = bool(seg_has[k])
    on_vertex = np.zeros(V)
    np.add.at(on_vertex, pb.seg_v0[pb.pt_seg], 1.0 - np.asarray(pb.pt_t, float))
    np.add.at(on_vertex, pb.seg_v1[pb.pt_seg], np.asarray(pb.pt_t, float))
    for chain in pb.chains:
        chain = np.asarray(chain, np.int64)
        if chain.size < 2:
            continue
        pos = pb.vertices[chain]
        h = np.maximum(np.linalg.norm(np.diff(pos, axis=0), axis=1), 1e-9)
        data = np.array([pair_has.get((int(a), int(b)), False)
                         for a, b in zip(chain[:-1], chain[1:], strict=True)])
        # a vertex that the points barely weigh on (a chain's end where a lead-in
        # without points ends, or a point a few per cent into the last segment; the
        # last vertex before a stretch without points, the next point sitting at the
        # segment's far end) is interpolated from its neighbours, not left to follow
        # one side only or to extend a slope (OFFSET_PIN)
        weak = on_vertex[chain] < OFFSET_PIN
        data &= ~(weak[:-1] | weak[1:])
        for i in range(chain.size - 1):
            if not data[i]:
                for a in range(3):
                    add([vcols(int(chain[i]))[a], vcols(int(chain[i + 1]))[a]],
                        ls * np.array([1.0, -1.0]), 0.0)
        for i in range(1, chain.size - 1):
            if not (data[i - 1] and data[i]):
                continue
            hm, hp = h[i - 1], h[i]
            mid = 0.5 * (hm + hp)
            wts = np.array([hp / mid, -(hp / mid) - (hm / mid), hm / mid])
            vs = chain[i - 1:i + 2]
            d2_rows.append(r)
            for a in range(3):
                cs = np.array([vcols(int(v))[a] for v in vs])
                add(cs, ls * wts, 0.0)
    # --- ridge ---------------------------------------------------------------------------
    lr = math.sqrt(ridge)
    R = np.arange(N)
    rows.append(r + R)
    cols.append(R)
    vals.append(np.full(N, lr))
    rhs.extend([0.0] * N)
    r += N
    moves = np.zeros((V, 3)) if pb.fixed_moves is None else np.array(pb.fixed_moves, float)
    moves[mov] = 0.0
    b = np.asarray(rhs)
    sw = np.sqrt(np.maximum(pb.pt_weight, 0.0))

    def per_point(resid: np.ndarray) -> np.ndarray:
        if not Q:
            return np.zeros(0)
        return np.where(sw > 0, resid[eq_rows] / np.where(sw > 0, sw, 1.0), np.nan)

    if N == 0:
        return OffsetSolution(moves, {}, per_point(-b))
    A = coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                   shape=(r, N)).tocsr()
    # edge-preserving smoothness (iteratively reweighted): a second difference much
    # larger than OFFSET_EDGE_UM is a real step of the error (a wall's end, the tool
    # leaving the material), which the moves follow; smaller ones (noise) are damped
    d2 = np.asarray(d2_rows, np.int64)
    scale = np.ones(r)
    for it in range(1 + OFFSET_EDGE_ITERATIONS):
        Aw = A.multiply(scale[:, None]).tocsr() if it else A
        x = np.atleast_1d(spsolve((Aw.T @ Aw).tocsc(), Aw.T @ (scale * b)))
        if d2.size == 0 or it == OFFSET_EDGE_ITERATIONS:
            break
        res = A @ x - b             # rows next to a given vertex have a right-hand side
        mag = np.sqrt(res[d2] ** 2 + res[d2 + 1] ** 2 + res[d2 + 2] ** 2) / max(ls, 1e-300)
        w = 1.0 / np.sqrt(1.0 + (mag * 1e3 / OFFSET_EDGE_UM) ** 2)
        for a in range(3):
            scale[d2 + a] = w
    moves[mov] = x[:3 * mov.size].reshape(-1, 3)
    circle = {s: (_circle_shift(pb, s, x[g:g + 3]), float(x[g + 2])) for s, g in circ_col.items()}
    return OffsetSolution(moves, circle, per_point(A @ x - b))


def _vertex_normals(pb: OffsetProblem) -> tuple[np.ndarray, np.ndarray]:
    """Unit surface normal at each vertex (the mean of its segments' points' normals,
    weighted toward the nearer end; vertices without points take the nearest one's
    along their chain), and whether a point reached it, (V, 3) and (V,)."""
    V = pb.vertices.shape[0]
    acc = np.zeros((V, 3))
    kind = pb.seg_kind[pb.pt_seg]
    on = kind == LINE
    t = pb.pt_t[on, None]
    # the points next to the vertex count most (a long block's far end, little)
    np.add.at(acc, pb.seg_v0[pb.pt_seg[on]], (1 - t) ** 4 * pb.pt_normal[on])
    np.add.at(acc, pb.seg_v1[pb.pt_seg[on]], t ** 4 * pb.pt_normal[on])
    # an arc's or a full circle's ends: its own normal there (radial, on the side its
    # points' normals are)
    for s in np.flatnonzero(pb.seg_kind != LINE):
        q = np.flatnonzero(pb.pt_seg == s)
        if q.size == 0:
            continue
        a1, a2, _ = (int(x) for x in pb.seg_plane[s])
        c = pb.seg_centre[s]
        rel = pb.vertices[pb.seg_v0[s]] + np.zeros((q.size, 3))
        radial = np.zeros((q.size, 3))
        if pb.seg_kind[s] == CIRCLE:
            radial[:, a1], radial[:, a2] = np.cos(pb.pt_theta[q]), np.sin(pb.pt_theta[q])
        else:
            # the points on the arc: between its ends by the similarity weights
            p0, p1 = pb.vertices[pb.seg_v0[s]], pb.vertices[pb.seg_v1[s]]
            w = pb.pt_w[q, 0] + 1j * pb.pt_w[q, 1]
            z = complex(p0[a1], p0[a2]) + w * complex(p1[a1] - p0[a1], p1[a2] - p0[a2])
            rel = z - complex(c[a1], c[a2])
            radial[:, a1], radial[:, a2] = rel.real / np.abs(rel), rel.imag / np.abs(rel)
        side = 1.0 if np.sum(radial * pb.pt_normal[q]) >= 0 else -1.0
        for v in (int(pb.seg_v0[s]), int(pb.seg_v1[s])):
            p = pb.vertices[v]
            r = np.zeros(3)
            r[a1], r[a2] = p[a1] - c[a1], p[a2] - c[a2]
            acc[v] += side * r / max(float(np.linalg.norm(r)), 1e-12)
    norm = np.linalg.norm(acc, axis=1)
    has = norm > 1e-9
    d = np.zeros((V, 3))
    d[has] = acc[has] / norm[has, None]
    for chain in pb.chains:
        chain = np.asarray(chain, np.int64)
        known = np.flatnonzero(has[chain])
        if known.size == 0:
            continue
        pos = np.arange(chain.size)
        nearest = known[np.argmin(np.abs(pos[:, None] - known[None, :]), axis=1)]
        miss = ~has[chain]
        d[chain[miss]] = d[chain[nearest[miss]]]
    lost = np.linalg.norm(d, axis=1) < 0.5
    d[lost] = (0.0, 0.0, 1.0)
    return d, has


def _circle_shift(pb: OffsetProblem, s: int, g: np.ndarray) -> np.ndarray:
    a1, a2, _ = (int(x) for x in pb.seg_plane[s])
    d = np.zeros(3)
    d[a1], d[a2] = g[0], g[1]
    return d


@dataclass(frozen=True, eq=False)
class Units:
    """The moves a path is made of, as the fit needs them (a program's blocks, or a 5-axis
    path's segments between cutter locations). Unit ``u`` runs from the end of unit
    ``u - 1`` (for ``u = 0``: a fixed start) to its own end.

    Attributes
    ----------
    start, end : ndarray, shape (n, 3) [mm]
    kind : ndarray, shape (n,), int
        ``LINE``, ``ARC`` or ``CIRCLE``.
    plane : ndarray, shape (n, 3), int
        In-plane axes and the plane's axis (arcs).
    centre : ndarray, shape (n, 3) [mm]
    radius : ndarray, shape (n, 2) [mm]
        Start and end radius (arcs).
    sweep : ndarray, shape (n,) [rad]
    splittable : ndarray, shape (n,), bool
        Straight units that may be split into pieces.
    joined : ndarray, shape (n,), bool
        Unit ``u`` continues from unit ``u - 1`` (a feed move after a feed move).
    """

    start: np.ndarray
    end: np.ndarray
    kind: np.ndarray
    plane: np.ndarray
    centre: np.ndarray
    radius: np.ndarray
    sweep: np.ndarray
    splittable: np.ndarray
    joined: np.ndarray

    def __len__(self) -> int:
        return int(self.kind.shape[0])

    def point(self, u: int, t: float) -> np.ndarray:
        """The point at fraction ``t`` of unit ``u`` [mm] (on the arc for arcs)."""
        a, e = self.start[u], self.end[u]
        p = a + t * (e - a)
        if self.kind[u] != LINE:
            a1, a2, _ = (int(x) for x in self.plane[u])
            c = self.centre[u]
            r0, r1 = self.radius[u]
            ang = math.atan2(a[a2] - c[a2], a[a1] - c[a1]) + t * float(self.sweep[u])
            r = r0 + t * (r1 - r0)
            p[a1] = c[a1] + r * math.cos(ang)
            p[a2] = c[a2] + r * math.sin(ang)
        return p


@dataclass(frozen=True, eq=False)
class OffsetEdit:
    """A fitted correction: moves of the units' ends and of the points they are split at.

    Attributes
    ----------
    moves : ndarray, shape (V, 3) [mm]
        Vertex ``u < n``: the end of unit ``u``; vertex ``n``: the fixed start of unit
        0 (never moves); then the split points (:attr:`split_vertices`).
    split_fractions : dict of int -> ndarray
        Unit -> fractions (0..1, ascending) at which it is split.
    split_vertices : dict of int -> ndarray of int
        Unit -> the vertices at those fractions.
    circles : dict of int -> (ndarray (3,), float)
        Full-circle unit -> (centre shift [mm], radius change [mm]).
    movable : ndarray, shape (V,), bool
    vertices : ndarray, shape (V, 3) [mm]
        Where the vertices are before the moves.
    """

    moves: np.ndarray
    split_fractions: dict
    split_vertices: dict
    circles: dict
    movable: np.ndarray
    vertices: np.ndarray

    @property
    def n_vertices(self) -> int:
        return int(self.moves.shape[0])

    @property
    def largest_mm(self) -> float:
        """Largest vertex move [mm]."""
        return float(np.linalg.norm(self.moves, axis=1).max(initial=0.0))


def _same_units(hold: OffsetEdit, verts: np.ndarray, n: int) -> bool:
    """Whether ``hold`` is an edit of the same ``n`` units (the same ends and start)."""
    units = hold.n_vertices - 1 - sum(len(v) for v in hold.split_vertices.values())
    return units == n and np.array_equal(hold.vertices[:n + 1], verts[:n + 1])


def split_fractions(length_mm: float, t: np.ndarray, target: np.ndarray,
                    normal: np.ndarray) -> np.ndarray:
    """Fractions at which a straight piece of ``length_mm`` must be split so that
    straight pieces can follow the wanted moves ``target`` [mm] along ``normal`` of its
    points at fractions ``t`` (empty if a straight move of its ends can, within
    ``SPLIT_TOL_MM``)."""
    want = target[:, None] * normal
    A = np.column_stack([1 - t, t])
    coef, *_ = np.linalg.lstsq(A, want, rcond=None)
    resid = np.abs(np.einsum("ij,ij->i", A @ coef - want, normal))
    if resid.max(initial=0.0) <= SPLIT_TOL_MM:
        return np.zeros(0)
    inner = np.unique(t[(t > 0) & (t < 1)])
    out: list[float] = []
    last = 0.0
    for x in inner:
        if (x - last) * length_mm >= _MIN_PIECE_MM and (1 - x) * length_mm >= _MIN_PIECE_MM:
            out.append(float(x))
            last = float(x)
    return np.asarray(out)


def feed_chains(feed: np.ndarray, cut: np.ndarray, sticky: np.ndarray | None = None
                ) -> list[list[int]]:
    """Runs of consecutive feed units (``feed``), each trimmed to its first and last
    cutting unit (``cut``), with the ``sticky`` units next to the trimmed ends kept in
    (a full circle's start and end move together); runs that do not cut are dropped."""
    n = len(feed)
    out: list[list[int]] = []
    run: list[int] = []
    for u in range(n + 1):
        if u < n and feed[u]:
            run.append(u)
            continue
        idx = [i for i, v in enumerate(run) if cut[v]]
        if idx:
            lo, hi = idx[0], idx[-1]
            if sticky is not None:
                while lo > 0 and sticky[run[lo - 1]]:
                    lo -= 1
                while hi < len(run) - 1 and sticky[run[hi + 1]]:
                    hi += 1
            out.append(run[lo:hi + 1])
        run = []
    return out


def fit_units(units: Units, chains: list, unit: np.ndarray, t: np.ndarray,
              target: np.ndarray, normal: np.ndarray, *, weight: np.ndarray | None = None,
              split: bool = True, hold: OffsetEdit | None = None,
              free: np.ndarray | None = None) -> OffsetEdit:
    """The correction of a path of ``units`` for points asking for moves.

    Parameters
    ----------
    units : Units
    chains : list of list of int
        Runs of joined units to fit (trimmed by the caller to where they cut).
    unit, t : ndarray, shape (q,)
        Each point's unit and fraction along it.
    target : ndarray, shape (q,) [mm]
        The move each point asks for along its ``normal`` (q, 3).
    weight : ndarray, shape (q,), optional
        Factor on each point's ``target`` (the verified loop's fallback); 0: the point
        must not move (its equation asks for no move, weighted ``OFFSET_HOLD``): where
        a correction made the surface worse, the original coordinates there.
    split : bool
        Split straight units whose points ask for more than a straight move.
    hold : OffsetEdit, optional
        A fit of the same units to keep everywhere but near the points ``free`` (q,)
        bool (a fallback's refit: the points whose weight changed): the vertices more
        than ``FALLBACK_FREE_VERTICES`` vertices along their chain from a unit with a
        free point (or a unit split otherwise than in ``hold``) keep ``hold``'s moves
        exactly and the rest is fitted to them, so the refit changes the path there
        only (and its dense prediction recomputes there only, errpred.repredict).
        Ignored (a whole fit) when ``hold`` is not of the same units.
    """
    n = len(units)
    if hold is not None and free is None:
        raise ValueError("fit_units: hold= needs free= (the points whose weight changed)")
    held = np.zeros(unit.size, bool)
    if weight is not None:
        target = target * np.asarray(weight, float)
        held = np.asarray(weight) == 0
    vertices = [units.end, units.start[:1]]          # vertex n: the start of unit 0
    V = n + 1
    split_frac: dict[int, np.ndarray] = {}
    split_vtx: dict[int, np.ndarray] = {}
    movable = np.zeros(n + 1, bool)
    seg_v0, seg_v1, seg_unit, seg_lo, seg_hi = [], [], [], [], []
    chain_vertices, chain_units = [], []
    for chain in chains:
        first = chain[0]
        cv = [first - 1 if first > 0 else n]
        cu = [first]                            # the unit each chain vertex belongs to
        movable[cv[0]] = cv[0] < n
        for u in chain:
            movable[u] = True
            sel = np.flatnonzero(unit == u)
            fr = np.zeros(0)
            if split and sel.size >= 2 and units.splittable[u]:
                tt, tg, nn = t[sel], target[sel], normal[sel]
                prev = np.flatnonzero((unit == u - 1) & (t >= 1.0 - 1e-9))
                if prev.size and not np.any(tt <= 1e-9) and units.joined[u]:
                    # the corner is predicted once, as the end of the unit before
                    tt, tg = np.r_[0.0, tt], np.r_[target[prev[0]], tg]
                    nn = np.vstack([normal[prev[0]], nn])
                fr = split_fractions(float(np.linalg.norm(units.end[u] - units.start[u])),
                                     tt, tg, nn)
            pieces = np.concatenate([[0.0], fr, [1.0]])
            vs = [cv[-1]]
            if fr.size:
                ids = np.arange(V, V + fr.size)
                V += fr.size
                split_frac[u], split_vtx[u] = fr, ids
                vertices.append(units.start[u] + fr[:, None] * (units.end[u] - units.start[u]))
                vs += ids.tolist()
            vs.append(u)
            for j in range(len(vs) - 1):
                seg_v0.append(vs[j])
                seg_v1.append(vs[j + 1])
                seg_unit.append(u)
                seg_lo.append(pieces[j])
                seg_hi.append(pieces[j + 1])
            cv += vs[1:]
            cu += [u] * (len(vs) - 1)
        chain_vertices.append(np.asarray(cv, np.int64))
        chain_units.append(np.asarray(cu, np.int64))
    verts = np.vstack(vertices)
    mov = np.ones(V, bool)
    mov[:n + 1] = movable
    fixed_moves = None
    if hold is not None and _same_units(hold, verts, n):
        free_units = np.zeros(n + 1, bool)
        free_units[np.asarray(unit)[np.asarray(free, bool)]] = True
        fixed_moves = np.zeros((V, 3))
        for u, fr in split_frac.items():
            o = hold.split_fractions.get(u)
            if o is None or not np.array_equal(fr, o):
                free_units[u] = True            # split otherwise: its vertices are new
            else:
                fixed_moves[split_vtx[u]] = hold.moves[hold.split_vertices[u]]
        for u in hold.split_fractions:
            if u not in split_frac:
                free_units[u] = True
        fixed_moves[:n + 1] = hold.moves[:n + 1]
        keep_free = np.zeros(V, bool)
        for cv, cu in zip(chain_vertices, chain_units, strict=True):
            near = free_units[cu].astype(np.int64)
            if near.any():
                # within FALLBACK_FREE_VERTICES of a free unit's vertex along the chain
                k = FALLBACK_FREE_VERTICES
                near = np.convolve(near, np.ones(2 * k + 1, np.int64))[k:k + near.size] > 0
                keep_free[cv[near]] = True
        mov &= keep_free
    seg_unit = np.asarray(seg_unit, np.int64)
    seg_lo, seg_hi = np.asarray(seg_lo), np.asarray(seg_hi)
    # each point on its piece
    first_seg: dict[int, int] = {}
    for s_, u in enumerate(seg_unit):
        first_seg.setdefault(int(u), s_)
    keep = np.array([int(u) in first_seg for u in unit], bool)
    Q = unit.size
    q_seg = np.zeros(Q, np.int64)
    q_t, q_th = np.zeros(Q), np.zeros(Q)
    q_w = np.zeros((Q, 2))
    for q in np.flatnonzero(keep):
        u = int(unit[q])
        s_ = first_seg[u]
        while s_ + 1 < seg_unit.size and seg_unit[s_ + 1] == u and seg_lo[s_ + 1] < t[q]:
            s_ += 1
        span = seg_hi[s_] - seg_lo[s_]
        tt = float(np.clip((t[q] - seg_lo[s_]) / span, 0.0, 1.0)) if span > 0 else 0.0
        q_seg[q], q_t[q], q_w[q] = s_, tt, (tt, 0.0)
        if units.kind[u] != LINE:
            a1, a2, _ = (int(x) for x in units.plane[u])
            c = units.centre[u]
            p = units.point(u, float(t[q]))
            if units.kind[u] == ARC:
                p0, p1 = units.start[u], units.end[u]
                q_w[q] = arc_weights(p0[[a1, a2]], p1[[a1, a2]], p[None, [a1, a2]])[0]
            q_th[q] = math.atan2(p[a2] - c[a2], p[a1] - c[a1])
    pb = OffsetProblem(
        vertices=verts, movable=mov, seg_v0=np.asarray(seg_v0, np.int64),
        seg_v1=np.asarray(seg_v1, np.int64), seg_kind=units.kind[seg_unit].astype(np.int64),
        seg_plane=units.plane[seg_unit].astype(np.int64).reshape(-1, 3),
        seg_centre=units.centre[seg_unit].reshape(-1, 3), chains=chain_vertices,
        pt_seg=q_seg[keep], pt_t=q_t[keep], pt_w=q_w[keep], pt_theta=q_th[keep],
        pt_normal=normal[keep], pt_target=np.where(held[keep], 0.0, target[keep]),
        pt_weight=np.where(held[keep], OFFSET_HOLD, 1.0), fixed_moves=fixed_moves)
    sol = solve_offsets(pb)
    circles = {int(seg_unit[s_]): v for s_, v in sol.circle.items()}
    if fixed_moves is not None:
        # a full circle between held vertices keeps the held change exactly (the solve
        # gives it back within rounding only)
        for u in circles:
            if u in hold.circles and not (mov[u] or mov[u - 1 if u > 0 else n]):
                circles[u] = hold.circles[u]
        mov = np.ones(V, bool)
        mov[:n + 1] = movable
    return OffsetEdit(moves=sol.moves, split_fractions=split_frac, split_vertices=split_vtx,
                      circles=circles, movable=mov, vertices=verts)
