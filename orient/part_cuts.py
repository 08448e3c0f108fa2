"""The local cut at each cutter location from the part: the in-process stock.

A scenario without ``[orient.cut]`` gets its cut here, per cutter location, from the
stock mesh and the program's earlier moves as errpred sees them (errpred's stock,
``errpred.raster.meshes.Stock.contains``, and its swept tool solids,
``errpred.sweeps``: the same membership errpred's engagement is rasterized from),
instead of one table for the program. In the local frame ``(f, b, n)`` of the contact
(:func:`orient.geometry.local_frame`), with "before this pass" meaning the stock minus
every earlier move but the pass's own trail (the moves of the current pass within
``PART_CUT_OWN_TRAIL_RADII`` tool radii of path behind; a pass ends at a rapid or where
the path turns by more than ``PART_CUT_PASS_TURN_DEG``):

* **depth and curvatures** (:class:`orient.engagement.LocalCut`'s stock top): the
  stock's top above the contact along ``n`` (found by bisection up a column), and its
  curvature along ``f`` and ``b`` from its top ``PART_CUT_CURVATURE_SPAN_RADII`` tool
  radii either side, turned into the finished surface's (convex up to
  ``PART_CUT_MAX_CURVATURE_RADII``, concave up to ``PART_CUT_MAX_CONCAVE_RADII`` over
  the tool radius, see :meth:`_Section.stock_tops`);
* **previous pass, its side and the pick feed**: the nearest earlier move running
  within ``PART_CUT_PASS_TURN_DEG`` of the feed (either way) whose ball centre crosses
  the plane through the centre normal to ``f`` within a tool diameter: its offset along
  ``b`` is the pick feed, its sign the side (the previous pass lies at
  ``previous_side * pick * b``, so passes going the other way get the other side);
  none (a first pass): side 0;
* **air, entry, exit**: the ball meets no material before this pass on its front lower
  quarter (where a ball end mill cuts) nor above its profile in the centre's section
  -> air, depth 0 (no cut); material ahead but not yet at the centre's section, or the
  cutter location before it on the path in air (or not touching the design) -> entry;
  the one after it -> exit.

Limits: a previous pass is one line parallel to this one, shifted along ``b`` (as in
the kernels); material an earlier operation removed across the pass (a raster over a
contoured flank) is not subtracted from the depth, only air is told (conservative:
the full cut's process gain is the larger); an entry or exit keeps the full cut (its
gain is the larger too).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from errpred import constants as EK
from errpred.sweeps import build_sweeps, inside_any_sweep, read_only
from errpred.tool import Tool
from nc.path import CutterLocations

from .constants import (
    PART_CUT_BISECTIONS,
    PART_CUT_CHUNK,
    PART_CUT_COLUMNS,
    PART_CUT_CURVATURE_SPAN_RADII,
    PART_CUT_MAX_CONCAVE_RADII,
    PART_CUT_MAX_CURVATURE_RADII,
    PART_CUT_MIN_DEPTH_MM,
    PART_CUT_MIN_PICK_MM,
    PART_CUT_OWN_TRAIL_RADII,
    PART_CUT_PASS_TURN_DEG,
    PART_CUT_SHELL_STEPS,
    PART_CUT_TOP_CHUNK,
)
from .contacts import Contacts
from .geometry import local_frame

__all__ = ["AIR", "CUT", "ENTRY", "EXIT", "STATE_NAMES", "PartCuts", "cuts_from_part",
           "pass_starts"]

#: :attr:`PartCuts.state` values.
AIR, CUT, ENTRY, EXIT = 0, 1, 2, 3
STATE_NAMES = ("air", "cut", "entry", "exit")


@dataclass(frozen=True, eq=False)
class PartCuts:
    """The local cut from the part at cutter locations ``index``.

    Attributes
    ----------
    index : ndarray of int, shape (t,)
        Cutter locations (indices into the path).
    depth_mm : ndarray, shape (t,) [mm]
        The stock's top above the contact along the normal (0 in air).
    pick_mm : ndarray, shape (t,) [mm]
        Offset along ``b`` of the previous pass (where there is none: the median of
        the others, or 0).
    previous_side : ndarray of int8, shape (t,)
        +1 or -1: the previous pass lies at ``previous_side * pick * b``; 0: none.
    state : ndarray of int8, shape (t,)
        :data:`AIR`, :data:`CUT`, :data:`ENTRY` or :data:`EXIT`.
    curvature_f_1_mm, curvature_b_1_mm : ndarray, shape (t,) [1/mm]
        The finished surface's normal curvatures along ``f`` and ``b`` (positive
        convex), from the stock's top.
    seconds : float [s]
        Time taken.
    """

    index: np.ndarray
    depth_mm: np.ndarray
    pick_mm: np.ndarray
    previous_side: np.ndarray
    state: np.ndarray
    curvature_f_1_mm: np.ndarray
    curvature_b_1_mm: np.ndarray
    seconds: float

    def counts(self) -> dict[str, int]:
        """Cutter locations per state name."""
        return {name: int(np.sum(self.state == k)) for k, name in enumerate(STATE_NAMES)}


def pass_starts(cl: CutterLocations, turn_deg: float = PART_CUT_PASS_TURN_DEG) -> np.ndarray:
    """Per cutter location, the first move of its pass (the index of the cutter location
    that move ends at), shape (n,): a pass ends at a rapid or where the path turns by
    more than ``turn_deg`` [deg] between two moves (zero-length moves keep the pass)."""
    n = len(cl)
    brk = np.ones(n, bool)
    if n > 1:
        seg = np.zeros((n, 3))
        seg[1:] = np.diff(cl.tip, axis=0)
        ln = np.linalg.norm(seg, axis=1)
        unit = np.divide(seg, ln[:, None], out=np.zeros_like(seg), where=ln[:, None] > 0)
        # the last non-zero move's direction carried over standstills
        last = np.maximum.accumulate(np.where(ln > 0, np.arange(n), 0))
        prev_dir = np.zeros((n, 3))
        prev_dir[1:] = unit[last[:-1]]
        cos = np.sum(unit * prev_dir, axis=1)
        turn = (ln > 0) & (np.linalg.norm(prev_dir, axis=1) > 0) & (
            cos < math.cos(math.radians(turn_deg)))
        rapid = np.asarray(cl.rapid, bool)
        brk[1:] = rapid[1:] | rapid[:-1] | turn[1:]
    return np.maximum.accumulate(np.where(brk, np.arange(n), 0))


def cuts_from_part(tool: Tool, stock, cl: CutterLocations, contacts: Contacts,
                   index: np.ndarray, sweeps=None) -> PartCuts:
    """Depth, curvatures, pick feed, side of the previous pass and air/entry/exit at the
    cutter locations ``index`` from the in-process stock (module docstring).

    Parameters
    ----------
    tool : errpred.tool.Tool
        A ball end mill.
    stock : errpred.raster.meshes.Stock
        The stock before the program.
    cl : CutterLocations
        The whole program's path (every earlier move counts).
    contacts : Contacts
        The ball's contacts along ``cl`` (:func:`orient.contacts.ball_contacts`); only
        those at ``index`` are read.
    index : array_like of int, shape (t,)
        Cutter locations to derive the cut at (touching ones).
    sweeps : errpred.sweeps.Sweeps, optional
        ``build_sweeps(cl, tool)`` when already built.

    Returns
    -------
    PartCuts
    """
    t0 = time.perf_counter()
    if tool.kind != "ball":
        raise ValueError(f"tool: the cut from the part is derived for ball end mills, got "
                         f"{tool.kind!r}")
    idx = np.asarray(index, dtype=np.int64).reshape(-1)
    R = tool.radius_mm
    sw = build_sweeps(cl, tool) if sweeps is None else sweeps
    seg = np.zeros(len(cl))
    if len(cl) > 1:
        seg[1:] = np.linalg.norm(np.diff(cl.tip, axis=0), axis=1)
    path = np.cumsum(seg)
    first = pass_starts(cl)
    # the first move of each location's own trail: its pass's, within the window
    trail = np.searchsorted(path, path - PART_CUT_OWN_TRAIL_RADII * R, side="right")
    own_first = np.maximum(first, trail)
    t = len(idx)
    out = {k: np.zeros(t) for k in ("depth", "kf", "kb")}
    pick = np.full(t, np.nan)
    side = np.zeros(t, np.int8)
    engaged = np.zeros(t, bool)
    ahead_only = np.zeros(t, bool)
    if t:
        f_all, b_all, n_all = local_frame(contacts.normal[idx], contacts.feed[idx])
    geo = _Section(R)
    tail = (tool.core_radius_mm, tool.corner_radius_mm, tool.flute_length_mm,
            EK.MEMBERSHIP_EPS_MM)
    cos_par = math.cos(math.radians(PART_CUT_PASS_TURN_DEG))

    def _one(r, i, t1, piece_end, t1_end) -> None:
        c = contacts.centre[i]
        f, b, n = f_all[r], b_all[r], n_all[r]
        # this location's earlier moves: before its own trail, near its ball
        keep = (piece_end <= t1_end) & np.all(t1[3] <= c + R, axis=1) & np.all(
            t1[4] >= c - R, axis=1)
        # the sweeps read-only, as errpred's own: the membership test's callees compiled
        # once for both (numba types read-only arrays apart)
        parts = tuple(np.ascontiguousarray(a[keep]) for a in t1)
        read_only(*parts[:3])

        def material(pts: np.ndarray) -> np.ndarray:
            pts = np.ascontiguousarray(pts)
            inside = stock.contains(pts)
            if parts[0].shape[0] and inside.any():
                inside &= ~inside_any_sweep(pts, inside.copy(), *parts, *tail)
            return inside

        contact = c - R * n
        mid, front = geo.engaged(material, contact, c, f, b, n)
        engaged[r] = mid or front
        ahead_only[r] = front and not mid
        if parts[0].shape[0]:
            side[r], pick[r] = _previous_pass(parts[0], parts[1], parts[2], c, f, b, n, R,
                                              cos_par)

    reach = math.sqrt(2.0) * R + 1e-6     # every point tested lies this close to its centre
    for start in range(0, t, PART_CUT_CHUNK):
        rows = np.arange(start, min(start + PART_CUT_CHUNK, t))
        # the earlier moves that may reach the chunk's balls, nearest its middle first,
        # looked up once for the chunk (about 7 ms on mold-ball's flanks)
        cs = contacts.centre[idx[rows]]
        lo_c, hi_c = cs.min(axis=0) - R, cs.max(axis=0) + R
        mid = 0.5 * (lo_c + hi_c)
        ends = np.array([path[own_first[i] - 1] if own_first[i] >= 1 else -math.inf
                         for i in idx[rows]])
        t1, _, ids1 = sw.near(lo_c, hi_c, mid, 0.5 * float(np.linalg.norm(hi_c - lo_c))
                              + reach, mid, float(ends.max()), math.inf)
        piece_end = sw.path_end[ids1]
        for r, t1_end in zip(rows, ends):
            i = idx[r]
            _one(r, i, t1, piece_end, t1_end)
    # the stock's top at the engaged locations, PART_CUT_TOP_CHUNK at once: it reads the
    # stock before the program alone, so one bisection serves them all (one location at
    # a time: 17 calls of the mesh's test each, half the time of the part's cuts)
    engaged_rows = np.flatnonzero(engaged)
    for start in range(0, engaged_rows.size, PART_CUT_TOP_CHUNK):
        on = engaged_rows[start:start + PART_CUT_TOP_CHUNK]
        n_on = n_all[on]
        out["depth"][on], out["kf"][on], out["kb"][on] = geo.stock_tops(
            stock.contains, contacts.centre[idx[on]] - R * n_on, f_all[on], b_all[on], n_on)
    found = np.isfinite(pick)
    fill = float(np.median(pick[found])) if found.any() else 0.0
    pick = np.where(found, pick, fill)
    state = _states(engaged, idx, ahead_only)
    return PartCuts(idx, out["depth"], pick, side, state, out["kf"], out["kb"],
                    time.perf_counter() - t0)


class _Section:
    """The sample points of one cutter location, in the local frame (made once)."""

    def __init__(self, R: float) -> None:
        self.R = R
        eps = PART_CUT_MIN_DEPTH_MM
        y = np.linspace(-R, R, PART_CUT_COLUMNS)[1:-1]
        # the foot of each column: just above the ball's profile in the centre's section
        self.y = y
        self.t_foot = R - np.sqrt(R * R - y ** 2) + eps
        # the ball's front lower quarter: polar angle from -n, azimuth over the f side
        k = PART_CUT_SHELL_STEPS
        pol = (np.arange(k) + 0.5) / k * (math.pi / 2)
        azi = (np.arange(k) + 0.5) / k * math.pi - math.pi / 2
        P, A = np.meshgrid(pol, azi, indexing="ij")
        inner = R - 2 * eps
        # coordinates along (f, b, n) from the ball centre
        self.shell = inner * np.stack([np.sin(P) * np.cos(A), np.sin(P) * np.sin(A),
                                       -np.cos(P)], axis=-1).reshape(-1, 3)
        h = PART_CUT_CURVATURE_SPAN_RADII * R
        self.h = h
        # the stock-top columns: the contact, then +-h along f, then +-h along b
        self.top_fb = np.array([[0, 0], [h, 0], [-h, 0], [0, h], [0, -h]], dtype=float)

    def engaged(self, material, contact, centre, f, b, n) -> tuple[bool, bool]:
        """Is there material before this pass above the ball's profile in the centre's
        section, and on the ball's front lower quarter?"""
        cols = contact + self.y[:, None] * b + self.t_foot[:, None] * n
        shell = centre + self.shell @ np.stack([f, b, n])
        inside = material(np.concatenate([cols, shell]))
        return bool(inside[:len(cols)].any()), bool(inside[len(cols):].any())

    def stock_tops(self, contains, contact, f, b, n) -> tuple[np.ndarray, np.ndarray,
                                                               np.ndarray]:
        """The stock's top above each contact along its ``n`` [mm], and the finished
        surface's curvatures along ``f`` and ``b`` [1/mm] from the stock's top either side.

        ``contact``, ``f``, ``b``, ``n``: shape (k, 3), one row a location; the answers,
        shape (k,) each, are each row's alone (every point is tested on its own)."""
        R, eps = self.R, PART_CUT_MIN_DEPTH_MM
        n3 = n[:, None, :]
        base = (contact[:, None, :] + self.top_fb[None, :, :1] * f[:, None, :]
                + self.top_fb[None, :, 1:] * b[:, None, :])                  # (k, 5, 3)
        shape = base.shape[:2]

        def inside(along: np.ndarray) -> np.ndarray:
            return contains((base + along[..., None] * n3).reshape(-1, 3)).reshape(shape)

        # from just above the contact, and beside it from as deep as the surface can lie
        # under the clamped curvature (0.45 h^2 / R), up to one tool radius
        lo = np.full(shape, -self.h ** 2 / R)
        lo[:, 0] = 0.5 * eps
        hi = np.full(shape, R)
        has_lo = inside(lo)
        has_hi = inside(hi)
        # the top is where the column leaves the stock
        for _ in range(PART_CUT_BISECTIONS + 1):
            mid = 0.5 * (lo + hi)
            ok = inside(mid)
            lo = np.where(ok, mid, lo)
            hi = np.where(ok, hi, mid)
        top = np.where(has_hi, R, np.where(has_lo, 0.5 * (lo + hi), -math.inf))
        depth, kf, kb = np.zeros(shape[0]), np.zeros(shape[0]), np.zeros(shape[0])
        kmax = PART_CUT_MAX_CURVATURE_RADII / R
        for q in range(shape[0]):
            d = float(top[q, 0])
            if not d > eps:
                depth[q] = max(d, 0.0)
                continue
            depth[q] = d
            ks = []
            for a, b_ in ((1, 2), (3, 4)):
                # the stock top's curvature (positive convex), both sides if it has them
                sides = [top[q, k] for k in (a, b_)
                         if np.isfinite(top[q, k]) and top[q, k] < R]
                kappa = 2.0 * (d - float(np.mean(sides))) / self.h ** 2 if sides else 0.0
                k = kappa / (1.0 - kappa * d) if 1.0 - kappa * d > 0 else kmax
                ks.append(float(np.clip(k, -PART_CUT_MAX_CONCAVE_RADII / R, kmax)))
            kf[q], kb[q] = ks
        return depth, kf, kb


def _previous_pass(p0, d, w, c, f, b, n, R, cos_par) -> tuple[int, float]:
    """Side and offset along ``b`` of the nearest earlier move (tips ``p0``, moves
    ``d``, axes ``w``) running along ``+-f`` whose ball centre crosses the plane through
    ``c`` normal to ``f`` within ``2 R``; (0, nan) if none."""
    q0 = p0 + R * w                           # ball centres (a ball's core radius is 0)
    ln = np.linalg.norm(d, axis=1)
    s0 = (q0 - c) @ f
    s1 = s0 + d @ f
    par = np.abs(d @ f) >= cos_par * np.maximum(ln, 1e-300)
    cross = par & (ln > 0) & (np.minimum(s0, s1) <= 0) & (np.maximum(s0, s1) >= 0) & (s0 != s1)
    if not cross.any():
        return 0, math.nan
    k = np.flatnonzero(cross)
    q = q0[k] + (s0[k] / (s0[k] - s1[k]))[:, None] * d[k]
    lat = (q - c) @ b
    nor = (q - c) @ n
    dist = np.hypot(lat, nor)
    keep = (dist < 2 * R) & (np.abs(lat) >= PART_CUT_MIN_PICK_MM)
    if not keep.any():
        return 0, math.nan
    j = np.flatnonzero(keep)[np.argmin(dist[keep])]
    return int(np.sign(lat[j])), float(abs(lat[j]))


def _states(engaged: np.ndarray, idx: np.ndarray, ahead_only: np.ndarray) -> np.ndarray:
    """Air, cut, entry or exit from the neighbouring cutter locations along the path
    (among ``idx``: a rapid or a location not touching the design between them breaks
    the run; a corner in the material does not)."""
    t = len(idx)
    state = np.where(engaged, CUT, AIR).astype(np.int8)
    run_prev = np.zeros(t, bool)
    run_prev[1:] = (idx[1:] == idx[:-1] + 1) & engaged[:-1]
    run_next = np.zeros(t, bool)
    run_next[:-1] = (idx[1:] == idx[:-1] + 1) & engaged[1:]
    entry = engaged & (~run_prev | ahead_only)
    exit_ = engaged & ~run_next & ~entry
    state[entry] = ENTRY
    state[exit_] = EXIT
    return state
