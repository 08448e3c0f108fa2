"""Which samples of one prediction point are inside T1 (the sweeps before it),
each tested once and remembered (:class:`RemovedMemo`)."""

from __future__ import annotations

import math

import numpy as np

from . import constants as K
from ._cluster_kernels import inside_any_sweep_clustered, read_only
from .tool import Tool
from .zmap import SweepMap

__all__ = ["RemovedMemo"]


class RemovedMemo:
    """Which tool-frame samples of one prediction point are inside T1, remembered.

    The engagement and its sensitivity pass (the stock a little thicker) test
    the same samples against the same sweeps; only the stock moves. Each
    sample is tested once (:func:`~errpred._cluster_kernels.inside_any_sweep_clustered`,
    exact per point, so the answer does not depend on what else is asked with it).
    Where a height map of the sweeps applies (:class:`~errpred.zmap.SweepMap`),
    it answers first: a sample it finds inside an earlier sweep is inside T1; one
    below every sweep it holds is tested against the rest of T1 only (the move
    the tool is on, and the sweeps of other axes than the map's); the others as
    before.

    Parameters
    ----------
    tool : Tool
    t1 : tuple
        The point's T1 sweeps ``(p0, d, w, lo, hi)``.
    zmap : SweepMap or None
    t1_end : float [mm]
        The path length where T1 ends.
    t1_ids : ndarray of int
        The sweep each part of T1 comes from.
    """

    def __init__(self, tool: Tool, t1, zmap: SweepMap | None = None, t1_end: float = math.inf,
                 t1_ids: np.ndarray | None = None) -> None:
        self._tail = (tool.core_radius_mm, tool.corner_radius_mm, tool.flute_length_mm,
                      K.MEMBERSHIP_EPS_MM, K.CLUSTER_CELL_MM)
        self._t1 = t1
        self._zmap = zmap if t1_ids is not None else None
        self._t1_end = t1_end
        self._t1_ids = t1_ids
        self._rest = None
        self._known: dict = {}

    def test(self, world: np.ndarray) -> np.ndarray:
        """Inside T1? for world points (k, 3), not remembered (the same answer as
        the exact test of every point against every part of T1)."""
        ones = np.ones(world.shape[0], dtype=np.bool_)
        zmap = self._zmap
        if zmap is None or world.shape[0] == 0:
            return inside_any_sweep_clustered(world, ones, *self._t1, *self._tail)
        state = zmap.classify(world, self._t1_end)
        out = state > 0
        unsure = state == 0
        if unsure.any():
            out |= inside_any_sweep_clustered(world, unsure, *self._t1, *self._tail)
        below = state < 0
        if below.any():
            if self._rest is None:
                # the parts of T1 the map does not hold yet (the current move)
                late = np.flatnonzero(~zmap.holds(self._t1_ids))
                self._rest = read_only(*(np.ascontiguousarray(a[late]) for a in self._t1))
            if self._rest[0].shape[0]:
                out |= inside_any_sweep_clustered(world, below, *self._rest, *self._tail)
        return out

    def __call__(self, tag, keys: np.ndarray, world: np.ndarray) -> np.ndarray:
        """Inside T1? for the samples ``keys`` (int, unique per ``tag``) at ``world`` (k, 3)."""
        keys = np.asarray(keys, dtype=np.int64)
        k_known, v_known = self._known.get(tag, (None, None))
        out = np.zeros(keys.size, dtype=bool)
        miss = np.ones(keys.size, dtype=bool)
        if k_known is not None and k_known.size:
            pos = np.minimum(np.searchsorted(k_known, keys), k_known.size - 1)
            hit = k_known[pos] == keys
            out[hit] = v_known[pos[hit]]
            miss = ~hit
        if miss.any():
            w = np.ascontiguousarray(world[miss])
            new = self.test(w)
            out[miss] = new
            k_all = keys[miss] if k_known is None else np.concatenate([k_known, keys[miss]])
            v_all = new if v_known is None else np.concatenate([v_known, new])
            order = np.argsort(k_all, kind="stable")
            self._known[tag] = (k_all[order], v_all[order])
        return out
