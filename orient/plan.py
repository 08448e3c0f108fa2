"""CAM-side planning of lead and tilt per cutter location (method.md §7, "Planning").

For each cutter location of the CAM program where the ball touches the design:

1. the contact point and surface normal (:mod:`orient.contacts`); the ball
   centre stays where CAM put it, so the finished surface does not change;
2. candidate postures: a lead x tilt grid around the normal, plus the CAM's
   own posture; dropped where the inclination leaves
   ``[min_inclination, max_inclination]`` or the machine cannot reach the
   axis within its limits;
3. the process gain of every candidate (:func:`orient.gain.process_gain_batch`,
   the local cut: depth and pick feed times the safety factor) and its
   zero-order stability margin at the spindle speed against the tool's modes
   (carried with the axis) plus the workpiece's modes at the contact point
   (:func:`orient.stability.zoa_margin_batch`);
4. a smooth sequence (:func:`orient.smoothing.best_smooth_path`) maximizing
   the margin capped at ``margin_target`` (postures above it are equally
   good; ties go to the one nearest the CAM's), with the axis turning at most
   ``max_rate`` per mm;
5. interference: the chosen postures are checked with FCL (shank and holder
   against the stock, the flute part above the ball against the design);
   colliding ones are removed from the candidates and step 4 repeats;
6. the time-periodic (full-discretization) margin of the planned posture at
   the points with the lowest zero-order margin, where the average can be
   wrong for intermittent ball-end cuts.

With ``[orient.spindle]`` the spindle speed is first chosen from the lobes
(zero-order, at a sample of the cutter locations, each at its best posture)
and the feed scaled to keep the feed per tooth.

Points where the ball does not touch the design (air moves inside a pass)
take the posture of the nearest touching point of their pass; rapid moves
break the smoothness limit (the rotary axes move during the rapid).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from nc.path import CutterLocations, cutter_locations

from .contacts import Contacts, ball_contacts
from .dynamics import ModalSystem
from .engagement import LocalCut
from .gain import process_gain, process_gain_batch
from .geometry import inclination, lead_tilt_of, local_frame, posture_axis
from .interference import InterferenceChecker, ToolAssembly
from .scenario import PlanScenario
from .smoothing import best_smooth_path
from .stability import sdm_margin, zoa_margin_batch
from .workpiece import WorkpieceModel

__all__ = ["SDM_CHECK_POINTS", "PlanResult", "candidate_grid", "local_cuts", "plan", "stock_mesh"]

#: Points (those with the lowest planned zero-order margin) at which the
#: time-periodic margin of the planned posture is computed [-].
SDM_CHECK_POINTS = 6
#: Score preference for the CAM posture among equally good ones, per radian
#: of axis change [-/rad] (small against any margin difference).
CAM_PREFERENCE_PER_RAD = 1.0e-3
#: Cutter locations (spread along the path) on which a spindle speed is chosen [-].
SPEED_SAMPLE_POINTS = 24
#: Cutter locations per Dask task when planning on a cluster [-].
DASK_CHUNK_POINTS = 256
#: A previous pass counts if an earlier contact lies within this fraction of the
#: pick feed of where it should be [-].
FIRST_PASS_TOLERANCE = 0.5
#: Rounds of "choose, check interference, drop colliding postures" [-].
MAX_INTERFERENCE_ROUNDS = 12


@dataclass(frozen=True, eq=False)
class PlanResult:
    """A planned path and why each posture was chosen.

    Arrays have one entry per cutter location of the CAM path (``n``).
    """

    cl: CutterLocations
    cam: CutterLocations
    contacts: Contacts
    lead_rad: np.ndarray
    tilt_rad: np.ndarray
    cam_lead_rad: np.ndarray
    cam_tilt_rad: np.ndarray
    margin: np.ndarray
    cam_margin: np.ndarray
    cut_sense: np.ndarray
    cam_cut_sense: np.ndarray
    cam_feasible: np.ndarray
    reason: tuple[str, ...]
    spindle_rpm: float
    machine: object
    grid_lead_rad: np.ndarray
    grid_tilt_rad: np.ndarray
    sdm_checks: list = field(default_factory=list)
    stats: dict = field(default_factory=dict)
    #: margin (capped at ``margin_target``: values equal to it mean "at least") and
    #: feasibility over the grid at the touching points, (t, nl, nt)
    grid_margin: np.ndarray | None = None
    grid_feasible: np.ndarray | None = None
    touching_index: np.ndarray | None = None
    #: the workpiece's modes along the touching points, as the margins used them
    #: (its finite elements take seconds: later stages reuse it)
    workpiece: WorkpieceModel | None = None


def candidate_grid(options) -> tuple[np.ndarray, np.ndarray]:
    """Lead and tilt values of the search grid [rad], shapes (nl,), (nt,)."""
    nl, nt = options.grid
    lead = np.linspace(*options.lead_range_rad, nl) if nl > 1 else np.zeros(1)
    tilt = np.linspace(*options.tilt_range_rad, nt) if nt > 1 else np.zeros(1)
    return lead, tilt


def _reachable(machine, tips: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """True where some inverse solution of the machine is inside its limits."""
    s0, s1 = machine.inverse(tips.reshape(-1, 3), axes.reshape(-1, 3))
    ok = machine.within_limits(s0) | machine.within_limits(s1)
    return ok.reshape(tips.shape[:-1])


def local_cuts(scn: PlanScenario, contacts: Contacts, idx: np.ndarray, cam: CutterLocations,
               spindle_rpm: float) -> list[LocalCut]:
    """The local cut (depth and pick feed times the safety factor, side of the previous
    pass, feed per tooth at ``spindle_rpm`` [rev/min]) at cutter locations ``idx``.

    The previous pass lies on the ``machined_side``, where an earlier cutter location
    of ``idx`` touched within a pick feed (``FIRST_PASS_TOLERANCE`` of it); where none
    did (the first pass of a face), nothing is removed beside the tool and the ball
    cuts on both sides (``previous_side = 0``).
    """
    opt = scn.options
    cut = opt.cut
    _, b, _ = local_frame(contacts.normal[idx], contacts.feed[idx])
    side = np.sign(b @ cut.machined_side)
    side[np.abs(b @ cut.machined_side) < 1e-6] = 0.0
    side[~_previous_pass_cut(contacts.point[idx], b * side[:, None], cut.pick_mm)] = 0.0
    fz = cam.feed_mm_min[idx] / (spindle_rpm * scn.base.tool.flutes)
    return [LocalCut(cut.depth_mm * opt.safety_factor, cut.pick_mm * opt.safety_factor,
                     int(s), float(z)) for s, z in zip(side, fz)]


def _previous_pass_cut(points: np.ndarray, toward: np.ndarray, pick_mm: float) -> np.ndarray:
    """True where an earlier point lies about one pick feed along ``toward`` (unit or
    zero vectors, (n, 3)) from each of ``points`` (n, 3) [mm], in path order."""
    from scipy.spatial import cKDTree

    if len(points) == 0 or pick_mm <= 0:
        return np.zeros(len(points), bool)
    tol = FIRST_PASS_TOLERANCE * pick_mm
    tree = cKDTree(points)
    out = np.zeros(len(points), bool)
    for k, near in enumerate(tree.query_ball_point(points + pick_mm * toward, tol)):
        out[k] = bool(near) and min(near) < k and np.any(toward[k])
    return out


def _gains_rows(tool, coeffs, normal: np.ndarray, feed: np.ndarray, axes: np.ndarray,
                ok: np.ndarray, cuts: list, parallel: bool = True
                ) -> tuple[np.ndarray, np.ndarray]:
    """Process gain P (t, s, 3, 3) [N/m] and cut sense (t, s) of candidate axes (t, s, 3)
    where ``ok`` (0 elsewhere), at cutter locations with ``normal``, ``feed`` (t, 3);
    ``parallel``: over numba's threads (not in a Dask task: the workers are the
    parallelism there, and the threaded kernel would only add its compilation)."""
    t, s, _ = axes.shape
    sense = np.zeros((t, s))
    P = np.zeros((t, s, 3, 3))
    pi, ps = np.nonzero(ok)
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
                  progress=None) -> np.ndarray:
    """ZOA margin (t, s) of candidate axes (t, s, 3) at ``rpm`` where ``ok``; inf elsewhere.

    With ``cap``, margins at or above it come back as ``cap`` (the score only
    needs ``min(margin, target)``; much faster). ``systems``, a list of length
    t, receives each cutter location's :class:`ModalSystem`.
    """
    t, s, _ = axes.shape
    margin = np.full((t, s), np.inf)
    for i in range(t):
        sel = np.flatnonzero(ok[i])
        if len(sel) == 0:
            continue
        system = wp.system_at(tool_sys, points[i])
        if systems is not None:
            systems[i] = system
        dirs = system.directions_for_axes(axes[i, sel])
        margin[i, sel] = zoa_margin_batch(P[i, sel], system, rpm, tool.flutes,
                                          mode_directions=dirs, cap=cap)
        if progress is not None:
            progress(i + 1, t)
    return margin


def _gains(scn, contacts: Contacts, idx: np.ndarray, axes: np.ndarray, ok: np.ndarray,
           cuts: list) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_gains_rows` at the touching cutter locations ``idx``."""
    return _gains_rows(scn.base.tool, scn.base.coefficients, contacts.normal[idx],
                       contacts.feed[idx], axes, ok, cuts)


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
                         cap: float) -> tuple:
    """Process gains, cut senses, capped margins and systems of a chunk of cutter
    locations (a Dask task; the same functions as the one-process path)."""
    P, sense = _gains_rows(tool, coeffs, normal, feed, axes, ok, cuts, parallel=False)
    systems: list = [None] * axes.shape[0]
    margin = _margins_rows(tool, wp, tool_sys, points, axes, ok, P, rpm, cap, systems)
    return P, sense, margin, systems


def _dask_gains_margins(client, scn, wp, tool_sys, contacts, idx, axes, ok, cuts, rpm, cap,
                        chunk: int = DASK_CHUNK_POINTS) -> tuple:
    """:func:`_chunk_gains_margins` over chunks of cutter locations on a Dask cluster;
    the workpiece model is scattered once; results are put back in order."""
    t = len(idx)
    wp_f = client.scatter(wp, broadcast=True)
    tool, coeffs = scn.base.tool, scn.base.coefficients
    futures = []
    for a in range(0, t, chunk):
        b = min(a + chunk, t)
        r = idx[a:b]
        futures.append(client.submit(
            _chunk_gains_margins, tool, coeffs, wp_f, tool_sys, contacts.point[r],
            contacts.normal[r], contacts.feed[r], axes[a:b], ok[a:b], cuts[a:b], rpm, cap,
            pure=False))
    parts = client.gather(futures)
    P = np.concatenate([p[0] for p in parts])
    sense = np.concatenate([p[1] for p in parts])
    margin = np.concatenate([p[2] for p in parts])
    systems = [sys_ for p in parts for sys_ in p[3]]
    return P, sense, margin, systems


def _uncap(scn, systems: list, axes: np.ndarray, P: np.ndarray, rpm: float,
           margin: np.ndarray, cols: np.ndarray, cap: float) -> None:
    """Exact margins, in place, of the postures ``margin[r, cols[r, :]]`` found capped."""
    flutes = scn.base.tool.flutes
    for r in range(margin.shape[0]):
        c = np.unique(cols[r])
        c = c[margin[r, c] >= cap]
        if len(c) == 0 or systems[r] is None:
            continue
        sys_r = systems[r]
        margin[r, c] = zoa_margin_batch(P[r, c], sys_r, rpm, flutes,
                                        mode_directions=sys_r.directions_for_axes(axes[r, c]))


def _choose_speed(scn, tool_sys, wp, contacts, idx, axes, ok, P, rpm0: float) -> float:
    """Spindle speed from the lobes: the speed of ``[orient.spindle]``'s range whose
    worst sampled cutter location has the best reachable (capped) margin; ties go to
    the speed nearest the programmed one."""
    sp = scn.options.spindle
    speeds = np.linspace(*sp.range_rpm, sp.steps)
    rows = np.unique(np.linspace(0, len(idx) - 1, min(SPEED_SAMPLE_POINTS, len(idx)))
                     .astype(int))
    target = scn.options.margin_target
    score = np.full(len(speeds), np.inf)
    for r in rows:
        sel = np.flatnonzero(ok[r])
        if len(sel) == 0:
            continue
        system = wp.system_at(tool_sys, contacts.point[idx[r]])
        dirs = system.directions_for_axes(axes[r, sel])
        k = len(sel)
        m = zoa_margin_batch(np.tile(P[r, sel], (len(speeds), 1, 1)), system,
                             np.repeat(speeds, k), scn.base.tool.flutes,
                             mode_directions=np.tile(dirs, (len(speeds), 1, 1)))
        best = np.minimum(m.reshape(len(speeds), k), target).max(axis=1)
        score = np.minimum(score, best)
    top = np.flatnonzero(score >= score.max() - 1e-9)
    return float(speeds[top[np.argmin(np.abs(speeds[top] - rpm0))]])


def plan(scn: PlanScenario, *, machine=None, spindle_rpm: float | None = None,
         progress=None, client=None) -> PlanResult:
    """Plan lead and tilt along the scenario's CAM program.

    Parameters
    ----------
    scn : PlanScenario
    machine : nc Machine or str, optional
        Default: the scenario's ``program.machine``.
    spindle_rpm : float, optional [rev/min]
        Plan at this speed (default: the program's).
    progress : callable, optional
        ``progress(stage: str, done: int, total: int)``.
    client : dask.distributed.Client, optional
        Compute the process gains and margins on its workers, chunks of cutter
        locations at a time (the result is the same as in one process).

    Returns
    -------
    PlanResult
    """
    t0 = time.perf_counter()
    opt = scn.options
    tool = scn.base.tool
    R = tool.radius_mm
    machine = scn.machine(machine)
    program = scn.base.read_program()
    cam = cutter_locations(program, machine)
    design = scn.base.stock.load_design()
    contacts = ball_contacts(cam, R, design)
    feed_pts = ~cam.rapid
    rpm = float(spindle_rpm) if spindle_rpm else float(np.max(cam.spindle_rpm))
    if not rpm > 0:
        raise ValueError(f"{scn.base.program_path}: no spindle speed in the program (S word)")
    idx = np.flatnonzero(contacts.touching)
    if len(idx) == 0:
        raise ValueError(f"{scn.base.program_path}: the ball never touches the design surface "
                         f"{scn.base.stock.design_path}; nothing to plan")
    lead_g, tilt_g = candidate_grid(opt)
    nl, nt = len(lead_g), len(tilt_g)
    Lg, Tg = np.meshgrid(lead_g, tilt_g, indexing="ij")
    normal, feed = contacts.normal[idx], contacts.feed[idx]
    grid_axes = posture_axis(normal[:, None, :], feed[:, None, :], Lg.ravel()[None, :],
                             Tg.ravel()[None, :])                        # (t, S, 3)
    cam_lead, cam_tilt = (np.full(len(cam), np.nan), np.full(len(cam), np.nan))
    cl_, ct_ = lead_tilt_of(cam.axis[idx], normal, feed)
    cam_lead[idx], cam_tilt[idx] = cl_, ct_
    axes = np.concatenate([grid_axes, cam.axis[idx][:, None, :]], axis=1)   # (t, S+1, 3)
    S1 = axes.shape[1]
    centres = contacts.centre[idx][:, None, :]
    tips = centres - R * axes
    incl = inclination(axes, normal[:, None, :])
    ok = (incl >= opt.min_inclination_rad - 1e-9) & (incl <= opt.max_inclination_rad + 1e-9)
    ok &= _reachable(machine, tips, axes)
    cam_ok = ok[:, -1].copy()
    ok[:, -1] = True            # the CAM posture is always evaluated (for the report)
    t1 = time.perf_counter()
    cuts = local_cuts(scn, contacts, idx, cam, rpm)
    choose_speed = opt.spindle is not None and spindle_rpm is None
    if client is not None and choose_speed:
        # the speed's sample of gains on a worker, which compiles the gain kernel (and
        # caches it for the others) while this process builds the workpiece model
        rows_s = np.unique(np.linspace(0, len(idx) - 1, min(SPEED_SAMPLE_POINTS, len(idx)))
                           .astype(int))
        sample_f = client.submit(_gains_rows, tool, scn.base.coefficients,
                                 contacts.normal[idx[rows_s]], contacts.feed[idx[rows_s]],
                                 axes[rows_s], ok[rows_s], [cuts[r] for r in rows_s], False,
                                 pure=False)
    tool_sys = ModalSystem.tool(scn.base.compliance)
    wp = WorkpieceModel(scn.workpiece, contacts.point[idx])
    t2 = time.perf_counter()
    rpm_program = rpm
    cap = opt.margin_target
    if client is not None:
        if choose_speed:
            P_s = np.zeros(axes.shape[:2] + (3, 3))
            P_s[rows_s] = sample_f.result()[0]
            rpm = _choose_speed(scn, tool_sys, wp, contacts, idx, axes, ok, P_s, rpm)
        P, sense, margin, systems = _dask_gains_margins(client, scn, wp, tool_sys, contacts,
                                                        idx, axes, ok, cuts, rpm, cap)
    else:
        P, sense = _gains(scn, contacts, idx, axes, ok, cuts)
        if choose_speed:
            rpm = _choose_speed(scn, tool_sys, wp, contacts, idx, axes, ok, P, rpm)
        systems = [None] * len(idx)
        margin = _margins(scn, tool_sys, wp, contacts, idx, axes, ok, P, rpm,
                          None if progress is None else (lambda d, n: progress("margins", d, n)),
                          cap=cap, systems=systems)
    if rpm != rpm_program:        # the CAM's posture at the CAM's speed, for the report
        cam_col = np.zeros_like(ok)
        cam_col[:, -1] = True
        margin[:, -1] = _margins(scn, tool_sys, wp, contacts, idx, axes, cam_col, P,
                                 rpm_program)[:, -1]
    ok[:, -1] = cam_ok
    t3 = time.perf_counter()
    # --- choose: smooth, then interference, repeated -------------------------
    checker = InterferenceChecker(stock_mesh(scn, design), ToolAssembly.from_tool(
        tool, clearance_mm=opt.clearance_mm), design_mesh=design,
        gouge_tol_mm=opt.gouge_tol_mm)
    cam_interf = checker.check(cam.tip[idx], cam.axis[idx])
    cam_ok &= ~cam_interf.collides & ~cam_interf.gouges
    ok[:, -1] = cam_ok
    pref = CAM_PREFERENCE_PER_RAD * np.arccos(np.clip(np.sum(axes * cam.axis[idx][:, None, :],
                                                             axis=-1), -1, 1))
    base_score = np.minimum(margin, opt.margin_target) - pref
    dropped = 0
    choice = None
    run_id = np.cumsum(cam.rapid)[idx]                 # passes: rapids separate them
    breaks = np.zeros(len(idx), bool)
    breaks[1:] = run_id[1:] != run_id[:-1]
    step = np.zeros(len(idx))
    step[1:] = np.linalg.norm(np.diff(cam.tip[idx], axis=0), axis=1)
    for _round in range(MAX_INTERFERENCE_ROUNDS):
        score = np.where(ok, base_score, -np.inf)
        none = ~ok.any(axis=1)
        score[none, -1] = -1e6                         # nothing feasible: CAM posture, flagged
        choice = best_smooth_path(score, axes, step, opt.max_rate_rad_per_mm, breaks)
        rows = np.arange(len(idx))
        res = checker.check(tips[rows, choice], axes[rows, choice])
        bad = (res.collides | res.gouges) & ~none
        if not bad.any():
            break
        ok[rows[bad], choice[bad]] = False
        dropped += int(bad.sum())
    rows = np.arange(len(idx))
    # the score needed only min(margin, target): the chosen and the CAM postures'
    # margins are made exact again for the report
    cam_col = np.full(len(idx), S1 - 1) if rpm == rpm_program else choice
    _uncap(scn, systems, axes, P, rpm, margin, np.stack([choice, cam_col], axis=1), cap)
    t4 = time.perf_counter()
    u_new = axes[rows, choice]
    n_all = len(cam)
    lead = np.full(n_all, np.nan)
    tilt = np.full(n_all, np.nan)
    ln, tn = lead_tilt_of(u_new, normal, feed)
    lead[idx], tilt[idx] = ln, tn
    m_all = np.full(n_all, np.inf)
    mc_all = np.full(n_all, np.inf)
    m_all[idx] = margin[rows, choice]
    mc_all[idx] = margin[:, -1]
    cs = np.zeros(n_all)
    csc = np.zeros(n_all)
    cs[idx], csc[idx] = sense[rows, choice], sense[:, -1]
    cam_feasible = np.ones(n_all, bool)
    cam_feasible[idx] = cam_ok
    new_tip, new_axis = _place_all(cam, contacts, idx, u_new, R)
    # a changed spindle speed keeps the feed per tooth: the feed scales with it
    planned = CutterLocations(new_tip, new_axis, cam.feed_mm_min * (rpm / rpm_program),
                              np.full(n_all, rpm), cam.block, cam.rapid)
    final = checker.check(planned.tip[feed_pts], planned.axis[feed_pts])
    reasons = _reasons(cam, contacts, idx, choice, S1, ok, margin, sense, lead, tilt,
                       cam_lead, cam_tilt, opt.margin_target, cam_ok)
    checks = _sdm_checks(scn, tool_sys, wp, contacts, idx, u_new, cuts, rpm,
                         m_all[idx], run_id) if opt.verify_sdm else []
    t5 = time.perf_counter()
    nlg = nl * nt
    return PlanResult(
        cl=planned, cam=cam, contacts=contacts, lead_rad=lead, tilt_rad=tilt,
        cam_lead_rad=cam_lead, cam_tilt_rad=cam_tilt, margin=m_all, cam_margin=mc_all,
        cut_sense=cs, cam_cut_sense=csc, cam_feasible=cam_feasible, reason=tuple(reasons),
        spindle_rpm=rpm, machine=machine, grid_lead_rad=lead_g, grid_tilt_rad=tilt_g,
        sdm_checks=checks,
        stats={"program_spindle_rpm": rpm_program, "points": n_all, "touching": len(idx), "postures": int(len(idx) * S1),
               "interference_dropped": dropped,
               "planned_collisions": int(np.sum(final.collides | final.gouges)),
               "wall_first_frequencies_hz": wp.first_frequencies_hz() if wp.levels else [],
               "seconds": {"candidates": t1 - t0, "setup": t2 - t1, "margins": t3 - t2,
                           "choice_and_interference": t4 - t3, "finish": t5 - t4,
                           "total": t5 - t0}},
        grid_margin=margin[:, :nlg].reshape(-1, nl, nt),
        grid_feasible=ok[:, :nlg].reshape(-1, nl, nt), touching_index=idx, workpiece=wp)


def stock_mesh(scn: PlanScenario, design: Any) -> Any:
    """The stock as a mesh (shank and holder must clear the material still standing)."""
    import trimesh

    st = scn.base.stock
    if st.kind == "stl":
        return trimesh.load(str(st.path), force="mesh")
    lo, hi = np.asarray(st.bounds[0]), np.asarray(st.bounds[1])
    return trimesh.creation.box(extents=hi - lo,
                                transform=trimesh.transformations.translation_matrix(
                                    (lo + hi) / 2))


def _place_all(cam: CutterLocations, contacts: Contacts, idx: np.ndarray, u_new: np.ndarray,
               R: float) -> tuple[np.ndarray, np.ndarray]:
    """Tips and axes of every point: touching ones about their ball centre, the others
    (air moves, approach, retract) moved with the nearest touching point of their pass."""
    n = len(cam)
    tip = cam.tip.copy()
    axis = cam.axis.copy()
    tip[idx], axis[idx] = contacts.centre[idx] - R * u_new, u_new
    run = np.cumsum(cam.rapid)          # a rapid starts a new run (it leads into a pass)
    pos = np.arange(n)
    touching = np.zeros(n, bool)
    touching[idx] = True
    for r in np.unique(run):
        members = np.flatnonzero(run == r)
        t_in = members[touching[members]]
        if len(t_in) == 0:
            continue
        others = members[~touching[members]]
        near = t_in[np.argmin(np.abs(pos[others][:, None] - t_in[None, :]), axis=1)]
        k = np.searchsorted(idx, near)
        # a point off the wall keeps its offset from the ball centre along the CAM axis
        centre_old = contacts.centre[near]
        rel = cam.tip[others] - centre_old
        along = np.sum(rel * cam.axis[near], axis=1)
        perp = rel - along[:, None] * cam.axis[near]
        tip[others] = centre_old + perp + along[:, None] * u_new[k]
        axis[others] = u_new[k]
    return tip, axis


def _reasons(cam, contacts, idx, choice, S1, ok, margin, sense, lead, tilt, cam_lead,
             cam_tilt, target, cam_ok) -> list[str]:
    n = len(cam)
    out = ["rapid move" if cam.rapid[i] else "not touching the design: posture of the "
           "nearest cutting point of the pass" for i in range(n)]
    for r, i in enumerate(idx):
        j = choice[r]
        m, mc = margin[r, j], margin[r, -1]
        where = (f"lead {math.degrees(lead[i]):+.1f} tilt {math.degrees(tilt[i]):+.1f} deg, "
                 f"{'up' if sense[r, j] > 0 else 'down'}-cut {sense[r, j]:+.2f}")
        cam_txt = (f"CAM posture (lead {math.degrees(cam_lead[i]):+.1f} tilt "
                   f"{math.degrees(cam_tilt[i]):+.1f}) margin {mc:.2f}"
                   + ("" if cam_ok[r] else ", infeasible"))
        if not ok[r].any():
            out[i] = f"no feasible posture: CAM posture kept (margin {mc:.2f})"
        elif j == S1 - 1:
            out[i] = f"CAM posture kept: margin {m:.2f} ({where})"
        elif m >= target:
            out[i] = f"margin {m:.2f} >= target {target:g} at {where}; {cam_txt}"
        else:
            out[i] = f"best smooth margin {m:.2f} at {where}; {cam_txt}"
    return out


def _sdm_checks(scn, tool_sys, wp, contacts, idx, u_new, cuts, rpm, zoa, runs
                ) -> list[dict]:
    """Time-periodic margins of the planned posture at the lowest-ZOA points."""
    from .constants import GAIN_ANGLES_PER_REV

    tool = scn.base.tool
    order = np.argsort(zoa)
    picked: list[int] = []
    for r in order:                      # the lowest point of each of the lowest passes
        if len(picked) >= SDM_CHECK_POINTS or not np.isfinite(zoa[r]):
            break
        if all(runs[r] != runs[p] for p in picked):
            picked.append(int(r))
    out = []
    for r in picked:
        i = int(idx[r])
        g = process_gain(tool, scn.base.coefficients, u_new[r], contacts.normal[i],
                         contacts.feed[i], cuts[r], spindle_rpm=rpm,
                         n_angles=GAIN_ANGLES_PER_REV)
        system = wp.system_at(tool_sys, contacts.point[i]).with_tool_axis(u_new[r])
        res = sdm_margin(g.H, system, rpm, tool.flutes)
        out.append({"point": i, "zoa_margin": float(zoa[r]), "sdm_margin": float(res.margin),
                    "kind": res.kind})
    return out

