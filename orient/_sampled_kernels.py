"""Numba kernel of the sampled engagement of flute 0 (:func:`orient.engagement.engagement`),
with its numpy twin.

For each rotation sample ``i`` and micro edge ``j`` of flute 0 (tool-frame position
``x = rho sin phi, y = rho cos phi, z``, ``phi = theta_i - psi_j``) the kernel decides, in
one pass and without the arrays numpy made per sample (``docs/method.md`` §8;
``orient/engagement.py`` describes the material model):

1. below the stock top: ``n . p < depth - (kf (f . p)^2 + kb (b . p)^2) / 2``, each
   projection ``tip . v + x (F v)_0 + y (F v)_1 + z (F v)_2`` (``F`` the tool frame),
   tested only on the edges that can reach below it somewhere on their circle
   (:func:`edges_reaching`: on the bundled thin wall's simulated run the kernel then
   takes 0.69 of its time);
2. the chip ``h = (f0 sk) sin phi + (f1 sk) cos phi - f2 ck``, clamped at 0
   (``errpred.force.chip_thickness``);
3. outside the previous pass's sweep (when there is one), tested only for the
   points whose answer can matter: ``h > chip_min``, or ``h <= 0`` when the trailing
   edges are asked for;
4. with ``trailing``: of the points below the top with ``h <= 0``, those outside the
   current pass's sweep up to one feed per tooth back (tested before the previous
   pass's: most of them are inside it, and then the other test is not needed).

The sweep tests are errpred's (``errpred.sweeps.inside_any_sweep``) on world points
``tip + x F_0 + y F_1 + z F_2``, formed term by term (the numpy code formed them by a
matrix product, whose BLAS may round the three-term sum otherwise: a point within
rounding, ~1e-15 mm, of a sweep's boundary could answer differently; on the whole
bundled mold-core program no answer did).

:func:`flute0_engagement_numpy` is the twin: the same IEEE operations in the same order
on whole arrays; ``tests/orient/test_sampled_kernels.py`` compares them bit for bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from errpred.sweeps import inside_any_sweep

__all__ = ["edges_reaching", "flute0_engagement", "flute0_engagement_numpy"]

#: The sweeps' axis-aligned bounds: none (one sweep, every point tested) [mm].
_BIG = 1e300
#: Margin of an edge's reach below the stock top over rounding [mm]: the bound and the
#: samples' ``n . p`` are sums of a few terms of at most tens of mm, rounded to ~1e-14 mm;
#: an edge within this of the top is sampled as before (the same answers).
_REACH_MARGIN_MM = 1e-9


@njit(cache=True, nogil=True)
def _world_points(sin0, cos0, rho, z, frame, tip, ii, jj, k):
    """World points of samples ``(ii[t], jj[t])``, ``t < k``, shape (k, 3) [mm]."""
    pts = np.empty((k, 3))
    for t in range(k):
        i, j = ii[t], jj[t]
        x = rho[j] * sin0[i, j]
        y = rho[j] * cos0[i, j]
        zz = z[j]
        for c in range(3):
            pts[t, c] = tip[c] + (x * frame[0, c] + y * frame[1, c] + zz * frame[2, c])
    return pts


@njit(cache=True, nogil=True)
def edges_reaching(proj, rho, z, depth, kf, kb):
    """Which micro edges can reach below the stock top anywhere on their circle, shape (m,)
    of bool (:func:`flute0_engagement`'s arguments of the same names).

    The lowest ``n . p`` of an edge is ``tip . n + z (F n)_2 - rho |((F n)_0, (F n)_1)|``;
    the top is at most ``depth`` where it is convex or flat, and where it is concave (a
    curvature < 0) at most ``depth`` plus its rise over the largest ``|f . p|``,
    ``|b . p|`` on the circle. An edge whose lowest point stays above that by more than
    rounding (``_REACH_MARGIN_MM``) has no sample below the top: the kernel fills only
    its chips."""
    m = rho.shape[0]
    reach = np.empty(m, np.bool_)
    r_n = np.sqrt(proj[0, 1] * proj[0, 1] + proj[0, 2] * proj[0, 2])
    r_f = np.sqrt(proj[1, 1] * proj[1, 1] + proj[1, 2] * proj[1, 2])
    r_b = np.sqrt(proj[2, 1] * proj[2, 1] + proj[2, 2] * proj[2, 2])
    for j in range(m):
        top_j = depth
        if kf < 0.0:
            a = abs(proj[1, 0] + z[j] * proj[1, 3]) + rho[j] * r_f
            top_j -= 0.5 * kf * a * a
        if kb < 0.0:
            a = abs(proj[2, 0] + z[j] * proj[2, 3]) + rho[j] * r_b
            top_j -= 0.5 * kb * a * a
        reach[j] = proj[0, 0] + z[j] * proj[0, 3] - rho[j] * r_n < top_j + _REACH_MARGIN_MM
    return reach


@njit(cache=True, nogil=True)
def flute0_engagement(sin0, cos0, rho, z, sk, ck, frame, tip, proj, depth, kf, kb,
                      prev_p0, prev_d, cur_p0, cur_d, axis, c, r, top, eps, f_tool,
                      chip_min, trailing, cutting, h):
    """Fill ``cutting`` (bool) and ``h`` [mm], shape (n, m), for flute 0.

    Parameters
    ----------
    sin0, cos0 : ndarray, shape (n, m)
        ``sin``, ``cos`` of ``phi = theta_i - psi_j`` (numpy's, made once per angle grid).
    rho, z, sk, ck : ndarray, shape (m,)
        Micro edges' radius and height [mm], ``sin``/``cos`` of their contact angle.
    frame : ndarray, shape (3, 3)
        Tool frame rows.
    tip : ndarray, shape (3,) [mm]
        Tip relative to the contact point.
    proj : ndarray, shape (3, 4)
        Rows for ``n``, ``f``, ``b``: ``tip . v`` and ``frame @ v``.
    depth, kf, kb : float
        Stock top: depth [mm], its curvatures along ``f``, ``b`` [1/mm].
    prev_p0, prev_d : ndarray, shape (s, 3) [mm]
        The previous pass's sweep (``s = 0``: none).
    cur_p0, cur_d : ndarray, shape (1, 3) [mm]
        The current pass's sweep up to one feed per tooth back (used with ``trailing``).
    axis : ndarray, shape (1, 3)
        Unit tool axis.
    c, r, top, eps : float [mm]
        Core radius, corner radius, flute length, membership tolerance.
    f_tool : ndarray, shape (3,) [mm]
        Feed per tooth in the tool frame.
    chip_min : float [mm]
        A sample cuts where its chip is above this.
    trailing : bool
    cutting : ndarray of bool, shape (n, m)
    h : ndarray, shape (n, m) [mm]

    Returns
    -------
    rows, cols : ndarray of int64, shape (c,)
        The cutting samples, ``np.nonzero(cutting)``.
    """
    n, m = sin0.shape
    f0, f1, f2 = f_tool[0], f_tool[1], f_tool[2]
    # a flat top is at ``depth`` exactly: ``depth - 0.5 (0 (af af) + 0 (ab ab))`` is
    # ``depth`` for any finite af, ab (a zero's sign aside, which the difference drops)
    flat = kf == 0.0 and kb == 0.0
    reach = edges_reaching(proj, rho, z, depth, kf, kb)
    # samples whose sweep test can matter, and what their chip says
    ii = np.empty(n * m, np.int64)
    jj = np.empty(n * m, np.int64)
    k = 0
    for i in range(n):
        for j in range(m):
            hv = (f0 * sk[j]) * sin0[i, j] + (f1 * sk[j]) * cos0[i, j] - f2 * ck[j]
            if hv < 0.0:
                hv = 0.0
            h[i, j] = hv
            cutting[i, j] = False
            if not reach[j]:
                continue
            x = rho[j] * sin0[i, j]
            y = rho[j] * cos0[i, j]
            zz = z[j]
            an = proj[0, 0] + x * proj[0, 1] + y * proj[0, 2] + zz * proj[0, 3]
            if flat:
                level = depth
            else:
                af = proj[1, 0] + x * proj[1, 1] + y * proj[1, 2] + zz * proj[1, 3]
                ab = proj[2, 0] + x * proj[2, 1] + y * proj[2, 2] + zz * proj[2, 3]
                level = depth - 0.5 * (kf * (af * af) + kb * (ab * ab))
            if an < level and (hv > chip_min or (trailing and hv <= 0.0)):
                ii[k] = i
                jj[k] = j
                k += 1
    big = np.full((1, 3), _BIG)
    # a zero chip cuts only outside both sweeps: the current pass's first, which holds most
    # of them (the same answers as the previous pass's first; fewer tests)
    if trailing:
        kz = 0
        for t in range(k):
            if h[ii[t], jj[t]] <= 0.0:
                kz += 1
        if kz > 0:
            iz = np.empty(kz, np.int64)
            jz = np.empty(kz, np.int64)
            kz = 0
            for t in range(k):
                if h[ii[t], jj[t]] <= 0.0:
                    iz[kz] = ii[t]
                    jz[kz] = jj[t]
                    kz += 1
            pts = _world_points(sin0, cos0, rho, z, frame, tip, iz, jz, kz)
            removed = inside_any_sweep(pts, np.ones(kz, np.bool_), cur_p0, cur_d, axis, -big,
                                       big, c, r, top, eps)
            kept = 0
            kz = 0
            for t in range(k):
                if h[ii[t], jj[t]] <= 0.0:
                    kz += 1
                    if removed[kz - 1]:
                        continue
                ii[kept] = ii[t]
                jj[kept] = jj[t]
                kept += 1
            k = kept
    if prev_p0.shape[0] > 0 and k > 0:
        pts = _world_points(sin0, cos0, rho, z, frame, tip, ii, jj, k)
        removed = inside_any_sweep(pts, np.ones(k, np.bool_), prev_p0, prev_d, axis, -big,
                                   big, c, r, top, eps)
        kept = 0
        for t in range(k):
            if not removed[t]:
                ii[kept] = ii[t]
                jj[kept] = jj[t]
                kept += 1
        k = kept
    # what is left is in the material (and, for a zero chip, outside the current pass);
    # every step kept the samples' order: by row, then edge (np.nonzero's)
    for t in range(k):
        cutting[ii[t], jj[t]] = True
    return ii[:k].copy(), jj[:k].copy()


def flute0_engagement_numpy(sin0, cos0, rho, z, sk, ck, frame, tip, proj, depth, kf, kb,
                            prev_p0, prev_d, cur_p0, cur_d, axis, c, r, top, eps, f_tool,
                            chip_min, trailing):
    """The twin of :func:`flute0_engagement` on whole arrays (the numpy code it replaced,
    with the world points formed term by term); returns ``(cutting, h, rows, cols)``."""
    x = rho * sin0
    y = rho * cos0
    zz = z[None, :]

    def along(row: int) -> np.ndarray:
        return proj[row, 0] + x * proj[row, 1] + y * proj[row, 2] + zz * proj[row, 3]

    level = depth - 0.5 * (kf * along(1) ** 2 + kb * along(2) ** 2)
    inside = along(0) < level
    h = np.maximum((f_tool[0] * sk) * sin0 + (f_tool[1] * sk) * cos0 - f_tool[2] * ck, 0.0)
    big = np.full((1, 3), _BIG)

    def removed_by(mask: np.ndarray, p0: np.ndarray, d: np.ndarray) -> np.ndarray:
        where = np.nonzero(mask)
        px, py, pz = x[where], y[where], np.broadcast_to(zz, x.shape)[where]
        pts = np.stack([tip[cc] + (px * frame[0, cc] + py * frame[1, cc] + pz * frame[2, cc])
                        for cc in range(3)], axis=-1)
        out = np.zeros(mask.shape, bool)
        out[where] = inside_any_sweep(np.ascontiguousarray(pts), np.ones(len(pts), bool), p0,
                                      d, axis, -big, big, c, r, top, eps)
        return out

    material = inside.copy()
    if prev_p0.shape[0] > 0 and inside.any():
        material &= ~removed_by(inside, prev_p0, prev_d)
    cutting = material & (h > chip_min)
    if trailing:
        cand = material & (h <= 0.0)
        if cand.any():
            cutting |= cand & ~removed_by(cand, cur_p0, cur_d)
    rows, cols = np.nonzero(cutting)
    return cutting, h, rows.astype(np.int64), cols.astype(np.int64)
