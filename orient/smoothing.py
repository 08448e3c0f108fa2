"""Choose one posture per cutter location under a limit on the axis change per mm.

The planner scores every candidate posture at every cutter location (its
stability margin, capped at the target so that any posture reaching the target
is as good as another, minus a small preference for the CAM's own posture).
Picking the best posture point by point could whip the rotary axes from one
extreme to another; :func:`best_smooth_path` picks the sequence with the
largest total score among those whose tool axis turns by at most
``max_rate_rad_per_mm`` per mm of tip travel (a Viterbi pass over the
candidates, exact for this objective). Where the surface normal itself turns
faster than the limit allows, the smallest achievable change is allowed.
A break (a rapid move between passes) lifts the limit.
"""

from __future__ import annotations

import numpy as np
from .constants import ANGLE_SLACK_RAD

__all__ = ["best_smooth_path"]



def best_smooth_path(score: np.ndarray, axes: np.ndarray, step_mm: np.ndarray,
                     max_rate_rad_per_mm: float, breaks: np.ndarray | None = None
                     ) -> np.ndarray:
    """Indices of the chosen candidate at each point (Viterbi).

    Parameters
    ----------
    score : ndarray, shape (n, s)
        Score of candidate ``j`` at point ``i``; ``-inf`` marks an infeasible
        candidate. Every point needs at least one finite score.
    axes : ndarray, shape (n, s, 3)
        Unit tool axis of each candidate.
    step_mm : ndarray, shape (n,) [mm]
        Tip travel from point ``i - 1`` to ``i`` (entry 0 unused).
    max_rate_rad_per_mm : float [rad/mm]
        Largest axis change per mm of travel.
    breaks : ndarray of bool, shape (n,), optional
        True where no limit applies between point ``i - 1`` and ``i``.

    Returns
    -------
    ndarray of int, shape (n,)
        The chosen candidate per point.

    Raises
    ------
    ValueError
        Bad shapes, a NaN score, or a point without a feasible candidate.
    """
    score = np.asarray(score, dtype=float)
    axes = np.asarray(axes, dtype=float)
    if score.ndim != 2:
        raise ValueError(f"score: expected shape (n, s), got {score.shape}")
    n, s = score.shape
    if axes.shape != (n, s, 3):
        raise ValueError(f"axes: expected shape ({n}, {s}, 3), got {axes.shape}")
    step = np.asarray(step_mm, dtype=float)
    if step.shape != (n,) or not np.all(np.isfinite(step[1:])) or np.any(step[1:] < 0):
        raise ValueError(f"step_mm: expected ({n},) finite values >= 0")
    if np.isnan(score).any():
        raise ValueError("score: NaN (use -inf for infeasible candidates)")
    if not (np.isfinite(max_rate_rad_per_mm) and max_rate_rad_per_mm > 0):
        raise ValueError(f"max_rate_rad_per_mm: expected a finite value > 0, got "
                         f"{max_rate_rad_per_mm!r}")
    feasible = np.isfinite(score)
    empty = ~feasible.any(axis=1)
    if empty.any():
        raise ValueError(f"score: point {int(np.argmax(empty))} has no feasible candidate")
    brk = np.zeros(n, bool) if breaks is None else np.asarray(breaks, dtype=bool)
    back = np.zeros((n, s), dtype=np.int32)
    total = np.where(feasible[0], score[0], -np.inf)
    for i in range(1, n):
        if brk[i]:
            j = int(np.argmax(total))
            back[i] = j
            total = np.where(feasible[i], score[i] + total[j], -np.inf)
            continue
        cos = np.clip(axes[i - 1] @ axes[i].T, -1.0, 1.0)          # (s_prev, s_now)
        angle = np.arccos(cos)
        reach = np.where(np.isfinite(total)[:, None] & feasible[i][None, :], angle, np.inf)
        limit = max_rate_rad_per_mm * step[i] + ANGLE_SLACK_RAD
        limit = max(limit, float(reach.min()) + ANGLE_SLACK_RAD)   # normal turns faster
        cand = np.where(reach <= limit, total[:, None], -np.inf)
        j = np.argmax(cand, axis=0)
        best = cand[j, np.arange(s)]
        back[i] = j
        total = np.where(np.isfinite(best) & feasible[i], best + score[i], -np.inf)
    out = np.empty(n, dtype=np.int64)
    out[-1] = int(np.argmax(total))
    for i in range(n - 1, 0, -1):
        out[i - 1] = back[i, out[i]]
    return out
