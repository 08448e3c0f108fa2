"""A height map of the sweeps so far, to answer most T1 membership tests at once.

The seeds make engagement a depth-buffer question (``docs/method.md`` §3): what
earlier moves removed is rendered once, and each micro-edge sample becomes a
look-up, with exact tests only near a boundary. :class:`SweepMap` does this for
a ball end mill's sweeps that share one tool axis (a 3-axis finishing program's
vertical one, a 3+2 program's tilted one; :func:`sweep_map` picks the axis most
sweeps have, where at least ``ZMAP_AXIS_SHARE`` of them do): in a frame whose z is
that axis (the world frame for a vertical one), per cell of a grid across the
axis, it keeps bounds of the inserted sweeps' solids over the cell's column
(:mod:`errpred._zmap_kernels`), so a sample below every solid, or inside one, is
known without an exact test. Samples between the bounds, the sweeps of other
axes, and the sweeps not yet inserted (the move the tool is
on), go to the exact test as before; every answer is the exact one.

The map is filled in program order: a query at path length ``L`` needs the
sweeps that end by ``L`` inserted and no later one; a query earlier than the
map's time goes back to the state kept at the map's first query, or starts the
map again. A query ``ZMAP_JUMP_SWEEPS`` or more sweeps later is a jump: the tiles
are left behind, and each is caught up, with the skipped sweeps that reach it, when
a query next touches it; a tile left behind never answers (it reads as not
allocated). By default every later query is a jump: a sweep goes only into the
tiles queries touch (eager insertion into every tile it reaches, a larger
``ZMAP_JUMP_SWEEPS``, is the tests' reference: the same contents, bit for bit).
Cells are allocated by tiles where queries ask (with eager insertion, also where
sweeps reach), and beyond a budget the least recently used tiles are dropped (to
be filled again, if asked for, with the earlier sweeps that reach them).
"""

from __future__ import annotations

from copy import copy

import numpy as np

from . import constants as K
from ._zmap_kernels import classify, empty_tile, insert_sweeps, tiles_of
from .frames import tool_frame
from .sweeps import Sweeps
from .tool import Tool

__all__ = ["SweepMap", "sweep_map"]


#: What the map is at a given time (what the kept state copies and restores).
_STATE = ("time", "tile_index", "_vals", "_owner", "_used", "_free", "_filled")


class SweepMap:
    """Bounds of the sweeps inserted so far, per cell of a grid across the map's axis.

    Parameters
    ----------
    sweeps : Sweeps
        The program's sweeps, world frame (:func:`sweep_map`).
    tool : Tool
        A ball end mill.
    cell_mm : float [mm]
        Cell side.
    tile : int
        Cells a tile side.
    max_tiles : int
        Tiles kept at most (least recently used dropped first).
    axis : ndarray, shape (3,), optional
        The unit tool axis of the sweeps the map holds (the others are tested
        exactly: :meth:`holds`); None: every sweep, all of them vertical (+z).
        :meth:`classify` takes world points either way.
    """

    def __init__(self, sweeps: Sweeps, tool: Tool, cell_mm: float = K.ZMAP_CELL_MM,
                 tile: int = K.ZMAP_TILE_CELLS, max_tiles: int = K.ZMAP_MAX_TILES,
                 axis: np.ndarray | None = None) -> None:
        #: which sweeps the map holds: those whose axis is ``axis`` (all of them if
        #: every axis is); the others are left to the exact test (:meth:`holds`)
        if axis is None:
            self.held = np.ones(len(sweeps), dtype=bool)
        else:
            self.held = np.all(sweeps.w == np.asarray(axis, dtype=float), axis=1)
        self.all_held = bool(self.held.all())
        #: the map's frame (rows: its axes in world coordinates, the third the held
        #: axis), or None where that axis is +z (the world frame itself)
        self.frame = None
        if axis is not None and not np.array_equal(axis, (0.0, 0.0, 1.0)):
            self.frame = tool_frame(axis, (1.0, 0.0, 0.0))
            sweeps = sweeps.in_frame(self.frame)
        self.sweeps = sweeps
        self.cell = float(cell_mm)
        self.size = int(tile)
        self.max_tiles = int(max_tiles)
        self.rc = float(tool.corner_radius_mm)
        self.lim = self.rc + K.MEMBERSHIP_EPS_MM
        self.top = float(tool.flute_length_mm)
        self._empty = empty_tile(self.size)
        span = self.cell * self.size
        lo = sweeps.lo[:, :2].min(axis=0) - span
        hi = sweeps.hi[:, :2].max(axis=0) + span
        self.origin = lo
        self._zlo = float(sweeps.lo[:, 2].min())
        self._zhi = float(sweeps.hi[:, 2].max())
        self.shape = np.maximum(np.ceil((hi - lo) / span).astype(np.int64), 1)
        self._hand_over = False
        self._reset()

    def _reset(self) -> None:
        self.time = 0  # sweeps 0 .. time - 1: in every tile not left behind (_filled)
        self.tile_index = np.full(tuple(self.shape), -1, dtype=np.int64)
        cap = min(64, self.max_tiles)
        self._vals = np.broadcast_to(self._empty, (cap,) + self._empty.shape).copy()
        self._owner = np.full(cap, -1, dtype=np.int64)  # flat tile key of each slot
        self._used = np.zeros(cap, dtype=np.int64)  # last query that touched it
        self._free = list(range(cap - 1, -1, -1))
        # sweeps 0 .. _filled[s] - 1 are in slot s: the map's time, but for a tile left
        # behind by a jump (_advance), caught up when a query next touches it
        self._filled = np.zeros(cap, dtype=np.int64)
        self._clock = 0
        self._snapshot = None

    @property
    def nbytes(self) -> int:
        """Memory held [bytes] (with the kept state)."""
        kept = 0 if self._snapshot is None or "_vals" not in self._snapshot \
            else self._snapshot["_vals"].nbytes
        return int(self._vals.nbytes + self.tile_index.nbytes + kept)

    def _advance(self, t1_end: float) -> bool:
        """Take the map to the sweeps that end by path length ``t1_end``, no later one:
        insert them, or after a jump leave the tiles behind (:meth:`_catch_up`).

        A query earlier than the map's time goes back to the state kept at the
        first query after the map was started (a run over the same blocks again,
        or a slice after the program's start), or starts the map again.
        """
        target = int(np.searchsorted(self.sweeps.path_end, t1_end, side="right"))
        if target < self.time:
            if self._snapshot is not None and self._snapshot["time"] <= target:
                self._restore()
            else:
                self._reset()
        fresh = self._snapshot is None
        if target - self.time >= K.ZMAP_JUMP_SWEEPS:
            # a jump (a run's start far into the program, or a stage-1 worker's next
            # chunk after the other workers' chunks): the tiles are left where they are
            # and each is caught up, with the skipped sweeps that reach it, when a query
            # next touches it (classify)
            self.time = target
        elif target > self.time:
            ids = np.arange(self.time, target, dtype=np.int64)
            self._insert(ids)
            self.time = target
        return fresh

    def _keep(self) -> None:
        self._snapshot = {name: copy(getattr(self, name)) for name in _STATE}

    def _restore(self) -> None:
        if self._hand_over:         # the kept arrays themselves; no state kept after
            for name in _STATE:
                setattr(self, name, self._snapshot[name])
            self._snapshot = {"time": np.iinfo(np.int64).max}
            return
        for name in _STATE:
            setattr(self, name, copy(self._snapshot[name]))

    def hand_over_kept(self) -> None:
        """For a process that only goes forward from here (a forked stage-1 worker,
        :mod:`errpred.predict`, whose chunks come in program order): going back to the
        kept state takes the kept arrays themselves, not a copy of them (a copy of
        the whole map, 76-151 MB on the mold-ball bench slices, in each worker of
        each run); going back a second time starts the map again. Same answers."""
        self._hand_over = True

    def _insert(self, ids: np.ndarray) -> None:
        """Insert sweeps ``ids`` (the map's next ones) into every tile they reach but
        those left behind by a jump, allocating the tiles they reach first (so tiles are
        filled as the program goes, not from scratch when first asked for)."""
        sw = self.sweeps
        span = self.cell * self.size
        grow = self.lim + self.cell
        own = ids[self.held[ids]]       # the tiles the held ones reach
        lo = np.minimum(sw.p0[own, :2], sw.p0[own, :2] + sw.d[own, :2]) - grow
        hi = np.maximum(sw.p0[own, :2], sw.p0[own, :2] + sw.d[own, :2]) + grow
        a0 = np.clip(np.floor((lo - self.origin) / span).astype(np.int64), 0, self.shape - 1)
        a1 = np.clip(np.floor((hi - self.origin) / span).astype(np.int64), 0, self.shape - 1)
        keys = set()
        for (i0, j0), (i1, j1) in zip(a0.tolist(), a1.tolist()):
            for i in range(i0, i1 + 1):
                keys.update(range(i * self.shape[1] + j0, i * self.shape[1] + j1 + 1))
        need = np.array(sorted(keys), dtype=np.int64)
        need = need[self.tile_index.ravel()[need] < 0]
        if need.size:
            self._allocate(need)
        index = self._current_index()   # the tiles left behind: not before their catch-up
        self._insert_only(ids, index)
        slots = index.ravel()
        self._filled[slots[slots >= 0]] = int(ids[-1]) + 1

    def _current_index(self) -> np.ndarray:
        """:attr:`tile_index` with the tiles left behind by a jump hidden (-1)."""
        flat = self.tile_index.ravel()
        held = np.flatnonzero(flat >= 0)
        behind = held[self._filled[flat[held]] < self.time]
        if behind.size == 0:
            return self.tile_index
        out = flat.copy()
        out[behind] = -1
        return out.reshape(self.tile_index.shape)

    def holds(self, ids: np.ndarray) -> np.ndarray:
        """Which of sweeps ``ids`` the map answers for: inserted by its time, and of
        the held axis."""
        ids = np.asarray(ids, dtype=np.int64)
        return (ids < self.time) & self.held[ids]

    def _insert_only(self, ids: np.ndarray, index: np.ndarray | None = None) -> None:
        """Insert sweeps ``ids`` (those of the held axis) into the tiles of ``index``
        (default: every allocated tile)."""
        if not self.all_held:
            ids = ids[self.held[ids]]
            if ids.size == 0:
                return
        sw = self.sweeps
        insert_sweeps(ids, sw.p0, sw.d, self.rc, self.lim, self.top, self.cell, self.size,
                      self._vals, self.tile_index if index is None else index, self.origin)

    def _slot(self) -> int:
        if not self._free:
            cap = self._vals.shape[0]
            if cap < self.max_tiles:
                grow = min(cap, self.max_tiles - cap)
                self._vals = np.concatenate(
                    [self._vals, np.broadcast_to(self._empty, (grow,) + self._empty.shape)])
                self._owner = np.concatenate([self._owner, np.full(grow, -1, dtype=np.int64)])
                self._used = np.concatenate([self._used, np.zeros(grow, dtype=np.int64)])
                self._filled = np.concatenate([self._filled,
                                               np.zeros(grow, dtype=np.int64)])
                self._free = list(range(cap + grow - 1, cap - 1, -1))
            else:
                s = int(np.argmin(self._used))  # the least recently used tile
                key = int(self._owner[s])
                self.tile_index.flat[key] = -1
                self._free.append(s)
        return self._free.pop()

    def _allocate(self, keys: np.ndarray) -> None:
        """Tiles ``keys`` (flat) that have no slot: allocate and fill to the map's time."""
        flat = self.tile_index.ravel()
        new = keys[flat[keys] < 0]
        if new.size == 0:
            return
        if new.size > self.max_tiles:
            raise MemoryError(f"a query needs {new.size} tiles of the sweep map, "
                              f"more than its budget of {self.max_tiles}")
        for key in new.tolist():
            s = self._slot()
            self._vals[s] = self._empty
            self._owner[s] = key
            self._used[s] = self._clock
            self._filled[s] = self.time
            self.tile_index.flat[key] = s
        # (a tile given a slot here and dropped again for a later one of them reads -1)
        self._fill(new[self.tile_index.ravel()[new] >= 0], 0)

    def _fill(self, keys: np.ndarray, start: int) -> None:
        """Insert into tiles ``keys`` (flat, allocated) the sweeps from ``start`` to the
        map's time that reach them."""
        if self.time <= start or keys.size == 0:
            return
        span = self.cell * self.size
        a, b = np.divmod(keys, self.shape[1])
        lo = np.array([self.origin[0] + a.min() * span, self.origin[1] + b.min() * span,
                       self._zlo])
        hi = np.array([self.origin[0] + (a.max() + 1) * span,
                       self.origin[1] + (b.max() + 1) * span, self._zhi])
        grow = self.lim + self.cell
        lo[:2] -= grow
        hi[:2] += grow
        if self.time - start <= K.ZMAP_SCAN_SWEEPS:   # a few: each one's bounds
            ids = self.sweeps.overlapping(np.arange(start, self.time), lo, hi)
        else:                                       # the index (every sweep so far)
            ids = self.sweeps.query(lo, hi)
            ids = ids[(ids >= start) & (ids < self.time)]
        if ids.size:
            self._insert_into(keys, ids)

    def _insert_into(self, keys: np.ndarray, ids: np.ndarray) -> None:
        """Insert sweeps ``ids`` into tiles ``keys`` (flat, allocated) only."""
        mask = np.full(self.tile_index.size, -1, dtype=np.int64)
        mask[keys] = self.tile_index.ravel()[keys]
        self._insert_only(ids, mask.reshape(self.tile_index.shape))

    def _catch_up(self, keys: np.ndarray) -> None:
        """Tiles ``keys`` (flat, allocated) left behind by jumps: the sweeps they miss
        inserted, from each one's own time."""
        slots = self.tile_index.ravel()[keys]
        behind = (slots >= 0) & (self._filled[slots] < self.time)
        if not behind.any():
            return
        keys, slots = keys[behind], slots[behind]
        since = self._filled[slots]
        for start in np.unique(since).tolist():
            self._fill(keys[since == start], start)
        self._filled[slots] = self.time

    def classify(self, points: np.ndarray, t1_end: float) -> np.ndarray:
        """Per point, against the sweeps that end by path length ``t1_end``:
        -1 inside none, 1 inside one, 0 not known here (test exactly).

        Parameters
        ----------
        points : ndarray, shape (k, 3) [mm]
            World points.
        t1_end : float [mm]

        Returns
        -------
        ndarray, shape (k,), int8
        """
        if self.frame is not None:
            points = np.ascontiguousarray(points @ self.frame.T)
        self._clock += 1
        fresh = self._advance(t1_end)
        keys = tiles_of(points, self.origin, self.cell, self.size, self.shape)
        slots = self.tile_index.ravel()[keys]
        self._used[slots[slots >= 0]] = self._clock  # first: not dropped for its own new tiles
        self._allocate(keys)
        self._catch_up(keys)
        if fresh:  # the state a later query earlier than the map's time goes back to
            self._keep()
        return classify(points, self._vals, self._current_index(), self.origin, self.cell,
                        self.size, K.ZMAP_GUARD_MM)


def sweep_map(sweeps: Sweeps, tool: Tool) -> SweepMap | None:
    """A :class:`SweepMap` of ``sweeps`` if the map applies, else None: a ball end mill,
    and an axis that at least ``ZMAP_AXIS_SHARE`` of the sweeps have (the one most of
    them have; ties: the first of them in numpy's sorted order), the map of those."""
    if len(sweeps) == 0 or tool.core_radius_mm != 0.0:
        return None
    w = sweeps.w
    if np.all(w[:, 2] == 1.0) and np.all(w[:, :2] == 0.0):
        return SweepMap(sweeps, tool)                  # a 3-axis program: every sweep
    axes, counts = np.unique(w, axis=0, return_counts=True)
    k = int(np.argmax(counts))
    if counts[k] < K.ZMAP_AXIS_SHARE * len(sweeps):
        return None
    return SweepMap(sweeps, tool, axis=axes[k])
