"""Predicting programs that differ a little, each taking stage 1 from the one before.

A verified correction (:mod:`errpred.verified`) predicts its candidates densely,
one after another; a fallback candidate differs from the one before it only
near the points that were worse, yet each was predicted whole (on the whole
mold core, ~400 s a prediction on two workers, for 4 worse points of 11,411).
:class:`Repredictor` predicts each program of such a sequence with stage 1
(``docs/method.md`` §3-4, the expensive part) taken from the program before
wherever it cannot have changed, and stage 2 (forces, wear, deflection, error)
for every block, in order, as :meth:`errpred.predict.Predictor.run` does.

Stage 1 of a block depends on (``errpred/geometry.py``):

* the block's cutter locations and their neighbours: the one before the block
  (where its first move starts; the move before for a corner; the pre-check's
  station at the block's start looks back across moves of zero length) and the
  one after (a corner's plunge, a turning move's end cap in
  :func:`errpred.sweeps.build_sweeps`): :func:`block_keys` digests them;
* the tool, the resolution and the stock (the same objects for every program);
* the sweeps whose bounds overlap a box in which the block looked sweeps up
  (every use of the sweeps goes through :meth:`errpred.sweeps.Sweeps.near`,
  whose answer is decided by those boxes): their union is
  :attr:`errpred.geometry.PointGeometry.lookup_box`.

So a block of the new program whose key is that of a block of the last one
(the two programs aligned as sequences of keys, in order) and whose look-up
box no sweep of a changed block overlaps, in either program, has the last
one's stage 1, but for its path lengths, shifted by the difference of the
blocks' starts (rounding: ~1e-12 mm on a path of metres; the T1/T2 split of the
sweeps is the same, as every sweep near the block keeps its order). Stage 1
of every other block is computed. ``tests/errpred/test_repredict.py`` compares
the result with a whole prediction of the new program.

Stage 2 carries the wear along the program, so a block's stage 2 depends on every
block before it. While the new program's blocks are the last one's (at the same
places, with the same lines, their points pickling to the same bytes: taken from the
last run unshifted, or computed again where a changed sweep came within their look-up
box, a long rapid's box holds much of the part, and found the same) and stage 2's
models are the same, the last run's points are taken window by window of
``STAGE2_STATE_BLOCKS`` blocks and stage 2 goes on from its kept state
(:class:`errpred.predict.Follow`): the same answers, without running stage 2 up to the
first window that differs (a fallback candidate of the mold core changes blocks near
its end: most of its 28,000 blocks are before).
"""

from __future__ import annotations

import dataclasses
import difflib
import hashlib
import pickle
import tempfile
from collections.abc import Iterable, Iterator, Mapping, Sequence

import numpy as np

from . import constants as K
from .geometry import GeometryModel, PointGeometry
from .predict import Follow, PointPrediction, Prediction, Predictor, Stage2State
from .sweeps import _build_grid, _query

__all__ = ["Repredictor", "block_keys"]


def block_keys(model: GeometryModel, n_blocks: int) -> list[bytes | None]:
    """A digest per program block of what its stage 1 reads of the path (None for a
    block without cutter locations: no stage 1).

    The cutter locations from the one before the move before the block (the corner
    at the block's start asks whether that move is a plunge; further back across moves
    of zero length, where the pre-check's station at the block's start lands) to the
    one after it: tips, axes, feeds, spindle speeds, rapid flags, which of
    them are the block's, and whether the path starts or ends there.
    """
    return _block_table(model, n_blocks)[0]


def _block_table(model: GeometryModel, n_blocks: int
                 ) -> tuple[list[bytes | None], np.ndarray]:
    """:func:`block_keys`, and the path length at each block's start [mm] (nan: no
    cutter locations), in one pass over the blocks."""
    cl = model.cl
    n = len(cl)
    path = model.path
    keys: list[bytes | None] = []
    starts = np.full(n_blocks, np.nan)
    for b in range(n_blocks):
        rng = model.block_points(b)
        if rng is None:
            keys.append(None)
            continue
        i0, i1 = rng
        start = starts[b] = path[i0 - 1] if i0 > 0 else 0.0
        first = max(min(i0 - 1, int(np.searchsorted(path, start, side="left")) - 1), 0)
        rows = slice(first, min(i1 + 2, n))
        h = hashlib.blake2b(digest_size=20)
        h.update(np.array([i0 == 0, i1 == n - 1, first - i0, rows.stop - i1]).tobytes())
        for a in (cl.tip[rows], cl.axis[rows], cl.feed_mm_min[rows], cl.spindle_rpm[rows],
                  cl.rapid[rows], cl.block[rows] == b):
            h.update(np.ascontiguousarray(a).tobytes())
        keys.append(h.digest())
    return keys, starts


class _Store:
    """Stage 1 of a run's blocks, pickled into a temporary file (memory stays flat in
    program length), read back by block. Each point is pickled on its own: a point
    pickles to the same bytes however it came (computed here, read back from a worker,
    taken from the last run), which a block's list does not (objects its points share)."""

    def __init__(self) -> None:
        self._file = tempfile.TemporaryFile()
        self._at: dict[int, tuple[int, int]] = {}

    def put(self, block: int, points: list[PointGeometry]) -> tuple[bytes, ...]:
        """Store the block's stage 1; returns its points' pickles."""
        parts = tuple(pickle.dumps(g, protocol=pickle.HIGHEST_PROTOCOL) for g in points)
        self.put_parts(block, parts)
        return parts

    def __contains__(self, block: int) -> bool:
        return block in self._at

    def get(self, block: int) -> list[PointGeometry]:
        return [pickle.loads(p) for p in self.parts(block)]

    def put_parts(self, block: int, parts: tuple[bytes, ...]) -> None:
        """Store a block's points as pickled already (:meth:`parts` of another store)."""
        data = pickle.dumps(parts, protocol=pickle.HIGHEST_PROTOCOL)
        self._file.seek(0, 2)
        self._at[block] = (self._file.tell(), len(data))
        self._file.write(data)

    def parts(self, block: int) -> tuple[bytes, ...]:
        """The block's points as pickled."""
        offset, size = self._at[block]
        self._file.seek(offset)
        return pickle.loads(self._file.read(size))

    def close(self) -> None:
        self._file.close()


@dataclasses.dataclass
class _Run:
    """What the next program needs of the last run (not its model: the sweeps' index
    and the sample grids are large)."""

    same: tuple                  # (tool, stock, resolution, sensitivity)
    sweep_lo: np.ndarray         # the sweeps' bounds, (k, 3) each [mm]
    sweep_hi: np.ndarray
    sweep_block: np.ndarray      # the block each sweep belongs to, (k,)
    keys: list[bytes | None]
    starts: np.ndarray           # path length at each block's start [mm] (nan: none)
    boxes: np.ndarray            # (n_blocks, 2, 3) look-up box (nan: none, or no look-up)
    store: _Store
    blocks: list[int]            # the run's blocks, in order
    lines: np.ndarray            # each program block's source line
    stage2: tuple                # stage 2's models (:func:`_stage2_same`)
    points: list[PointPrediction]  # the run's points
    states: list[Stage2State]    # stage 2's state every STAGE2_STATE_BLOCKS blocks


class _Taken(Sequence):
    """A block's stage 1 taken from the last run as it was (the same block, its path
    lengths not shifted), read from the last run's store when first looked at: while a
    re-prediction follows the last run, its points are neither read back nor pickled
    again (the new store copies their bytes)."""

    def __init__(self, store: _Store, block: int) -> None:
        self.store, self.block = store, block
        self._points: list[PointGeometry] | None = None

    def _get(self) -> list[PointGeometry]:
        if self._points is None:
            self._points = self.store.get(self.block)
        return self._points

    def __getitem__(self, i):
        return self._get()[i]

    def __len__(self) -> int:
        return len(self._get())


class _Given(Mapping):
    """The reused blocks' stage 1, read from the last run's store as asked for, with the
    new program's block index and path lengths."""

    def __init__(self, last: _Run, pairs: dict[int, int], shift: dict[int, float],
                 strip: bool = False) -> None:
        self._last, self._pairs, self._shift, self._strip = last, pairs, shift, strip

    def __getitem__(self, block: int) -> Sequence[PointGeometry]:
        a = self._pairs[block]
        dL = self._shift[block]
        if a == block and dL == 0.0 and not self._strip:
            return _Taken(self._last.store, a)
        # the last run had the sensitivity pass and this one not: its points without it
        extra = {"sensitivity": None} if self._strip else {}
        return [dataclasses.replace(g, block=block, path_mm=g.path_mm + dL, **extra)
                for g in self._last.store.get(a)]

    def __contains__(self, block: object) -> bool:
        return block in self._pairs

    def __iter__(self) -> Iterator[int]:
        return iter(self._pairs)

    def __len__(self) -> int:
        return len(self._pairs)


def _sweep_blocks(model: GeometryModel) -> np.ndarray:
    """The program block of each sweep."""
    return model.cl.block[model.sweeps.cl_index]


def _same(model: GeometryModel) -> tuple:
    return (model.tool, model.stock, model.res, model.sensitivity)


def _same_model(last: _Run, model: GeometryModel) -> bool:
    """Stage 1 of ``model`` may be taken from the last run's where the path is the same:
    the same tool, stock and resolution, and the sensitivity pass as there or, without
    it, from a run with it (the point without its sensitivity is the one computed
    without: the pass runs after the point's own engagement and changes nothing of it,
    tested)."""
    tool, stock, res, sens = last.same
    return (model.tool is tool and model.stock is stock and model.res == res
            and (model.sensitivity == sens or sens))


def _stage2_same(predictor: Predictor, series_lines) -> tuple:
    """What stage 2 reads besides stage 1 (compared by value: each candidate's predictor
    is built anew from the same scenario): a digest of the models' pickle, the workpiece
    (compared with ``==``: a bound method is equal for the same object) and the series
    lines asked for."""
    h = hashlib.blake2b(digest_size=20)
    h.update(pickle.dumps((predictor.tool, predictor.coefficients, predictor.compliance,
                           predictor.shape, predictor.theta, predictor.edges,
                           predictor.initial_wear_mm), protocol=pickle.HIGHEST_PROTOCOL))
    return (h.digest(), predictor.workpiece, tuple(sorted(int(x) for x in series_lines)))


class Repredictor:
    """Predicts programs one after another, each taking stage 1 from the one before
    where it cannot have changed (see the module docstring).

    Attributes
    ----------
    stats : list of dict
        Per run: ``blocks`` predicted, ``reused`` (stage 1 taken from the run before),
        ``computed``.
    reused : frozenset of int
        The last run's blocks whose stage 1 was taken from the run before.
    """

    def __init__(self) -> None:
        self._last: _Run | None = None
        self.stats: list[dict] = []
        self.reused: frozenset[int] = frozenset()

    def close(self) -> None:
        """Drop the last run's stage 1 (its temporary file)."""
        if self._last is not None:
            self._last.store.close()
            self._last = None

    def run(self, predictor: Predictor, blocks: Iterable[int] | None = None,
            **kwargs) -> Prediction:
        """:meth:`errpred.predict.Predictor.run` of ``blocks`` (default: all), with the
        stage 1 of the last run's program reused where it cannot have changed.

        The predictor must share the last one's tool and stock (the same objects) and
        resolution; otherwise nothing is reused. ``kwargs`` go to
        :meth:`~errpred.predict.Predictor.run` (not ``given`` nor ``keep``).
        """
        model = predictor.model
        n_blocks = len(predictor.program)
        blocks = list(range(n_blocks)) if blocks is None else [int(b) for b in blocks]
        keys, starts = _block_table(model, n_blocks)
        sweep_block = _sweep_blocks(model)
        given = self._reusable(model, keys, starts, sweep_block, blocks)
        lines = np.asarray(predictor.program.line)
        stage2 = _stage2_same(predictor, kwargs.get("series_lines", ()))
        store = _Store()
        boxes = np.full((n_blocks, 2, 3), np.nan)
        last = self._last
        # followed only with the same sensitivity pass (without it the points' gain differs)
        following = (last is not None and bool(last.states) and last.stage2 == stage2
                     and _same_model(last, model) and last.same[3] == model.sensitivity)
        same_at: dict[int, bool] = {}          # position in the run -> the last run's

        def keep(block: int, points: Sequence[PointGeometry]) -> None:
            if isinstance(points, _Taken):          # the last run's, as it was
                parts = points.store.parts(points.block)
                store.put_parts(block, parts)
                boxes[block] = last.boxes[points.block]
            else:
                parts = store.put(block, points)
                if points and points[0].lookup_box is not None:
                    boxes[block] = points[0].lookup_box
            if following:
                pos = len(same_at)
                # once a block differs the run no longer follows: no more reading back
                same_at[pos] = ((pos == 0 or same_at[pos - 1])
                                and pos < len(last.blocks) and last.blocks[pos] == block
                                and block in last.store and lines[block] == last.lines[block]
                                and ((isinstance(points, _Taken) and points.block == block)
                                     or parts == last.store.parts(block)))

        follow = None
        if following:
            follow = Follow(last.points, {st.blocks: st for st in last.states},
                            lambda pos, block: same_at.get(pos, False))
        states: list[Stage2State] = []
        try:
            out = predictor.run(blocks, given=given, keep=keep, follow=follow,
                                states=states.append, **kwargs)
        except BaseException:
            store.close()
            raise
        # the windows taken from the last run: its own states, handed on (a prefix)
        prev = {id(st) for st in last.states} if following else set()
        followed = max((st.blocks for st in states if id(st) in prev), default=0)
        self.close()
        sw = model.sweeps
        self._last = _Run(_same(model), sw.lo, sw.hi, sweep_block, keys, starts, boxes,
                          store, blocks, lines, stage2, out.points, states)
        self.reused = frozenset(given)
        self.stats.append(dict(blocks=len(blocks), reused=len(given),
                               computed=len(blocks) - len(given), followed=followed))
        return out

    def _reusable(self, model: GeometryModel, keys: list, starts: np.ndarray,
                  sweep_block: np.ndarray, blocks: list[int]) -> _Given:
        last = self._last
        if last is None:
            return _Given(last, {}, {})
        if not _same_model(last, model):
            return _Given(last, {}, {})
        # align the programs (in order) by their blocks' keys; blocks without cutter
        # locations never pair
        a_seq = [k if k is not None else ("none-a", i) for i, k in enumerate(last.keys)]
        b_seq = [k if k is not None else ("none-b", i) for i, k in enumerate(keys)]
        sm = difflib.SequenceMatcher(None, a_seq, b_seq, autojunk=False)
        pair_b = np.full(len(b_seq), -1, dtype=np.int64)
        for m in sm.get_matching_blocks():
            pair_b[m.b:m.b + m.size] = np.arange(m.a, m.a + m.size)
        changed_a = np.ones(len(a_seq), dtype=bool)
        changed_a[pair_b[pair_b >= 0]] = False
        changed_b = pair_b < 0
        hit_a = changed_a[last.sweep_block]
        hit_b = changed_b[sweep_block]
        lo = np.concatenate([last.sweep_lo[hit_a], model.sweeps.lo[hit_b]])
        hi = np.concatenate([last.sweep_hi[hit_a], model.sweeps.hi[hit_b]])
        cell = K.SWEEP_GRID_CELL_PER_RADIUS * model.tool.radius_mm
        grid = _build_grid(lo, hi, cell) if lo.shape[0] else None
        pad = K.REUSE_BOX_PAD_MM
        pairs: dict[int, int] = {}
        shift: dict[int, float] = {}
        for b in blocks:
            a = int(pair_b[b])
            if a < 0 or a not in last.store:
                continue
            box = last.boxes[a]
            if grid is not None and not np.isnan(box[0, 0]):
                hit = _query(grid["cell_start"], grid["cell_items"], grid["grid_shape"],
                             grid["grid_origin"], cell, lo, hi, box[0] - pad, box[1] + pad)
                if hit.size:
                    continue
            pairs[b] = a
            shift[b] = float(starts[b] - last.starts[a])
        return _Given(last, pairs, shift, strip=last.same[3] and not model.sensitivity)
