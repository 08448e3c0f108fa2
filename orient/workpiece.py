"""The workpiece's modes at each cutting point, from a planning scenario's ``[workpiece]``.

* rigid: no modes;
* ``[[workpiece.modes]]``: the same modes (with their directions) everywhere;
* ``[workpiece.thin_wall]``: a finite-element model of the wall in its
  in-process shape (:mod:`orient.workpiece_fem`). Finishing goes top-down, so
  when the tool cuts at height ``h`` the wall above ``h`` has its finished
  thickness and the wall below still carries the stock. The model is solved
  at a few cut levels (:data:`WALL_LEVELS`) spread over the heights the path
  cuts at; each point takes the level nearest its own height, and the
  equivalent single-DOF modes at the contact point itself along the wall
  normal (:meth:`orient.workpiece_fem.WallModes.modes_at`).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from functools import partial

import numpy as np

from .blas import limited_blas
from .dynamics import ModalSystem
from .scenario import WorkpieceSpec
from .constants import WALL_LEVEL_THREADS, WALL_LEVELS, WALL_POINT_TOL_MM

__all__ = ["WALL_LEVELS", "WorkpieceModel"]



class WorkpieceModel:
    """Workpiece modes along a path.

    Parameters
    ----------
    spec : WorkpieceSpec
    points_mm : ndarray, shape (n, 3) [mm], optional
        Contact points where the thin wall's levels are spread (their heights on
        the wall); needed for ``thin_wall``.
    client : dask.distributed.Client, optional
        Offer the thin wall's levels but the first to its workers
        (:func:`_solve_shared`); the same modes.
    """

    def __init__(self, spec: WorkpieceSpec, points_mm: np.ndarray | None = None, *,
                 client=None) -> None:
        self.spec = spec
        self.levels: list = []
        self.level_z: np.ndarray = np.zeros(0)
        if spec.kind == "thin_wall":
            self._build_wall(np.asarray(points_mm, dtype=float).reshape(-1, 3), client)

    @property
    def rigid(self) -> bool:
        return self.spec.kind == "rigid"

    def _build_wall(self, points: np.ndarray, client=None) -> None:
        from .workpiece_fem import Material, ThinWall, wall_modes

        w = self.spec.thin_wall
        wall = ThinWall(w["length_mm"], w["height_mm"], w["stock_thickness_mm"],
                        Material(w["young_GPa"], w["density_kg_m3"], w["poisson"]),
                        damping_ratio=w["damping_ratio"], origin_mm=tuple(w["origin_mm"]),
                        along=tuple(w["along"]), normal=tuple(w["normal"]),
                        finish_side="front")
        self.wall = wall
        h = wall.to_local(points)[:, 2] if len(points) else np.array([w["height_mm"]])
        h = np.clip(h, 0.0, w["height_mm"])
        lo, hi = float(h.min()), float(h.max())
        z = np.linspace(hi, lo, WALL_LEVELS) if hi > lo else np.array([hi])
        self.level_z = z
        shapes = [wall.in_process(float(cut_z), w["thickness_mm"])
                  if w["stock_thickness_mm"] > w["thickness_mm"] and cut_z < w["height_mm"]
                  else wall for cut_z in z]
        # the levels are independent and their time is in SuperLU and ARPACK, which
        # release the GIL: WALL_LEVEL_THREADS threads could solve them side by side (under
        # one BLAS limit, set here for all of them: orient.blas); one keeps a single
        # factorization in memory at a time
        solve = partial(wall_modes, n_modes=w["modes"], elements=w["element_mm"])
        if client is not None and len(shapes) > 1:
            self.levels = _solve_shared(client, solve, shapes)
            return
        threads = max(1, min(len(shapes), WALL_LEVEL_THREADS, os.cpu_count() or 1))
        with limited_blas(), ThreadPoolExecutor(max_workers=threads) as pool:
            self.levels = list(pool.map(solve, shapes))

    def _level(self, p: np.ndarray) -> int:
        """The solved in-process level nearest the point's height on the wall."""
        h = float(self.wall.to_local(p)[2])
        return int(np.argmin(np.abs(self.level_z - h)))

    def modes_at(self, point_mm: np.ndarray) -> list:
        """``[(Mode, direction)]`` of the workpiece at a contact point (empty: rigid)."""
        if self.spec.kind == "rigid":
            return []
        if self.spec.kind == "modes":
            return list(self.spec.modes)
        p = np.asarray(point_mm, dtype=float)
        k = self._level(p)
        # along the wall normal: the flexible direction (a thin wall's modes move the
        # cutting point along it to within a few degrees); one direction keeps the
        # stability analysis at tool (2) + wall (1) directions
        return self.levels[k].modes_at(p, direction=np.asarray(self.wall.normal),
                                       tol_mm=WALL_POINT_TOL_MM)

    def shape_at(self, point_mm: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
        """The workpiece modes of :meth:`modes_at` by name, for carrying a vibration
        from point to point: ``(level, index, amp)`` -- the level (-1: none), each
        mode's number and its signed displacement at the point along the
        direction (1 for point-independent modes)."""
        if self.spec.kind == "rigid":
            return -1, np.zeros(0, dtype=np.int64), np.zeros(0)
        if self.spec.kind == "modes":
            n = len(self.spec.modes)
            return 0, np.arange(n), np.ones(n)
        p = np.asarray(point_mm, dtype=float)
        k = self._level(p)
        idx, amp = self.levels[k].shape_along(p, np.asarray(self.wall.normal),
                                              tol_mm=WALL_POINT_TOL_MM)
        return k, idx, amp

    def system_at(self, tool: ModalSystem, point_mm: np.ndarray) -> ModalSystem:
        """Tool modes plus the workpiece's modes at ``point_mm``."""
        modes = self.modes_at(point_mm)
        if not modes:
            return tool
        return ModalSystem.combine(tool, ModalSystem.from_modes(modes, source="workpiece"))

    def first_frequencies_hz(self) -> list[float]:
        """First natural frequency of each solved level [Hz] (thin wall only)."""
        return [float(m.frequencies_hz[0]) for m in self.levels]


def _solve_shared(client, solve, shapes: list) -> list:
    """``[solve(shape) for shape in shapes]``, the first here and the others offered to
    the cluster's workers: each is taken from a worker that has finished it; one a worker
    is solving is waited for; one no worker has started by the time this process would
    start it is withdrawn and solved here (the last of those first: a worker that gets
    free takes the earlier ones).

    In the main job the workers are idle while the planner builds the model once the
    kernels are cached (the bundled thin wall's three levels: about 7-8 s in one
    process), but one of them waits for the job's warm-up child at first, and every
    process shares the two cores: a level still being solved on a worker when this
    process finished its own was solved here again (the plan's set-up 8.6 s instead of
    about 5 s). On an empty cache the workers are busy compiling: then this process
    solves every level, as it did alone. (A withdrawn level a worker starts just before
    the withdrawal reaches it is solved there too, and dropped.) Where the workers cannot
    say what they run, every level not finished is treated as not started.
    """
    from distributed import wait

    offered = [client.submit(solve, shape, pure=False) for shape in shapes[1:]]
    levels: list = [None] * len(shapes)
    with limited_blas():
        levels[0] = solve(shapes[0])
        left = list(range(1, len(shapes)))
        while left:
            for q in list(left):
                future = offered[q - 1]
                if future.done():
                    left.remove(q)
                    levels[q] = (future.result() if future.status == "finished"
                                 else solve(shapes[q]))
            if not left:
                break
            running = _running_keys(client)
            waiting = [q for q in left if offered[q - 1].key not in running]
            if waiting:
                q = waiting[-1]
                offered[q - 1].cancel()
                left.remove(q)
                levels[q] = solve(shapes[q])
            else:
                wait([offered[q - 1] for q in left], return_when="FIRST_COMPLETED")
    return levels


def _executing_keys(dask_worker=None) -> list:
    """The keys of the tasks a Dask worker is running now (``client.run`` passes the
    worker)."""
    return [ts.key for ts in dask_worker.state.executing]


def _running_keys(client) -> set:
    """The keys of the tasks the cluster's workers are running now (empty where they
    cannot say)."""
    try:
        per_worker = client.run(_executing_keys)
    except Exception:                       # noqa: BLE001 -- only time depends on it
        return set()
    return {k for keys in per_worker.values() for k in keys}
