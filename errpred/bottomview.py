"""The bottom view, precomputed once per tool and resolution.

The bottom view (``docs/method.md`` §3) looks up the tool axis from below
the tip, a window of the tool's diameter. In tool coordinates it is the same
at every cutter location: the pixel centres, the envelope point each pixel
ray meets (with its analytic rotation and contact angle), and the pixel and
depth of every micro-edge sample over a revolution. Only the placement in
the world (tip and frame) changes, so this template holds the constant part
and :meth:`BottomTemplate.finished_surface` does the per-location work.

Finished-surface search, coarse to fine: the finished region a revolution
leaves is a strip about one feed per tooth wide, usually narrower than a
pixel. At pixel centres the margins to T1 and T2 (distance outside the
nearest sweep) are computed; since the distance is 1-Lipschitz and the
envelope point moves by at most ``p / (sqrt(2) cos kappa)`` within a pixel,
pixels whose margins are above minus that bound may hold finished area and
are refined into ``VIEW_ZOOM`` x ``VIEW_ZOOM`` sub-pixels, which are tested
exactly. The cost follows the strip, not the window.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import constants as K
from ._cluster_kernels import inside_any_sweep_clustered, sweep_margin_clustered
from ._interval_kernels import box_membership, cells_smooth, interval_membership
from .tool import MicroEdges, Tool

__all__ = ["BottomTemplate", "Finished", "SampleGrid", "StockView", "stock_view"]


@dataclass(frozen=True, eq=False)
class Finished:
    """Cutting and finished area found at one cutter location.

    Attributes
    ----------
    cutting_pixels : int
        Coarse pixels whose envelope point is in the cutting region.
    xyz : ndarray, shape (k, 3) [mm]
        Tool-frame envelope points of the finished sub-pixels.
    phi, kappa : ndarray, shape (k,) [rad]
    cutting_phi : ndarray [rad]
        Rotation angle of the coarse cutting pixels (for the side view).
    cutting_z : ndarray [mm]
    refined_pixels : int
        Coarse pixels refined.
    """

    cutting_pixels: int
    xyz: np.ndarray
    phi: np.ndarray
    kappa: np.ndarray
    cutting_phi: np.ndarray
    cutting_z: np.ndarray
    refined_pixels: int


@dataclass(frozen=True, eq=False)
class StockView:
    """The stock's material interval in a view, and where it interpolates.

    ``bottom``, ``top``: (n, n) depths of the first entry and exit per pixel
    centre; ``smooth_bottom``, ``smooth_top``: (n-1, n-1) cells where the
    surface is gentle enough to interpolate bilinearly between centres.
    Elsewhere (steep walls, silhouettes) points are decided by the mesh.
    """

    bottom: np.ndarray
    top: np.ndarray
    smooth_bottom: np.ndarray
    smooth_top: np.ndarray


def stock_view(stock, view, depth_range) -> StockView | None:
    """The stock's material interval in a view; None for a box (analytic)."""
    if getattr(stock, "is_box", False):
        return None
    bottom, top = stock.interval(view, depth_range=depth_range)
    limit = view.pixel_mm * math.sqrt(2.0) * math.tan(K.STOCK_INTERPOLATION_SLOPE_RAD)
    return StockView(bottom, top, cells_smooth(bottom, limit), cells_smooth(top, limit))


@dataclass(frozen=True, eq=False)
class SampleGrid:
    """Flute 0's micro-edge samples over a revolution, tool frame.

    Attributes
    ----------
    theta : ndarray, shape (n,) [rad]
    samples : ndarray, shape (n * m, 3) [mm]
    ij : tuple of ndarray
        Bottom-view pixel of each sample.
    shape : tuple
        (n, m).
    rotation_step : ndarray, shape (n, m, 3) [mm]
        Displacement of each sample over one rotation step (no feed).
    """

    theta: np.ndarray
    samples: np.ndarray
    ij: tuple
    shape: tuple
    rotation_step: np.ndarray


class BottomTemplate:
    """Tool-frame constants of the bottom view and the micro-edge samples.

    Parameters
    ----------
    tool : Tool
    edges : MicroEdges
    theta : ndarray, shape (n,) [rad]
    pixel_mm : float [mm]
    """

    def __init__(self, tool: Tool, edges: MicroEdges, theta: np.ndarray, pixel_mm: float):
        self.tool = tool
        self.pixel_mm = p = float(pixel_mm)
        self.window_mm = tool.diameter_mm + 2 * p
        self.n = n = int(math.ceil(self.window_mm / p - 1e-9))
        self.depth_offset_mm = tool.radius_mm
        centres = (np.arange(n) + 0.5) * p - 0.5 * n * p
        X, Y = np.meshgrid(centres, centres)  # rows: v (y'), columns: u (x')
        rho = np.hypot(X, Y).ravel()
        self.valid = rho <= tool.radius_mm
        z = tool.envelope_z(np.where(self.valid, rho, 0.0))
        self.xyz = np.column_stack([X.ravel(), Y.ravel(), z])
        self.phi = np.arctan2(X.ravel(), Y.ravel())
        self.kappa = tool.kappa_at_rho(np.where(self.valid, rho, 0.0))
        # refinement bound: how far the envelope point moves inside a pixel
        kap = np.minimum(self.kappa, K.VIEW_CORRECTION_KAPPA_RAD)
        self.reach = p / (math.sqrt(2.0) * np.cos(kap)) + K.MEMBERSHIP_EPS_MM
        self.edges = edges
        self.grid = self.sample_grid(theta)
        self.samples, self.sample_ij = self.grid.samples, self.grid.ij
        self.sample_shape, self.rotation_step = self.grid.shape, self.grid.rotation_step
        sub = int(K.VIEW_ZOOM)
        off = (np.arange(sub) + 0.5) / sub - 0.5
        self.sub_offsets = np.stack(np.meshgrid(off, off), axis=-1).reshape(-1, 2) * p

    def sample_grid(self, theta: np.ndarray) -> "SampleGrid":
        """Micro-edge samples of flute 0 at rotation angles ``theta``."""
        edges = self.edges
        phi = theta[:, None] - edges.psi[None, :]
        rr = edges.rho[None, :]
        pts = np.stack(np.broadcast_arrays(rr * np.sin(phi), rr * np.cos(phi),
                                           edges.z[None, :]), axis=-1)
        step = 2 * math.pi / theta.shape[0]
        phi2 = phi + step
        rot = np.stack(np.broadcast_arrays(rr * np.sin(phi2), rr * np.cos(phi2),
                                           edges.z[None, :]), axis=-1) - pts
        flat = pts.reshape(-1, 3)
        return SampleGrid(theta, flat, self._pixel(flat), pts.shape[:2], rot)

    def _pixel(self, xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p, n = self.pixel_mm, self.n
        j = np.floor((xyz[:, 0] + 0.5 * n * p) / p).astype(np.int64)
        i = np.floor((xyz[:, 1] + 0.5 * n * p) / p).astype(np.int64)
        return np.clip(i, 0, n - 1), np.clip(j, 0, n - 1)

    # --- stock membership ----------------------------------------------------
    def in_stock_local(self, stock, interval: StockView | None, tip, frame,
                       xyz_local: np.ndarray, ij=None) -> np.ndarray:
        """Stock material at tool-frame points.

        Box: analytic. Mesh: the bottom view's interval interpolated
        bilinearly between pixel centres where the surface is gentle; where
        it is steep or at a silhouette, the mesh decides (exact, slower).
        """
        if getattr(stock, "is_box", False):
            lo, hi = stock.bounds
            return box_membership(np.ascontiguousarray(xyz_local, dtype=float),
                                  np.ascontiguousarray(tip, dtype=float),
                                  np.ascontiguousarray(frame, dtype=float),
                                  np.array(lo, dtype=float), np.array(hi, dtype=float),
                                  K.MEMBERSHIP_EPS_MM)
        inside, unsure = interval_membership(
            np.ascontiguousarray(xyz_local, dtype=float), interval.top, interval.bottom,
            interval.smooth_top, interval.smooth_bottom, self.pixel_mm, self.depth_offset_mm,
            K.MEMBERSHIP_EPS_MM)
        if unsure.any():
            world = tip + xyz_local[unsure] @ frame
            inside[unsure] = stock.contains(world)
        return inside

    def _bound(self, m: np.ndarray, known: np.ndarray) -> np.ndarray:
        """How much ``m`` may rise from a pixel centre to its corners [mm].

        Twice the steepest difference to the neighbouring centres, capped by
        the rigorous bound (1-Lipschitz distance along an envelope that
        tilts by kappa); the rigorous bound where a neighbour is unknown.
        """
        n, p = self.n, self.pixel_mm
        grid = np.where(known, m, np.nan).reshape(n, n)
        slope = np.zeros((n, n))
        unknown = np.zeros((n, n), dtype=bool)
        for sl_a, sl_b in (((slice(1, None), slice(None)), (slice(None, -1), slice(None))),
                           ((slice(None), slice(1, None)), (slice(None), slice(None, -1)))):
            diff = np.abs(grid[sl_a] - grid[sl_b]) / p
            nan = np.isnan(diff)
            diff[nan] = 0.0
            for sl in (sl_a, sl_b):
                np.maximum(slope[sl], diff, out=slope[sl])
                unknown[sl] |= nan
        unknown[0, :] = unknown[-1, :] = unknown[:, 0] = unknown[:, -1] = True
        rigorous = self.reach.reshape(n, n)
        est = np.minimum(2.0 * slope * p / math.sqrt(2.0) + K.MEMBERSHIP_EPS_MM, rigorous)
        return np.where(unknown, rigorous, est).ravel()

    # --- the finished surface ----------------------------------------------
    def finished_surface(self, stock, interval, tip, frame, t1, t2, inside_t1) -> Finished:
        """The pixels and sub-pixels of the finished surface (the tool's envelope in
        the stock, outside T1 and T2) at one location.

        The pixels' margins are measured against ``t1``; ``inside_t1(world) -> bool``
        answers the sub-pixels' T1 test (the point's
        :meth:`~errpred.t1memo.RemovedMemo.test`: the sweeps' height map first, the
        same answers as the exact test).
        """
        tool = self.tool
        c, r, top = tool.core_radius_mm, tool.corner_radius_mm, tool.flute_length_mm
        eps = K.MEMBERSHIP_EPS_MM
        cell = K.CLUSTER_CELL_MM
        cand = self.valid.copy()
        idx = np.flatnonzero(cand)
        n = self.n
        ij = (idx // n, idx % n)
        cand[idx] = self.in_stock_local(stock, interval, tip, frame, self.xyz[idx], ij)
        world = tip + self.xyz @ frame
        floor = -float(self.reach.max())
        m1 = sweep_margin_clustered(world, cand, *t1, c, r, top, floor, cell)
        cutting = cand & (m1 > 0)
        b1 = self._bound(m1, cand)
        near = cand & (m1 + b1 > 0)
        m2 = sweep_margin_clustered(world, near, *t2, c, r, top, floor, cell)
        near &= m2 + self._bound(m2, near) > 0
        refine = np.flatnonzero(near)
        if refine.size == 0:
            return Finished(int(cutting.sum()), np.zeros((0, 3)), np.zeros(0), np.zeros(0),
                            self.phi[cutting], self.xyz[cutting, 2], 0)
        # sub-pixels of the refined pixels
        xy = (self.xyz[refine, None, :2] + self.sub_offsets[None, :, :]).reshape(-1, 2)
        rho = np.hypot(xy[:, 0], xy[:, 1])
        ok = rho <= tool.radius_mm
        xy, rho = xy[ok], rho[ok]
        sub = np.column_stack([xy, tool.envelope_z(rho)])
        # the stock at a sub-pixel: its coarse pixel's interval (the stock
        # surface is smooth at pixel scale; the strip lies well inside it)
        incand = self.in_stock_local(stock, interval, tip, frame, sub)
        sw = tip + sub @ frame
        in1 = np.zeros(sw.shape[0], dtype=bool)
        in1[incand] = inside_t1(np.ascontiguousarray(sw[incand]))
        cut = incand & ~in1
        in2 = inside_any_sweep_clustered(sw, cut, *t2, c, r, top, eps, cell)
        fin = cut & ~in2
        phi = np.arctan2(sub[fin, 0], sub[fin, 1])
        kappa = tool.kappa_at_rho(rho[fin])
        return Finished(int(cutting.sum()), sub[fin], phi, kappa, self.phi[cutting],
                        self.xyz[cutting, 2], int(refine.size))
