"""Correct a 5-axis path (cutter locations, workpiece frame) against its predicted error.

``docs/method.md`` §6 on a path instead of a program's text: a 5-axis
program's X/Y/Z words are machine coordinates that the rotary axes turn, so
the correction is made where the physics is, on the tool tips in the
workpiece frame, and the program is written again from them (``nc.writer``).
The tool axis is kept: each tip moves along the surface normals by the chain
fit of :func:`errpred.correct.chain_moves` (segment ``k`` runs from cutter
location ``k - 1`` to ``k``), so the ball centre moves by the same vector.

Each prediction point (on the program written from the path, where the
writer may have inserted points) is placed on the path's nearest feed
segment. As in :func:`errpred.correct.compensate`, iterating measures the
error against the *reference* path's surface: the prediction plus how far
the corrected path moved along the normal at that place.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from nc.path import CutterLocations

from .constants import LOCATE_AXIS_MM
from .correct import BlockError, chain_moves, largest_error_um
from .predict import Prediction

__all__ = ["PathCompensation", "compensate_path", "corrected_path", "error_points",
           "path_errors"]


def _locate(cl: CutterLocations, points: np.ndarray, axes: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """Feed segment (ending at cutter location k) and fraction along it nearest each point.

    The nearest cutter location is found on tip *and* axis (``LOCATE_AXIS_MM`` per
    radian of axis): on a 5-axis path the same tip is reached from different
    contacts with different axes (a tilted pass can run where another pass's tips
    lie), so the tip alone can put a point on the wrong pass."""
    from scipy.spatial import cKDTree

    tip = cl.tip
    n = len(cl)
    w = LOCATE_AXIS_MM
    near = cKDTree(np.hstack([tip, w * cl.axis])).query(np.hstack([points, w * axes]))[1]
    best_d = np.full(len(points), np.inf)
    seg = np.full(len(points), -1, dtype=np.int64)
    frac = np.zeros(len(points))
    for cand in (near, near + 1):
        k = np.clip(cand, 1, n - 1)
        a, e = tip[k - 1], tip[k]
        d = e - a
        L2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
        t = np.clip(np.einsum("ij,ij->i", points - a, d) / L2, 0.0, 1.0)
        ax = (1 - t[:, None]) * cl.axis[k - 1] + t[:, None] * cl.axis[k]
        dist = np.hypot(np.linalg.norm(a + t[:, None] * d - points, axis=1),
                        w * np.linalg.norm(ax - axes, axis=1))
        better = (dist < best_d) & ~cl.rapid[k]
        best_d[better], seg[better], frac[better] = dist[better], k[better], t[better]
    return seg, frac


def _point_errors(cl: CutterLocations, prediction: Prediction,
                  reference: CutterLocations | None):
    """Per predicted point: the point, its segment, fraction, normal, gain and error [mm]."""
    pts = prediction.predicted()
    if reference is not None and len(reference) != len(cl):
        raise ValueError(f"reference: expected {len(cl)} cutter locations like the path, got "
                         f"{len(reference)}")
    if not pts:
        return pts, np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
    tips = np.array([p.geometry.tip for p in pts])
    seg, frac = _locate(cl, tips, np.array([p.geometry.axis for p in pts]))
    E = np.array([p.result.E_um * 1e-3 for p in pts])
    if reference is not None:
        k = np.maximum(seg, 1)
        t = frac[:, None]
        moved = ((1 - t) * (cl.tip[k - 1] - reference.tip[k - 1])
                 + t * (cl.tip[k] - reference.tip[k]))
        normal = np.array([p.geometry.gen.normal_world for p in pts])
        E = E + np.einsum("ij,ij->i", moved, normal)
    return pts, seg, frac, E


def error_points(cl: CutterLocations, prediction: Prediction,
                 reference: CutterLocations | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Generation points (m, 3) [mm] and errors (m,) [um] against ``reference``'s surface
    (see :func:`path_errors`), for the points on a feed segment of ``cl``."""
    pts, seg, _, E = _point_errors(cl, prediction, reference)
    keep = seg >= 0
    xyz = np.array([p.geometry.gen.point_world for p in pts]).reshape(-1, 3)
    return xyz[keep], E[keep] * 1e3


def path_errors(cl: CutterLocations, prediction: Prediction,
                reference: CutterLocations | None = None) -> dict[int, list[BlockError]]:
    """Errors per feed segment of ``cl``, against ``reference`` (default: ``cl`` itself).

    Returns
    -------
    dict of int -> list of BlockError
        Segment ``k`` (cutter location ``k - 1`` to ``k``): one entry per prediction
        point on it, ordered along it; ``E_mm`` is the prediction plus, with a
        reference of the same length, the normal component of how far the path moved
        from it at that place.
    """
    pts, seg, frac, E = _point_errors(cl, prediction, reference)
    out: dict[int, list[BlockError]] = {}
    for p, k, t, e in zip(pts, seg, frac, E, strict=True):
        if k < 0:
            continue
        out.setdefault(int(k), []).append(BlockError(float(e), p.geometry.gen.normal_world,
                                                     float(t), p.result.gain))
    for v in out.values():
        v.sort(key=lambda be: be.fraction)
    return out


def corrected_path(cl: CutterLocations, errors: dict[int, list[BlockError]]
                   ) -> tuple[CutterLocations, float]:
    """The path with the tips moved against ``errors``, and the largest move [mm]."""
    moves = chain_moves(errors, joined=lambda k: not cl.rapid[k])
    tip = cl.tip.copy()
    largest = 0.0
    for k, m in moves.items():
        tip[k] += m
        largest = max(largest, float(np.linalg.norm(m)))
    return CutterLocations(tip, cl.axis, cl.feed_mm_min, cl.spindle_rpm, cl.block,
                           cl.rapid), largest


@dataclass
class PathCompensation:
    """Result of :func:`compensate_path`.

    Attributes
    ----------
    cl : CutterLocations
        The corrected path (the best pass).
    iterations : int
        Correction passes made.
    largest_change_mm : list of float [mm]
        Largest tip move of each pass.
    max_error_um, rms_error_um : list of float [um]
        Largest and root-mean-square |error| against the reference path's surface,
        before each pass and after the last (re-predicted).
    best : int
        Index (into the lists above) of the pass returned: 0 is the reference itself.
    predictions : list of Prediction
        The prediction of each pass's path (the first: the reference).
    paths : list of CutterLocations
        The path of each pass (the first: the reference).
    """

    cl: CutterLocations
    iterations: int = 0
    largest_change_mm: list[float] = field(default_factory=list)
    max_error_um: list[float] = field(default_factory=list)
    rms_error_um: list[float] = field(default_factory=list)
    best: int = 0
    predictions: list[Prediction] = field(default_factory=list)
    paths: list[CutterLocations] = field(default_factory=list)


def _rms_um(errors: dict[int, list[BlockError]]) -> float:
    e = [be.E_mm for v in errors.values() for be in v]
    return float(np.sqrt(np.mean(np.square(e)))) * 1e3 if e else 0.0


def compensate_path(cl: CutterLocations, predict: Callable[[CutterLocations], Prediction], *,
                    iterate: bool = True, tolerance_mm: float = 1e-4,
                    max_iterations: int = 3,
                    progress: Callable[[int, CutterLocations], None] | None = None
                    ) -> PathCompensation:
    """Correct a path; with ``iterate``, until a pass changes no tip by ``tolerance_mm``.

    Parameters
    ----------
    cl : CutterLocations
        The reference path (e.g. the planned one), workpiece frame.
    predict : callable
        ``predict(path) -> Prediction`` of the program written from ``path``.
    iterate : bool
        One correction (False) or predict-then-correct until converged.
    tolerance_mm : float [mm]
    max_iterations : int
    progress : callable, optional
        ``progress(k, path)`` before predicting pass ``k`` (0: the reference).

    Returns
    -------
    PathCompensation
        The pass with the smallest RMS error is returned (iterating wanders
        once the prediction's own noise is reached).
    """
    if not (math.isfinite(tolerance_mm) and tolerance_mm > 0):
        raise ValueError(f"tolerance_mm: expected a finite value > 0, got {tolerance_mm!r}")
    if not (isinstance(max_iterations, int) and max_iterations >= 1):
        raise ValueError(f"max_iterations: expected an integer >= 1, got {max_iterations!r}")
    out = PathCompensation(cl=cl)
    current = cl
    passes = max_iterations if iterate else 1
    for k in range(passes + 1):
        if progress is not None:
            progress(k, current)
        pred = predict(current)
        errs = path_errors(current, pred, reference=cl)
        out.predictions.append(pred)
        out.paths.append(current)
        out.max_error_um.append(largest_error_um(errs))
        out.rms_error_um.append(_rms_um(errs))
        if k == passes or (k > 0 and out.largest_change_mm[-1] < tolerance_mm):
            break
        if k > 1 and out.rms_error_um[-1] > out.rms_error_um[-2]:
            break  # the prediction's own noise is reached
        current, largest = corrected_path(current, errs)
        out.iterations += 1
        out.largest_change_mm.append(largest)
    out.best = int(np.argmin(out.rms_error_um))
    out.cl = out.paths[out.best]
    return out
