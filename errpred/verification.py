"""Verify a corrected program against its original, densely, before it is written.

A correction is verified on the program that would be cut: it is re-predicted
with points at most ``VERIFY_SPACING_MM`` apart on every block, both ends
included (:meth:`errpred.geometry.Resolution.dense`), and so is the original.
Every error is measured against the *original* path's surface, the one the
CAM meant (:func:`error_field`): the prediction at a point plus how far the
corrected path moved there along the normal (the point's tool tip projected
onto the original path, :func:`locate_on_path`).

:func:`compare` puts the two fields side by side along the original path: each
point of the corrected program is compared with the original's error at the
same place on the same pass (the original's point there, or the two it lies
between: the original's error there is known only to lie between theirs). It is
*worse* there when its ``|E|`` exceeds the original's (the larger of the two) by
more than the tolerance (1 um by default), or when it cuts deeper (``E`` more
negative than both the original's and zero) by more than ``VERIFY_OVERCUT_UM``:
an overcut cannot be mended. A point of the corrected program with no original
point near it on its pass (it cuts where the original did not) is held to the
nominal surface instead: worse when ``E`` is beyond the tolerance either way (the
overcut limit below). The result carries max ``|E|``, most negative ``E``
and RMS before and after, overall and per block of the original, the worse
points and blocks, and a one-line reason.

Walls are compared too. A flat or radius end mill's point on a floor may also
finish the wall beside it with its flank (:attr:`errpred.physics.PointResult.E_wall_um`);
the correction fits the floors only, and on a sloped floor its move has a part along
the wall's normal. So the walls form a field of their own
(:attr:`ErrorField.walls`: the wall's generation point and normal, its error plus the
move along its normal), compared with the original's walls by the same rules
(:attr:`Comparison.walls`), except that a wall point with no original wall near it
is worse only where it cuts deeper than nominal by more than the overcut limit (the
original's wall there was not predicted, so material left is not known to be worse),
and where the original has two wall points at one place (a block's end and the next
one's start: a flank's wall can step there by tens of um) the reference is the range of
both. A candidate worse on a wall is worse. An original wall point with no wall of the
candidate near it is counted (``Comparison.lost``) and said, not compared.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from nc.path import CutterLocations

from .constants import (
    LOCATE_AXIS_MM,
    LOCATE_SAMPLE_MM,
    VERIFY_BRACKET_SPACINGS,
    VERIFY_OVERCUT_UM,
    VERIFY_SAME_PLACE,
    VERIFY_SPACING_MM,
    VERIFY_TOLERANCE_UM,
)
from .predict import Prediction

__all__ = ["ErrorField", "ErrorStats", "Comparison", "locate_on_path", "error_field",
           "compare", "error_stats", "reference_at"]


def locate_on_path(cl: CutterLocations, points: np.ndarray, axes: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Feed segment (ending at cutter location k) and fraction along it nearest each point.

    The path is sampled along its feed segments (at most ``LOCATE_SAMPLE_MM`` apart, so
    a long straight block is found from its middle too) and the nearest sample is found
    on tip *and* axis (``LOCATE_AXIS_MM`` per radian of axis): on a 5-axis path the
    same tip is reached from different contacts with different axes (a tilted pass can
    run where another pass's tips lie), so the tip alone can put a point on the wrong
    pass. The sample's segment and its neighbours are then projected on exactly.
    Segments ending at a rapid are never chosen; -1 where no feed segment is found.
    """
    from scipy.spatial import cKDTree

    points = np.asarray(points, float).reshape(-1, 3)
    axes = np.asarray(axes, float).reshape(-1, 3)
    tip = cl.tip
    n = len(cl)
    seg = np.full(len(points), -1, dtype=np.int64)
    frac = np.zeros(len(points))
    feed = np.flatnonzero(~cl.rapid[1:]) + 1 if n >= 2 else np.zeros(0, np.int64)
    if feed.size == 0 or len(points) == 0:
        return seg, frac
    w = LOCATE_AXIS_MM
    length = np.linalg.norm(tip[feed] - tip[feed - 1], axis=1)
    count = np.maximum(1, np.ceil(length / LOCATE_SAMPLE_MM).astype(np.int64))
    owner = np.repeat(feed, count)
    start = np.repeat(np.cumsum(count) - count, count)
    t = (np.arange(owner.size) - start + 0.5) / np.repeat(count, count)
    t = np.concatenate([t, np.zeros(feed.size), np.ones(feed.size)])
    owner = np.concatenate([owner, feed, feed])
    a, e = tip[owner - 1], tip[owner]
    ua, ue = cl.axis[owner - 1], cl.axis[owner]
    samples = np.hstack([a + t[:, None] * (e - a), w * ((1 - t[:, None]) * ua + t[:, None] * ue)])
    near = owner[cKDTree(samples).query(np.hstack([points, w * axes]))[1]]
    best_d = np.full(len(points), np.inf)
    for cand in (near - 1, near, near + 1):
        k = np.clip(cand, 1, n - 1)
        a, e = tip[k - 1], tip[k]
        d = e - a
        L2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
        tt = np.clip(np.einsum("ij,ij->i", points - a, d) / L2, 0.0, 1.0)
        ax = (1 - tt[:, None]) * cl.axis[k - 1] + tt[:, None] * cl.axis[k]
        dist = np.hypot(np.linalg.norm(a + tt[:, None] * d - points, axis=1),
                        w * np.linalg.norm(ax - axes, axis=1))
        better = (dist < best_d) & ~cl.rapid[k]
        best_d[better], seg[better], frac[better] = dist[better], k[better], tt[better]
    return seg, frac


@dataclass(frozen=True, eq=False)
class ErrorField:
    """Predicted errors of one program at its prediction points, against a reference path.

    Attributes
    ----------
    point_mm : ndarray, shape (n, 3)
        Generation points [mm].
    tip_mm, axis : ndarray, shape (n, 3)
        Tool tip and axis at each point (on the predicted program's path).
    normal : ndarray, shape (n, 3)
    E_um : ndarray, shape (n,)
        Error against the reference path's surface [um] (positive: material left).
    gain : ndarray, shape (n,)
        ``dE/dx`` of each point (:attr:`errpred.physics.PointResult.gain`).
    block : ndarray, shape (n,), int
        Block of the predicted program each point belongs to.
    ref_segment : ndarray, shape (n,), int
        Feed segment of the reference path the point lies on (-1: none).
    ref_block : ndarray, shape (n,), int
        Block of the reference program it stands for (-1: none).
    ref_line : ndarray, shape (n,), int
        Source line of that block.
    chain : ndarray, shape (n,), int
        Pass of the reference path (runs between rapids).
    s_mm : ndarray, shape (n,)
        Path length along the reference path [mm].
    shift_um : ndarray, shape (n,)
        How far the predicted program's path lies from the reference's, along the
        normal [um] (0 for the reference itself): ``E_um`` includes it.
    walls : ErrorField or None
        The walls the points' flanks finish beside their floors (a field of its own:
        the wall's generation point, normal and error; ``gain`` NaN), or None where
        not built.
    """

    point_mm: np.ndarray
    tip_mm: np.ndarray
    axis: np.ndarray
    normal: np.ndarray
    E_um: np.ndarray
    gain: np.ndarray
    block: np.ndarray
    ref_segment: np.ndarray
    ref_block: np.ndarray
    ref_line: np.ndarray
    chain: np.ndarray
    s_mm: np.ndarray
    shift_um: np.ndarray
    walls: ErrorField | None = None

    def __len__(self) -> int:
        return int(self.E_um.size)


def error_field(prediction: Prediction, reference: CutterLocations,
                reference_lines: np.ndarray | None = None, *, moved: bool = True
                ) -> ErrorField:
    """The predicted points of ``prediction`` as an :class:`ErrorField` on ``reference``.

    Parameters
    ----------
    prediction : Prediction
        Of the program to verify (or of the reference itself).
    reference : CutterLocations
        The original path (``reference.block``: its program's blocks).
    reference_lines : ndarray, shape (blocks,), int, optional
        Source line of each block of the reference program (for the report).
    moved : bool
        Add how far the predicted program's path moved from the reference along
        the normal (False when ``prediction`` is of the reference itself).

    Its :attr:`~ErrorField.walls` holds the points' walls (their errors plus the move
    along the wall's normal), as a field of their own.
    """
    pts = prediction.predicted()
    floor = _field(reference, reference_lines, moved,
                   [(p.geometry.tip, p.geometry.axis, p.geometry.gen, p.result.E_um,
                     p.result.gain, p.block) for p in pts])
    walls = _field(reference, reference_lines, moved,
                   [(p.geometry.tip, p.geometry.axis, p.geometry.wall, p.result.E_wall_um,
                     math.nan, p.block) for p in pts
                    if p.geometry.wall is not None and math.isfinite(p.result.E_wall_um)])
    return dataclasses.replace(floor, walls=walls)


def _field(reference: CutterLocations, reference_lines, moved: bool, rows: list
           ) -> ErrorField:
    """An :class:`ErrorField` of ``rows`` (tip, axis, generation point, E [um], gain,
    block) on ``reference``."""
    n = len(rows)
    tip = np.array([r[0] for r in rows], float).reshape(n, 3)
    axis = np.array([r[1] for r in rows], float).reshape(n, 3)
    normal = np.array([r[2].normal_world for r in rows], float).reshape(n, 3)
    point = np.array([r[2].point_world for r in rows], float).reshape(n, 3)
    E = np.array([r[3] for r in rows], float)
    gain = np.array([r[4] for r in rows], float)
    block = np.array([r[5] for r in rows], np.int64)
    seg, frac = locate_on_path(reference, tip, axis)
    k = np.maximum(seg, 1)
    a, e = reference.tip[k - 1], reference.tip[k]
    on_ref = a + frac[:, None] * (e - a)
    shift = np.einsum("ij,ij->i", tip - on_ref, normal) * 1e3 if moved else np.zeros(n)
    E = E + shift
    ds = np.zeros(len(reference))
    if len(reference) > 1:
        ds[1:] = np.linalg.norm(np.diff(reference.tip, axis=0), axis=1)
    path = np.cumsum(ds)
    s = path[k - 1] + frac * (path[k] - path[k - 1])
    chain = np.cumsum(reference.rapid)[k]
    ref_block = np.where(seg >= 0, reference.block[k], -1)
    lines = np.full(n, -1, np.int64)
    if reference_lines is not None:
        ok = ref_block >= 0
        lines[ok] = np.asarray(reference_lines)[ref_block[ok]]
    return ErrorField(point_mm=point, tip_mm=tip, axis=axis, normal=normal, E_um=E, gain=gain,
                      block=block, ref_segment=seg, ref_block=ref_block, ref_line=lines,
                      chain=np.where(seg >= 0, chain, -1), s_mm=s, shift_um=shift)


@dataclass(frozen=True)
class ErrorStats:
    """Largest |E|, most negative E (overcut), largest E and RMS of a set of points [um]."""

    points: int
    max_abs_um: float
    min_um: float
    max_um: float
    rms_um: float

    def as_dict(self) -> dict:
        def r(v: float) -> float | None:
            return None if not math.isfinite(v) else round(float(v), 3)

        return {"points": self.points, "max_abs_um": r(self.max_abs_um),
                "most_negative_um": r(self.min_um), "max_um": r(self.max_um),
                "rms_um": r(self.rms_um)}


def error_stats(E_um: np.ndarray) -> ErrorStats:
    """:class:`ErrorStats` of errors [um] (NaN everywhere for no points)."""
    E = np.asarray(E_um, float)
    if E.size == 0:
        return ErrorStats(0, math.nan, math.nan, math.nan, math.nan)
    return ErrorStats(int(E.size), float(np.abs(E).max()), float(E.min()), float(E.max()),
                      float(np.sqrt(np.mean(E * E))))


@dataclass(frozen=True, eq=False)
class Comparison:
    """A corrected program's dense errors against the original's (:func:`compare`).

    Attributes
    ----------
    before, after : ErrorStats
        Over all points of the original and of the corrected program.
    per_block : dict of int -> (ErrorStats, ErrorStats)
        Block of the original -> stats before and after.
    reference_um : ndarray, shape (n_after,)
        The original's error at each point of the corrected program (NaN: no match).
    worse : ndarray, shape (n_after,), bool
        Points of the corrected program worse than the original there.
    worse_blocks : ndarray of int
        Blocks of the original holding a worse point.
    allowed_um : ndarray, shape (n_after, 2)
        The band of E each point of the corrected program had to stay in (low, high)
        [um]; (-overcut, tolerance) where there is no reference (walls: (-overcut, inf)).
    unmatched : int
        Points of the corrected program with no original point near them on their pass.
    tolerance_um : float
    lines : dict of int -> int
        Block of the original -> its source line.
    after_field : ErrorField or None
        The corrected program's field compared.
    walls : Comparison or None
        The walls' comparison (``kind`` "wall"; :func:`compare`), or None where they
        are not compared (``walls=False``) or neither program has wall points.
    lost : int
        (walls) Wall points of the original with no wall of the corrected program near
        them on their pass: not compared (said in the report and the reason).
    kind : str
        "floor" or "wall".
    """

    before: ErrorStats
    after: ErrorStats
    per_block: dict
    reference_um: np.ndarray
    worse: np.ndarray
    worse_blocks: np.ndarray
    unmatched: int
    tolerance_um: float
    lines: dict = field(default_factory=dict)
    after_field: ErrorField | None = None
    allowed_um: np.ndarray | None = None
    walls: Comparison | None = None
    kind: str = "floor"
    lost: int = 0

    @property
    def ok(self) -> bool:
        """No point worse than the original (within the tolerance), floors and walls."""
        return not bool(self.worse.any()) and (self.walls is None or self.walls.ok)

    def reason(self) -> str:
        """One line: what the verification found."""
        b, a = self.before, self.after
        head = (f"max |E| {_f(b.max_abs_um)} -> {_f(a.max_abs_um)} um, most negative "
                f"{_f(b.min_um)} -> {_f(a.min_um)} um, RMS {_f(b.rms_um)} -> {_f(a.rms_um)} um")
        w = self.walls
        if self.ok:
            walls = (f"; walls at {w.after.points} points no worse either"
                     if w is not None and w.after.points else "")
            if w is not None and w.lost:
                walls += (f"; {w.lost} of the original's {w.before.points} wall points have "
                          "no wall of the corrected program near them (not compared)")
            return f"verified on {a.points} points: no worse anywhere ({head}){walls}"
        if not self.worse.any():
            return (f"the walls beside the floors: {w.reason()}; the floors: {head} (where "
                    "those walls are not the part's surfaces: [correction] verify_walls = "
                    "false)")
        f = self.after_field
        ref = np.nan_to_num(self.reference_um, nan=0.0)
        excess = np.where(self.worse, np.abs(ref - f.E_um), -np.inf)
        i = int(np.argmax(excess))
        said = (f"the original has {ref[i]:+.2f} um" if np.isfinite(self.reference_um[i])
                else "the original does not cut" if self.kind == "floor"
                else "no wall of the original is predicted")
        line = int(f.ref_line[i]) if f is not None and f.ref_line[i] >= 0 else None
        where = f"line {line}" if line is not None else f"block {int(f.ref_block[i])}"
        return (f"worse than the original at {int(self.worse.sum())} of {a.points} points "
                f"on {self.worse_blocks.size} block(s), worst at {where}: E {f.E_um[i]:+.2f} um "
                f"where {said} (tolerance "
                f"{self.tolerance_um:g} um); {head}"
                + (f"; walls worse at {int(w.worse.sum())} points too"
                   if w is not None and not w.ok else ""))

    def as_dict(self) -> dict:
        """JSON-ready summary (per block: the original's line, stats before and after)."""
        return {
            "tolerance_um": self.tolerance_um,
            "ok": self.ok,
            "before": self.before.as_dict(),
            "after": self.after.as_dict(),
            "worse_points": int(self.worse.sum()),
            "worse_blocks": [int(b) for b in self.worse_blocks],
            "unmatched_points": self.unmatched,
            "lost_points": self.lost,
            "per_block": [{"block": int(k), "line": self.lines.get(int(k)),
                           "before": v[0].as_dict(), "after": v[1].as_dict()}
                          for k, v in sorted(self.per_block.items())],
            "walls": None if self.walls is None else {
                k: v for k, v in self.walls.as_dict().items() if k != "per_block"},
            "reason": self.reason(),
        }


def _f(v: float) -> str:
    return "n/a" if not math.isfinite(v) else f"{v:+.2f}" if v < 0 else f"{v:.2f}"


def reference_at(before: ErrorField, after: ErrorField,
                 spacing_mm: float = VERIFY_SPACING_MM, values: np.ndarray | None = None,
                 envelope: bool = False, joints: bool = False):
    """The original's error (or ``values``, one per point of ``before``) at each point
    of ``after`` [um]: interpolated along the reference path between the two nearest
    points of ``before`` on the same pass when they are at most
    ``VERIFY_BRACKET_SPACINGS`` spacings apart, else the nearest one within a spacing
    (or where ``after``'s point is at one of ``before``'s, that one's); NaN where there
    is none. With ``envelope``, also the smaller and the larger of the two values it
    lies between (both the one value where there is one; with ``joints``, where several
    of ``before``'s points are at that place, a block's end and the next one's start,
    the smallest and the largest of theirs): the original's error between two predicted
    points is known only to lie between them, a step included."""
    vals = before.E_um if values is None else np.asarray(values, float)
    out = np.full(len(after), np.nan)
    env_lo = np.full(len(after), np.nan)
    env_hi = np.full(len(after), np.nan)
    gap = VERIFY_BRACKET_SPACINGS * spacing_mm
    for c in np.unique(after.chain[after.chain >= 0]):
        ia = np.flatnonzero(after.chain == c)
        ib = np.flatnonzero(before.chain == c)
        if ib.size == 0:
            continue
        order = np.argsort(before.s_mm[ib], kind="stable")
        sb, Eb = before.s_mm[ib][order], vals[ib][order]
        sa = after.s_mm[ia]
        j = np.searchsorted(sb, sa)
        lo = np.clip(j - 1, 0, sb.size - 1)
        hi = np.clip(j, 0, sb.size - 1)
        d_lo, d_hi = np.abs(sa - sb[lo]), np.abs(sb[hi] - sa)
        span = sb[hi] - sb[lo]
        inside = (j > 0) & (j < sb.size) & (span <= gap)
        t = np.where(span > 0, (sa - sb[lo]) / np.where(span > 0, span, 1.0), 0.0)
        val = np.where(inside, (1 - t) * Eb[lo] + t * Eb[hi], np.nan)
        nearest = np.where(d_lo <= d_hi, lo, hi)
        near = np.minimum(d_lo, d_hi)
        single = (~inside & (near <= spacing_mm)) | (near <= VERIFY_SAME_PLACE * spacing_mm)
        val = np.where(single, Eb[nearest], val)
        out[ia] = val
        one_lo = one_hi = Eb[nearest]
        if joints and envelope:
            # several of the original's points at that place (a block's end and the
            # next one's start): the original's error there lies between theirs
            same = VERIFY_SAME_PLACE * spacing_mm
            a0 = np.searchsorted(sb, sa - same, side="left")
            a1 = np.searchsorted(sb, sa + same, side="right")
            several = np.flatnonzero(single & (a1 - a0 > 1))
            if several.size:
                one_lo, one_hi = one_lo.copy(), one_hi.copy()
                for q in several:
                    part = Eb[a0[q]:a1[q]]
                    one_lo[q] = min(one_lo[q], part.min())
                    one_hi[q] = max(one_hi[q], part.max())
        env_lo[ia] = np.where(single, one_lo,
                              np.where(inside, np.minimum(Eb[lo], Eb[hi]), np.nan))
        env_hi[ia] = np.where(single, one_hi,
                              np.where(inside, np.maximum(Eb[lo], Eb[hi]), np.nan))
    return (out, env_lo, env_hi) if envelope else out


def compare(before: ErrorField, after: ErrorField, *,
            tolerance_um: float = VERIFY_TOLERANCE_UM, spacing_mm: float = VERIFY_SPACING_MM,
            overcut_um: float = VERIFY_OVERCUT_UM, lines: dict | None = None,
            walls: bool = True) -> Comparison:
    """Compare a corrected program's dense errors with the original's (see the module).

    Parameters
    ----------
    before : ErrorField
        The original program's, on its own path.
    after : ErrorField
        The corrected program's, against the original path.
    tolerance_um : float [um]
        How much larger ``|E|`` may be than the original's.
    spacing_mm : float [mm]
        The dense spacing both were predicted at.
    overcut_um : float [um]
        How much deeper than the original (and than zero) a point may cut (at least
        ``tolerance_um``).
    lines : dict of int -> int, optional
        Block of the original -> source line (for the report).
    walls : bool
        Compare the walls too (:attr:`ErrorField.walls`, where ``after`` has any): into
        :attr:`Comparison.walls`, which :attr:`Comparison.ok` includes. False (a
        scenario's ``[correction] verify_walls = false``) where the flank's walls are
        not the part's surfaces (a flat end mill's raster leaves steps between its
        passes).
    """
    if not (math.isfinite(tolerance_um) and tolerance_um >= 0):
        raise ValueError(f"tolerance_um: expected a finite value >= 0, got {tolerance_um!r}")
    out = _compare(before, after, tolerance_um, spacing_mm, overcut_um, lines, tolerance_um,
                   False)
    bw = before.walls if before.walls is not None else _no_points()
    aw = after.walls if after.walls is not None else _no_points()
    if not walls or len(aw) + len(bw) == 0:
        return out
    wc = _compare(bw, aw, tolerance_um, spacing_mm, overcut_um, lines, math.inf, True)
    # the original's walls that the candidate no longer finishes there (not compared)
    lost = int((~np.isfinite(reference_at(aw, bw, spacing_mm)) & (bw.chain >= 0)).sum())
    return dataclasses.replace(out, walls=dataclasses.replace(wc, kind="wall", lost=lost))


def _no_points() -> ErrorField:
    """An :class:`ErrorField` without points."""
    v, i = np.zeros((0, 3)), np.zeros(0, np.int64)
    return ErrorField(point_mm=v, tip_mm=v, axis=v, normal=v, E_um=np.zeros(0),
                      gain=np.zeros(0), block=i, ref_segment=i, ref_block=i, ref_line=i,
                      chain=i, s_mm=np.zeros(0), shift_um=np.zeros(0))


def _compare(before: ErrorField, after: ErrorField, tolerance_um: float, spacing_mm: float,
             overcut_um: float, lines: dict | None, unmatched_high_um: float,
             joints: bool) -> Comparison:
    """:func:`compare` of one kind of point (floors or walls); a point without an
    original one near it may lie in ``(-overcut, unmatched_high_um)``; ``joints``: see
    :func:`reference_at`."""
    ref, lo, hi = reference_at(before, after, spacing_mm, envelope=True, joints=joints)
    Ea = after.E_um
    k = np.isfinite(ref)                      # points with a reference
    over = max(tolerance_um, overcut_um)
    largest = np.maximum(np.abs(lo[k]), np.abs(hi[k]))
    band = np.full((len(after), 2), np.nan)
    band[k, 1] = largest + tolerance_um
    band[k, 0] = np.maximum(-band[k, 1], np.minimum(lo[k], 0.0) - over)
    band[~k] = (-over, unmatched_high_um)     # cuts where the original did not: nominal
    worse = (Ea > band[:, 1]) | (Ea < band[:, 0])
    per_block: dict[int, tuple[ErrorStats, ErrorStats]] = {}
    blocks = np.union1d(before.ref_block[before.ref_block >= 0],
                        after.ref_block[after.ref_block >= 0])
    for b in blocks:
        per_block[int(b)] = (error_stats(before.E_um[before.ref_block == b]),
                             error_stats(Ea[after.ref_block == b]))
    wb = np.unique(after.ref_block[worse & (after.ref_block >= 0)])
    return Comparison(before=error_stats(before.E_um), after=error_stats(Ea),
                      per_block=per_block, reference_um=ref, worse=worse, worse_blocks=wb,
                      unmatched=int((~k).sum()), tolerance_um=float(tolerance_um),
                      lines=dict(lines or {}), after_field=after, allowed_um=band)
