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
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from nc.gcode import parse_program
from nc.path import CutterLocations, cutter_locations
from nc.program import LINEAR, PLANE_AXES, RAPID, TCP_OFF, Program
from nc.rewrite import rewrite_coordinates

from .constants import CORRECTION_DECIMALS, MAX_GAIN, VERIFY_SPACING_MM, VERIFY_TOLERANCE_UM
from .offset import ARC, CIRCLE, LINE, OffsetEdit, Units, feed_chains, fit_units
from .predict import Prediction
from .verification import ErrorField, error_field
from .verified import VerifiedCorrection, VerifiedResult, correct_verified

__all__ = ["ProgramEdit", "program_units", "wanted_moves", "fit_program", "apply_edit",
           "Compensation", "compensate"]


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


def _splittable(program: Program, b: int) -> bool:
    """A straight feed block that moves no rotary axis and is not under TCP control."""
    if int(program.motion[b]) != LINEAR or program.arc_index[b] >= 0:
        return False
    m = program.modals[int(program.modal_index[b])]
    return m.tcp == TCP_OFF and not np.any(np.abs(program.end[b, 3:] - program.start[b, 3:])
                                           > 1e-12)


#: A fitted correction of a program (units: its blocks).
ProgramEdit = OffsetEdit


def program_units(program: Program) -> Units:
    """A program's blocks as the fit's :class:`errpred.offset.Units`."""
    n = len(program)
    kind = np.full(n, LINE, np.int64)
    plane = np.tile([0, 1, 2], (n, 1))
    centre = np.zeros((n, 3))
    radius = np.zeros((n, 2))
    sweep = np.zeros(n)
    arcs = np.flatnonzero(program.arc_index >= 0)
    k = program.arc_index[arcs]
    if arcs.size:
        plane[arcs] = [PLANE_AXES[int(x)] for x in program.arc_plane[k]]
        centre[arcs] = program.arc_centre[k]
        radius[arcs] = program.arc_radius[k]
        sweep[arcs] = program.arc_sweep[k]
        kind[arcs] = np.where(np.abs(sweep[arcs]) >= 2 * math.pi - 1e-9, CIRCLE, ARC)
    joined = np.zeros(n, bool)
    joined[1:] = (program.motion[1:] != RAPID) & (program.motion[:-1] != RAPID)
    return Units(start=program.start[:, :3], end=program.end[:, :3], kind=kind, plane=plane,
                 centre=centre, radius=radius, sweep=sweep,
                 splittable=np.array([_splittable(program, b) for b in range(n)], bool),
                 joined=joined)


def _full_circle(program: Program, b: int) -> bool:
    k = int(program.arc_index[b])
    return k >= 0 and abs(float(program.arc_sweep[k])) >= 2 * math.pi - 1e-9


def fit_program(program: Program, field_: ErrorField, slope: np.ndarray | None = None,
                weight: np.ndarray | None = None, *, split: bool = True,
                hold: ProgramEdit | None = None, free: np.ndarray | None = None
                ) -> ProgramEdit:
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
        Factor on each point's wanted move (the verified loop's fallback); 0: the
        point must not move (held where it is).
    split : bool
        Split straight blocks whose points ask for more than a straight move.
    hold, free : optional
        A fallback's refit: keep ``hold``'s moves away from the points ``free``
        (:func:`errpred.offset.fit_units`).
    """
    pblock = field_.block
    t = np.array([_fraction_on_block(program, int(b), tip)
                  for b, tip in zip(pblock, field_.tip_mm, strict=True)])
    n = len(program)
    cut = np.zeros(n, bool)
    cut[pblock] = True
    circle = np.array([_full_circle(program, b) for b in range(n)], bool)
    chains = feed_chains(program.motion != RAPID, cut, sticky=circle)
    return fit_units(program_units(program), chains, pblock, t, wanted_moves(field_, slope),
                     field_.normal, weight=weight, split=split, hold=hold, free=free)


def apply_edit(program: Program, edit: ProgramEdit, scale: np.ndarray | None = None, *,
               min_decimals: int | Mapping[int, int] | None = None) -> tuple[str, np.ndarray]:
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
                               min_decimals=(CORRECTION_DECIMALS if min_decimals is None
                                             else min_decimals))
    owner = []
    for b in range(n):
        v0 = b - 1 if b > 0 else n
        vs = [v0] + list(edit.split_vertices.get(b, [])) + [b]
        owner.extend([vs[j], vs[j + 1]] for j in range(len(vs) - 1))
    return text, np.asarray(owner, np.int64).reshape(-1, 2)


@dataclass
class Compensation(VerifiedResult):
    """Result of :func:`compensate` (the loop's figures: :class:`errpred.verified.VerifiedResult`).

    Attributes
    ----------
    text : str
        The corrected program (the original's text when no correction was verified).
    verified : VerifiedCorrection
        The loop's record: the original's and every candidate's dense comparison.
    original, program : Program
        The original and the program returned.
    origin : ndarray of int, optional
        Per source line of :attr:`program`, the line of the original it comes from
        (1-based; a split block's added lines come from their block's line).
    """

    text: str
    verified: VerifiedCorrection
    original: Program | None = None
    program: Program | None = None
    origin: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class _Candidate:
    """A program and, per source line, the line of the original it comes from (1-based;
    split blocks' added lines come from their block's line)."""

    program: Program
    origin: np.ndarray


def compensate(program: Program, predict: Callable[[Program, np.ndarray], Prediction], *,
               path: Callable[[Program], CutterLocations] | None = None,
               iterate: bool = False, tolerance_mm: float = 1e-4, max_iterations: int = 5,
               relaxation: float | None = None,
               min_decimals: int | Mapping[int, int] | None = None,
               tolerance_um: float = VERIFY_TOLERANCE_UM,
               spacing_mm: float = VERIFY_SPACING_MM, reach_mm: float = 0.0,
               verify_walls: bool = True,
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
    relaxation : float, optional [-]
        Share of the first pass's fit applied (:func:`errpred.verified.correct_verified`).
    min_decimals : int or dict of int -> int, optional
        Decimals for changed words, or per unit mode (default ``CORRECTION_DECIMALS``:
        a tenth of a micrometre in mm, a quarter in inch; the correction is micrometres).
    tolerance_um : float [um]
        How much worse than the original a point of the corrected program may be.
    spacing_mm : float [mm]
        The dense spacing of ``predict``.
    reach_mm : float [mm]
        Where a candidate is worse than the original, the wanted moves of the points
        within this distance (at least ``spacing_mm``) of the worse ones are scaled
        back (:func:`errpred.verified.correct_verified`).
    verify_walls : bool
        Compare the walls beside the floors too (:func:`errpred.verification.compare`).
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

    def fit(c: _Candidate, fld: ErrorField, slope, weight, hold=None, free=None
            ) -> ProgramEdit:
        return fit_program(c.program, fld, slope, weight, hold=hold, free=free)

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
                           max_iterations=max_iterations, relaxation=relaxation,
                           tolerance_mm=tolerance_mm, tolerance_um=tolerance_um,
                           spacing_mm=spacing_mm, reach_mm=reach_mm, lines=lines,
                           verify_walls=verify_walls, progress=progress)
    best, origin = res.best.program, res.best.origin
    res.best = best
    text = best.newline.join(best.lines) + best.newline
    return Compensation(text=text, verified=res, original=program, program=best,
                        origin=origin)
