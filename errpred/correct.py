"""Correct a program against its predicted error (``docs/method.md`` §6).

Each NC point joins block ``i`` (ending there) and block ``j`` (starting
there). With errors ``E`` along normals ``n`` (positive: material left),
block ``k`` needs a displacement of ``-E_k`` along ``n_k``. The point moves
by ``M = s d``, ``d`` along ``-(E_i n_i + E_j n_j)`` (the seeds' direction).
The seeds fit each point's ``s`` to its two blocks alone; here the ``s`` of
a whole chain of connected blocks are fitted together (arcs excepted: their
own error is taken up by refitting their centre), so that each block's
prediction point (at fraction ``t`` along it) moves by
``((1 - t) M_start + t M_end) . n = -E``: the per-point fit is the local
version of this, and leaves alternating residuals where the error steps
from block to block (which iterating cannot remove, they are its fixed
point). A small smoothness term (on differences of neighbouring moves) fixes the
free combination and keeps block-to-block noise from zigzagging the path. Arcs: their
ends move like any point, and the centre is refitted through the corrected
start, end and middle.

Correcting changes the engagement, so :func:`compensate` can iterate:
predict on the corrected program, measure the error against the *original*
program's surface (the prediction on the corrected program plus how far its
path moved along the normal), correct again, until the largest change of a
coordinate is below a tolerance.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from nc.gcode import parse_program
from nc.program import PLANE_AXES, RAPID, Program
from nc.rewrite import rewrite_coordinates

from .predict import Prediction

#: Sensitivities beyond this are not trusted for the correction's size [-].
MAX_GAIN = 0.5

__all__ = ["BlockError", "block_errors", "chain_moves", "largest_error_um", "correction_moves",
           "corrected_program", "Compensation", "compensate"]


@dataclass(frozen=True)
class BlockError:
    """The error of one block, for correction.

    Attributes
    ----------
    E_mm : float [mm]
        Error against the reference surface (positive: material left).
    normal : ndarray, shape (3,)
    fraction : float
        Where along the block it was predicted (0 start, 1 end).
    gain : float
        ``dE/dx`` (:attr:`errpred.physics.PointResult.gain`): cutting deeper
        by ``x`` raises the error by ``gain x``, so removing ``E`` takes a
        move of ``E / (1 - gain)``.
    """

    E_mm: float
    normal: np.ndarray
    fraction: float
    gain: float = 0.0

    @property
    def move_mm(self) -> float:
        """Normal move that cancels the error, first order in the gain [mm]."""
        g = min(max(self.gain, -MAX_GAIN), MAX_GAIN)
        return self.E_mm / (1.0 - g)


def block_errors(program: Program, prediction: Prediction,
                 reference: Program | None = None) -> dict[int, list[BlockError]]:
    """Per-block errors against ``reference`` (default: the program itself).

    A list per block, one entry per prediction point, ordered along it.

    With a reference (the original of a corrected program), the error is the
    predicted one plus the normal component of how far the program's path
    moved from the reference's at the prediction point.
    """
    out: dict[int, list[BlockError]] = {}
    for p in prediction.predicted():
        b = p.block
        g = p.geometry
        n = g.gen.normal_world
        t = _fraction_on_block(program, b, g.tip)
        E = p.result.E_um * 1e-3
        if reference is not None:
            disp = _point_on_block(program, b, t) - _point_on_block(reference, b, t)
            E += float(disp @ n)
        out.setdefault(b, []).append(BlockError(E, n, t, p.result.gain))
    for v in out.values():
        v.sort(key=lambda be: be.fraction)
    return out


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


def largest_error_um(errors: dict[int, list[BlockError]]) -> float:
    """Largest |E| over all points [um]."""
    return max((abs(be.E_mm) * 1e3 for v in errors.values() for be in v), default=0.0)


def _direction(errors: list[BlockError]) -> np.ndarray:
    """Direction of a point's move: the seeds' ``-(E_i n_i + E_j n_j)``, up to sign.

    Weighted by ``|E|`` so that it does not turn over when the two errors
    have opposite signs (as residuals do when iterating): the chain fit
    chooses the sign and size. Falls back to the mean normal.
    """
    v = sum(abs(be.E_mm) * be.normal for be in errors)
    norm = float(np.linalg.norm(v))
    if norm < 1e-12:
        v = sum(be.normal for be in errors)
        norm = float(np.linalg.norm(v))
        if norm < 1e-12:
            return errors[0].normal.copy()
    return v / norm


#: Tikhonov weight of the chain fit, relative to the equations (unit normals).
_RIDGE = 1e-6
#: Weight of the chain fit's smoothness term (differences of neighbouring
#: moves), relative to the equations. Uniform errors are unaffected; errors
#: alternating from block to block (numerical noise) are not chased.
_SMOOTH = 0.005


def correction_moves(program: Program, errors: dict[int, list[BlockError]]
                     ) -> dict[int, np.ndarray]:
    """The displacement of each block's end point [mm], (3,) each.

    Chains are runs of consecutive predicted blocks, each starting where the
    previous ends (no rapid between). Point ``P_0`` of a chain is the end of
    the block before its first block, ``P_K`` the end of its last block.
    """
    return chain_moves(errors, joined=lambda b: program.motion[b] != RAPID,
                       refit=lambda b: _refit_arc(program, b))


def chain_moves(errors: dict[int, list[BlockError]], *, joined: Callable[[int], bool],
                refit: Callable[[int], bool] = lambda k: False) -> dict[int, np.ndarray]:
    """The displacement of each segment's end point [mm], (3,) each.

    Segment ``k`` runs from point ``k - 1`` to point ``k`` (a program's blocks, or a
    path's cutter locations). ``joined(k)``: segment ``k`` continues from segment
    ``k - 1`` (not a rapid); ``refit(k)``: segment ``k``'s own error is taken up
    elsewhere (an arc's centre) and adds no equation.
    """
    moves: dict[int, np.ndarray] = {}
    chains: list[list[int]] = []
    for b in sorted(errors):
        if chains and chains[-1][-1] == b - 1 and joined(b):
            chains[-1].append(b)
        else:
            chains.append([b])
    for chain in chains:
        K = len(chain)
        # point p (0..K) is the end of segment chain[0] - 1 + p; its direction
        # comes from the prediction points next to it on either side
        dirs = []
        for p in range(K + 1):
            adj = []
            if p - 1 >= 0:
                adj.append(errors[chain[p - 1]][-1])
            if p < K:
                adj.append(errors[chain[p]][0])
            dirs.append(_direction(adj))
        # an arc's own error is corrected by refitting its centre through its
        # moved middle (corrected_program), so it adds no equation here: its
        # ends follow the neighbouring blocks (a full circle keeps its centre
        # and so keeps its equation)
        rows = [(k, be) for k, b in enumerate(chain) for be in errors[b] if not refit(b)]
        if not rows:
            continue
        A = np.zeros((len(rows), K + 1))
        rhs = np.zeros(len(rows))
        for q, (k, be) in enumerate(rows):
            A[q, k] = (1 - be.fraction) * float(dirs[k] @ be.normal)
            A[q, k + 1] = be.fraction * float(dirs[k + 1] @ be.normal)
            rhs[q] = -be.move_mm
        s = _banded_lstsq(A, rhs, [k for k, _ in rows])
        for p in range(K + 1):
            seg = chain[0] - 1 + p
            if seg >= 0:
                moves[seg] = s[p] * dirs[p]
    return moves


def _refit_arc(program: Program, block: int) -> bool:
    """Is the block an arc whose centre is refitted (not a full circle)?"""
    k = int(program.arc_index[block])
    return k >= 0 and abs(float(program.arc_sweep[k])) < 2 * math.pi - 1e-9


def _banded_lstsq(A: np.ndarray, rhs: np.ndarray, cols: list[int]) -> np.ndarray:
    """Ridge least squares of a system whose row q touches columns cols[q], +1.

    The normal equations are tridiagonal; with the smoothness term (on
    differences of neighbouring unknowns) and a small ridge they are solved
    banded.
    """
    from scipy.linalg import solveh_banded

    n = A.shape[1]
    diag = np.zeros(n)
    off = np.zeros(n - 1)
    c = np.asarray(cols, dtype=int)
    q = np.arange(A.shape[0])
    a0, a1 = A[q, c], A[q, c + 1]
    np.add.at(diag, c, a0 ** 2)
    np.add.at(diag, c + 1, a1 ** 2)
    np.add.at(off, c, a0 * a1)
    b = np.zeros(n)
    np.add.at(b, c, a0 * rhs)
    np.add.at(b, c + 1, a1 * rhs)
    scale = max(float(diag.max()), 1e-300)
    diag += _RIDGE * scale
    # smoothness: penalize differences of neighbouring moves, so a chain of
    # blocks is not zigzagged to chase block-to-block noise in the prediction
    lam = _SMOOTH * scale
    diag[:-1] += lam
    diag[1:] += lam
    off -= lam
    ab = np.zeros((2, n))
    ab[0, 1:] = off
    ab[1] = diag
    return solveh_banded(ab, b)


def _circle_centre(p1, p2, p3, a1: int, a2: int) -> np.ndarray | None:
    """Centre of the circle through three points, in the plane axes (a1, a2)."""
    x1, y1 = p1[a1], p1[a2]
    x2, y2 = p2[a1], p2[a2]
    x3, y3 = p3[a1], p3[a2]
    det = 2 * ((x2 - x1) * (y3 - y1) - (y2 - y1) * (x3 - x1))
    if abs(det) < 1e-12:
        return None
    s1 = x2 * x2 - x1 * x1 + y2 * y2 - y1 * y1
    s2 = x3 * x3 - x1 * x1 + y3 * y3 - y1 * y1
    cx = (s1 * (y3 - y1) - s2 * (y2 - y1)) / det
    cy = (s2 * (x2 - x1) - s1 * (x3 - x1)) / det
    c = np.zeros(3)
    c[a1], c[a2] = cx, cy
    return c


def corrected_program(program: Program, errors: dict[int, list[BlockError]], *,
                      min_decimals: int | None = None) -> tuple[str, float]:
    """Program text with the corrections applied, and the largest move [mm].

    Written through :func:`nc.rewrite.rewrite_coordinates`: the original's
    words, order, comments and formatting stay; only coordinates change.
    """
    moves = correction_moves(program, errors)
    ends = {}
    for i, m in moves.items():
        e = program.end[i].copy()
        e[:3] += m
        ends[i] = e
    centres = {}
    for b in np.flatnonzero(program.arc_index >= 0):
        b = int(b)
        k = int(program.arc_index[b])
        if b not in errors and b not in moves and (b - 1) not in moves:
            continue
        plane = int(program.arc_plane[k])
        a1, a2, ax = PLANE_AXES[plane]
        s0 = program.start[b, :3] + (moves.get(b - 1, np.zeros(3)) if b > 0 else 0)
        e0 = program.end[b, :3] + moves.get(b, np.zeros(3))
        centre = program.arc_centre[k]
        sweep = float(program.arc_sweep[k])
        r = float(program.arc_radius[k, 0])
        ang0 = math.atan2(program.start[b, a2] - centre[a2], program.start[b, a1] - centre[a1])
        mid = np.zeros(3)
        mid[a1] = centre[a1] + r * math.cos(ang0 + sweep / 2)
        mid[a2] = centre[a2] + r * math.sin(ang0 + sweep / 2)
        if b in errors:
            near = min(errors[b], key=lambda be: abs(be.fraction - 0.5))
            mid += -near.move_mm * near.normal
        else:
            mid += 0.5 * (moves.get(b - 1, np.zeros(3)) + moves.get(b, np.zeros(3)))
        if abs(sweep) >= 2 * math.pi - 1e-9:
            continue  # full circles keep their centre
        c = _circle_centre(s0, mid, e0, a1, a2)
        if c is not None:
            centres[b] = c
    text = rewrite_coordinates(program, ends, centres=centres, min_decimals=min_decimals)
    largest = max((float(np.linalg.norm(m)) for m in moves.values()), default=0.0)
    return text, largest


@dataclass
class Compensation:
    """Result of :func:`compensate`.

    Attributes
    ----------
    text : str
        The corrected program.
    iterations : int
    largest_change_mm : list of float
        Largest coordinate change of each pass.
    max_error_um : list of float
        Largest |error| against the original surface before each pass and
        after the last (re-predicted); when iterating, one more entry: that
        of the program returned (the best pass, since iterating wanders once
        the prediction's own numerical noise is reached).
    """

    text: str
    iterations: int
    largest_change_mm: list[float] = field(default_factory=list)
    max_error_um: list[float] = field(default_factory=list)
    predictions: list[Prediction] = field(default_factory=list)


def compensate(program: Program, predict: Callable[[Program], Prediction], *,
               iterate: bool = False, tolerance_mm: float = 1e-4, max_iterations: int = 5,
               min_decimals: int | None = 4) -> Compensation:
    """Correct ``program``; with ``iterate``, until changes drop below ``tolerance_mm``.

    Parameters
    ----------
    program : Program
        The original.
    predict : callable
        ``predict(program) -> Prediction`` (same scenario, any program).
    iterate : bool
        One pass (False) or predict-then-correct until converged.
    tolerance_mm : float [mm]
        Stop when the largest coordinate change of a pass is below this.
    max_iterations : int
    min_decimals : int, optional
        Decimals for changed words (the correction is micrometres).
    """
    if not (math.isfinite(tolerance_mm) and tolerance_mm > 0):
        raise ValueError(f"tolerance_mm: expected a finite value > 0, got {tolerance_mm!r}")
    if not (isinstance(max_iterations, int) and max_iterations >= 1):
        raise ValueError(f"max_iterations: expected an integer >= 1, got {max_iterations!r}")
    current = program
    text = "\n".join(program.lines) + program.newline
    out = Compensation(text=text, iterations=0)
    passes = max_iterations if iterate else 1
    best_err, best_text = math.inf, text
    for k in range(passes + 1):
        pred = predict(current)
        errs = block_errors(current, pred, reference=program)
        out.predictions.append(pred)
        err = largest_error_um(errs)
        out.max_error_um.append(err)
        if k > 0 and err < best_err:
            best_err, best_text = err, text
        if k == passes or (k > 0 and out.largest_change_mm[-1] < tolerance_mm):
            break
        if k > 1 and err > out.max_error_um[-2] and err > best_err:
            break  # the prediction's own noise is reached: further passes only wander
        # corrections accumulate: errors are measured against the original surface
        text, largest = corrected_program(current, errs, min_decimals=min_decimals)
        out.iterations += 1
        out.largest_change_mm.append(largest)
        current = parse_program(text, file=program.file, allow=program.allowed,
                                block_delete=program.block_delete)
    # keep the pass that came out best (iterating wanders at the noise floor)
    out.text = best_text
    if iterate:
        out.max_error_um.append(best_err)
    return out
