"""The prediction pipeline: a program in, an error per block out.

Two stages (``docs/architecture.md``): stage 1, the geometry of every
prediction point (:mod:`errpred.geometry`), depends only on the program and
the stock, so it runs block by block in any order, in this process or in a
pool of worker processes; stage 2, forces with wear, deflection and error
(:mod:`errpred.physics`), runs in program order because the actual cutting
distance of each micro edge carries from block to block. Memory stays
bounded: stage-1 results are consumed in order as they arrive.
"""

from __future__ import annotations

import gc
import math
import os
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Mapping
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from nc.cycles import refuse_drilling
from nc.path import CutterLocations, cutter_locations
from nc.program import Program

from . import constants as K
from .coefficients import CuttingCoefficients
from .conditions import refuse_feed_beyond_model
from .dynamics import Compliance
from .geometry import STATUS, GeometryModel, PointGeometry, Resolution
from .physics import PointResult, ShapeErrorModel, WearState, evaluate
from .tool import Tool
from .zmap import SweepMap

__all__ = ["Follow", "PointPrediction", "Prediction", "Predictor", "Stage2State",
           "predict_points"]


@dataclass(frozen=True, eq=False)
class PointPrediction:
    """Stage 1 and stage 2 of one prediction point, together."""

    geometry: PointGeometry
    result: PointResult | None
    line: int

    @property
    def block(self) -> int:
        return self.geometry.block

    @property
    def status(self) -> str:
        return self.geometry.status

    @property
    def E_um(self) -> float:
        return self.result.E_um if self.result is not None else math.nan


@dataclass(eq=False)
class Prediction:
    """Results along a program.

    Attributes
    ----------
    points : list of PointPrediction
        In program order.
    wear_mm : ndarray, shape (m,)
        Actual cutting distance of each micro edge at the end [mm].
    edges_kappa_rad, edges_z_mm : ndarray, shape (m,)
        Where the micro edges are (for plots of wear along the edge).
    theta : ndarray, shape (n,) [rad]
        Rotation angles of one revolution.
    series : dict
        Program line -> ``(force_N (n, 3), deflection_mm (n, 3), theta_m,
        theta (n,))`` over one revolution, kept for the lines asked for and
        for the point with the largest |E| (key ``-1``, with its line last).
    initial_wear_mm : ndarray, shape (m,) or None
        Actual cutting distance of each micro edge at the start [mm] (None:
        a fresh tool).
    flute_length_mm : float [mm]
        The tool's flute length the points were judged with
        (:attr:`errpred.geometry.PointGeometry.above_flutes`; NaN: not known).
    """

    points: list[PointPrediction]
    wear_mm: np.ndarray
    edges_kappa_rad: np.ndarray
    edges_z_mm: np.ndarray
    theta: np.ndarray = field(default_factory=lambda: np.zeros(0))
    series: dict[int, tuple[np.ndarray, np.ndarray, float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    initial_wear_mm: np.ndarray | None = None
    flute_length_mm: float = math.nan

    def errors_um(self) -> np.ndarray:
        return np.array([p.E_um for p in self.points])

    def predicted(self) -> list[PointPrediction]:
        return [p for p in self.points if p.result is not None and p.status == "predicted"]


# --- the worker side of stage 1 ----------------------------------------------
_WORKER_MODEL: GeometryModel | None = None


def _init_worker(model: GeometryModel) -> None:
    """A forked worker's model: the parent's, inherited; its sweeps' height map (if
    the parent had one) goes back to its kept state without a copy
    (:meth:`errpred.zmap.SweepMap.hand_over_kept`: the worker's chunks come in order)."""
    global _WORKER_MODEL
    _WORKER_MODEL = model
    zmap = getattr(model, "_zmap", None)
    if isinstance(zmap, SweepMap):
        zmap.hand_over_kept()


def _chunks(blocks: list[int], workers: int,
            largest: int = K.WORKER_CHUNK_MAX_BLOCKS) -> list[list[int]]:
    """``blocks`` cut into runs of consecutive entries for ``workers`` workers, in
    order, shrinking toward the end (guided): each the blocks left over
    ``WORKER_CHUNK_SHARE * workers``, at least ``WORKER_CHUNK_MIN_BLOCKS`` and at most
    ``largest`` blocks, so the last tasks are short and no worker waits a whole
    chunk for the other at the end."""
    share = K.WORKER_CHUNK_SHARE * max(1, workers)
    out: list[list[int]] = []
    i, n = 0, len(blocks)
    while i < n:
        size = min(max(1, largest), max(K.WORKER_CHUNK_MIN_BLOCKS, -(-(n - i) // share)))
        out.append(blocks[i:i + size])
        i += size
    return out


def _in_order(submit: Callable, chunks: list[list[int]], limit: int,
              release: Callable | None = None, cancel: Callable | None = None
              ) -> Iterator[list[PointGeometry]]:
    """The results of ``submit(chunk)`` (a future) for each chunk, block by block and
    in order, with at most ``limit`` chunks submitted ahead of the one taken; each
    future is dropped (``release(f)``) once taken, so the workers and this process
    hold a few chunks' results, not a pass's; those still pending when the consumer
    stops are handed to ``cancel``."""
    pending: deque = deque()
    nxt = 0
    try:
        while nxt < len(chunks) or pending:
            while nxt < len(chunks) and len(pending) < limit:
                pending.append(submit(chunks[nxt]))
                nxt += 1
            f = pending.popleft()
            res = f.result()
            if release is not None:
                release(f)
            del f
            yield from res
    finally:
        if pending and cancel is not None:
            cancel(list(pending))


def _on_cluster(client, model, blocks: list[int], chunk: int
                ) -> Iterator[list[PointGeometry]]:
    """Stage 1 of ``blocks`` on a Dask cluster, in order, in guided chunks of at most
    ``chunk`` blocks (:func:`_chunks`), with a bounded number in flight
    (``DASK_CHUNKS_IN_FLIGHT`` a worker): each chunk's future is released as soon
    as its result is taken, so the workers hold a few chunks' results at a time, not
    the whole pass's."""
    if not blocks:
        return
    workers = max(1, len(client.scheduler_info().get("workers", {})))
    chunks = _chunks(blocks, workers, chunk)
    scattered = client.scatter(model, broadcast=True)
    yield from _in_order(
        lambda c: client.submit(_model_chunk, scattered, c, pure=False), chunks,
        K.DASK_CHUNKS_IN_FLIGHT * workers, release=lambda f: f.release(),
        cancel=client.cancel)


def _on_pool(model, blocks: list[int], workers: int, chunk: int
             ) -> Iterator[list[PointGeometry]]:
    """Stage 1 of ``blocks`` on ``workers`` forked processes (where the platform
    forks), in order, in guided chunks (:func:`_chunks`), at most
    ``POOL_CHUNKS_IN_FLIGHT`` a worker submitted ahead. The model is inherited at the
    fork (not pickled); Python's garbage collector is frozen over the fork, so the
    workers' collections do not walk (and copy, page by page) every object the
    parent had."""
    import multiprocessing as mp

    chunks = _chunks(blocks, workers, chunk)
    ctx = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else None
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx,
                             initializer=_init_worker, initargs=(model,)) as pool:
        frozen = [True]
        gc.freeze()             # the pool forks its workers at the first submit

        def submit(c):
            try:
                return pool.submit(_worker_chunk, c)
            finally:
                if frozen:
                    gc.unfreeze()
                    frozen.clear()

        try:
            yield from _in_order(submit, chunks, K.POOL_CHUNKS_IN_FLIGHT * workers,
                                 cancel=lambda fs: [f.cancel() for f in fs])
        finally:
            if frozen:
                gc.unfreeze()


def _model_chunk(model: GeometryModel, blocks: list[int]) -> list[list[PointGeometry]]:
    """Stage 1 of a chunk with a given model (a Dask task; the model is scattered once)."""
    return [model.geometry(b) for b in blocks]


def _worker_chunk(blocks: list[int]) -> list[list[PointGeometry]]:
    assert _WORKER_MODEL is not None
    return [_WORKER_MODEL.geometry(b) for b in blocks]


@dataclass(frozen=True, eq=False)
class Stage2State:
    """What stage 2 carries along a run after its first :attr:`blocks` blocks: enough to
    go on from there with the same answers as the run (:class:`Follow`).

    Attributes
    ----------
    blocks : int
        Blocks of the run done (its first ``blocks`` blocks).
    points : int
        Points predicted in them.
    wear_mm : ndarray, shape (m,) [mm]
        Each micro edge's actual cutting distance after them.
    worst : float [um]
        The largest |E| of a predicted point so far (-1: none).
    kept : dict
        The force and deflection series kept so far (:attr:`Prediction.series`).
    """

    blocks: int
    points: int
    wear_mm: np.ndarray
    worst: float
    kept: dict


@dataclass(frozen=True, eq=False)
class Follow:
    """A run of the same predictor's inputs to follow (:meth:`Predictor.run`'s
    ``follow``): while this run's blocks are that run's, window by window of
    ``STAGE2_STATE_BLOCKS`` blocks, its points are taken and stage 2 goes on from its
    kept state at the window's end instead of running (the same answers: the same
    stage 1 from the same state).

    Attributes
    ----------
    points : list of PointPrediction
        That run's points.
    states : mapping of int to Stage2State
        Its kept states by blocks done (:attr:`Stage2State.blocks`).
    same : callable
        ``same(position, block)``: whether this run's block at that position (in the
        run's order) is that run's at the same position, with the same stage 1 (asked
        after the block's stage 1 has been handed to ``keep``) and the same line. The
        stage 2 models, series lines and start state must be that run's (the caller's
        part: :class:`errpred.repredict.Repredictor` compares them).
    """

    points: list
    states: Mapping[int, Stage2State]
    same: Callable[[int, int], bool]


class Predictor:
    """Holds the models; :meth:`run` predicts.

    Parameters
    ----------
    tool : Tool
    stock : errpred.raster.meshes.Stock
    program : Program
    coefficients : CuttingCoefficients
    compliance : Compliance
    shape_error : ShapeErrorModel, optional
    resolution : Resolution, optional
    machine : nc.kinematics.Machine, optional
        For programs that move rotary axes.
    cl : CutterLocations, optional
        The path, if already made (else from ``program`` and ``machine``).
    workpiece : callable, optional
        ``workpiece(point_mm) -> [(Mode, direction)]``: the workpiece's modes at
        a cutting point (a thin wall); the deflection is then tool minus
        workpiece (:func:`errpred.physics.revolution`). Default: rigid.
    initial_wear_mm : float or ndarray of shape (m,), optional
        The tool's state at the start of :meth:`run` [mm]: each micro edge's
        actual cutting distance so far (an array, e.g. from a tool-state file,
        :mod:`errpred.tool_state`), or one distance for every micro edge.
        Default: a fresh tool (0).
    sensitivity : bool
        Also each point's error sensitivity to a correction
        (:attr:`errpred.physics.PointResult.gain`; 0 where not computed). A
        correction needs it; a prediction alone does not (it costs a second
        engagement and a second revolution per point).
    """

    def __init__(self, tool: Tool, stock, program: Program,
                 coefficients: CuttingCoefficients, compliance: Compliance,
                 shape_error: ShapeErrorModel | None = None,
                 resolution: Resolution | None = None, machine=None,
                 cl: CutterLocations | None = None, workpiece=None,
                 initial_wear_mm=None, sensitivity: bool = True) -> None:
        refuse_drilling(program, "the error prediction")  # holes are not milled surfaces
        self.tool = tool
        self.workpiece = workpiece
        self.program = program
        self.coefficients = coefficients
        self.compliance = compliance
        self.shape = shape_error or ShapeErrorModel()
        self.resolution = resolution or Resolution.default(tool)
        self.cl = cl if cl is not None else cutter_locations(
            program, machine, chord_tol_mm=self.resolution.chord_tol_mm)
        refuse_feed_beyond_model(program, self.cl, tool)   # before any geometry
        self.model = GeometryModel(tool, stock, self.cl, self.resolution, sensitivity)
        self.initial_wear_mm = WearState.start(self.edges, initial_wear_mm).cl_mm

    @property
    def edges(self):
        return self.model.edges

    @property
    def theta(self) -> np.ndarray:
        return self.model.theta

    def geometries(self, blocks: Iterable[int], *, workers: int = 1,
                   chunk: int = K.WORKER_CHUNK_MAX_BLOCKS, client=None,
                   given: Mapping[int, list[PointGeometry]] | None = None
                   ) -> Iterator[list[PointGeometry]]:
        """Stage 1 of ``blocks``, yielded in the given order.

        ``given``: stage 1 of some blocks, already known (a block in it is taken from
        it, not computed; :class:`errpred.repredict.Repredictor`).

        With ``client`` (a ``dask.distributed.Client``) the chunks run on its
        workers: the geometry model is scattered to every worker once, the chunks
        are submitted in order and their results taken in order (stage 1 of a
        block depends only on the program and the stock, method.md §3), so the
        prediction is the same as in one process. With ``workers`` > 1 (and no
        client) they run on as many forked processes. Either way in guided chunks
        of at most ``chunk`` consecutive blocks (:func:`_chunks`).
        """
        blocks = list(blocks)
        if given:
            todo = [b for b in blocks if b not in given]
            computed = self.geometries(todo, workers=workers, chunk=chunk, client=client)
            try:
                for b in blocks:
                    yield given[b] if b in given else next(computed)
            finally:
                computed.close()        # the cluster's chunks in flight are cancelled
            return
        self.model.plan_sweep_map(blocks)
        if client is not None:
            yield from _on_cluster(client, self.model, blocks, chunk)
            return
        if workers <= 1 or len(blocks) < 2 * workers:
            for b in blocks:
                yield self.model.geometry(b)
            return
        yield from _on_pool(self.model, blocks, workers, chunk)

    def run(self, blocks: Iterable[int] | None = None, *, workers: int = 1,
            progress: Callable[[int], None] | None = None,
            series_lines: Iterable[int] = (), client=None,
            given: Mapping[int, list[PointGeometry]] | None = None,
            keep: Callable[[int, list[PointGeometry]], None] | None = None,
            follow: Follow | None = None,
            states: Callable[[Stage2State], None] | None = None) -> Prediction:
        """Predict the error of ``blocks`` (default: every block of the program).

        Parameters
        ----------
        blocks : iterable of int, optional
            Program block indices, ascending. Wear is carried through the
            blocks given only: pass every block (the default) for wear along
            the whole program.
        workers : int
            Processes for stage 1 (1: this process).
        progress : callable, optional
            Called with the number of blocks done after each block.
        series_lines : iterable of int
            Program lines whose force and deflection over a revolution are
            kept (:attr:`Prediction.series`); the largest-|E| point's always is.
        client : dask.distributed.Client, optional
            Run stage 1 on a Dask cluster instead (``workers`` is then unused).
        given : mapping, optional
            Stage 1 of some blocks, already known (:meth:`geometries`); stage 2 runs
            for every block as usual (the wear goes on through them).
        keep : callable, optional
            ``keep(block, points)`` with each block's stage 1 as it arrives (the whole
            :class:`PointGeometry`, before stage 2).
        follow : Follow, optional
            A run to follow while this one's blocks are the same (:class:`Follow`;
            :class:`errpred.repredict.Repredictor`): its points and states are taken
            window by window instead of running stage 2.
        states : callable, optional
            ``states(Stage2State)`` every ``STAGE2_STATE_BLOCKS`` blocks (for a later
            ``follow``).

        The wear starts from :attr:`initial_wear_mm` (a fresh tool unless the
        predictor was given a used tool's state).
        """
        blocks = list(range(len(self.program))) if blocks is None else list(blocks)
        wear = WearState(self.initial_wear_mm.copy())
        out: list[PointPrediction] = []
        series_kept = set(int(x) for x in series_lines)
        kept: dict[int, tuple[np.ndarray, np.ndarray, float]] = {}
        worst = -1.0
        done = 0
        every = K.STAGE2_STATE_BLOCKS
        syncing = follow is not None
        window: list[list[PointGeometry]] = []   # following: the window's stage 1 so far

        def stage2(geoms: list[PointGeometry]) -> None:
            nonlocal worst
            for g in geoms:
                buf: list = []
                res = evaluate(self.tool, self.edges, self.coefficients, self.compliance,
                               self.shape, self.theta, g, wear, series=buf,
                               workpiece=self.workpiece)
                line = int(self.program.line[g.block])
                out.append(PointPrediction(g.light(), res, line))
                if buf:
                    item = (buf[0][1], buf[0][2], g.gen.theta_rad, buf[0][0])
                    if line in series_kept:
                        kept[line] = item
                    if g.status == "predicted" and abs(res.E_um) > worst:
                        worst = abs(res.E_um)
                        kept[-1] = (*item, line)

        for block, geoms in zip(blocks, self.geometries(blocks, workers=workers,
                                                        client=client, given=given),
                                strict=True):
            if keep is not None:
                keep(block, geoms)
            state = None
            if syncing:
                window.append(geoms)
                if not follow.same(done, block):
                    syncing = False
                elif (done + 1) % every == 0:
                    state = follow.states.get(done + 1)
                    syncing = state is not None
            if state is not None:               # the window is that run's: take it
                out.extend(follow.points[len(out):state.points])
                wear = WearState(state.wear_mm.copy())
                kept, worst = dict(state.kept), state.worst
                window = []
            elif not syncing:
                if window:      # no longer following: the window, this block last, from its start
                    for gs in window:
                        stage2(gs)
                    window = []
                else:
                    stage2(geoms)
            done += 1
            if states is not None and done % every == 0:
                states(state if state is not None else
                       Stage2State(done, len(out), wear.cl_mm.copy(), worst, dict(kept)))
            if progress is not None:
                progress(done)
        for gs in window:               # the end, within a window that was followed
            stage2(gs)
        return Prediction(points=out, wear_mm=wear.cl_mm, edges_kappa_rad=self.edges.kappa,
                          edges_z_mm=self.edges.z, theta=self.theta, series=kept,
                          initial_wear_mm=self.initial_wear_mm.copy(),
                          flute_length_mm=float(self.model.tool.flute_length_mm))


def predict_points(predictor: Predictor, blocks=None, **kwargs) -> Prediction:
    """Functional form of :meth:`Predictor.run`."""
    return predictor.run(blocks, **kwargs)


def status_text(status: str) -> str:
    """Human-readable meaning of a point's status."""
    return STATUS.get(status, status)


def default_workers() -> int:
    """Stage-1 workers for this machine (the cores available to the process)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover
        return max(1, os.cpu_count() or 1)
