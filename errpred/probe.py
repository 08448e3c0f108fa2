"""Is there stock material at these points? One view's answer.

A box answers analytically. A mesh answers through the depth buffer of the
current view: the material along a pixel ray lies between the first entry
(``bottom``) and the first exit (``top``) of the stock
(:meth:`errpred.raster.meshes.Stock.interval`); a point is in material when
its depth lies in its pixel's interval. Points outside the view's window
have no answer and count as no material, so a view must cover the points it
is asked about (the bottom view covers the tool's disk).
"""

from __future__ import annotations

import numpy as np

from ._side_kernels import interval_contains
from .constants import MEMBERSHIP_EPS_MM

__all__ = ["StockProbe"]

_UNUSED = np.zeros((1, 1))
_UNUSED_3 = np.zeros(3)


class StockProbe:
    """``probe(points) -> bool`` for one stock and one view.

    Parameters
    ----------
    stock : errpred.raster.meshes.Stock
    view : errpred.raster.camera.View
    depth_range : tuple of float [mm]
        Depths of the view that matter (the tool's extent along the rays).
    """

    def __init__(self, stock, view, depth_range: tuple[float, float]) -> None:
        self.stock = stock
        self.view = view
        self._box = getattr(stock, "is_box", False)
        if not self._box:
            self.bottom, self.top = stock.interval(view, depth_range=depth_range)

    def kernel_args(self) -> tuple:
        """``(box, lo, hi, bottom, top)`` for :func:`errpred._side_kernels.side_stock_hits`:
        whether the stock is a box, its bounds [mm], and the view's material interval
        [mm] (a box's: unused 1 x 1 arrays)."""
        if self._box:
            lo, hi = (np.ascontiguousarray(b, dtype=float) for b in self.stock.bounds)
            return True, lo, hi, _UNUSED, _UNUSED
        return False, _UNUSED_3, _UNUSED_3, self.bottom, self.top

    def __call__(self, points: np.ndarray) -> np.ndarray:
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        if self._box:
            lo, hi = self.stock.bounds
            e = MEMBERSHIP_EPS_MM
            return np.all((pts >= lo - e) & (pts <= hi + e), axis=1)
        v = self.view
        # one numba pass (its numpy twin: errpred._side_kernels.interval_contains_numpy)
        return interval_contains(np.ascontiguousarray(pts), v.origin, v.basis, v.pixel_mm,
                                 v.nx, v.ny, self.bottom, self.top, MEMBERSHIP_EPS_MM)
