"""What a run of the cutting simulation needs, prepared once per cut and posture
(:func:`sim.cutting.prepare_cut` makes it; :mod:`sim.forced` and :mod:`sim.generation`
read it, so it lives apart from the simulation that imports them)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from errpred.spindle import tooth_period
from orient.dynamics import ModalSystem

__all__ = ["CuttingModel"]


@dataclass(frozen=True, eq=False)
class CuttingModel:
    """Everything a run needs, prepared once per cut and posture.

    Attributes
    ----------
    spindle_rpm : float [rev/min]
    flutes : int
    steps_per_rev : int
        Rotation steps per revolution (a multiple of the flutes).
    dt_s : float [s]
        Step.
    system : ModalSystem
        The dynamics, tool modes carried to the posture's axis.
    normal : ndarray, shape (3,) [-]
        Outward surface normal at the contact (workpiece frame).
    fz_mm : float [mm]
        Feed per tooth.
    table : tuple of ndarray
        The engagement table of the kernel (``ptr, pos, edge, h0, nrm, f0, f1``).
    n_edges : int
        Micro edges per flute.
    step_map : tuple of ndarray
        ``(phi_d (nm, 2, 2), gam_d (nm, 2))``: the modes' exact step map.
    generating : ndarray, shape (steps_per_tooth,) [-]
        Weight of each rotation sample within a tooth in the surface the cut
        leaves (:func:`generating_weights`; sums to 1, all zero if it cuts nothing).
    """

    spindle_rpm: float
    flutes: int
    steps_per_rev: int
    dt_s: float
    system: ModalSystem
    normal: np.ndarray
    fz_mm: float
    table: tuple
    n_edges: int
    step_map: tuple
    generating: np.ndarray

    def __post_init__(self) -> None:
        # the kernel walks two tables' entries at a sample side by side
        # (sim._kernels._leave): they must ascend by (position, edge) within each sample
        ptr, pos, edge = self.table[:3]
        if pos.size > 1:
            start = np.zeros(pos.size, bool)
            inner = ptr[1:-1]
            start[inner[inner < pos.size]] = True
            key = pos * self.n_edges + edge
            bad = np.flatnonzero((np.diff(key) <= 0) & ~start[1:])
            if bad.size:
                i = int(np.searchsorted(ptr, bad[0] + 1, side="right") - 1)
                raise ValueError(f"table: the entries at rotation sample {i} are not in "
                                 f"ascending (position, edge) order, which the kernel walks "
                                 f"(sim.cutting.prepare_cut orders them)")

    @property
    def steps_per_tooth(self) -> int:
        return self.steps_per_rev // self.flutes

    @property
    def tooth_period_s(self) -> float:
        return tooth_period(self.spindle_rpm, self.flutes)
