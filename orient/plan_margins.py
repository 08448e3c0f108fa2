"""The candidates' process gains and zero-order margins for the planner
(:func:`orient.plan.plan`, step 3), in one process or in chunks of cutter locations on a
Dask cluster (the same functions: the same result); the exact margins of the chosen
postures (the choice needs only ``min(margin, target)``); the spindle speed from the
lobes at a sample of the cutter locations.

The grid postures' gains are computed once per local cut and turned into each cutter
location's frame (:mod:`orient.grid_gains`). The margins of cutter locations sharing one
modal system (a rigid workpiece: the tool's modes alone) are computed in one call
(over numba's threads when there are many); a cutter location with its own system (a
thin wall's modes at the contact) in the calling thread
(:data:`orient.constants.ZOA_PARALLEL_MIN_POSTURES`).
"""

from __future__ import annotations

import numpy as np

from .contacts import Contacts
from .dynamics import ModalSystem
from .gain import process_gain_batch
from .grid_gains import share_grid_gains
from .stability import zoa_margin_batch
from .workpiece import WorkpieceModel

__all__ = ["DASK_CHUNK_POINTS", "DASK_SPEED_ROWS", "MARGIN_CALL_POSTURES", "SPEED_SAMPLE_POINTS",
           "candidate_grid"]

#: Cutter locations (spread along the path) on which a spindle speed is chosen [-].
SPEED_SAMPLE_POINTS = 24
#: Cutter locations per Dask task when planning on a cluster [-].
DASK_CHUNK_POINTS = 256
#: Sampled cutter locations per Dask task of the speed choice [-]: small tasks (about
#: 0.4 s each on the bundled thin wall), so that a worker busy elsewhere (the job's
#: warm-up) holds up none for long: the idle worker takes them.
DASK_SPEED_ROWS = 4
#: Postures per call of the zero-order margins of cutter locations sharing a system
#: [-]: their gains and mode directions are copied for the call (about 0.3 kB a
#: posture with the tool's four modes), so the whole mold core's 1.8 million postures
#: would take some 600 MB at once; this many keep it near 20 MB and both threads busy.
MARGIN_CALL_POSTURES = 65536


def candidate_grid(options) -> tuple[np.ndarray, np.ndarray]:
    """Lead and tilt values of the search grid [rad], shapes (nl,), (nt,)."""
    nl, nt = options.grid
    lead = np.linspace(*options.lead_range_rad, nl) if nl > 1 else np.zeros(1)
    tilt = np.linspace(*options.tilt_range_rad, nt) if nt > 1 else np.zeros(1)
    return lead, tilt


def _grid_postures(options) -> tuple[np.ndarray, np.ndarray]:
    """Lead and tilt [rad] of each grid posture, in the candidates' column order (the
    grid's lead-major raveling), shapes (nl * nt,)."""
    lead, tilt = candidate_grid(options)
    L, T = np.meshgrid(lead, tilt, indexing="ij")
    return L.ravel(), T.ravel()

def _gains_rows(tool, coeffs, normal: np.ndarray, feed: np.ndarray, axes: np.ndarray,
                ok: np.ndarray, cuts: list, parallel: bool = True,
                grid: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Process gain P (t, s, 3, 3) [N/m] and cut sense (t, s) of candidate axes (t, s, 3)
    where ``ok`` (0 elsewhere), at cutter locations with ``normal``, ``feed`` (t, 3);
    ``parallel``: over numba's threads (not in a Dask task: the workers are the
    parallelism there, and the threaded kernel would only add its compilation).
    ``grid``: (lead, tilt) [rad] of the first columns' postures, whose gains are then
    shared between the locations with the same local cut
    (:func:`orient.grid_gains.share_grid_gains`)."""
    t, s, _ = axes.shape
    sense = np.zeros((t, s))
    P = np.zeros((t, s, 3, 3))
    todo = ok
    if grid is not None:
        todo = ok & ~share_grid_gains(tool, coeffs, normal, feed, ok, cuts, grid, P, sense,
                                      parallel=parallel)
    pi, ps = np.nonzero(todo)
    if len(pi) == 0:
        return P, sense
    per_point = np.empty(len(cuts), dtype=object)
    per_point[:] = cuts
    gains = process_gain_batch(tool, coeffs, axes[pi, ps], normal[pi], feed[pi], per_point[pi],
                               parallel=parallel)
    sense[pi, ps] = gains.cut_sense
    P[pi, ps] = gains.P
    return P, sense


def _margins_rows(tool, wp: WorkpieceModel, tool_sys: ModalSystem, points: np.ndarray,
                  axes: np.ndarray, ok: np.ndarray, P: np.ndarray, rpm: float,
                  cap: float | None = None, systems: list | None = None,
                  progress=None, parallel: bool | None = None) -> np.ndarray:
    """ZOA margin (t, s) of candidate axes (t, s, 3) at ``rpm`` where ``ok``; inf elsewhere.

    With ``cap``, margins at or above it come back as ``cap`` (the score only
    needs ``min(margin, target)``; much faster). ``systems``, a list of length
    t, receives each cutter location's :class:`ModalSystem`. The cutter locations
    whose system is one object (the tool's alone where the workpiece is rigid) are
    computed in one call, the others one by one (the same margins either way: one
    kernel body per posture). ``parallel``: as :func:`orient.stability.zoa_margin_batch`
    (False in a Dask task: the workers are the parallelism there).
    """
    t, s, _ = axes.shape
    margin = np.full((t, s), np.inf)
    rows: dict[int, list] = {}
    for i in range(t):
        if not ok[i].any():
            continue
        system = wp.system_at(tool_sys, points[i])
        if systems is not None:
            systems[i] = system
        rows.setdefault(id(system), [system, []])[1].append(i)
    done = 0
    for system, members in rows.values():
        r_all, c_all = np.nonzero(ok[members])
        r_all = np.asarray(members)[r_all]
        for a in range(0, len(r_all), MARGIN_CALL_POSTURES):
            r, c = r_all[a:a + MARGIN_CALL_POSTURES], c_all[a:a + MARGIN_CALL_POSTURES]
            dirs = system.directions_for_axes(axes[r, c])
            margin[r, c] = zoa_margin_batch(P[r, c], system, rpm, tool.flutes,
                                            mode_directions=dirs, cap=cap, parallel=parallel)
        done += len(members)
        if progress is not None:
            progress(done, t)
    if progress is not None and done < t:
        progress(t, t)
    return margin


def _gains(scn, contacts: Contacts, idx: np.ndarray, axes: np.ndarray, ok: np.ndarray,
           cuts: list) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_gains_rows` at the touching cutter locations ``idx``."""
    return _gains_rows(scn.base.tool, scn.base.coefficients, contacts.normal[idx],
                       contacts.feed[idx], axes, ok, cuts, grid=_grid_postures(scn.options))


def _margins(scn, tool_sys: ModalSystem, wp: WorkpieceModel, contacts: Contacts,
             idx: np.ndarray, axes: np.ndarray, ok: np.ndarray, P: np.ndarray, rpm: float,
             progress=None, cap: float | None = None, systems: list | None = None
             ) -> np.ndarray:
    """:func:`_margins_rows` at the touching cutter locations ``idx``."""
    return _margins_rows(scn.base.tool, wp, tool_sys, contacts.point[idx], axes, ok, P, rpm,
                         cap, systems, progress)


def _chunk_gains_margins(tool, coeffs, wp: WorkpieceModel, tool_sys: ModalSystem,
                         points: np.ndarray, normal: np.ndarray, feed: np.ndarray,
                         axes: np.ndarray, ok: np.ndarray, cuts: list, rpm: float,
                         cap: float, cam_rpm: float | None = None,
                         grid: tuple | None = None) -> tuple:
    """Process gains, cut senses, capped margins and systems of a chunk of cutter
    locations (a Dask task; the same functions as the one-process path; ``grid`` as in
    :func:`_gains_rows`); with
    ``cam_rpm``, also the CAM posture's (the last column's) exact margin at that speed
    (None otherwise)."""
    P, sense = _gains_rows(tool, coeffs, normal, feed, axes, ok, cuts, parallel=False,
                           grid=grid)
    systems: list = [None] * axes.shape[0]
    margin = _margins_rows(tool, wp, tool_sys, points, axes, ok, P, rpm, cap, systems,
                           parallel=False)
    cam = None
    if cam_rpm is not None:
        cam = _margins_rows(tool, wp, tool_sys, points, axes, _cam_column(ok), P,
                            cam_rpm, parallel=False)[:, -1]
    return P, sense, margin, systems, cam


def _cam_column(ok: np.ndarray) -> np.ndarray:
    """Only the CAM posture (the last column) of ``ok``'s shape."""
    out = np.zeros_like(ok)
    out[:, -1] = True
    return out


def _dask_gains_margins(client, scn, wp, tool_sys, contacts, idx, axes, ok, cuts, rpm, cap,
                        chunk: int = DASK_CHUNK_POINTS, wp_f=None,
                        cam_rpm: float | None = None) -> tuple:
    """:func:`_chunk_gains_margins` over chunks of cutter locations on a Dask cluster;
    the workpiece model is scattered once (``wp_f``: already scattered); results are put
    back in order. Returns P, sense, margin, systems and the CAM margins (None without
    ``cam_rpm``)."""
    t = len(idx)
    wp_f = client.scatter(wp, broadcast=True) if wp_f is None else wp_f
    tool, coeffs = scn.base.tool, scn.base.coefficients
    futures = []
    for a in range(0, t, chunk):
        b = min(a + chunk, t)
        r = idx[a:b]
        futures.append(client.submit(
            _chunk_gains_margins, tool, coeffs, wp_f, tool_sys, contacts.point[r],
            contacts.normal[r], contacts.feed[r], axes[a:b], ok[a:b], cuts[a:b], rpm, cap,
            cam_rpm, _grid_postures(scn.options), pure=False))
    parts = client.gather(futures)
    P = np.concatenate([p[0] for p in parts])
    sense = np.concatenate([p[1] for p in parts])
    margin = np.concatenate([p[2] for p in parts])
    systems = [sys_ for p in parts for sys_ in p[3]]
    cam = None if cam_rpm is None else np.concatenate([p[4] for p in parts])
    return P, sense, margin, systems, cam


def _uncap(scn, systems: list, axes: np.ndarray, P: np.ndarray, rpm: float,
           margin: np.ndarray, cols: np.ndarray, cap: float, client=None,
           chunk: int = DASK_CHUNK_POINTS) -> None:
    """Exact margins, in place, of the postures ``margin[r, cols[r, :]]`` found capped
    (with ``client``: chunks of rows on its workers, the same function)."""
    flutes = scn.base.tool.flutes
    wanted = []
    for r in range(margin.shape[0]):
        c = np.unique(cols[r])
        c = c[margin[r, c] >= cap]
        if len(c) and systems[r] is not None:
            wanted.append((r, c))
    if client is None or len(wanted) < 2:
        parts = [_uncap_rows(flutes, rpm, [(systems[r], axes[r, c], P[r, c])
                                           for r, c in wanted])]
    else:
        futures = [client.submit(_uncap_rows, flutes, rpm,
                                 [(systems[r], axes[r, c], P[r, c]) for r, c in
                                  wanted[a:a + chunk]], False, pure=False)
                   for a in range(0, len(wanted), chunk)]
        parts = client.gather(futures)
    for (r, c), m in zip(wanted, (m for p in parts for m in p), strict=True):
        margin[r, c] = m


def _uncap_rows(flutes: int, rpm: float, rows: list, parallel: bool | None = None) -> list:
    """Exact ZOA margins of ``rows``: (system, axes (k, 3), P (k, 3, 3)) each;
    ``parallel`` as in :func:`_speed_rows`."""
    return [zoa_margin_batch(P_, sys_r, rpm, flutes,
                             mode_directions=sys_r.directions_for_axes(ax), parallel=parallel)
            for sys_r, ax, P_ in rows]


def _choose_speed(scn, tool_sys, wp, contacts, idx, axes, ok, P, rpm0: float,
                  client=None, wp_f=None) -> float:
    """Spindle speed from the lobes: the speed of ``[orient.spindle]``'s range whose
    worst sampled cutter location has the best reachable (capped) margin; ties go to
    the speed nearest the programmed one. With ``client``, the sampled cutter locations
    are shared among its workers (``wp_f``: the workpiece model scattered)."""
    sp = scn.options.spindle
    speeds = np.linspace(*sp.range_rpm, sp.steps)
    rows = np.unique(np.linspace(0, len(idx) - 1, min(SPEED_SAMPLE_POINTS, len(idx)))
                     .astype(int))
    rows = [r for r in rows if ok[r].any()]
    target = scn.options.margin_target
    args = [(contacts.point[idx[r]], axes[r, ok[r]], P[r, ok[r]]) for r in rows]
    flutes = scn.base.tool.flutes
    if client is None:
        bests = _speed_rows(wp, tool_sys, speeds, flutes, target, args)
    else:
        wp_f = client.scatter(wp, broadcast=True) if wp_f is None else wp_f
        futures = [client.submit(_speed_rows, wp_f, tool_sys, speeds, flutes, target,
                                 args[a:a + DASK_SPEED_ROWS], False, pure=False)
                   for a in range(0, len(args), DASK_SPEED_ROWS)]
        bests = [x for part in client.gather(futures) for x in part]
    score = np.full(len(speeds), np.inf)
    for best in bests:
        score = np.minimum(score, best)
    top = np.flatnonzero(score >= score.max() - 1e-9)
    return float(speeds[top[np.argmin(np.abs(speeds[top] - rpm0))]])


def _speed_rows(wp: WorkpieceModel, tool_sys: ModalSystem, speeds: np.ndarray, flutes: int,
                target: float, rows: list, parallel: bool | None = None) -> list:
    """Per sampled cutter location (point, feasible axes (k, 3), their P (k, 3, 3)): the
    best capped margin of its postures at each of ``speeds`` (a Dask task or not). The
    margins are computed capped at ``target`` (exact below it, to the phase crossing's
    tolerance): the choice needs no more, and uncapped they took the most of the speed
    choice's time (each posture's eigenvalues over the whole frequency grid).
    ``parallel``: as :func:`orient.stability.zoa_margin_batch` (False in a Dask task: the
    workers are the parallelism there; a row's 71 speeds x its postures passed the
    threaded kernel's threshold, and the job's warm-up compiled that kernel for it)."""
    out = []
    for point, ax, P_ in rows:
        system = wp.system_at(tool_sys, point)
        dirs = system.directions_for_axes(ax)
        k = len(ax)
        m = zoa_margin_batch(np.tile(P_, (len(speeds), 1, 1)), system,
                             np.repeat(speeds, k), flutes,
                             mode_directions=np.tile(dirs, (len(speeds), 1, 1)), cap=target,
                             parallel=parallel)
        out.append(np.minimum(m.reshape(len(speeds), k), target).max(axis=1))
    return out
