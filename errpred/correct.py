"""Correct a program against its predicted error, verified before it is written (``method.md`` §6).

The correction is geometry, not points: a smooth offset of the path along the
surface normal (:mod:`errpred.offset`), fitted to the errors of a dense
prediction (points at most ``VERIFY_SPACING_MM`` apart on every block, both
ends included), so the error at the blocks' ends counts as much as in their
middle. From the program's blocks:

* every block end is one vertex: a point shared by two blocks moves once;
* a straight block stays straight between its ends; where the moves its points
  ask for depart from a straight line by more than ``SPLIT_TOL_MM`` (the error
  falls where the tool leaves a wall inside the block) the block is split at its
  points, one ``G1`` line per piece (``nc.rewrite``, ``splits``);
* an arc stays an arc with the same sweep: its new centre is the image of the old
  one under the similarity that maps the old ends onto the moved ones; a full
  circle stays a full circle: its centre shifts and its radius changes, and its
  start (= end) stays on it;
* a chain of feed blocks is fitted from its first to its last cutting block:
  lead-ins and lead-outs in air are not fitted and pull nothing.

:func:`compensate` runs the loop of :mod:`errpred.verified`: re-predict each
candidate densely, compare it with the original point by point, halve and then
drop the moves where it is worse, accept only what is no worse anywhere and
better than before. Correcting changes the engagement, so errors are always
measured against the *original* program's surface.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from nc.gcode import parse_program
from nc.path import CutterLocations, cutter_locations
from nc.program import LINEAR, PLANE_AXES, RAPID, TCP_OFF, Program
from nc.rewrite import rewrite_coordinates

from .constants import MAX_GAIN, SPLIT_TOL_MM, VERIFY_SPACING_MM, VERIFY_TOLERANCE_UM
from .offset import ARC, CIRCLE, LINE, OffsetProblem, arc_weights, solve_offsets
from .predict import Prediction
from .verification import ErrorField, error_field
from .verified import VerifiedCorrection, correct_verified

__all__ = ["ProgramEdit", "wanted_moves", "split_fractions", "fit_program", "apply_edit",
           "Compensation", "compensate"]

#: Pieces of a split block shorter than this are merged with their neighbour [mm].
_MIN_PIECE_MM = 0.05


def wanted_moves(field_: ErrorField, slope: np.ndarray | None = None) -> np.ndarray:
    """The move along the normal that cancels each point's error [mm], (n,).

    ``-E / slope`` with ``slope = dE/dshift``: measured (``slope``, where finite), or
    first order in the model's gain ``dE/dx`` (cutting deeper by ``x`` raises the
    error by ``gain x``): ``1 - gain``, the gain clipped to ``[-MAX_GAIN, 0]``. The
    model's gain may only shrink a move, never enlarge it beyond the error: its
    first-order value overshoots where the engagement changes (a circle's entry, a
    wall's end), and an overcut cannot be mended; the measured slope of later passes
    takes the step to the end.
    """
    s = 1.0 - np.clip(field_.gain, -MAX_GAIN, 0.0)
    if slope is not None:
        s = np.where(np.isfinite(slope), slope, s)
    return -(field_.E_um * 1e-3) / s


def _fraction_on_block(program: Program, b: int, tip: np.ndarray) -> float:
    """Where along block b (0 start, 1 end) a point lies: by chord, or by angle on arcs."""
    a, e = program.start[b, :3], program.end[b, :3]
    k = int(program.arc_index[b])
    if k >= 0:
        a1, a2, _ = PLANE_AXES[int(program.arc_plane[k])]
        c = program.arc_centre[k]
        ang0 = math.atan2(a[a2] - c[a2], a[a1] - c[a1])
        ang = math.atan2(tip[a2] - c[a2], tip[a1] - c[a1])
        sweep = float(program.arc_sweep[k])
        d = (ang - ang0) % (2 * math.pi) if sweep > 0 else -((ang0 - ang) % (2 * math.pi))
        if abs(sweep) >= 2 * math.pi - 1e-9 and abs(d) < 1e-9:
            # a full circle's start is also its end: nearer the end by chord order
            return 0.0
        return float(np.clip(d / sweep, 0.0, 1.0)) if sweep != 0 else 0.5
    length = float(np.linalg.norm(e - a))
    return float(np.clip(np.dot(tip - a, e - a) / length ** 2, 0, 1)) if length > 0 else 1.0


def _point_on_block(program: Program, b: int, t: float) -> np.ndarray:
    """The point at fraction t along block b [mm], on the arc for arcs."""
    a, e = program.start[b, :3], program.end[b, :3]
    p = a + t * (e - a)
    k = int(program.arc_index[b])
    if k >= 0:
        a1, a2, _ = PLANE_AXES[int(program.arc_plane[k])]
        c = program.arc_centre[k]
        r0, r1 = program.arc_radius[k]
        ang = math.atan2(a[a2] - c[a2], a[a1] - c[a1]) + t * float(program.arc_sweep[k])
        r = r0 + t * (r1 - r0)
        p[a1] = c[a1] + r * math.cos(ang)
        p[a2] = c[a2] + r * math.sin(ang)
    return p


def _splittable(program: Program, b: int) -> bool:
    """A straight feed block that moves no rotary axis and is not under TCP control."""
    if int(program.motion[b]) != LINEAR or program.arc_index[b] >= 0:
        return False
    m = program.modals[int(program.modal_index[b])]
    return m.tcp == TCP_OFF and not np.any(np.abs(program.end[b, 3:] - program.start[b, 3:])
                                           > 1e-12)


@dataclass(frozen=True, eq=False)
class ProgramEdit:
    """A fitted correction of a program.

    Attributes
    ----------
    moves : ndarray, shape (V, 3) [mm]
        Vertex moves: vertex ``b < n`` is the end of block ``b``; then the split
        points (:attr:`split_vertices`).
    split_fractions : dict of int -> ndarray
        Block -> fractions (0..1, ascending) at which it is split.
    split_vertices : dict of int -> ndarray of int
        Block -> the vertices at those fractions.
    circles : dict of int -> (ndarray (3,), float)
        Full-circle block -> (centre shift [mm], radius change [mm]).
    movable : ndarray, shape (V,), bool
    vertices : ndarray, shape (V, 3) [mm]
        Where the vertices are before the moves.
    """

    moves: np.ndarray
    split_fractions: dict
    split_vertices: dict
    circles: dict
    movable: np.ndarray
    vertices: np.ndarray | None = None

    @property
    def n_vertices(self) -> int:
        return int(self.moves.shape[0])

    @property
    def largest_mm(self) -> float:
        """Largest vertex move [mm]."""
        return float(np.linalg.norm(self.moves, axis=1).max(initial=0.0))


def _chains(program: Program, cut: np.ndarray) -> list[list[int]]:
    """Runs of feed blocks, trimmed to their first and last cutting block (full circles
    next to the trimmed ends are kept in: their start and end move together)."""
    n = len(program)
    out: list[list[int]] = []
    run: list[int] = []
    for b in range(n + 1):
        if b < n and program.motion[b] != RAPID:
            run.append(b)
            continue
        idx = [i for i, blk in enumerate(run) if cut[blk]]
        if idx:
            lo, hi = idx[0], idx[-1]
            while lo > 0 and _full_circle(program, run[lo - 1]):
                lo -= 1
            while hi < len(run) - 1 and _full_circle(program, run[hi + 1]):
                hi += 1
            out.append(run[lo:hi + 1])
        run = []
    return out


def _full_circle(program: Program, b: int) -> bool:
    k = int(program.arc_index[b])
    return k >= 0 and abs(float(program.arc_sweep[k])) >= 2 * math.pi - 1e-9


def fit_program(program: Program, field_: ErrorField, slope: np.ndarray | None = None,
                weight: np.ndarray | None = None, *, split: bool = True) -> ProgramEdit:
    """The correction of ``program`` for the errors ``field_`` (its own dense prediction,
    against the original surface).

    Parameters
    ----------
    program : Program
    field_ : ErrorField
        ``field_.block`` are ``program``'s blocks.
    slope : ndarray, shape (points,), optional
        Measured ``dE/dshift`` per point (:func:`wanted_moves`).
    weight : ndarray, shape (points,), optional
        Factor on each point's wanted move (the verified loop's fallback).
    split : bool
        Split straight blocks whose points ask for more than a straight move.
    """
    n = len(program)
    target = wanted_moves(field_, slope)
    if weight is not None:
        target = target * np.asarray(weight, float)
    pblock = field_.block
    t = np.array([_fraction_on_block(program, int(b), tip)
                  for b, tip in zip(pblock, field_.tip_mm, strict=True)])
    cut = np.zeros(n, bool)
    cut[pblock] = True
    chains = _chains(program, cut)
    ends = program.end[:, :3]
    starts = program.start[:, :3]
    vertices = [ends, starts[:1]]          # vertex n: the start of block 0 (never moves)
    V = n + 1
    split_frac: dict[int, np.ndarray] = {}
    split_vtx: dict[int, np.ndarray] = {}
    movable = np.zeros(n + 1, bool)
    seg_v0, seg_v1, seg_kind, seg_plane, seg_centre, seg_block = [], [], [], [], [], []
    seg_lo, seg_hi = [], []
    chain_vertices = []
    for chain in chains:
        first = chain[0]
        v_start = first - 1 if first > 0 else n
        cv = [v_start]
        if v_start < n:
            movable[v_start] = True
        for b in chain:
            movable[b] = True
            sel = np.flatnonzero(pblock == b)
            fr = np.zeros(0)
            if split and sel.size >= 2 and _splittable(program, b):
                tt, tg, nn = t[sel], target[sel], field_.normal[sel]
                prev = np.flatnonzero((pblock == b - 1) & (t >= 1.0 - 1e-9))
                if prev.size and not np.any(tt <= 1e-9) and program.motion[b - 1] != RAPID:
                    # the corner is predicted once, as the end of the block before
                    tt, tg = np.r_[0.0, tt], np.r_[target[prev[0]], tg]
                    nn = np.vstack([field_.normal[prev[0]], nn])
                fr = split_fractions(float(np.linalg.norm(ends[b] - starts[b])), tt, tg, nn)
            pieces = np.concatenate([[0.0], fr, [1.0]])
            vs = [cv[-1]]
            if fr.size:
                ids = np.arange(V, V + fr.size)
                V += fr.size
                split_frac[b], split_vtx[b] = fr, ids
                vertices.append(starts[b] + fr[:, None] * (ends[b] - starts[b]))
                vs += ids.tolist()
            vs.append(b)
            k = int(program.arc_index[b])
            kind, plane, centre = LINE, (0, 1, 2), np.zeros(3)
            if k >= 0:
                plane = PLANE_AXES[int(program.arc_plane[k])]
                centre = program.arc_centre[k]
                kind = CIRCLE if _full_circle(program, b) else ARC
            for j in range(len(vs) - 1):
                seg_v0.append(vs[j])
                seg_v1.append(vs[j + 1])
                seg_kind.append(kind)
                seg_plane.append(plane)
                seg_centre.append(centre)
                seg_block.append(b)
                seg_lo.append(pieces[j])
                seg_hi.append(pieces[j + 1])
            cv += vs[1:]
        chain_vertices.append(np.asarray(cv, np.int64))
    verts = np.vstack(vertices)
    mov = np.zeros(V, bool)
    mov[:n + 1] = movable
    mov[n + 1:] = True
    mov[n] = False
    seg_block = np.asarray(seg_block, np.int64)
    seg_lo, seg_hi = np.asarray(seg_lo), np.asarray(seg_hi)
    # each point on its piece
    first_seg = {}
    for s, b in enumerate(seg_block):
        first_seg.setdefault(int(b), s)
    keep = np.array([int(b) in first_seg for b in pblock], bool)
    q_seg = np.zeros(pblock.size, np.int64)
    q_t = np.zeros(pblock.size)
    q_w = np.zeros((pblock.size, 2))
    q_th = np.zeros(pblock.size)
    for q in np.flatnonzero(keep):
        b = int(pblock[q])
        s = first_seg[b]
        while s + 1 < seg_block.size and seg_block[s + 1] == b and seg_lo[s + 1] < t[q]:
            s += 1
        span = seg_hi[s] - seg_lo[s]
        tt = float(np.clip((t[q] - seg_lo[s]) / span, 0.0, 1.0)) if span > 0 else 0.0
        q_seg[q], q_t[q] = s, tt
        q_w[q] = (tt, 0.0)
        kind = seg_kind[s]
        if kind != LINE:
            a1, a2, _ = seg_plane[s]
            k = int(program.arc_index[b])
            c = program.arc_centre[k]
            p0, p1 = starts[b], ends[b]
            p = _point_on_block(program, b, float(t[q]))
            if kind == ARC:
                q_w[q] = arc_weights(p0[[a1, a2]], p1[[a1, a2]], p[None, [a1, a2]])[0]
            q_th[q] = math.atan2(p[a2] - c[a2], p[a1] - c[a1])
    pb = OffsetProblem(
        vertices=verts, movable=mov, seg_v0=np.asarray(seg_v0, np.int64),
        seg_v1=np.asarray(seg_v1, np.int64), seg_kind=np.asarray(seg_kind, np.int64),
        seg_plane=np.asarray(seg_plane, np.int64).reshape(-1, 3),
        seg_centre=np.asarray(seg_centre, float).reshape(-1, 3), chains=chain_vertices,
        pt_seg=q_seg[keep], pt_t=q_t[keep], pt_w=q_w[keep], pt_theta=q_th[keep],
        pt_normal=field_.normal[keep], pt_target=target[keep],
        pt_weight=np.ones(int(keep.sum())))
    sol = solve_offsets(pb)
    circles = {int(seg_block[s]): v for s, v in sol.circle.items()}
    return ProgramEdit(moves=sol.moves, split_fractions=split_frac, split_vertices=split_vtx,
                       circles=circles, movable=mov, vertices=verts)


def split_fractions(length_mm: float, t: np.ndarray, target: np.ndarray,
                    normal: np.ndarray) -> np.ndarray:
    """Fractions at which a straight piece of ``length_mm`` must be split so that
    straight pieces can follow the wanted moves ``target`` [mm] along ``normal`` of its
    points at fractions ``t`` (empty if a straight move of its ends can)."""
    # the wanted moves as vectors along the normals, fitted by a straight move
    want = target[:, None] * normal
    A = np.column_stack([1 - t, t])
    coef, *_ = np.linalg.lstsq(A, want, rcond=None)
    resid = np.abs(np.einsum("ij,ij->i", A @ coef - want, normal))
    if resid.max(initial=0.0) <= SPLIT_TOL_MM:
        return np.zeros(0)
    length = float(length_mm)
    inner = np.unique(t[(t > 0) & (t < 1)])
    out: list[float] = []
    last = 0.0
    for x in inner:
        if (x - last) * length >= _MIN_PIECE_MM and (1 - x) * length >= _MIN_PIECE_MM:
            out.append(float(x))
            last = float(x)
    return np.asarray(out)


def apply_edit(program: Program, edit: ProgramEdit, scale: np.ndarray | None = None, *,
               min_decimals: int | None = 4) -> tuple[str, np.ndarray]:
    """The program text with ``edit``'s moves (times ``scale`` per vertex) applied.

    Returns
    -------
    text : str
        Written through :func:`nc.rewrite.rewrite_coordinates`: the original's words,
        order, comments and formatting stay; coordinates change, split blocks get
        ``G1`` lines after their own.
    owner : ndarray, shape (blocks of the new program, 2), int
        The two vertices (of ``edit``) at the ends of each block of the new program
        (-1: none).
    """
    n = len(program)
    s = np.ones(edit.n_vertices) if scale is None else np.asarray(scale, float)
    moves = edit.moves * s[:, None]
    ends = {}
    for b in np.flatnonzero(edit.movable[:n]):
        e = program.end[b].copy()
        e[:3] += moves[b]
        ends[int(b)] = e
    centres = {}
    starts = program.start[:, :3]
    for b in np.flatnonzero(program.arc_index >= 0):
        b = int(b)
        v0 = b - 1 if b > 0 else n
        if not (edit.movable[v0] or edit.movable[b]):
            continue
        k = int(program.arc_index[b])
        a1, a2, _ = PLANE_AXES[int(program.arc_plane[k])]
        c = program.arc_centre[k].copy()
        if b in edit.circles:
            shift, _ = edit.circles[b]
            c_new = c + min(s[v0], s[b]) * shift
        else:
            p0, p1 = starts[b], program.end[b, :3]
            q0, q1 = p0 + moves[v0], p1 + moves[b]
            z0, z1 = complex(p0[a1], p0[a2]), complex(p1[a1], p1[a2])
            w0, w1 = complex(q0[a1], q0[a2]), complex(q1[a1], q1[a2])
            alpha = (w1 - w0) / (z1 - z0) if abs(z1 - z0) > 1e-12 else 1.0
            zc = w0 + alpha * (complex(c[a1], c[a2]) - z0)
            c_new = c.copy()
            c_new[a1], c_new[a2] = zc.real, zc.imag
        centres[b] = c_new
    splits = {}
    for b, fr in edit.split_fractions.items():
        ids = edit.split_vertices[b]
        base = starts[b] + fr[:, None] * (program.end[b, :3] - starts[b])
        splits[b] = base + moves[ids]
    text = rewrite_coordinates(program, ends, centres=centres, splits=splits,
                               min_decimals=min_decimals)
    owner = []
    for b in range(n):
        v0 = b - 1 if b > 0 else n
        vs = [v0] + list(edit.split_vertices.get(b, [])) + [b]
        owner.extend([vs[j], vs[j + 1]] for j in range(len(vs) - 1))
    return text, np.asarray(owner, np.int64).reshape(-1, 2)


@dataclass
class Compensation:
    """Result of :func:`compensate`.

    Attributes
    ----------
    text : str
        The corrected program (the original's text when no correction was verified).
    verified : VerifiedCorrection
        The loop's record: the original's and every candidate's dense comparison.
    """

    text: str
    verified: VerifiedCorrection
    original: Program | None = None
    program: Program | None = None
    notes: list = field(default_factory=list)

    @property
    def corrected(self) -> bool:
        """A correction no worse than the original anywhere was found."""
        return self.verified.corrected

    @property
    def iterations(self) -> int:
        return len({p.index for p in self.verified.passes})

    @property
    def max_error_um(self) -> list[float]:
        """Largest |E| of the original, then of each predicted candidate [um]."""
        v = self.verified
        return [v.before_stats.max_abs_um] + [p.comparison.after.max_abs_um for p in v.passes]

    @property
    def predictions(self) -> list[Prediction]:
        return self.verified.predictions

    def reason(self) -> str:
        return self.verified.reason()


@dataclass(frozen=True, eq=False)
class _Candidate:
    """A program and, per source line, the line of the original it comes from (1-based;
    split blocks' added lines come from their block's line)."""

    program: Program
    origin: np.ndarray


def compensate(program: Program, predict: Callable[[Program, np.ndarray], Prediction], *,
               path: Callable[[Program], CutterLocations] | None = None,
               iterate: bool = False, tolerance_mm: float = 1e-4, max_iterations: int = 5,
               min_decimals: int | None = 4, tolerance_um: float = VERIFY_TOLERANCE_UM,
               spacing_mm: float = VERIFY_SPACING_MM, reach_mm: float = 0.0,
               progress: Callable[[str], None] | None = None) -> Compensation:
    """Correct ``program``, verified (see the module docstring and :mod:`errpred.verified`).

    Parameters
    ----------
    program : Program
        The original.
    predict : callable
        ``predict(program, origin_line) -> Prediction`` (same scenario, any program),
        dense: points at most ``spacing_mm`` apart on every block, both ends included
        (:meth:`errpred.geometry.Resolution.dense`). ``origin_line`` (one per source
        line of ``program``) is the line of the original each line comes from, for
        predicting the same part of a corrected program as of the original.
    path : callable, optional
        ``path(program) -> CutterLocations`` as the prediction makes it (default:
        :func:`nc.path.cutter_locations` without a machine).
    iterate : bool
        One pass (False) or up to ``max_iterations``.
    tolerance_mm : float [mm]
        Stop when a pass's largest move is below this.
    min_decimals : int, optional
        Decimals for changed words (the correction is micrometres).
    tolerance_um : float [um]
        How much worse than the original a point of the corrected program may be.
    spacing_mm : float [mm]
        The dense spacing of ``predict``.
    reach_mm : float [mm]
        Where a candidate is worse than the original, the wanted moves of the points
        within this distance (at least ``spacing_mm``) of the worse ones are scaled
        back (:func:`errpred.verified.correct_verified`).
    progress : callable, optional
        ``progress(stage)`` before each prediction.
    """
    locate = path or cutter_locations
    ref_cl = locate(program)
    lines = {b: int(program.line[b]) for b in range(len(program))}
    first = _Candidate(program, np.arange(1, len(program.lines) + 1))

    def predict_field(c: _Candidate) -> tuple[ErrorField, Prediction]:
        pred = predict(c.program, c.origin)
        return error_field(pred, ref_cl, program.line, moved=c is not first), pred

    def fit(c: _Candidate, fld: ErrorField, slope, weight) -> ProgramEdit:
        return fit_program(c.program, fld, slope, weight)

    def apply(c: _Candidate, edit: ProgramEdit, factor: float) -> _Candidate:
        prog = c.program
        text, _ = apply_edit(prog, edit, np.full(edit.n_vertices, factor),
                             min_decimals=min_decimals)
        new = parse_program(text, file=program.file, allow=program.allowed,
                            block_delete=program.block_delete)
        added = np.zeros(len(prog.lines), np.int64)       # lines added after each line
        for b, fr in edit.split_fractions.items():
            added[int(prog.line[b]) - 1] += len(fr)
        return _Candidate(new, np.repeat(c.origin, added + 1))

    res = correct_verified(first, predict_field, fit, apply, iterate=iterate,
                           max_iterations=max_iterations, tolerance_mm=tolerance_mm,
                           tolerance_um=tolerance_um, spacing_mm=spacing_mm,
                           reach_mm=reach_mm, lines=lines, progress=progress)
    best = res.best.program
    res.best = best
    text = best.newline.join(best.lines) + best.newline
    return Compensation(text=text, verified=res, original=program, program=best)
