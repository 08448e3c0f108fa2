"""Flute 0's engagement at one prediction point, sampled, refined and sub-sampled.

Stage 1 of the prediction (:mod:`errpred.geometry`) asks, at each prediction
point, which micro edges of flute 0 cut during one revolution
(``docs/method.md`` §3-4): a sample cuts where it is in the stock (the bottom
view's interval, :meth:`errpred.bottomview.BottomTemplate.in_stock_local`) and
outside T1 (the sweeps up to one feed per tooth before the point, through the
point's memo :class:`errpred.t1memo.RemovedMemo`). :class:`PointEngagement`
holds what does not change from point to point (the sample grids, the
sub-edges) and answers :meth:`PointEngagement.engagement`; the cells on the
engagement's boundary are resolved by :meth:`PointEngagement.step_weights`,
whose per-cell work is compiled (``errpred/_engage_kernels.py``).
"""

from __future__ import annotations

import math

import numpy as np

from . import constants as K
from ._engage_kernels import boundary_cells, cell_weights, grid_candidates, sub_samples
from .bottomview import BottomTemplate, SampleGrid, StockView
from .tool import MicroEdges, Tool

__all__ = ["PointEngagement"]


class PointEngagement:
    """The engagement of flute 0 at a prediction point (``docs/method.md`` §4).

    Parameters
    ----------
    tool : Tool
    edges : MicroEdges
    theta : ndarray, shape (n,) [rad]
        The resolution's rotation angles (:func:`errpred.engagement.revolution_angles`).
    bottom : BottomTemplate
        The bottom view (its sample grid at ``theta``).
    stock : errpred.raster.meshes.Stock
    pixel_mm : float [mm]
        The bottom view's pixel (micro edges higher than the stock's top by more
        than this cannot cut).
    """

    def __init__(self, tool: Tool, edges: MicroEdges, theta: np.ndarray,
                 bottom: BottomTemplate, stock, pixel_mm: float) -> None:
        self.tool, self.edges, self.theta = tool, edges, theta
        self.bottom, self.stock = bottom, stock
        self.pixel_mm = float(pixel_mm)
        self._grids: dict[int, SampleGrid] = {1: bottom.grid}
        self._precheck: dict[tuple, np.ndarray] = {}
        # the sub-edges of the step weights: profile radius, height and helix lag at
        # ENGAGEMENT_SUBEDGES points along each micro edge, (m, se) each
        se = K.ENGAGEMENT_SUBEDGES
        dv = (np.arange(se) + 0.5) / se - 0.5
        sarc = edges.s[:, None] + dv[None, :] * edges.db[:, None]
        sub_rho, sub_z, _ = tool.profile_at(sarc)
        self.sub_edges = tuple(np.ascontiguousarray(a, dtype=float)
                               for a in (sub_rho, sub_z, tool.helix_lag(sub_z)))
        st = K.ENGAGEMENT_SUBSTEPS
        #: the sub-steps' offsets within a rotation step [steps]
        self.du = (np.arange(st) + 0.5) / st - 0.5

    def grid(self, factor: int) -> SampleGrid:
        """Sample grid with the rotation step divided by ``factor`` (cached)."""
        grid = self._grids.get(factor)
        if grid is None:
            n = self.theta.shape[0] * factor
            grid = self._grids[factor] = self.bottom.sample_grid(
                np.arange(n) * (2 * math.pi / n))
        return grid

    def precheck_samples(self, edge_ok: np.ndarray, inset: float) -> np.ndarray:
        """The block pre-check's samples, tool frame (k, 3) [mm], read only (cached):
        every ``PRECHECK_ROTATION_STRIDE``-th rotation step of ``grid(1)``, the micro
        edges where ``edge_ok`` (m,), moved ``inset`` [mm] in radially and up (the
        tool shrunk a little: samples on the boundary of an earlier sweep, a slot's
        walls and floor, are no cut, whatever the rounding)."""
        key = (edge_ok.tobytes(), float(inset))
        local = self._precheck.get(key)
        if local is None:
            grid = self.grid(1)
            n, m = grid.shape
            rows = np.arange(0, n, K.PRECHECK_ROTATION_STRIDE)
            idx = (rows[:, None] * m + np.flatnonzero(edge_ok)[None, :]).ravel()
            local = grid.samples[idx]
            rho = np.hypot(local[:, 0], local[:, 1])
            shrink = np.maximum(rho - inset, 0.0) / np.maximum(rho, 1e-300)
            local = np.column_stack([local[:, 0] * shrink, local[:, 1] * shrink,
                                     local[:, 2] + inset])
            if len(self._precheck) >= K.PRECHECK_SAMPLE_SETS:
                self._precheck.clear()
            self._precheck[key] = local
        return local

    def engagement(self, tip: np.ndarray, frame: np.ndarray, interval: StockView | None,
                   removed_by_t1, f_tooth: np.ndarray, z_top: float,
                   stock_shift: np.ndarray | None = None) -> tuple | None:
        """Flute 0's engagement: (cutting, weight, shift, cutting distance per rev), or
        None where nothing measurable cuts.

        At the resolution's rotation step first; where a tooth's engagement
        spans fewer than ``ENGAGEMENT_MIN_STEPS`` steps (a short pulse of
        force, light finishing cuts), again with the step divided until it
        does (at most ``ENGAGEMENT_MAX_REFINE`` times), inside the engaged
        window only: the force pulse must be resolved for its dynamic
        response.

        Parameters
        ----------
        tip : ndarray, shape (3,) [mm]
        frame : ndarray, shape (3, 3)
            Tool frame rows x', y', z' (``errpred/frames.py``).
        interval : StockView or None
            The stock in the bottom view at this point (None for a box).
        removed_by_t1 : errpred.t1memo.RemovedMemo
            Whether a sample is inside T1, remembered for a second call at the
            same point.
        f_tooth : ndarray, shape (3,) [mm]
            Feed per tooth, world frame.
        z_top : float [mm]
            Height above the tip of the highest stock under the tool.
        stock_shift : ndarray, shape (3,), optional [mm]
            Tool frame: displaces the stock, as if the tool cut that much deeper
            (for the correction's sensitivity).
        """
        tool = self.tool
        shift_vec = np.zeros(3) if stock_shift is None else np.asarray(stock_shift, float)
        # micro edges above the highest stock under the tool cannot cut
        edge_ok = np.flatnonzero(self.edges.z <= z_top + self.pixel_mm)
        factor, window = 1, None
        while True:
            grid = self.grid(factor)
            n, m = grid.shape
            rows = np.arange(n) if window is None else np.flatnonzero(window)
            idx, local = self._in_stock(grid, rows, edge_ok, interval, tip, frame, shift_vec)
            removed = removed_by_t1(("grid", factor), idx, tip + local @ frame)
            cut_idx = idx[~removed]
            if cut_idx.size == 0:
                return None
            cutting0 = np.zeros(n * m, dtype=bool)
            cutting0[cut_idx] = True
            cutting0 = cutting0.reshape(n, m)
            # the engaged rotation steps, from the cutting samples' rows (not the full grid)
            engaged = np.zeros(n, dtype=bool)
            engaged[cut_idx // m] = True
            span = int(np.count_nonzero(engaged))  # flute 0 passes the engagement once a rev
            if span >= K.ENGAGEMENT_MIN_STEPS or factor >= K.ENGAGEMENT_MAX_REFINE:
                break
            q = 1
            while span * q < K.ENGAGEMENT_MIN_STEPS and factor * q < K.ENGAGEMENT_MAX_REFINE:
                q *= 2
            # the fine window: the engaged steps and one either side
            engaged = _with_neighbours(engaged)
            fine = np.arange(n * q)
            window = engaged[np.round(fine / q).astype(int) % n]
            factor *= q
        # the rows that may hold a non-zero weight: the engaged steps and one either side
        # (in ascending order, so that what is read from them keeps the grid's order)
        near = np.flatnonzero(_with_neighbours(engaged))
        weight0, shift0 = self.step_weights(grid, cutting0, near, interval, tip, frame,
                                            removed_by_t1, factor, shift_vec)
        feed_step = (frame @ (f_tooth * tool.flutes)) / n
        ii, j = np.nonzero(weight0[near])
        if ii.size == 0:
            return None  # only slivers thinner than the sub-samples: nothing measurable
        i = near[ii]
        step_len = np.linalg.norm(grid.rotation_step[i, j] + feed_step, axis=-1)
        cl_rev = np.bincount(j, weights=weight0[i, j] * step_len, minlength=m)
        return weight0 > 0, weight0, shift0, cl_rev

    def _in_stock(self, grid: SampleGrid, rows: np.ndarray, cols: np.ndarray,
                  interval: StockView | None, tip: np.ndarray, frame: np.ndarray,
                  shift: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The samples ``rows x cols`` of ``grid`` in the stock displaced by ``shift``
        (tool frame [mm]): their indices and tool-frame positions, in grid order."""
        m = grid.shape[1]
        if interval is None:  # a box: analytic (BottomTemplate.in_stock_local)
            idx = (rows[:, None] * m + cols[None, :]).ravel()
            local = grid.samples[idx]
            cand = self.bottom.in_stock_local(self.stock, None, tip, frame, local - shift)
            return idx[cand], local[cand]
        idx, local, moved, unsure = grid_candidates(
            grid.samples, rows, cols, m, shift, interval.top, interval.bottom,
            interval.smooth_top, interval.smooth_bottom, self.bottom.pixel_mm,
            self.bottom.depth_offset_mm, K.MEMBERSHIP_EPS_MM)
        if unsure.any():
            # steep cells and silhouettes: the mesh decides (as in_stock_local)
            keep = np.ones(idx.size, dtype=bool)
            keep[unsure] = self.stock.contains(tip + moved[unsure] @ frame)
            idx, local = idx[keep], local[keep]
        return idx, local

    def step_weights(self, grid: SampleGrid, cutting0: np.ndarray, rows: np.ndarray,
                     interval: StockView | None, tip: np.ndarray, frame: np.ndarray,
                     removed_by_t1, factor: int, stock_shift: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
        """Share of each sample's cell (rotation step x micro edge) that cuts, (n, m),
        and the rotation offset of that share's centroid [rad], (n, m); both float32
        (the share is a multiple of 1/32: exact).

        ``rows`` (ascending): the rotation steps that may be on the engagement's
        boundary (those that cut and one either side); the others are 0.
        ``stock_shift`` (3,) [mm]: the stock's displacement, tool frame (zeros
        for none).

        1 or 0 inside or outside the engagement. On its boundary (samples
        with a neighbour in the other state, in rotation or along the edge)
        each cell is sub-sampled ``ENGAGEMENT_SUBSTEPS`` times in rotation and
        ``ENGAGEMENT_SUBEDGES`` times along the edge and tested exactly like
        the samples (stock, then T1). The share and the centroid resolve the
        boundary within a cell, so the force does not move in whole steps
        when the boundary moves: the reason the prediction converges with
        resolution.
        """
        c0 = cutting0
        n, m = c0.shape
        weight = c0.astype(np.float32)
        shift = np.zeros((n, m), dtype=np.float32)
        i, j = boundary_cells(c0, np.ascontiguousarray(rows, dtype=np.int64))
        if i.size == 0:
            return weight, shift
        st, se = self.du.size, K.ENGAGEMENT_SUBEDGES
        step = 2 * math.pi / n
        sub_rho, sub_z, sub_lag = self.sub_edges
        local, moved = sub_samples(grid.theta[i], j, self.du * step, sub_rho, sub_z, sub_lag,
                                   np.asarray(stock_shift, dtype=float))
        inside = self.bottom.in_stock_local(self.stock, interval, tip, frame, moved)
        # sub-sample keys: the cell, then the sub-sample within it
        keys = ((i * m + j)[:, None] * (st * se) + np.arange(st * se)[None, :]).ravel()
        cut = inside.copy()
        cut[inside] = ~removed_by_t1(("sub", factor), keys[inside], tip + local[inside] @ frame)
        cell_weights(cut, i, j, self.du, step, weight, shift)
        return weight, shift


def _with_neighbours(mask: np.ndarray) -> np.ndarray:
    """A cyclic 1-d mask with each set entry's two neighbours set too: ``mask |
    np.roll(mask, 1) | np.roll(mask, -1)``, without ``np.roll``'s general machinery
    (25.7 against 4.3 us a call, twice per refinement and per point: 1.6 % of a 5-axis
    stage 1)."""
    out = mask.copy()
    if mask.size:
        out[1:] |= mask[:-1]
        out[0] |= mask[-1]
        out[:-1] |= mask[1:]
        out[-1] |= mask[0]
    return out
