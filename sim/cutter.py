"""A cut that goes on while the NC moves: the cutting model changes, the vibration and
the surface memory carry on (``docs/method.md`` §8).

Along a segment of the path the posture changes continuously from one cutter
location's to the next's; the simulation has the engagement (its table) at
the cutter locations, so along the segment it blends the two tables' forces
(:class:`Cut`). Where the dynamics change (the workpiece's modes at the next
point), :meth:`Cutter.switch` moves the state by the change of the cut's
periodic forced response (:mod:`sim.forced`), so the change does not ring the
modes like a hammer blow, which no machine does.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from errpred.spindle import rpm_for_tooth_period
from nc.checks import real_number
from orient.dynamics import ModalSystem

from . import _kernels as _k
from .cutting import CuttingModel, MillingRun, _integrate, _step_map, empty_table
from .forced import forced_response, mid_step_displacement
from .generation import tooth_surfaces

__all__ = ["Cut", "Cutter"]

#: Forced responses kept by the cutter (the cuts of the segment in hand and the next) [-].
_FORCED_CACHE = 4


class Cut(NamedTuple):
    """The cut in effect at an instant: ``weight`` of ``model``'s force and ``1 - weight``
    of ``previous``'s (the posture between two cutter locations).

    Attributes
    ----------
    model : CuttingModel
    previous : CuttingModel or None
        Another table with ``model``'s dynamics (the same ``system`` object);
        None: ``model`` alone.
    weight : float [-]
        In [0, 1].
    """

    model: CuttingModel
    previous: CuttingModel | None = None
    weight: float = 1.0

    def parts(self) -> list[tuple[CuttingModel, float]]:
        """The models with a share of the force, and their shares."""
        if self.previous is None:
            return [(self.model, 1.0)]
        out = [(self.model, self.weight), (self.previous, 1.0 - self.weight)]
        return [(m, w) for m, w in out if w > 0.0]

    def same_as(self, other: Cut | None) -> bool:
        return other is not None and self.model is other.model \
            and self.previous is other.previous \
            and (self.previous is None or abs(self.weight - other.weight) < 1e-12)


def _as_cut(cut: Cut | CuttingModel | None) -> Cut | None:
    return Cut(cut) if isinstance(cut, CuttingModel) else cut


class Cutter:
    """A cut that goes on across changes of the cutting model (the NC moving on).

    Keeps the modal state, the surface memory and the rotation sample between
    calls of :meth:`advance`, so a run can be cut into servo ticks and the
    model swapped when the cutter location or the posture changes (same
    ``steps_per_rev`` and micro edges; when the number of modes changes, the
    state of the modes kept by index is carried and new ones start at rest).

    Parameters
    ----------
    steps_per_rev : int
        Rotation steps per revolution of every model used.
    n_edges : int
        Micro edges per flute of every model used.
    """

    def __init__(self, steps_per_rev: int, n_edges: int) -> None:
        self.steps_per_rev = int(steps_per_rev)
        self.n_edges = int(n_edges)
        self.surface = np.zeros((self.steps_per_rev, self.n_edges, 3))
        self.state = np.zeros((0, 2))
        self.step = 0
        self.time_s = 0.0
        #: The cut in effect after the last :meth:`advance` or :meth:`switch` (None: idle).
        self.cut: Cut | None = None
        self._forced_cache: OrderedDict = OrderedDict()
        self._idle: tuple | None = None          # (system, dt_s, model) of the last idle
        self._engaged_kept: list = []            # the last two cuts' models and places

    def switch(self, new: Cut | CuttingModel | None,
               carry: Callable[[np.ndarray], np.ndarray] | None = None) -> None:
        """Leave the cut in effect and take ``new`` (None: not cutting) as a machine
        would, whose posture and cutting point move continuously.

        The state moves by the change of the forced response
        (:func:`sim.forced.forced_response`) at the current step, ``carry``
        (optional) in between maps it to ``new``'s modes. The surface memory: a
        place both cuts engage keeps what the vibration beyond the forced
        response left on it; a place only ``new`` engages is as ``new``'s forced
        response leaves it (what the tool would have left, had it been cutting so
        already)."""
        old, new = self.cut, _as_cut(new)
        p = self.step % self.steps_per_rev
        q_old = None
        if old is not None:
            x = self._forced(old)
            self._check_modes(old.model)
            self.state = self.state - x[p]
            q_old = mid_step_displacement(old.model, x)
        if carry is not None:
            self.state = carry(self.state)
        self.cut = new
        if new is None:
            return
        x = self._forced(new)
        self._check_modes(new.model)
        self.state = self.state + x[p]
        q_new = mid_step_displacement(new.model, x)
        on_new = self._engaged(new)
        if old is not None:                  # both engage it: the vibration's imprint stays
            both = np.intersect1d(on_new, self._engaged(old), assume_unique=True)
            rows, cols = np.divmod(both, self.n_edges)
            self.surface[rows, cols] += (q_new - q_old)[rows]
            on_new = np.setdiff1d(on_new, both, assume_unique=True)
        rows, cols = np.divmod(on_new, self.n_edges)     # only the new cut engages it
        self.surface[rows, cols] = q_new[rows]

    def _engaged(self, cut: Cut) -> np.ndarray:
        """The places of the surface memory the cut engages, as flat indices
        ``position * n_edges + edge`` of ``surface``'s first two axes, ascending (the
        order of :func:`sim.forced.engaged_cells`' mask's ``nonzero``; from the tables'
        few thousand entries instead of a mask of every place)."""
        models = tuple(m for m, _w in cut.parts())
        for kept, cells in self._engaged_kept:      # a switch's old cut: the one before's new
            if len(kept) == len(models) and all(a is b for a, b in zip(kept, models)):
                return cells
        # the places marked on a mask of the surface memory, read back in order: the sorted
        # unique indices (np.unique sorted the tables' tens of thousands of entries, a
        # twentieth of a verification run)
        mask = np.zeros(self.steps_per_rev * self.n_edges, dtype=bool)
        for m in models:
            mask[m.table[1] * self.n_edges + m.table[2]] = True
        cells = np.flatnonzero(mask)
        cells.flags.writeable = False
        self._engaged_kept = [(models, cells)] + self._engaged_kept[:1]
        return cells

    def _forced(self, cut: Cut) -> np.ndarray:
        """The forced response of ``cut``: the weighted sum of its models' (the same
        dynamics), each kept for the next cuts (a segment's end is the next one's
        start)."""
        total = 0.0
        for m, w in cut.parts():
            hit = self._forced_cache.get(id(m))
            if hit is None or hit[0] is not m:
                hit = (m, forced_response(m))
                self._forced_cache[id(m)] = hit
                if len(self._forced_cache) > _FORCED_CACHE:
                    self._forced_cache.popitem(last=False)
            else:
                self._forced_cache.move_to_end(id(m))
            total = total + w * hit[1]
        return total

    def _check_modes(self, model: CuttingModel) -> None:
        if self.state.shape[0] == 0:                   # at rest before the first cut
            self.state = np.zeros((model.system.n_modes, 2))
        if self.state.shape[0] != model.system.n_modes:
            raise ValueError(f"state: expected {model.system.n_modes} modes, got "
                             f"{self.state.shape[0]}")

    def advance(self, model: CuttingModel, n_steps: int, scale: float = 1.0, *,
                linear: bool = False, previous: CuttingModel | None = None,
                weight: tuple[float, float] = (1.0, 1.0),
                variation: np.ndarray | None = None) -> MillingRun:
        """Cut ``n_steps`` steps with ``model`` (its table, modes and step) from where
        the last call stopped; returns that stretch (``modal_state`` empty,
        ``surface_offset_mm`` at the generating phase of each tooth within it).

        With ``previous`` (a table with ``model``'s dynamics, see :class:`Cut`), the
        force is blended: ``model``'s share goes linearly from ``weight[0]`` at
        the start of the stretch to ``weight[1]`` at its end, ``previous`` has the
        rest. ``variation`` (``n_steps``,) [-], optional, multiplies the chip widths step
        by step (the work material's scatter, ``sim.constants.MATERIAL_SCATTER``)."""
        w0, w1 = (real_number("weight", w, ">=0") for w in weight)
        if w0 > 1.0 or w1 > 1.0:
            raise ValueError(f"weight: expected values in [0, 1], got {weight!r}")
        run, _teeth = self.advance_pieces(model, [int(n_steps)], scale, linear=linear,
                                          previous=previous, weights=([w0], [w1]),
                                          variation=variation)
        return run

    def advance_pieces(self, model: CuttingModel, counts, scale: float = 1.0, *,
                       linear: bool = False, previous: CuttingModel | None = None,
                       weights: tuple | None = None, variation: np.ndarray | None = None
                       ) -> tuple[MillingRun, np.ndarray]:
        """:meth:`advance` over consecutive pieces in one kernel call: the same numbers,
        bit for bit, as calling it piece by piece with the same model.

        Piece ``p`` is ``counts[p]`` steps over which ``model``'s share goes linearly
        from ``weights[0][p]`` to ``weights[1][p]`` (with ``previous``; default 1 to
        1); its time starts where the piece before ended, its surface offsets are
        those of the teeth mostly within it, with the generating weights of its
        mean share (as :meth:`advance` gives them). ``variation`` covers all the
        steps.

        Returns
        -------
        MillingRun
            All the steps (``surface_offset_mm`` the pieces' teeth, piece after piece).
        ndarray of int, shape (len(counts),)
            Teeth per piece in ``surface_offset_mm``.
        """
        for m in (model, previous):
            if m is not None and (m.steps_per_rev != self.steps_per_rev
                                  or m.n_edges != self.n_edges):
                raise ValueError(f"model: expected {self.steps_per_rev} steps per revolution "
                                 f"and {self.n_edges} micro edges, got {m.steps_per_rev} and "
                                 f"{m.n_edges}")
        if previous is not None and previous.system is not model.system:
            raise ValueError("previous: expected a table with the model's dynamics "
                             "(the same system)")
        counts = np.asarray(counts, dtype=np.int64).reshape(-1)
        if np.any(counts < 0):
            raise ValueError(f"counts: expected steps >= 0, got {counts.min()}")
        n = int(counts.sum())
        s = real_number("scale", scale, ">=0")
        widths = np.full(n, s)
        if variation is not None:
            v = np.asarray(variation, dtype=float)
            if v.shape != (n,) or not np.all(v >= 0.0):
                raise ValueError(f"variation: expected {n} values >= 0, got shape {v.shape}")
            widths = widths * v
        if weights is None:
            w0 = w1 = np.ones(counts.size)
        else:
            w0, w1 = (np.asarray(w, dtype=float).reshape(-1) for w in weights)
            if w0.shape != counts.shape or w1.shape != counts.shape \
                    or not (np.all(w0 >= 0.0) and np.all(w0 <= 1.0)
                            and np.all(w1 >= 0.0) and np.all(w1 <= 1.0)):
                raise ValueError(f"weights: expected {counts.size} values in [0, 1] at each "
                                 f"end of the pieces")
        nm = model.system.n_modes
        if self.state.shape[0] != nm:
            st = np.zeros((nm, 2))
            k = min(nm, self.state.shape[0])
            st[:k] = self.state[:k]
            self.state = st
        force = np.empty((n, 3))
        disp = np.empty((n, 3))
        acc = np.empty((n, 3))
        chip = np.empty(n)
        lost = np.empty(n, dtype=np.int64)
        first = np.cumsum(counts) - counts               # each piece's first step
        start = np.empty(counts.size)                    # each piece's start time
        t0 = self.time_s
        for p, k in enumerate(counts.tolist()):
            start[p] = t0
            t0 += k * model.dt_s
        # each step's time and, blended, the previous table's share: advance's
        # w0 + (w1 - w0) (j + 1/2) / n, j the step within its piece (one pass)
        t, other = _k.piece_steps(counts, w0, w1, start, float(model.dt_s),
                                  previous is not None)
        generating = None
        if previous is None:
            _integrate(model, self.step, widths, linear, self.surface, self.state,
                       force, disp, acc, chip, lost)
        else:
            _integrate(model, self.step, widths, linear, self.surface, self.state,
                       force, disp, acc, chip, lost, previous.table, other)
            wm = 0.5 * (w0 + w1)
            generating = wm[:, None] * model.generating + (1.0 - wm)[:, None] \
                * previous.generating
        surf, teeth = tooth_surfaces(disp, model, self.step + first, counts, generating)
        self.step += n
        self.time_s = t0
        self.cut = Cut(model, previous, float(w1[-1]) if w1.size else 1.0)
        return (MillingRun(time_s=t, force_N=force, displacement_m=disp,
                           tool_acceleration_m_s2=acc, modal_state=np.zeros((0, nm, 2)),
                           chip_mean_mm=chip, contact_loss=lost, surface_offset_mm=surf,
                           scale=s), teeth)

    def idle(self, dt_s: float, n_steps: int, system: ModalSystem) -> MillingRun:
        """Advance without cutting (the modes ring down; no force), ``dt_s`` [s] per step.
        The idle model of the last ``system`` and step is kept (the air moves of a run
        ring down the same tool modes tick after tick: one step map, not one a tick)."""
        return self.idle_pieces(dt_s, [int(n_steps)], system)

    def idle_pieces(self, dt_s: float, counts, system: ModalSystem) -> MillingRun:
        """:meth:`idle` over consecutive pieces of ``counts`` steps in one kernel call (each
        piece's time starting where the one before ended, as piece by piece)."""
        hit = self._idle
        if hit is not None and hit[0] is system and hit[1] == dt_s:
            model = hit[2]
        else:
            spr = self.steps_per_rev
            model = CuttingModel(spindle_rpm=rpm_for_tooth_period(dt_s, spr), flutes=1,
                                 steps_per_rev=spr, dt_s=dt_s, system=system,
                                 normal=np.array([0.0, 0.0, 1.0]), fz_mm=0.0,
                                 table=empty_table(spr), n_edges=self.n_edges,
                                 step_map=_step_map(system, dt_s), generating=np.zeros(spr))
            self._idle = (system, dt_s, model)
        run, _teeth = self.advance_pieces(model, counts, 0.0)
        self.cut = None
        return run
