"""The planner's choice among collision-free postures (``orient.plan`` step 5).

The smooth choice of :func:`orient.smoothing.best_smooth_path` is made among the
candidate postures that the interference checker (:mod:`orient.interference`,
FCL) finds free, checking only where needed: each round checks the chosen
postures not known to be free (with the points that take them over: air moves,
approach and retract); where one collides, every remaining candidate of that point
is checked at once and the colliding ones removed, widening the checked window
around a pass that collides again. Points left with no feasible candidate are
infeasible: the plan reports them (``PlanResult.infeasible``) and the command lines
refuse them unless a fallback is allowed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from nc.path import CutterLocations

from .contacts import Contacts
from .interference import InterferenceChecker
from .smoothing import best_smooth_path
from .constants import FALLBACK_SCORE, LINK_VERTICAL_TOL_MM

__all__ = ["FALLBACK_SCORE"]


# why a candidate posture was rejected (PlanResult.reason): codes
_FEASIBLE, _OUTSIDE_INCLINATION, _OUTSIDE_LIMITS, _AT_POLE = 0, 1, 2, 3
#: the first interference code: part p of the tool assembly violates at the cutting
#: point (code _PART + p) or at a point that takes the posture (_PART + n_parts + p)
_PART = 4



def _choose_collision_free(checker: InterferenceChecker, tips: np.ndarray, axes: np.ndarray,
                           inh: _Inherited, ok: np.ndarray, cause: np.ndarray,
                           base_score: np.ndarray, step: np.ndarray, max_rate: float,
                           breaks: np.ndarray, n_parts: int) -> tuple[np.ndarray, dict]:
    """The smooth choice (:func:`best_smooth_path`) among collision-free candidates.

    Each round chooses, then checks the chosen postures not known to be free (each
    with the points that take it over, :func:`_check_candidates`). Where one
    collides, every still-feasible candidate of that touching point is checked and
    the colliding ones are removed; the k-th time (k >= 2) a pass has a colliding
    choice, every candidate within ``2**(k - 2)`` points of it is checked as well,
    so that the smoothing limit cannot push the choice onto untested neighbours
    one point per round. Points left without a feasible candidate take
    the CAM posture (the last column) with :data:`FALLBACK_SCORE` and break the
    smoothness limit on both sides (they must not drag their neighbours along).

    Termination: a pass's choice depends only on its own candidates (rapids
    break the limit); a round goes on only if some pass had a colliding choice
    (every candidate of a completely checked pass is free, so it never has one
    again); by its ``2 + ceil(log2(length))``-th such round a pass's window
    covers it. So there are at most ``1 + passes * (2 + ceil(log2(longest)))``
    rounds (in practice 2: the passes are independent, so all those with a
    colliding choice show in the first round). A round beyond that bound is a
    bug: RuntimeError, never a colliding choice kept silently.

    Parameters
    ----------
    checker : InterferenceChecker
    tips, axes : ndarray, shape (t, s, 3) [mm], [-]
        Candidate postures at the touching points (last column: the CAM's).
    inh : _Inherited
        The points that take a touching point's posture.
    ok : ndarray of bool, shape (t, s)
        Feasible candidates; updated in place (colliding ones become False).
    cause : ndarray of int, shape (t, s)
        Why a candidate is infeasible (codes of :func:`_cause_labels`); updated
        in place.
    base_score : ndarray, shape (t, s)
    step : ndarray, shape (t,) [mm]
    max_rate : float [rad/mm]
    breaks : ndarray of bool, shape (t,)
        Starts of passes.
    n_parts : int
        Parts of the tool assembly.

    Returns
    -------
    choice : ndarray of int, shape (t,)
    stats : dict
        ``rounds``, ``checks`` (postures checked, inherited points included) and
        ``dropped`` (candidates removed for interference).
    """
    t, s = ok.shape
    rows = np.arange(t)
    known = np.zeros((t, s), bool)          # checked (with inherited points): free
    verified = np.zeros(t, bool)            # every candidate checked
    run = np.cumsum(breaks) - (1 if t and breaks[0] else 0)
    start = np.flatnonzero(np.r_[True, breaks[1:]]) if t else np.zeros(0, np.int64)
    length = np.diff(np.r_[start, t])
    strikes = np.zeros(len(start), np.int64)
    bound = 1 + len(start) * (2 + math.ceil(math.log2(max(2, int(length.max(initial=1))))))
    stats = {"rounds": 0, "checks": 0, "dropped": 0}

    def check(r: np.ndarray, c: np.ndarray) -> np.ndarray:
        code, n_checks = _check_candidates(checker, tips, axes, inh, r, c, n_parts)
        stats["checks"] += n_checks
        free = code == _FEASIBLE
        known[r[free], c[free]] = True
        ok[r[~free], c[~free]] = False
        cause[r[~free], c[~free]] = code[~free]
        stats["dropped"] += int(np.count_nonzero(~free))
        return ~free

    while True:
        stats["rounds"] += 1
        if stats["rounds"] > bound:
            raise RuntimeError(f"orient.plan: the interference loop did not end within its "
                               f"bound of {bound} rounds (a bug)")
        none = ~ok.any(axis=1)
        score = np.where(ok, base_score, -np.inf)
        score[none, -1] = FALLBACK_SCORE
        brk = breaks | none
        brk[1:] |= none[:-1]
        choice = best_smooth_path(score, axes, step, max_rate, brk)
        todo = rows[~none & ~known[rows, choice]]
        if len(todo) == 0:
            break
        bad = todo[check(todo, choice[todo])]
        if len(bad) == 0:
            break
        sel = np.zeros(t, bool)
        for g in np.unique(run[bad]):
            w = 0 if strikes[g] == 0 else 2 ** int(strikes[g] - 1)
            strikes[g] += 1
            pos = bad[run[bad] == g]
            lo = np.maximum(pos - w, start[g])
            hi = np.minimum(pos + w, start[g] + length[g] - 1)
            for a_, b_ in zip(lo, hi):
                sel[a_:b_ + 1] = True
        sel &= ~verified
        pr, pc = np.nonzero(ok[sel] & ~known[sel])
        if len(pr):
            check(rows[sel][pr], pc)
        verified |= sel
    return choice, stats


#: kinds of points that take a touching point's posture (:attr:`_Inherited.kind`)
_IN_PASS, _RETRACT, _APPROACH = 0, 1, 2


@dataclass(frozen=True, eq=False)
class _Inherited:
    """The points that take the posture of a touching point.

    * a point of a pass that does not touch the design (air moves, the plunge) takes
      the posture of its pass's nearest touching point, keeping its offset from the
      ball centre (along the axis: along the new axis) -- :data:`_IN_PASS`;
    * a rapid of a link (the rapids between two passes) takes the posture of the pass
      it leaves (:data:`_RETRACT`: its last touching point) up to and including the
      link's highest point, the posture of the pass it enters (:data:`_APPROACH`: its
      first touching point) after it. Where its CAM ball centre is straight above the
      pass's end (its last point, or its first; within ``LINK_VERTICAL_TOL_MM``: a
      3-axis program's retract and approach), it keeps the CAM's ball centre, so the tool leaves the pass
      straight up without turning (the ball sweeps what the CAM's did; the rest of the
      tool, clear at the cut, rises above a 3-axis part), the rotary axes turn in the
      move leaving the link's top (the ball no lower than there), and it descends
      straight down in the new pass's posture. Elsewhere (a 5-axis program's link along
      its tool axis) it keeps its offset as a point of a pass does. (A pass that ended
      tilted and turned during its retract swung the tool through the flank's stock on
      a head machine; retracting along the tilted axis dragged the ball through it: the
      mold core's raster with the pole floor.) The link's last point always takes the
      entered pass's posture: the turn is in a rapid, never in the feed move after it. A
      link before the first pass approaches, one after the last pass retracts; a pass
      without a touching point leaves its link points at the CAM posture.

    Attributes
    ----------
    point : ndarray of int, shape (m,)
        Index into the path.
    row : ndarray of int, shape (m,)
        Row (index into the touching points) whose posture it takes.
    base : ndarray, shape (m, 3) [mm]
        The ball centre of that touching point plus the point's offset from it normal
        to the CAM axis; on a link straight above its pass's end: the CAM's ball
        centre.
    along : ndarray, shape (m,) [mm]
        The tip's offset from ``base`` along the new axis (the offset along the CAM
        axis; on a link straight above: minus the ball radius).
    order, start : ndarray of int
        ``point[order[start[r]:start[r + 1]]]`` are the points of row ``r``.
    kind : ndarray of int, shape (m,), optional
        :data:`_IN_PASS`, :data:`_RETRACT` or :data:`_APPROACH` (None: all in a pass).
    """

    point: np.ndarray
    row: np.ndarray
    base: np.ndarray
    along: np.ndarray
    order: np.ndarray
    start: np.ndarray
    kind: np.ndarray | None = None

    def tips(self, k: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Tips [mm] of inherited points ``k`` (indices into ``point``) at axes ``u``."""
        return self.base[k] + self.along[k][:, None] * u


def _links(rapid: np.ndarray, touching: np.ndarray, centre_z: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The link points that take a touching point's posture (:class:`_Inherited`):
    points, the touching point whose posture each takes, their kinds, and the point of
    that pass next to the link (its last point, or its first)."""
    n = len(rapid)
    pts, nears, kinds, anchors = [], [], [], []
    edge = np.diff(np.r_[0, rapid.astype(np.int8), 0])
    starts, ends = np.flatnonzero(edge == 1), np.flatnonzero(edge == -1) - 1
    tpos = np.flatnonzero(touching)
    for k, (a, b) in enumerate(zip(starts, ends)):
        lo = ends[k - 1] + 1 if k else 0                 # the pass it leaves: [lo, a)
        hi = starts[k + 1] if k + 1 < len(starts) else n  # the pass it enters: (b, hi)
        i = np.searchsorted(tpos, a)
        prev = int(tpos[i - 1]) if i and tpos[i - 1] >= lo else -1
        j = np.searchsorted(tpos, b + 1)
        nxt = int(tpos[j]) if j < len(tpos) and tpos[j] < hi else -1
        link = np.arange(a, b + 1)
        if hi == b + 1:
            top = b                                       # after the last pass: all retract
        elif lo == a:
            top = a - 1                                   # before the first pass: all approach
        else:
            z = centre_z[link]
            top = a + int(np.flatnonzero(z >= z.max() - 1e-9)[0])
            top = min(top, b - 1)                         # the last point: the new posture
        for sel, near, kind, anchor in ((link[link <= top], prev, _RETRACT, a - 1),
                                        (link[link > top], nxt, _APPROACH, b + 1)):
            if near >= 0 and len(sel):
                pts.append(sel)
                nears.append(np.full(len(sel), near))
                kinds.append(np.full(len(sel), kind))
                anchors.append(np.full(len(sel), anchor))
    if not pts:
        return (np.zeros(0, np.int64),) * 4
    return (np.concatenate(pts), np.concatenate(nears), np.concatenate(kinds),
            np.concatenate(anchors))


def _inherited(cam: CutterLocations, contacts: Contacts, idx: np.ndarray) -> _Inherited:
    """:class:`_Inherited` of the path (``idx``: the touching points, ascending)."""
    n = len(cam)
    rapid = np.asarray(cam.rapid, bool)
    pos = np.arange(n)
    touching = np.zeros(n, bool)
    touching[idx] = True
    run = np.cumsum(rapid)              # a pass: from a rapid to the next
    pts, nears = [], []
    for r in np.unique(run[~rapid]):
        members = np.flatnonzero((run == r) & ~rapid)
        t_in = members[touching[members]]
        if len(t_in) == 0:
            continue
        others = members[~touching[members]]
        pts.append(others)
        nears.append(t_in[np.argmin(np.abs(pos[others][:, None] - t_in[None, :]), axis=1)])
    point = np.concatenate(pts) if pts else np.zeros(0, np.int64)
    near = np.concatenate(nears) if nears else np.zeros(0, np.int64)
    centre_old = contacts.centre[near]
    rel = cam.tip[point] - centre_old
    along = np.sum(rel * cam.axis[near], axis=1)
    perp = rel - along[:, None] * cam.axis[near]
    l_pt, l_near, l_kind, l_anchor = _links(rapid, touching, contacts.centre[:, 2])
    # on a link: straight above the pass's end (a 3-axis retract or approach), the
    # CAM's ball centre, the tip a ball radius below it along the new axis; elsewhere
    # (e.g. a 5-axis program's retract along its tool axis) as in a pass
    c_near = contacts.centre[l_near]
    l_rel = cam.tip[l_pt] - c_near
    l_along = np.sum(l_rel * cam.axis[l_near], axis=1)
    l_base = c_near + l_rel - l_along[:, None] * cam.axis[l_near]
    up = contacts.centre[l_pt] - contacts.centre[l_anchor]
    vertical = (np.hypot(up[:, 0], up[:, 1]) <= LINK_VERTICAL_TOL_MM) & (up[:, 2] > 0)
    radius = np.linalg.norm(contacts.centre[l_pt] - cam.tip[l_pt], axis=1)
    l_base[vertical] = contacts.centre[l_pt][vertical]
    l_along[vertical] = -radius[vertical]
    point = np.concatenate([point, l_pt])
    row = np.searchsorted(idx, np.concatenate([near, l_near]))
    base = np.concatenate([centre_old + perp, l_base])
    along = np.concatenate([along, l_along])
    kind = np.concatenate([np.full(len(near), _IN_PASS), l_kind]).astype(np.int8)
    order = np.argsort(row, kind="stable")
    start = np.searchsorted(row[order], np.arange(len(idx) + 1))
    return _Inherited(point, row, base.reshape(-1, 3), along, order, start, kind)


def _check_candidates(checker: InterferenceChecker, tips: np.ndarray, axes: np.ndarray,
                      inh: _Inherited, rows: np.ndarray, cols: np.ndarray, n_parts: int
                      ) -> tuple[np.ndarray, int]:
    """Interference of candidates ``(rows[k], cols[k])`` at their touching point and at
    every point that would take them over (:class:`_Inherited`), in one batch.

    Returns
    -------
    code : ndarray of int, shape (k,)
        ``_FEASIBLE``, ``_PART + p`` (part p violates at the touching point) or
        ``_PART + n_parts + p`` (at an inherited point; the part nearest the tip).
    checks : int
        Postures checked.
    """
    res = checker.check(tips[rows, cols], axes[rows, cols])
    code = np.where(res.part >= 0, _PART + res.part, _FEASIBLE).astype(np.int16)
    cnt = np.diff(inh.start)[rows]
    total = int(cnt.sum())
    if total:
        pair = np.repeat(np.arange(len(rows)), cnt)
        off = np.arange(total) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        k = inh.order[np.repeat(inh.start[rows], cnt) + off]
        u = axes[rows[pair], cols[pair]]
        rd = checker.check(inh.tips(k, u), u)
        hit = rd.part >= 0
        dep = np.full(len(rows), np.iinfo(np.int16).max, np.int16)
        np.minimum.at(dep, pair[hit], (_PART + n_parts + rd.part[hit]).astype(np.int16))
        code = np.where((code == _FEASIBLE) & (dep < np.iinfo(np.int16).max), dep, code)
    return code, len(rows) + total


def _cause_labels(part_names: tuple[str, ...]) -> list[str]:
    """Text of each rejection code (index = code)."""
    what = {"flank": "flank gouges the design", "shank": "shank against the stock",
            "holder": "holder against the stock"}
    at_point = [what.get(p, f"{p} collides") for p in part_names]
    return (["feasible", "outside the inclination range", "outside the axis limits",
             "within the pole floor of the machine's rotary axis"]
            + at_point + [f"{w} at a non-cutting point taking this posture"
                          for w in at_point])


