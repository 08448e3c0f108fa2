"""The process gains of the planner's lead x tilt grid, shared between cutter locations
with the same local cut (``orient.plan`` step 3).

A grid posture is given in the contact's local frame ``(f, b, n)``
(:func:`orient.geometry.posture_axis`), and the process gain of a posture depends on
the axis, the normal and the feed only through that frame: the kernel
(:func:`orient.gain.process_gain_batch`) works with their dot products and returns
``P = F^T H_t F`` for the tool frame ``F``. So at every cutter location whose local cut
(depth, pick feed, side of the previous pass, feed per tooth, curvatures) is the same,
the grid's gains are one set of matrices turned into that location's frame::

    P_world = M P_c M^T,    M = [f b n] (columns, world frame),

``P_c`` computed once with the normal ``+z`` and the feed ``+x`` (where ``M`` is the
identity); the cut sense and the engaged fraction do not turn. On the mold core's
raster (``[orient.cut]``: one depth and pick feed, the side one of three) the grid's
226 x 920 gains of a 1,220-line slice become 3 x 225. The result equals the direct
computation to round-off in the frame's dot products (the kernel's root finders then
stop within their tolerances of the same roots): ``tests/orient/test_grid_gains.py``
and ``benchmarks/check_plan_same.py`` compare them.

Every location's grid gains come this way, shared or not (the thin wall's cuts from
the part are nearly all different: there it costs what the direct computation does),
so that the gains do not depend on which locations are computed together: a Dask
task's chunk gives the one-process plan's gains bit for bit.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from .gain import process_gain_batch
from .geometry import local_frame, posture_axis

__all__ = ["share_grid_gains"]


def _cut_key(cut) -> tuple:
    return (float(cut.depth_mm), float(cut.pick_mm), int(cut.previous_side),
            float(cut.fz_mm), float(cut.curvature_f_1_mm), float(cut.curvature_b_1_mm))


def share_grid_gains(tool, coeffs, normal: np.ndarray, feed: np.ndarray, ok: np.ndarray,
                     cuts: list, grid: tuple[np.ndarray, np.ndarray], P: np.ndarray,
                     sense: np.ndarray, parallel: bool = True) -> np.ndarray:
    """Fill ``P`` (t, s, 3, 3) [N/m] and ``sense`` (t, s) of the grid's postures (the
    first ``S`` columns, ``grid = (lead, tilt)`` [rad] of shape (S,) each) where ``ok``
    (t, s), each local cut's once in the canonical frame, turned into the frames of the
    cutter locations (``normal``, ``feed`` (t, 3)) that have it; returns the mask (t, s)
    of what was filled (the caller computes the rest, the CAM's postures, directly)."""
    lead, tilt = (np.asarray(a, dtype=float) for a in grid)
    n_grid = lead.size
    done = np.zeros(ok.shape, bool)
    groups: dict[tuple, list[int]] = defaultdict(list)
    for r, c in enumerate(cuts):
        if ok[r, :n_grid].any():
            groups[_cut_key(c)].append(r)
    shared = [(rows, cuts[rows[0]]) for rows in groups.values()]
    if not shared:
        return done
    canon = posture_axis(np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), lead, tilt)
    ax, cut_of, where = [], [], []
    for rows, cut in shared:
        cols = np.flatnonzero(ok[rows, :n_grid].any(axis=0))
        ax.append(canon[cols])
        cut_of.extend([cut] * len(cols))
        where.append((np.asarray(rows), cols))
    cut_arr = np.empty(len(cut_of), dtype=object)
    cut_arr[:] = cut_of
    z = np.array([0.0, 0.0, 1.0])
    x = np.array([1.0, 0.0, 0.0])
    g = process_gain_batch(tool, coeffs, np.concatenate(ax), z, x, cut_arr, parallel=parallel)
    f, b, n = local_frame(normal, feed)
    M = np.stack([f, b, n], axis=-1)                     # (t, 3, 3): columns f, b, n
    at = 0
    for rows, cols in where:
        Pc, sc = g.P[at:at + len(cols)], g.cut_sense[at:at + len(cols)]
        at += len(cols)
        sub = ok[np.ix_(rows, cols)]
        rr, kk = np.nonzero(sub)
        r_, c_ = rows[rr], cols[kk]
        Mr = M[r_]
        P[r_, c_] = np.einsum("kia,kab,kjb->kij", Mr, Pc[kk], Mr)
        sense[r_, c_] = sc[kk]
        done[r_, c_] = True
    return done
