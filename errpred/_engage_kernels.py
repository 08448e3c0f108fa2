"""Numba kernels of the step weights (:mod:`errpred.point_engagement`), with numpy twins.

The step weights resolve the engagement's boundary inside each rotation step x
micro edge cell (``docs/method.md`` §4): the cells with a neighbour in the
other state are sub-sampled ``st`` x ``se`` times and each sub-sample tested
against the stock and T1. The membership tests are the sweep and stock kernels'
(``errpred/_kernels.py``); these kernels do the per-cell work around them in one
call each, where numpy made a dozen temporaries a point:

* :func:`grid_candidates`: the samples of a grid's rows the stock's interval in
  the bottom view holds or cannot decide (in place of a gather, a shift, the
  interval test and two compactions over the whole grid);
* :func:`boundary_cells`: which cells are on the boundary;
* :func:`sub_samples`: their sub-samples' tool-frame positions (and the same
  minus the stock's shift, for the sensitivity pass);
* :func:`cell_weights`: each cell's cutting share and its rotation centroid from
  the sub-samples that cut.

Each ``*_numpy`` function is the numpy code the kernel replaced, kept as its
twin: ``tests/errpred/test_engage_kernels.py`` compares them on seeded cases
(bit for bit: the same IEEE operations in the same order; the shares and the
centroid sums are multiples of 1/16, exact in any order).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._interval_kernels import _bilinear, interval_membership

__all__ = ["grid_candidates", "boundary_cells", "sub_samples", "cell_weights",
           "grid_candidates_numpy", "boundary_cells_numpy", "sub_samples_numpy",
           "cell_weights_numpy"]


#: How far outside its four corners' range a bilinear interpolation may not reach
#: [mm]: far above the rounding of the sum (~1e-14 mm at these depths), far below
#: any surface feature.
_CELL_MARGIN_MM = 1e-9


@njit(cache=True, nogil=True)
def grid_candidates(samples, rows, cols, m, shift, top, bottom, smooth_top, smooth_bottom,
                    pixel, depth_offset, eps):
    """The samples ``rows x cols`` of a grid (``samples`` (n * m, 3) [mm], tool frame,
    row ``i * m + j``) that the stock's interval in the bottom view holds or cannot
    decide, the stock displaced by ``shift`` (3,) [mm].

    The test is :func:`errpred._interval_kernels.interval_membership`'s on ``sample - shift``
    (in cells where both surfaces interpolate, points clear of the corners' depth
    range are outside without interpolating: the same answer, sooner).
    Returns, in grid order, the samples' indices (k,), positions (k, 3) [mm], the
    positions minus ``shift`` (k, 3) [mm], and whether the interval could not decide
    (k,) bool (those are for the mesh).
    """
    total = rows.shape[0] * cols.shape[0]
    idx = np.empty(total, dtype=np.int64)
    local = np.empty((total, 3))
    moved = np.empty((total, 3))
    unsure = np.empty(total, dtype=np.bool_)
    n = top.shape[0]
    half = 0.5 * n * pixel
    # per cell of four pixel centres where both surfaces interpolate and are finite: the
    # depths no interpolated interval can reach (the corners' range, widened by
    # ``_CELL_MARGIN_MM`` beyond any rounding of the bilinear sum); a point outside it
    # is outside the interval without interpolating
    lo = np.full((n - 1, n - 1), -np.inf)
    hi = np.full((n - 1, n - 1), np.inf)
    for i0 in range(n - 1):
        for j0 in range(n - 1):
            if not (smooth_top[i0, j0] and smooth_bottom[i0, j0]):
                continue
            b0, b1 = bottom[i0, j0], bottom[i0, j0 + 1]
            b2, b3 = bottom[i0 + 1, j0], bottom[i0 + 1, j0 + 1]
            t0, t1 = top[i0, j0], top[i0, j0 + 1]
            t2, t3 = top[i0 + 1, j0], top[i0 + 1, j0 + 1]
            if (math.isfinite(b0) and math.isfinite(b1) and math.isfinite(b2)
                    and math.isfinite(b3) and math.isfinite(t0) and math.isfinite(t1)
                    and math.isfinite(t2) and math.isfinite(t3)):
                lo[i0, j0] = min(min(b0, b1), min(b2, b3)) - eps - _CELL_MARGIN_MM
                hi[i0, j0] = max(max(t0, t1), max(t2, t3)) + eps + _CELL_MARGIN_MM
    k = 0
    for a in range(rows.shape[0]):
        base = rows[a] * m
        for b in range(cols.shape[0]):
            q = base + cols[b]
            x, y, z = samples[q, 0], samples[q, 1], samples[q, 2]
            mx, my, mz = x - shift[0], y - shift[1], z - shift[2]
            # interval_membership, one point
            fx = (mx + half) / pixel - 0.5
            fy = (my + half) / pixel - 0.5
            j0 = min(max(int(math.floor(fx)), 0), n - 2)
            i0 = min(max(int(math.floor(fy)), 0), n - 2)
            depth = mz + depth_offset
            if depth < lo[i0, j0] or depth > hi[i0, j0]:
                continue
            tx = min(max(fx - j0, 0.0), 1.0)
            ty = min(max(fy - i0, 0.0), 1.0)
            t = _bilinear(top, i0, j0, tx, ty)
            bo = _bilinear(bottom, i0, j0, tx, ty)
            inside = (bo - eps <= depth) and (depth <= t + eps)
            uns = not (smooth_top[i0, j0] and smooth_bottom[i0, j0])
            if inside or uns:
                idx[k] = q
                local[k, 0], local[k, 1], local[k, 2] = x, y, z
                moved[k, 0], moved[k, 1], moved[k, 2] = mx, my, mz
                unsure[k] = uns
                k += 1
    return idx[:k], local[:k], moved[:k], unsure[:k]


def grid_candidates_numpy(samples, rows, cols, m, shift, top, bottom, smooth_top,
                          smooth_bottom, pixel, depth_offset, eps):
    """Twin of :func:`grid_candidates` (the gather, shift and test it replaced)."""
    idx = (rows[:, None] * m + cols[None, :]).ravel()
    local = samples[idx]
    moved = local - shift
    inside, unsure = interval_membership(np.ascontiguousarray(moved), top, bottom, smooth_top,
                                         smooth_bottom, pixel, depth_offset, eps)
    keep = inside | unsure
    return idx[keep], local[keep], moved[keep], unsure[keep]


@njit(cache=True, nogil=True)
def boundary_cells(c0, rows):
    """Cells ``(i, j)`` of ``c0`` (n, m, bool) on rows ``rows`` (ascending) with a
    neighbour in the other state: rotation cyclic, the edge's ends their own
    neighbours; row-major order. Returns two int64 arrays."""
    n, m = c0.shape
    out_i = np.empty(rows.shape[0] * m, dtype=np.int64)
    out_j = np.empty(rows.shape[0] * m, dtype=np.int64)
    k = 0
    for a in range(rows.shape[0]):
        r = rows[a]
        rm, rp = (r - 1 + n) % n, (r + 1) % n
        for j in range(m):
            v = c0[r, j]
            jm, jp = max(j - 1, 0), min(j + 1, m - 1)
            if (c0[rm, jm] != v or c0[rm, j] != v or c0[rm, jp] != v
                    or c0[r, jm] != v or c0[r, jp] != v
                    or c0[rp, jm] != v or c0[rp, j] != v or c0[rp, jp] != v):
                out_i[k] = r
                out_j[k] = j
                k += 1
    return out_i[:k], out_j[:k]


def boundary_cells_numpy(c0: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Twin of :func:`boundary_cells`."""
    n, m = c0.shape
    sub = c0[rows]
    diff = np.zeros(sub.shape, dtype=bool)
    for nb in (c0[(rows - 1) % n], sub, c0[(rows + 1) % n]):
        pad = np.concatenate([nb[:, :1], nb, nb[:, -1:]], axis=1)
        for dj in (-1, 0, 1):
            diff |= pad[:, 1 + dj:1 + dj + m] != sub
    ii, j = np.nonzero(diff)
    return rows[ii].astype(np.int64), j.astype(np.int64)


@njit(cache=True, nogil=True)
def sub_samples(theta_i, j, du_step, sub_rho, sub_z, sub_lag, shift):
    """Tool-frame positions of the cells' sub-samples, (cells * st * se, 3) [mm], and
    the same minus ``shift`` (3,) [mm] (the stock's displacement).

    Cell ``c`` at rotation angle ``theta_i[c]`` [rad] on micro edge ``j[c]``;
    sub-sample ``(c, s, e)`` (row ``(c * st + s) * se + e``) at angle
    ``theta_i[c] + du_step[s] - sub_lag[j[c], e]`` on the profile point
    ``(sub_rho, sub_z)[j[c], e]``.
    """
    cells = theta_i.shape[0]
    st = du_step.shape[0]
    se = sub_rho.shape[1]
    local = np.empty((cells * st * se, 3))
    moved = np.empty((cells * st * se, 3))
    q = 0
    for c in range(cells):
        jc = j[c]
        for s in range(st):
            ang = theta_i[c] + du_step[s]
            for e in range(se):
                phi = ang - sub_lag[jc, e]
                rho = sub_rho[jc, e]
                x = rho * math.sin(phi)
                y = rho * math.cos(phi)
                z = sub_z[jc, e]
                local[q, 0] = x
                local[q, 1] = y
                local[q, 2] = z
                moved[q, 0] = x - shift[0]
                moved[q, 1] = y - shift[1]
                moved[q, 2] = z - shift[2]
                q += 1
    return local, moved


def sub_samples_numpy(theta_i, j, du_step, sub_rho, sub_z, sub_lag, shift):
    """Twin of :func:`sub_samples`."""
    ang = theta_i[:, None, None] + du_step[None, :, None]
    rho = sub_rho[j][:, None, :]
    phi = ang - sub_lag[j][:, None, :]
    local = np.empty(phi.shape + (3,))
    np.multiply(rho, np.sin(phi), out=local[..., 0])
    np.multiply(rho, np.cos(phi), out=local[..., 1])
    local[..., 2] = sub_z[j][:, None, :]
    local = local.reshape(-1, 3)
    return local, local - shift


@njit(cache=True, nogil=True)
def cell_weights(cut, i, j, du, step, weight, shift):
    """Write each cell's cutting share and centroid offset into ``weight`` and ``shift``
    (both (n, m), float32) at ``(i[c], j[c])``.

    ``cut``: (cells * st * se,) bool, the sub-samples that cut (rows as
    :func:`sub_samples`); ``du``: (st,) offsets of the sub-steps in steps [-];
    ``step``: the rotation step [rad]. The share is the cutting sub-samples'
    count over ``st * se``; the offset their mean ``du`` times ``step`` [rad]
    (0 where none cuts).
    """
    cells = i.shape[0]
    st = du.shape[0]
    se = cut.shape[0] // max(cells * st, 1)
    q = 0
    for c in range(cells):
        count = 0
        ushare = 0.0
        for s in range(st):
            for _e in range(se):
                if cut[q]:
                    count += 1
                    ushare += du[s]
                q += 1
        weight[i[c], j[c]] = count / (st * se)
        shift[i[c], j[c]] = ushare / max(count, 1) * step if count > 0 else 0.0


def cell_weights_numpy(cut, i, j, du, step, weight, shift) -> None:
    """Twin of :func:`cell_weights`."""
    if i.size == 0:
        return
    st = du.shape[0]
    cut = cut.reshape(i.size, st, -1)
    count = cut.sum(axis=(1, 2))
    weight[i, j] = count / cut[0].size
    ushare = (cut * du[None, :, None]).sum(axis=(1, 2))
    shift[i, j] = np.where(count > 0, ushare / np.maximum(count, 1) * step, 0.0)
