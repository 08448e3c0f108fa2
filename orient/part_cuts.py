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

* **depth**: the height above the contact plane of the material left before this pass,
  measured up ``PART_CUT_COLUMNS`` columns across the ball's cross-section (sampled,
  then bisected), the highest among the columns the ball reaches (its top above the
  ball's profile there);
* **previous pass, its side and the pick feed**: the nearest earlier move running
  within 45 deg of the feed (either way) whose ball centre crosses the cross-section
  within a tool diameter of the centre: its offset along ``b`` is the pick feed, its
  sign the side (``LocalCut.previous_side``: the previous pass lies at
  ``previous_side * pick * b``, so passes going the other way get the other side);
  none (a first pass): side 0;
* **air, entry, exit**: the ball meets no material before this pass on its front
  lower quarter (where a ball end mill cuts) -> air, depth 0 (no cut); the pass's
  neighbouring cutter location in air (or none) behind -> entry, ahead -> exit.

Limits: the finished surface is taken as the contact plane (on a curved part a
column ``y`` from the contact is off it by ``k y^2 / 2``: 0.04 mm at 1.2 mm for
``k = 1/20 mm``), a previous pass is one line parallel to this one (a crossing pass
of another operation shows in the depth only), and an entry or exit keeps the full
cut (conservative: the process gain of a partial cut is smaller).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from errpred import constants as EK
from errpred.sweeps import build_sweeps, inside_any_sweep
from errpred.tool import Tool
from nc.path import CutterLocations

from .constants import (
    PART_CUT_BISECTIONS,
    PART_CUT_COLUMNS,
    PART_CUT_MIN_DEPTH_MM,
    PART_CUT_MIN_PICK_MM,
    PART_CUT_OWN_TRAIL_RADII,
    PART_CUT_PASS_TURN_DEG,
    PART_CUT_SCAN_SAMPLES,
    PART_CUT_SHELL_STEPS,
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
        Material above the finished surface in the ball's reach before this pass
        (0 in air).
    pick_mm : ndarray, shape (t,) [mm]
        Offset along ``b`` of the previous pass (where there is none: the median of
        the others, or 0).
    previous_side : ndarray of int8, shape (t,)
        +1 or -1: the previous pass lies at ``previous_side * pick * b``; 0: none.
    state : ndarray of int8, shape (t,)
        :data:`AIR`, :data:`CUT`, :data:`ENTRY` or :data:`EXIT`.
    seconds : float [s]
        Time taken.
    """

    index: np.ndarray
    depth_mm: np.ndarray
    pick_mm: np.ndarray
    previous_side: np.ndarray
    state: np.ndarray
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
    """Depth, pick feed, side of the previous pass and air/entry/exit at the cutter
    locations ``index`` from the in-process stock (module docstring).

    Parameters
    ----------
    tool : errpred.tool.Tool
        A ball end mill.
    stock : errpred.raster.meshes.Stock
        The stock before the program.
    cl : CutterLocations
        The whole program's path (every earlier move counts).
    contacts : Contacts
        The ball's contacts along ``cl`` (:func:`orient.contacts.ball_contacts`).
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
    depth = np.zeros(t)
    pick = np.full(t, np.nan)
    side = np.zeros(t, np.int8)
    engaged = np.zeros(t, bool)
    if t == 0:
        return PartCuts(idx, depth, np.zeros(0), side, np.zeros(0, np.int8),
                        time.perf_counter() - t0)
    f_all, b_all, n_all = local_frame(contacts.normal[idx], contacts.feed[idx])
    geo = _Section(R)
    tail = (tool.core_radius_mm, tool.corner_radius_mm, tool.flute_length_mm,
            EK.MEMBERSHIP_EPS_MM)
    cos_par = math.cos(math.radians(PART_CUT_PASS_TURN_DEG))
    for r, i in enumerate(idx):
        c = contacts.centre[i]
        f, b, n = f_all[r], b_all[r], n_all[r]
        # the sweeps that may reach the sample points (all within the ball's box)
        ids = sw.query(c - R, c + R)
        ids = ids[sw.cl_index[ids] < own_first[i]]
        parts = tuple(np.ascontiguousarray(a[ids]) for a in (sw.p0, sw.d, sw.w, sw.lo, sw.hi))

        def material(pts: np.ndarray, parts=parts) -> np.ndarray:
            pts = np.ascontiguousarray(pts)
            inside = stock.contains(pts)
            if parts[0].shape[0] and inside.any():
                inside &= ~inside_any_sweep(pts, inside, *parts, *tail)
            return inside

        contact = c - R * n
        d_mid, mid_eng, d_front, front_eng = geo.measure(material, contact, c, f, b, n)
        engaged[r] = mid_eng or front_eng
        depth[r] = d_mid if mid_eng else (d_front if front_eng else 0.0)
        if ids.size:
            s, p = _previous_pass(sw, ids, c, f, b, n, R, cos_par)
            side[r], pick[r] = s, p
    found = np.isfinite(pick)
    fill = float(np.median(pick[found])) if found.any() else 0.0
    pick = np.where(found, pick, fill)
    depth = np.minimum(depth, R)
    depth[~engaged] = 0.0
    state = _states(engaged, first[idx], idx)
    return PartCuts(idx, depth, pick, side, state, time.perf_counter() - t0)


class _Section:
    """The sample points of one cutter location, in the local frame (made once)."""

    def __init__(self, R: float) -> None:
        self.R = R
        self.y = np.linspace(-R, R, PART_CUT_COLUMNS)
        # from just above the contact plane (the finished surface's material counts)
        self.t = PART_CUT_MIN_DEPTH_MM / 2 + np.arange(PART_CUT_SCAN_SAMPLES) * (
            R / PART_CUT_SCAN_SAMPLES)
        self.step = R / PART_CUT_SCAN_SAMPLES
        with np.errstate(invalid="ignore"):
            self.t_ball = R - np.sqrt(np.maximum(R * R - self.y ** 2, 0.0))
        # the ball's front lower quarter: polar angle from -n, azimuth over the f side
        k = PART_CUT_SHELL_STEPS
        pol = (np.arange(k) + 0.5) / k * (math.pi / 2)
        azi = (np.arange(k) + 0.5) / k * math.pi - math.pi / 2
        P, A = np.meshgrid(pol, azi, indexing="ij")
        inner = R - 2 * PART_CUT_MIN_DEPTH_MM
        # coordinates along (f, b, n) from the ball centre
        self.shell = inner * np.stack([np.sin(P) * np.cos(A), np.sin(P) * np.sin(A),
                                       -np.cos(P)], axis=-1).reshape(-1, 3)

    def measure(self, material, contact, centre, f, b, n):
        """(depth at the centre's section, whether the ball reaches it there, highest
        material on the front shell, whether there is any) [mm]."""
        R, y, tt = self.R, self.y, self.t
        K = tt.size
        cols = contact + y[:, None, None] * b + tt[None, :, None] * n      # (C, K, 3)
        shell = centre + self.shell @ np.stack([f, b, n])
        inside = material(np.concatenate([cols.reshape(-1, 3), shell]))
        m = inside[:cols.shape[0] * K].reshape(cols.shape[:2])
        sh = inside[cols.shape[0] * K:]
        # the first run of material from the bottom of each column
        run = np.cumprod(m, axis=1).astype(bool)
        last = run.sum(axis=1) - 1                                         # -1: none
        has = last >= 0
        top = np.zeros(y.size)
        lo = tt[np.maximum(last, 0)]
        full = has & (last == K - 1)
        top[full] = R
        open_ = np.flatnonzero(has & ~full)
        if open_.size:
            a, hi = lo[open_].copy(), lo[open_] + self.step
            for _ in range(PART_CUT_BISECTIONS):
                mid = 0.5 * (a + hi)
                ok = material(contact + y[open_, None] * b + mid[:, None] * n)
                a = np.where(ok, mid, a)
                hi = np.where(ok, hi, mid)
            top[open_] = 0.5 * (a + hi)
        reach = has & (top > self.t_ball + PART_CUT_MIN_DEPTH_MM)
        d_mid = float(top[reach].max()) if reach.any() else 0.0
        d_front = float(((shell[sh] - contact) @ n).max()) if sh.any() else 0.0
        return d_mid, bool(reach.any()), max(d_front, 0.0), bool(sh.any())


def _previous_pass(sw, ids, c, f, b, n, R, cos_par) -> tuple[int, float]:
    """Side and offset along ``b`` of the nearest earlier move running along ``+-f``
    whose ball centre crosses the plane through ``c`` normal to ``f`` within ``2 R``;
    (0, nan) if none."""
    w = sw.w[ids]
    q0 = sw.p0[ids] + R * w                   # ball centres (a ball's core radius is 0)
    d = sw.d[ids]
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


def _states(engaged: np.ndarray, pass_first: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Air, cut, entry or exit from the neighbours on the same pass (among ``idx``)."""
    t = len(idx)
    state = np.where(engaged, CUT, AIR).astype(np.int8)
    same_prev = np.zeros(t, bool)
    same_prev[1:] = (pass_first[1:] == pass_first[:-1]) & (idx[1:] == idx[:-1] + 1)
    prev_air = np.ones(t, bool)
    prev_air[1:] = ~engaged[:-1]
    next_air = np.ones(t, bool)
    next_air[:-1] = ~engaged[1:]
    same_next = np.zeros(t, bool)
    same_next[:-1] = same_prev[1:]
    entry = engaged & (~same_prev | prev_air)
    exit_ = engaged & (~same_next | next_air) & ~entry
    state[entry] = ENTRY
    state[exit_] = EXIT
    return state
