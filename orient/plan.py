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
   against the stock, the flute part above the ball against the design),
   each together with the points that take it over (below); where one
   collides, every candidate of that point -- and, each further time its pass
   has a colliding choice, of a window around it twice as wide -- is checked
   and the colliding ones removed, and step 4 repeats. A point whose
   candidates are all infeasible is *infeasible*; the loop ends when no
   chosen posture collides, within a bound it provably stays under (the
   windows reach the ends of their pass);
6. the time-periodic (full-discretization) margin of the planned posture at
   the points with the lowest zero-order margin, where the average can be
   wrong for intermittent ball-end cuts.

With ``[orient.spindle]`` the spindle speed is first chosen from the lobes
(zero-order, at a sample of the cutter locations, each at its best posture)
and the feed scaled to keep the feed per tooth.

Points where the ball does not touch the design (air moves, the plunge) take the
posture of the nearest touching point of their pass. The rapids between two passes
keep the CAM's ball centre: up to the link's highest point with the posture of the
pass they leave (a 3-axis program's retract goes straight up without turning), after
it with the posture of the pass they enter (descending straight down in it), so the
rotary axes turn at the clearance height (:class:`orient.choice._Inherited`). Rapids
break the smoothness limit.

**Infeasible points.** The planned path is checked once more as a whole (every
feed point and every point the planner moved). Where no feasible posture
exists -- every candidate outside the inclination range or the axis limits,
or colliding at the point or at a point that takes its posture -- or the
planned path still collides, the point is listed in
:attr:`PlanResult.infeasible` with the true cause in its reason, and keeps the
CAM posture. :func:`plan` raises nothing for it: callers must look
(``python -m orient plan`` refuses to write unless a fallback is allowed).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from nc.path import CutterLocations, cutter_locations

from .contacts import Contacts, ball_contacts
from .cuts import local_cuts
from .dynamics import ModalSystem
from .gain import process_gain
from .geometry import inclination, lead_tilt_of, posture_axis
from .scenario import PlanScenario, ScenarioError
from .choice import (
    _FEASIBLE,
    _OUTSIDE_INCLINATION,
    _OUTSIDE_LIMITS,
    _AT_POLE,
    _PART,
    _cause_labels,
    _choose_collision_free,
    _Inherited,
    _inherited,
)
from .plan_margins import (
    SPEED_SAMPLE_POINTS,
    _cam_column,
    _choose_speed,
    _dask_gains_margins,
    _gains,
    _gains_rows,
    _grid_postures,
    _margins,
    _uncap,
    candidate_grid,
)
from .reasons import _reasons
from .stability import recommended_samples, sdm_margin
from .workpiece import WorkpieceModel

__all__ = ["SDM_CHECK_POINTS", "PlanResult", "candidate_grid", "plan"]

#: Points (those with the lowest planned zero-order margin) at which the
#: time-periodic margin of the planned posture is computed [-].
SDM_CHECK_POINTS = 6
#: Score preference for the CAM posture among equally good ones, per radian
#: of axis change [-/rad] (small against any margin difference).
CAM_PREFERENCE_PER_RAD = 1.0e-3


@dataclass(frozen=True, eq=False)
class PlanResult:
    """A planned path and why each posture was chosen.

    Arrays have one entry per cutter location of the CAM path (``n``).

    ``infeasible`` lists the points (indices into ``cl``) where no feasible
    posture exists or the planned path collides; they keep the CAM posture and
    their ``reason`` says why. A non-empty ``infeasible`` means ``cl`` must not
    be run as it is: check it (``stats["infeasible_points"]`` is its length,
    ``stats["infeasible_lines"]`` the CAM program's source lines).
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
    #: feasibility over the grid at the touching points, (t, nl, nt); feasibility as
    #: far as checked: interference is checked where a chosen posture collided (every
    #: candidate there) and for the chosen postures, elsewhere True means within the
    #: inclination range and the axis limits
    grid_margin: np.ndarray | None = None
    grid_feasible: np.ndarray | None = None
    touching_index: np.ndarray | None = None
    #: the workpiece's modes along the touching points, as the margins used them
    #: (its finite elements take seconds: later stages reuse it)
    workpiece: WorkpieceModel | None = None
    #: points (indices into ``cl``, ascending) without a feasible posture, or whose
    #: planned posture collides: the CAM posture is kept there, flagged in ``reason``
    infeasible: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))


def _reachable(machine, tips: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """True where some inverse solution of the machine is inside its limits."""
    s0, s1 = machine.inverse(tips.reshape(-1, 3), axes.reshape(-1, 3))
    ok = machine.within_limits(s0) | machine.within_limits(s1)
    return ok.reshape(tips.shape[:-1])


def _off_pole(machine, axes: np.ndarray, floor_rad: float) -> np.ndarray:
    """True where the tool axis is at least ``floor_rad`` [rad] from the machine's rotary
    (free) axis, e.g. ``|B| >= floor`` on a B/C machine. That axis is fixed in the
    workpiece frame on every supported machine (a table rotary axis turns with the
    workpiece; a head rotary axis is carried by nothing that tilts)."""
    if floor_rad <= 0:
        return np.ones(axes.shape[:-1], bool)
    pole = np.asarray(machine.axes[1].vector, dtype=float)
    return np.abs(axes @ pole) <= np.cos(floor_rad) + 1e-12


def plan(scn: PlanScenario, *, machine=None, spindle_rpm: float | None = None,
         progress=None, client=None) -> PlanResult:
    """Plan lead and tilt along the scenario's CAM program.

    Parameters
    ----------
    scn : PlanScenario
    machine : nc Machine, str or Path, optional
        A machine as given, or a name or machine file resolved with the tool's overhang
        as tool length (:meth:`orient.scenario.PlanScenario.machine`). Default: the
        scenario's ``program.machine``.
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
        **Check** ``result.infeasible`` **before using** ``result.cl``: points
        where no candidate posture is feasible (all outside the inclination
        range or the axis limits, or colliding -- shank or holder against the
        stock, the flank gouging the design -- at the point or at a point that
        takes its posture) or where the planned path collides keep the CAM
        posture, which may collide. Nothing is raised for them; the caller
        decides (refuse, or accept the fallback knowingly). Their reasons name
        the cause; ``stats["infeasible_points"]`` counts them and
        ``stats["infeasible_lines"]`` gives the CAM program's source lines.

    Raises
    ------
    ScenarioError
        No spindle speed in the program, or the ball never touches the design (an
        input error: the scenario's program and design do not go together).
    """
    t0 = time.perf_counter()
    opt = scn.options
    tool = scn.base.tool
    R = tool.radius_mm
    machine = scn.machine(machine)
    program = scn.base.read_program()
    cam = cutter_locations(program, machine)
    # the program's own errors before the contacts (their kernels compile on an empty
    # numba cache: a missing S word took 5.8 s to report in the suite)
    rpm = float(spindle_rpm) if spindle_rpm else float(np.max(cam.spindle_rpm))
    if not rpm > 0:
        raise ScenarioError(str(scn.path), "program.gcode", f"{scn.base.program_path}: no "
                            f"spindle speed in the program (S word)")
    design = scn.base.stock.load_design()
    contacts = ball_contacts(cam, R, design)
    feed_pts = ~cam.rapid
    idx = np.flatnonzero(contacts.touching)
    if len(idx) == 0:
        raise ScenarioError(str(scn.path), "program.gcode", f"{scn.base.program_path}: the "
                            f"ball never touches the design surface "
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
    incl_ok = (incl >= opt.min_inclination_rad - 1e-9) & (incl <= opt.max_inclination_rad
                                                           + 1e-9)
    reach_ok = _reachable(machine, tips, axes)
    # off the machine's pole (B near 0 on a B/C machine: there the rotary axis would turn
    # while the tip stands), the CAM's own posture included (it stays the fallback)
    pole_ok = _off_pole(machine, axes, opt.pole_floor_rad)
    ok = incl_ok & reach_ok & pole_ok
    cause = np.where(incl_ok, np.where(reach_ok, np.where(ok, _FEASIBLE, _AT_POLE),
                                       _OUTSIDE_LIMITS),
                     _OUTSIDE_INCLINATION).astype(np.int16)
    cam_ok = ok[:, -1].copy()
    ok[:, -1] = True            # the CAM posture is always evaluated (for the report)
    t1 = time.perf_counter()
    cut_info: dict = {}
    cuts = local_cuts(scn, contacts, idx, cam, rpm, info=cut_info)
    choose_speed = opt.spindle is not None and spindle_rpm is None
    if client is not None and choose_speed:
        # the speed's sample of gains on a worker, which compiles the gain kernel (and
        # caches it for the others) while this process builds the workpiece model
        rows_s = np.unique(np.linspace(0, len(idx) - 1, min(SPEED_SAMPLE_POINTS, len(idx)))
                           .astype(int))
        sample_f = client.submit(_gains_rows, tool, scn.base.coefficients,
                                 contacts.normal[idx[rows_s]], contacts.feed[idx[rows_s]],
                                 axes[rows_s], ok[rows_s], [cuts[r] for r in rows_s], False,
                                 _grid_postures(opt), pure=False)
    tool_sys = ModalSystem.tool(scn.base.compliance)
    wp = WorkpieceModel(scn.workpiece, contacts.point[idx], client=client)
    t2 = time.perf_counter()
    rpm_program = rpm
    cap = opt.margin_target
    cam_margin = None
    if client is not None:
        wp_f = client.scatter(wp, broadcast=True)
        if choose_speed:
            P_s = np.zeros(axes.shape[:2] + (3, 3))
            P_s[rows_s] = sample_f.result()[0]
            rpm = _choose_speed(scn, tool_sys, wp, contacts, idx, axes, ok, P_s, rpm,
                                client=client, wp_f=wp_f)
        # the CAM's posture at the CAM's speed (for the report) in the same tasks
        P, sense, margin, systems, cam_margin = _dask_gains_margins(
            client, scn, wp, tool_sys, contacts, idx, axes, ok, cuts, rpm, cap, wp_f=wp_f,
            cam_rpm=rpm_program if rpm != rpm_program else None)
    else:
        P, sense = _gains(scn, contacts, idx, axes, ok, cuts)
        if choose_speed:
            rpm = _choose_speed(scn, tool_sys, wp, contacts, idx, axes, ok, P, rpm)
        systems = [None] * len(idx)
        margin = _margins(scn, tool_sys, wp, contacts, idx, axes, ok, P, rpm,
                          None if progress is None else (lambda d, n: progress("margins", d, n)),
                          cap=cap, systems=systems)
    if rpm != rpm_program and cam_margin is None:
        # the CAM's posture at the CAM's speed, for the report (its column keeps the
        # margin at the planned speed: the choice and the reasons are about the planned
        # path)
        cam_margin = _margins(scn, tool_sys, wp, contacts, idx, axes, _cam_column(ok), P,
                              rpm_program)[:, -1]
    ok[:, -1] = cam_ok
    t3 = time.perf_counter()
    # --- choose: smooth, then interference, repeated -------------------------
    checker = scn.interference_checker(design)
    n_parts = len(checker.part_names)
    cam_interf = checker.check(cam.tip[idx], cam.axis[idx])
    cam_ok &= ~cam_interf.collides & ~cam_interf.gouges
    cause[:, -1] = np.where((cause[:, -1] == _FEASIBLE) & (cam_interf.part >= 0),
                            _PART + cam_interf.part, cause[:, -1])
    ok[:, -1] = cam_ok
    pref = CAM_PREFERENCE_PER_RAD * np.arccos(np.clip(np.sum(axes * cam.axis[idx][:, None, :],
                                                             axis=-1), -1, 1))
    base_score = np.minimum(margin, opt.margin_target) - pref
    run_id = np.cumsum(cam.rapid)[idx]                 # passes: rapids separate them
    breaks = np.zeros(len(idx), bool)
    breaks[1:] = run_id[1:] != run_id[:-1]
    step = np.zeros(len(idx))
    step[1:] = np.linalg.norm(np.diff(cam.tip[idx], axis=0), axis=1)
    inh = _inherited(cam, contacts, idx)
    choice, interf = _choose_collision_free(checker, tips, axes, inh, ok, cause, base_score,
                                            step, opt.max_rate_rad_per_mm, breaks, n_parts)
    none = ~ok.any(axis=1)
    rows = np.arange(len(idx))
    # the score needed only min(margin, target): the chosen and the CAM postures'
    # margins are made exact again for the report
    _uncap(scn, systems, axes, P, rpm, margin,
           np.stack([choice, np.full(len(idx), S1 - 1)], axis=1), cap, client=client)
    if cam_margin is None:
        cam_margin = margin[:, -1]
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
    mc_all[idx] = cam_margin
    cs = np.zeros(n_all)
    csc = np.zeros(n_all)
    cs[idx], csc[idx] = sense[rows, choice], sense[:, -1]
    cam_feasible = np.ones(n_all, bool)
    cam_feasible[idx] = cam_ok
    new_tip, new_axis = _place_all(cam, contacts, idx, u_new, R, inh)
    # a changed spindle speed keeps the feed per tooth: the feed scales with it
    planned = CutterLocations(new_tip, new_axis, cam.feed_mm_min * (rpm / rpm_program),
                              np.full(n_all, rpm), cam.block, cam.rapid)
    # the planned path as a whole: every feed point and every point the planner moved
    checked = feed_pts.copy()
    checked[idx] = True
    checked[inh.point] = True
    pts = np.flatnonzero(checked)
    final = checker.check(planned.tip[pts], planned.axis[pts])
    final_cause = np.zeros(n_all, np.int16)
    final_cause[pts] = np.where(final.part >= 0, _PART + final.part, _FEASIBLE)
    infeasible_mask = final_cause != _FEASIBLE
    infeasible_mask[idx[none]] = True
    infeasible = np.flatnonzero(infeasible_mask)
    labels = _cause_labels(checker.part_names)
    reasons = _reasons(cam, idx, inh, choice, S1, none, cause, final_cause, labels,
                       margin, sense, lead, tilt, cam_lead, cam_tilt, opt.margin_target,
                       cam_margin, None if rpm == rpm_program else rpm_program)
    checks = _sdm_checks(scn, tool_sys, wp, contacts, idx, u_new, cuts, rpm,
                         m_all[idx], run_id, client=client) if opt.verify_sdm else []
    t5 = time.perf_counter()
    nlg = nl * nt
    blk = cam.block[infeasible]
    lines = np.where(blk >= 0, program.line[np.clip(blk, 0, None)], -1) if len(program) \
        else np.full(len(blk), -1)
    return PlanResult(
        cl=planned, cam=cam, contacts=contacts, lead_rad=lead, tilt_rad=tilt,
        cam_lead_rad=cam_lead, cam_tilt_rad=cam_tilt, margin=m_all, cam_margin=mc_all,
        cut_sense=cs, cam_cut_sense=csc, cam_feasible=cam_feasible, reason=tuple(reasons),
        spindle_rpm=rpm, machine=machine, grid_lead_rad=lead_g, grid_tilt_rad=tilt_g,
        sdm_checks=checks,
        stats={"program_spindle_rpm": rpm_program, "points": n_all, "touching": len(idx),
               "postures": int(len(idx) * S1),
               "interference_dropped": interf["dropped"],
               "interference_checks": interf["checks"],
               "interference_rounds": interf["rounds"],
               "planned_collisions": int(np.count_nonzero(final_cause)),
               "infeasible_points": int(len(infeasible)),
               "infeasible_lines": sorted({int(x) for x in lines}),
               "wall_first_frequencies_hz": wp.first_frequencies_hz() if wp.levels else [],
               "cut": cut_info,
               "seconds": {"candidates": t1 - t0, "setup": t2 - t1, "margins": t3 - t2,
                           "choice_and_interference": t4 - t3, "finish": t5 - t4,
                           "total": t5 - t0}},
        grid_margin=margin[:, :nlg].reshape(-1, nl, nt),
        grid_feasible=ok[:, :nlg].reshape(-1, nl, nt), touching_index=idx, workpiece=wp,
        infeasible=infeasible)


def _place_all(cam: CutterLocations, contacts: Contacts, idx: np.ndarray, u_new: np.ndarray,
               R: float, inh: _Inherited | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Tips and axes of every point: touching ones about their ball centre, the others
    (air moves, approach, retract) moved with the nearest touching point of their pass
    (:class:`_Inherited`); points of passes without a touching point are kept."""
    inh = _inherited(cam, contacts, idx) if inh is None else inh
    tip = cam.tip.copy()
    axis = cam.axis.copy()
    tip[idx], axis[idx] = contacts.centre[idx] - R * u_new, u_new
    k = np.arange(len(inh.point))
    tip[inh.point] = inh.tips(k, u_new[inh.row])
    axis[inh.point] = u_new[inh.row]
    return tip, axis


def _sdm_checks(scn, tool_sys, wp, contacts, idx, u_new, cuts, rpm, zoa, runs, *,
                client=None) -> list[dict]:
    """Time-periodic margins of the planned posture at the lowest-ZOA points (with a
    ``client``, each point's margin on its workers: about 0.3 s each on the bundled thin
    wall since the monodromy matrices are taken on their active states, 0.7 s before and
    1.6 s before the kernel worked on the columns the history reaches)."""
    from .constants import GAIN_ANGLES_PER_REV

    tool = scn.base.tool
    order = np.argsort(zoa)
    picked: list[int] = []
    for r in order:                      # the lowest point of each of the lowest passes
        if len(picked) >= SDM_CHECK_POINTS or not np.isfinite(zoa[r]):
            break
        if all(runs[r] != runs[p] for p in picked):
            picked.append(int(r))

    cases = []
    for r in picked:
        i = int(idx[r])
        g = process_gain(tool, scn.base.coefficients, u_new[r], contacts.normal[i],
                         contacts.feed[i], cuts[r], spindle_rpm=rpm,
                         n_angles=GAIN_ANGLES_PER_REV)
        if g.engaged_fraction > 0.0:     # H's step averages as fine as the analysis wants
            n = recommended_samples(min(1.0, g.engaged_fraction)) * tool.flutes
            if n > GAIN_ANGLES_PER_REV:
                g = process_gain(tool, scn.base.coefficients, u_new[r], contacts.normal[i],
                                 contacts.feed[i], cuts[r], spindle_rpm=rpm, n_angles=n)
        system = wp.system_at(tool_sys, contacts.point[i]).with_tool_axis(u_new[r])
        cases.append((g.H, system))
    if client is not None:
        results = client.gather([client.submit(sdm_margin, H, system, rpm, tool.flutes,
                                               pure=False) for H, system in cases])
    else:
        results = [sdm_margin(H, system, rpm, tool.flutes) for H, system in cases]
    return [{"point": int(idx[r]), "zoa_margin": float(zoa[r]),
             "sdm_margin": float(res.margin), "kind": res.kind}
            for r, res in zip(picked, results, strict=True)]
