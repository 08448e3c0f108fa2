"""Correct a 5-axis path (cutter locations, workpiece frame) against its predicted error.

``docs/method.md`` §6 on a path instead of a program's text: a 5-axis
program's X/Y/Z words are machine coordinates that the rotary axes turn, so
the correction is made where the physics is, on the tool tips in the
workpiece frame, and the program is written again from them (``nc.writer``).
The tool axis is kept: each tip moves by the smooth offset along the surface
normal of :mod:`errpred.offset` (every cutter location a vertex, every feed
segment a straight piece; a segment whose points ask for more than a straight
move gets cutter locations inserted at them), so the ball centre moves by the
same vector.

The loop is :func:`errpred.verified.correct_verified`: every candidate path is
written, re-predicted densely (``predict``) and compared point by point with
the reference path's own dense prediction, against the reference path's
surface; only a candidate nowhere worse than the reference and better than the
best so far is accepted, and the reference itself is the first candidate.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from nc.path import CutterLocations

from .constants import VERIFY_SPACING_MM, VERIFY_TOLERANCE_UM
from .correct import wanted_moves
from .offset import LINE, OffsetEdit, Units, feed_chains, fit_units
from .predict import Prediction
from .verification import ErrorField, error_field, locate_on_path
from .verified import VerifiedCorrection, VerifiedResult, correct_verified

__all__ = ["PathEdit", "PathCompensation", "path_units", "compensate_path", "fit_path",
           "apply_path_edit", "error_points"]


def error_points(cl: CutterLocations, prediction: Prediction,
                 reference: CutterLocations | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Generation points (m, 3) [mm] and errors (m,) [um] against ``reference``'s surface
    (default: ``cl``'s own), for the predicted points on a feed segment of the reference."""
    ref = cl if reference is None else reference
    f = error_field(prediction, ref, moved=reference is not None)
    keep = f.ref_segment >= 0
    return f.point_mm[keep], f.E_um[keep]


#: A fitted correction of a path (units: its segments; vertex k is cutter location k).
PathEdit = OffsetEdit


def path_units(cl: CutterLocations) -> Units:
    """A path's segments as the fit's :class:`errpred.offset.Units`: unit ``k`` runs
    from cutter location ``k - 1`` to ``k``; straight, splittable; joined unless one
    of the two is a rapid."""
    n = len(cl)
    joined = np.zeros(n, bool)
    joined[1:] = ~cl.rapid[1:] & ~cl.rapid[:-1]
    return Units(start=np.vstack([cl.tip[:1], cl.tip[:-1]]), end=cl.tip,
                 kind=np.full(n, LINE, np.int64), plane=np.tile([0, 1, 2], (n, 1)),
                 centre=np.zeros((n, 3)), radius=np.zeros((n, 2)), sweep=np.zeros(n),
                 splittable=np.ones(n, bool), joined=joined)


def fit_path(cl: CutterLocations, field_: ErrorField, slope: np.ndarray | None = None,
             weight: np.ndarray | None = None, *, split: bool = True,
             hold: PathEdit | None = None, free: np.ndarray | None = None) -> PathEdit:
    """The correction of path ``cl`` for the errors ``field_`` (its own dense
    prediction, against the reference surface): see :mod:`errpred.correct`; segments
    whose points ask for more than a straight move get cutter locations inserted."""
    seg, t = locate_on_path(cl, field_.tip_mm, field_.axis)
    ok = seg >= 1
    cut = np.zeros(len(cl), bool)
    cut[seg[ok]] = True
    feed = ~cl.rapid
    feed[0] = False                       # location 0 starts the path: no segment ends there
    w = None if weight is None else np.asarray(weight, float)[ok]
    f = None if free is None else np.asarray(free, bool)[ok]
    return fit_units(path_units(cl), feed_chains(feed, cut), seg[ok], t[ok],
                     wanted_moves(field_, slope)[ok], field_.normal[ok], weight=w,
                     split=split, hold=hold, free=f)


def apply_path_edit(cl: CutterLocations, edit: PathEdit, scale: np.ndarray | None = None
                    ) -> tuple[CutterLocations, np.ndarray]:
    """The path with ``edit``'s moves (times ``scale`` per vertex) applied and its points
    inserted (tip and axis interpolated, the segment's feed, spindle and block).

    Returns
    -------
    CutterLocations
    owner : ndarray, shape (new points, 2), int
        The edit's vertices at the ends of the segment ending at each new point (-1 for
        the first point).
    """
    n = len(cl)
    s = np.ones(edit.n_vertices) if scale is None else np.asarray(scale, float)
    moves = edit.moves * s[:, None]
    tips, axes, feed, rpm, block, rapid, vid = [], [], [], [], [], [], []
    for k in range(n):
        fr = edit.split_fractions.get(k)
        if fr is not None:
            ids = edit.split_vertices[k]
            a, b = cl.tip[k - 1], cl.tip[k]
            u = (1 - fr[:, None]) * cl.axis[k - 1] + fr[:, None] * cl.axis[k]
            u /= np.linalg.norm(u, axis=1, keepdims=True)
            tips.append(a + fr[:, None] * (b - a) + moves[ids])
            axes.append(u)
            feed.append(np.full(fr.size, cl.feed_mm_min[k]))
            rpm.append(np.full(fr.size, cl.spindle_rpm[k]))
            block.append(np.full(fr.size, cl.block[k]))
            rapid.append(np.zeros(fr.size, bool))
            vid.append(ids)
        tips.append(cl.tip[k:k + 1] + moves[k:k + 1])
        axes.append(cl.axis[k:k + 1])
        feed.append(cl.feed_mm_min[k:k + 1])
        rpm.append(cl.spindle_rpm[k:k + 1])
        block.append(cl.block[k:k + 1])
        rapid.append(cl.rapid[k:k + 1])
        vid.append(np.array([k]))
    v = np.concatenate(vid)
    owner = np.column_stack([np.r_[-1, v[:-1]], v])
    new = CutterLocations(np.vstack(tips), np.vstack(axes), np.concatenate(feed),
                          np.concatenate(rpm), np.concatenate(block), np.concatenate(rapid))
    return new, owner


@dataclass
class PathCompensation(VerifiedResult):
    """Result of :func:`compensate_path` (the loop's figures:
    :class:`errpred.verified.VerifiedResult`).

    Attributes
    ----------
    cl : CutterLocations
        The accepted path (the reference when no correction was verified).
    verified : VerifiedCorrection
    best : int
        Index of the accepted path in :attr:`paths` (0: the reference).
    paths : list of CutterLocations
        The reference, then every predicted candidate.
    """

    cl: CutterLocations
    verified: VerifiedCorrection
    best: int = 0
    paths: list = field(default_factory=list)


def compensate_path(cl: CutterLocations, predict: Callable[[CutterLocations], Prediction], *,
                    iterate: bool = True, tolerance_mm: float = 1e-4, max_iterations: int = 3,
                    relaxation: float | None = None,
                    tolerance_um: float = VERIFY_TOLERANCE_UM,
                    spacing_mm: float = VERIFY_SPACING_MM, reach_mm: float = 0.0,
                    enough_rms_um: float | None = None, verify_walls: bool = True,
                    progress: Callable[[int, CutterLocations], None] | None = None
                    ) -> PathCompensation:
    """Correct a path, verified (see the module docstring).

    Parameters
    ----------
    cl : CutterLocations
        The reference path (e.g. the planned one), workpiece frame.
    predict : callable
        ``predict(path) -> Prediction`` of the program written from ``path``, dense
        (:meth:`errpred.geometry.Resolution.dense`).
    iterate : bool
    relaxation : float, optional [-]
        Share of the first pass's fit applied (:func:`errpred.verified.correct_verified`).
    tolerance_mm : float [mm]
        Stop when a pass's largest move is below this.
    max_iterations : int
    tolerance_um : float [um]
        How much worse than the reference a point may be.
    spacing_mm : float [mm]
        The dense spacing of ``predict``.
    reach_mm : float [mm]
        Where a candidate is worse, the wanted moves of the points within this distance
        (at least ``spacing_mm``) of the worse points are scaled back
        (:func:`errpred.verified.correct_verified`).
    enough_rms_um : float, optional [um]
        Stop iterating once a verified candidate's dense RMS is at most this.
    verify_walls : bool
        Compare the walls beside the floors too (:func:`errpred.verification.compare`).
    progress : callable, optional
        ``progress(k, path)`` before predicting candidate ``k`` (0: the reference).
    """
    paths: list[CutterLocations] = []

    def predict_field(c: CutterLocations) -> tuple[ErrorField, Prediction]:
        if progress is not None:
            progress(len(paths), c)
        paths.append(c)
        pred = predict(c)
        return error_field(pred, cl, moved=c is not cl), pred

    def apply(c: CutterLocations, edit: PathEdit, factor: float) -> CutterLocations:
        return apply_path_edit(c, edit, np.full(edit.n_vertices, factor))[0]

    res = correct_verified(cl, predict_field, fit_path, apply, iterate=iterate,
                           max_iterations=max_iterations, relaxation=relaxation,
                           tolerance_mm=tolerance_mm,
                           tolerance_um=tolerance_um, spacing_mm=spacing_mm,
                           reach_mm=reach_mm, enough_rms_um=enough_rms_um,
                           verify_walls=verify_walls)
    best = 0 if res.best_pass < 0 else res.best_pass + 1
    return PathCompensation(cl=res.best, verified=res, best=best, paths=paths)

