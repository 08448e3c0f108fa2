"""Correct, re-predict densely, compare with the original, repeat: the loop that decides
what may be written (shared by a program's correction, :mod:`errpred.correct`, and a
5-axis path's, :mod:`errpred.correct_path`).

1. The original is predicted densely (every block, points at most
   ``VERIFY_SPACING_MM`` apart, both ends included): the reference field.
2. A pass fits moves to the current candidate's errors (against the original
   surface) and applies a share of them (``RELAXATION``, halved after a pass that
   did not improve: under-relaxation; a single pass, ``iterate=False``, applies them
   whole). From the second pass on, the error's
   response to a move is measured at each point between the last two accepted
   candidates (a secant) instead of taken from the model's first-order gain.
3. The new candidate is predicted densely and compared with the original point
   by point (:func:`errpred.verification.compare`). Where it is worse, the moves
   wanted by the points near there are scaled down (``FALLBACK_SCALINGS`` times) by
   the share that brings the worse point's error back inside its allowed band with
   half the tolerance to spare (linear in the move; at most ``FALLBACK_SCALE_MAX``),
   then those points are held where they are (their original coordinates), the
   moves fitted again each time near the points whose weight changed only (the
   rejected candidate's moves kept beyond ``FALLBACK_FREE_VERTICES`` vertices along
   each chain; between, the fit joins them smoothly) and the candidate predicted
   again (which recomputes stage 1 near the change only, errpred.repredict).
4. A candidate is accepted only when it is no worse than the original anywhere
   and better than the best so far (RMS, or the largest |E| at no higher RMS):
   acceptance is monotone, so iterating cannot wander off. The original is the
   first candidate: if no pass is accepted, nothing is corrected, and the caller
   says so.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .constants import (
    FALLBACK_SCALE_MAX,
    FALLBACK_SCALINGS,
    RELAXATION,
    SECANT_MIN_SHIFT_UM,
    SECANT_SLOPE_RANGE,
    VERIFY_SPACING_MM,
    VERIFY_TOLERANCE_UM,
)
from .verification import (
    Comparison,
    ErrorField,
    ErrorStats,
    _no_points,
    compare,
    error_stats,
    reference_at,
)

__all__ = ["PassRecord", "VerifiedCorrection", "VerifiedResult", "correct_verified"]

#: An improvement smaller than this does not count (the prediction's noise) [um].
_IMPROVEMENT_UM = 1.0e-3
#: Iterating stops once the relaxation has been halved below this [-].
_MIN_RELAXATION = 0.1


@dataclass(frozen=True)
class PassRecord:
    """One predicted candidate.

    Attributes
    ----------
    index : int
        Pass number (1, 2, ...).
    attempt : int
        0 for the pass's moves as fitted; 1, 2, ... after scaling down the moves where
        it was worse.
    relaxation : float
        Share of the fitted moves applied.
    largest_move_mm : float [mm]
        Largest vertex move of the pass's fit (before relaxation and fallback).
    comparison : Comparison
        Against the original.
    accepted : bool
    """

    index: int
    attempt: int
    relaxation: float
    largest_move_mm: float
    comparison: Comparison
    accepted: bool


@dataclass
class VerifiedCorrection:
    """Result of :func:`correct_verified`.

    Attributes
    ----------
    best : object
        The accepted candidate (the original if none was).
    best_pass : int
        Index into :attr:`passes` of the accepted candidate, -1 for the original.
    before : ErrorField
        The original's dense errors.
    best_field : ErrorField
        The best candidate's (against the original's surface).
    comparison : Comparison or None
        The best candidate against the original (None when it is the original).
    passes : list of PassRecord
    predictions : list
        The prediction of the original, then of every candidate, in order; None for a
        candidate that is not the best (dropped before the next one is predicted: a
        program's dense prediction is large, and only the original's and the best's
        are read).
    """

    best: Any
    best_pass: int
    before: ErrorField
    best_field: ErrorField
    comparison: Comparison | None
    passes: list = field(default_factory=list)
    predictions: list = field(default_factory=list)

    @property
    def corrected(self) -> bool:
        """Whether a verified correction was found."""
        return self.best_pass >= 0

    @property
    def before_stats(self) -> ErrorStats:
        return error_stats(self.before.E_um)

    @property
    def after_stats(self) -> ErrorStats:
        return error_stats(self.best_field.E_um)

    def reason(self) -> str:
        """One line: the verified result, or why nothing may be written."""
        if self.corrected:
            return self.comparison.reason()
        if not self.passes:
            b = self.before_stats
            return (f"nothing to correct: max |E| {b.max_abs_um:.2f} um on {b.points} "
                    f"points" if b.points else "nothing to correct: no predicted point")
        last = self.passes[-1].comparison
        if last.ok:
            return ("no correction improved on the original program: " + last.reason())
        return "no verified correction: the best candidate was " + last.reason()


class VerifiedResult:
    """What a correction's result says of its loop (``self.verified``), for the results of
    :func:`errpred.correct.compensate` and :func:`errpred.correct_path.compensate_path`."""

    verified: VerifiedCorrection

    @property
    def corrected(self) -> bool:
        """A correction no worse than the original anywhere was found."""
        return self.verified.corrected

    @property
    def iterations(self) -> int:
        """Correction passes made."""
        return len({p.index for p in self.verified.passes})

    @property
    def predictions(self) -> list:
        """The dense prediction of the original, then of every candidate (None but for the
        best one: :attr:`VerifiedCorrection.predictions`)."""
        return self.verified.predictions

    @property
    def largest_change_mm(self) -> list[float]:
        """Largest move of each predicted candidate (fitted times relaxation) [mm]."""
        return [p.largest_move_mm * p.relaxation for p in self.verified.passes]

    @property
    def max_error_um(self) -> list[float]:
        """Largest |E| of the original, then of each candidate, on the dense points [um]."""
        v = self.verified
        return [v.before_stats.max_abs_um] + [p.comparison.after.max_abs_um for p in v.passes]

    @property
    def rms_error_um(self) -> list[float]:
        """RMS of E of the original, then of each candidate, on the dense points [um]."""
        v = self.verified
        return [v.before_stats.rms_um] + [p.comparison.after.rms_um for p in v.passes]

    def reason(self) -> str:
        """One line: the verified result, or why nothing may be written."""
        return self.verified.reason()


def _improved(after: ErrorStats, best: ErrorStats) -> bool:
    if after.points == 0:
        return False
    if after.rms_um < best.rms_um - _IMPROVEMENT_UM:
        return True
    return (after.max_abs_um < best.max_abs_um - _IMPROVEMENT_UM
            and after.rms_um <= best.rms_um + _IMPROVEMENT_UM)


def _drop_rejected(out: VerifiedCorrection) -> None:
    """Drop the dense predictions of the candidates that are not the best (None): only
    the original's and the best's are read, and each is a program's worth."""
    for i in range(1, len(out.predictions)):
        if i != out.best_pass + 1:
            out.predictions[i] = None


def _secant_slope(prev: ErrorField | None, cur: ErrorField, spacing_mm: float
                  ) -> np.ndarray | None:
    """``dE/dshift`` at each point of ``cur`` measured between two predicted candidates
    (the error against the original's surface over the path's normal displacement,
    both at the same place on the original path), NaN where the path hardly moved
    there or the earlier candidate has no point; clipped to ``SECANT_SLOPE_RANGE``.
    The model's first-order value is ``1 - gain``; near a wall's end or where another
    pass finishes the surface the measured one is the better guide."""
    if prev is None:
        return None
    E0 = reference_at(prev, cur, spacing_mm, prev.E_um)
    s0 = reference_at(prev, cur, spacing_mm, prev.shift_um)
    dE, ds = cur.E_um - E0, cur.shift_um - s0
    slope = np.full(len(cur), np.nan)
    ok = np.isfinite(dE) & np.isfinite(ds) & (np.abs(ds) >= SECANT_MIN_SHIFT_UM)
    slope[ok] = np.clip(dE[ok] / ds[ok], *SECANT_SLOPE_RANGE)
    return slope


def _fallback_scale(Fc: ErrorField, Fk: ErrorField, cmp: Comparison, spacing_mm: float,
                    reach_mm: float) -> np.ndarray:
    """Per point of ``Fc`` (the candidate the pass moved from), the share of its wanted
    move to keep (1 away from the worse points of ``Fk``): at each worse point the
    error went from ``Ec`` to ``Ea`` outside its band; the share of that change that
    ends half a tolerance inside the band, assuming the error linear in the move,
    clipped to [0, ``FALLBACK_SCALE_MAX``]; the smallest one within ``reach_mm``.
    The worse wall points (:attr:`Comparison.walls`) count the same way, their ``Ec``
    from ``Fc``'s walls (none there: share 0)."""
    from scipy.spatial import cKDTree

    scale = np.ones(len(Fc))
    if len(Fc) == 0:
        return scale
    parts = [(Fc, Fk, cmp)]
    if cmp.walls is not None and Fk.walls is not None:
        parts.append((Fc.walls if Fc.walls is not None else _no_points(), Fk.walls,
                      cmp.walls))
    tree = None
    for fc, fk, c in parts:
        bad = np.flatnonzero(c.worse)
        if bad.size == 0:
            continue
        Ec = reference_at(fc, fk, spacing_mm, fc.E_um)[bad]
        Ea = fk.E_um[bad]
        low, high = c.allowed_um[bad, 0], c.allowed_um[bad, 1]
        margin = 0.5 * c.tolerance_um
        target = np.where(Ea > high, high - margin, low + margin)
        change = Ea - Ec
        with np.errstate(divide="ignore", invalid="ignore"):
            share = (target - Ec) / change
        share = np.where(np.isfinite(share) & (np.abs(change) > 0), share, 0.0)
        share = np.clip(share, 0.0, FALLBACK_SCALE_MAX)
        if tree is None:
            tree = cKDTree(Fc.tip_mm)
        near = tree.query_ball_point(fk.tip_mm[bad], reach_mm)
        for idx, f in zip(near, share, strict=True):
            if idx:
                scale[idx] = np.minimum(scale[idx], f)
    return scale


def correct_verified(original: Any,
                     predict: Callable[[Any], tuple[ErrorField, Any]],
                     fit: Callable[..., Any],
                     apply: Callable[[Any, Any, float], Any],
                     *, iterate: bool = True, max_iterations: int = 5,
                     relaxation: float | None = None,
                     tolerance_mm: float = 1e-4, tolerance_um: float = VERIFY_TOLERANCE_UM,
                     spacing_mm: float = VERIFY_SPACING_MM, reach_mm: float = 0.0,
                     lines: dict | None = None, enough_rms_um: float | None = None,
                     verify_walls: bool = True,
                     progress: Callable[[str], None] | None = None) -> VerifiedCorrection:
    """The verified correction loop (see the module docstring).

    Parameters
    ----------
    original : object
        The program or path to correct.
    predict : callable
        ``predict(candidate) -> (ErrorField against the original, prediction)``, dense.
    fit : callable
        ``fit(candidate, field, slope, weight, hold=None, free=None) -> edit``:
        ``slope`` (one per point of the field, or None) is the measured ``dE/dshift``
        between the last two accepted candidates (NaN: not measured; use the model's);
        ``weight`` (one per point) scales each point's wanted move (1; less near the
        places where a candidate was worse; 0 at last: those points are held where they
        are). A fallback's refit passes ``hold`` (the rejected candidate's edit) and
        ``free`` (the points whose weight changed): the refit keeps ``hold``'s moves
        away from those points (:func:`errpred.offset.fit_units`). The edit has
        ``largest_mm`` (largest vertex move [mm]).
    apply : callable
        ``apply(candidate, edit, factor) -> new candidate``: the edit's moves times
        ``factor`` (the relaxation).
    iterate : bool
        One pass (False) or up to ``max_iterations``.
    relaxation : float, optional [-]
        Share of the first pass's fit applied, in (0, 1] (default ``RELAXATION`` when
        iterating, 1 for one pass). Below 1 where passes share the finished surface
        (a raster's picks: the first-order gain overshoots there).
    tolerance_mm : float [mm]
        Stop when a pass's largest move is below this.
    tolerance_um : float [um]
        How much worse than the original a point may be.
    spacing_mm : float [mm]
        The dense spacing ``predict`` uses.
    reach_mm : float [mm]
        Where a candidate is worse than the original, the wanted moves of the points
        within this distance (at least ``spacing_mm``) of the worse ones are scaled
        down and the moves fitted again (a neighbouring vertex's move, or a neighbouring
        pass's, can overcut a surface that its own point did not ask for).
    lines : dict, optional
        Block of the original -> source line, for the comparisons' reasons.
    enough_rms_um : float, optional [um]
        Stop iterating once an accepted candidate's dense RMS error is at most this
        (default: go on to ``max_iterations`` or ``tolerance_mm``).
    verify_walls : bool
        Compare the walls beside the floors too (:func:`errpred.verification.compare`).
    progress : callable, optional
        ``progress(stage)`` before each prediction.
    """
    if not (math.isfinite(tolerance_mm) and tolerance_mm > 0):
        raise ValueError(f"tolerance_mm: expected a finite value > 0, got {tolerance_mm!r}")
    if not (isinstance(max_iterations, int) and max_iterations >= 1):
        raise ValueError(f"max_iterations: expected an integer >= 1, got {max_iterations!r}")
    if relaxation is not None and not (math.isfinite(relaxation) and 0 < relaxation <= 1):
        raise ValueError(f"relaxation: expected a share in (0, 1], got {relaxation!r}")
    if enough_rms_um is not None and not (math.isfinite(enough_rms_um) and enough_rms_um >= 0):
        raise ValueError(f"enough_rms_um: expected a finite value >= 0, got {enough_rms_um!r}")
    say = progress or (lambda stage: None)
    say("original")
    F0, P0 = predict(original)
    out = VerifiedCorrection(best=original, best_pass=-1, before=F0, best_field=F0,
                             comparison=None, predictions=[P0])
    if len(F0) == 0:
        return out
    best_stats = error_stats(F0.E_um)
    current, Fc = original, F0
    # the first pass's share: one pass applies the whole fit unless told (the fallback
    # guards it), an iteration starts under-relaxed
    omega = relaxation if relaxation is not None else (RELAXATION if iterate else 1.0)
    passes = max_iterations if iterate else 1
    F_prev = None
    for k in range(1, passes + 1):
        slope = _secant_slope(F_prev, Fc, spacing_mm)
        weight = np.ones(len(Fc))
        edit = fit(current, Fc, slope, weight)
        if edit.largest_mm * omega < tolerance_mm:
            break
        largest = float(edit.largest_mm)
        fitted_with = weight
        for attempt in range(FALLBACK_SCALINGS + 2):
            say(f"pass {k}" + (f", fallback {attempt}" if attempt else ""))
            if attempt:
                # refitted near the points whose weight changed only; the rejected
                # candidate's moves everywhere else (FALLBACK_FREE_VERTICES)
                edit = fit(current, Fc, slope, weight, hold=edit, free=weight != fitted_with)
                fitted_with = weight
            cand = apply(current, edit, omega)
            _drop_rejected(out)                       # before the next one is made
            Fk, Pk = predict(cand)
            out.predictions.append(Pk)
            cmp = compare(F0, Fk, tolerance_um=tolerance_um, spacing_mm=spacing_mm,
                          lines=lines, walls=verify_walls)
            ok = cmp.ok and _improved(cmp.after, best_stats)
            out.passes.append(PassRecord(k, attempt, omega, largest, cmp, ok))
            if cmp.ok:
                break
            scale = _fallback_scale(Fc, Fk, cmp, spacing_mm, max(reach_mm, spacing_mm))
            if (scale >= 1.0).all():
                break
            if attempt < FALLBACK_SCALINGS:
                weight = weight * scale
            else:
                weight = np.where(scale < 1.0, 0.0, weight)
            if not weight.any():
                break                 # nothing left to move: the candidate is the current
        if out.passes[-1].accepted:
            out.best, out.best_pass, out.best_field, out.comparison = (
                cand, len(out.passes) - 1, Fk, cmp)
            best_stats = cmp.after
            F_prev, current, Fc = Fc, cand, Fk
            omega = min(1.0, 2.0 * omega)
            if enough_rms_um is not None and best_stats.rms_um <= enough_rms_um:
                break
        else:
            omega *= 0.5
            if omega < _MIN_RELAXATION:
                break
    _drop_rejected(out)
    return out
